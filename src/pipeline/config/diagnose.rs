//! `[diagnose]`: the options of `kinescan diagnose` (docs/diagnosis.md).

use super::refusal::{refuse, require_positive, Refusal};
use crate::io::config_file::ConfigPath;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

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
    /// Variance of the white position noise per trajectory record (shared by the returns
    /// between the same records), as a share of the median SMRMSG position variance. Absent:
    /// estimated.
    #[serde(default)]
    pub nav_position_white_share: Option<f64>,
    /// Variance of the white attitude noise per trajectory record, as a share of the median
    /// SMRMSG attitude variance. Absent: estimated.
    #[serde(default)]
    pub nav_attitude_white_share: Option<f64>,
    /// Variance of a second, slow position error process, as a share of the SMRMSG position
    /// variance (docs/diagnosis.md, "Two time scales"); 0: no second process. Absent:
    /// estimated on a survey long enough to tell, used where the data need it.
    #[serde(default)]
    pub nav_position_slow_share: Option<f64>,
    /// Variance of a second, slow attitude error process, as a share of the SMRMSG attitude
    /// variance; 0: none. Absent: estimated.
    #[serde(default)]
    pub nav_attitude_slow_share: Option<f64>,
    /// Correlation time of the slow position error process (s). Absent: estimated.
    #[serde(default)]
    pub nav_position_slow_tau_s: Option<f64>,
    /// Correlation time of the slow attitude error process (s). Absent: estimated.
    #[serde(default)]
    pub nav_attitude_slow_tau_s: Option<f64>,
    /// The navigation error model that `kinescan trajectory` exported with the SBET
    /// (`output.error_model`, docs/trajectory.md): where the keys above are absent, the
    /// correlation times are fitted to its autocorrelation ([`fit_correlation_time`]), the
    /// scales are 1 (the SMRMSG is that smoother's own sigma) and the white and slow shares 0
    /// (its model has no white term and one process per component). Absent: nothing is
    /// filled.
    #[serde(default)]
    pub nav_error_model: Option<ConfigPath>,
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
    /// At most this many returns on patches are kept over the survey (the observations, about
    /// 330 B each, are the diagnosis' largest allocation): beyond it every visit keeps fewer,
    /// evenly spaced, down to `min_per_visit`, and then visits are left out evenly (each
    /// reference's over the whole survey). Memory stays flat with the survey's length.
    #[serde(default = "default_max_observations")]
    pub max_observations: usize,
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
/// Position (north, east, down) and attitude (roll, pitch, heading) components of the error
/// model file.
const POSITION_COMPONENTS: [&str; 3] = ["north_m", "east_m", "down_m"];
const ATTITUDE_COMPONENTS: [&str; 3] = ["roll_rad", "pitch_rad", "heading_rad"];

/// The position and attitude correlation times (s) of an error-model file of `kinescan
/// trajectory` (`components`, `lags_s`, `rho`, `pairs`).
pub fn read_nav_error_model(path: &Path) -> Result<[f64; 2]> {
    let key = "diagnose.nav_error_model";
    let bad = |what: String| Error::bad_file(path, format!("{what} (the file of {key})"));
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let v: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| {
        bad(format!(
            "not JSON ({e}): expected the error model of kinescan trajectory"
        ))
    })?;
    let numbers = |x: &serde_json::Value| -> Option<Vec<f64>> {
        // A NaN correlation is written as null: it is left out (as NaN).
        x.as_array()
            .map(|a| a.iter().map(|y| y.as_f64().unwrap_or(f64::NAN)).collect())
    };
    let lags = numbers(&v["lags_s"]).ok_or_else(|| bad("no lags_s array".into()))?;
    let pairs = numbers(&v["pairs"]).ok_or_else(|| bad("no pairs array".into()))?;
    let names: Vec<&str> = v["components"]
        .as_array()
        .map(|a| a.iter().filter_map(|c| c.as_str()).collect())
        .ok_or_else(|| bad("no components array".into()))?;
    let rho = v["rho"]
        .as_array()
        .ok_or_else(|| bad("no rho array".into()))?;
    let tau = |group: [&str; 3]| -> Result<f64> {
        let mut series = Vec::new();
        for c in group {
            let k = names
                .iter()
                .position(|n| *n == c)
                .ok_or_else(|| bad(format!("no component {c}")))?;
            let r = rho
                .get(k)
                .and_then(numbers)
                .filter(|r| r.len() == lags.len());
            let r = r.ok_or_else(|| bad(format!("rho[{k}] ({c}) missing or not one per lag")))?;
            series.push(r);
        }
        let used: Vec<(f64, [f64; 3])> = (0..lags.len())
            .filter(|&l| pairs.get(l).is_some_and(|p| *p > 0.0))
            .map(|l| (lags[l], [series[0][l], series[1][l], series[2][l]]))
            .collect();
        fit_correlation_time(&used).ok_or_else(|| {
            bad(format!(
                "no correlation time fits {group:?}: too few lags with pairs (a run shorter \
                 than a few GNSS epochs?)"
            ))
        })
    };
    Ok([tau(POSITION_COMPONENTS)?, tau(ATTITUDE_COMPONENTS)?])
}

