//! The georeferencing equation (conventions §4):
//! `x_e = r_e(t) + R_n^e(lat(t), lon(t)) * R_b^n(t + tau) * (l_b + R_s^b * x_s)`,
//! `x_s = (1 + S 1e-6) (rho + K) * u_s(alpha, beta + dbeta)`,
//! `u_s = (sin(alpha), -cos(alpha) sin(beta), cos(alpha) cos(beta))` (docs/conventions.md §3-4).
//! Functions taking a [`Sensor`] take the RECORDED range and mirror angle and apply `K`, `S`
//! and `dbeta` themselves.

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
    /// Range scale error S (ppm): the range is `(1 + S 1e-6) (rho + K)`.
    pub range_scale_ppm: f64,
    /// Encoder offset dbeta (rad), added to every recorded mirror angle.
    pub encoder_offset_rad: f64,
}

impl Sensor {
    /// A sensor from lever arm (m), boresight angles (rad), alpha0 (rad) and K (m); no range
    /// scale error and no encoder offset.
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
            range_scale_ppm: 0.0,
            encoder_offset_rad: 0.0,
        }
    }

    /// The same sensor with range scale error `S` (ppm).
    pub fn with_range_scale_ppm(self, range_scale_ppm: f64) -> Self {
        Sensor {
            range_scale_ppm,
            ..self
        }
    }

    /// The same sensor with encoder offset `dbeta` (rad).
    pub fn with_encoder_offset_rad(self, encoder_offset_rad: f64) -> Self {
        Sensor {
            encoder_offset_rad,
            ..self
        }
    }

    /// Corrected range `(1 + S 1e-6) (rho + K)` (m) of a recorded range `rho` (m).
    #[inline]
    pub fn range_total_m(&self, range_m: f64) -> f64 {
        (1.0 + self.range_scale_ppm * 1e-6) * (range_m + self.range_zero_m)
    }

    /// Corrected mirror angle `beta + dbeta` (rad) of a recorded angle `beta` (rad).
    #[inline]
    pub fn beta_rad(&self, recorded_beta_rad: f64) -> f64 {
        recorded_beta_rad + self.encoder_offset_rad
    }
}

/// `u_s` from the `(sin, cos)` of alpha and beta: the one place the beam formula is written.
#[inline]
fn beam_of_trig((sa, ca): (f64, f64), (sb, cb): (f64, f64)) -> Vector3<f64> {
    Vector3::new(sa, -ca * sb, ca * cb)
}

/// Unit beam direction in the scanner frame for out-of-plane angle `alpha` and mirror angle
/// `beta` (rad).
#[inline]
pub fn beam_s(alpha_rad: f64, beta_rad: f64) -> Vector3<f64> {
    beam_of_trig(alpha_rad.sin_cos(), beta_rad.sin_cos())
}

/// Measured point in the scanner frame (m) of a recorded range (m) and mirror angle (rad):
/// `(1 + S 1e-6) (rho + K) u_s(alpha, beta + dbeta)`.
#[inline]
pub fn point_s(sensor: &Sensor, range_m: f64, alpha_rad: f64, beta_rad: f64) -> Vector3<f64> {
    beam_s(alpha_rad, sensor.beta_rad(beta_rad)) * sensor.range_total_m(range_m)
}

/// `R_b^e = R_n^e(lat, lon) R_b^n` for a pose.
#[inline]
pub fn r_b_to_e(pose: &Pose) -> Matrix3<f64> {
    r_n_to_e(pose.nav.lat_rad, pose.nav.lon_rad) * pose.q_b_to_n.to_rotation_matrix().matrix()
}

/// ECEF point (m) of a scanner-frame point `x_s_m` for a pose (conventions §4).
#[inline]
pub fn georeference(pose: &Pose, sensor: &Sensor, x_s_m: &Vector3<f64>) -> Vector3<f64> {
    pose.nav.r_e_m + r_b_to_e(pose) * (sensor.lever_arm_b_m + sensor.r_s_to_b * x_s_m)
}

