//! The scanner: `[sensor]` (mounting, intrinsics, range limits), `[time]` (its clock) and
//! `[latency]` (IMU-to-scanner latencies).

use super::refusal::{elements, refuse, require_finite, Refusal};
use crate::timing::{MirrorDirection, TimeModel};
use serde::{Deserialize, Serialize};

/// `[sensor]`: lever arm, boresight, scanner intrinsics and range limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Scanner optical centre relative to the IMU origin in the body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (bx, by, bz) (deg): `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    #[serde(default)]
    pub boresight_deg: [f64; 3],
    /// Out-of-plane beam angle alpha0 (deg), used when a profile file has no alpha column.
    #[serde(default)]
    pub alpha0_deg: f64,
    /// Range zero error K (m), added to every range.
    #[serde(default)]
    pub range_zero_m: f64,
    /// Range scale error S (ppm): `x_s = (1 + S 1e-6) (rho + K) u_s` (docs/conventions.md §3).
    #[serde(default)]
    pub range_scale_ppm: f64,
    /// Encoder offset dbeta (deg), added to the recorded mirror angle everywhere it is used:
    /// the beam direction and the time model's `f(beta)` (docs/conventions.md §2-3).
    #[serde(default)]
    pub encoder_offset_deg: f64,
    /// Returns closer than this are rejected (m).
    #[serde(default = "default_min_range_m")]
    pub min_range_m: f64,
    /// Returns further than this are rejected (m).
    #[serde(default = "default_max_range_m")]
    pub max_range_m: f64,
}

impl SensorConfig {
    /// The georeferencing sensor (angles converted to radians).
    pub fn sensor(&self) -> crate::georef::Sensor {
        crate::georef::Sensor::new(
            nalgebra::Vector3::from(self.lever_arm_b_m),
            nalgebra::Vector3::from(self.boresight_deg.map(f64::to_radians)),
            self.alpha0_deg.to_radians(),
            self.range_zero_m,
        )
        .with_range_scale_ppm(self.range_scale_ppm)
        .with_encoder_offset_rad(self.encoder_offset_deg.to_radians())
    }
}

/// `[time]`: the scanner clock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeConfig {
    /// Which time model.
    #[serde(default = "default_time_model")]
    pub model: TimeModel,
    /// GPS time of the start of profile 0 (s); required by the software model.
    #[serde(default)]
    pub t0_s: Option<f64>,
    /// Mirror period T (s).
    pub period_s: f64,
    /// Mirror angle at which the profile counter increments (deg).
    #[serde(default)]
    pub beta_start_deg: f64,
    /// Sense of mirror rotation.
    #[serde(default = "default_direction")]
    pub direction: MirrorDirection,
}

impl TimeConfig {
    /// The mirror geometry (radians) for RECORDED mirror angles, with the encoder offset
    /// dbeta (deg, `sensor.encoder_offset_deg`) applied: `f(beta + dbeta)` is the fraction of
    /// the recorded `beta` with the profile start moved to `beta_start - dbeta`.
    pub fn mirror(&self, encoder_offset_deg: f64) -> crate::timing::Mirror {
        crate::timing::Mirror {
            beta_start_rad: (self.beta_start_deg - encoder_offset_deg).to_radians(),
            direction: self.direction,
        }
    }
}

/// `[latency]` (conventions §2 signs).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LatencyConfig {
    /// Attitude latency tau (s): attitude is evaluated at `t + tau`.
    #[serde(default)]
    pub attitude_s: f64,
    /// Position latency (s): position is evaluated at `t + position_s`.
    #[serde(default)]
    pub position_s: f64,
}

/// Shortest mirror period accepted (s): a 10 kHz mirror, far beyond any profile scanner;
/// anything shorter is a typing error (and would make profile times meaningless).
pub const MIN_PERIOD_S: f64 = 1e-4;

impl SensorConfig {
    /// Checks that every value is finite and the range limits ordered.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        let scalars = [
            ("sensor.alpha0_deg", self.alpha0_deg),
            ("sensor.range_zero_m", self.range_zero_m),
            ("sensor.range_scale_ppm", self.range_scale_ppm),
            ("sensor.encoder_offset_deg", self.encoder_offset_deg),
        ];
        require_finite(
            elements("sensor.lever_arm_b_m", &self.lever_arm_b_m)
                .chain(elements("sensor.boresight_deg", &self.boresight_deg))
                .chain(scalars.map(|(k, v)| (k.to_string(), v))),
        )?;
        let (min, max) = (self.min_range_m, self.max_range_m);
        if !(min >= 0.0 && max > min && max.is_finite()) {
            let problem = format!("need 0 <= min_range_m < max_range_m, got {min} and {max}");
            return Err(refuse("sensor.max_range_m", problem));
        }
        Ok(())
    }
}

impl TimeConfig {
    /// Checks the period and t0 (the software model's need of t0 is checked with `[sync]`).
    pub(super) fn check(&self) -> Result<(), Refusal> {
        if !(MIN_PERIOD_S..=1.0).contains(&self.period_s) {
            let problem = format!("must be in [{MIN_PERIOD_S}, 1] s, got {:?}", self.period_s);
            return Err(refuse("time.period_s", problem));
        }
        require_finite(self.t0_s.map(|t0| ("time.t0_s", t0)))?;
        match self.t0_s {
            Some(t0) if t0.abs() > MAX_SECONDS_OF_WEEK => {
                let week = (t0 / SECONDS_PER_WEEK).floor();
                let problem = format!(
                    "{t0} s looks like absolute GPS time (week {week}, {:.3} s into it): \
                     trajectory times are seconds of the GPS week, so t0_s is too (set \
                     inputs.gps_week for the week)",
                    t0 - week * SECONDS_PER_WEEK
                );
                Err(refuse("time.t0_s", problem))
            }
            _ => Ok(()),
        }
    }
}

/// Seconds in a GPS week.
const SECONDS_PER_WEEK: f64 = 604_800.0;
/// The largest seconds-of-week time a survey may reach: one week on from its start (an SBET
/// that crosses the end of a week keeps counting).
const MAX_SECONDS_OF_WEEK: f64 = 2.0 * SECONDS_PER_WEEK;

impl LatencyConfig {
    /// Checks both latencies are finite and below 1 s in magnitude.
    pub(super) fn check(&self) -> Result<(), Refusal> {
        for (key, v) in [
            ("latency.attitude_s", self.attitude_s),
            ("latency.position_s", self.position_s),
        ] {
            if !v.is_finite() || v.abs() >= 1.0 {
                return Err(refuse(
                    key,
                    format!("must be finite and below 1 s in magnitude, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

fn default_min_range_m() -> f64 {
    0.5
}
fn default_max_range_m() -> f64 {
    1000.0
}
fn default_time_model() -> TimeModel {
    TimeModel::Software
}
fn default_direction() -> MirrorDirection {
    MirrorDirection::Increasing
}
