//! The pipeline with an `[uncertainty]` table: sigma extra dimensions in the LAS, their values,
//! rejection outside the SMRMSG span, configuration errors (the run-time overhead is measured
//! by `benches/uncertainty.rs` and `benches/end_to_end.rs`, docs/uncertainty.md, not here).

use crate::common;

use common::*;
use kinescan::georef::Sensor;
use kinescan::io::las::FRACTION_SCALE;
use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use kinescan::pipeline::config;
use kinescan::pipeline::report::RejectReason;
use kinescan::pipeline::{run, RunOptions};
use kinescan::timing::{Mirror, MirrorDirection, ScannerClock};
use kinescan::trajectory::{PoseCursor, Trajectory, TrajectoryOptions};
use kinescan::uncertainty::model::{r_e_to_map_axes, LocalLevel};
use kinescan::uncertainty::{propagate, PointGeometry};
use nalgebra::Vector3;
use std::path::Path;

const LEVER_ARM_B_M: [f64; 3] = [0.41, -0.27, -1.63];
const BORESIGHT_DEG: [f64; 3] = [1.7, -2.3, 91.4];
const TAU_S: f64 = 0.0037;
const T0_S: f64 = T_START_S + 0.013;
const PERIOD_S: f64 = 0.01;

/// Full sigma set: Table 1 "expected" of paper 003 plus timing terms.
pub(crate) const FULL: &str = r#"
[uncertainty]
sigma_lever_arm_b_m = [0.02, 0.02, 0.02]
sigma_boresight_deg = [0.02, 0.02, 0.02]
sigma_alpha_deg = 0.0055
sigma_beta_deg = 0.0055
sigma_range_m = 0.008
sigma_range_zero_m = 0.01
clock_covariance_s2 = [[1e-8, -1e-12], [-1e-12, 1e-15]]
sigma_attitude_latency_s = 0.0005
write_95 = true
write_shares = true
"#;

/// Only the SMRMSG (INS) sigmas.
const INS_ONLY: &str = r#"
[uncertainty]
sigma_lever_arm_b_m = [0.0, 0.0, 0.0]
sigma_boresight_deg = [0.0, 0.0, 0.0]
sigma_alpha_deg = 0.0
sigma_beta_deg = 0.0
sigma_range_m = 0.0
sigma_range_zero_m = 0.0
clock_covariance_s2 = [[0.0, 0.0], [0.0, 0.0]]
sigma_attitude_latency_s = 0.0
write_shares = true
"#;

fn clock() -> ScannerClock {
    ScannerClock {
        t0_s: T0_S,
        period_s: PERIOD_S,
        mirror: Mirror {
            beta_start_rad: -std::f64::consts::PI,
            direction: MirrorDirection::Increasing,
        },
    }
}

/// Profiles over the whole trajectory, `per_profile` returns each at random beta; ranges of a
/// parking-lot-like scene (flat ground 2.5 m below the scanner, nothing beyond 80 m, 5 cm of
/// noise), so consecutive returns of a profile are close as in real data.
pub(crate) fn write_profiles(path: &Path, per_profile: usize) -> Vec<RawReturn> {
    let mut w = ProfileWriter::create(path, ProfileColumns::default()).unwrap();
    let mut rng = Lcg(7);
    let profiles = ((DURATION_S - 0.1) / PERIOD_S) as u32;
    let mut all = Vec::new();
    for n in 0..profiles {
        let mut betas: Vec<f64> = (0..per_profile).map(|_| rng.range(-3.1, 3.1)).collect();
        betas.sort_by(f64::total_cmp);
        for beta in betas {
            let r = RawReturn {
                profile: n,
                intensity: 10,
                beta_rad: beta,
                range_m: min_of([2.5 / max_of([beta.cos(), 0.03]), 80.0]) + rng.range(0.0, 0.05),
                alpha_rad: 0.0,
                time_s: 0.0,
            };
            w.push(&r).unwrap();
            all.push(r);
        }
    }
    w.finish().unwrap();
    all
}

