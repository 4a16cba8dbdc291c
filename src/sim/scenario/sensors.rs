//! The simulated instruments: `[scanner]` and `[nav_errors]` (what the INS gets wrong).

use crate::sim::checker::Checker;
use serde::{Deserialize, Serialize};

/// Profile scanner: mounting, mirror, clock and measurement noise.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScannerCfg {
    /// Mirror period T (s), 1/250 .. 1/33.
    pub period_s: f64,
    /// Returns per profile (mirror turn).
    pub points_per_profile: u32,
    /// Mirror angle where the profile counter increments (deg).
    pub beta_start_deg: f64,
    /// +1 when beta increases with time, -1 otherwise.
    pub direction: i32,
    /// Out-of-plane (cone) angle alpha0 (deg).
    pub alpha0_deg: f64,
    /// Longest range measured (m).
    pub max_range_m: f64,
    /// Shortest range measured (m).
    pub min_range_m: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Mirror (beta) and cone (alpha) angle noise, 1 sigma (deg).
    pub sigma_angle_deg: f64,
    /// Probability that a return is lost at random.
    pub dropout_probability: f64,
    /// Range at which intensity stops growing as range shrinks (m).
    pub intensity_ref_range_m: f64,
    /// Lever arm, scanner optical centre relative to the IMU, body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (bx, by, bz) of `R_s^b = Rz(bz) Ry(by) Rx(bx)` (deg).
    pub boresight_deg: [f64; 3],
    /// Range zero error K of the scanner (m), known to the pipeline.
    pub range_zero_m: f64,
    /// Start of profile 0 relative to the start of the trajectory (s).
    pub t0_offset_s: f64,
    /// Stop scanning this long before the trajectory ends (s).
    pub end_margin_s: f64,
    /// Write each profile's PPS-derived GPS start time in the returns' time column.
    pub pps_time_tags: bool,
}

impl Default for ScannerCfg {
    fn default() -> Self {
        ScannerCfg {
            period_s: 0.01,
            points_per_profile: 1000,
            beta_start_deg: 0.0,
            direction: 1,
            alpha0_deg: 0.0,
            max_range_m: 80.0,
            min_range_m: 0.5,
            sigma_range_m: 0.0,
            sigma_angle_deg: 0.0,
            dropout_probability: 0.0,
            intensity_ref_range_m: 10.0,
            lever_arm_b_m: [-0.5, 0.0, -0.4],
            boresight_deg: [0.0, 0.0, 0.0],
            range_zero_m: 0.0,
            t0_offset_s: 1.0,
            end_margin_s: 1.0,
            pps_time_tags: false,
        }
    }
}

/// The random process of every navigation error component (docs/simulator.md, "Navigation
/// errors").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NavErrorModel {
    /// One first-order Gauss-Markov process (`position_tau_s`, `attitude_tau_s`).
    #[default]
    GaussMarkov,
    /// A random walk started at zero plus white noise (`white_share` of the variance white).
    RandomWalkWhite,
    /// The sum of two independent Gauss-Markov processes (`*_tau_s` and `*_tau2_s`,
    /// `second_share` of the variance in the second).
    TwoGaussMarkov,
}

/// Random navigation errors: a process per axis (first-order Gauss-Markov by default).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct NavErrorCfg {
    /// Process of every component.
    pub model: NavErrorModel,
    /// Position error sigma north, east, down (m).
    pub position_sigma_m: [f64; 3],
    /// Position error correlation time (s).
    pub position_tau_s: f64,
    /// Attitude error sigma roll, pitch, heading (deg).
    pub attitude_sigma_deg: [f64; 3],
    /// Attitude error correlation time (s).
    pub attitude_tau_s: f64,
    /// GNSS outages [start, end] relative to the start of the trajectory (s).
    pub outages_s: Vec<[f64; 2]>,
    /// Factor on every sigma inside outages.
    pub outage_sigma_factor: f64,
    /// Velocity RMS written to SMRMSG (m/s); velocities carry no injected error.
    pub velocity_sigma_mps: f64,
    /// SMRMSG record rate (Hz); must divide the nav rate.
    pub smrmsg_rate_hz: f64,
    /// `random_walk_white`: share of the variance that is white noise (0..1).
    pub white_share: f64,
    /// `two_gauss_markov`: correlation time of the second position process (s).
    pub position_tau2_s: f64,
    /// `two_gauss_markov`: correlation time of the second attitude process (s).
    pub attitude_tau2_s: f64,
    /// `two_gauss_markov`: share of the variance in the second process (0..1).
    pub second_share: f64,
    /// The SMRMSG states this factor times the true sigma (the errors are unchanged).
    pub smrmsg_factor: f64,
    /// Write the SBET's body acceleration and angular-rate fields as zero.
    pub zero_rate_fields: bool,
}

impl Default for NavErrorCfg {
    fn default() -> Self {
        NavErrorCfg {
            model: NavErrorModel::GaussMarkov,
            position_sigma_m: [0.0; 3],
            position_tau_s: 60.0,
            attitude_sigma_deg: [0.0; 3],
            attitude_tau_s: 30.0,
            outages_s: Vec::new(),
            outage_sigma_factor: 5.0,
            velocity_sigma_mps: 0.01,
            smrmsg_rate_hz: 10.0,
            white_share: 0.3,
            position_tau2_s: 600.0,
            attitude_tau2_s: 300.0,
            second_share: 0.5,
            smrmsg_factor: 1.0,
            zero_rate_fields: false,
        }
    }
}

