//! `[diagnose]`: the options of `kinescan diagnose` (docs/diagnosis.md).

use super::refusal::{refuse, require_positive, Refusal};
use crate::io::config_file::ConfigPath;
use serde::{Deserialize, Serialize};

/// `[diagnose]`: what `kinescan diagnose` reads and how it turns returns on reference patches
/// into observations (docs/diagnosis.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiagnoseConfig {
    /// Reference planar patches (patch CSV).
    #[serde(default)]
    pub patches: Option<ConfigPath>,
    /// Control points (control-point CSV: target face centres), optional references found by
    /// intensity (docs/diagnosis.md, "Control points").
    #[serde(default)]
    pub control_points: Option<ConfigPath>,
    /// Output folder of the diagnosis.
    #[serde(default)]
    pub out: Option<ConfigPath>,
    /// A return further than this from its patch plane is not an observation (m).
    #[serde(default = "default_plane_tolerance_m")]
    pub plane_tolerance_m: f64,
    /// Returns closer than this to a patch edge are left out (m).
    #[serde(default = "default_edge_margin_m")]
    pub edge_margin_m: f64,
    /// A gap longer than this between two returns on one patch starts a new visit (s).
    #[serde(default = "default_visit_gap_s")]
    pub visit_gap_s: f64,
    /// A visit longer than this is split (s): one visit shares one navigation error.
    #[serde(default = "default_max_visit_s")]
    pub max_visit_s: f64,
    /// Correlation time of the INS position errors (s): first-order Gauss-Markov in time,
    /// within and between visits (docs/diagnosis.md, "The residual model"). Absent: estimated
    /// from the survey (docs/diagnosis.md, "The nuisance").
    #[serde(default)]
    pub nav_position_tau_s: Option<f64>,
    /// Correlation time of the INS attitude errors (s). Absent: estimated.
    #[serde(default)]
    pub nav_attitude_tau_s: Option<f64>,
    /// True / SMRMSG sigma of the INS position errors. Absent: estimated.
    #[serde(default)]
    pub nav_position_scale: Option<f64>,
    /// True / SMRMSG sigma of the INS attitude errors. Absent: estimated.
    #[serde(default)]
    pub nav_attitude_scale: Option<f64>,
    /// A reference with more than this share of its returns set aside as foreign is reported
    /// and not used (docs/diagnosis.md, "Foreign returns").
    #[serde(default = "default_max_foreign_share")]
    pub max_foreign_share: f64,
    /// Visits with fewer returns are left out.
    #[serde(default = "default_min_per_visit")]
    pub min_per_visit: usize,
    /// At most this many returns of a visit are kept, evenly spaced in time.
    #[serde(default = "default_max_per_visit")]
    pub max_per_visit: usize,
    /// A return at least this bright (raw intensity) within `target_radius_m` of a control
    /// point is a return on its target.
    #[serde(default = "default_target_min_intensity")]
    pub target_min_intensity: u16,
    /// Search radius about a control point for its target's returns (m).
    #[serde(default = "default_target_radius_m")]
    pub target_radius_m: f64,
    /// Target visits with fewer returns are left out.
    #[serde(default = "default_target_min_returns")]
    pub target_min_returns: usize,
    /// A target visit whose returns lie further than this (rms, m) from their best plane is not
    /// a flat target and is left out.
    #[serde(default = "default_target_flatness_m")]
    pub target_flatness_m: f64,
    /// Seed of the split of the references into fit and held-out halves.
    #[serde(default = "default_diagnose_seed")]
    pub seed: u64,
    /// Family-wise significance level of the effect tests (Holm).
    #[serde(default = "default_diagnose_alpha")]
    pub alpha: f64,
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

fn default_plane_tolerance_m() -> f64 {
    0.15
}
fn default_edge_margin_m() -> f64 {
    0.1
}
fn default_visit_gap_s() -> f64 {
    1.0
}
fn default_max_visit_s() -> f64 {
    5.0
}
/// Where the search for the correlation times starts when they are estimated (s).
pub const START_NAV_TAU_S: [f64; 2] = [60.0, 30.0];
fn default_max_foreign_share() -> f64 {
    0.25
}
fn default_min_per_visit() -> usize {
    20
}
fn default_max_per_visit() -> usize {
    400
}
fn default_target_min_intensity() -> u16 {
    60000
}
fn default_target_radius_m() -> f64 {
    0.5
}
fn default_target_min_returns() -> usize {
    8
}
fn default_target_flatness_m() -> f64 {
    0.02
}
fn default_diagnose_seed() -> u64 {
    1
}
fn default_diagnose_alpha() -> f64 {
    0.01
}

impl DiagnoseConfig {
    /// Checks tolerances, correlation times and visit sizes.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        let positive = [
            ("diagnose.plane_tolerance_m", self.plane_tolerance_m),
            ("diagnose.visit_gap_s", self.visit_gap_s),
            ("diagnose.max_visit_s", self.max_visit_s),
            ("diagnose.target_radius_m", self.target_radius_m),
            ("diagnose.target_flatness_m", self.target_flatness_m),
        ];
        require_positive(positive)?;
        let optional = [
            ("diagnose.nav_position_tau_s", self.nav_position_tau_s),
            ("diagnose.nav_attitude_tau_s", self.nav_attitude_tau_s),
            ("diagnose.nav_position_scale", self.nav_position_scale),
            ("diagnose.nav_attitude_scale", self.nav_attitude_scale),
        ];
        require_positive(optional.into_iter().filter_map(|(k, v)| Some((k, v?))))?;
        if !(self.edge_margin_m.is_finite() && self.edge_margin_m >= 0.0) {
            let v = self.edge_margin_m;
            return Err(refuse(
                "diagnose.edge_margin_m",
                format!("must be >= 0, got {v}"),
            ));
        }
        if !(self.max_foreign_share > 0.0 && self.max_foreign_share <= 1.0) {
            let v = self.max_foreign_share;
            return Err(refuse(
                "diagnose.max_foreign_share",
                format!("must be in (0, 1], got {v}"),
            ));
        }
        if self.min_per_visit < 2 || self.max_per_visit < self.min_per_visit {
            let problem = format!(
                "need 2 <= min_per_visit <= max_per_visit, got {} and {}",
                self.min_per_visit, self.max_per_visit
            );
            return Err(refuse("diagnose.max_per_visit", problem));
        }
        if self.target_min_returns < 3 {
            let problem = format!("must be >= 3, got {}", self.target_min_returns);
            return Err(refuse("diagnose.target_min_returns", problem));
        }
        if !(self.alpha > 0.0 && self.alpha < 0.5) {
            let v = self.alpha;
            return Err(refuse(
                "diagnose.alpha",
                format!("must be in (0, 0.5), got {v}"),
            ));
        }
        Ok(())
    }
}
