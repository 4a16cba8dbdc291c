//! End-to-end throughput: `kinescan run` from a memory-mapped binary profile file to LAS on
//! disk, with 1 and 2 threads, without uncertainty, with the default uncertainty fields
//! (sigma_x/y/z) and with all of them (plus thu95/tvu95 and the six shares). Not a criterion
//! bench: whole runs on a large file, interleaved and repeated, medians of the returns/s and
//! peak RSS from the run reports and of the wall time.
//!
//! `cargo bench --bench end_to_end` (2e7 returns, 3 repetitions); `KINESCAN_BENCH_RETURNS`,
//! `KINESCAN_BENCH_REPS` to change them; `KINESCAN_BENCH_DIR=DIR` to keep the generated survey
//! for profiling.

use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use kinescan::io::sbet::{SbetRecord, SbetWriter};
use kinescan::io::smrmsg::{SmrmsgRecord, SmrmsgWriter};
use std::path::Path;
use std::process::Command;

const RATE_HZ: f64 = 2.0e6;
const PERIOD_S: f64 = 0.004;
const T0_S: f64 = 100_000.0;

/// A straight 15 m/s drive north at 200 Hz covering `seconds`.
fn write_sbet(path: &Path, seconds: f64) {
    let mut w = SbetWriter::create(path).unwrap();
    let (lat0, lon0) = (48.1f64.to_radians(), 11.5f64.to_radians());
    for k in 0..=((seconds + 2.0) * 200.0) as usize {
        let t = k as f64 / 200.0;
        let r = SbetRecord {
            time_s: T0_S - 1.0 + t,
            lat_rad: lat0 + 15.0 * t / 6_366_000.0,
            lon_rad: lon0,
            alt_m: 520.0,
            vel_x_mps: 15.0,
            roll_rad: 0.01 * (3.0 * t).sin(),
            pitch_rad: 0.01 * (2.0 * t).cos(),
            platform_heading_rad: 0.001 * t,
            ..SbetRecord::default()
        };
        w.push(&r).unwrap();
    }
    w.finish().unwrap();
}

/// 1 Hz accuracy over the same span.
fn write_smrmsg(path: &Path, seconds: f64) {
    let mut w = SmrmsgWriter::create(path).unwrap();
    for k in 0..=(seconds + 2.0) as usize {
        let r = SmrmsgRecord {
            time_s: T0_S - 1.0 + k as f64,
            north_m: 0.02,
            east_m: 0.02,
            down_m: 0.03,
            vel_north_mps: 0.01,
            vel_east_mps: 0.01,
            vel_down_mps: 0.01,
            roll_arcmin: 0.3,
            pitch_arcmin: 0.3,
            heading_arcmin: 1.0,
        };
        w.push(&r).unwrap();
    }
    w.finish().unwrap();
}

/// The `[uncertainty]` table of the uncertainty runs (default fields: sigma_x, sigma_y,
/// sigma_z).
const UNCERTAINTY: &str = "\n[uncertainty]\nsigma_lever_arm_b_m = [0.01, 0.01, 0.01]\n\
    sigma_boresight_deg = [0.01, 0.01, 0.01]\nsigma_alpha_deg = 0.005\nsigma_beta_deg = 0.005\n\
    sigma_range_m = 0.005\nsigma_range_zero_m = 0.005\n\
    clock_covariance_s2 = [[1e-8, 0.0], [0.0, 1e-16]]\nsigma_attitude_latency_s = 0.0002\n";
/// The optional fields, added for the "all fields" runs.
const OPTIONAL_FIELDS: &str = "write_95 = true\nwrite_shares = true\n";

/// `n` returns: 2 M returns/s, 250 Hz mirror, 1% missing; ranges 5-40 m varying smoothly
/// along each profile, as a street cross-section does.
fn write_profiles(path: &Path, n: u64) {
    let per_profile = (RATE_HZ * PERIOD_S) as u64;
    let mut w = ProfileWriter::create(path, ProfileColumns::default()).unwrap();
    for i in 0..n {
        let k = i % per_profile;
        let beta =
            -std::f64::consts::PI + std::f64::consts::TAU * (k as f64 + 0.5) / per_profile as f64;
        let range = if i % 100 == 7 {
            0.0
        } else {
            let phase = 3.0 * beta + 1e-3 * (i / per_profile) as f64;
            5.0 + 35.0 * (0.5 + 0.5 * phase.sin())
        };
        let r = RawReturn {
            profile: (i / per_profile) as u32,
            intensity: (i % 4096) as u16,
            beta_rad: beta,
            range_m: range,
            ..RawReturn::default()
        };
        w.push(&r).unwrap();
    }
    w.finish().unwrap();
}