/// The terms of the conventions §4 equation for one return, computed once and shared by the point
/// ([`ReturnTerms::point_e`], identical to [`georeference`]) and the uncertainty Jacobian
/// (`PointGeometry::jacobian_in_axes` of the uncertainty model), which needs the same rotations and
/// beam trigonometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnTerms {
    /// `R_n^e(lat, lon)` at the IMU.
    pub r_n_to_e: Matrix3<f64>,
    /// `R_b^n` (`Rz(heading) Ry(pitch) Rx(roll)`).
    pub r_b_to_n: Matrix3<f64>,
    /// `(sin, cos)` of alpha.
    pub sin_cos_alpha: (f64, f64),
    /// `(sin, cos)` of the corrected mirror angle `beta + dbeta`.
    pub sin_cos_beta: (f64, f64),
    /// Corrected range `(1 + S 1e-6) (rho + K)` (m).
    pub range_total_m: f64,
    /// Scanner-frame point `x_s = range_total_m u_s(alpha, beta + dbeta)` (m).
    pub x_s_m: Vector3<f64>,
    /// `a_b = l_b + R_s^b x_s` (m, body frame).
    pub a_b_m: Vector3<f64>,
}

impl ReturnTerms {
    /// The terms for `R_n^e`, `R_b^n`, lever arm `l_b` (m), `R_s^b`, alpha, corrected beta
    /// (rad) and corrected range (m).
    pub fn new(
        r_n_to_e: Matrix3<f64>,
        r_b_to_n: Matrix3<f64>,
        lever_arm_b_m: &Vector3<f64>,
        r_s_to_b: &Matrix3<f64>,
        alpha_rad: f64,
        beta_rad: f64,
        range_total_m: f64,
    ) -> Self {
        let trig = (alpha_rad.sin_cos(), beta_rad.sin_cos());
        Self::of_trig(
            r_n_to_e,
            r_b_to_n,
            lever_arm_b_m,
            r_s_to_b,
            trig,
            range_total_m,
        )
    }

    /// [`Self::new`] with the `(sin, cos)` of alpha and of the corrected beta given.
    #[inline]
    pub fn of_trig(
        r_n_to_e: Matrix3<f64>,
        r_b_to_n: Matrix3<f64>,
        lever_arm_b_m: &Vector3<f64>,
        r_s_to_b: &Matrix3<f64>,
        (sin_cos_alpha, sin_cos_beta): ((f64, f64), (f64, f64)),
        range_total_m: f64,
    ) -> Self {
        let x_s_m = beam_of_trig(sin_cos_alpha, sin_cos_beta) * range_total_m;
        ReturnTerms {
            r_n_to_e,
            r_b_to_n,
            sin_cos_alpha,
            sin_cos_beta,
            range_total_m,
            x_s_m,
            a_b_m: lever_arm_b_m + r_s_to_b * x_s_m,
        }
    }

    /// The terms of a return with recorded range `range_m` (m), `(sin, cos)` of alpha and
    /// recorded mirror angle `beta_rad` (rad) georeferenced with `pose` and `sensor` (which
    /// applies `K`, `S` and `dbeta`). Alpha comes as its sine and cosine: a constant alpha0's
    /// are computed once per run, not per return.
    #[inline]
    pub fn of_pose(
        pose: &Pose,
        sensor: &Sensor,
        range_m: f64,
        sin_cos_alpha: (f64, f64),
        beta_rad: f64,
    ) -> Self {
        ReturnTerms::of_trig(
            r_n_to_e(pose.nav.lat_rad, pose.nav.lon_rad),
            *pose.q_b_to_n.to_rotation_matrix().matrix(),
            &sensor.lever_arm_b_m,
            &sensor.r_s_to_b,
            (sin_cos_alpha, sensor.beta_rad(beta_rad).sin_cos()),
            sensor.range_total_m(range_m),
        )
    }

    /// Unit beam `u_s(alpha, beta)` in the scanner frame.
    #[inline]
    pub fn u_s(&self) -> Vector3<f64> {
        beam_of_trig(self.sin_cos_alpha, self.sin_cos_beta)
    }

    /// The LAS 1.4 scan angle (rad, in (-pi, pi]): the beam's rotation from nadir about the
    /// vehicle's horizontal along-track axis, i.e. the angle in the vertical cross-track plane
    /// between the downward vertical and the beam's projection, positive to the right looking
    /// forward (counter-clockwise seen from behind), as LAS 1.4 R15 defines it for the
    /// `Scan Angle` field ("relative to the vertical of the data's coordinate system"). The
    /// beam is `R_s^b x_s` (= `a_b - l_b`, `lever_arm_b_m` the lever arm of these terms).
    #[inline]
    pub fn scan_angle_rad(&self, lever_arm_b_m: &Vector3<f64>) -> f64 {
        let beam_n = self.r_b_to_n * (self.a_b_m - lever_arm_b_m);
        // Body x (forward) in the local level (north, east, down), made horizontal.
        let (fwd_n, fwd_e) = (self.r_b_to_n[(0, 0)], self.r_b_to_n[(1, 0)]);
        let h = fwd_n.hypot(fwd_e).max(f64::MIN_POSITIVE);
        // Right of the horizontal forward direction: (-east, north) / h.
        let across = (beam_n.y * fwd_n - beam_n.x * fwd_e) / h;
        across.atan2(beam_n.z)
    }

