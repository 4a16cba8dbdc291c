//! Strapdown mechanisation in the local-level NED frame (conventions §3): attitude
//! `R_b^n` as a unit quaternion, NED velocity, geodetic position; Earth rotation, transport
//! rate and normal gravity ([`super::earth`]).
//!
//! One step integrates one IMU record, the angle increment `dtheta = w_b dt` and velocity
//! increment `dv = f_b dt` of the interval:
//! - attitude: `R(k+1) = exp(-w_in dt) R(k) exp(dtheta)`, `w_in = w_ie + w_en` at step k;
//! - velocity: `v(k+1) = v(k) + R_mid dv + (g - (2 w_ie + w_en) x v(k)) dt`, `R_mid` the
//!   attitude half way through the interval (`exp(-w_in dt/2) R(k) exp(dtheta/2)`);
//! - position: height, then latitude, then longitude with the trapezoid of the velocities
//!   and the radii at the mean latitude and height.
//!
//! [`increments`] is this step's exact inverse: the increments that carry one state to the
//! next. The simulator derives its IMU data from the true trajectory with it, so an
//! error-free IMU reproduces the truth to rounding (tested below).

use super::earth::{gravity_n, metres_per_rad, omega_en_n, omega_ie_n};
use crate::geo::ellipsoid::{geodetic_to_ecef, Geodetic};
use nalgebra::{Rotation3, UnitQuaternion, Vector3};

/// Navigation state of the IMU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavState {
    /// GPS seconds of the week (s).
    pub time_s: f64,
    /// Geodetic latitude (rad).
    pub lat_rad: f64,
    /// Longitude (rad).
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub h_m: f64,
    /// Velocity north, east, down (m/s).
    pub v_n: Vector3<f64>,
    /// Attitude `R_b^n` as a quaternion.
    pub q_b_n: UnitQuaternion<f64>,
}

impl NavState {
    /// ECEF position (m).
    pub fn ecef(&self) -> Vector3<f64> {
        geodetic_to_ecef(Geodetic {
            lat_rad: self.lat_rad,
            lon_rad: self.lon_rad,
            h_m: self.h_m,
        })
    }

    /// Moves the position by `d` metres north, east, down.
    pub fn shift_ned(&mut self, d: &Vector3<f64>) {
        let (m_lat, m_lon) = metres_per_rad(self.lat_rad, self.h_m);
        self.lat_rad += d.x / m_lat;
        self.lon_rad += d.y / m_lon;
        self.h_m -= d.z;
    }

    /// `other - self` in metres north, east, down (first order, for small differences).
    pub fn ned_to(&self, lat_rad: f64, lon_rad: f64, h_m: f64) -> Vector3<f64> {
        let (m_lat, m_lon) = metres_per_rad(self.lat_rad, self.h_m);
        Vector3::new(
            (lat_rad - self.lat_rad) * m_lat,
            crate::geo::rotations::wrap_pi(lon_rad - self.lon_rad) * m_lon,
            self.h_m - h_m,
        )
    }
}

/// The rotations of one step: NED frame over `dt` and half of it.
struct StepFrames {
    q_n: UnitQuaternion<f64>,
    q_n_half: UnitQuaternion<f64>,
    coriolis_gravity: Vector3<f64>,
}

fn step_frames(s: &NavState, dt: f64) -> StepFrames {
    let w_ie = omega_ie_n(s.lat_rad);
    let w_en = omega_en_n(s.lat_rad, s.h_m, &s.v_n);
    let w_in = w_ie + w_en;
    StepFrames {
        q_n: UnitQuaternion::from_scaled_axis(-w_in * dt),
        q_n_half: UnitQuaternion::from_scaled_axis(-w_in * (0.5 * dt)),
        coriolis_gravity: (gravity_n(s.lat_rad, s.h_m) - (2.0 * w_ie + w_en).cross(&s.v_n)) * dt,
    }
}

