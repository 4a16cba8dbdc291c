//! `kinescan tpu` (SPEC §9, docs/tpu.md): per-point uncertainty for an existing cloud. The
//! round trip (`run` then `tpu` on its LAS gives `run`'s sigmas), the copy keeps every record
//! and VLR, and bad inputs are refused or counted naming the file and point, nothing published.

use crate::common::*;
use crate::uncertainty_pipeline::{write_pipeline, write_profiles, FULL};
use kinescan::app::tpu::recover::PointReject;
use kinescan::app::tpu::{tpu, TpuOptions};
use kinescan::pipeline::{config, run, RunOptions};
use std::path::Path;

fn quiet_run() -> RunOptions {
    RunOptions {
        threads: Some(2),
        progress: false,
        chunk_returns: 1 << 14,
    }
}

fn quiet_tpu() -> TpuOptions {
    TpuOptions {
        threads: Some(2),
        progress: false,
        ..TpuOptions::default()
    }
}

/// A survey in `dir` georeferenced by `run` into `out/cloud.las` with the full sigma set and
/// the output frame `frame` (TOML inline table); gives the pipeline path.
fn survey(dir: &Path, per_profile: usize, frame: &str) -> std::path::PathBuf {
    write_trajectory(dir);
    write_profiles(&dir.join("pass.ksprof"), per_profile);
    let path = write_pipeline(dir, "traj.smrmsg", FULL);
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("frame = { kind = \"utm\" }", &format!("frame = {frame}"));
    std::fs::write(&path, text).unwrap();
    // run's cloud ends with its uncertainty dimensions (no mirror_angle after them), so the
    // copy, which replaces them and appends ours, has the same dimension order and the tests
    // compare dimensions by index.
    let layout = ["output.mirror_angle_dimension=false".to_string()];
    let report = run(&config::load(&path, &layout).unwrap(), &quiet_run()).unwrap();
    assert_eq!(report.totals.rejected_total(), 0);
    path
}

fn tpu_on(
    pipeline: &Path,
    cloud: &Path,
    set: &[&str],
) -> kinescan::Result<kinescan::app::tpu::report::TpuReport> {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    let loaded = config::load_tpu(pipeline, &set)?;
    tpu(&loaded, cloud, &quiet_tpu())
}