/// The correlation time `tau` (s) of a first-order Gauss-Markov process whose
/// autocorrelation `exp(-lag / tau)` fits the components' correlations best (least squares
/// over every lag and component, finite values of lags > 0 only; golden-section search on
/// `ln tau` between a tenth of the shortest lag and ten times the longest). None with fewer
/// than two usable lags.
pub fn fit_correlation_time(lags: &[(f64, [f64; 3])]) -> Option<f64> {
    let used: Vec<(f64, Vec<f64>)> = lags
        .iter()
        .filter(|(l, _)| l.is_finite() && *l > 0.0)
        .map(|(l, r)| (*l, r.iter().copied().filter(|x| x.is_finite()).collect()))
        .filter(|(_, r): &(f64, Vec<f64>)| !r.is_empty())
        .collect();
    if used.len() < 2 {
        return None;
    }
    let cost = |ln_tau: f64| -> f64 {
        let tau = ln_tau.exp();
        used.iter()
            .map(|(l, r)| {
                let m = (-l / tau).exp();
                r.iter().map(|x| (x - m).powi(2)).sum::<f64>()
            })
            .sum()
    };
    let lo_lag = used.iter().map(|u| u.0).fold(f64::INFINITY, f64::min);
    let hi_lag = used.iter().map(|u| u.0).fold(0.0, f64::max);
    let (mut a, mut b) = ((lo_lag / 10.0).ln(), (hi_lag * 10.0).ln());
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (cost(c), cost(d));
    while b - a > 1e-9 {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = cost(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = cost(d);
        }
    }
    Some((0.5 * (a + b)).exp())
}

fn default_max_foreign_share() -> f64 {
    0.25
}
fn default_min_per_visit() -> usize {
    20
}
fn default_max_per_visit() -> usize {
    400
}
fn default_max_observations() -> usize {
    250_000
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
    /// Fills the absent navigation error keys from `nav_error_model` (when given).
    pub(super) fn resolve_nav_error_model(&mut self) -> Result<()> {
        let Some(path) = &self.nav_error_model else {
            return Ok(());
        };
        let [position, attitude] = read_nav_error_model(path)?;
        self.nav_position_tau_s.get_or_insert(position);
        self.nav_attitude_tau_s.get_or_insert(attitude);
        self.nav_position_scale.get_or_insert(1.0);
        self.nav_attitude_scale.get_or_insert(1.0);
        // The smoother's own model has no white term and one process per component.
        self.nav_position_white_share.get_or_insert(0.0);
        self.nav_attitude_white_share.get_or_insert(0.0);
        self.nav_position_slow_share.get_or_insert(0.0);
        self.nav_attitude_slow_share.get_or_insert(0.0);
        Ok(())
    }

    /// Checks tolerances, correlation times and visit sizes.
    pub(super) fn check(&self) -> std::result::Result<(), Refusal> {
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
            (
                "diagnose.nav_position_slow_tau_s",
                self.nav_position_slow_tau_s,
            ),
            (
                "diagnose.nav_attitude_slow_tau_s",
                self.nav_attitude_slow_tau_s,
            ),
        ];
        require_positive(optional.into_iter().filter_map(|(k, v)| Some((k, v?))))?;
        for (key, v) in [
            (
                "diagnose.nav_position_white_share",
                self.nav_position_white_share,
            ),
            (
                "diagnose.nav_attitude_white_share",
                self.nav_attitude_white_share,
            ),
            (
                "diagnose.nav_position_slow_share",
                self.nav_position_slow_share,
            ),
            (
                "diagnose.nav_attitude_slow_share",
                self.nav_attitude_slow_share,
            ),
        ] {
            if let Some(v) = v.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(refuse(key, format!("must be >= 0, got {v}")));
            }
        }
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
        if self.max_observations < self.min_per_visit {
            let problem = format!(
                "must be at least min_per_visit ({}), got {}",
                self.min_per_visit, self.max_observations
            );
            return Err(refuse("diagnose.max_observations", problem));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A file with exponential correlations gives back their correlation times; the scales
    /// are 1; a key given in the file wins; a missing file is named with the key.
    #[test]
    fn nav_error_model_fills_the_absent_keys() {
        let dir = tempfile::tempdir().unwrap();
        let lags = [0.1, 0.3, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0];
        let rho = |tau: f64| lags.map(|l: f64| (-l / tau).exp()).to_vec();
        let model = serde_json::json!({
            "components": ["north_m", "east_m", "down_m", "vel_north_mps", "vel_east_mps",
                           "vel_down_mps", "roll_rad", "pitch_rad", "heading_rad"],
            "lags_s": lags,
            "rho": [rho(7.0), rho(7.0), rho(7.0), rho(1.0), rho(1.0), rho(1.0),
                    rho(30.0), rho(30.0), rho(30.0)],
            "pairs": vec![4; 8],
        });
        let path = dir.path().join("m.error_model.json");
        std::fs::write(&path, model.to_string()).unwrap();
        let [p, a] = read_nav_error_model(&path).unwrap();
        // The golden-section search stops at 1e-9 in ln tau.
        assert!(
            (p - 7.0).abs() <= 1e-6 && (a - 30.0).abs() <= 1e-6,
            "{p} {a}"
        );
        let mut cfg: DiagnoseConfig = toml::from_str(&format!(
            "nav_error_model = {:?}\nnav_attitude_tau_s = 12.0",
            path.display().to_string()
        ))
        .unwrap();
        cfg.resolve_nav_error_model().unwrap();
        let got = (
            cfg.nav_position_tau_s,
            cfg.nav_attitude_tau_s,
            cfg.nav_position_scale,
            cfg.nav_attitude_scale,
        );
        assert!(got.0.is_some_and(|t| (t - 7.0).abs() <= 1e-6), "{got:?}");
        assert_eq!((got.1, got.2, got.3), (Some(12.0), Some(1.0), Some(1.0)));
        let missing = dir.path().join("none.json");
        let err = read_nav_error_model(&missing).unwrap_err().to_string();
        assert!(err.contains("none.json"), "{err}");
        std::fs::write(&path, "{}").unwrap();
        let err = read_nav_error_model(&path).unwrap_err().to_string();
        assert!(
            err.contains("diagnose.nav_error_model") && err.contains("lags_s"),
            "{err}"
        );
    }
}
