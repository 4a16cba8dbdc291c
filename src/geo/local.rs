//! Fast map projection near a point: a second-order Taylor expansion of
//! [`MapFrame::ecef_to_map`] about an ECEF centre, exact beyond a radius.
//!
//! Georeferencing projects millions of points that lie within a few hundred metres of the
//! vehicle; the full ECEF -> geodetic -> transverse Mercator chain costs ~0.4 us a point, the
//! expansion a few ns. The remainder is third order in the distance `d` from the centre, about
//! `d^3 / R^2` times factors of order `tan^2(lat)`: below 1 um for `d` <= [`EXPANSION_RADIUS_M`]
//! at latitudes to 80 deg and 6 deg off the central meridian (tested in `tests/geodesy_local.rs`
//! against the exact projection). For the projected CRSs by EPSG code the same holds, measured
//! <= 0.55 um over 25 CRSs of nine projection classes (Lambert conformal, transverse Mercator,
//! oblique and polar stereographic, Albers, ...: `tests/suite/epsg_frames.rs`). Points further
//! away use the exact projection.

use super::ellipsoid::{ecef_to_geodetic, meridian_radius_m, prime_vertical_radius_m, r_enu_to_e};
use super::projection::MapFrame;
use nalgebra::{Matrix3, RowVector3, Vector3};

/// Radius (m) within which the expansion is used.
pub const EXPANSION_RADIUS_M: f64 = 300.0;
/// Finite-difference step (m) for the derivatives: large enough that f64 rounding of map
/// coordinates (~1e-9 m) contributes < 1e-12 m/m^2 to the Hessian, small enough that the
/// truncation (~h^2 / R^3) is negligible.
const STEP_M: f64 = 25.0;

/// Second-order expansion of a map projection about `centre_e`.
#[derive(Debug, Clone, Copy)]
pub struct LocalProjection {
    frame: MapFrame,
    centre_e: Vector3<f64>,
    f0: Vector3<f64>,
    jacobian: Matrix3<f64>,
    hessian: [Matrix3<f64>; 3],
}

impl LocalProjection {
    /// Expansion of `frame.ecef_to_map` about `centre_e` (ECEF, m): value, Jacobian and the three
    /// output Hessians by central differences.
    pub fn new(frame: MapFrame, centre_e: Vector3<f64>) -> Self {
        let f = |d: Vector3<f64>| frame.ecef_to_map(&(centre_e + d));
        let e = |i: usize| Vector3::ith(i, STEP_M);
        let f0 = f(Vector3::zeros());
        let mut jacobian = Matrix3::zeros();
        let mut hessian = [Matrix3::zeros(); 3];
        for i in 0..3 {
            let (fp, fm) = (f(e(i)), f(-e(i)));
            jacobian.set_column(i, &((fp - fm) / (2.0 * STEP_M)));
            let second = (fp - f0 * 2.0 + fm) / (STEP_M * STEP_M);
            for (k, h) in hessian.iter_mut().enumerate() {
                h[(i, i)] = second[k];
            }
            for j in 0..i {
                let cross = (f(e(i) + e(j)) - f(e(i) - e(j)) - f(e(j) - e(i)) + f(-e(i) - e(j)))
                    / (4.0 * STEP_M * STEP_M);
                for (k, h) in hessian.iter_mut().enumerate() {
                    h[(i, j)] = cross[k];
                    h[(j, i)] = cross[k];
                }
            }
        }
        LocalProjection {
            frame,
            centre_e,
            f0,
            jacobian,
            hessian,
        }
    }

    /// Expansion centre (ECEF, m).
    pub fn centre_e(&self) -> Vector3<f64> {
        self.centre_e
    }

    /// Map coordinates of `x_e` (ECEF, m): the expansion within [`EXPANSION_RADIUS_M`] of the
    /// centre, the exact projection beyond.
    #[inline]
    pub fn ecef_to_map(&self, x_e: &Vector3<f64>) -> Vector3<f64> {
        let d = x_e - self.centre_e;
        if d.norm_squared() > EXPANSION_RADIUS_M * EXPANSION_RADIUS_M {
            return self.frame.ecef_to_map(x_e);
        }
        let quad = Vector3::new(
            d.dot(&(self.hessian[0] * d)),
            d.dot(&(self.hessian[1] * d)),
            d.dot(&(self.hessian[2] * d)),
        );
        self.f0 + self.jacobian * d + quad * 0.5
    }
}

