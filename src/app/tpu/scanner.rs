//! Scanner kinds behind one trait: how a scanner-frame vector (recovered by inverting the
//! georeferencing equation) becomes the beam parameters of conventions §4 (corrected range,
//! out-of-plane angle alpha, corrected mirror angle beta), and whether it fits the kind's
//! geometry and limits.
//!
//! Every kind shares the beam `u_s(alpha, beta) = (sin a, -cos a sin b, cos a cos b)` of
//! `georef`, so the propagation is `run`'s; a kind decides which `(alpha, beta)` are possible:
//! - [`ProfileScanner`]: a rotating mirror (the profile scanner of `run`), beams on the cone
//!   `alpha = alpha0`, any beta;
//! - [`OscillatingMirror`]: an airborne oscillating mirror, beams in the plane `alpha = alpha0`
//!   (0 for a plane through the scanner's z axis), `|beta| <= max_scan_angle`;
//! - [`RotatingMirror`]: an airborne rotating (Palmer) mirror, beams on a cone of half-angle
//!   `theta` about the scanner's z axis, any rotation angle.
//!
//! A kind may describe its beams in a frame of its own `s'` (`x_s = Q x_s'`,
//! [`ScannerGeometry::beam_axes`]) where they are `u_s(alpha, beta)`: the Palmer cone about z
//! is the cone `alpha = 90 deg - theta` about the x axis of `s'`. The propagation then takes
//! the scanner partials in `s'` (`R_s^b Q`, `Propagator::with_beam_axes`) and the boresight
//! sigmas about `R_s^b`'s own axes, so no new partials are needed. A kind whose beams are not
//! `u_s(alpha, beta)` in any fixed frame needs its own partials in `uncertainty::model`.

use crate::geo::rotations::wrap_pi;
use crate::pipeline::config::{ScannerKind, TpuConfig};
use nalgebra::{Matrix3, Vector3};

/// Why a point does not fit the scanner's geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Misfit {
    /// Further than `tpu.cone_tolerance_m` from the beam cone (plane) `alpha = alpha0`.
    OffCone,
    /// Mirror angle beyond `tpu.max_scan_angle_deg`.
    ScanAngleOutOfLimits,
}

/// The beam of one recovered point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beam {
    /// `|x_s|`: the corrected range `(1 + S 1e-6) (rho + K)` (m).
    pub range_total_m: f64,
    /// Recovered out-of-plane angle (rad).
    pub alpha_rad: f64,
    /// Corrected mirror angle `beta + dbeta` (rad), in (-pi, pi].
    pub beta_rad: f64,
    /// Distance of the point from the kind's beam cone (m): `range * |alpha - alpha0|`.
    pub off_cone_m: f64,
}

/// A scanner kind: its beam parameters from a scanner-frame vector and its fit check.
pub trait ScannerGeometry: Send + Sync {
    /// The kind's name in reports.
    fn name(&self) -> &'static str;
    /// The nominal out-of-plane angle the propagation uses (rad).
    fn alpha0_rad(&self) -> f64;
    /// The kind's beam frame `s'` in the scanner frame (`x_s = Q x_s'`), `None` when the
    /// beams are `u_s(alpha, beta)` in the scanner frame itself.
    fn beam_axes(&self) -> Option<Matrix3<f64>> {
        None
    }
    /// The beam of the vector `x` (m) in the kind's beam frame (the scanner frame unless
    /// [`Self::beam_axes`]: then `Q^T x_s`), or why it does not fit.
    fn fit(&self, x: &Vector3<f64>) -> Result<Beam, Misfit>;
}

/// The beam parameters of `x_s` (m) (the inverse of `georef::point_s`).
#[inline]
pub fn beam_of(x_s: &Vector3<f64>, alpha0_rad: f64) -> Beam {
    let range_total_m = x_s.norm();
    let alpha_rad = (x_s.x / range_total_m).clamp(-1.0, 1.0).asin();
    Beam {
        range_total_m,
        alpha_rad,
        beta_rad: (-x_s.y).atan2(x_s.z),
        off_cone_m: range_total_m * (alpha_rad - alpha0_rad).abs(),
    }
}

