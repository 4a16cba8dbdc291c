//! Pipeline files (TOML): every stage's options, declared in one place.
//!
//! A pipeline file has one table per stage, in the order the data flows: `[inputs]` (read),
//! `[trajectory]`, `[sensor]`, `[time]` (scanner clock), `[latency]`, `[uncertainty]`
//! (optional per-point sigmas), `[output]` (georeference and write). Unknown keys are refused,
//! naming the key and the file (`io::config_file`). Paths are `ConfigPath`s: relative ones are
//! resolved against the pipeline file's folder when it is loaded.
//! Angles are given in degrees (keys ending `_deg`) and converted once, here.
//! docs/pipeline.md documents every option.
//!
//! One module per concept: `inputs` (`[inputs]`, `[trajectory]`), `sensor` (`[sensor]`,
//! `[time]`, `[latency]`), `output`, `uncertainty`, `sync`, `diagnose`; each checks its own
//! values, [`load`] checks what spans tables.

mod diagnose;
mod inputs;
mod output;
mod refusal;
mod sensor;
mod sync;
mod tpu;
mod uncertainty;

pub use diagnose::{DiagnoseConfig, START_NAV_TAU_S};
pub use inputs::{InputsConfig, TrajectoryConfig};
pub use output::{FrameConfig, OutputConfig, OutputFormat, SplitMode, Strictness};
use refusal::refuse;
pub use refusal::Refusal;
pub use sensor::{LatencyConfig, SensorConfig, TimeConfig, MIN_PERIOD_S};
pub use sync::SyncConfig;
pub use tpu::{
    load_tpu, LoadedTpuPipeline, ScannerKind, TpuConfig, TpuInputsConfig, TpuPipelineConfig,
};
pub use uncertainty::UncertaintyConfig;

use crate::io::config_file;
pub use crate::timing::TimeModel;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole pipeline definition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineConfig {
    /// Input files.
    pub inputs: InputsConfig,
    /// Trajectory handling.
    #[serde(default)]
    pub trajectory: TrajectoryConfig,
    /// Scanner mounting and intrinsics.
    pub sensor: SensorConfig,
    /// Scanner time model.
    pub time: TimeConfig,
    /// IMU-to-scanner latencies.
    #[serde(default)]
    pub latency: LatencyConfig,
    /// Output LAS and report.
    pub output: OutputConfig,
    /// Per-point uncertainty (optional; needs `inputs.smrmsg`).
    #[serde(default)]
    pub uncertainty: Option<UncertaintyConfig>,
    /// Object-space time synchronisation (optional; runs before georeferencing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sync: Option<SyncConfig>,
    /// `kinescan diagnose` options (optional; command-line options win).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnose: Option<DiagnoseConfig>,
    /// `kinescan tpu` options (optional; `run` does not use them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tpu: Option<TpuConfig>,
}

/// A pipeline file loaded with its overrides applied and paths resolved.
#[derive(Debug, Clone)]
pub struct LoadedPipeline {
    /// Pipeline file.
    pub path: PathBuf,
    /// The configuration, every path absolute (resolved against the pipeline file's folder).
    pub config: PipelineConfig,
    /// `--set` overrides applied, as given.
    pub overrides: Vec<String>,
}

/// Reads `path`, applies `KEY=VALUE` overrides (`io::config_file`), validates and resolves
/// relative paths against the file's folder.
pub fn load(path: &Path, overrides: &[String]) -> Result<LoadedPipeline> {
    let mut parsed = config_file::load::<PipelineConfig>(path, overrides)?;
    validate(&parsed.value, &parsed.source)?;
    resolve(&mut parsed.value)?;
    Ok(LoadedPipeline {
        path: path.to_path_buf(),
        config: parsed.value,
        overrides: overrides.to_vec(),
    })
}

impl LoadedPipeline {
    /// This pipeline as it is in memory (a caller may have changed it since it was loaded)
    /// with more `KEY=VALUE` overrides applied and checked as [`load`] does; relative paths in
    /// them are resolved against the pipeline file's folder. Errors name the file `(with
    /// --set)` and the key.
    pub fn with_overrides(&self, set: &[String]) -> Result<LoadedPipeline> {
        let body = toml::to_string(&self.config)
            .map_err(|e| Error::Invalid(format!("{}: TOML: {e}", self.path.display())))?;
        let dir = crate::io::atomic::parent_dir(&self.path);
        let dir = std::path::absolute(dir).map_err(|e| Error::io(&self.path, e))?;
        let source = self.path.display().to_string();
        let mut parsed = config_file::parse::<PipelineConfig>(&body, &source, &dir, set)?;
        validate(&parsed.value, &parsed.source)?;
        resolve(&mut parsed.value)?;
        Ok(LoadedPipeline {
            path: self.path.clone(),
            config: parsed.value,
            overrides: self.overrides.iter().chain(set).cloned().collect(),
        })
    }
}

/// Values read from the files a configuration names: `diagnose.nav_error_model`.
fn resolve(c: &mut PipelineConfig) -> Result<()> {
    match c.diagnose.as_mut() {
        Some(d) => d.resolve_nav_error_model(),
        None => Ok(()),
    }
}

/// Each table's own checks, then what spans tables.
fn validate(c: &PipelineConfig, source: &str) -> Result<()> {
    check(c).map_err(|(key, problem)| Error::config(source, key, problem))
}

fn check(c: &PipelineConfig) -> std::result::Result<(), Refusal> {
    c.inputs.check()?;
    c.trajectory.check()?;
    c.sensor.check()?;
    c.time.check()?;
    if let Some(sy) = &c.sync {
        sy.check(&c.time)?;
    }
    if let Some(d) = &c.diagnose {
        d.check()?;
    }
    if let Some(t) = &c.tpu {
        t.check()?;
    }
    let t = &c.time;
    if t.model == TimeModel::Software && !t.t0_s.is_some_and(f64::is_finite) && c.sync.is_none() {
        let problem = "the software time model needs t0_s (or a sync stage)";
        return Err(refuse("time.t0_s", problem));
    }
    c.latency.check()?;
    if let Some(u) = &c.uncertainty {
        u.check("uncertainty")?;
        if c.inputs.smrmsg.is_none() {
            let problem = "[uncertainty] needs the SMRMSG file (INS position and attitude sigmas)";
            return Err(refuse("inputs.smrmsg", problem));
        }
    }
    c.output.check()
}

fn yes() -> bool {
    true
}

#[cfg(test)]
mod tests {
    /// Every path key of a pipeline file is a `ConfigPath` (resolved against the file's folder
    /// by type): a `PathBuf` field in a table would be read relative to the working directory.
    #[test]
    fn tables_hold_paths_as_config_paths() {
        let tables = [
            include_str!("inputs.rs"),
            include_str!("sensor.rs"),
            include_str!("output.rs"),
            include_str!("uncertainty.rs"),
            include_str!("sync.rs"),
            include_str!("diagnose.rs"),
        ];
        for text in tables {
            let fields = text.lines().filter(|l| l.trim_start().starts_with("pub "));
            let raw: Vec<&str> = fields.filter(|l| l.contains("PathBuf")).collect();
            assert!(raw.is_empty(), "{raw:?}");
        }
        assert!(
            tables[0].contains("pub sbet: ConfigPath"),
            "the check reads the fields"
        );
    }
}
