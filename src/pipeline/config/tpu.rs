//! `kinescan tpu`: the `[tpu]` table (the scanner kind and the fit check of clouds georeferenced
//! elsewhere) and [`TpuPipelineConfig`], the pipeline file as `tpu` reads it: the tables `run`
//! reads, with `[inputs] profiles` and `[time]` optional (a cloud has its points' times) and
//! `[uncertainty]` required. docs/tpu.md documents both.

use super::refusal::{refuse, require_non_negative, require_positive, Refusal};
use super::{
    DiagnoseConfig, LatencyConfig, OutputConfig, SensorConfig, SyncConfig, TimeConfig,
    TrajectoryConfig, UncertaintyConfig,
};
use crate::io::config_file::{self, ConfigPath};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The scanner kinds `tpu` can invert (docs/tpu.md).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScannerKind {
    /// The profile scanner of `run` (conventions §4): a rotating mirror, beams on the cone
    /// `alpha = alpha0`, any mirror angle.
    #[default]
    Profile,
    /// An airborne oscillating mirror: beams in the plane `alpha = alpha0` (usually 0), the
    /// mirror angle within `+-max_scan_angle_deg` of nadir (the scanner's z axis).
    OscillatingMirror,
    /// An airborne rotating (Palmer) mirror: beams on the cone of half-angle
    /// `cone_half_angle_deg` about the scanner's z axis (nadir with the identity boresight),
    /// any rotation angle (0 forward, +90 deg right).
    RotatingMirror,
}

/// `[tpu]`: how `kinescan tpu` checks that a cloud fits the trajectory and the sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TpuConfig {
    /// The scanner kind (`profile`, `oscillating_mirror` or `rotating_mirror`).
    #[serde(default)]
    pub scanner: ScannerKind,
    /// Half field of view of an oscillating mirror (deg): a recovered mirror angle beyond it
    /// is a misfit.
    #[serde(default = "default_max_scan_angle_deg")]
    pub max_scan_angle_deg: f64,
    /// Largest distance (m) of a point from the scanner's beam cone (`range * |alpha -
    /// alpha0|`); a point further off is a misfit.
    #[serde(default = "default_cone_tolerance_m")]
    pub cone_tolerance_m: f64,
    /// Half-angle (deg) of a rotating (Palmer) mirror's cone about the scanner's z axis.
    #[serde(default = "default_cone_half_angle_deg")]
    pub cone_half_angle_deg: f64,
}

impl Default for TpuConfig {
    fn default() -> Self {
        TpuConfig {
            scanner: ScannerKind::default(),
            max_scan_angle_deg: default_max_scan_angle_deg(),
            cone_tolerance_m: default_cone_tolerance_m(),
            cone_half_angle_deg: default_cone_half_angle_deg(),
        }
    }
}

impl TpuConfig {
    pub(super) fn check(&self) -> std::result::Result<(), Refusal> {
        require_positive([("tpu.cone_tolerance_m", self.cone_tolerance_m)])?;
        require_non_negative([("tpu.max_scan_angle_deg", self.max_scan_angle_deg)])?;
        if self.max_scan_angle_deg > 90.0 {
            let problem = format!("must be at most 90 deg, got {}", self.max_scan_angle_deg);
            return Err(refuse("tpu.max_scan_angle_deg", problem));
        }
        let half = self.cone_half_angle_deg;
        if !(half > 0.0 && half < 90.0) {
            let problem = format!("must be above 0 and below 90 deg, got {half}");
            return Err(refuse("tpu.cone_half_angle_deg", problem));
        }
        Ok(())
    }
}

fn default_max_scan_angle_deg() -> f64 {
    90.0
}
fn default_cone_tolerance_m() -> f64 {
    0.01
}
fn default_cone_half_angle_deg() -> f64 {
    15.0
}

