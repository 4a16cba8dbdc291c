//! The scanner time model (conventions §2): when did a return of profile `n` at mirror angle `beta`
//! happen?
//!
//! Software sync: `t = t0 + T * (n + f(beta))`; hardware (PPS) profile tags:
//! `t = t_n + T * f(beta)`; with `f(beta) = wrap(dir * (beta - beta_start)) / (2 pi)` and
//! `wrap` into [0, 2 pi). Times are GPS seconds, angles radians. [`ReturnClock`] is the one
//! place a return's time is decided from the configured [`TimeModel`].

use crate::geo::rotations::wrap_two_pi;
use crate::io::profiles::RawReturn;
use std::f64::consts::TAU;

/// How return times are obtained (conventions §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeModel {
    /// `t = t0 + T (n + f(beta))` from the profile counter (no hardware time tags).
    Software,
    /// The `time_s` column holds each profile's PPS-derived start time `t_n`:
    /// `t = t_n + T f(beta)`.
    HardwareProfile,
    /// The `time_s` column holds each return's own GPS time.
    HardwareReturn,
}

impl TimeModel {
    /// The model as spelled in a pipeline file (`hardware_return`...).
    pub fn name(self) -> &'static str {
        match self {
            TimeModel::Software => "software",
            TimeModel::HardwareProfile => "hardware_profile",
            TimeModel::HardwareReturn => "hardware_return",
        }
    }

    /// Whether the model reads the profile file's `time_s` column.
    pub fn needs_time_tags(self) -> bool {
        self != TimeModel::Software
    }
}

/// Sense of mirror rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MirrorDirection {
    /// beta increases with time (`dir` = +1).
    Increasing,
    /// beta decreases with time (`dir` = -1).
    Decreasing,
}

impl MirrorDirection {
    /// `dir` of conventions §2: +1 or -1.
    pub fn sign(self) -> f64 {
        match self {
            MirrorDirection::Increasing => 1.0,
            MirrorDirection::Decreasing => -1.0,
        }
    }
}

/// The mirror geometry that places a return inside its profile.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Mirror {
    /// Mirror angle at which the profile counter increments (rad).
    pub beta_start_rad: f64,
    /// Sense of rotation.
    pub direction: MirrorDirection,
}

impl Mirror {
    /// Fraction of a revolution since the profile started, in [0, 1).
    #[inline]
    pub fn fraction(&self, beta_rad: f64) -> f64 {
        wrap_two_pi(self.direction.sign() * (beta_rad - self.beta_start_rad)) / TAU
    }
}

/// Software clock: profile 0 starts at `t0_s`, profiles last `period_s`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ScannerClock {
    /// GPS time of the start of profile 0 (s).
    pub t0_s: f64,
    /// Mirror period T (s).
    pub period_s: f64,
    /// Mirror geometry.
    pub mirror: Mirror,
}

impl ScannerClock {
    /// GPS time (s) of a return of `profile` at mirror angle `beta_rad`.
    #[inline]
    pub fn time_of(&self, profile: u32, beta_rad: f64) -> f64 {
        self.time_and_partials(profile, beta_rad).0
    }

    /// Partial derivatives of [`Self::time_of`] with respect to (t0, T): (1, n + f(beta)).
    #[inline]
    pub fn partials(&self, profile: u32, beta_rad: f64) -> (f64, f64) {
        self.time_and_partials(profile, beta_rad).1
    }

    /// [`Self::time_of`] and [`Self::partials`] together (the mirror fraction computed once).
    #[inline]
    pub fn time_and_partials(&self, profile: u32, beta_rad: f64) -> (f64, (f64, f64)) {
        let k = profile as f64 + self.mirror.fraction(beta_rad);
        (self.t0_s + self.period_s * k, (1.0, k))
    }

    /// GPS time (s) of a return tagged with its profile's hardware start time `t_n_s`.
    #[inline]
    pub fn time_from_profile_tag(&self, t_n_s: f64, beta_rad: f64) -> f64 {
        self.time_from_profile_tag_and_partial(t_n_s, beta_rad).0
    }

