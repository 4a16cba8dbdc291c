//! Projected CRSs by EPSG code against PROJ: every point of a short simulated survey per CRS
//! (tests/oracle/epsg_oracle.csv, written and checked in CI by make_epsg_oracle.py with pyproj)
//! through the pipeline's mechanism (the projection expanded about the vehicle, re-expanded
//! every 100 m) to <= 1 mm, and sigmas rotated by kinescan's map-axes Jacobian against the same
//! covariance rotated by pyproj's Jacobian to 1e-6 relative.

use std::collections::BTreeMap;

use kinescan::geo::local::LocalProjection;
use kinescan::geo::projection::MapFrame;
use kinescan::uncertainty::model::r_e_to_map_axes;
use nalgebra::{Matrix3, Vector3};

/// The pipeline re-expands the projection when the vehicle has moved this far (m).
const RECENTRE_M: f64 = 100.0;

struct Row {
    code: u32,
    class: String,
    vehicle_e: Vector3<f64>,
    x_e: Vector3<f64>,
    map: Vector3<f64>,
    jacobian: Matrix3<f64>,
}

fn rows() -> Vec<Row> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/oracle/epsg_oracle.csv");
    let text = std::fs::read_to_string(path).expect("oracle CSV");
    text.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let v = |i: usize| f[i].parse::<f64>().expect("number");
            let v3 = |i: usize| Vector3::new(v(i), v(i + 1), v(i + 2));
            Row {
                code: f[0].parse().expect("code"),
                class: f[1].to_string(),
                vehicle_e: v3(3),
                x_e: v3(6),
                map: v3(9),
                jacobian: Matrix3::from_row_iterator((12..21).map(v)),
            }
        })
        .collect()
}

/// A full, correlated ECEF covariance (m^2) of centimetre size.
fn covariance_e() -> Matrix3<f64> {
    let a = Matrix3::new(0.02, 0.0, 0.0, 0.006, 0.015, 0.0, -0.004, 0.009, 0.03);
    a * a.transpose()
}

fn sigmas(j: &Matrix3<f64>) -> Vector3<f64> {
    (j * covariance_e() * j.transpose())
        .diagonal()
        .map(f64::sqrt)
}

#[test]
fn epsg_frames_match_pyproj() {
    let rows = rows();
    let mut by_code: BTreeMap<u32, Vec<&Row>> = BTreeMap::new();
    for r in &rows {
        by_code.entry(r.code).or_default().push(r);
    }
    assert!(by_code.len() >= 20, "only {} CRSs", by_code.len());
    let mut worst_by_class: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
    let mut failures = Vec::new();
    for (code, survey) in &by_code {
        let mut worst = (0.0, 0.0);
        let frame = MapFrame::from_epsg(*code).unwrap();
        let MapFrame::Epsg { crs } = frame else {
            unreachable!()
        };
        let unit = crs.metres_per_unit();
        let mut local: Option<LocalProjection> = None;
        for r in survey {
            if local
                .as_ref()
                .is_none_or(|l| (l.centre_e() - r.vehicle_e).norm() > RECENTRE_M)
            {
                local = Some(LocalProjection::new(frame, r.vehicle_e));
            }
            let got = local.as_ref().unwrap().ecef_to_map(&r.x_e);
            let d = got - r.map;
            // Horizontal difference in metres whatever the CRS unit; height in metres.
            let err_m = Vector3::new(d.x * unit, d.y * unit, d.z).norm();
            let (s_k, s_o) = (
                sigmas(&r_e_to_map_axes(&frame, &r.x_e)),
                sigmas(&r.jacobian),
            );
            let rel = crate::common::max_abs((s_k - s_o).component_div(&s_o).iter().copied());
            let w = worst_by_class.entry(r.class.as_str()).or_default();
            crate::common::raise_max(&mut w.0, err_m);
            crate::common::raise_max(&mut w.1, rel);
            crate::common::raise_max(&mut worst.0, err_m);
            crate::common::raise_max(&mut worst.1, rel);
        }
        println!(
            "EPSG:{code}: position {:.2e} m, sigma {:.2e} relative",
            worst.0, worst.1
        );
        if worst.0 > 1e-3 || worst.1 > 1e-6 {
            failures.push(*code);
        }
    }
    for (class, (pos, sig)) in worst_by_class {
        println!("{class:>26}: position {pos:.2e} m, sigma {sig:.2e} relative");
    }
    assert!(
        failures.is_empty(),
        "beyond 1 mm or 1e-6: EPSG {failures:?}"
    );
}

/// The expansion about the vehicle against the exact projection, for every CRS of the oracle,
/// points anywhere within the expansion radius of a centre at the survey's start.
#[test]
fn epsg_local_expansion_error_below_a_micrometre() {
    use kinescan::geo::local::EXPANSION_RADIUS_M;
    let mut rng = crate::common::Lcg(11);
    let mut worst: f64 = 0.0;
    let mut starts: BTreeMap<u32, Vector3<f64>> = BTreeMap::new();
    for r in rows() {
        starts.entry(r.code).or_insert(r.vehicle_e);
    }
    for (code, centre) in starts {
        let frame = MapFrame::from_epsg(code).unwrap();
        let MapFrame::Epsg { crs } = frame else {
            unreachable!()
        };
        let local = LocalProjection::new(frame, centre);
        for _ in 0..300 {
            let d = Vector3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize()
                * EXPANSION_RADIUS_M
                * 0.999
                * rng.uniform();
            let x = centre + d;
            let diff = local.ecef_to_map(&x) - frame.ecef_to_map(&x);
            let unit = crs.metres_per_unit();
            let err_m = Vector3::new(diff.x * unit, diff.y * unit, diff.z).norm();
            crate::common::raise_max(&mut worst, err_m);
        }
    }
    println!("worst EPSG local-projection error {worst:.3e} m");
    assert!(worst < 1e-6, "worst {worst} m");
}
