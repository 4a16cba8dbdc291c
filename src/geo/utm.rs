//! The transverse Mercator projection of UTM zones: the Krüger n-series to sixth order in the
//! third flattening `n` (Karney 2011, eqs. 7-11, 35-36), evaluated with Clenshaw summation in
//! complex arithmetic, and the trig-free ECEF -> latitude step (see `projection` for accuracy
//! and speed).

use std::sync::LazyLock;

use nalgebra::{Complex, Vector3};

use super::ellipsoid::{ecef_to_geodetic, WGS84_A, WGS84_E2, WGS84_F};

/// UTM central scale factor.
pub const UTM_K0: f64 = 0.9996;
/// UTM false easting (m).
pub const UTM_FALSE_EASTING_M: f64 = 500_000.0;
/// UTM false northing in the southern hemisphere (m).
pub const UTM_FALSE_NORTHING_SOUTH_M: f64 = 10_000_000.0;

/// Third flattening n = f / (2 - f).
const N: f64 = WGS84_F / (2.0 - WGS84_F);
/// Rectifying radius A = a / (1 + n) * (1 + n^2/4 + n^4/64 + n^6/256) (Karney eq. 14).
pub(super) const RECT_A_M: f64 = {
    let n2 = N * N;
    WGS84_A / (1.0 + N) * (1.0 + n2 / 4.0 + n2 * n2 / 64.0 + n2 * n2 * n2 / 256.0)
};

/// Krüger coefficients alpha_1..6 (forward, Karney eq. 35) as polynomials in `n`.
macro_rules! kruger_alpha {
    ($n:expr) => {{
        let n: f64 = $n;
        let (n2, n3) = (n * n, n * n * n);
        let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
        [
            n / 2.0 - 2.0 / 3.0 * n2 + 5.0 / 16.0 * n3 + 41.0 / 180.0 * n4 - 127.0 / 288.0 * n5
                + 7891.0 / 37800.0 * n6,
            13.0 / 48.0 * n2 - 3.0 / 5.0 * n3 + 557.0 / 1440.0 * n4 + 281.0 / 630.0 * n5
                - 1983433.0 / 1935360.0 * n6,
            61.0 / 240.0 * n3 - 103.0 / 140.0 * n4
                + 15061.0 / 26880.0 * n5
                + 167603.0 / 181440.0 * n6,
            49561.0 / 161280.0 * n4 - 179.0 / 168.0 * n5 + 6601661.0 / 7257600.0 * n6,
            34729.0 / 80640.0 * n5 - 3418889.0 / 1995840.0 * n6,
            212378941.0 / 319334400.0 * n6,
        ]
    }};
}

/// Krüger coefficients beta_1..6 (inverse, Karney eq. 36) as polynomials in `n`.
macro_rules! kruger_beta {
    ($n:expr) => {{
        let n: f64 = $n;
        let (n2, n3) = (n * n, n * n * n);
        let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
        [
            n / 2.0 - 2.0 / 3.0 * n2 + 37.0 / 96.0 * n3 - 1.0 / 360.0 * n4 - 81.0 / 512.0 * n5
                + 96199.0 / 604800.0 * n6,
            n2 / 48.0 + n3 / 15.0 - 437.0 / 1440.0 * n4 + 46.0 / 105.0 * n5
                - 1118711.0 / 3870720.0 * n6,
            17.0 / 480.0 * n3 - 37.0 / 840.0 * n4 - 209.0 / 4480.0 * n5 + 5569.0 / 90720.0 * n6,
            4397.0 / 161280.0 * n4 - 11.0 / 504.0 * n5 - 830251.0 / 7257600.0 * n6,
            4583.0 / 161280.0 * n5 - 108847.0 / 3991680.0 * n6,
            20648693.0 / 638668800.0 * n6,
        ]
    }};
}

const ALPHA: [f64; 6] = kruger_alpha!(N);
const BETA: [f64; 6] = kruger_beta!(N);

