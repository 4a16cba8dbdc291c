//! The day file (TOML, docs/nightly.md): the passes of a survey day, the pipeline template
//! that says how every pass is processed, the output folder and layout, and what the night
//! does. Loaded with the project's one config loader (`io::config_file`): unknown keys are
//! refused with their dotted key, relative paths are relative to the day file's folder.

use crate::geo::projection::GEOGRAPHIC_CODES;
use crate::io::config_file::{self, ConfigPath};
use crate::io::paths::{self, KeyedPath};
use crate::pipeline::config::{self as pipeline_config, LoadedPipeline};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole day file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DayConfig {
    /// What the night does and where it writes.
    pub day: DaySettings,
    /// The day's passes, in acquisition order.
    pub passes: Vec<PassConfig>,
}

/// `[day]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaySettings {
    /// Pipeline file used for every pass: trajectory (`inputs.sbet`, `inputs.smrmsg`),
    /// sensor, time model, latency, uncertainty, `[sync]` (sync targets), `[diagnose]`
    /// (reference patches), output frame and scale. Its `inputs.profiles` and `output.las`
    /// are replaced per pass.
    pub template: ConfigPath,
    /// Output folder: the day's LAS files, report, plan, journal and unit outputs.
    pub out: ConfigPath,
    /// Output layout.
    #[serde(default)]
    pub layout: Layout,
    /// Length of a work unit (s of scanning): a pass is cut into units of this many seconds
    /// of profiles.
    #[serde(default = "default_unit_s")]
    pub unit_s: f64,
    /// What the night does besides georeferencing.
    #[serde(default)]
    pub night: NightOptions,
}

fn default_unit_s() -> f64 {
    60.0
}

/// `[day.layout]`: how the day's points are grouped into LAS files.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Layout {
    /// One LAS file per pass, `<pass name>.las`.
    #[default]
    PerPass,
    /// Square tiles of `size_m` in the output frame, `tile_<E>_<N>.las` (lower-left corner, m).
    Tiles {
        /// Tile edge (m).
        size_m: f64,
    },
}

/// `[day.night]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NightOptions {
    /// Synchronise each pass with the template's `[sync]` (ignored without it).
    #[serde(default = "yes")]
    pub sync: bool,
    /// Run the diagnosis on each pass (needs the template's `[diagnose]`).
    #[serde(default)]
    pub diagnose: bool,
    /// Re-process a pass whose diagnosis names an effect with its correction, replacing the
    /// pass's output (otherwise the correction is reported); needs `diagnose`.
    #[serde(default)]
    pub auto_correct: bool,
}

impl Default for NightOptions {
    fn default() -> Self {
        NightOptions {
            sync: true,
            diagnose: false,
            auto_correct: false,
        }
    }
}

fn yes() -> bool {
    true
}

/// `[[passes]]`: one drive past the area; each profile file is one scanner's recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PassConfig {
    /// Pass name (letters, digits, `-`, `_`): names its output and work units.
    pub name: String,
    /// Profile files of the pass (binary or CSV), one per scanner.
    pub profiles: Vec<ConfigPath>,
}

/// A loaded day file.
#[derive(Debug, Clone)]
pub struct LoadedDay {
    /// The day file.
    pub path: PathBuf,
    /// How errors name it.
    pub source: String,
    /// Its content, paths absolute.
    pub config: DayConfig,
    /// The template, loaded once (its profile list and output replaced per input).
    pub template: LoadedPipeline,
}

/// Reads and checks the day file and its template; errors name the file and the dotted key.
pub fn load(path: &Path) -> Result<LoadedDay> {
    let parsed = config_file::load::<DayConfig>(path, &[])?;
    let c = parsed.value;
    check(&c).map_err(|(key, problem)| Error::config(&parsed.source, key, problem))?;
    let missing = c.passes.iter().enumerate().flat_map(|(i, p)| {
        let keys = (0..p.profiles.len()).map(move |j| format!("passes[{i}].profiles[{j}]"));
        keys.zip(&p.profiles)
    });
    for (key, file) in missing {
        if !file.is_file() {
            let problem = format!("profile file {} does not exist", file.display());
            return Err(Error::config(&parsed.source, key, problem));
        }
    }
    if !c.day.template.is_file() {
        let problem = format!("template {} is not a file", c.day.template.display());
        return Err(Error::config(&parsed.source, "day.template", problem));
    }
    // The template is checked with the first pass's files (its own list may be empty).
    let files: Vec<toml::Value> = c.passes[0]
        .profiles
        .iter()
        .map(|p| toml::Value::String(p.to_string_lossy().into()))
        .collect();
    let profiles = format!("inputs.profiles={}", toml::Value::Array(files));
    let template = pipeline_config::load(&c.day.template, &[profiles])?;
    let geographic = match template.config.output.frame {
        pipeline_config::FrameConfig::Epsg { code } => GEOGRAPHIC_CODES.contains(&code),
        _ => false,
    };
    if let (Layout::Tiles { size_m }, true) = (c.day.layout, geographic) {
        let problem = format!(
            "tiles of {size_m} m cannot be cut in the template's geographic output.frame \
             (EPSG code in degrees): use layout = {{ kind = \"per_pass\" }} or a projected \
             output.frame"
        );
        return Err(Error::config(&parsed.source, "day.layout", problem));
    }
    Ok(LoadedDay {
        path: path.to_path_buf(),
        source: parsed.source,
        config: c,
        template,
    })
}

