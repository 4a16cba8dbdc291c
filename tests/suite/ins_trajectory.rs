//! The loosely coupled INS/GNSS filter and RTS smoother (`kinescan trajectory`, issue #26,
//! docs/trajectory.md) on the simulator's raw records: mechanisation against the truth,
//! consistency by NEES over Monte Carlo runs, accuracy with and without an outage, a wrong
//! initial heading, GNSS outliers, the command's files and its bad-input rules.

use kinescan::ins::align::align;
use kinescan::ins::config::AlignmentCfg;
use kinescan::ins::filter::{
    apply_correction, initial_covariance, Filter, ProcessNoise, SensorEstimate, Vec21,
};
use kinescan::ins::imu_model;
use kinescan::ins::mechanisation::{euler, NavState};
use kinescan::ins::smoother::{forward, smooth, Estimate, FilterStats, Start};
use kinescan::ins::{error6, euler_sigmas};
use kinescan::io::gnss::GnssRecord;
use kinescan::io::imu::ImuRecord;
use kinescan::sim::raw::RawGen;
use kinescan::sim::Scenario;
use kinescan::testing::raise_max;
use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::path::Path;

const LEVER: [f64; 3] = [0.3, 0.0, -1.2];

/// The demo's city block with a `[raw]` table, `seed` and `duration_s` replaced.
fn scenario(seed: u64, duration_s: f64, raw: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenario_city_block.toml");
    let base = std::fs::read_to_string(path).unwrap();
    let base = base
        .replace("seed = 20261121", &format!("seed = {seed}"))
        .replace("duration_s = 62.0", &format!("duration_s = {duration_s}"));
    assert!(
        base.contains(&format!("seed = {seed}"))
            && base.contains(&format!("duration_s = {duration_s}"))
    );
    let raw = format!("[raw]\nantenna_lever_arm_b_m = {LEVER:?}\n{raw}\n");
    Scenario::parse(&format!("{base}\n{raw}"), "test").unwrap()
}

/// Truth at every IMU record time; IMU records with a leading record at the first truth time
/// (the filter's start, never integrated); GNSS fixes.
struct Raw {
    truth: Vec<NavState>,
    imu: Vec<ImuRecord>,
    gnss: Vec<GnssRecord>,
    outliers: Vec<f64>,
}

fn simulate(sc: &Scenario) -> Raw {
    let mut gen = RawGen::new(sc).unwrap();
    let samples: Vec<_> = gen.by_ref().collect();
    let truth: Vec<NavState> = samples.iter().map(|s| s.truth).collect();
    let mut imu = vec![ImuRecord {
        time_s: truth[0].time_s,
        ..Default::default()
    }];
    imu.extend(samples.iter().filter_map(|s| s.imu));
    assert_eq!(imu.len(), truth.len());
    Raw {
        truth,
        imu,
        gnss: samples.iter().filter_map(|s| s.gnss).collect(),
        outliers: gen.raw_truth().outlier_times_s,
    }
}

/// Initial attitude sigmas of the Monte Carlo starts (rad): roll, pitch 0.06 deg, heading 0.3 deg.
const ATT0: [f64; 3] = [1e-3, 1e-3, 5e-3];

/// The filter started from the truth perturbed by a draw from its own initial covariance
/// (the sensor estimates start at zero; the simulator drew the sensor errors from the grade).
fn perturbed_start(truth0: &NavState, seed: u64) -> Start {
    let grade = imu_model::grade("tactical").unwrap();
    let p = initial_covariance(&grade, [0.05; 3], 0.02, ATT0);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED);
    let z = Vec21::from_fn(|_, _| StandardNormal.sample(&mut rng));
    let err = p.cholesky().unwrap().l() * z;
    let mut nav = *truth0;
    let mut ignored = SensorEstimate::default();
    apply_correction(&mut nav, &mut ignored, &-err);
    Start {
        filter: Filter {
            nav,
            sens: SensorEstimate::default(),
            p,
            noise: ProcessNoise::of(&grade),
            lever_b: Vector3::from(LEVER),
            gate: 16.27,
        },
        index: 0,
    }
}

