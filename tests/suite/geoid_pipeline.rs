//! `output.geoid` in the pipeline: orthometric heights H = h - N from the committed test grid
//! (tests/data/geoid_test.gtx, tests/oracle/make_geoid_oracle.py), the compound WKT, the run
//! report, the uncertainty unchanged, and the refusals before any point is processed. Set
//! `KINESCAN_GEOID_OUT=/dir` to keep `ortho.las` for tests/laspy_check.py (pyproj reads its
//! compound CRS, in CI).

use crate::common;
use crate::pipeline_roundtrip::fixture;
use kinescan::geo::ellipsoid::ecef_to_geodetic;
use kinescan::pipeline::report::RejectReason;
use kinescan::pipeline::{config, run, RunOptions};
use std::path::{Path, PathBuf};

fn test_grid() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/geoid_test.gtx")
}

fn quiet() -> RunOptions {
    RunOptions {
        threads: Some(2),
        progress: false,
        chunk_returns: 1000,
    }
}

/// The test grid's undulation (m) by its definition in make_geoid_oracle.py (nodes every
/// 0.25 deg from 47 N, 5 E, values rounded to float32), interpolated bilinearly between nodes
/// here, independently of `geo::geoid`.
fn oracle_undulation_m(lat_deg: f64, lon_deg: f64) -> f64 {
    let node = |row: f64, col: f64| {
        let (lat, lon) = (47.0 + 0.25 * row, 5.0 + 0.25 * col);
        let n = 47.5
            + 2.5 * (3.0 * lat).to_radians().sin() * (2.0 * lon).to_radians().cos()
            + 0.04 * (lat - 49.0) * (lon - 9.0);
        f64::from(n as f32)
    };
    let (y, x) = ((lat_deg - 47.0) / 0.25, (lon_deg - 5.0) / 0.25);
    let (row, col) = (y.floor(), x.floor());
    let (fy, fx) = (y - row, x - col);
    (1.0 - fx) * (1.0 - fy) * node(row, col)
        + fx * (1.0 - fy) * node(row, col + 1.0)
        + (1.0 - fx) * fy * node(row + 1.0, col)
        + fx * fy * node(row + 1.0, col + 1.0)
}

/// The in-test interpolation reproduces pyproj's vgridshift on the committed grid
/// (tests/oracle/geoid_oracle.csv, H = h - N printed to 0.1 um), so it is an oracle for the
/// pipeline below.
#[test]
fn oracle_undulation_reproduces_pyproj() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/oracle/geoid_oracle.csv");
    let text = std::fs::read_to_string(path).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|s| s.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() >= 300);
    let worst = common::max_of(
        rows.iter()
            .map(|v| (v[2] - oracle_undulation_m(v[0], v[1]) - v[3]).abs()),
    );
    // The CSV's 0.1 um printing plus float32 node rounding differences of libm sin (1 ulp).
    assert!(worst <= 1e-6, "worst {worst} m");
}

/// Known points (2..150 m from the scanner) come back with H = h - N to a tenth of a
/// millimetre, horizontally unchanged, with the same uncertainty bytes; the WKT is compound and
/// names the grid, as does the report.
#[test]
fn orthometric_heights_are_h_minus_n_and_nothing_else_changes() {
    let f = fixture(2_000);
    let path = f.dir.path().join("pipeline.toml");
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str(crate::uncertainty_pipeline::FULL);
    std::fs::write(&path, text).unwrap();
    let ellipsoidal = run(&config::load(&path, &[]).unwrap(), &quiet()).unwrap();
    let set = [
        format!("output.geoid = {:?}", test_grid().display().to_string()),
        "output.las = \"out/ortho.las\"".to_string(),
    ];
    let ortho = run(&config::load(&path, &set).unwrap(), &quiet()).unwrap();
    assert_eq!(ellipsoidal.geoid_grid, None);
    assert_eq!(ortho.geoid_grid.as_deref(), Some("geoid_test.gtx"));
    assert!(ortho
        .files
        .iter()
        .any(|r| r.role == "geoid" && r.path == test_grid()));

    let read = |name: &str| crate::pipeline_roundtrip::read_las(&f.dir.path().join(name));
    let (h_points, big_h_points) = (read("out/cloud.las"), read("out/ortho.las"));
    assert_eq!(big_h_points.len(), f.truth_e.len());
    assert_eq!(h_points.len(), f.truth_e.len());
    let mut worst = 0.0;
    for ((p, q), x_e) in big_h_points.iter().zip(&h_points).zip(&f.truth_e) {
        let g = ecef_to_geodetic(x_e);
        let expected = g.h_m - oracle_undulation_m(g.lat_rad.to_degrees(), g.lon_rad.to_degrees());
        common::raise_max(&mut worst, (p.z - expected).abs());
        assert_eq!((p.x, p.y), (q.x, q.y), "horizontal coordinates unchanged");
        assert_eq!(
            p.extra_bytes, q.extra_bytes,
            "sigmas, shares and range unchanged"
        );
    }
    println!("worst |H - (h - N_pyproj)| = {worst:.2e} m");
    // The ellipsoidal round trip's bound (pipeline_roundtrip: <= 0.1 mm in 3D); the geoid adds
    // the lat/lon expansion's < 25 um (module docs of geo::local).
    assert!(worst <= 1e-4, "worst {worst} m");

    let wkt = common::las_wkt(&f.dir.path().join("out/ortho.las"));
    if let Some(keep) = std::env::var_os("KINESCAN_GEOID_OUT") {
        std::fs::copy(
            f.dir.path().join("out/ortho.las"),
            Path::new(&keep).join("ortho.las"),
        )
        .unwrap();
    }
    assert!(
        wkt.starts_with("COMPD_CS[\"WGS 84 / UTM zone 32N + geoid_test.gtx height\",PROJCS["),
        "{wkt}"
    );
    assert!(
        wkt.contains("VERT_CS[\"geoid_test.gtx height\",VERT_DATUM[\"geoid_test.gtx\",2005]"),
        "{wkt}"
    );
}