/// Acceptance (issue 25): `run` then `tpu` on its LAS with the same pipeline gives the sigmas
/// `run` wrote, over >= 1e6 points in UTM, ECEF and ENU: sigma_x/y/z, thu95, tvu95 within
/// 1e-4 relative (the recovered geometry differs from `run`'s by the LAS quantisation, 1e-4 m
/// scale: <= 0.87e-4 m of position, i.e. <= 3.5e-5 of the 2.5 m shortest range; f32 storage
/// adds 6e-8), shares within one step (0.004); the recovered range equals the `range` `run`
/// stored to 1e-4 m; every original record byte is kept.
#[test]
fn run_then_tpu_gives_runs_sigmas_in_every_frame() {
    let frames = [
        "{ kind = \"utm\" }",
        "{ kind = \"ecef\" }",
        "{ kind = \"enu\", lat_deg = 48.137, lon_deg = 11.575, h_m = 520.0 }",
    ];
    for frame in frames {
        let dir = tempfile::tempdir().unwrap();
        let pipeline = survey(dir.path(), 503, frame);
        let cloud = dir.path().join("out/cloud.las");
        let report = tpu_on(&pipeline, &cloud, &["output.las=out/tpu.las"]).unwrap();
        let n = report.totals.read;
        assert!(n >= 1_000_000, "{frame}: {n} points");
        assert_eq!(
            report.totals.with_sigma, n,
            "{frame}: {:?}",
            report.totals.rejected
        );
        let (names_run, run_values) = read_extra(&cloud);
        let (names_tpu, tpu_values) = read_extra(&dir.path().join("out/tpu.las"));
        // The copy: run's range dimension kept, the uncertainty dimensions replaced (same
        // names, same order), so the name lists are equal.
        assert_eq!(names_run, names_tpu, "{frame}");
        assert_eq!(
            report.cloud.replaced_dimensions,
            names_run[1..].to_vec(),
            "{frame}"
        );
        let mut worst_sigma = 0.0f64;
        let mut worst_share = 0.0f64;
        for (a, b) in run_values.iter().zip(&tpu_values) {
            assert_eq!(a[0], b[0], "range kept byte for byte");
            for (x, y) in a.iter().zip(b).take(6).skip(1) {
                let (x, y) = (f64::from(*x), f64::from(*y));
                assert!(x > 0.0 && y > 0.0, "{frame}: {names_run:?} {a:?} {b:?}");
                raise_max(&mut worst_sigma, (y / x - 1.0).abs());
            }
            for (x, y) in a.iter().zip(b).skip(6) {
                raise_max(&mut worst_share, (f64::from(*y) - f64::from(*x)).abs());
            }
        }
        eprintln!("{frame}: {n} points, worst sigma ratio - 1 {worst_sigma:.2e}, worst share {worst_share}");
        assert!(worst_sigma <= 1e-4, "{frame}: {worst_sigma}");
        assert!(worst_share <= 0.004 + 1e-6, "{frame}: {worst_share}");
        let fit = report.fit.unwrap();
        assert!(
            fit.range_m.0 >= 2.5 - 1e-3 && fit.range_m.1 <= 80.05 + 1e-3,
            "{fit:?}"
        );
        assert!(fit.max_off_cone_m <= 2e-4, "{fit:?}");
        // Every record's original bytes (the 30-byte core and the 4-byte range) are kept.
        let a = std::fs::read(&cloud).unwrap();
        let b = std::fs::read(dir.path().join("out/tpu.las")).unwrap();
        let at = |f: &[u8], i| u32::from_le_bytes(f[i..i + 4].try_into().unwrap()) as usize;
        let len = |f: &[u8]| u16::from_le_bytes([f[105], f[106]]) as usize;
        let (oa, ob, la, lb) = (at(&a, 96), at(&b, 96), len(&a), len(&b));
        assert_eq!(la, lb, "same dimensions, same record length");
        for i in (0..n as usize).step_by(997) {
            assert_eq!(
                a[oa + i * la..oa + i * la + 34],
                b[ob + i * lb..ob + i * lb + 34]
            );
        }
        // The header block up to the offsets is unchanged but for what moved.
        assert_eq!(a[..94], b[..94]);
    }
}

/// The recovered range of every point equals the `range` `run` stored (f32) to the LAS
/// quantisation; checked through the library's per-point recovery.
#[test]
fn recovered_range_and_mirror_angle_match_runs() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = survey(dir.path(), 20, "{ kind = \"utm\" }");
    let cloud = dir.path().join("out/cloud.las");
    let loaded = config::load_tpu(&pipeline, &[]).unwrap();
    let points = kinescan::app::tpu::inspect(&loaded, &cloud, 0..2000).unwrap();
    let (_, run_values) = read_extra(&cloud);
    let mut worst = 0.0f64;
    for (p, v) in points.iter().zip(&run_values) {
        let p = p.as_ref().unwrap();
        raise_max(&mut worst, (p.recovered.range_m - f64::from(v[0])).abs());
    }
    // 0.87e-4 m of position quantisation plus the f32 range (<= 80 m: 4e-6 m).
    assert!(worst <= 1e-4, "{worst}");
}

