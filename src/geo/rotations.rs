//! Rotations between frames, angle wrapping and attitude interpolation helpers.
//!
//! Convention (conventions §3): attitude `R_b^n = Rz(heading) * Ry(pitch) * Rx(roll)` maps body vectors
//! into North-East-Down; boresight `R_s^b = Rz(bz) * Ry(by) * Rx(bx)` maps scanner vectors into
//! the body. `Rx`, `Ry`, `Rz` are active right-handed rotations about the axis (rad).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use std::f64::consts::{PI, TAU};

/// Active rotation about x by `a` (rad).
#[inline]
pub fn rot_x(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// Active rotation about y by `a` (rad).
#[inline]
pub fn rot_y(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// Active rotation about z by `a` (rad).
#[inline]
pub fn rot_z(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// `Rz(z) * Ry(y) * Rx(x)` (rad): the z-y-x (yaw-pitch-roll) composition used for both attitude
/// and boresight.
#[inline]
pub fn r_zyx(x_rad: f64, y_rad: f64, z_rad: f64) -> Matrix3<f64> {
    let (sx, cx) = x_rad.sin_cos();
    let (sy, cy) = y_rad.sin_cos();
    let (sz, cz) = z_rad.sin_cos();
    Matrix3::new(
        cz * cy,
        cz * sy * sx - sz * cx,
        cz * sy * cx + sz * sx,
        sz * cy,
        sz * sy * sx + cz * cx,
        sz * sy * cx - cz * sx,
        -sy,
        cy * sx,
        cy * cx,
    )
}

/// Body-to-NED attitude matrix `R_b^n` from roll, pitch, true heading (rad).
#[inline]
pub fn r_b_to_n(roll_rad: f64, pitch_rad: f64, heading_rad: f64) -> Matrix3<f64> {
    r_zyx(roll_rad, pitch_rad, heading_rad)
}

/// Body-to-NED attitude quaternion, same rotation as [`r_b_to_n`].
#[inline]
pub fn q_b_to_n(roll_rad: f64, pitch_rad: f64, heading_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, heading_rad)
}

/// Inverse of [`r_zyx`]: `(x, y, z)` angles (rad) with x, z in (-pi, pi], y in [-pi/2, pi/2].
///
/// At gimbal lock (|y| = pi/2) only x -/+ z is defined: x comes out of rounding noise and z is
/// solved from `R * Rx(x)^T = Rz(z) * Ry(y)`, so `r_zyx` of the result reproduces `r` to
/// ~1e-15 for every rotation.
pub fn zyx_angles(r: &Matrix3<f64>) -> (f64, f64, f64) {
    // atan2 rather than asin: keeps full precision near |y| = pi/2.
    let y = (-r[(2, 0)]).atan2(r[(2, 1)].hypot(r[(2, 2)]));
    let x = r[(2, 1)].atan2(r[(2, 2)]);
    let (sx, cx) = x.sin_cos();
    // Columns 1 of R Rx(x)^T and of Rz Ry are (r01 cx - r02 sx, r11 cx - r12 sx, .) = (-sz, cz, 0).
    let z = (r[(0, 2)] * sx - r[(0, 1)] * cx).atan2(r[(1, 1)] * cx - r[(1, 2)] * sx);
    (x, y, z)
}

/// `(sin, cos)` of angles that move slowly (a trajectory's latitude and longitude from one
/// point to the next): from the last exactly computed angle by the angle-addition formulas
/// with the series of the small difference `d` (to `d^5` for the sine, `d^4` for the cosine:
/// the first omitted terms are below 1e-27 for `|d| <= REACH_RAD`), so the result is within a
/// few 1e-16 of `sin_cos` at a fraction of its cost. Beyond the reach it computes `sin_cos`
/// and moves its base there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinCosNear {
    base: f64,
    sin_cos: (f64, f64),
}

impl Default for SinCosNear {
    fn default() -> Self {
        SinCosNear {
            base: f64::NAN,
            sin_cos: (f64::NAN, f64::NAN),
        }
    }
}

impl SinCosNear {
    /// Largest `|angle - base|` (rad) served from the base (~640 m of latitude).
    pub const REACH_RAD: f64 = 1e-4;

    /// `(sin a, cos a)`.
    #[inline]
    pub fn at(&mut self, a: f64) -> (f64, f64) {
        let d = a - self.base;
        // NaN (no base yet) and far angles take the exact path.
        if d.is_nan() || d.abs() > Self::REACH_RAD {
            self.base = a;
            self.sin_cos = a.sin_cos();
            return self.sin_cos;
        }
        let d2 = d * d;
        let sin_d = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0));
        let cos_d_minus_1 = -0.5 * d2 * (1.0 - d2 / 12.0);
        let (s, c) = self.sin_cos;
        (
            s + (s * cos_d_minus_1 + c * sin_d),
            c + (c * cos_d_minus_1 - s * sin_d),
        )
    }
}

