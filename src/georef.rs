//! The georeferencing equation (SPEC 4):
//! `x_e = r_e(t) + R_n^e(lat(t), lon(t)) * R_b^n(t + tau) * (l_b + R_s^b * x_s)`,
//! `x_s = (rho + K) * u_s(alpha, beta)`,
//! `u_s = (sin(alpha), -cos(alpha) sin(beta), cos(alpha) cos(beta))`.

use crate::geo::ellipsoid::r_n_to_e;
use crate::geo::rotations::r_zyx;
use crate::trajectory::Pose;
use nalgebra::{Matrix3, Vector3};

/// Scanner mounting and intrinsic parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// Scanner optical centre relative to the IMU origin, body frame (m).
    pub lever_arm_b_m: Vector3<f64>,
    /// Boresight angles (bx, by, bz) (rad): `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    pub boresight_rad: Vector3<f64>,
    /// `R_s^b` computed from `boresight_rad`.
    pub r_s_to_b: Matrix3<f64>,
    /// Out-of-plane beam angle alpha0 of a profile scanner (rad).
    pub alpha0_rad: f64,
    /// Range zero error K (m), added to every measured range.
    pub range_zero_m: f64,
}

impl Sensor {
    /// A sensor from lever arm (m), boresight angles (rad), alpha0 (rad) and K (m).
    pub fn new(
        lever_arm_b_m: Vector3<f64>,
        boresight_rad: Vector3<f64>,
        alpha0_rad: f64,
        range_zero_m: f64,
    ) -> Self {
        let r_s_to_b = r_zyx(boresight_rad.x, boresight_rad.y, boresight_rad.z);
        Sensor {
            lever_arm_b_m,
            boresight_rad,
            r_s_to_b,
            alpha0_rad,
            range_zero_m,
        }
    }
}

/// Unit beam direction in the scanner frame for out-of-plane angle `alpha` and mirror angle
/// `beta` (rad).
#[inline]
pub fn beam_s(alpha_rad: f64, beta_rad: f64) -> Vector3<f64> {
    let (sa, ca) = alpha_rad.sin_cos();
    let (sb, cb) = beta_rad.sin_cos();
    Vector3::new(sa, -ca * sb, ca * cb)
}

/// Measured point in the scanner frame (m): `(rho + K) u_s(alpha, beta)`.
#[inline]
pub fn point_s(sensor: &Sensor, range_m: f64, alpha_rad: f64, beta_rad: f64) -> Vector3<f64> {
    beam_s(alpha_rad, beta_rad) * (range_m + sensor.range_zero_m)
}

/// `R_b^e = R_n^e(lat, lon) R_b^n` for a pose.
#[inline]
pub fn r_b_to_e(pose: &Pose) -> Matrix3<f64> {
    r_n_to_e(pose.nav.lat_rad, pose.nav.lon_rad) * pose.q_b_to_n.to_rotation_matrix().matrix()
}

/// ECEF point (m) of a scanner-frame point `x_s_m` for a pose (SPEC 4).
#[inline]
pub fn georeference(pose: &Pose, sensor: &Sensor, x_s_m: &Vector3<f64>) -> Vector3<f64> {
    pose.nav.r_e_m + r_b_to_e(pose) * (sensor.lever_arm_b_m + sensor.r_s_to_b * x_s_m)
}

/// The beam as a ray in ECEF: scanner optical centre (m) and unit direction, for the forward
/// (simulation) direction of the equation. `x_e = origin + (rho + K) * dir`.
#[inline]
pub fn beam_e(
    pose: &Pose,
    sensor: &Sensor,
    alpha_rad: f64,
    beta_rad: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let r_b_e = r_b_to_e(pose);
    let origin = pose.nav.r_e_m + r_b_e * sensor.lever_arm_b_m;
    let dir = r_b_e * (sensor.r_s_to_b * beam_s(alpha_rad, beta_rad));
    (origin, dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn beam_convention() {
        assert!((beam_s(0.0, 0.0) - Vector3::z()).norm() < 1e-15);
        assert!((beam_s(0.0, FRAC_PI_2) + Vector3::y()).norm() < 1e-15);
        assert!((beam_s(FRAC_PI_2, 0.3) - Vector3::x()).norm() < 1e-15);
    }
}
