//! Property tests of the frame conventions (conventions §3): rotations, angle wrapping, geodetic/ECEF,
//! ENU, UTM round trips and the ENU-to-map Jacobian. Tolerances are a few hundred ulps of the
//! quantities involved unless stated.

use kinescan::geo::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, r_enu_to_e, Geodetic};
use kinescan::geo::projection::MapFrame;
use kinescan::geo::rotations::{
    q_b_to_n, r_b_to_n, r_zyx, roll_pitch_heading, rot_x, rot_y, rot_z, wrap_pi, wrap_two_pi,
    zyx_angles,
};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Gimbal-lock margin for the z-y-x angle round trip: |y| <= pi/2 - 0.01 rad. The angle error
/// grows like eps / cos(y) <= 2e-14 there; tolerance 1e-12 rad.
const GIMBAL_MARGIN_RAD: f64 = 0.01;

fn angle() -> impl Strategy<Value = f64> {
    -PI..=PI
}

fn is_rotation(r: &Matrix3<f64>) -> bool {
    (r * r.transpose() - Matrix3::identity()).norm() < 1e-14
        && (r.determinant() - 1.0).abs() < 1e-14
}

/// Geodetic points for UTM work: latitude -80..84 deg, a zone, and a longitude up to 6 deg from
/// its central meridian (3 deg beyond the zone edge), height -100..9000 m.
fn utm_point() -> impl Strategy<Value = (MapFrame, Geodetic)> {
    (1u8..=60, -80.0..84.0f64, -6.0..6.0f64, -100.0..9000.0f64).prop_map(|(zone, lat, dlon, h)| {
        let lon = wrap_pi((6.0 * zone as f64 - 183.0 + dlon).to_radians());
        let g = Geodetic {
            lat_rad: lat.to_radians(),
            lon_rad: lon,
            h_m: h,
        };
        (MapFrame::utm(zone, lat >= 0.0).unwrap(), g)
    })
}

fn wrapped_diff(a: f64, b: f64) -> f64 {
    wrap_pi(a - b).abs()
}

/// Central-difference Jacobian of `frame.ecef_to_map` with respect to an ENU displacement at
/// `x_e`, step 1 m: truncation ~ (1 m)^2 / R^2 ~ 1e-14, rounding ~ ulp(1e7 m) / 2 m ~ 1e-9.
fn fd_jacobian(frame: &MapFrame, x_e: &Vector3<f64>) -> Matrix3<f64> {
    let g = ecef_to_geodetic(x_e);
    let r = r_enu_to_e(g.lat_rad, g.lon_rad);
    let mut j = Matrix3::zeros();
    for i in 0..3 {
        let d = r.column(i).into_owned();
        let col = (frame.ecef_to_map(&(x_e + d)) - frame.ecef_to_map(&(x_e - d))) / 2.0;
        j.set_column(i, &col);
    }
    j
}

