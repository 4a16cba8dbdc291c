//! The sensitivity study file (TOML, unknown keys refused): the sigma set, the INS and timing
//! sigmas, and either flat-ground points or a simulated scenario.

use crate::io::config_file::{self, ConfigPath};
use crate::pipeline::config::{Refusal, UncertaintyConfig};
use crate::uncertainty::UncertaintyInputs;
use crate::{Error, Result};
use nalgebra::{Matrix2, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which sigma set: paper 003 Table 1 "expected" or "ideal", or `[custom]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SigmaSet {
    /// Table 1 expected: lever 0.02 m, boresight 0.02 deg, alpha/beta 0.0055 deg, range
    /// 0.008 m, K 0.01 m.
    Expected,
    /// Table 1 ideal: lever 0.004 m, boresight 0.001 deg, alpha/beta 0.0055 deg, range 0.003 m,
    /// K 0.005 m.
    Ideal,
    /// The `[custom]` table.
    Custom,
}

/// A sensitivity study file (TOML, unknown keys refused).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensitivityConfig {
    /// Sigma set.
    pub sigma_set: SigmaSet,
    /// Sigmas for `sigma_set = "custom"` (same keys as the pipeline's `[uncertainty]`).
    #[serde(default)]
    pub custom: Option<UncertaintyConfig>,
    /// Saltelli base rows per point (model runs: `samples * (18 + 6 + 2)`).
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Bootstrap resamples for the 95% intervals.
    #[serde(default = "default_bootstrap")]
    pub bootstrap: usize,
    /// Random seed.
    #[serde(default)]
    pub seed: u64,
    /// INS sigmas ("estimated from INS" in Table 1). Required for flat ground; with
    /// `[scenario]`, absent means the simulated SMRMSG at each return's time.
    #[serde(default)]
    pub ins: Option<InsSigmaConfig>,
    /// Timing sigmas (not in Table 1; used by every set).
    #[serde(default)]
    pub timing: TimingSigmaConfig,
    /// Platform state (flat ground).
    #[serde(default)]
    pub platform: Option<PlatformConfig>,
    /// Scanner mounting (flat ground).
    #[serde(default)]
    pub sensor: Option<StudySensorConfig>,
    /// Points studied (flat ground).
    #[serde(default)]
    pub points: Option<PointsConfig>,
    /// Or: the returns of a simulated survey (instead of `[platform]`, `[sensor]`, `[points]`).
    #[serde(default)]
    pub scenario: Option<ScenarioPointsConfig>,
}

/// `[scenario]`: study returns of a survey simulated from a scenario file (docs/simulator.md),
/// with their real ranges, beam directions and attitudes; the sensor is the scenario's
/// configured one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioPointsConfig {
    /// Scenario file, relative to the study file.
    pub file: ConfigPath,
    /// Simulated duration (s), replacing the scenario's `duration_s`.
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// First and last range (m): split into `count` equal bins, one return per bin (the one
    /// closest to the bin centre; bins without a return are left out).
    pub range_m: [f64; 2],
    /// Number of range bins.
    pub count: usize,
}

/// `[ins]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsSigmaConfig {
    /// North, east, down position (m).
    pub sigma_position_ned_m: [f64; 3],
    /// Roll, pitch, heading (deg).
    pub sigma_attitude_rph_deg: [f64; 3],
}

/// `[timing]`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingSigmaConfig {
    /// Clock time error of a return (s): `sqrt(g^T C g)` of the (t0, T) covariance.
    #[serde(default)]
    pub sigma_clock_time_s: f64,
    /// Attitude latency (s).
    #[serde(default)]
    pub sigma_attitude_latency_s: f64,
}

/// `[platform]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformConfig {
    /// IMU latitude (deg).
    pub lat_deg: f64,
    /// IMU longitude (deg).
    pub lon_deg: f64,
    /// IMU ellipsoidal height (m).
    pub h_m: f64,
    /// Roll, pitch, heading (deg).
    #[serde(default)]
    pub rph_deg: [f64; 3],
    /// Speed along the heading (m/s).
    #[serde(default)]
    pub speed_mps: f64,
    /// Body angular rate (deg/s, body axes).
    #[serde(default)]
    pub body_rate_deg_s: [f64; 3],
}

/// `[sensor]` of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySensorConfig {
    /// Lever arm (m, body frame).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (deg).
    #[serde(default)]
    pub boresight_deg: [f64; 3],
    /// Out-of-plane angle alpha0 (deg).
    #[serde(default)]
    pub alpha0_deg: f64,
}