/// (latitude functions, sin(dlon), cos(dlon), h) of an ECEF point for UTM zone `zone`, dlon
/// the longitude from the central meridian: the trig-free [`ecef_to_lat_h`] plus a rotation of
/// (x, y).
#[inline]
pub(super) fn utm_point(zone: u8, x_e: &Vector3<f64>) -> (Lat, f64, f64, f64) {
    let p = (x_e.x * x_e.x + x_e.y * x_e.y).sqrt();
    if p < 1e-3 {
        // Within 1 mm of the polar axis: longitude undefined, any value will do.
        let g = ecef_to_geodetic(x_e);
        let (s, c) = (g.lon_rad - central_meridian_rad(zone)).sin_cos();
        return (Lat::from_rad(g.lat_rad), s, c, g.h_m);
    }
    let inv_p = 1.0 / p;
    let (lat, h_m) = ecef_to_lat_h(p, inv_p, x_e.z);
    let (s0, c0) = central_meridian_sin_cos(zone);
    (
        lat,
        (x_e.y * c0 - x_e.x * s0) * inv_p,
        (x_e.x * c0 + x_e.y * s0) * inv_p,
        h_m,
    )
}

/// Central meridian of UTM zone `zone` (rad).
#[inline]
pub(super) fn central_meridian_rad(zone: u8) -> f64 {
    (6.0 * zone as f64 - 183.0).to_radians()
}

/// (sin, cos) of the central meridian of `zone` (1..=60; others computed on the fly).
#[inline]
fn central_meridian_sin_cos(zone: u8) -> (f64, f64) {
    static TABLE: LazyLock<[(f64, f64); 60]> =
        LazyLock::new(|| std::array::from_fn(|i| central_meridian_rad(i as u8 + 1).sin_cos()));
    match zone {
        1..=60 => TABLE[zone as usize - 1],
        _ => central_meridian_rad(zone).sin_cos(),
    }
}

#[inline]
pub(super) fn false_northing_m(north: bool) -> f64 {
    if north {
        0.0
    } else {
        UTM_FALSE_NORTHING_SOUTH_M
    }
}

/// tan, sec and sin of a latitude (the forms the projection works with).
#[derive(Debug, Clone, Copy)]
pub(super) struct Lat {
    tan: f64,
    sec: f64,
    pub(super) sin: f64,
    cos: f64,
}

impl Lat {
    #[inline]
    pub(super) fn from_rad(lat_rad: f64) -> Self {
        let (s, c) = lat_rad.sin_cos();
        Lat {
            tan: s / c,
            sec: 1.0 / c,
            sin: s,
            cos: c,
        }
    }

    #[inline]
    fn from_tan(tan: f64) -> Self {
        let sec = (1.0 + tan * tan).sqrt();
        let cos = 1.0 / sec;
        Lat {
            tan,
            sec,
            sin: tan * cos,
            cos,
        }
    }
}

/// tan of the conformal latitude, tau' = tau sqrt(1+sigma^2) - sigma sqrt(1+tau^2),
/// sigma = sinh(e atanh(e sin(lat))) (Karney eqs. 7-9).
#[inline]
fn tau_prime(lat: Lat) -> f64 {
    // x = e atanh(e s) = e^2 s sum_k u^k / (2k+1), u = e^2 s^2 <= 0.0067: terms k <= 6 leave
    // e^2 u^7 / 15 < 3e-19 absolute in x; summed by Estrin's scheme (short dependency chain).
    // sinh(x), x <= 0.0068, by Taylor to x^7 (next term 4e-25).
    let u = WGS84_E2 * lat.sin * lat.sin;
    let (u2, u4) = (u * u, u * u * u * u);
    let series =
        (1.0 + u / 3.0 + u2 * (1.0 / 5.0 + u / 7.0)) + u4 * (1.0 / 9.0 + u / 11.0 + u2 / 13.0);
    let x = WGS84_E2 * lat.sin * series;
    let x2 = x * x;
    let sigma = x * (1.0 + x2 / 6.0 * (1.0 + x2 / 20.0 * (1.0 + x2 / 42.0)));
    lat.tan * (1.0 + sigma * sigma).sqrt() - sigma * lat.sec
}