proptest! {
    #[test]
    fn rotations_are_proper_orthonormal(x in angle(), y in angle(), z in angle()) {
        for r in [rot_x(x), rot_y(y), rot_z(z), r_zyx(x, y, z), r_b_to_n(x, y, z)] {
            prop_assert!(is_rotation(&r), "{r}");
        }
    }

    #[test]
    fn zyx_composition_order(x in angle(), y in angle(), z in angle()) {
        let explicit = rot_z(z) * rot_y(y) * rot_x(x);
        prop_assert!((r_zyx(x, y, z) - explicit).norm() < 1e-14);
        prop_assert!((r_b_to_n(x, y, z) - explicit).norm() < 1e-14);
    }

    /// For generic angles (each 0.2..1.2 rad in size) the reversed product is a different
    /// rotation: the difference is at least the size of the commutators, >= ~0.04; we require
    /// > 1e-3.
    #[test]
    fn zyx_is_not_xyz(
        x in 0.2..1.2f64, y in 0.2..1.2f64, z in 0.2..1.2f64,
        sx in any::<bool>(), sy in any::<bool>(), sz in any::<bool>(),
    ) {
        let s = |neg: bool, a: f64| if neg { -a } else { a };
        let (x, y, z) = (s(sx, x), s(sy, y), s(sz, z));
        let xyz = rot_x(x) * rot_y(y) * rot_z(z);
        prop_assert!((r_zyx(x, y, z) - xyz).norm() > 1e-3);
    }

    #[test]
    fn zyx_angles_round_trip(
        x in angle(), y in (-FRAC_PI_2 + GIMBAL_MARGIN_RAD)..(FRAC_PI_2 - GIMBAL_MARGIN_RAD),
        z in angle(),
    ) {
        let (xa, ya, za) = zyx_angles(&r_zyx(x, y, z));
        prop_assert!(wrapped_diff(xa, x) < 1e-12 && (ya - y).abs() < 1e-12);
        prop_assert!(wrapped_diff(za, z) < 1e-12);
    }

    /// Any rotation, including at and near gimbal lock (pitch within 1e-6 rad of +-pi/2, built
    /// through a quaternion so that rounding does not keep the matrix exactly of z-y-x form),
    /// survives matrix -> angles -> matrix to 1e-13.
    #[test]
    fn matrix_angles_matrix(
        x in angle(), z in angle(), dy in 0.0..1.0e-6f64, up in any::<bool>(), free in any::<bool>(),
        y_free in -FRAC_PI_2..=FRAC_PI_2,
    ) {
        let y = if free { y_free } else if up { FRAC_PI_2 - dy } else { dy - FRAC_PI_2 };
        let r = q_b_to_n(x, y, z).to_rotation_matrix().into_inner();
        let (xa, ya, za) = zyx_angles(&r);
        prop_assert!((r_zyx(xa, ya, za) - r).norm() < 1e-13, "{x} {y} {z}");
    }

    #[test]
    fn quaternion_matches_matrix(
        roll in angle(), pitch in -FRAC_PI_2..FRAC_PI_2, heading in angle(),
        v in prop::array::uniform3(-10.0..10.0f64),
    ) {
        let q = q_b_to_n(roll, pitch, heading);
        let r = r_b_to_n(roll, pitch, heading);
        prop_assert!((q.to_rotation_matrix().matrix() - r).norm() < 1e-14);
        let v = Vector3::from(v);
        prop_assert!((q * v - r * v).norm() < 1e-13);
        let (rr, pp, hh) = roll_pitch_heading(&q);
        prop_assert!((0.0..TAU).contains(&hh));
        prop_assert!((r_b_to_n(rr, pp, hh) - r).norm() < 1e-13);
    }

    /// wrap_pi lands in (-pi, pi], differs from its input by a multiple of 2 pi, and is
    /// idempotent up to one rounding of 2 pi (<= 1e-15 rad); likewise wrap_two_pi on [0, 2 pi).
    #[test]
    fn wrapping(a in -1.0e4..1.0e4f64) {
        let w = wrap_pi(a);
        prop_assert!(w > -PI && w <= PI);
        let turns = (a - w) / TAU;
        prop_assert!((turns - turns.round()).abs() < 1e-12);
        prop_assert!((wrap_pi(w) - w).abs() <= 1e-15);
        let w2 = wrap_two_pi(a);
        prop_assert!((0.0..TAU).contains(&w2));
        let turns = (a - w2) / TAU;
        prop_assert!((turns - turns.round()).abs() < 1e-12);
        prop_assert!((wrap_two_pi(w2) - w2).abs() <= 1e-15);
    }

    /// ecef_to_geodetic inverts geodetic_to_ecef for -1e4..1e5 m heights at all latitudes:
    /// 1e-12 rad in latitude and longitude (longitude away from the poles), 1e-7 m in height
    /// and 1e-8 m in position.
    #[test]
    fn geodetic_ecef_round_trip(
        lat in -FRAC_PI_2..=FRAC_PI_2, lon in angle(), h in -1.0e4..1.0e5f64,
    ) {
        let g = Geodetic { lat_rad: lat, lon_rad: lon, h_m: h };
        let x = geodetic_to_ecef(g);
        let back = ecef_to_geodetic(&x);
        prop_assert!((back.lat_rad - lat).abs() < 1e-12 && (back.h_m - h).abs() < 1e-7);
        prop_assert!(lat.cos() < 1e-6 || wrapped_diff(back.lon_rad, lon) < 1e-12);
        prop_assert!((geodetic_to_ecef(back) - x).norm() < 1e-8);
    }

    /// ENU rotation: proper orthonormal; its columns are the directions of increasing
    /// longitude, latitude and height (central differences of geodetic_to_ecef, 1e-7 rad / 1 m
    /// steps: direction error < 1e-8).
    #[test]
    fn enu_axes_point_east_north_up(
        lat in -1.5..1.5f64, lon in angle(), h in -100.0..9000.0f64,
    ) {
        let r = r_enu_to_e(lat, lon);
        prop_assert!(is_rotation(&r));
        let at = |dlat: f64, dlon: f64, dh: f64| {
            geodetic_to_ecef(Geodetic { lat_rad: lat + dlat, lon_rad: lon + dlon, h_m: h + dh })
        };
        let dirs = [
            at(0.0, 1e-7, 0.0) - at(0.0, -1e-7, 0.0),
            at(1e-7, 0.0, 0.0) - at(-1e-7, 0.0, 0.0),
            at(0.0, 0.0, 1.0) - at(0.0, 0.0, -1.0),
        ];
        for (i, d) in dirs.iter().enumerate() {
            prop_assert!((d.normalize() - r.column(i)).norm() < 1e-8, "axis {i}");
        }
    }

    /// Local ENU frame: ECEF -> ENU -> ECEF to 1e-8 m within 100 km; the origin is (0, 0, 0)
    /// and the point 10 m above it is (0, 0, 10) to 1e-8 m.
    #[test]
    fn local_enu_round_trip(
        lat in -1.5..1.5f64, lon in angle(), h in -100.0..9000.0f64,
        d in prop::array::uniform3(-1.0e5..1.0e5f64),
    ) {
        let origin = Geodetic { lat_rad: lat, lon_rad: lon, h_m: h };
        let f = MapFrame::local_enu(origin).unwrap();
        let o = geodetic_to_ecef(origin);
        prop_assert!(f.ecef_to_map(&o).norm() < 1e-8);
        let up = f.geodetic_to_map(Geodetic { h_m: h + 10.0, ..origin });
        prop_assert!((up - Vector3::new(0.0, 0.0, 10.0)).norm() < 1e-8);
        let x = o + Vector3::from(d);
        prop_assert!((f.map_to_ecef(&f.ecef_to_map(&x)) - x).norm() < 1e-8);
    }

    /// UTM forward/inverse round trip up to 6 deg from the central meridian: ECEF -> UTM ->
    /// ECEF and UTM -> ECEF -> UTM to 1e-8 m (a few ulps of 1e7 m); the ECEF and geodetic
    /// forward paths agree to 1e-8 m.
    #[test]
    fn utm_round_trip((frame, g) in utm_point()) {
        let x = geodetic_to_ecef(g);
        let m = frame.ecef_to_map(&x);
        prop_assert!((frame.geodetic_to_map(g) - m).norm() < 1e-8);
        prop_assert!((frame.map_to_ecef(&m) - x).norm() < 1e-8);
        let back = frame.map_to_geodetic(&m);
        prop_assert!((back.lat_rad - g.lat_rad).abs() < 1e-14);
        prop_assert!(wrapped_diff(back.lon_rad, g.lon_rad) < 1e-14);
        prop_assert!((frame.ecef_to_map(&frame.map_to_ecef(&m)) - m).norm() < 1e-8);
    }

    /// r_enu_to_map_axes equals central finite differences of ecef_to_map (1e-8 per entry)
    /// for UTM (within 6 deg of the central meridian), ECEF and local ENU (within 50 km).
    #[test]
    fn enu_to_map_jacobian((utm, g) in utm_point(), d in prop::array::uniform3(-5.0e4..5.0e4f64)) {
        let x = geodetic_to_ecef(g);
        let origin_e = x + Vector3::from(d);
        let enu = MapFrame::local_enu(ecef_to_geodetic(&origin_e)).unwrap();
        for f in [utm, MapFrame::Ecef, enu] {
            let j = f.r_enu_to_map_axes(&x);
            let fd = fd_jacobian(&f, &x);
            prop_assert!(crate::common::max_abs((j - fd).iter().copied()) < 1e-8, "{f}: {j} vs {fd}");
        }
    }
}

/// wrap_pi puts the seam at +-pi: both map to +pi, and just past it wraps to just above -pi.
#[test]
fn wrap_seams() {
    assert_eq!(wrap_pi(PI), PI);
    assert_eq!(wrap_pi(-PI), PI);
    assert!((wrap_pi(PI + 1e-9) - (-PI + 1e-9)).abs() < 1e-15);
    assert!((wrap_pi(-PI - 1e-9) - (PI - 1e-9)).abs() < 1e-15);
    assert_eq!(wrap_two_pi(TAU), 0.0);
    assert!(wrap_two_pi(-1e-20) < TAU);
}

/// The UTM Jacobian at the central meridian on the ellipsoid is k0 times identity (no
/// convergence, scale 0.9996).
#[test]
fn utm_jacobian_on_central_meridian() {
    let f = MapFrame::utm(32, true).unwrap();
    let x = geodetic_to_ecef(Geodetic {
        lat_rad: 0.8,
        lon_rad: 9f64.to_radians(),
        h_m: 0.0,
    });
    let j = f.r_enu_to_map_axes(&x);
    assert!((j - Matrix3::from_diagonal(&Vector3::new(0.9996, 0.9996, 1.0))).norm() < 1e-14);
}
