//! Scenario files: the TOML description of a simulated survey, read strictly (unknown keys and
//! impossible values are refused with the dotted key named). Keys ending `_deg` are degrees
//! and are converted once here; everything else is SI. Every key, unit and default is listed
//! in docs/simulator.md.
//!
//! Modules: `scene`, `route` (route and vehicle), `sensors` (scanner and navigation errors);
//! the scenario as a whole, its origin and outputs here.

mod raw;
mod route;
mod scene;
mod sensors;

pub use raw::RawCfg;
pub use route::{RouteCfg, StopCfg, VehicleCfg};
pub use scene::{SceneCfg, SceneKind};
pub use sensors::{NavErrorCfg, NavErrorModel, ScannerCfg};

use super::checker::Checker;
use super::effects::Effects;
use crate::io::config_file;
use crate::Result;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A whole scenario, as read from its TOML file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Scenario name (recorded in the truth file).
    pub name: String,
    /// Master seed of every random stream.
    pub seed: u64,
    /// Length of the trajectory (s).
    pub duration_s: f64,
    /// GPS seconds of the week at the start of the trajectory (s).
    #[serde(default = "default_start_time")]
    pub start_time_s: f64,
    /// GPS week number, when the survey is to be tied to an absolute date.
    #[serde(default)]
    pub gps_week: Option<u32>,
    /// Origin of the local East-North-Up scene frame.
    pub origin: OriginCfg,
    /// Scene generator parameters.
    pub scene: SceneCfg,
    /// Route and speed profile.
    pub route: RouteCfg,
    /// Vehicle body dynamics and true-trajectory sampling.
    #[serde(default)]
    pub vehicle: VehicleCfg,
    /// Profile scanner.
    pub scanner: ScannerCfg,
    /// Random errors of the navigation solution.
    #[serde(default)]
    pub nav_errors: NavErrorCfg,
    /// Injected systematic effects (all off by default).
    #[serde(default)]
    pub effects: Effects,
    /// Optional outputs.
    #[serde(default)]
    pub output: OutputCfg,
    /// Raw IMU and GNSS records (written only when the table is present).
    #[serde(default)]
    pub raw: Option<RawCfg>,
}

fn default_start_time() -> f64 {
    345_600.0
}

/// Geodetic origin of the scene frame (WGS84, ellipsoidal height).
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OriginCfg {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Ellipsoidal height of the scene's ground at the origin (m).
    pub h_m: f64,
}

/// Optional outputs.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputCfg {
    /// Also write profiles as CSV (conventions §6); large.
    pub profiles_csv: bool,
    /// Write the per-return truth sidecar (24 bytes per return).
    pub truth_points: bool,
    /// Write the true trajectory as `truth.sbet`.
    pub truth_sbet: bool,
    /// A facade or ground patch is listed once it has this many returns.
    pub patch_min_returns: u32,
}

impl Default for OutputCfg {
    fn default() -> Self {
        OutputCfg {
            profiles_csv: false,
            truth_points: true,
            truth_sbet: true,
            patch_min_returns: 200,
        }
    }
}

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario> {
        let parsed = config_file::load::<Scenario>(path, &[])?;
        parsed.value.validate(&parsed.source)?;
        Ok(parsed.value)
    }

    /// Parses and validates scenario text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<Scenario> {
        let sc: Scenario = config_file::parse(text, source, Path::new("."), &[])?.value;
        sc.validate(source)?;
        Ok(sc)
    }

    /// Checks every value's range; `src` names the scenario in errors.
    pub(crate) fn validate(&self, src: &str) -> Result<()> {
        let mut c = Checker::new(src);
        c.pos("duration_s", self.duration_s);
        c.range("start_time_s", self.start_time_s, 0.0, 604_800.0);
        c.range("origin.lat_deg", self.origin.lat_deg, -89.0, 89.0);
        c.range("origin.lon_deg", self.origin.lon_deg, -180.0, 180.0);
        c.range("origin.h_m", self.origin.h_m, -1000.0, 9000.0);
        self.scene.check(&mut c);
        self.route.check(&mut c);
        self.vehicle.check(&mut c);
        self.scanner.check(&mut c);
        self.nav_errors.check(&mut c, self.vehicle.nav_rate_hz);
        self.effects.check(&mut c);
        if let Some(r) = &self.raw {
            r.check(&mut c, self.vehicle.nav_rate_hz);
        }
        if let Some(q) = self.effects.clock_drift_quadratic_per_s {
            c.test(
                "effects.clock_drift_quadratic_per_s",
                (2.0 * q * self.duration_s).abs() < 0.1,
                || {
                    format!(
                        "{q} 1/s over duration_s {} s would make the scanner clock run backwards",
                        self.duration_s
                    )
                },
            );
        }
        let s = &self.scanner;
        let scan_s = self.duration_s - s.t0_offset_s - s.end_margin_s;
        c.test("duration_s", scan_s > s.period_s, || {
            "too short: no complete profile between scanner.t0_offset_s and scanner.end_margin_s"
                .into()
        });
        c.done()
    }
}