/// ECEF to geodetic latitude functions and ellipsoidal height (m), from the distance from the
/// polar axis `p_m` (> 0) and `z_m`. Newton's method on t = tan(lat),
/// f(t) = p t - z - e^2 a t / sqrt(1 + (1 - e^2) t^2), from the h = 0 solution, with no
/// trigonometry. Newton's error contracts as e_{k+1} <= 0.01 e_k^2 (|f''/2f'| <= 1.5 e^2), so
/// stopping once |dt| <= 1e-8 max(|t|, 1) leaves < 1e-18 rad: two steps for |h| < 1e5 m
/// (checked against [`ecef_to_geodetic`] to 1e-14 rad and 1e-8 m in the unit tests).
#[inline]
fn ecef_to_lat_h(p_m: f64, inv_p: f64, z_m: f64) -> (Lat, f64) {
    const ONE_M_E2: f64 = 1.0 - WGS84_E2;
    const E2A: f64 = WGS84_E2 * WGS84_A;
    let mut t = z_m * inv_p * (1.0 / ONE_M_E2);
    for _ in 0..8 {
        let inv_w = 1.0 / (1.0 + ONE_M_E2 * t * t).sqrt();
        let f = p_m * t - z_m - E2A * t * inv_w;
        let dt = f / (p_m - E2A * inv_w * inv_w * inv_w);
        t -= dt;
        if dt.abs() <= 1e-8 * t.abs().max(1.0) {
            break;
        }
    }
    let lat = Lat::from_tan(t);
    // h = p cos + z sin - a sqrt(1 - e^2 sin^2) = (p + z t - a sqrt(1 + (1 - e^2) t^2)) / sec.
    let h_m = (p_m + z_m * t - WGS84_A * (1.0 + ONE_M_E2 * t * t).sqrt()) * lat.cos;
    (lat, h_m)
}

/// A point on the Gauss-Schreiber (conformal-sphere) transverse Mercator, zeta' = xi' + i eta'.
struct GaussSchreiber {
    /// tan of the conformal latitude.
    taup: f64,
    /// sqrt(1 + tau'^2).
    sec_p: f64,
    /// 1 / sqrt(tau'^2 + cos^2(dlon)).
    inv_r: f64,
    /// 1 / (tau'^2 + cos^2(dlon)).
    inv_r2: f64,
    /// sin(2 zeta').
    s2: Complex<f64>,
    /// cos(2 zeta').
    c2: Complex<f64>,
}

/// Gauss-Schreiber point from tan(lat) and the sine/cosine of the longitude from the central
/// meridian (Karney eqs. 7-10), with the double-angle functions of zeta' obtained
/// algebraically (no transcendental functions beyond those in [`tau_prime`]).
#[inline]
fn gauss_schreiber(lat: Lat, sin_dlon: f64, cos_dlon: f64) -> GaussSchreiber {
    let taup = tau_prime(lat);
    let sec_p = (1.0 + taup * taup).sqrt();
    let inv_r = 1.0 / (taup * taup + cos_dlon * cos_dlon).sqrt();
    let inv_r2 = inv_r * inv_r;
    // sin(xi') = tau'/r, cos(xi') = cos(dlon)/r, sinh(eta') = sin(dlon)/r, cosh(eta') = sec'/r.
    let sin2 = 2.0 * taup * cos_dlon * inv_r2;
    let cos2 = (cos_dlon * cos_dlon - taup * taup) * inv_r2;
    let sinh2 = 2.0 * sin_dlon * sec_p * inv_r2;
    let cosh2 = 1.0 + 2.0 * sin_dlon * sin_dlon * inv_r2;
    GaussSchreiber {
        taup,
        sec_p,
        inv_r,
        inv_r2,
        s2: Complex::new(sin2 * cosh2, cos2 * sinh2),
        c2: Complex::new(cos2 * cosh2, -sin2 * sinh2),
    }
}

/// Forward TM: zeta = xi + i eta (northing and easting over k0 A) from the latitude and the
/// sine/cosine of the longitude from the central meridian (Karney eq. 11).
#[inline]
pub(super) fn tm_zeta(lat: Lat, sin_dlon: f64, cos_dlon: f64) -> Complex<f64> {
    let gs = gauss_schreiber(lat, sin_dlon, cos_dlon);
    let xip = gs.taup.atan2(cos_dlon);
    // eta' = asinh(x), x = sin(dlon)/r, = ln_1p(x + x^2 / (1 + sqrt(1 + x^2))), sqrt(1 + x^2) = sec'/r.
    let x = sin_dlon * gs.inv_r;
    let etap = (x + x * x / (1.0 + gs.sec_p * gs.inv_r)).ln_1p();
    Complex::new(xip, etap) + clenshaw_sin(&ALPHA, gs.s2, gs.c2)
}