pub(crate) fn write_pipeline(dir: &Path, smrmsg: &str, uncertainty: &str) -> std::path::PathBuf {
    let text = format!(
        r#"[inputs]
sbet = "traj.sbet"
smrmsg = "{smrmsg}"
profiles = ["pass.ksprof"]

[sensor]
lever_arm_b_m = {LEVER_ARM_B_M:?}
boresight_deg = {BORESIGHT_DEG:?}
min_range_m = 1.0
max_range_m = 200.0

[time]
t0_s = {T0_S}
period_s = {PERIOD_S}
beta_start_deg = -180.0

[latency]
attitude_s = {TAU_S}

[output]
las = "out/cloud.las"
frame = {{ kind = "utm" }}
{uncertainty}"#
    );
    let path = dir.join("pipeline.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn quiet() -> RunOptions {
    RunOptions {
        threads: Some(2),
        progress: false,
        chunk_returns: 4096,
    }
}

/// With INS sigmas only, the position sigma passes straight to the point: sigma_z = down
/// sigma (0.04 m) and the horizontal sigma = sqrt(2) 0.02 m times the UTM scale factor
/// (|k - 1| <= 4e-4 near a central meridian), all variance in the INS groups.
#[test]
fn ins_sigmas_reach_the_las_along_the_map_axes() {
    let dir = tempfile::tempdir().unwrap();
    write_trajectory(dir.path());
    write_profiles(&dir.path().join("pass.ksprof"), 3);
    let path = write_pipeline(dir.path(), "traj.smrmsg", INS_ONLY);
    let mut c = std::fs::read_to_string(&path).unwrap();
    // Attitude sigmas off in this check: the SMRMSG attitude terms grow with range.
    c = c.replace("smrmsg = \"traj.smrmsg\"", "smrmsg = \"pos_only.smrmsg\"");
    std::fs::write(&path, c).unwrap();
    write_smrmsg(
        &dir.path().join("pos_only.smrmsg"),
        T_START_S,
        DURATION_S,
        [0.0; 3],
    );
    let report = run(&config::load(&path, &[]).unwrap(), &quiet()).unwrap();
    let (names, values) = read_extra(&dir.path().join("out/cloud.las"));
    let expect = [
        "range",
        "sigma_x",
        "sigma_y",
        "sigma_z",
        "share_ins_position",
        "share_ins_attitude",
        "share_lever_arm",
        "share_boresight",
        "share_scanner",
        "share_timing",
        "mirror_angle",
    ];
    assert_eq!(names, expect);
    assert_eq!(values.len() as u64, report.totals.written);
    for v in &values {
        let horiz = (v[1] as f64).hypot(v[2] as f64);
        assert!((v[3] as f64 - 0.04).abs() < 4e-6, "sigma_z {}", v[3]);
        assert!(
            (horiz / (0.02 * 2f64.sqrt()) - 1.0).abs() < 5e-4,
            "horizontal {horiz}"
        );
        assert!((v[4] - 1.0).abs() < 1e-6 && v[5..10].iter().all(|s| *s == 0.0));
    }
}

/// Every written point carries the library's propagated covariance for its return (the
/// pipeline passes the right pose, SMRMSG time, clock partials and map axes), to f32.
#[test]
fn written_sigmas_equal_the_library_propagation() {
    let dir = tempfile::tempdir().unwrap();
    let (sbet, smrmsg) = write_trajectory(dir.path());
    let raw = write_profiles(&dir.path().join("pass.ksprof"), 2);
    let path = write_pipeline(dir.path(), "traj.smrmsg", FULL);
    let loaded = config::load(&path, &[]).unwrap();
    let report = run(&loaded, &quiet()).unwrap();
    assert_eq!(report.totals.written as usize, raw.len());
    let (names, values) = read_extra(&dir.path().join("out/cloud.las"));
    assert_eq!(
        &names[1..6],
        ["sigma_x", "sigma_y", "sigma_z", "thu95", "tvu95"]
    );

    let traj = Trajectory::open(&sbet, Some(&smrmsg), TrajectoryOptions::default()).unwrap();
    let mut poses = PoseCursor::new(&traj, TAU_S, 0.0);
    let mut sig = traj.sigma_cursor().unwrap();
    let sensor = Sensor::new(
        Vector3::from(LEVER_ARM_B_M),
        Vector3::from(BORESIGHT_DEG.map(f64::to_radians)),
        0.0,
        0.0,
    );
    let frame = kinescan::geo::projection::MapFrame::utm(32, true).unwrap();
    let inputs = loaded.config.uncertainty.as_ref().unwrap().inputs();
    let mut worst: f64 = 0.0;
    for (r, v) in raw.iter().zip(&values).step_by(97) {
        let t = clock().time_of(r.profile, r.beta_rad);
        let pose = poses.at(t).unwrap();
        let geom = PointGeometry::from_pose(&pose, &sensor, 0.0, r.beta_rad, r.range_m);
        let x_e = geom.point_e(&[0.0; 18]);
        let (a, b) = clock().partials(r.profile, r.beta_rad);
        let local = LocalLevel::at(geom.lat_rad, geom.lon_rad, geom.h_m);
        let cov = propagate(
            &geom,
            &local,
            &inputs,
            &sig.at(t).unwrap(),
            [a, b],
            &r_e_to_map_axes(&frame, &x_e),
        )
        .axes();
        let s = cov.sigma_xyz_m();
        let want = [s.x, s.y, s.z, cov.thu95_m(), cov.tvu95_m()];
        let shares = cov.shares();
        // The pipeline reuses the frames within 25 m (FrameCache: < 8.5e-6 at this latitude
        // times the ratio of the other axes' sigma to its own) plus f32 rounding (6e-8);
        // measured worst 1.9e-6.
        for k in 0..5 {
            let rel = (v[1 + k] as f64 / want[k] - 1.0).abs();
            raise_max(&mut worst, rel);
            assert!(rel < 2e-5, "field {k}: {} vs {}", v[1 + k], want[k]);
        }
        // Shares are stored in steps of FRACTION_SCALE (0.004): within half a step.
        for g in 0..6 {
            let stored = f64::from(v[6 + g]);
            assert!((stored - shares[g]).abs() <= 0.5 * FRACTION_SCALE + 1e-6);
        }
    }
    println!("LAS sigmas vs library: worst relative difference {worst:e}");
}

/// Returns outside the SMRMSG span are rejected as `outside_accuracy`; the rest are written.
#[test]
fn returns_outside_the_smrmsg_span_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    write_trajectory(dir.path());
    write_smrmsg(
        &dir.path().join("short.smrmsg"),
        T_START_S + 5.0,
        10.0,
        [0.3; 3],
    );
    let raw = write_profiles(&dir.path().join("pass.ksprof"), 2);
    let path = write_pipeline(dir.path(), "short.smrmsg", FULL);
    // Half the returns are outside the SMRMSG on purpose (the default limit is 5%).
    let set = ["output.max_rejected_share = 1".to_string()];
    let report = run(&config::load(&path, &set).unwrap(), &quiet()).unwrap();
    let outside = raw
        .iter()
        .filter(|r| {
            let t = clock().time_of(r.profile, r.beta_rad);
            !(T_START_S + 5.0..=T_START_S + 15.0).contains(&t)
        })
        .count() as u64;
    assert!(outside > 0);
    let rejected = report
        .totals
        .rejected
        .get(&RejectReason::OutsideAccuracy)
        .copied();
    assert_eq!(rejected, Some(outside));
    assert_eq!(report.totals.written, raw.len() as u64 - outside);
}