/// `[points]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointsConfig {
    /// Height of the scanner's optical centre above the ground (m).
    pub scanner_height_m: f64,
    /// First and last range (m), both >= the scanner height.
    pub range_m: [f64; 2],
    /// Number of ranges, evenly spaced.
    pub count: usize,
}

fn default_samples() -> usize {
    4096
}

fn default_bootstrap() -> usize {
    100
}

impl SigmaSet {
    /// Table 1 of paper 003 (no timing terms; they come from `[timing]`).
    pub(super) fn inputs(self, custom: Option<&UncertaintyConfig>) -> Option<UncertaintyInputs> {
        let table = |lever: f64, bore_deg: f64, range: f64, k: f64| UncertaintyInputs {
            sigma_lever_arm_b_m: Vector3::repeat(lever),
            sigma_boresight_rad: Vector3::repeat(bore_deg.to_radians()),
            sigma_alpha_rad: 0.0055f64.to_radians(),
            sigma_beta_rad: 0.0055f64.to_radians(),
            sigma_range_m: range,
            sigma_range_zero_m: k,
            clock_covariance_s2: Matrix2::zeros(),
            sigma_attitude_latency_s: 0.0,
        };
        match self {
            SigmaSet::Expected => Some(table(0.02, 0.02, 0.008, 0.01)),
            SigmaSet::Ideal => Some(table(0.004, 0.001, 0.003, 0.005)),
            SigmaSet::Custom => custom.map(UncertaintyConfig::inputs),
        }
    }
}

/// Reads a study file (TOML).
pub fn load_sensitivity(path: &Path) -> Result<SensitivityConfig> {
    let parsed = config_file::load::<SensitivityConfig>(path, &[])?;
    validate(&parsed.value)
        .map_err(|(key, problem)| Error::config(&parsed.source, key, problem))?;
    Ok(parsed.value)
}

fn validate(c: &SensitivityConfig) -> std::result::Result<(), Refusal> {
    if c.sigma_set == SigmaSet::Custom {
        c.custom
            .as_ref()
            .ok_or((
                "custom".to_string(),
                "sigma_set = \"custom\" needs a [custom] table".into(),
            ))?
            .check("custom")?;
    }
    if !(64..=1 << 22).contains(&c.samples) || c.bootstrap == 1 {
        return Err((
            "samples".into(),
            "samples must be in 64..=4194304 and bootstrap 0 or >= 2".into(),
        ));
    }
    let ins = c.ins.iter().flat_map(|i| {
        i.sigma_position_ned_m
            .iter()
            .chain(&i.sigma_attitude_rph_deg)
    });
    let t = &c.timing;
    let timing = [t.sigma_clock_time_s, t.sigma_attitude_latency_s];
    if !ins.chain(&timing).all(|s| s.is_finite() && *s >= 0.0) {
        return Err((
            "ins".into(),
            "INS and timing sigmas must be finite and >= 0".into(),
        ));
    }
    match (&c.scenario, &c.platform, &c.sensor, &c.points) {
        (Some(sc), None, None, None) => validate_scenario(sc),
        (None, Some(_), Some(_), Some(p)) => {
            if c.ins.is_none() {
                return Err(("ins".into(), "flat ground needs [ins]".into()));
            }
            validate_points(p)
        }
        _ => Err((
            "scenario".into(),
            "give either [scenario] or all of [platform], [sensor], [points]".into(),
        )),
    }
}

fn validate_points(p: &PointsConfig) -> std::result::Result<(), Refusal> {
    let ok = p.scanner_height_m > 0.0
        && p.range_m[0] >= p.scanner_height_m
        && p.range_m[1] >= p.range_m[0]
        && p.range_m[1].is_finite()
        && p.count >= 1;
    if !ok {
        return Err((
            "points".into(),
            "need 0 < scanner_height_m <= range_m[0] <= range_m[1] and count >= 1".into(),
        ));
    }
    Ok(())
}

fn validate_scenario(s: &ScenarioPointsConfig) -> std::result::Result<(), Refusal> {
    let ok = s.range_m[0] >= 0.0
        && s.range_m[1] > s.range_m[0]
        && s.range_m[1].is_finite()
        && s.count >= 1
        && s.duration_s.is_none_or(|d| d > 0.0 && d.is_finite());
    if !ok {
        return Err((
            "scenario".into(),
            "need 0 <= range_m[0] < range_m[1], count >= 1 and duration_s > 0".into(),
        ));
    }
    Ok(())
}