/// Roll, pitch, heading (rad) of an attitude quaternion; heading in [0, 2 pi).
pub fn roll_pitch_heading(q: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let (r, p, h) = zyx_angles(Rotation3::from(*q).matrix());
    (r, p, wrap_two_pi(h))
}

/// `a.rem_euclid(2 pi)`, bit for bit, without `fmod` for `|a| < 2 pi` (where `a % 2 pi` is
/// `a` exactly): the angles wrapped per return are almost always within one turn.
#[inline]
fn rem_tau(a: f64) -> f64 {
    if a.abs() >= TAU || a.is_nan() {
        return a.rem_euclid(TAU);
    }
    if a < 0.0 {
        a + TAU
    } else {
        a
    }
}

/// Wraps an angle into (-pi, pi].
#[inline]
pub fn wrap_pi(a: f64) -> f64 {
    let w = rem_tau(a);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// Wraps an angle into [0, 2 pi).
#[inline]
pub fn wrap_two_pi(a: f64) -> f64 {
    let w = rem_tau(a);
    if w >= TAU {
        0.0
    } else {
        w
    }
}

/// Skew-symmetric matrix `[v]x` with `[v]x w = v x w`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zyx_matches_product_and_quaternion() {
        let (x, y, z) = (0.3, -0.4, 2.9);
        let prod = rot_z(z) * rot_y(y) * rot_x(x);
        assert!((r_zyx(x, y, z) - prod).norm() < 1e-15);
        let q = q_b_to_n(x, y, z);
        assert!((q.to_rotation_matrix().matrix() - prod).norm() < 1e-15);
        let (xa, ya, za) = zyx_angles(&prod);
        assert!((xa - x).abs() < 1e-14 && (ya - y).abs() < 1e-14 && (za - z).abs() < 1e-14);
    }

    #[test]
    fn heading_is_clockwise_from_north() {
        // Heading 90 deg: body x (forward) points East in NED.
        let fwd = r_b_to_n(0.0, 0.0, PI / 2.0) * Vector3::x();
        assert!((fwd - Vector3::y()).norm() < 1e-15);
        // Positive pitch raises the nose: forward gets a negative Down component.
        let fwd = r_b_to_n(0.0, 0.1, 0.0) * Vector3::x();
        assert!(fwd.z < 0.0);
        // Positive roll lowers the right wing: body y gets a positive Down component.
        let right = r_b_to_n(0.1, 0.0, 0.0) * Vector3::y();
        assert!(right.z > 0.0);
    }

    #[test]
    fn wraps() {
        assert!((wrap_pi(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_pi(-PI) - PI).abs() < 1e-12);
        assert!(wrap_two_pi(-1e-20) < TAU);
        assert!((wrap_two_pi(-0.5) - (TAU - 0.5)).abs() < 1e-15);
    }

    /// The fast path gives the very bits of `rem_euclid` (output bytes depend on it).
    #[test]
    fn rem_tau_is_rem_euclid_bit_for_bit() {
        let edges = [
            0.0, -0.0, 1e-300, -1e-300, -1e-20, PI, -PI, TAU, -TAU, 7.0, -7.0,
        ];
        let near_tau = [
            TAU.next_up(),
            TAU.next_down(),
            (-TAU).next_up(),
            (-TAU).next_down(),
        ];
        let special = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e17, -1e17];
        let mut state = 0x9e37_79b9_7f4a_7c15_u64; // fixed seed: reproducible sample
        let sampled = (0..100_000).map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 40.0 - 20.0
        });
        let all = edges
            .into_iter()
            .chain(near_tau)
            .chain(special)
            .chain(sampled);
        for a in all {
            assert_eq!(
                rem_tau(a).to_bits(),
                a.rem_euclid(TAU).to_bits(),
                "a = {a:e}"
            );
        }
    }

    /// Near its base `SinCosNear` is `sin_cos` to a few 1e-16; far from it, exactly it.
    #[test]
    fn sin_cos_near_matches_sin_cos() {
        let mut near = SinCosNear::default();
        for base in [-3.1, -1.2, 0.0, 0.6503, 1.5, 3.1] {
            assert_eq!(near.at(base), f64::sin_cos(base));
            for k in -100..=100 {
                let a = base + k as f64 * SinCosNear::REACH_RAD / 100.0;
                let (s, c) = near.at(a);
                let (s0, c0) = a.sin_cos();
                assert!(
                    (s - s0).abs() <= 5e-16 && (c - c0).abs() <= 5e-16,
                    "{a}: {s} {s0}"
                );
            }
            near.at(base + 1.0);
        }
    }
}