/// One timed run: (returns/s georeferenced, whole wall time s, peak RSS MB).
fn run_once(dir: &Path, file: &str, threads: usize) -> (f64, f64, f64) {
    // Each run starts from the same state: replacing a multi-GB LAS still in the page cache
    // makes the kernel's write copy 2-3x slower on a small VM, whichever run came before.
    let _ = std::fs::remove_file(dir.join("out/cloud.las"));
    let started = std::time::Instant::now();
    let status = Command::new(env!("CARGO_BIN_EXE_kinescan"))
        .args(["--quiet", "run", file, "--threads", &threads.to_string()])
        .current_dir(dir)
        .status()
        .unwrap();
    assert!(status.success());
    let wall = started.elapsed().as_secs_f64();
    let report = std::fs::read(dir.join("out/cloud.report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
    let rps = report["returns_per_second"].as_f64().unwrap();
    let rss = report["peak_rss_bytes"].as_u64().unwrap_or(0) as f64 / 1e6;
    (rps, wall, rss)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (v[(n - 1) / 2] + v[n / 2]) / 2.0
}

fn main() {
    let n: u64 = std::env::var("KINESCAN_BENCH_RETURNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000_000);
    // KINESCAN_BENCH_DIR keeps the dataset (for profiling); default: a temporary folder.
    let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
    let kept = std::env::var_os("KINESCAN_BENCH_DIR").map(std::path::PathBuf::from);
    let dir = kept.as_deref().unwrap_or(tmp.path());
    std::fs::create_dir_all(dir).unwrap();
    write_sbet(&dir.join("t.sbet"), n as f64 / RATE_HZ);
    write_smrmsg(&dir.join("t.smrmsg"), n as f64 / RATE_HZ);
    write_profiles(&dir.join("p.ksprof"), n);
    let pipeline = format!(
        "[inputs]\nsbet = \"t.sbet\"\nprofiles = [\"p.ksprof\"]\n\n[sensor]\n\
         lever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {T0_S}\nperiod_s = {PERIOD_S}\n\
         beta_start_deg = -180.0\n\n[output]\nlas = \"out/cloud.las\"\n"
    );
    let with_smrmsg = pipeline.replace("profiles =", "smrmsg = \"t.smrmsg\"\nprofiles =");
    let sigmas = with_smrmsg + UNCERTAINTY;
    std::fs::write(
        dir.join("all_fields.toml"),
        sigmas.clone() + OPTIONAL_FIELDS,
    )
    .unwrap();
    std::fs::write(dir.join("uncertainty.toml"), sigmas).unwrap();
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
    let reps: usize = std::env::var("KINESCAN_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    println!(
        "end_to_end: {n} returns ({:.1} GB profile file), median of {reps} interleaved runs",
        n as f64 * 40.0 / 1e9
    );
    let files = ["pipeline.toml", "uncertainty.toml", "all_fields.toml"];
    for threads in [1, 2] {
        let mut runs = vec![Vec::new(); files.len()];
        for _ in 0..reps {
            for (k, file) in files.iter().enumerate() {
                runs[k].push(run_once(dir, file, threads));
            }
        }
        let base_wall = median(runs[0].iter().map(|r| r.1).collect());
        for (file, r) in files.iter().zip(&runs) {
            let rps = median(r.iter().map(|r| r.0).collect());
            let wall = median(r.iter().map(|r| r.1).collect());
            let rss = median(r.iter().map(|r| r.2).collect());
            println!(
                "{file}, {threads} thread(s): {:.2} M returns/s georeferenced, {wall:.2} s for \
                 the whole run ({:+.0}% vs pipeline.toml), peak RSS {rss:.0} MB",
                rps / 1e6,
                (wall / base_wall - 1.0) * 100.0
            );
        }
    }
}
