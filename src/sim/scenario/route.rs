//! `[route]` (waypoints, speed, stops) and `[vehicle]` (body dynamics).

use crate::sim::checker::Checker;
use serde::{Deserialize, Serialize};

/// A stop on the route.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct StopCfg {
    /// Distance along one lap where the vehicle stands (m).
    pub at_m: f64,
    /// How long it stands (s).
    pub dwell_s: f64,
}

/// Route: a closed loop through waypoints (scene frame), driven lap after lap.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RouteCfg {
    /// Waypoints East, North (m); the loop closes back to the first. Corners are rounded.
    pub waypoints_m: Vec<[f64; 2]>,
    /// Corner radius (m).
    pub corner_radius_m: f64,
    /// Top speed on straights (m/s), at most 20.
    pub max_speed_mps: f64,
    /// Largest lateral acceleration in corners (m/s^2).
    pub max_lateral_acc_mps2: f64,
    /// Largest longitudinal acceleration (m/s^2).
    pub max_acc_mps2: f64,
    /// Largest braking deceleration (m/s^2).
    pub max_decel_mps2: f64,
    /// Stops within each lap (besides the start/end of every lap).
    pub stops: Vec<StopCfg>,
    /// Standing time at the start of every lap (s).
    pub lap_start_dwell_s: f64,
}

impl Default for RouteCfg {
    fn default() -> Self {
        RouteCfg {
            waypoints_m: Vec::new(),
            corner_radius_m: 8.0,
            max_speed_mps: 12.0,
            max_lateral_acc_mps2: 2.5,
            max_acc_mps2: 1.5,
            max_decel_mps2: 2.5,
            stops: Vec::new(),
            lap_start_dwell_s: 2.0,
        }
    }
}

/// Vehicle body dynamics.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct VehicleCfg {
    /// IMU origin height above the road (m).
    pub imu_height_m: f64,
    /// Lateral offset of the driving line from the street centre line, to the right (m).
    pub lane_offset_m: f64,
    /// Body roll per lateral acceleration (deg per m/s^2), rolling out of the turn.
    pub roll_per_lateral_acc_deg: f64,
    /// Body pitch per longitudinal acceleration (deg per m/s^2), nose down when braking.
    pub pitch_per_longitudinal_acc_deg: f64,
    /// Time constant of the body's roll/pitch response (s).
    pub body_time_constant_s: f64,
    /// Road vibration amplitude at top speed: roll, pitch (deg).
    pub vibration_deg: [f64; 2],
    /// When set, roll and pitch vibrate as one sinusoid at this frequency (Hz) of amplitude
    /// `vibration_deg` at top speed, instead of three seeded sinusoids.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vibration_hz: Option<f64>,
    /// Road vibration vertical amplitude at top speed (m).
    pub vibration_vertical_m: f64,
    /// True trajectory (and SBET) sampling rate (Hz), >= 200.
    pub nav_rate_hz: f64,
}

impl Default for VehicleCfg {
    fn default() -> Self {
        VehicleCfg {
            imu_height_m: 2.0,
            lane_offset_m: 2.0,
            roll_per_lateral_acc_deg: 0.5,
            pitch_per_longitudinal_acc_deg: 0.4,
            body_time_constant_s: 0.3,
            vibration_deg: [0.02, 0.02],
            vibration_hz: None,
            vibration_vertical_m: 0.003,
            nav_rate_hz: 200.0,
        }
    }
}

impl RouteCfg {
    /// Checks every value's range.
    pub(super) fn check(&self, c: &mut Checker) {
        c.test("route.waypoints_m", self.waypoints_m.len() >= 3, || {
            format!("needs at least 3 waypoints, got {}", self.waypoints_m.len())
        });
        let flat: Vec<f64> = self.waypoints_m.iter().flatten().copied().collect();
        c.finite("route.waypoints_m", &flat);
        c.range("route.corner_radius_m", self.corner_radius_m, 2.0, 500.0);
        c.range("route.max_speed_mps", self.max_speed_mps, 0.5, 20.0);
        c.range(
            "route.max_lateral_acc_mps2",
            self.max_lateral_acc_mps2,
            0.1,
            8.0,
        );
        c.range("route.max_acc_mps2", self.max_acc_mps2, 0.1, 8.0);
        c.range("route.max_decel_mps2", self.max_decel_mps2, 0.1, 10.0);
        c.range(
            "route.lap_start_dwell_s",
            self.lap_start_dwell_s,
            0.0,
            3600.0,
        );
        for (i, s) in self.stops.iter().enumerate() {
            c.nonneg(&format!("route.stops[{i}].at_m"), s.at_m);
            c.range(&format!("route.stops[{i}].dwell_s"), s.dwell_s, 0.0, 3600.0);
        }
    }
}

impl VehicleCfg {
    /// Checks every value's range.
    pub(super) fn check(&self, c: &mut Checker) {
        c.range("vehicle.imu_height_m", self.imu_height_m, 0.3, 10.0);
        c.range("vehicle.lane_offset_m", self.lane_offset_m, -20.0, 20.0);
        c.range(
            "vehicle.roll_per_lateral_acc_deg",
            self.roll_per_lateral_acc_deg,
            0.0,
            5.0,
        );
        let p = self.pitch_per_longitudinal_acc_deg;
        c.range("vehicle.pitch_per_longitudinal_acc_deg", p, 0.0, 5.0);
        c.range(
            "vehicle.body_time_constant_s",
            self.body_time_constant_s,
            0.0,
            10.0,
        );
        for (i, v) in self.vibration_deg.iter().enumerate() {
            c.range(&format!("vehicle.vibration_deg[{i}]"), *v, 0.0, 2.0);
        }
        if let Some(f) = self.vibration_hz {
            c.range("vehicle.vibration_hz", f, 0.5, 20.0);
        }
        c.range(
            "vehicle.vibration_vertical_m",
            self.vibration_vertical_m,
            0.0,
            0.1,
        );
        c.range("vehicle.nav_rate_hz", self.nav_rate_hz, 200.0, 2000.0);
    }
}