/// The profile scanner of `run`: beams on the cone `alpha = alpha0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileScanner {
    /// Cone angle alpha0 (rad).
    pub alpha0_rad: f64,
    /// Largest distance from the cone (m).
    pub cone_tolerance_m: f64,
}

impl ScannerGeometry for ProfileScanner {
    fn name(&self) -> &'static str {
        "profile"
    }
    fn alpha0_rad(&self) -> f64 {
        self.alpha0_rad
    }
    #[inline]
    fn fit(&self, x_s: &Vector3<f64>) -> Result<Beam, Misfit> {
        let beam = beam_of(x_s, self.alpha0_rad);
        // NaN (a zero vector) is a misfit too.
        if beam.off_cone_m.is_nan() || beam.off_cone_m > self.cone_tolerance_m {
            return Err(Misfit::OffCone);
        }
        Ok(beam)
    }
}

/// An airborne oscillating mirror: beams in the plane `alpha = alpha0`, `|beta| <= max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OscillatingMirror {
    /// The profile geometry (plane angle and tolerance).
    pub plane: ProfileScanner,
    /// Half field of view (rad).
    pub max_scan_angle_rad: f64,
}

impl ScannerGeometry for OscillatingMirror {
    fn name(&self) -> &'static str {
        "oscillating_mirror"
    }
    fn alpha0_rad(&self) -> f64 {
        self.plane.alpha0_rad
    }
    #[inline]
    fn fit(&self, x_s: &Vector3<f64>) -> Result<Beam, Misfit> {
        let beam = self.plane.fit(x_s)?;
        if wrap_pi(beam.beta_rad).abs() > self.max_scan_angle_rad {
            return Err(Misfit::ScanAngleOutOfLimits);
        }
        Ok(beam)
    }
}

/// An airborne rotating (Palmer) mirror: beams on the cone of half-angle `theta` about the
/// scanner's z axis; rotation angle 0 tilts the beam towards the scanner's +x (forward with the
/// identity boresight), +90 deg towards +y (right).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotatingMirror {
    /// The cone in the beam frame `s'`: `alpha0 = 90 deg - theta` about `s'`'s x axis.
    pub cone: ProfileScanner,
}

impl RotatingMirror {
    /// `Q`: the beam frame's axes in the scanner frame, `x_s' -> z_s`, `y_s' -> -y_s`,
    /// `z_s' -> x_s` (a rotation, its own inverse). Then `Q u_s(90 deg - theta, phi) =
    /// (sin theta cos phi, sin theta sin phi, cos theta)`.
    pub fn axes() -> Matrix3<f64> {
        Matrix3::new(0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0)
    }

    /// A cone of half-angle `theta` (rad) and tolerance (m).
    pub fn new(half_angle_rad: f64, cone_tolerance_m: f64) -> Self {
        RotatingMirror {
            cone: ProfileScanner {
                alpha0_rad: std::f64::consts::FRAC_PI_2 - half_angle_rad,
                cone_tolerance_m,
            },
        }
    }
}

impl ScannerGeometry for RotatingMirror {
    fn name(&self) -> &'static str {
        "rotating_mirror"
    }
    fn alpha0_rad(&self) -> f64 {
        self.cone.alpha0_rad
    }
    fn beam_axes(&self) -> Option<Matrix3<f64>> {
        Some(Self::axes())
    }
    #[inline]
    fn fit(&self, x: &Vector3<f64>) -> Result<Beam, Misfit> {
        self.cone.fit(x)
    }
}