/// Sum_j a_j sin(2 j z) by Clenshaw, given sin(2z) and cos(2z) (complex).
#[inline]
fn clenshaw_sin(a: &[f64; 6], s2: Complex<f64>, c2: Complex<f64>) -> Complex<f64> {
    let x = c2 * 2.0;
    let (mut b1, mut b2) = (Complex::new(0.0, 0.0), Complex::new(0.0, 0.0));
    for &ak in a.iter().rev() {
        let b0 = x * b1 - b2 + ak;
        b2 = b1;
        b1 = b0;
    }
    b1 * s2
}

/// Sum_j 2 j a_j cos(2 j z) by Clenshaw, given cos(2z) (complex).
#[inline]
fn clenshaw_dcos(a: &[f64; 6], c2: Complex<f64>) -> Complex<f64> {
    let x = c2 * 2.0;
    let (mut b1, mut b2) = (Complex::new(0.0, 0.0), Complex::new(0.0, 0.0));
    for (j, &ak) in a.iter().enumerate().rev() {
        let b0 = x * b1 - b2 + 2.0 * (j + 1) as f64 * ak;
        b2 = b1;
        b1 = b0;
    }
    b1 * c2 - b2
}

/// `k exp(i gamma)`: UTM point scale factor k and grid convergence gamma (rad, bearing of
/// grid north clockwise from true north) as one complex number, from tan(lat) and the
/// sine/cosine of the longitude from the central meridian (Karney eqs. 12-13, 16-17, with the
/// angles combined as unit complex numbers instead of atan2 and sin/cos).
#[inline]
pub(super) fn tm_scale_convergence(lat: Lat, sin_dlon: f64, cos_dlon: f64) -> Complex<f64> {
    let gs = gauss_schreiber(lat, sin_dlon, cos_dlon);
    // Sphere: k' = sqrt(1 - e^2 sin^2 lat) sec(lat) / r; gamma' = arg(sec' cos + i tau' sin),
    // whose modulus is r.
    let k_gamma_sphere = Complex::new(gs.sec_p * cos_dlon, gs.taup * sin_dlon)
        * ((1.0 - WGS84_E2 * lat.sin * lat.sin).sqrt() * lat.sec * gs.inv_r2);
    // d zeta / d zeta' = p - i q: scales by |.| and turns gamma by -arg(.).
    let w = Complex::new(1.0, 0.0) + clenshaw_dcos(&ALPHA, gs.c2);
    k_gamma_sphere * w.conj() * (UTM_K0 * RECT_A_M / WGS84_A)
}