/// Writes a GTX grid: south-west node, steps (deg), rows south to north.
fn write_gtx<const C: usize>(path: &Path, [south, west, dlat, dlon]: [f64; 4], rows: &[[f32; C]]) {
    let mut b = Vec::new();
    for v in [south, west, dlat, dlon] {
        b.extend(v.to_be_bytes());
    }
    b.extend((rows.len() as i32).to_be_bytes());
    b.extend((rows[0].len() as i32).to_be_bytes());
    for v in rows.iter().flatten() {
        b.extend(v.to_be_bytes());
    }
    std::fs::write(path, b).unwrap();
}

/// A grid that misses the survey, or whose edge lies within the scanner's reach of the
/// trajectory, is refused naming the key and the file before any point is written; so is a
/// missing grid and a geoid with a frame that has no height axis.
#[test]
fn grids_not_covering_the_survey_are_refused_before_any_point() {
    let f = fixture(200);
    let dir = f.dir.path();
    let path = dir.join("pipeline.toml");
    // Trajectory: a 30 m circle north and east of 48.137 N, 11.575 E; reach 200 m + lever arm.
    let far = dir.join("far.gtx");
    write_gtx(&far, [40.0, 1.0, 0.5, 0.5], &[[45.0; 2]; 2]);
    let edge = dir.join("edge.gtx");
    // North edge at 48.1385 N: about 140 m north of the trajectory's north end.
    write_gtx(&edge, [48.1335, 11.57, 0.0025, 0.01], &[[45.0; 2]; 3]);
    for (grid, why) in [
        (far.clone(), "would fall outside"),
        (edge.clone(), "would fall outside"),
        (dir.join("missing.gtx"), "No such file"),
    ] {
        let set = [format!("output.geoid = {:?}", grid.display().to_string())];
        let err = run(&config::load(&path, &set).unwrap(), &quiet())
            .unwrap_err()
            .to_string();
        let file = grid.display().to_string();
        assert!(
            err.contains("output.geoid") && err.contains(&file) && err.contains(why),
            "{err}"
        );
        assert!(!dir.join("out/cloud.las").exists(), "no output published");
    }
    // The same grid widened to 48.1435 N covers the reach: the run goes through.
    write_gtx(&edge, [48.1335, 11.57, 0.0025, 0.01], &[[45.0; 2]; 5]);
    let set = [format!("output.geoid = {:?}", edge.display().to_string())];
    let report = run(&config::load(&path, &set).unwrap(), &quiet()).unwrap();
    assert_eq!(report.totals.written, f.truth_e.len() as u64);
    for frame in [
        "{ kind = \"ecef\" }",
        "{ kind = \"enu\", lat_deg = 48.1, lon_deg = 11.5, h_m = 500.0 }",
    ] {
        let set = [
            format!("output.geoid = {:?}", edge.display().to_string()),
            format!("output.frame = {frame}"),
        ];
        let err = config::load(&path, &set).unwrap_err().to_string();
        assert!(err.contains("output.geoid") && err.contains("utm"), "{err}");
    }
}

/// A no-data node under the points rejects them with their reason (counted, not written).
#[test]
fn no_data_nodes_reject_points_with_their_reason() {
    let f = fixture(200);
    let dir = f.dir.path();
    let grid = dir.join("holes.gtx");
    let no_data = -88.8888f32;
    write_gtx(
        &grid,
        [48.0, 11.4, 0.5, 0.5],
        &[[45.0, 45.0], [no_data, 45.0]],
    );
    let set = [
        format!("output.geoid = {:?}", grid.display().to_string()),
        "output.allow_empty = true".to_string(),
        // Every point is rejected on purpose (issue #23's limit is 5% by default).
        "output.max_rejected_share = 1".to_string(),
    ];
    let report = run(
        &config::load(&dir.join("pipeline.toml"), &set).unwrap(),
        &quiet(),
    )
    .unwrap();
    assert_eq!(report.totals.written, 0);
    assert_eq!(
        report
            .totals
            .rejected
            .get(&RejectReason::NoGeoidValue)
            .copied(),
        Some(f.truth_e.len() as u64)
    );
}
