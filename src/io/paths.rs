//! Output paths checked against input paths before a command does any work: an output may
//! never be an input (a night's raw data cannot be recorded again), and two outputs of one
//! command may never be one file.
//!
//! Two paths are the same file when their canonical paths are equal (symbolic links resolved)
//! or, for files that exist, when they share device and inode (hard links). Every command
//! calls [`check_collisions`] with its inputs and outputs, each named by the key the user sets
//! it with (`inputs.sbet`, `output.las`, a command-line argument...).

use crate::{Error, Result};
use std::path::{Component, Path, PathBuf};

/// A file named by the key that sets it (a dotted config key or an argument name).
pub type KeyedPath = (String, PathBuf);

/// What identifies a file on disk: its canonical path and, when it exists, (device, inode).
#[derive(Debug, Clone, PartialEq, Eq)]
struct FileId {
    canonical: PathBuf,
    device_inode: Option<(u64, u64)>,
}

impl FileId {
    fn of(path: &Path) -> FileId {
        FileId {
            canonical: canonical(path),
            device_inode: device_inode(path),
        }
    }

    fn same_as(&self, other: &FileId) -> bool {
        self.canonical == other.canonical
            || (self.device_inode.is_some() && self.device_inode == other.device_inode)
    }
}

#[cfg(unix)]
fn device_inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn device_inode(_path: &Path) -> Option<(u64, u64)> {
    None
}

/// The canonical path when the file exists; else its canonical folder joined with its name;
/// else the absolute path with `.` and `..` removed lexically.
fn canonical(path: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(path) {
        return c;
    }
    if let (Some(dir), Some(name)) = (path.parent(), path.file_name()) {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = std::fs::canonicalize(dir) {
            return d.join(name);
        }
    }
    lexical_absolute(path)
}

fn lexical_absolute(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// The files `names` a command writes into its `--out` folder, keyed `--out <name>`.
pub fn in_out_dir(out_dir: &Path, names: &[&str]) -> Vec<KeyedPath> {
    names
        .iter()
        .map(|n| (format!("--out {n}"), out_dir.join(n)))
        .collect()
}

/// Refuses any output that is the same file as an input, and any two outputs that are the
/// same file, with an error naming both keys and both paths. Call it before any work.
pub fn check_collisions(inputs: &[KeyedPath], outputs: &[KeyedPath]) -> Result<()> {
    let input_ids: Vec<FileId> = inputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let output_ids: Vec<FileId> = outputs.iter().map(|(_, p)| FileId::of(p)).collect();
    let collision = |(key, path): &KeyedPath, (other_key, other): &KeyedPath, what: &str| {
        Err(Error::Collision {
            output_key: key.clone(),
            output: path.clone(),
            other_key: other_key.clone(),
            other: other.clone(),
            problem: format!("is the same file as the {what}"),
        })
    };
    for (o, output) in outputs.iter().enumerate() {
        if let Some(i) = input_ids.iter().position(|id| output_ids[o].same_as(id)) {
            return collision(output, &inputs[i], "input");
        }
        if let Some(e) = output_ids[..o]
            .iter()
            .position(|id| output_ids[o].same_as(id))
        {
            return collision(output, &outputs[e], "output");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keyed(key: &str, p: &Path) -> KeyedPath {
        (key.to_string(), p.to_path_buf())
    }

    #[test]
    fn distinct_paths_pass_and_equal_paths_fail_naming_both_keys() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("a.sbet");
        std::fs::write(&input, b"x").unwrap();
        let las = dir.path().join("out.las");
        check_collisions(
            &[keyed("inputs.sbet", &input)],
            &[keyed("output.las", &las)],
        )
        .unwrap();
        // The same file through `./` and `..` is still the same file.
        let odd = dir.path().join("sub").join("..").join(".").join("a.sbet");
        let e = check_collisions(
            &[keyed("inputs.sbet", &input)],
            &[keyed("output.las", &odd)],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("output.las") && e.contains("inputs.sbet"), "{e}");
        assert!(e.contains(&*input.display().to_string()), "{e}");
    }

    #[test]
    fn outputs_colliding_with_each_other_fail_even_before_they_exist() {
        let dir = tempfile::tempdir().unwrap();
        let las = dir.path().join("out.las");
        let e = check_collisions(
            &[],
            &[keyed("output.las", &las), keyed("output.report", &las)],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("output.las") && e.contains("output.report"),
            "{e}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn symbolic_and_hard_links_are_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("p.ksprof");
        std::fs::write(&input, b"x").unwrap();
        let sym = dir.path().join("sym.las");
        std::os::unix::fs::symlink(&input, &sym).unwrap();
        let hard = dir.path().join("hard.las");
        std::fs::hard_link(&input, &hard).unwrap();
        for out in [&sym, &hard] {
            let r = check_collisions(&[keyed("inputs.profiles[0]", &input)], &[keyed("o", out)]);
            assert!(r.is_err(), "{} not refused", out.display());
        }
    }
}