/// Filtered and smoothed estimates of a run, in time order.
fn process(
    raw: &Raw,
    start: Start,
) -> kinescan::Result<(Vec<Estimate>, Vec<Estimate>, FilterStats)> {
    let mut filtered = Vec::with_capacity(raw.imu.len());
    let fwd = forward(raw.imu.as_slice(), &raw.gnss, start, 50, &mut |e| {
        filtered.push(*e)
    })?;
    let mut smoothed = Vec::with_capacity(raw.imu.len());
    smooth(raw.imu.as_slice(), &fwd, &mut |e| {
        smoothed.push(*e);
        Ok(())
    })?;
    Ok((filtered, smoothed, fwd.stats.clone()))
}

/// NEES of position + attitude and the number of components inside 3 sigma.
fn nees(e: &Estimate, truth: &NavState) -> (f64, usize) {
    let (x, c) = error6(e, truth);
    let n = x.dot(&(c.try_inverse().expect("covariance invertible") * x));
    let inside = (0..6)
        .filter(|&i| x[i].abs() <= 3.0 * c[(i, i)].sqrt())
        .count();
    (n, inside)
}

/// Wilson-Hilferty quantile of chi-square with `k` dof at the standard normal quantile `z`.
fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// A perfect IMU integrated by the mechanisation from the true start stays on the truth:
/// the simulator's increments are the mechanisation's exact inverse.
#[test]
fn mechanisation_reproduces_the_truth_from_a_perfect_imu() {
    let raw = simulate(&scenario(7, 60.0, "imu_grade = \"perfect\""));
    let mut start = perturbed_start(&raw.truth[0], 0);
    start.filter.nav = raw.truth[0];
    let mut worst = (0.0f64, 0.0f64);
    let mut k = 0;
    forward(raw.imu.as_slice(), &[], start, 50, &mut |e| {
        let (x, _) = error6(e, &raw.truth[k]);
        raise_max(&mut worst.0, x.fixed_rows::<3>(0).norm());
        raise_max(&mut worst.1, x.fixed_rows::<3>(3).norm());
        k += 1;
    })
    .unwrap();
    assert_eq!(k, raw.truth.len());
    // 1e-4 m and 1e-10 rad: rounding over 12000 steps, far below any sensor error.
    assert!(
        worst.0 < 1e-4 && worst.1 < 1e-10,
        "worst position {} m, attitude {} rad",
        worst.0,
        worst.1
    );
}

/// Issue #26 acceptance: NEES of position + attitude (6 dof) of the filter and of the smoother
/// over 50 Monte Carlo runs of 60 s (tactical IMU, 10 Hz GNSS at 2 cm, starts drawn from the
/// initial covariance): mean within the 95% chi-square band of 6 x 50 dof over 50 runs
/// (the band of one epoch's ensemble mean; the mean over epochs is tighter, so the test is
/// not looser than the criterion), and at least 98% of the components inside 3 sigma.
#[test]
fn filter_and_smoother_are_consistent_by_nees() {
    let runs = 50u64;
    let per_run: Vec<[f64; 6]> = (0..runs)
        .into_par_iter()
        .map(|seed| {
            let raw = simulate(&scenario(100 + seed, 60.0, ""));
            let (filt, smth, _) = process(&raw, perturbed_start(&raw.truth[0], seed)).unwrap();
            let mut acc = [0.0; 6];
            // One sample a second (200 records), from 0.5 s.
            for k in (100..raw.truth.len()).step_by(200) {
                let (nf, inf) = nees(&filt[k], &raw.truth[k]);
                let (ns, ins) = nees(&smth[k], &raw.truth[k]);
                acc[0] += nf;
                acc[1] += ns;
                acc[2] += inf as f64;
                acc[3] += ins as f64;
                acc[4] += 1.0;
            }
            acc
        })
        .collect();
    let sum = |i: usize| per_run.iter().map(|a| a[i]).sum::<f64>();
    let n = sum(4);
    let (mean_f, mean_s) = (sum(0) / n, sum(1) / n);
    let (cov_f, cov_s) = (sum(2) / (6.0 * n), sum(3) / (6.0 * n));
    let k = 6.0 * runs as f64;
    let (lo, hi) = (
        chi2_quantile(k, -1.96) / runs as f64,
        chi2_quantile(k, 1.96) / runs as f64,
    );
    println!("NEES filter {mean_f:.3}, smoother {mean_s:.3}, band [{lo:.2}, {hi:.2}]; 3-sigma coverage {cov_f:.4} / {cov_s:.4}");
    assert!(
        mean_f >= lo && mean_f <= hi,
        "filter NEES mean {mean_f} outside [{lo}, {hi}]"
    );
    assert!(
        mean_s >= lo && mean_s <= hi,
        "smoother NEES mean {mean_s} outside [{lo}, {hi}]"
    );
    assert!(
        cov_f >= 0.98 && cov_s >= 0.98,
        "3-sigma coverage {cov_f} / {cov_s}"
    );
}

