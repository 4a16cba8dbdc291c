//! `[raw]`: the raw sensor records a van's INS/GNSS unit logs (IMU at the nav rate, GNSS
//! positions with sigmas, outages, outliers), for `kinescan trajectory` (docs/simulator.md).

use crate::sim::checker::Checker;
use serde::{Deserialize, Serialize};

/// Raw IMU and GNSS output of the simulator.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RawCfg {
    /// IMU grade: "tactical", "navigation" or "perfect" (`ins::imu_model::GRADES`).
    pub imu_grade: String,
    /// GNSS fix rate (Hz); must divide `vehicle.nav_rate_hz` (the IMU rate).
    pub gnss_rate_hz: f64,
    /// GNSS 1-sigma white noise north, east, down (m); written with each fix.
    pub gnss_sigma_m: [f64; 3],
    /// GNSS antenna phase centre relative to the IMU, body frame (m).
    pub antenna_lever_arm_b_m: [f64; 3],
    /// Share of the duration without GNSS (street canyons), in outages of `outage_length_s`
    /// spread evenly over the run.
    pub outage_share: f64,
    /// Length of each outage placed by `outage_share` (s).
    pub outage_length_s: f64,
    /// Further outages [start, end] (s from the start of the trajectory).
    pub outages_s: Vec<[f64; 2]>,
    /// Probability that a fix is an outlier (multipath).
    pub outlier_probability: f64,
    /// Size of an outlier: displacement in a random direction (m).
    pub outlier_m: f64,
}

impl Default for RawCfg {
    fn default() -> Self {
        RawCfg {
            imu_grade: "tactical".into(),
            gnss_rate_hz: 10.0,
            gnss_sigma_m: [0.02, 0.02, 0.02],
            antenna_lever_arm_b_m: [0.0, 0.0, -1.0],
            outage_share: 0.0,
            outage_length_s: 30.0,
            outages_s: Vec::new(),
            outlier_probability: 0.0,
            outlier_m: 5.0,
        }
    }
}

impl RawCfg {
    /// Checks every value's range against the IMU rate `rate_hz`.
    pub(crate) fn check(&self, c: &mut Checker, rate_hz: f64) {
        let grades = crate::ins::imu_model::GRADES;
        c.test(
            "raw.imu_grade",
            grades.contains(&self.imu_grade.as_str()),
            || format!("must be one of {grades:?}, got {:?}", self.imu_grade),
        );
        c.test("vehicle.nav_rate_hz", rate_hz <= 500.0, || {
            format!("is the IMU rate with [raw]: at most 500 Hz, got {rate_hz}")
        });
        let ratio = rate_hz / self.gnss_rate_hz;
        c.test(
            "raw.gnss_rate_hz",
            (1.0..=10.0).contains(&self.gnss_rate_hz) && (ratio - ratio.round()).abs() < 1e-9,
            || {
                format!(
                    "must be 1..10 Hz and divide vehicle.nav_rate_hz ({rate_hz}), got {}",
                    self.gnss_rate_hz
                )
            },
        );
        for (i, s) in self.gnss_sigma_m.iter().enumerate() {
            c.range(&format!("raw.gnss_sigma_m[{i}]"), *s, 1e-4, 100.0);
        }
        c.finite("raw.antenna_lever_arm_b_m", &self.antenna_lever_arm_b_m);
        c.test(
            "raw.antenna_lever_arm_b_m",
            self.antenna_lever_arm_b_m.iter().all(|v| v.abs() <= 10.0),
            || "each component must be within +-10 m".into(),
        );
        c.range("raw.outage_share", self.outage_share, 0.0, 0.9);
        c.range("raw.outage_length_s", self.outage_length_s, 0.1, 3600.0);
        for (i, o) in self.outages_s.iter().enumerate() {
            c.test(
                &format!("raw.outages_s[{i}]"),
                o[0] >= 0.0 && o[1] > o[0],
                || format!("must be [start, end] with 0 <= start < end, got {o:?}"),
            );
        }
        c.range(
            "raw.outlier_probability",
            self.outlier_probability,
            0.0,
            0.5,
        );
        c.range("raw.outlier_m", self.outlier_m, 0.0, 1000.0);
    }

    /// Every outage [start, end] (s from the start), `outage_share` of `duration_s` placed
    /// evenly first, then `outages_s`.
    pub fn outages(&self, duration_s: f64) -> Vec<[f64; 2]> {
        let n = (self.outage_share * duration_s / self.outage_length_s).round() as usize;
        let mut out: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let c = (i as f64 + 0.5) / n as f64 * duration_s;
                [
                    c - 0.5 * self.outage_length_s,
                    c + 0.5 * self.outage_length_s,
                ]
            })
            .collect();
        out.extend(self.outages_s.iter().copied());
        out
    }
}
