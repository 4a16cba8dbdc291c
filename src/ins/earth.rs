//! The Earth model of the strapdown mechanisation: WGS84 radii, Earth rotation, transport
//! rate and normal gravity in the local-level North-East-Down frame (conventions §3).

use crate::geo::ellipsoid::{
    meridian_radius_m, prime_vertical_radius_m, WGS84_A, WGS84_E2, WGS84_F,
};
use nalgebra::Vector3;

/// Earth rotation rate, WGS84 (rad/s).
pub const OMEGA_IE_RADPS: f64 = 7.292_115e-5;
/// Normal gravity at the equator, WGS84 (m/s^2).
const GAMMA_E: f64 = 9.780_325_335_9;
/// Somigliana's constant k = (b gamma_p) / (a gamma_e) - 1, WGS84.
const SOMIGLIANA_K: f64 = 0.001_931_852_652_41;
/// m = omega^2 a^2 b / GM, WGS84.
const WGS84_M: f64 = 0.003_449_786_506_84;

/// Earth rotation in NED at latitude `lat` (rad/s).
#[inline]
pub fn omega_ie_n(lat_rad: f64) -> Vector3<f64> {
    let (s, c) = lat_rad.sin_cos();
    Vector3::new(OMEGA_IE_RADPS * c, 0.0, -OMEGA_IE_RADPS * s)
}

/// Transport rate (rotation of NED against ECEF) for NED velocity `v` (rad/s).
#[inline]
pub fn omega_en_n(lat_rad: f64, h_m: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let rn = prime_vertical_radius_m(lat_rad) + h_m;
    let rm = meridian_radius_m(lat_rad) + h_m;
    Vector3::new(v.y / rn, -v.x / rm, -v.y * lat_rad.tan() / rn)
}

/// Normal gravity magnitude (m/s^2): Somigliana's formula on the ellipsoid and the WGS84
/// second-order free-air reduction with height (NIMA TR8350.2, eq. 4-1 and 4-3).
#[inline]
pub fn normal_gravity_mps2(lat_rad: f64, h_m: f64) -> f64 {
    let s2 = lat_rad.sin().powi(2);
    let g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / (1.0 - WGS84_E2 * s2).sqrt();
    let a = WGS84_A;
    g0 * (1.0 - 2.0 / a * (1.0 + WGS84_F + WGS84_M - 2.0 * WGS84_F * s2) * h_m
        + 3.0 * h_m * h_m / (a * a))
}

/// Normal gravity vector in NED (along the ellipsoid normal, down) (m/s^2).
#[inline]
pub fn gravity_n(lat_rad: f64, h_m: f64) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, normal_gravity_mps2(lat_rad, h_m))
}

/// Metres per radian of latitude and of longitude at (lat, h).
#[inline]
pub fn metres_per_rad(lat_rad: f64, h_m: f64) -> (f64, f64) {
    (
        meridian_radius_m(lat_rad) + h_m,
        (prime_vertical_radius_m(lat_rad) + h_m) * lat_rad.cos(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// WGS84 normal gravity: 9.7803253 m/s^2 at the equator, 9.8321849 at the poles
    /// (NIMA TR8350.2 table 3.4), decreasing by about 3.086e-6 m/s^2 per metre of height.
    #[test]
    fn normal_gravity_matches_wgs84_values() {
        assert!((normal_gravity_mps2(0.0, 0.0) - 9.780_325_3).abs() < 1e-7);
        let pole = normal_gravity_mps2(std::f64::consts::FRAC_PI_2, 0.0);
        assert!((pole - 9.832_184_9).abs() < 1e-6, "{pole}");
        let grad = normal_gravity_mps2(0.8, 0.0) - normal_gravity_mps2(0.8, 1000.0);
        assert!((grad / 1000.0 - 3.086e-6).abs() < 0.01e-6, "{grad}");
    }
}