/// Integrates the position over `dt` from velocity `v0` to `v1` (trapezoid).
fn integrate_position(s: &mut NavState, v0: &Vector3<f64>, v1: &Vector3<f64>, dt: f64) {
    let h0 = s.h_m;
    let h1 = h0 - 0.5 * (v0.z + v1.z) * dt;
    let (m_lat, _) = metres_per_rad(s.lat_rad, 0.5 * (h0 + h1));
    let lat1 = s.lat_rad + 0.5 * (v0.x + v1.x) * dt / m_lat;
    let (_, m_lon) = metres_per_rad(0.5 * (s.lat_rad + lat1), 0.5 * (h0 + h1));
    s.lon_rad += 0.5 * (v0.y + v1.y) * dt / m_lon;
    s.lat_rad = lat1;
    s.h_m = h1;
}

/// One mechanisation step over `dt` with angle increment `dtheta` (rad) and velocity
/// increment `dv` (m/s), both body frame; returns the state at `time_s + dt`.
pub fn step(s: &NavState, dtheta: &Vector3<f64>, dv: &Vector3<f64>, dt: f64) -> NavState {
    let f = step_frames(s, dt);
    let q_mid = f.q_n_half * s.q_b_n * UnitQuaternion::from_scaled_axis(0.5 * dtheta);
    let q1 = f.q_n * s.q_b_n * UnitQuaternion::from_scaled_axis(*dtheta);
    let v1 = s.v_n + q_mid * dv + f.coriolis_gravity;
    let mut next = *s;
    integrate_position(&mut next, &s.v_n, &v1, dt);
    next.v_n = v1;
    next.q_b_n = UnitQuaternion::new_normalize(*q1.quaternion());
    next.time_s = s.time_s + dt;
    next
}

/// The increments `(dtheta, dv)` (body frame) that carry `s0` to the attitude and velocity
/// of `s1` in one [`step`] of `dt`.
pub fn increments(s0: &NavState, s1: &NavState, dt: f64) -> (Vector3<f64>, Vector3<f64>) {
    let f = step_frames(s0, dt);
    let dq = s0.q_b_n.inverse() * f.q_n.inverse() * s1.q_b_n;
    let dtheta = dq.scaled_axis();
    let q_mid = f.q_n_half * s0.q_b_n * UnitQuaternion::from_scaled_axis(0.5 * dtheta);
    let dv = q_mid.inverse() * (s1.v_n - s0.v_n - f.coriolis_gravity);
    (dtheta, dv)
}

/// Roll, pitch, true heading (rad; heading in [0, 2 pi)) of a state.
pub fn euler(s: &NavState) -> (f64, f64, f64) {
    crate::geo::rotations::roll_pitch_heading(&s.q_b_n)
}

/// `R_b^n` of a state.
pub fn r_b_n(s: &NavState) -> Rotation3<f64> {
    s.q_b_n.to_rotation_matrix()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A state, stepped with increments from [`increments`], lands on the target attitude
    /// and velocity to rounding, whatever the motion.
    #[test]
    fn increments_invert_the_step() {
        let s0 = NavState {
            time_s: 0.0,
            lat_rad: 0.8,
            lon_rad: 0.2,
            h_m: 300.0,
            v_n: Vector3::new(10.0, -4.0, 0.3),
            q_b_n: crate::geo::rotations::q_b_to_n(0.1, -0.05, 2.0),
        };
        let mut s1 = s0;
        s1.v_n = Vector3::new(10.2, -3.9, 0.28);
        s1.q_b_n = crate::geo::rotations::q_b_to_n(0.102, -0.049, 2.003);
        let (dth, dv) = increments(&s0, &s1, 0.005);
        let s = step(&s0, &dth, &dv, 0.005);
        assert!((s.v_n - s1.v_n).norm() < 1e-12);
        assert!(s.q_b_n.angle_to(&s1.q_b_n) < 1e-12);
    }
}
