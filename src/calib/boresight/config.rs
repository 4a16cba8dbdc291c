//! The `calibrate boresight` configuration file (TOML) and its [`BoresightSetup`].

use crate::calib::tripod::BoresightSetup;
use crate::geo::rotations::r_zyx;
use crate::io::config_file::ConfigPath;
use crate::{Error, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// `calibrate boresight` configuration (TOML). Paths are relative to the config file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoresightConfig {
    /// Input files.
    pub files: BoresightFiles,
    /// The tripod.
    pub tripod: TripodConfig,
    /// Prior mounting.
    #[serde(default)]
    pub scanner: BoresightScannerConfig,
}

/// Input files of a boresight run.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoresightFiles {
    /// Ellipse centres `site,leg,y_s_m,z_s_m,sigma_m` (give this or `scans`).
    #[serde(default)]
    pub centres: Option<ConfigPath>,
    /// Raw static scan returns `site,beta_rad,range_m,intensity` (`alpha0 = 0`); the centres
    /// are fitted ([`crate::calib::ellipse`]; needs `tripod.leg_radius_m`, `scanner.sigma_range_m`).
    #[serde(default)]
    pub scans: Option<ConfigPath>,
    /// Site attitudes `site,roll_deg,pitch_deg,heading_deg,sigma_roll_deg,sigma_pitch_deg,sigma_heading_deg`.
    pub sites: ConfigPath,
}

/// Tripod description.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TripodConfig {
    /// Inter-leg angles for leg pairs (1,2), (1,3), (2,3) (deg).
    pub leg_angles_deg: [f64; 3],
    /// Tripod axis, apex towards feet, in NED (default down: standing on the floor).
    #[serde(default = "default_axis")]
    pub axis_n: [f64; 3],
    /// Leg radius (m), for fitting centres from `scans`.
    #[serde(default)]
    pub leg_radius_m: Option<f64>,
}

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Prior mounting.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoresightScannerConfig {
    /// Nominal boresight `[bx, by, bz]` (deg, convention), any size.
    #[serde(default)]
    pub nominal_boresight_deg: [f64; 3],
    /// Range noise, 1 sigma (m), for fitting centres from `scans`.
    #[serde(default)]
    pub sigma_range_m: Option<f64>,
    /// Range zero error `K` (m) of `scans`.
    #[serde(default)]
    pub range_zero_error_m: f64,
}

impl BoresightConfig {
    /// The [`BoresightSetup`] in SI, validated; `src` names the config in errors.
    pub fn setup(&self, src: &str) -> Result<BoresightSetup> {
        if self
            .tripod
            .leg_angles_deg
            .iter()
            .any(|a| !(*a > 0.0 && *a < 180.0))
        {
            return Err(Error::config(
                src,
                "tripod.leg_angles_deg",
                "angles must be in (0, 180) deg",
            ));
        }
        let axis = Vector3::from(self.tripod.axis_n);
        if !crate::calib::positive(axis.norm()) {
            return Err(Error::config(src, "tripod.axis_n", "must be non-zero"));
        }
        let [bx, by, bz] = self.scanner.nominal_boresight_deg.map(f64::to_radians);
        Ok(BoresightSetup {
            cos_leg_angles: self.tripod.leg_angles_deg.map(|a| a.to_radians().cos()),
            tripod_axis_n: axis.normalize(),
            r_nominal_s_to_b: r_zyx(bx, by, bz),
        })
    }
}