/// Every file a day reads, named by its key: the day file, the template and its inputs
/// (trajectory, accuracy, sync and diagnosis files, geoid), every pass's profile files.
pub fn inputs(day: &LoadedDay) -> Vec<KeyedPath> {
    let mut v = vec![
        ("day file".to_string(), day.path.clone()),
        ("day.template".to_string(), day.template.path.clone()),
    ];
    let template = crate::pipeline::files::inputs(&day.template);
    v.extend(
        template
            .into_iter()
            .filter(|(k, _)| k != "pipeline file" && !k.starts_with("inputs.profiles"))
            .map(|(k, p)| (format!("day.template: {k}"), p)),
    );
    for (i, pass) in day.config.passes.iter().enumerate() {
        for (j, f) in pass.profiles.iter().enumerate() {
            v.push((format!("passes[{i}].profiles[{j}]"), f.to_path_buf()));
        }
    }
    v
}

/// Whether `name` is a file the day may write into its folder: a pass or tile LAS file
/// (`<pass>.las`, `tile_<E>_<N>.las`), its reports, plan, journal or corrections.
pub fn owns(name: &str) -> bool {
    let las = name.strip_suffix(".las").is_some_and(|stem| {
        !stem.is_empty()
            && stem
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_')
    });
    las || FILES.contains(&name)
}

/// The day's own files in its folder, besides the LAS files.
pub const FILES: [&str; 6] = [
    "day.report.json",
    "report.md",
    "report.html",
    "plan.json",
    "journal.jsonl",
    CORRECTIONS,
];

/// The night's diagnosis and corrections of every pass (`night`).
pub const CORRECTIONS: &str = "corrections.json";

/// Every file a day may write or remove, named by its key: the pass LAS files (or every
/// existing `*.las` its tiles may replace), its reports, plan, journal and corrections.
pub fn outputs(day: &LoadedDay) -> Vec<KeyedPath> {
    let out = &day.config.day.out;
    let mut v: Vec<KeyedPath> = day
        .config
        .passes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            (
                format!("passes[{i}] output"),
                out.join(format!("{}.las", p.name)),
            )
        })
        .collect();
    if let Layout::Tiles { .. } = day.config.day.layout {
        let tile = |n: &str| n.starts_with("tile_") && owns(n);
        v.extend(paths::existing_owned(out, "day.layout tiles", tile));
    }
    v.extend(FILES.iter().map(|f| (format!("day.out {f}"), out.join(f))));
    v
}

/// Refuses a day whose outputs would overwrite one of its inputs (or each other), and a
/// profile file given twice (by path, link or a copy). Before any work.
pub fn check_files(day: &LoadedDay) -> Result<()> {
    let inputs = inputs(day);
    paths::check_collisions(&inputs, &outputs(day))?;
    // The work units' files (hard links of the pass files once merged) may be replaced too.
    let units = day.config.day.out.join("units");
    paths::check_collisions(
        &inputs,
        &paths::existing_owned(&units, "day.out units/", |_| true),
    )?;
    let profiles: Vec<KeyedPath> = inputs
        .into_iter()
        .filter(|(k, _)| k.starts_with("passes["))
        .collect();
    paths::check_distinct_inputs(&profiles)
        .map_err(|e| Error::Invalid(format!("{}: {e}", day.source)))
}

fn check(c: &DayConfig) -> std::result::Result<(), (String, String)> {
    let d = &c.day;
    if !(d.unit_s.is_finite() && d.unit_s > 0.0) {
        return Err((
            "day.unit_s".into(),
            format!("must be > 0 s, got {}", d.unit_s),
        ));
    }
    if let Layout::Tiles { size_m } = d.layout {
        if !(size_m.is_finite() && size_m >= 1.0) {
            let problem = format!("must be at least 1 m, got {size_m}");
            return Err(("day.layout.size_m".into(), problem));
        }
    }
    if d.night.auto_correct && !d.night.diagnose {
        let problem = "needs day.night.diagnose = true: the correction is the night's diagnosis'";
        return Err(("day.night.auto_correct".into(), problem.into()));
    }
    if c.passes.is_empty() {
        return Err(("passes".into(), "at least one pass is required".into()));
    }
    for (i, p) in c.passes.iter().enumerate() {
        let ok = |ch: char| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_';
        if p.name.is_empty() || !p.name.chars().all(ok) {
            let problem = format!("`{}`: letters, digits, - and _ only", p.name);
            return Err((format!("passes[{i}].name"), problem));
        }
        if let Some(j) = c.passes[..i].iter().position(|q| q.name == p.name) {
            let problem = format!("`{}` is also the name of passes[{j}]", p.name);
            return Err((format!("passes[{i}].name"), problem));
        }
        if p.profiles.is_empty() {
            let problem = "at least one profile file is required".to_string();
            return Err((format!("passes[{i}].profiles"), problem));
        }
    }
    Ok(())
}