/// The rotating (Palmer) mirror kind end to end: `run` writes a cloud whose beams lie on a
/// Palmer cone (its profile cone `alpha0 = 90 deg - theta` behind the boresight `R_s^b Q`, which
/// is the Palmer's own equation with the mounting `R_s^b`); `tpu` with `rotating_mirror`,
/// `theta` and `R_s^b` inverts every point back onto its cone with `run`'s range (to the LAS
/// quantisation); with another half-angle every point is off the cone.
#[test]
fn rotating_mirror_recovers_a_palmer_cloud() {
    use kinescan::app::tpu::scanner::RotatingMirror;
    use kinescan::geo::rotations::{r_zyx, zyx_angles};
    let dir = tempfile::tempdir().unwrap();
    write_trajectory(dir.path());
    write_profiles(&dir.path().join("pass.ksprof"), 20);
    let pipeline = write_pipeline(dir.path(), "traj.smrmsg", FULL);
    // A mounting that tilts the cone's axis 30 deg off the body's vertical (away from the
    // ZYX gimbal lock of R_s^b Q) and a 20 deg half-angle.
    let mount_deg = [30.0, -5.0, 10.0];
    let r = mount_deg.map(f64::to_radians);
    let composite = r_zyx(r[0], r[1], r[2]) * RotatingMirror::axes();
    let (bx, by, bz) = zyx_angles(&composite);
    let deg = |a: f64| a.to_degrees();
    let run_set = [
        format!(
            "sensor.boresight_deg=[{}, {}, {}]",
            deg(bx),
            deg(by),
            deg(bz)
        ),
        "sensor.alpha0_deg=70.0".to_string(),
        "output.mirror_angle_dimension=false".to_string(),
    ];
    let report = run(&config::load(&pipeline, &run_set).unwrap(), &quiet_run()).unwrap();
    assert_eq!(report.totals.rejected_total(), 0);
    let cloud = dir.path().join("out/cloud.las");
    let tpu_set = |half: f64| {
        vec![
            format!(
                "sensor.boresight_deg=[{}, {}, {}]",
                mount_deg[0], mount_deg[1], mount_deg[2]
            ),
            "tpu.scanner=\"rotating_mirror\"".to_string(),
            format!("tpu.cone_half_angle_deg={half}"),
        ]
    };
    let loaded = config::load_tpu(&pipeline, &tpu_set(20.0)).unwrap();
    let points = kinescan::app::tpu::inspect(&loaded, &cloud, 0..3000).unwrap();
    let (_, run_values) = read_extra(&cloud);
    assert_eq!(points.len(), 3000);
    let (mut worst_range, mut worst_off) = (0.0f64, 0.0f64);
    for (p, v) in points.iter().zip(&run_values) {
        let p = p.as_ref().unwrap();
        raise_max(
            &mut worst_range,
            (p.recovered.range_m - f64::from(v[0])).abs(),
        );
        raise_max(&mut worst_off, p.recovered.off_cone_m);
        assert!(p.variances.var_m2.iter().all(|v| *v > 0.0), "{p:?}");
    }
    eprintln!("palmer: worst range {worst_range:e} m, worst off cone {worst_off:e} m");
    // LAS quantisation: 0.87e-4 m of position, plus the f32 range (<= 200 m: 1e-5 m).
    assert!(worst_range <= 1e-4, "{worst_range}");
    assert!(worst_off <= 2e-4, "{worst_off}");
    // The same cloud seen as a 19 deg cone: 1 deg off, every point beyond 1 cm at >= 1 m.
    let loaded = config::load_tpu(&pipeline, &tpu_set(19.0)).unwrap();
    let points = kinescan::app::tpu::inspect(&loaded, &cloud, 0..3000).unwrap();
    assert!(points
        .iter()
        .all(|p| matches!(p, Err(PointReject::OffCone))));
}