/// `[uncertainty]` without an SMRMSG file, an unknown key, a negative sigma and a
/// non-positive-semi-definite clock covariance are refused, naming the key.
#[test]
fn bad_uncertainty_tables_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_pipeline(dir.path(), "traj.smrmsg", FULL);
    let text = std::fs::read_to_string(&path).unwrap();
    let cases = [
        (
            text.replace("smrmsg = \"traj.smrmsg\"\n", ""),
            "inputs.smrmsg",
        ),
        (
            text.replace("sigma_range_m", "sigma_rang_m"),
            "sigma_rang_m",
        ),
        (
            text.replace("sigma_range_m = 0.008", "sigma_range_m = -0.008"),
            "uncertainty.sigma_range_m",
        ),
        (
            text.replace("-1e-12, 1e-15", "-1e-10, 1e-15"),
            "clock_covariance_s2",
        ),
    ];
    for (bad, key) in cases {
        std::fs::write(&path, bad).unwrap();
        let err = config::load(&path, &[]).unwrap_err().to_string();
        assert!(err.contains(key), "expected `{key}` in: {err}");
    }
}

/// A CRS in US survey feet (EPSG:2263) has all three axes and the sigmas in feet (issue #24:
/// Z and the sigmas were metres beside X, Y in feet). Against the same returns written in
/// ECEF (whose ellipsoidal height is computed here) and in UTM (whose sigma_z, along the same
/// up axis, is in metres): Z_ft * 1200/3937 is the ellipsoidal height to the quantisation
/// (scale 1e-4 of either unit, so 2e-4 m with margin), sigma_z_ft * 1200/3937 is UTM's
/// sigma_z to f32 rounding (1e-6 relative), and the descriptions say (ft).
#[test]
fn a_foot_crs_has_z_and_sigmas_in_feet() {
    let dir = tempfile::tempdir().unwrap();
    write_trajectory(dir.path());
    write_profiles(&dir.path().join("pass.ksprof"), 2);
    let path = write_pipeline(dir.path(), "traj.smrmsg", FULL);
    let ft_m = 1200.0 / 3937.0;
    let mut clouds = Vec::new();
    for (frame, las) in [
        ("{ kind = \"epsg\", code = 2263 }", "out/ft.las"),
        ("{ kind = \"ecef\" }", "out/ecef.las"),
        ("{ kind = \"utm\" }", "out/utm.las"),
    ] {
        let set = [
            format!("output.frame={frame}"),
            format!("output.las=\"{las}\""),
        ];
        run(&config::load(&path, &set).unwrap(), &quiet()).unwrap();
        let file = dir.path().join(las);
        clouds.push((read_las_points(&file), read_extra(&file)));
    }
    let (ft, ecef, utm) = (&clouds[0], &clouds[1], &clouds[2]);
    assert!(ft.0.len() > 1000 && ft.0.len() == ecef.0.len() && ft.0.len() == utm.0.len());
    let z_at = |names: &[String]| names.iter().position(|n| n == "sigma_z").unwrap();
    let (kz_ft, kz_utm) = (z_at(&ft.1 .0), z_at(&utm.1 .0));
    let (mut worst_h, mut worst_sigma) = (0.0_f64, 0.0_f64);
    for k in 0..ft.0.len() {
        let (p, e) = (&ft.0[k], &ecef.0[k]);
        let h = kinescan::geo::ellipsoid::ecef_to_geodetic(&Vector3::new(e.x, e.y, e.z)).h_m;
        let dh = (p.z * ft_m - h).abs();
        let s_ft = f64::from(ft.1 .1[k][kz_ft]) * ft_m;
        let s_m = f64::from(utm.1 .1[k][kz_utm]);
        let rel = (s_ft / s_m - 1.0).abs();
        assert!(dh.is_finite() && rel.is_finite(), "point {k}");
        raise_max(&mut worst_h, dh);
        raise_max(&mut worst_sigma, rel);
    }
    assert!(worst_h < 2e-4, "Z in feet off the height by {worst_h} m");
    assert!(
        worst_sigma < 1e-6,
        "sigma_z in feet off by {worst_sigma} relative"
    );
    let header = kinescan::io::las::inspect::read_header(&dir.path().join("out/ft.las")).unwrap();
    let sigma_z = header
        .extra_dims
        .iter()
        .find(|d| d.name == "sigma_z")
        .unwrap();
    assert_eq!(sigma_z.description, "1-sigma along Z (ft)");
    assert_eq!(header.crs.unwrap().epsg, Some(2263));
}

fn read_las_points(path: &Path) -> Vec<las::Point> {
    let mut reader = las::Reader::from_path(path).unwrap();
    reader
        .read_all()
        .unwrap()
        .points()
        .map(|p| p.unwrap())
        .collect()
}