/// RMS of smoothed position (3D, m) and roll, pitch, heading (deg) errors over a run.
fn rms(smth: &[Estimate], truth: &[NavState]) -> [f64; 4] {
    let mut s = [0.0; 4];
    for (e, t) in smth.iter().zip(truth) {
        let (x, _) = error6(e, t);
        let (r, p, h) = euler(&e.nav);
        let (rt, pt, ht) = euler(t);
        let w = kinescan::geo::rotations::wrap_pi;
        s[0] += x.fixed_rows::<3>(0).norm_squared();
        s[1] += w(r - rt).powi(2);
        s[2] += w(p - pt).powi(2);
        s[3] += w(h - ht).powi(2);
    }
    let n = smth.len() as f64;
    [s[0] / n, s[1] / n, s[2] / n, s[3] / n].map(|v: f64| v.sqrt())
}

fn aligned(raw: &Raw, cfg: &AlignmentCfg) -> kinescan::Result<Start> {
    let grade = imu_model::grade("tactical").unwrap();
    align(
        raw.imu.as_slice(),
        &raw.gnss,
        cfg,
        &grade,
        Vector3::from(LEVER),
        16.27,
    )
    .map(|(s, _)| s)
}

/// Issue #26 acceptance: tactical IMU, 10 Hz GNSS at 2 cm, no outage, started by the automatic
/// alignment (static roll/pitch, heading from the GNSS course): smoothed position RMS <= 2.5
/// cm, roll and pitch <= 0.01 deg, heading <= 0.03 deg, on each of three 120 s runs.
#[test]
fn smoothed_accuracy_without_outage() {
    for seed in [1u64, 2, 3] {
        let raw = simulate(&scenario(seed, 120.0, ""));
        let start = aligned(&raw, &AlignmentCfg::default()).unwrap();
        assert_eq!(start.index, 0, "the first fix is at the first IMU record");
        let (_, smth, _) = process(&raw, start).unwrap();
        let [pos, roll, pitch, heading] = rms(&smth, &raw.truth);
        let deg = f64::to_degrees;
        println!(
            "seed {seed}: position {pos:.4} m, roll {:.5}, pitch {:.5}, heading {:.5} deg",
            deg(roll),
            deg(pitch),
            deg(heading)
        );
        assert!(pos <= 0.025, "position RMS {pos} m");
        assert!(
            deg(roll) <= 0.01 && deg(pitch) <= 0.01,
            "roll/pitch RMS {} / {} deg",
            deg(roll),
            deg(pitch)
        );
        assert!(deg(heading) <= 0.03, "heading RMS {} deg", deg(heading));
    }
}

/// Issue #26 acceptance: a 30 s outage in a 120 s run: the smoothed error stays inside the
/// smoother's 3-sigma envelope (every component, at least 99% of the outage's records, on
/// each of three runs), and the envelope does open up in the outage.
#[test]
fn outage_error_stays_inside_the_smoothed_envelope() {
    for seed in [11u64, 12, 13] {
        let raw = simulate(&scenario(seed, 120.0, "outages_s = [[45.0, 75.0]]"));
        let t0 = raw.truth[0].time_s;
        let (_, smth, _) = process(&raw, perturbed_start(&raw.truth[0], seed)).unwrap();
        let (mut inside, mut n, mut worst) = ([0usize; 6], 0usize, 0.0f64);
        let (mut sig_in, mut sig_out) = (0.0f64, 0.0f64);
        if seed == 11 {
            plot_outage(&smth, &raw.truth, t0);
        }
        for (e, t) in smth.iter().zip(&raw.truth) {
            let (x, c) = error6(e, t);
            let h = (c[(0, 0)] + c[(1, 1)]).sqrt();
            let rel = e.nav.time_s - t0;
            if !(45.0..75.0).contains(&rel) {
                raise_max(&mut sig_out, h);
                continue;
            }
            raise_max(&mut sig_in, h);
            n += 1;
            for (i, k) in inside.iter_mut().enumerate() {
                let r = x[i].abs() / c[(i, i)].sqrt();
                raise_max(&mut worst, r);
                *k += usize::from(r <= 3.0);
            }
        }
        println!("seed {seed}: outage records {n}, inside 3 sigma {inside:?}, worst |err|/sigma {worst:.2}, horizontal sigma max {sig_in:.3} m in the outage, {sig_out:.3} m outside");
        assert!(n > 5000, "outage not in the run: {n} records");
        for (i, k) in inside.iter().enumerate() {
            assert!(
                *k as f64 >= 0.99 * n as f64,
                "component {i}: {k} of {n} inside 3 sigma"
            );
        }
        assert!(
            sig_in > 2.0 * sig_out,
            "envelope: {sig_in} m in the outage, {sig_out} m outside"
        );
    }
}

