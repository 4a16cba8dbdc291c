//! The reference files agree with the scene the returns came from: true points near a
//! reference patch lie on its plane, true points near a sphere's control point lie on the
//! sphere, and returns from a sync target's face are saturated. Also checks the optional CSV
//! profiles mirror the binary ones.

use crate::sim_support;
use kinescan::io::patches::read_patches;
use kinescan::io::points::read_control_points;
use kinescan::io::profiles::ProfileFile;
use kinescan::sim::read_truth_points;
use nalgebra::Vector3;
use sim_support::*;

#[test]
fn patches_and_control_points_match_the_scanned_scene() {
    let mut sc = base();
    sc.output.profiles_csv = true;
    sc.duration_s = 22.0;
    let dir = tempfile::tempdir().unwrap();
    run(&sc, dir.path(), 2);
    let d = dir.path();
    let truth: Vec<Vector3<f64>> = read_truth_points(&d.join("truth_points.bin"))
        .unwrap()
        .into_iter()
        .filter(|p| !p[0].is_nan())
        .map(Vector3::from)
        .collect();
    let patches = read_patches(&d.join("patches.csv")).unwrap();
    let (mut facades, mut ground) = (0, 0);
    for p in &patches {
        let mut on = 0;
        for x in &truth {
            let c = p.patch_coords_m(x);
            let inside = c.x.abs() < p.half_length_m - 0.05 && c.y.abs() < p.half_height_m - 0.05;
            // Nothing stands within 0.3 m of a facade or the street centre: any true point
            // there is on the patch plane (to float precision).
            if inside && c.z.abs() < 0.3 {
                assert!(
                    c.z.abs() < 1e-6,
                    "{}: point {:.2e} m off the plane",
                    p.id,
                    c.z
                );
                on += 1;
            }
        }
        if p.id.starts_with("FAC") {
            // Listed because it was hit often enough: its rectangle must hold points.
            assert!(on > 0, "{}: no points on a listed facade", p.id);
            facades += 1;
        } else {
            ground += (on > 0) as usize;
        }
    }
    println!(
        "{} patches: {facades} facades and {ground} ground squares with points",
        patches.len()
    );
    assert!(facades >= 2 && ground >= 3);
    let points = read_control_points(&d.join("control_points.csv")).unwrap();
    let ecef = |p: &kinescan::io::points::ControlPoint| {
        kinescan::geo::ellipsoid::geodetic_to_ecef(kinescan::geo::ellipsoid::Geodetic {
            lat_rad: p.lat_rad,
            lon_rad: p.lon_rad,
            h_m: p.h_m,
        })
    };
    let r = sc.scene.sphere_radius_m;
    let mut spheres_hit = 0;
    for p in points.iter().filter(|p| p.id.starts_with("SPH")) {
        let c = ecef(p);
        let near: Vec<f64> = truth
            .iter()
            .map(|x| (x - c).norm())
            .filter(|&d| d < r + 0.1)
            .collect();
        for d in &near {
            assert!(
                (d - r).abs() < 1e-6,
                "{}: point {d} m from the centre",
                p.id
            );
        }
        spheres_hit += (near.len() >= 3) as usize;
    }
    assert!(spheres_hit >= 1);
    let prof = ProfileFile::open(&d.join("profiles.bin")).unwrap();
    let all = read_truth_points(&d.join("truth_points.bin")).unwrap();
    let mut sync_hits = 0;
    for p in points.iter().filter(|p| p.id.starts_with("SYNC")) {
        let c = ecef(p);
        for (i, x) in all.iter().enumerate() {
            if !x[0].is_nan() && (Vector3::from(*x) - c).norm() < 0.2 {
                assert_eq!(
                    prof.get(i).intensity,
                    u16::MAX,
                    "{}: return {i} not saturated",
                    p.id
                );
                sync_hits += 1;
            }
        }
    }
    assert!(sync_hits >= 5, "{sync_hits} returns on sync targets");
    // CSV profiles: header plus one line per return.
    let csv = std::fs::read_to_string(d.join("profiles.csv")).unwrap();
    assert!(csv.starts_with("profile,beta_rad,range_m,intensity"));
    assert_eq!(csv.lines().count(), prof.len() + 1);
}
