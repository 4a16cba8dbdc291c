//! `[sync]`: object-space time synchronisation before georeferencing (docs/sync.md).

use super::refusal::{refuse, require_positive, Refusal};
use super::sensor::TimeConfig;
use crate::io::config_file::ConfigPath;
use crate::timing::TimeModel;
use serde::{Deserialize, Serialize};

/// `[sync]`: estimate t0 and T (and optionally the attitude latency) from surveyed sync
/// targets before georeferencing; the estimates replace `time.t0_s` / `time.period_s`
/// (docs/sync.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyncConfig {
    /// Sync points (control-point CSV: target centres).
    pub points: ConfigPath,
    /// Target faces (patches CSV, ids as in `points`): needed by `method = "refined"`.
    #[serde(default)]
    pub targets: Option<ConfigPath>,
    /// Approximate t0 (s); default `time.t0_s`.
    #[serde(default)]
    pub t0_approx_s: Option<f64>,
    /// Approximate period (s); default `time.period_s`.
    #[serde(default)]
    pub period_approx_s: Option<f64>,
    /// Detection searches this far (s) either side of the predicted sighting.
    #[serde(default = "default_sync_window_s")]
    pub window_s: f64,
    /// `paper` (one observation per sighting), `refined` (every target return) or `auto`
    /// (`refined` where its sigma t0 beats the paper method's, else `paper`).
    #[serde(default = "default_sync_method")]
    pub method: crate::sync::Method,
    /// Estimate the attitude latency jointly (refined only; reported only if constrained).
    #[serde(default)]
    pub estimate_latency: bool,
    /// Returns at or above this intensity may belong to a target.
    #[serde(default = "default_sync_min_intensity")]
    pub min_intensity: u16,
    /// Targets further than this from the scanner are not looked for (m).
    #[serde(default = "default_sync_max_range_m")]
    pub max_range_m: f64,
    /// Range noise of the scanner, 1 sigma (m).
    #[serde(default = "default_sync_sigma_range_m")]
    pub sigma_range_m: f64,
    /// Mirror and cone angle noise, 1 sigma (deg).
    #[serde(default = "default_sync_sigma_angle_deg")]
    pub sigma_angle_deg: f64,
    /// Sightings must span at least this long (s).
    #[serde(default = "default_sync_min_span_s")]
    pub min_span_s: f64,
    /// Write the diagnostic PNGs beside the report.
    #[serde(default = "super::yes")]
    pub plots: bool,
}

fn default_sync_window_s() -> f64 {
    1.0
}
fn default_sync_method() -> crate::sync::Method {
    crate::sync::Method::Paper
}
fn default_sync_min_intensity() -> u16 {
    60000
}
fn default_sync_max_range_m() -> f64 {
    30.0
}
fn default_sync_sigma_range_m() -> f64 {
    0.005
}
fn default_sync_sigma_angle_deg() -> f64 {
    0.002
}
fn default_sync_min_span_s() -> f64 {
    30.0
}

impl SyncConfig {
    /// Checks the approximate clock (from here or `[time]`) and the detection settings.
    pub(super) fn check(&self, t: &TimeConfig) -> Result<(), Refusal> {
        if t.model != TimeModel::Software {
            return Err(refuse(
                "sync",
                "object-space sync estimates the software clock: needs time.model = \"software\"",
            ));
        }
        if !self.t0_approx_s.or(t.t0_s).is_some_and(f64::is_finite) {
            return Err(refuse(
                "sync.t0_approx_s",
                "an approximate t0 is needed (sync.t0_approx_s or time.t0_s)",
            ));
        }
        let checks = [
            ("sync.window_s", self.window_s),
            ("sync.max_range_m", self.max_range_m),
            ("sync.sigma_range_m", self.sigma_range_m),
            ("sync.sigma_angle_deg", self.sigma_angle_deg),
            ("sync.min_span_s", self.min_span_s),
            (
                "sync.period_approx_s",
                self.period_approx_s.unwrap_or(t.period_s),
            ),
        ];
        require_positive(checks)?;
        if self.estimate_latency && self.method == crate::sync::Method::Paper {
            return Err(refuse(
                "sync.estimate_latency",
                "the latency is estimated by method = \"refined\" or \"auto\" only",
            ));
        }
        Ok(())
    }
}
