//! The one loader of configuration files (TOML): pipeline, simulator scenario, calibration
//! and sensitivity study files.
//!
//! [`load`] reads the file, applies `--set KEY=VALUE` overrides (dotted keys; VALUE parsed as
//! TOML, or taken as a string when it does not parse) and deserialises the target type with
//! `serde_path_to_error`. The config types refuse unknown keys (`#[serde(deny_unknown_fields)]`),
//! and every error is an [`Error::Config`] naming the file and the full dotted key, e.g.
//! `sensor.boresight_deg[2]`.
//!
//! Paths in a config file are [`ConfigPath`]s: a relative path is resolved against the config
//! file's folder while it is deserialised, so a new path key cannot be left unresolved.

use crate::{Error, Result};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize};
use std::cell::RefCell;
use std::path::{Path, PathBuf};

/// A path read from a config file: relative paths are resolved against the file's folder
/// when the file is loaded through this module (kept as given otherwise).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(transparent)]
pub struct ConfigPath(PathBuf);

impl ConfigPath {
    /// The path, resolved.
    pub fn as_path(&self) -> &Path {
        &self.0
    }
    /// The path, resolved, owned.
    pub fn into_path_buf(self) -> PathBuf {
        self.0
    }
}

impl std::ops::Deref for ConfigPath {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ConfigPath {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl From<PathBuf> for ConfigPath {
    fn from(p: PathBuf) -> Self {
        ConfigPath(p)
    }
}

impl From<ConfigPath> for PathBuf {
    fn from(p: ConfigPath) -> Self {
        p.0
    }
}

impl From<&ConfigPath> for PathBuf {
    fn from(p: &ConfigPath) -> Self {
        p.0.clone()
    }
}

impl From<&Path> for ConfigPath {
    fn from(p: &Path) -> Self {
        ConfigPath(p.to_path_buf())
    }
}

impl From<&str> for ConfigPath {
    fn from(p: &str) -> Self {
        ConfigPath(PathBuf::from(p))
    }
}

thread_local! {
    /// Folder of the config file being deserialised on this thread (set by [`parse`]).
    static BASE_DIR: RefCell<Option<PathBuf>> = const { RefCell::new(None) };
}

impl<'de> Deserialize<'de> for ConfigPath {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let given = PathBuf::deserialize(d)?;
        let resolved = BASE_DIR.with(|base| match &*base.borrow() {
            Some(dir) if given.is_relative() => dir.join(&given),
            _ => given,
        });
        Ok(ConfigPath(resolved))
    }
}

/// Sets [`BASE_DIR`] for the guard's lifetime and restores the previous value on drop (also
/// on panic), so nested or failed loads leave no state behind.
struct BaseDirGuard(Option<PathBuf>);

impl BaseDirGuard {
    fn set(dir: &Path) -> Self {
        BaseDirGuard(BASE_DIR.with(|b| b.replace(Some(dir.to_path_buf()))))
    }
}

impl Drop for BaseDirGuard {
    fn drop(&mut self) {
        BASE_DIR.with(|b| *b.borrow_mut() = self.0.take());
    }
}

/// A config value with the name its errors use: the file, `(with --set)` when overridden.
#[derive(Debug, Clone)]
pub struct Parsed<T> {
    /// The deserialised value, paths resolved.
    pub value: T,
    /// How errors name the source, e.g. `survey/pipeline.toml (with --set)`.
    pub source: String,
}

/// Reads the config file `path`, applies `overrides` and deserialises it; relative
/// [`ConfigPath`]s are resolved against the file's folder, made absolute.
pub fn load<T: DeserializeOwned>(path: &Path, overrides: &[String]) -> Result<Parsed<T>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let dir = std::path::absolute(dir).map_err(|e| Error::io(path, e))?;
    parse(&text, &path.display().to_string(), &dir, overrides)
}

/// [`load`] for text already read: `source` names it in errors, relative paths are resolved
/// against `base_dir`.
pub fn parse<T: DeserializeOwned>(
    text: &str,
    source: &str,
    base_dir: &Path,
    overrides: &[String],
) -> Result<Parsed<T>> {
    let mut table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| Error::config(source, "(syntax)", e.to_string()))?;
    for o in overrides {
        apply_override(&mut table, o)?;
    }
    let source = if overrides.is_empty() {
        source.to_string()
    } else {
        format!("{source} (with --set)")
    };
    let _base = BaseDirGuard::set(base_dir);
    let value = serde_path_to_error::deserialize(toml::Value::Table(table))
        .map_err(|e| Error::config(&source, full_key(&e), e.inner().message()))?;
    Ok(Parsed { value, source })
}