/// Latitude and longitude near a point: the first-order expansion of ECEF -> (lat, lon) about
/// an ECEF centre, exact beyond [`EXPANSION_RADIUS_M`]. The remainder is second order in the
/// distance, growing with tan(lat): at 300 m <= 1.1 cm of horizontal position to 48 deg of
/// latitude, 4.6 cm at 80 deg (unit test); times the geoid's slope (the deflection of the
/// vertical, below 5e-4 rad on Earth) that moves an undulation by < 25 um.
#[derive(Debug, Clone, Copy)]
pub struct LocalLatLon {
    centre_e: Vector3<f64>,
    lat0_rad: f64,
    lon0_rad: f64,
    d_lat_d_e: RowVector3<f64>,
    d_lon_d_e: RowVector3<f64>,
}

impl LocalLatLon {
    /// Expansion about `centre_e` (ECEF, m): `d lat / d x_e = north / (M + h)`,
    /// `d lon / d x_e = east / ((N + h) cos lat)`.
    pub fn new(centre_e: Vector3<f64>) -> Self {
        let g = ecef_to_geodetic(&centre_e);
        let r_enu_to_e = r_enu_to_e(g.lat_rad, g.lon_rad);
        let east = r_enu_to_e.column(0).transpose();
        let north = r_enu_to_e.column(1).transpose();
        let parallel_radius_m = (prime_vertical_radius_m(g.lat_rad) + g.h_m) * g.lat_rad.cos();
        LocalLatLon {
            centre_e,
            lat0_rad: g.lat_rad,
            lon0_rad: g.lon_rad,
            d_lat_d_e: north / (meridian_radius_m(g.lat_rad) + g.h_m),
            d_lon_d_e: east / parallel_radius_m,
        }
    }

    /// Latitude and longitude (rad) of `x_e` (ECEF, m); the longitude is not wrapped.
    #[inline]
    pub fn lat_lon_rad(&self, x_e: &Vector3<f64>) -> (f64, f64) {
        let d = x_e - self.centre_e;
        if d.norm_squared() > EXPANSION_RADIUS_M * EXPANSION_RADIUS_M {
            let g = ecef_to_geodetic(x_e);
            return (g.lat_rad, g.lon_rad);
        }
        (
            self.lat0_rad + (self.d_lat_d_e * d)[0],
            self.lon0_rad + (self.d_lon_d_e * d)[0],
        )
    }
}

/// The inverse of a map projection near a map point: map coordinates to ECEF by Newton steps
/// on the [`LocalProjection`] expanded at the centre (a few ns a point where the exact inverse,
/// map -> geodetic -> ECEF, costs ~0.4 us). Points further than [`UNPROJECT_RADIUS_M`] from
/// the centre (map metres) use the exact inverse. Each step divides the error by ~`d / R`
/// (`R` ~ 6.4e6 m): the first leaves < `d^2 / R` (< 4 mm at 150 m), the second < 1e-8 m, so
/// two steps leave the expansion's own remainder (< 1 um within 300 m).
#[derive(Debug, Clone, Copy)]
pub struct LocalUnprojection {
    forward: LocalProjection,
    centre_map: Vector3<f64>,
    inverse_jacobian: Matrix3<f64>,
}

/// Map distance (m) from the centre within which [`LocalUnprojection`] expands.
pub const UNPROJECT_RADIUS_M: f64 = 150.0;

impl LocalUnprojection {
    /// The inverse of `frame` expanded at the map point `centre_map`.
    pub fn new(frame: MapFrame, centre_map: Vector3<f64>) -> Self {
        let forward = LocalProjection::new(frame, frame.map_to_ecef(&centre_map));
        let inverse_jacobian = forward
            .jacobian
            .try_inverse()
            .unwrap_or_else(Matrix3::identity);
        LocalUnprojection {
            forward,
            centre_map: forward.f0,
            inverse_jacobian,
        }
    }

