//! What [`super::estimate`] returns: the sightings, the clock estimates and their quality.

use super::geometry::TargetReturn;
use super::hardware::HardwareComparison;
use super::options::Method;
use nalgebra::Matrix2;
use serde::Serialize;

/// What became of a predicted pass over a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SightingStatus {
    /// Used in the fit.
    Accepted,
    /// Detected but inconsistent with the others (false target or wrong cluster).
    Outlier,
    /// No high-intensity cluster in the search window.
    NotFound,
}

/// One predicted pass over a sync target and its detection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sighting {
    /// Target id.
    pub target: String,
    /// Pass over this target, from 1, in route order.
    pub pass: u32,
    /// Plane-crossing time from the trajectory (s).
    pub crossing_time_s: f64,
    /// Range to the target at the crossing (m).
    pub range_m: f64,
    /// Profile where the approximate clock puts the crossing.
    pub predicted_profile: f64,
    /// Clusters found in the search window.
    pub candidates: usize,
    /// Sighting profile `n_i` (rounded mean profile of the chosen cluster).
    pub profile: Option<u32>,
    /// Mean mirror angle of the chosen cluster (deg).
    pub beta_deg: Option<f64>,
    /// `n_i + f(beta_i)`: where in the profile sequence the sighting lies (profiles).
    pub profile_position: Option<f64>,
    /// Returns in the chosen cluster.
    pub returns_count: usize,
    /// Residual of the crossing time against the paper fit (s).
    pub residual_s: Option<f64>,
    /// Residual / its sigma.
    pub normalised_residual: Option<f64>,
    /// 1-sigma of the observation (quantisation, navigation, survey) (s).
    pub sigma_s: f64,
    /// Outcome.
    pub status: SightingStatus,
    /// The chosen cluster's returns (not serialised).
    #[serde(skip)]
    pub returns: Vec<TargetReturn>,
    /// Of those, the front-face returns the refined estimator used (not serialised).
    #[serde(skip)]
    pub refined_returns: Vec<TargetReturn>,
}

/// An estimate of (t0, T) with its covariance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ClockEstimate {
    /// GPS time of the start of profile 0 (s).
    pub t0_s: f64,
    /// Mirror period (s).
    pub period_s: f64,
    /// 1-sigma of t0 (s).
    pub sigma_t0_s: f64,
    /// 1-sigma of T (s).
    pub sigma_period_s: f64,
    /// Covariance of (t0, T): [[s^2, s^2], [s^2, s^2]].
    pub cov_t0_period: [[f64; 2]; 2],
    /// Correlation of t0 and T.
    pub correlation: f64,
    /// Sum of squared normalised residuals.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
}

impl ClockEstimate {
    pub(super) fn new(t0_s: f64, period_s: f64, cov: &Matrix2<f64>, chi2: f64, dof: usize) -> Self {
        let (s0, s1) = (cov[(0, 0)].sqrt(), cov[(1, 1)].sqrt());
        ClockEstimate {
            t0_s,
            period_s,
            sigma_t0_s: s0,
            sigma_period_s: s1,
            cov_t0_period: [[cov[(0, 0)], cov[(0, 1)]], [cov[(1, 0)], cov[(1, 1)]]],
            correlation: cov[(0, 1)] / (s0 * s1),
            chi2,
            dof,
        }
    }

    /// Covariance of (t0, T) as a matrix.
    pub fn cov(&self) -> Matrix2<f64> {
        let c = self.cov_t0_period;
        Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1])
    }
}

/// The refined estimate and what the data constrain.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinedEstimate {
    /// (t0, T) and covariance.
    pub clock: ClockEstimate,
    /// Attitude latency (s), when estimated and constrained.
    pub attitude_latency_s: Option<f64>,
    /// Its 1-sigma (s).
    pub sigma_attitude_latency_s: Option<f64>,
    /// Why the latency is not reported, when it was asked for but is not constrained.
    pub latency_note: Option<String>,
    /// Parameters of the final fit, in order.
    pub parameters: Vec<String>,
    /// Correlation matrix of the parameters.
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the unit-diagonal information matrix.
    pub condition_number: f64,
    /// Variance inflation factor of each parameter.
    pub variance_inflation: Vec<f64>,
    /// Returns used.
    pub returns_used: usize,
}

/// Result of [`super::estimate`]: the answer (per `method`) and everything behind it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SyncResult {
    /// Method of the answer (`paper` or `refined`; with `auto`, the one chosen).
    pub method: Method,
    /// With `method = "auto"` and the paper method's answer: why the refined estimator was not
    /// used (its refusal, with its sigma t0 against the paper's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fallback: Option<String>,
    /// The answer: t0, T and their covariance (feeds georeferencing and uncertainty).
    pub clock: ClockEstimate,
    /// Attitude latency (s) when estimated and constrained.
    pub attitude_latency_s: Option<f64>,
    /// Its 1-sigma (s).
    pub sigma_attitude_latency_s: Option<f64>,
    /// The paper's method.
    pub paper: ClockEstimate,
    /// The refined estimator, when asked for.
    pub refined: Option<RefinedEstimate>,
    /// Every predicted pass and its detection.
    pub sightings: Vec<Sighting>,
    /// Hardware (PPS) comparison, when the profiles carry time tags.
    pub hardware: Option<HardwareComparison>,
}