/// The plots of docs/trajectory.md: north position and heading errors with the smoother's
/// 3-sigma envelope through the outage. Written into `$KINESCAN_TRAJECTORY_PLOTS` when set
/// (how the docs' copies were made), else into a temporary folder.
fn plot_outage(smth: &[Estimate], truth: &[NavState], t0: f64) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = std::env::var_os("KINESCAN_TRAJECTORY_PLOTS")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| tmp.path().to_path_buf());
    let mut series = [
        [Vec::new(), Vec::new(), Vec::new()],
        [Vec::new(), Vec::new(), Vec::new()],
    ];
    for (e, t) in smth.iter().zip(truth).step_by(10) {
        let (x, c) = error6(e, t);
        let rel = e.nav.time_s - t0;
        let dh = kinescan::geo::rotations::wrap_pi(euler(&e.nav).2 - euler(t).2).to_degrees();
        let sh = euler_sigmas(e).z.to_degrees();
        let sn = c[(0, 0)].sqrt();
        for (k, (v, s)) in [(x[0] * 100.0, sn * 100.0), (dh * 1000.0, sh * 1000.0)]
            .into_iter()
            .enumerate()
        {
            series[k][0].push((rel, v));
            series[k][1].push((rel, 3.0 * s));
            series[k][2].push((rel, -3.0 * s));
        }
    }
    let names = [
        (
            "trajectory_outage_north.png",
            "North position error, GNSS outage 45-75 s",
            "error (cm)",
        ),
        (
            "trajectory_outage_heading.png",
            "Heading error, GNSS outage 45-75 s",
            "error (mdeg)",
        ),
    ];
    for (k, (file, title, y)) in names.into_iter().enumerate() {
        kinescan::plot::Plot::new(title, "time from start (s)", y)
            .line("smoothed error", &series[k][0])
            .line("+3 sigma", &series[k][1])
            .color(kinescan::plot::PALETTE[1])
            .line("-3 sigma", &series[k][2])
            .color(kinescan::plot::PALETTE[1])
            .save_png(dir.join(file))
            .unwrap();
        assert!(dir.join(file).metadata().unwrap().len() > 1000);
    }
}

/// Issue #26 acceptance: a start 30 deg off in heading. Stated as 1 deg sure, the filter
/// refuses with a message naming the cause; stated with a 30 deg sigma, it converges: the
/// smoothed heading error over the last 60 s is below 0.03 deg RMS.
#[test]
fn wrong_initial_heading_refuses_or_converges() {
    let raw = simulate(&scenario(21, 120.0, ""));
    let off = UnitQuaternion::from_scaled_axis(Vector3::z() * 30f64.to_radians());
    let mut sure = perturbed_start(&raw.truth[0], 21);
    sure.filter.nav.q_b_n = off * raw.truth[0].q_b_n;
    sure.filter.p[(8, 8)] = 1f64.to_radians().powi(2);
    let err = process(&raw, sure).expect_err("a 30 deg error stated as 1 deg must be refused");
    let msg = err.to_string();
    assert!(
        msg.contains("rejected by the innovation test") && msg.contains("initial heading"),
        "{msg}"
    );
    let mut unsure = perturbed_start(&raw.truth[0], 21);
    unsure.filter.nav.q_b_n = off * raw.truth[0].q_b_n;
    unsure.filter.p[(8, 8)] = 30f64.to_radians().powi(2);
    let (_, smth, stats) = process(&raw, unsure).unwrap();
    let half = smth.len() / 2;
    let [_, _, _, heading] = rms(&smth[half..], &raw.truth[half..]);
    println!(
        "30 deg start, 30 deg sigma: heading RMS {:.5} deg over the second half, {} fixes rejected",
        heading.to_degrees(),
        stats.gnss_rejected
    );
    assert!(
        heading.to_degrees() < 0.03,
        "heading RMS {} deg",
        heading.to_degrees()
    );
}

