//! The local quadratic projection agrees with the exact projection to < 1 um within its radius.

use kinescan::geo::ellipsoid::{geodetic_to_ecef, Geodetic};
use kinescan::geo::local::{LocalProjection, EXPANSION_RADIUS_M};
use kinescan::geo::projection::MapFrame;
use nalgebra::Vector3;

#[test]
fn quadratic_expansion_error_below_a_micrometre() {
    let mut worst: f64 = 0.0;
    let mut state = 7u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for &lat in &[0.0, 25.0, 48.0, 65.0, 80.0, -45.0] {
        for &dlon in &[0.0, 2.9, -6.0] {
            for &h in &[-100.0, 500.0, 9000.0] {
                let g = Geodetic {
                    lat_rad: f64::to_radians(lat),
                    lon_rad: f64::to_radians(9.0 + dlon),
                    h_m: h,
                };
                let centre = geodetic_to_ecef(g);
                let frames = [
                    MapFrame::utm(32, lat >= 0.0).unwrap(),
                    MapFrame::Ecef,
                    MapFrame::local_enu(g).unwrap(),
                ];
                for frame in frames {
                    let local = LocalProjection::new(frame, centre);
                    for _ in 0..200 {
                        let d = Vector3::new(uniform(), uniform(), uniform()).normalize()
                            * EXPANSION_RADIUS_M
                            * 0.999
                            * uniform().abs();
                        let x = centre + d;
                        crate::common::raise_max(
                            &mut worst,
                            (local.ecef_to_map(&x) - frame.ecef_to_map(&x)).norm(),
                        );
                    }
                }
            }
        }
    }
    println!("worst local-projection error {worst:.3e} m");
    assert!(worst < 1e-6, "worst {worst} m");
}