/// Inverse TM: zeta = xi + i eta (northing and easting over k0 A) to (lat, dlon) in rad
/// (Karney eqs. 11, 15, 18-21; Newton on tau converges to 1e-15 relative in <= 4 steps).
pub(super) fn tm_inverse(zeta: Complex<f64>) -> (f64, f64) {
    let zetap = zeta - clenshaw_sin(&BETA, (zeta * 2.0).sin(), (zeta * 2.0).cos());
    let (sin_xip, cos_xip) = zetap.re.sin_cos();
    let sinh_etap = zetap.im.sinh();
    let taup = sin_xip / sinh_etap.hypot(cos_xip);
    let dlon = sinh_etap.atan2(cos_xip);
    let one_m_e2 = 1.0 - WGS84_E2;
    let mut tau = taup / one_m_e2;
    for _ in 0..6 {
        let taupi = tau_prime(Lat::from_tan(tau));
        let dtau = (taup - taupi) * (1.0 + one_m_e2 * tau * tau)
            / (one_m_e2 * taupi.hypot(1.0) * tau.hypot(1.0));
        tau += dtau;
        if dtau.abs() <= 1e-15 * tau.abs().max(1.0) {
            break;
        }
    }
    (tau.atan(), dlon)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::ellipsoid::{geodetic_to_ecef, Geodetic};

    /// Checks the Krüger coefficient polynomials against the exact latitude functions they
    /// expand: on the central meridian xi = mu (rectifying latitude) and xi' = chi (conformal
    /// latitude), so mu = chi + sum alpha_j sin(2 j chi) and chi = mu - sum beta_j sin(2 j mu).
    /// With an exaggerated n = 0.01 the sixth-order truncation is O(n^7) = O(1e-14) rad
    /// (measured <= 7e-14, and it scales as n^7 between n = 0.01 and 0.02), while an error of
    /// 0.2 in any n^6 coefficient shows as 2e-13 rad and lower-order errors far more: tolerance
    /// 2e-13 rad.
    #[test]
    fn kruger_coefficients_expand_exact_latitudes() {
        let n = 0.01_f64;
        let e2 = 4.0 * n / ((1.0 + n) * (1.0 + n));
        let alpha: [f64; 6] = kruger_alpha!(n);
        let beta: [f64; 6] = kruger_beta!(n);
        // Meridian arc / (semi-major axis), by composite Gauss-Legendre (exact to ~1e-16).
        let arc = |phi: f64| {
            let nodes = [
                (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
                (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
                (0.0, 0.568_888_888_888_888_9),
                (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
                (0.906_179_845_938_664, 0.236_926_885_056_189_1),
            ];
            let m = 400;
            let h = phi / m as f64;
            (0..m)
                .map(|i| {
                    let mid = (i as f64 + 0.5) * h;
                    nodes
                        .iter()
                        .map(|&(x, w)| {
                            let s = (mid + 0.5 * h * x).sin();
                            w * 0.5 * h * (1.0 - e2) / (1.0 - e2 * s * s).powf(1.5)
                        })
                        .sum::<f64>()
                })
                .sum::<f64>()
        };
        let quarter = arc(std::f64::consts::FRAC_PI_2);
        let e = e2.sqrt();
        for i in 1..18 {
            let phi = i as f64 * 5.0_f64.to_radians();
            let s = phi.sin();
            let chi = (s.atanh() - e * (e * s).atanh()).sinh().atan();
            let mu = arc(phi) / quarter * std::f64::consts::FRAC_PI_2;
            let sum = |c: &[f64; 6], x: f64| {
                c.iter()
                    .enumerate()
                    .map(|(j, a)| a * (2.0 * (j + 1) as f64 * x).sin())
                    .sum::<f64>()
            };
            assert!((chi + sum(&alpha, chi) - mu).abs() < 2e-13, "alpha at {i}");
            assert!((mu - sum(&beta, mu) - chi).abs() < 2e-13, "beta at {i}");
        }
    }

    /// The trig-free ECEF solver matches `ecef_to_geodetic` (itself tested to 1e-12 rad and
    /// 1e-7 m) to 1e-14 rad and 1e-8 m from -1e4 m to 1e5 m height, equator to 89.99 deg.
    #[test]
    fn tan_lat_solver_matches_ecef_to_geodetic() {
        for &lat_deg in &[
            -89.99, -84.0, -45.0, -1e-7, 0.0, 0.3, 30.0, 60.0, 80.0, 89.99,
        ] {
            for &h in &[-1.0e4, -100.0, 0.0, 9000.0, 1.0e5] {
                let g = Geodetic {
                    lat_rad: f64::to_radians(lat_deg),
                    lon_rad: 0.4,
                    h_m: h,
                };
                let x = geodetic_to_ecef(g);
                let p = x.x.hypot(x.y);
                let (lat, h_m) = ecef_to_lat_h(p, 1.0 / p, x.z);
                let t = lat.tan;
                let r = ecef_to_geodetic(&x);
                assert!((t.atan() - r.lat_rad).abs() < 1e-14, "{lat_deg} {h}");
                assert!((h_m - r.h_m).abs() < 1e-8, "{lat_deg} {h} {h_m} {}", r.h_m);
            }
        }
    }

    /// The series forms of e atanh(e s) and sinh in `tau_prime` equal the library functions.
    #[test]
    fn tau_prime_series_matches_closed_form() {
        for i in -89..=89 {
            let tau = (i as f64).to_radians().tan();
            let (sec, e) = (tau.hypot(1.0), WGS84_E2.sqrt());
            let sigma = (e * (e * tau / sec).atanh()).sinh();
            let exact = tau * sigma.hypot(1.0) - sigma * sec;
            assert!(
                (tau_prime(Lat::from_tan(tau)) - exact).abs()
                    <= 4.0 * f64::EPSILON * exact.abs().max(1.0)
            );
        }
    }
}