/// The scanner kind of a `[tpu]` table with the `[sensor]`'s alpha0 (rad).
pub fn scanner_of(t: &TpuConfig, alpha0_rad: f64) -> Box<dyn ScannerGeometry> {
    let plane = ProfileScanner {
        alpha0_rad,
        cone_tolerance_m: t.cone_tolerance_m,
    };
    match t.scanner {
        ScannerKind::Profile => Box::new(plane),
        ScannerKind::OscillatingMirror => Box::new(OscillatingMirror {
            plane,
            max_scan_angle_rad: t.max_scan_angle_deg.to_radians(),
        }),
        ScannerKind::RotatingMirror => Box::new(RotatingMirror::new(
            t.cone_half_angle_deg.to_radians(),
            t.cone_tolerance_m,
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::georef::beam_s;

    /// The recovered beam is the one `georef` built, and each kind refuses what it cannot see.
    #[test]
    fn beam_inverts_georef_and_kinds_check_their_limits() {
        let profile = ProfileScanner {
            alpha0_rad: 0.01,
            cone_tolerance_m: 0.01,
        };
        for k in 0..50 {
            let beta = -3.0 + 0.12 * k as f64;
            let x = beam_s(0.01, beta) * 37.5;
            let b = profile.fit(&x).unwrap();
            assert!((b.range_total_m - 37.5).abs() < 1e-12);
            assert!((b.beta_rad - wrap_pi(beta)).abs() < 1e-12, "{beta}");
            assert!(b.off_cone_m < 1e-12);
        }
        // 2 cm off a 100 m cone: a misfit.
        let off = beam_s(0.01 + 0.02 / 100.0, 0.3) * 100.0;
        assert_eq!(profile.fit(&off), Err(Misfit::OffCone));
        let mirror = OscillatingMirror {
            plane: ProfileScanner {
                alpha0_rad: 0.0,
                cone_tolerance_m: 0.01,
            },
            max_scan_angle_rad: 0.5,
        };
        assert!(mirror.fit(&(beam_s(0.0, 0.45) * 900.0)).is_ok());
        let wide = beam_s(0.0, 0.55) * 900.0;
        assert_eq!(mirror.fit(&wide), Err(Misfit::ScanAngleOutOfLimits));
    }

    /// A rotating (Palmer) mirror: its beams lie on the cone about z, rotation angle from
    /// +x towards +y; the kind recovers range and rotation angle from the scanner-frame point
    /// (through its beam axes) and refuses a point off its cone.
    #[test]
    fn rotating_mirror_inverts_its_cone_about_z() {
        let theta = 15f64.to_radians();
        let palmer = RotatingMirror::new(theta, 0.01);
        let q = palmer.beam_axes().unwrap();
        assert!((q * q.transpose() - Matrix3::identity()).norm() < 1e-15);
        assert!((q.determinant() - 1.0).abs() < 1e-15, "a rotation");
        for k in 0..72 {
            let phi = -3.1 + 0.086 * k as f64;
            let range = 600.0 + 3.0 * k as f64;
            let (st, ct) = theta.sin_cos();
            let x_s = Vector3::new(st * phi.cos(), st * phi.sin(), ct) * range;
            // The beam frame's own equation gives the same point.
            let own = q * beam_s(palmer.alpha0_rad(), phi) * range;
            assert!((own - x_s).norm() < 1e-9, "{phi}: {own} vs {x_s}");
            let b = palmer.fit(&(q.transpose() * x_s)).unwrap();
            assert!((b.range_total_m - range).abs() < 1e-9);
            assert!(
                (wrap_pi(b.beta_rad - phi)).abs() < 1e-12,
                "{phi} vs {}",
                b.beta_rad
            );
            assert!(b.off_cone_m < 1e-9);
        }
        // 2 cm off the cone at 100 m (half-angle 15.0115 deg): a misfit.
        let off = (theta + 0.02 / 100.0).sin_cos();
        let x_s = Vector3::new(off.0, 0.0, off.1) * 100.0;
        assert_eq!(palmer.fit(&(q.transpose() * x_s)), Err(Misfit::OffCone));
    }

    /// The propagation in the beam frame (`Propagator::with_beam_axes`) is the derivative of
    /// the Palmer's own equation `x_n = R_b^n (l_b + R_s^b Q u_s(alpha, beta) rho)`, with the
    /// boresight sigmas about `R_s^b`'s ZYX angles: against central differences.
    #[test]
    fn rotating_mirror_propagates_its_own_angles() {
        use crate::geo::rotations::r_zyx;
        use crate::georef::ReturnTerms;
        use crate::trajectory::NavSigma;
        use crate::uncertainty::propagate::{Propagator, ReturnInputs, UncertaintyInputs};
        let palmer = RotatingMirror::new(18f64.to_radians(), 0.01);
        let q = palmer.beam_axes().unwrap();
        let bore = Vector3::new(0.01, -0.02, 1.2);
        let lever = Vector3::new(0.3, -0.1, 0.5);
        let r_b_n = r_zyx(0.05, -0.03, 2.1);
        let (alpha, beta, rho) = (palmer.alpha0_rad(), 0.7, 850.0);
        let sig = UncertaintyInputs {
            sigma_lever_arm_b_m: Vector3::zeros(),
            sigma_boresight_rad: Vector3::new(1e-4, 2e-4, 3e-4),
            sigma_alpha_rad: 1e-4,
            sigma_beta_rad: 2e-4,
            sigma_range_m: 0.02,
            sigma_range_zero_m: 0.0,
            clock_covariance_s2: nalgebra::Matrix2::zeros(),
            sigma_attitude_latency_s: 0.0,
        };
        let p =
            Propagator::new(sig, false, lever, r_zyx(bore.x, bore.y, bore.z)).with_beam_axes(&q);
        let r_beam_to_b = r_zyx(bore.x, bore.y, bore.z) * q;
        let terms = ReturnTerms::new(
            Matrix3::identity(),
            r_b_n,
            &lever,
            &r_beam_to_b,
            alpha,
            beta,
            rho,
        );
        let nav = NavSigma {
            pos_ned_m: Vector3::zeros(),
            att_rph_rad: Vector3::zeros(),
        };
        let x = ReturnInputs::new(
            &Matrix3::identity(),
            &Matrix3::zeros(),
            &terms,
            &Vector3::zeros(),
            &Vector3::zeros(),
            &nav,
            [0.0, 0.0],
        );
        let got = p.variances_of::<false>(&x).var_m2;
        // x_n(e): e = (bx, by, bz, alpha, beta, rho) offsets.
        let f = |e: [f64; 6]| {
            let r_s_b = r_zyx(bore.x + e[0], bore.y + e[1], bore.z + e[2]);
            r_b_n
                * (lever
                    + r_s_b * q * crate::georef::beam_s(alpha + e[3], beta + e[4]) * (rho + e[5]))
        };
        let sigmas = [1e-4, 2e-4, 3e-4, 1e-4, 2e-4, 0.02];
        let mut want = Vector3::zeros();
        for (k, s) in sigmas.iter().enumerate() {
            let (mut up, mut down) = ([0.0; 6], [0.0; 6]);
            up[k] = 1e-6;
            down[k] = -1e-6;
            let column = (f(up) - f(down)) / 2e-6 * *s;
            want += column.component_mul(&column);
        }
        for k in 0..3 {
            // Central differences at 1e-6 rad/m: truncation ~ (1e-6)^2 relative, rounding
            // ~ 1e-16 * 850 m / 1e-6 = 1e-7 m in each partial (1e-7 relative of a ~1 m/rad one).
            let rel = (got[k] - want[k]).abs() / want[k];
            assert!(rel <= 1e-5, "axis {k}: {} vs {} ({rel:e})", got[k], want[k]);
        }
    }
}
