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
//!   (0 for a plane through the scanner's z axis), `|beta| <= max_scan_angle`.
//!
//! A new kind (e.g. a Palmer scanner, whose beams lie on a cone about z) implements
//! [`ScannerGeometry`] with its own fit; if its beam is not `u_s(alpha, beta)` for some alpha
//! and beta, it also needs its own partials in `uncertainty::model`.

use crate::geo::rotations::wrap_pi;
use crate::pipeline::config::{ScannerKind, TpuConfig};
use nalgebra::Vector3;

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
    /// The beam of the scanner-frame vector `x_s` (m), or why it does not fit.
    fn fit(&self, x_s: &Vector3<f64>) -> Result<Beam, Misfit>;
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
}