/// Issue #26 acceptance: GNSS outliers of 5 m (2% of the fixes) are all rejected by the
/// innovation test and counted; few good fixes are (the gate's false-alarm rate is 0.1%), and
/// the smoothed accuracy holds.
#[test]
fn gnss_outliers_are_rejected_and_counted() {
    let raw = simulate(&scenario(
        31,
        120.0,
        "outlier_probability = 0.02\noutlier_m = 5.0",
    ));
    assert!(
        raw.outliers.len() >= 10,
        "{} outliers drawn",
        raw.outliers.len()
    );
    let (_, smth, stats) = process(&raw, perturbed_start(&raw.truth[0], 31)).unwrap();
    for t in &raw.outliers {
        assert!(
            stats.rejected_times_s.contains(t),
            "outlier at {t} s was used"
        );
    }
    let false_alarms = stats.gnss_rejected - raw.outliers.len();
    println!(
        "{} outliers, {} rejected ({} good fixes rejected of {})",
        raw.outliers.len(),
        stats.gnss_rejected,
        false_alarms,
        stats.gnss_fixes
    );
    assert!(false_alarms <= 10, "{false_alarms} good fixes rejected");
    let [pos, ..] = rms(&smth, &raw.truth);
    assert!(pos <= 0.025, "position RMS {pos} m");
}

fn write_config(dir: &Path) -> std::path::PathBuf {
    let cfg = dir.join("trajectory.toml");
    let text = format!(
        "[inputs]\nimu = \"imu.bin\"\ngnss = \"gnss.bin\"\n[gnss]\nlever_arm_b_m = {LEVER:?}\n\
         [output]\nsbet = \"out/smoothed.sbet\"\nsmrmsg = \"out/smoothed.smrmsg\"\n"
    );
    std::fs::write(&cfg, text).unwrap();
    cfg
}

/// `kinescan trajectory` end to end from the simulator's files: SBET + SMRMSG at the IMU
/// rate (read back by the project's readers), the report counting the rejected outliers and
/// the GNSS gap, and the error model with a correlation time per position component.
#[test]
fn trajectory_command_writes_sbet_smrmsg_report_and_error_model() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scenario(
        41,
        60.0,
        "outages_s = [[30.0, 40.0]]\noutlier_probability = 0.02",
    );
    let counts = kinescan::sim::raw::write_raw(&sc, dir.path()).unwrap();
    let cfg = write_config(dir.path());
    let report = kinescan::ins::run(&cfg, &[]).unwrap();
    let sbet = kinescan::io::sbet::SbetFile::open(&dir.path().join("out/smoothed.sbet")).unwrap();
    let smr =
        kinescan::io::smrmsg::SmrmsgFile::open(&dir.path().join("out/smoothed.smrmsg")).unwrap();
    assert_eq!(sbet.len() as u64, report.records);
    assert_eq!(smr.len(), sbet.len());
    // From the IMU record at the first fix to the last record, every record.
    assert!(report.records + 20 >= counts.imu_records && report.records <= counts.imu_records);
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("raw_truth.json")).unwrap()).unwrap();
    let outliers = truth["outlier_times_s"].as_array().unwrap().len();
    assert!(
        outliers > 0 && report.filter.gnss_rejected >= outliers,
        "{outliers} outliers, {} rejected",
        report.filter.gnss_rejected
    );
    assert_eq!(report.gnss_gaps.len(), 1, "{:?}", report.gnss_gaps);
    let quiet = smr.record(smr.len() / 4); // 15 s, between fixes
    let (gap, outside) = (
        report.gnss_gaps[0].max_horizontal_sigma_m,
        quiet.north_m.hypot(quiet.east_m),
    );
    println!("horizontal sigma {gap:.4} m in the 10 s gap, {outside:.4} m at 15 s");
    assert!(
        gap > 1.5 * outside,
        "{gap} m in the gap, {outside} m outside"
    );
    let model: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("out/smoothed.error_model.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(model["components"].as_array().unwrap().len(), 9);
    for c in 0..3 {
        let tau = model["correlation_time_s"][c]
            .as_f64()
            .expect("a position correlation time");
        assert!(tau > 0.1 && tau < 60.0, "component {c}: {tau} s");
    }
    // The SMRMSG sigmas are the smoother's: centimetres, never zero.
    let r = smr.record(smr.len() / 2);
    assert!(r.north_m > 1e-4 && r.north_m < 0.05, "{r:?}");
    println!(
        "{} records in {:.2} s: {:.0}x real time",
        report.records, report.elapsed_s, report.realtime_factor
    );
}