/// The dotted key of a deserialisation error; for a missing field the path ends at its table,
/// so the field (named in the message) is appended.
fn full_key(e: &serde_path_to_error::Error<toml::de::Error>) -> String {
    let path = e.path().to_string();
    let message = e.inner().message();
    let missing = message
        .strip_prefix("missing field `")
        .and_then(|r| r.split('`').next());
    match (missing, path.as_str()) {
        (Some(field), "." | "") => field.to_string(),
        (Some(field), table) => format!("{table}.{field}"),
        (None, ".") => "(document)".to_string(),
        (None, key) => key.to_string(),
    }
}

/// Sets a dotted `KEY=VALUE` in a TOML table (VALUE parsed as TOML, else a string).
pub fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<()> {
    let (key, raw) = assignment
        .split_once('=')
        .ok_or_else(|| Error::config("--set", assignment, "expected KEY=VALUE"))?;
    let key = key.trim();
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(Error::config("--set", key, "empty key segment"));
    }
    let mut t = table;
    for p in &parts[..parts.len() - 1] {
        let entry = t
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(Default::default()));
        t = entry
            .as_table_mut()
            .ok_or_else(|| Error::config("--set", key, format!("`{p}` is not a table")))?;
    }
    t.insert(parts[parts.len() - 1].to_string(), parse_value(raw.trim()));
    Ok(())
}

fn parse_value(raw: &str) -> toml::Value {
    match format!("v = {raw}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed key"),
        Err(_) => toml::Value::String(raw.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Outer {
        inner: Inner,
        #[serde(default)]
        list: Vec<Inner>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        angles_deg: [f64; 3],
        #[serde(default)]
        file: Option<ConfigPath>,
        #[serde(default)]
        files: Vec<ConfigPath>,
    }

    fn err_of(text: &str, overrides: &[&str]) -> String {
        let set: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        parse::<Outer>(text, "t.toml", Path::new("/base"), &set)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn errors_name_the_file_and_the_full_dotted_key() {
        let ok = "inner.angles_deg = [1, 2, 3]\n";
        let bad_element = "inner.angles_deg = [1, 2, \"x\"]\n";
        assert!(err_of(bad_element, &[]).starts_with("t.toml: key `inner.angles_deg[2]`"));
        let unknown = format!("{ok}[[list]]\nangles_deg = [0, 0, 0]\ncolour = 1\n");
        let e = err_of(&unknown, &[]);
        assert!(e.starts_with("t.toml: key `list[0].colour`"), "{e}");
        let e = err_of("[inner]\n", &[]);
        assert!(e.starts_with("t.toml: key `inner.angles_deg`"), "{e}");
        assert!(e.contains("missing field"), "{e}");
        let e = err_of(ok, &["inner.angles_deg=[1, 2]"]);
        assert!(
            e.starts_with("t.toml (with --set): key `inner.angles_deg`"),
            "{e}"
        );
        let e = err_of("inner = [", &[]);
        assert!(e.starts_with("t.toml: key `(syntax)`"), "{e}");
    }

    #[test]
    fn every_config_path_is_resolved_against_the_files_folder() {
        let text =
            "[inner]\nangles_deg = [0, 0, 0]\nfile = \"a.csv\"\nfiles = [\"b\", \"/abs/c\"]\n\
                    [[list]]\nangles_deg = [0, 0, 0]\nfile = \"d/e.csv\"\n";
        let p = parse::<Outer>(text, "t.toml", Path::new("/base"), &[]).unwrap();
        let inner = &p.value.inner;
        assert_eq!(inner.angles_deg, [0.0; 3]);
        assert_eq!(inner.file.as_deref(), Some(Path::new("/base/a.csv")));
        let files: Vec<&Path> = inner.files.iter().map(|f| f.as_path()).collect();
        assert_eq!(files, [Path::new("/base/b"), Path::new("/abs/c")]);
        let nested = p.value.list[0].file.as_deref();
        assert_eq!(nested, Some(Path::new("/base/d/e.csv")));
        // Outside a load nothing is resolved (the guard restored the empty state).
        let plain: ConfigPath = toml::Value::String("x".into()).try_into().unwrap();
        assert_eq!(plain.as_path(), Path::new("x"));
    }

    #[test]
    fn overrides_set_nested_keys_and_refuse_malformed_ones() {
        let mut t = toml::Table::new();
        apply_override(&mut t, "a.b.c = [1, 2]").unwrap();
        apply_override(&mut t, "a.name = not toml").unwrap();
        assert_eq!(
            t["a"]["b"]["c"],
            toml::Value::Array(vec![1.into(), 2.into()])
        );
        assert_eq!(t["a"]["name"].as_str(), Some("not toml"));
        assert!(apply_override(&mut t, "a.b.c.d=1").is_err());
        assert!(apply_override(&mut t, "a..b=1").is_err());
        assert!(apply_override(&mut t, "novalue").is_err());
    }
}