/// `[inputs]` as `tpu` reads it: `profiles` optional (not read).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TpuInputsConfig {
    /// Applanix SBET trajectory.
    pub sbet: ConfigPath,
    /// Applanix SMRMSG accuracy file (required: the INS sigmas).
    #[serde(default)]
    pub smrmsg: Option<ConfigPath>,
    /// Profile files of `run` (not read by `tpu`).
    #[serde(default)]
    pub profiles: Vec<ConfigPath>,
    /// Point source id of the first profile file (not used by `tpu`).
    #[serde(default)]
    pub first_point_source_id: Option<u16>,
    /// GPS week of the trajectory: needed for a cloud in adjusted standard GPS time.
    #[serde(default)]
    pub gps_week: Option<u32>,
}

/// A pipeline file as `kinescan tpu` reads it (SPEC §9).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TpuPipelineConfig {
    /// Input files (`profiles` unused).
    pub inputs: TpuInputsConfig,
    /// Trajectory handling.
    #[serde(default)]
    pub trajectory: TrajectoryConfig,
    /// Scanner mounting and intrinsics.
    pub sensor: SensorConfig,
    /// Scanner time model: optional; with it the clock covariance enters as in `run`.
    #[serde(default)]
    pub time: Option<TimeConfig>,
    /// IMU-to-scanner latencies.
    #[serde(default)]
    pub latency: LatencyConfig,
    /// Output path, format and report.
    pub output: OutputConfig,
    /// The per-point uncertainty inputs (required).
    pub uncertainty: Option<UncertaintyConfig>,
    /// `[sync]` of `run` (not used by `tpu`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sync: Option<SyncConfig>,
    /// `[diagnose]` (not used by `tpu`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnose: Option<DiagnoseConfig>,
    /// The scanner kind and the fit check.
    #[serde(default)]
    pub tpu: TpuConfig,
}

/// A pipeline file loaded for `tpu`, overrides applied, paths resolved.
#[derive(Debug, Clone)]
pub struct LoadedTpuPipeline {
    /// Pipeline file.
    pub path: PathBuf,
    /// The configuration (every path absolute).
    pub config: TpuPipelineConfig,
    /// `--set` overrides applied, as given.
    pub overrides: Vec<String>,
}

/// Reads a pipeline file for `tpu`: `--set` overrides, unknown keys refused, every table
/// checked as `run` checks it; `[uncertainty]` and `inputs.smrmsg` required.
pub fn load_tpu(path: &Path, overrides: &[String]) -> Result<LoadedTpuPipeline> {
    let parsed = config_file::load::<TpuPipelineConfig>(path, overrides)?;
    check_tpu(&parsed.value)
        .map_err(|(key, problem)| Error::config(&parsed.source, key, problem))?;
    Ok(LoadedTpuPipeline {
        path: path.to_path_buf(),
        config: parsed.value,
        overrides: overrides.to_vec(),
    })
}

fn check_tpu(c: &TpuPipelineConfig) -> std::result::Result<(), Refusal> {
    c.trajectory.check()?;
    c.sensor.check()?;
    if let Some(t) = &c.time {
        t.check()?;
    }
    c.latency.check()?;
    c.output.check()?;
    c.tpu.check()?;
    let Some(u) = &c.uncertainty else {
        let problem =
            "tpu computes per-point uncertainty: the pipeline needs an [uncertainty] table";
        return Err(refuse("uncertainty", problem));
    };
    u.check("uncertainty")?;
    if c.inputs.smrmsg.is_none() {
        let problem = "tpu needs the SMRMSG file (INS position and attitude sigmas)";
        return Err(refuse("inputs.smrmsg", problem));
    }
    let cov = u.clock_covariance_s2;
    let clock_sigma = cov.iter().flatten().any(|v| *v != 0.0);
    if clock_sigma && c.time.is_none() {
        let problem = "a clock covariance needs [time] (how a point's time depends on t0 and T); \
                       set it to zeros for a cloud whose times are exact";
        return Err(refuse("uncertainty.clock_covariance_s2", problem));
    }
    if c.output.geoid.is_some() {
        let problem = "tpu reads ellipsoidal heights: a cloud with orthometric heights is not \
                       supported yet (remove output.geoid)";
        return Err(refuse("output.geoid", problem));
    }
    Ok(())
}