/// Bad inputs are refused with the file and record named; an unknown key with its dotted key.
#[test]
fn trajectory_refuses_bad_inputs_naming_file_and_record() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scenario(42, 10.0, "");
    kinescan::sim::raw::write_raw(&sc, dir.path()).unwrap();
    let cfg = write_config(dir.path());
    let msg = kinescan::ins::run(&cfg, &["gnss.bogus=1".into()])
        .unwrap_err()
        .to_string();
    assert!(msg.contains("gnss.bogus"), "{msg}");
    // A GNSS record with a zero east sigma (field 5, bytes 40..48).
    let gnss = dir.path().join("gnss.bin");
    let mut bytes = std::fs::read(&gnss).unwrap();
    bytes[3 * 56 + 40..3 * 56 + 48].copy_from_slice(&0f64.to_le_bytes());
    std::fs::write(&gnss, &bytes).unwrap();
    let msg = kinescan::ins::run(&cfg, &[]).unwrap_err().to_string();
    assert!(
        msg.contains("gnss.bin") && msg.contains("record 3") && msg.contains("east sigma"),
        "{msg}"
    );
    // A truncated IMU file.
    let imu = dir.path().join("imu.bin");
    let bytes = std::fs::read(&imu).unwrap();
    std::fs::write(&imu, &bytes[..bytes.len() - 3]).unwrap();
    let msg = kinescan::ins::run(&cfg, &[]).unwrap_err().to_string();
    assert!(msg.contains("imu.bin") && msg.contains("56"), "{msg}");
}

/// The example configuration in pipelines/ loads.
#[test]
fn trajectory_example_config_loads() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/trajectory_raw_city_block.toml");
    let (cfg, _) = kinescan::ins::config::TrajectoryConfig::load(&path, &[]).unwrap();
    assert_eq!(cfg.gnss.lever_arm_b_m, LEVER);
    let sc = Scenario::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenario_raw_city_block.toml"),
    )
    .unwrap();
    assert_eq!(sc.raw.unwrap().antenna_lever_arm_b_m, LEVER);
}

/// The command line: `kinescan trajectory CONFIG` succeeds and names its outputs; a bad
/// override exits 1 naming the key; `--help` has examples.
#[test]
fn trajectory_command_line() {
    let dir = tempfile::tempdir().unwrap();
    kinescan::sim::raw::write_raw(&scenario(43, 20.0, ""), dir.path()).unwrap();
    let cfg = write_config(dir.path());
    let exe = env!("CARGO_BIN_EXE_kinescan");
    let o = std::process::Command::new(exe)
        .arg("trajectory")
        .arg(&cfg)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && out.contains("smoothed.sbet") && out.contains("rejected"),
        "{out}"
    );
    let o = std::process::Command::new(exe)
        .args([
            "trajectory",
            cfg.to_str().unwrap(),
            "--set",
            "imu.grade=\"consumer\"",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.code() == Some(1) && err.contains("imu.grade"),
        "{err}"
    );
    let o = std::process::Command::new(exe)
        .args(["trajectory", "--help"])
        .output()
        .unwrap();
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("Example"));
}