    /// The map point about which it is expanded.
    pub fn centre_map(&self) -> Vector3<f64> {
        self.centre_map
    }

    /// ECEF (m) of the map point `x_m`.
    #[inline]
    pub fn map_to_ecef(&self, x_m: &Vector3<f64>) -> Vector3<f64> {
        let d = x_m - self.centre_map;
        if d.norm_squared() > UNPROJECT_RADIUS_M * UNPROJECT_RADIUS_M {
            return self.forward.frame.map_to_ecef(x_m);
        }
        let mut x_e = self.forward.centre_e + self.inverse_jacobian * d;
        for _ in 0..2 {
            x_e += self.inverse_jacobian * (x_m - self.forward.ecef_to_map(&x_e));
        }
        x_e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::ellipsoid::{geodetic_to_ecef, Geodetic};

    /// The expansion's horizontal error at the radius, measured against the exact conversion:
    /// <= 1.1 cm to 48 deg of latitude, <= 4.6 cm at 80 deg (the bounds the geoid's accuracy
    /// statement uses).
    #[test]
    fn lat_lon_expansion_error_at_the_radius() {
        for (lat_deg, bound_m) in [(0.0, 0.011), (35.0, 0.011), (48.1, 0.011), (80.0, 0.046)] {
            let g = Geodetic {
                lat_rad: f64::to_radians(lat_deg),
                lon_rad: 0.2,
                h_m: 500.0,
            };
            let centre = geodetic_to_ecef(g);
            let local = LocalLatLon::new(centre);
            let mut worst_m = 0.0f64;
            for k in 0..16 {
                let a = k as f64 * std::f64::consts::TAU / 16.0;
                let dir = Vector3::new(a.cos(), a.sin(), 0.3 * (2.0 * a).sin()).normalize();
                let x = centre + dir * (EXPANSION_RADIUS_M - 1e-6);
                let (lat, lon) = local.lat_lon_rad(&x);
                let exact = ecef_to_geodetic(&x);
                let north_m = (lat - exact.lat_rad) * meridian_radius_m(exact.lat_rad);
                let east_m = (lon - exact.lon_rad)
                    * prime_vertical_radius_m(exact.lat_rad)
                    * exact.lat_rad.cos();
                crate::testing::raise_max(&mut worst_m, north_m.hypot(east_m));
            }
            assert!(
                worst_m > 0.0 && worst_m <= bound_m,
                "lat {lat_deg}: {worst_m} m"
            );
        }
    }

    /// The local inverse agrees with the exact one to 1 um over the expansion radius, in UTM
    /// (off the central meridian, at two latitudes) and ECEF.
    #[test]
    fn unprojection_matches_the_exact_inverse() {
        let frames = [MapFrame::utm(11, true).unwrap(), MapFrame::Ecef];
        for (lat_deg, frame) in [(37.8, frames[0]), (60.0, frames[0]), (37.8, frames[1])] {
            let g = Geodetic {
                lat_rad: f64::to_radians(lat_deg),
                lon_rad: f64::to_radians(-119.0),
                h_m: 2500.0,
            };
            let centre = frame.ecef_to_map(&geodetic_to_ecef(g));
            let inv = LocalUnprojection::new(frame, centre);
            let mut worst_m = f64::NAN;
            for k in 0..64 {
                let a = k as f64 * 0.7;
                let d = Vector3::new(a.cos(), a.sin(), 0.5 * (3.0 * a).sin());
                let x = centre + d * (UNPROJECT_RADIUS_M * 0.999 * (k as f64 / 63.0));
                let err = (inv.map_to_ecef(&x) - frame.map_to_ecef(&x)).norm();
                worst_m = if worst_m.is_nan() {
                    err
                } else {
                    worst_m.max(err)
                };
            }
            assert!(worst_m <= 1e-6, "lat {lat_deg} {frame}: {worst_m} m");
        }
    }
}