/// A LAS without GPS time, without CRS, with times outside the SBET, with a wrong GPS week,
/// a truncated LAZ: clear errors naming the file; points whose recovered range is negative:
/// counted (and named) or, with strictness "fail", an error naming the point. Nothing is
/// published by a failed command.
#[test]
fn bad_clouds_are_refused_or_counted_naming_file_and_point() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = survey(dir.path(), 3, "{ kind = \"utm\" }");
    let cloud = dir.path().join("out/cloud.las");
    let out = dir.path().join("out/tpu.las");
    let set = ["output.las=out/tpu.las"];
    let bytes = std::fs::read(&cloud).unwrap();
    let message = |r: kinescan::Result<_>| match r {
        Ok(_) => panic!("accepted"),
        Err(e) => {
            assert!(!out.exists(), "published after an error: {e}");
            e.to_string()
        }
    };

    // No CRS: the WKT VLR's user id changed.
    let mut b = bytes.clone();
    let at = b.windows(15).position(|w| w == b"LASF_Projection").unwrap();
    b[at..at + 15].copy_from_slice(b"NOT_Projection_");
    let no_crs = dir.path().join("no_crs.las");
    std::fs::write(&no_crs, &b).unwrap();
    let e = message(tpu_on(&pipeline, &no_crs, &set));
    assert!(e.contains("no_crs.las") && e.contains("no CRS"), "{e}");

    // No GPS time: a format 0 LAS (the las crate) with the WKT.
    let no_time = dir.path().join("no_time.las");
    {
        let reader = las::Reader::from_path(&cloud).unwrap();
        let mut builder = las::Builder::from((1, 2));
        builder.point_format = las::point::Format::new(0).unwrap();
        builder.vlrs = reader
            .header()
            .vlrs()
            .iter()
            .filter(|v| v.record_id == 2112)
            .cloned()
            .collect();
        let mut w = las::Writer::from_path(&no_time, builder.into_header().unwrap()).unwrap();
        w.write_point(las::Point {
            x: 1.0,
            y: 2.0,
            z: 3.0,
            ..Default::default()
        })
        .unwrap();
        w.close().unwrap();
    }
    let e = message(tpu_on(&pipeline, &no_time, &set));
    assert!(
        e.contains("no_time.las") && e.contains("no GPS time"),
        "{e}"
    );

    // Times outside the SBET: a cloud an hour later.
    let late = dir.path().join("late.las");
    shift_times(&cloud, &late, 3600.0);
    let e = message(tpu_on(&pipeline, &late, &set));
    assert!(
        e.contains("late.las") && e.contains("outside the trajectory span"),
        "{e}"
    );

    // Wrong GPS week: run writes adjusted standard time with week 2300; tpu told 2301.
    let week_dir = tempfile::tempdir().unwrap();
    let wp = survey_with_week(week_dir.path(), 2300);
    let wcloud = week_dir.path().join("out/cloud.las");
    let e = tpu_on(
        &wp,
        &wcloud,
        &["output.las=out/tpu.las", "inputs.gps_week=2301"],
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("cloud.las") && e.contains("week"), "{e}");
    assert!(!week_dir.path().join("out/tpu.las").exists());
    // ... and the right week works.
    let r = tpu_on(&wp, &wcloud, &["output.las=out/tpu.las"]).unwrap();
    assert_eq!(r.totals.with_sigma, r.totals.read);

    // Truncated LAZ.
    let laz_dir = tempfile::tempdir().unwrap();
    let lp = survey(laz_dir.path(), 3, "{ kind = \"utm\" }");
    let text = std::fs::read_to_string(&lp).unwrap();
    std::fs::write(
        &lp,
        text.replace(
            "las = \"out/cloud.las\"",
            "las = \"out/cloud.las\"\nformat = \"laz\"",
        ),
    )
    .unwrap();
    run(&config::load(&lp, &[]).unwrap(), &quiet_run()).unwrap();
    let laz = laz_dir.path().join("out/cloud.laz");
    let full = std::fs::read(&laz).unwrap();
    let cut = laz_dir.path().join("cut.laz");
    std::fs::write(&cut, &full[..full.len() / 2]).unwrap();
    let e = tpu_on(
        &lp,
        &cut,
        &["output.las=out/tpu.las", "output.format=\"las\""],
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("cut.laz"), "{e}");
    assert!(!laz_dir.path().join("out/tpu.las").exists());
    // The whole LAZ reads and gives LAZ out.
    let r = tpu_on(&lp, &laz, &["output.las=out/tpu.las"]).unwrap();
    assert_eq!(r.totals.with_sigma, r.totals.read);
    assert!(laz_dir.path().join("out/tpu.laz").exists());

    // Negative recovered range: a range offset longer than every range. Counted (NaN
    // sigmas, first points named) when nothing fits: an error, nothing published.
    let e = message(tpu_on(
        &pipeline,
        &cloud,
        &["output.las=out/tpu.las", "sensor.range_zero_m=100.0"],
    ));
    assert!(
        e.contains("cloud.las") && e.contains("recovered range negative"),
        "{e}"
    );
    // With strictness "fail": the first point named.
    let e = message(tpu_on(
        &pipeline,
        &cloud,
        &[
            "output.las=out/tpu.las",
            "sensor.range_zero_m=100.0",
            "output.strictness=\"fail\"",
        ],
    ));
    assert!(
        e.contains("cloud.las") && e.contains("point 0") && e.contains("negative"),
        "{e}"
    );
    // Half the points an hour later: counted per reason, first points named, NaN sigmas.
    let half = dir.path().join("half.las");
    shift_times_from(&cloud, &half, 3600.0, 0.5);
    let r = tpu_on(&pipeline, &half, &set).unwrap();
    let outside = r.totals.rejected[&PointReject::OutsideTrajectory];
    assert_eq!(outside + r.totals.with_sigma, r.totals.read);
    assert!(outside > 0 && r.totals.with_sigma > 0);
    let first = r.totals.rejected_examples[&PointReject::OutsideTrajectory][0];
    let (_, values) = read_extra(&out);
    assert!(values[first as usize][1].is_nan());
    assert!(values[0][1] > 0.0);
}