/// Issue #26 item 4 end to end: the demo's city block (62 s) with its raw IMU + GNSS records,
/// `kinescan trajectory`, `run` on the smoothed SBET + SMRMSG, the cloud against the truth,
/// and `diagnose` with the smoother's error model (`diagnose.nav_error_model`): the verdict
/// is `none` (no effect was injected; the model is the smoother's own).
#[test]
fn raw_records_to_trajectory_to_run_to_diagnose_give_verdict_none() {
    use kinescan::app::diagnose::report::Verdict;
    let started = std::time::Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = format!(
        "{}\n[raw]\nantenna_lever_arm_b_m = {LEVER:?}\n",
        kinescan::app::demo::SCENARIO
    );
    let sc = Scenario::parse(&text, "raw city block").unwrap();
    crate::sim_support::run(&sc, &d.join("survey"), 2);
    std::fs::write(
        d.join("trajectory.toml"),
        format!(
            "[inputs]\nimu = \"survey/imu.bin\"\ngnss = \"survey/gnss.bin\"\n[gnss]\n\
             lever_arm_b_m = {LEVER:?}\n[output]\nsbet = \"traj/smoothed.sbet\"\n\
             smrmsg = \"traj/smoothed.smrmsg\"\n"
        ),
    )
    .unwrap();
    let tr = kinescan::ins::run(&d.join("trajectory.toml"), &[]).unwrap();
    let pipeline = kinescan::app::demo::PIPELINE
        .replace("survey/trajectory.sbet", "traj/smoothed.sbet")
        .replace("survey/trajectory.smrmsg", "traj/smoothed.smrmsg");
    assert!(
        pipeline.contains("\"traj/smoothed.sbet\"")
            && pipeline.contains("\"traj/smoothed.smrmsg\"")
    );
    let pipeline =
        format!("{pipeline}\n[diagnose]\nnav_error_model = \"traj/smoothed.error_model.json\"\n");
    std::fs::write(d.join("pipeline.toml"), pipeline).unwrap();
    let p = kinescan::pipeline::config::load(&d.join("pipeline.toml"), &[]).unwrap();
    let dc = p.config.diagnose.clone().unwrap();
    let (tau_p, tau_a) = (
        dc.nav_position_tau_s.expect("position tau from the model"),
        dc.nav_attitude_tau_s.expect("attitude tau from the model"),
    );
    assert_eq!(
        (dc.nav_position_scale, dc.nav_attitude_scale),
        (Some(1.0), Some(1.0))
    );
    assert_eq!(
        (dc.nav_position_white_share, dc.nav_attitude_white_share),
        (Some(0.0), Some(0.0))
    );
    let run = kinescan::pipeline::run(&p, &kinescan::pipeline::RunOptions::default()).unwrap();
    let e = kinescan::app::demo::cloud_error(&p, &run, &d.join("survey")).unwrap();
    let [rms, p95, max] = e.error_3d_m;
    let [h, v] = e.error_h_v_rms_m;
    let norm = e
        .normalised_rms_xyz
        .expect("the demo pipeline writes sigmas");
    println!(
        "trajectory {} records ({} fixes used, {} rejected); error model tau position {tau_p:.2} s, \
         attitude {tau_a:.2} s; cloud vs truth over {} points: 3D RMS {:.1} mm, 95% {:.1} mm, \
         max {:.1} mm, horizontal RMS {:.1} mm, vertical {:.1} mm; error/sigma RMS {:.2} {:.2} {:.2}",
        tr.records,
        tr.filter.gnss_used,
        tr.filter.gnss_rejected,
        e.compared,
        rms * 1e3,
        p95 * 1e3,
        max * 1e3,
        h * 1e3,
        v * 1e3,
        norm[0],
        norm[1],
        norm[2]
    );
    // Every point written compared with its truth (2,258,436 of 3,600,000 returns read: the
    // others have no echo).
    assert_eq!(e.compared, run.totals.written);
    // The smoothed trajectory (3.6 mm, 0.002-0.008 deg) and the scanner's 4 mm range and
    // 0.002 deg angle noise at up to 40 m give millimetres; the simulator's own SBET (1.5 cm,
    // 0.003-0.008 deg) gives 2-3 cm. 15 mm is the bound of a trajectory as good as the
    // issue's acceptance (2.5 cm position) would not meet.
    assert!(rms <= 0.015, "3D RMS {rms} m");
    // The per-point sigmas are honest: error / sigma RMS near 1 (within 0.5-1.5).
    for x in norm {
        assert!((0.5..=1.5).contains(&x), "error/sigma RMS {norm:?}");
    }
    let req = kinescan::app::diagnose::Request {
        patches: d.join("survey/patches.csv"),
        control_points: None,
        out_dir: d.join("diag"),
    };
    let dg = kinescan::app::diagnose::run(&p, &req).unwrap();
    println!(
        "diagnosis: {} ({}); whole chain {:.0} s",
        dg.headline(),
        dg.reason,
        started.elapsed().as_secs_f64()
    );
    assert_eq!(
        dg.verdict,
        Verdict::None,
        "{}: {}",
        dg.headline(),
        dg.reason
    );
}
