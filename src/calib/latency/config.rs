//! The `calibrate latency` configuration file (TOML) and its [`LatencySetup`].

use super::estimate::LatencySetup;
use crate::calib::sphere::SphereRadius;
use crate::geo::rotations::r_zyx;
use crate::io::config_file::ConfigPath;
use crate::{Error, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// `calibrate latency` configuration (TOML). Paths are relative to the config file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LatencyConfig {
    /// Input files.
    pub files: LatencyFiles,
    /// Table.
    pub table: TableConfig,
    /// Sphere target.
    pub sphere: SphereConfig,
    /// Scanner mounting and processing.
    #[serde(default)]
    pub scanner: ScannerConfig,
}

/// Input files of a latency run.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LatencyFiles {
    /// Scanner returns, convention profile CSV with `time_s`.
    pub returns: ConfigPath,
    /// Table passes CSV.
    pub passes: ConfigPath,
    /// IMU attitude stream CSV.
    pub attitude: ConfigPath,
}

/// Table geometry.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TableConfig {
    /// Table axis in NED (normalised on reading); positive rates turn right-handed about it.
    pub axis_n: [f64; 3],
}

/// Sphere target.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SphereConfig {
    /// Certified radius (m); omit to estimate it.
    pub radius_m: Option<f64>,
    /// Approximate centre in NED about the table centre (m); omit to use every return.
    pub approx_centre_n_m: Option<[f64; 3]>,
    /// Returns farther than radius + gate (known radius) or gate (free radius) from the
    /// approximate centre are ignored (m).
    #[serde(default = "default_gate")]
    pub gate_m: f64,
}

fn default_gate() -> f64 {
    0.05
}

/// Scanner mounting and processing settings (conventions §3).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ScannerConfig {
    /// Boresight `[bx, by, bz]` (deg), `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    #[serde(default)]
    pub boresight_deg: [f64; 3],
    /// Optical centre relative to the table's rotation centre, body frame (m).
    #[serde(default)]
    pub lever_arm_b_m: [f64; 3],
    /// Range zero error `K` (m).
    #[serde(default)]
    pub range_zero_error_m: f64,
    /// `alpha` for returns without an `alpha_rad` column (deg).
    #[serde(default)]
    pub alpha0_deg: f64,
    /// Latency already applied when placing returns (ms).
    #[serde(default)]
    pub applied_latency_ms: f64,
}

impl LatencyConfig {
    /// The [`LatencySetup`] in SI, validated; `src` names the config in errors.
    pub fn setup(&self, src: &str) -> Result<LatencySetup> {
        let axis = Vector3::from(self.table.axis_n);
        if !crate::calib::positive(axis.norm()) {
            return Err(Error::config(
                src,
                "table.axis_n",
                "must be a non-zero vector",
            ));
        }
        let sphere_radius = match self.sphere.radius_m {
            Some(r) if r > 0.0 => SphereRadius::Known(r),
            Some(_) => return Err(Error::config(src, "sphere.radius_m", "must be > 0")),
            None => SphereRadius::Free,
        };
        if !crate::calib::positive(self.sphere.gate_m) {
            return Err(Error::config(src, "sphere.gate_m", "must be > 0"));
        }
        let [bx, by, bz] = self.scanner.boresight_deg.map(f64::to_radians);
        Ok(LatencySetup {
            r_s_to_b: r_zyx(bx, by, bz),
            lever_arm_b_m: self.scanner.lever_arm_b_m.into(),
            range_zero_error_m: self.scanner.range_zero_error_m,
            table_axis_n: axis.normalize(),
            sphere_radius,
            applied_latency_s: self.scanner.applied_latency_ms * 1e-3,
            sphere_gate_n_m: self
                .sphere
                .approx_centre_n_m
                .map(|c| (c.into(), self.sphere.gate_m)),
        })
    }
}