    /// [`Self::time_from_profile_tag`] and its partial with respect to T, `f(beta)`.
    #[inline]
    pub fn time_from_profile_tag_and_partial(&self, t_n_s: f64, beta_rad: f64) -> (f64, f64) {
        let f = self.mirror.fraction(beta_rad);
        (t_n_s + self.period_s * f, f)
    }
}

/// A resolved scanner clock and the model that says how it is used: the time of any return.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ReturnClock {
    /// Which time model.
    pub model: TimeModel,
    /// Clock parameters (t0 is unused by the hardware models, T by `HardwareReturn`).
    pub clock: ScannerClock,
}

impl ReturnClock {
    /// GPS time (s) of a return and its partials with respect to the clock parameters
    /// (t0, T): `(1, n + f)` (software), `(0, f)` (profile tags), `(0, 0)` (return tags).
    #[inline]
    pub fn time_and_partials(&self, r: &RawReturn) -> (f64, [f64; 2]) {
        match self.model {
            TimeModel::Software => {
                let (t, (a, b)) = self.clock.time_and_partials(r.profile, r.beta_rad);
                (t, [a, b])
            }
            TimeModel::HardwareProfile => {
                let (t, f) = self
                    .clock
                    .time_from_profile_tag_and_partial(r.time_s, r.beta_rad);
                (t, [0.0, f])
            }
            TimeModel::HardwareReturn => (r.time_s, [0.0, 0.0]),
        }
    }

    /// GPS time (s) of a return.
    #[inline]
    pub fn time_of(&self, r: &RawReturn) -> f64 {
        self.time_and_partials(r).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fraction_wraps_and_follows_direction() {
        let up = Mirror {
            beta_start_rad: -3.0,
            direction: MirrorDirection::Increasing,
        };
        assert!((up.fraction(-3.0)).abs() < 1e-15);
        assert!((up.fraction(-3.0 + TAU / 4.0) - 0.25).abs() < 1e-15);
        assert!((up.fraction(-3.0 - TAU / 4.0) - 0.75).abs() < 1e-15);
        let down = Mirror {
            direction: MirrorDirection::Decreasing,
            ..up
        };
        assert!((down.fraction(-3.0 - TAU / 4.0) - 0.25).abs() < 1e-15);
    }

    #[test]
    fn time_of_profile_and_angle() {
        let m = Mirror {
            beta_start_rad: 0.0,
            direction: MirrorDirection::Increasing,
        };
        let c = ScannerClock {
            t0_s: 1000.0,
            period_s: 0.01,
            mirror: m,
        };
        assert!((c.time_of(10, std::f64::consts::PI) - 1000.105).abs() < 1e-12);
        assert_eq!(c.partials(10, std::f64::consts::PI), (1.0, 10.5));
        assert!((c.time_from_profile_tag(5.0, std::f64::consts::PI) - 5.005).abs() < 1e-15);
    }

    #[test]
    fn return_clock_dispatches_on_the_model() {
        let clock = ScannerClock {
            t0_s: 1000.0,
            period_s: 0.01,
            mirror: Mirror {
                beta_start_rad: 0.0,
                direction: MirrorDirection::Increasing,
            },
        };
        let r = RawReturn {
            profile: 10,
            beta_rad: std::f64::consts::PI,
            time_s: 7.0,
            ..RawReturn::default()
        };
        let at = |model| ReturnClock { model, clock }.time_and_partials(&r);
        let (t, d) = at(TimeModel::Software);
        assert!((t - 1000.105).abs() < 1e-12 && d == [1.0, 10.5]);
        let (t, d) = at(TimeModel::HardwareProfile);
        assert!((t - 7.005).abs() < 1e-15 && d == [0.0, 0.5]);
        assert_eq!(at(TimeModel::HardwareReturn), (7.0, [0.0, 0.0]));
    }
}
