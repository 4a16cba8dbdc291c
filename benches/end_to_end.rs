//! End-to-end throughput: `kinescan run` from a memory-mapped binary profile file to LAS on
//! disk, with 1 and 2 threads. Not a criterion bench: one timed run per thread count on a large
//! file, reading returns/s and peak RSS from the run report.
//!
//! `cargo bench --bench end_to_end` (2e7 returns); `KINESCAN_BENCH_RETURNS=100000000` for more;
//! `KINESCAN_BENCH_DIR=DIR` to keep the generated survey for profiling.

use kinescan::io::profiles::{ProfileColumns, ProfileWriter, RawReturn};
use kinescan::io::sbet::{SbetRecord, SbetWriter};
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

/// `n` returns: 2 M returns/s, 250 Hz mirror, ranges 5-40 m, 1% missing.
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
            5.0 + 35.0 * ((i * 7919) % 1000) as f64 / 1000.0
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
    write_profiles(&dir.join("p.ksprof"), n);
    let pipeline = format!(
        "[inputs]\nsbet = \"t.sbet\"\nprofiles = [\"p.ksprof\"]\n\n[sensor]\n\
         lever_arm_b_m = [0.5, 0.0, -1.5]\n\n[time]\nt0_s = {T0_S}\nperiod_s = {PERIOD_S}\n\
         beta_start_deg = -180.0\n\n[output]\nlas = \"out/cloud.las\"\n"
    );
    std::fs::write(dir.join("pipeline.toml"), pipeline).unwrap();
    println!(
        "end_to_end: {n} returns ({:.1} GB profile file)",
        n as f64 * 40.0 / 1e9
    );
    for threads in [1, 2] {
        let status = Command::new(env!("CARGO_BIN_EXE_kinescan"))
            .args([
                "--quiet",
                "run",
                "pipeline.toml",
                "--threads",
                &threads.to_string(),
            ])
            .current_dir(dir)
            .status()
            .unwrap();
        assert!(status.success());
        let report = std::fs::read(dir.join("out/cloud.report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
        let rps = report["returns_per_second"].as_f64().unwrap();
        let rss = report["peak_rss_bytes"].as_u64().unwrap_or(0) as f64 / 1e6;
        println!(
            "threads {threads}: {:.2} M returns/s, peak RSS {rss:.0} MB",
            rps / 1e6
        );
    }
}