    /// ECEF point (m) for the IMU at `r_e_m` (conventions §4).
    #[inline]
    pub fn point_e(&self, r_e_m: &Vector3<f64>) -> Vector3<f64> {
        r_e_m + (self.r_n_to_e * self.r_b_to_n) * self.a_b_m
    }
}

/// The beam as a ray in ECEF: scanner optical centre (m) and unit direction, for the forward
/// (simulation) direction of the equation, for a recorded mirror angle (rad):
/// `x_e = origin + sensor.range_total_m(rho) * dir`.
#[inline]
pub fn beam_e(
    pose: &Pose,
    sensor: &Sensor,
    alpha_rad: f64,
    beta_rad: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let r_b_e = r_b_to_e(pose);
    let origin = pose.nav.r_e_m + r_b_e * sensor.lever_arm_b_m;
    let dir = r_b_e * (sensor.r_s_to_b * beam_s(alpha_rad, sensor.beta_rad(beta_rad)));
    (origin, dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    /// The shared terms give the very same point as `georeference` (same operations, same
    /// order), so the pipeline's coordinates do not depend on whether uncertainty is on.
    #[test]
    fn return_terms_reproduce_georeference() {
        use crate::geo::rotations::q_b_to_n;
        use crate::trajectory::NavSample;
        let q = q_b_to_n(0.02, -0.03, 1.2);
        let nav = NavSample {
            t_s: 0.0,
            lat_rad: 0.84,
            lon_rad: 0.2,
            h_m: 300.0,
            r_e_m: Vector3::new(4.0e6, 0.8e6, 4.8e6),
            v_n_mps: Vector3::zeros(),
            q_b_to_n: q,
            omega_b_radps: Vector3::zeros(),
        };
        let pose = Pose::of(&nav);
        let sensor = Sensor::new(
            Vector3::new(0.4, -0.3, -1.6),
            Vector3::new(0.03, -0.04, 1.6),
            0.002,
            0.01,
        );
        for k in 0..100 {
            let (rho, beta) = (1.0 + k as f64 * 0.7, k as f64 * 0.063);
            let x = georeference(&pose, &sensor, &point_s(&sensor, rho, 0.002, beta));
            let t = ReturnTerms::of_pose(&pose, &sensor, rho, 0.002f64.sin_cos(), beta);
            assert_eq!(t.point_e(&nav.r_e_m), x);
        }
    }

    /// S scales the corrected range `rho + K`; dbeta adds to the recorded mirror angle in the
    /// point, the shared terms and the forward ray alike.
    #[test]
    fn range_scale_and_encoder_offset_enter_as_specified() {
        let base = Sensor::new(Vector3::zeros(), Vector3::zeros(), 0.01, 0.02);
        let (s_ppm, dbeta) = (150.0, 0.003);
        let sensor = base
            .with_range_scale_ppm(s_ppm)
            .with_encoder_offset_rad(dbeta);
        let (rho, beta) = (17.3, 0.7);
        let expect = beam_s(0.01, beta + dbeta) * ((1.0 + s_ppm * 1e-6) * (rho + 0.02));
        assert_eq!(point_s(&sensor, rho, 0.01, beta), expect);
        assert_eq!(
            ReturnTerms::new(
                Matrix3::identity(),
                Matrix3::identity(),
                &Vector3::zeros(),
                &Matrix3::identity(),
                0.01,
                sensor.beta_rad(beta),
                sensor.range_total_m(rho),
            )
            .x_s_m,
            expect
        );
        assert_eq!(
            point_s(&base, rho, 0.01, beta),
            beam_s(0.01, beta) * (rho + 0.02)
        );
    }

    #[test]
    fn beam_convention() {
        assert!((beam_s(0.0, 0.0) - Vector3::z()).norm() < 1e-15);
        assert!((beam_s(0.0, FRAC_PI_2) + Vector3::y()).norm() < 1e-15);
        assert!((beam_s(FRAC_PI_2, 0.3) - Vector3::x()).norm() < 1e-15);
    }
}