fn shift_times(from: &Path, to: &Path, dt: f64) {
    shift_times_from(from, to, dt, 0.0)
}

/// Copies the LAS `from` to `to` with the GPS time of the points after the fraction `from_frac`
/// of the file shifted by `dt`.
fn shift_times_from(from: &Path, to: &Path, dt: f64, from_frac: f64) {
    let mut b = std::fs::read(from).unwrap();
    let off = u32::from_le_bytes(b[96..100].try_into().unwrap()) as usize;
    let len = u16::from_le_bytes([b[105], b[106]]) as usize;
    let n = (b.len() - off) / len;
    for i in ((n as f64 * from_frac) as usize)..n {
        let at = off + i * len + 22;
        let t = f64::from_le_bytes(b[at..at + 8].try_into().unwrap()) + dt;
        b[at..at + 8].copy_from_slice(&t.to_le_bytes());
    }
    std::fs::write(to, b).unwrap();
}

/// [`survey`] with `inputs.gps_week` (adjusted standard GPS time in the LAS).
fn survey_with_week(dir: &Path, week: u32) -> std::path::PathBuf {
    write_trajectory(dir);
    write_profiles(&dir.join("pass.ksprof"), 3);
    let path = write_pipeline(dir, "traj.smrmsg", FULL);
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("profiles = [", &format!("gps_week = {week}\nprofiles = ["));
    std::fs::write(&path, text).unwrap();
    run(&config::load(&path, &[]).unwrap(), &quiet_run()).unwrap();
    path
}

/// The command line: `kinescan tpu PIPELINE --cloud FILE --set ...` writes the copy and the
/// report and says so; an error exits 1 naming the file.
#[test]
fn cli_tpu_writes_the_copy_and_refuses_a_cloud_without_crs() {
    let dir = tempfile::tempdir().unwrap();
    survey(dir.path(), 2, "{ kind = \"utm\" }");
    let args = [
        "tpu",
        "pipeline.toml",
        "--cloud",
        "out/cloud.las",
        "--set",
        "output.las=out/tpu.las",
    ];
    let out = kinescan(dir.path(), &args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("given a sigma") && stdout.contains("out/tpu.las"),
        "{stdout}"
    );
    assert!(dir.path().join("out/tpu.report.json").exists());
    let mut b = std::fs::read(dir.path().join("out/cloud.las")).unwrap();
    let at = b.windows(15).position(|w| w == b"LASF_Projection").unwrap();
    b[at] = b'X';
    std::fs::write(dir.path().join("bare.las"), b).unwrap();
    let args = [
        "tpu",
        "pipeline.toml",
        "--cloud",
        "bare.las",
        "--set",
        "output.las=out/bare_tpu.las",
    ];
    let out = kinescan(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("bare.las") && stderr.contains("no CRS"),
        "{stderr}"
    );
    assert!(!dir.path().join("out/bare_tpu.las").exists());
}
