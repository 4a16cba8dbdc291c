//! `kinescan trajectory` configuration (TOML; every key in docs/trajectory.md). Unknown keys
//! are refused with their dotted key; degrees only at this edge.

use crate::io::config_file::{self, ConfigPath};
use crate::{Error, Result};
use serde::Deserialize;
use std::path::Path;

/// The whole configuration.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Input files.
    pub inputs: InputsCfg,
    /// The filter's IMU model.
    #[serde(default)]
    pub imu: ImuCfg,
    /// GNSS handling.
    #[serde(default)]
    pub gnss: GnssCfg,
    /// Initial alignment.
    #[serde(default)]
    pub alignment: AlignmentCfg,
    /// Output files.
    pub output: OutputCfg,
}

/// `[inputs]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputsCfg {
    /// IMU records (docs/formats.md).
    pub imu: ConfigPath,
    /// GNSS fixes (docs/formats.md).
    pub gnss: ConfigPath,
}

/// `[imu]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuCfg {
    /// Error model of the IMU: "tactical" or "navigation" (`ins::imu_model`).
    pub grade: String,
}

impl Default for ImuCfg {
    fn default() -> Self {
        ImuCfg {
            grade: "tactical".into(),
        }
    }
}

/// `[gnss]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssCfg {
    /// Antenna phase centre relative to the IMU, body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Innovation test: a fix whose normalised innovation squared (3 dof) exceeds this is
    /// rejected. 16.27 = chi-square 3 dof at 0.999 (one good fix in 1000 rejected).
    pub innovation_gate: f64,
    /// Consecutive rejected fixes after which the run stops as diverged.
    pub max_rejected_run: usize,
}

impl Default for GnssCfg {
    fn default() -> Self {
        GnssCfg {
            lever_arm_b_m: [0.0, 0.0, -1.0],
            innovation_gate: 16.27,
            max_rejected_run: 50,
        }
    }
}

/// `[alignment]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AlignmentCfg {
    /// "auto": roll and pitch from the accelerometers over a static start (else 0 +- 5 deg),
    /// heading from the GNSS course once moving; "given": the angles below.
    pub mode: String,
    /// Length of the static window at the start (s).
    pub static_s: f64,
    /// Speed from which the GNSS course gives the heading (m/s).
    pub course_min_speed_mps: f64,
    /// 1-sigma of the heading from the course (deg).
    pub course_heading_sigma_deg: f64,
    /// "given": roll, pitch, heading at the first GNSS fix (deg).
    pub attitude_deg: Option<[f64; 3]>,
    /// "given": their 1-sigma (deg).
    pub attitude_sigma_deg: [f64; 3],
}

impl Default for AlignmentCfg {
    fn default() -> Self {
        AlignmentCfg {
            mode: "auto".into(),
            static_s: 5.0,
            course_min_speed_mps: 3.0,
            course_heading_sigma_deg: 2.0,
            attitude_deg: None,
            attitude_sigma_deg: [1.0, 1.0, 5.0],
        }
    }
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputCfg {
    /// Smoothed trajectory (SBET, at the IMU rate).
    pub sbet: ConfigPath,
    /// Its accuracy (SMRMSG, at the IMU rate).
    pub smrmsg: ConfigPath,
    /// Filtered (forward only) trajectory, if wanted.
    #[serde(default)]
    pub filtered_sbet: Option<ConfigPath>,
    /// Run report (JSON); default beside the SBET, `.report.json`.
    #[serde(default)]
    pub report: Option<ConfigPath>,
    /// Smoothed error model: autocorrelation and correlation time per component (JSON);
    /// default beside the SBET, `.error_model.json`.
    #[serde(default)]
    pub error_model: Option<ConfigPath>,
}

impl TrajectoryConfig {
    /// Loads and checks `path` with `--set` overrides; returns the config and its source name.
    pub fn load(path: &Path, overrides: &[String]) -> Result<(TrajectoryConfig, String)> {
        let parsed = config_file::load::<TrajectoryConfig>(path, overrides)?;
        parsed.value.check(&parsed.source)?;
        Ok((parsed.value, parsed.source))
    }

    fn check(&self, src: &str) -> Result<()> {
        let bad = |key: &str, problem: String| Err(Error::config(src, key, problem));
        let grades = ["tactical", "navigation"];
        if !grades.contains(&self.imu.grade.as_str()) {
            return bad(
                "imu.grade",
                format!("must be one of {grades:?}, got {:?}", self.imu.grade),
            );
        }
        if !self
            .gnss
            .lever_arm_b_m
            .iter()
            .all(|v| v.is_finite() && v.abs() <= 10.0)
        {
            return bad(
                "gnss.lever_arm_b_m",
                "each component must be within +-10 m".into(),
            );
        }
        let g = self.gnss.innovation_gate;
        if !(g.is_finite() && g >= 3.0) {
            return bad(
                "gnss.innovation_gate",
                format!("must be a number >= 3, got {g}"),
            );
        }
        if self.gnss.max_rejected_run == 0 {
            return bad("gnss.max_rejected_run", "must be at least 1".into());
        }
        let a = &self.alignment;
        match a.mode.as_str() {
            "auto" => {}
            "given" if a.attitude_deg.is_some() => {}
            "given" => {
                return bad(
                    "alignment.attitude_deg",
                    "mode \"given\" needs [roll, pitch, heading] (deg)".into(),
                )
            }
            m => {
                return bad(
                    "alignment.mode",
                    format!("must be \"auto\" or \"given\", got {m:?}"),
                )
            }
        }
        if let Some(att) = a.attitude_deg {
            if !att.iter().all(|v| v.is_finite()) || att[0].abs() > 90.0 || att[1].abs() > 89.0 {
                return bad(
                    "alignment.attitude_deg",
                    format!("roll within +-90, pitch within +-89 deg, got {att:?}"),
                );
            }
        }
        if !a
            .attitude_sigma_deg
            .iter()
            .all(|v| v.is_finite() && *v > 0.0 && *v <= 180.0)
        {
            return bad(
                "alignment.attitude_sigma_deg",
                "each must be in (0, 180] deg".into(),
            );
        }
        for (key, v, lo, hi) in [
            ("alignment.static_s", a.static_s, 0.5, 600.0),
            (
                "alignment.course_min_speed_mps",
                a.course_min_speed_mps,
                0.5,
                50.0,
            ),
            (
                "alignment.course_heading_sigma_deg",
                a.course_heading_sigma_deg,
                0.01,
                45.0,
            ),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return bad(key, format!("must be within [{lo}, {hi}], got {v}"));
            }
        }
        Ok(())
    }
}