impl NavErrorCfg {
    /// True when every key added with the error family (model, shares, second correlation
    /// times, SMRMSG factor, zero rate fields) is at its default: the survey is today's.
    pub fn is_plain(&self) -> bool {
        let d = NavErrorCfg::default();
        self.model == d.model
            && self.white_share == d.white_share
            && self.position_tau2_s == d.position_tau2_s
            && self.attitude_tau2_s == d.attitude_tau2_s
            && self.second_share == d.second_share
            && self.smrmsg_factor == d.smrmsg_factor
            && self.zero_rate_fields == d.zero_rate_fields
    }
}

impl ScannerCfg {
    /// Checks every value's range.
    pub(super) fn check(&self, c: &mut Checker) {
        c.range(
            "scanner.period_s",
            self.period_s,
            1.0 / 250.0 - 1e-12,
            1.0 / 33.0 + 1e-12,
        );
        c.test(
            "scanner.points_per_profile",
            (1..=100_000).contains(&self.points_per_profile),
            || format!("must be 1..=100000, got {}", self.points_per_profile),
        );
        c.finite("scanner.beta_start_deg", &[self.beta_start_deg]);
        c.test("scanner.direction", self.direction.abs() == 1, || {
            format!("must be +1 or -1, got {}", self.direction)
        });
        c.range("scanner.alpha0_deg", self.alpha0_deg, -45.0, 45.0);
        c.range("scanner.max_range_m", self.max_range_m, 1.0, 5000.0);
        c.range(
            "scanner.min_range_m",
            self.min_range_m,
            0.0,
            self.max_range_m.max(0.0),
        );
        c.range("scanner.sigma_range_m", self.sigma_range_m, 0.0, 1.0);
        c.range("scanner.sigma_angle_deg", self.sigma_angle_deg, 0.0, 1.0);
        c.range(
            "scanner.dropout_probability",
            self.dropout_probability,
            0.0,
            1.0,
        );
        c.pos("scanner.intensity_ref_range_m", self.intensity_ref_range_m);
        c.finite("scanner.lever_arm_b_m", &self.lever_arm_b_m);
        c.test(
            "scanner.lever_arm_b_m",
            self.lever_arm_b_m.iter().all(|v| v.abs() < 10.0),
            || {
                format!(
                    "each component must be within +-10 m, got {:?}",
                    self.lever_arm_b_m
                )
            },
        );
        c.finite("scanner.boresight_deg", &self.boresight_deg);
        c.range("scanner.range_zero_m", self.range_zero_m, -10.0, 10.0);
        c.nonneg("scanner.t0_offset_s", self.t0_offset_s);
        c.nonneg("scanner.end_margin_s", self.end_margin_s);
    }
}

impl NavErrorCfg {
    /// Checks every value's range.
    pub(super) fn check(&self, c: &mut Checker, nav_rate_hz: f64) {
        for (i, v) in self.position_sigma_m.iter().enumerate() {
            c.range(&format!("nav_errors.position_sigma_m[{i}]"), *v, 0.0, 100.0);
        }
        for (i, v) in self.attitude_sigma_deg.iter().enumerate() {
            c.range(
                &format!("nav_errors.attitude_sigma_deg[{i}]"),
                *v,
                0.0,
                10.0,
            );
        }
        c.pos("nav_errors.position_tau_s", self.position_tau_s);
        c.pos("nav_errors.attitude_tau_s", self.attitude_tau_s);
        c.range("nav_errors.white_share", self.white_share, 0.0, 1.0);
        c.pos("nav_errors.position_tau2_s", self.position_tau2_s);
        c.pos("nav_errors.attitude_tau2_s", self.attitude_tau2_s);
        c.range("nav_errors.second_share", self.second_share, 0.0, 1.0);
        c.range("nav_errors.smrmsg_factor", self.smrmsg_factor, 0.3, 3.0);
        for (i, o) in self.outages_s.iter().enumerate() {
            c.test(
                &format!("nav_errors.outages_s[{i}]"),
                o[0] >= 0.0 && o[1] > o[0],
                || format!("must be [start, end] with 0 <= start < end, got {o:?}"),
            );
        }
        c.range(
            "nav_errors.outage_sigma_factor",
            self.outage_sigma_factor,
            1.0,
            1000.0,
        );
        c.nonneg("nav_errors.velocity_sigma_mps", self.velocity_sigma_mps);
        let ratio = nav_rate_hz / self.smrmsg_rate_hz;
        c.test(
            "nav_errors.smrmsg_rate_hz",
            self.smrmsg_rate_hz > 0.0 && (ratio - ratio.round()).abs() < 1e-9 && ratio >= 1.0,
            || {
                format!(
                    "must divide vehicle.nav_rate_hz ({nav_rate_hz}), got {}",
                    self.smrmsg_rate_hz
                )
            },
        );
    }
}
