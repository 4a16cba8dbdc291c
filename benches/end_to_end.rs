//! End-to-end throughput against the machine's I/O floor: `kinescan run` from a memory-mapped
//! binary profile file to LAS on disk, with 1 and 2 threads, without uncertainty, with the
//! default uncertainty fields (sigma_x/y/z) and with all of them (plus thu95/tvu95 and the six
//! shares), alternated with the I/O floor on the same input: one process that reads every
//! input file once (4 MiB reads) and writes as many bytes as the run's LAS to a new file, then
//! fsyncs it. Not a criterion bench: whole-process runs on a large file, interleaved in every
//! repetition (floor, then the six runs), medians of the wall times, of the returns/s and peak
//! RSS from the run reports, and of the per-repetition ratios with their min-max spread (the
//! machine's noise).
//!
//! Then the LAZ case ([`laz_case`]): `output.format = "laz"` against the same run writing LAS,
//! and LAZ on 1 against 2 threads, alternated, with the compression stage's own time.
//!
//! `cargo bench --bench end_to_end` (2e7 returns, 3 repetitions); `KINESCAN_BENCH_RETURNS`,
//! `KINESCAN_BENCH_REPS` to change them (0: write the survey only); `KINESCAN_BENCH_DIR=DIR`
//! to keep the generated survey for profiling; `KINESCAN_BENCH_CASE=laz` for the LAZ case
//! alone, `KINESCAN_BENCH_CASE=day` for `kinescan day` against `kinescan run` ([`day_case`]),
//! `KINESCAN_BENCH_CASE=tpu` for `kinescan tpu` on the cloud `run` wrote ([`tpu_case`]).
//! See docs/performance.md.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

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

/// The inputs the floor reads: every file the pipelines read.
const INPUTS: [&str; 3] = ["t.sbet", "t.smrmsg", "p.ksprof"];
/// The floor's read size (bytes).
const FLOOR_READ_BYTES: usize = 4 << 20;
/// Set (to the byte count) in the re-executed bench process that measures the floor.
const FLOOR_ENV: &str = "KINESCAN_BENCH_FLOOR_BYTES";

/// The I/O floor's body, run in its own process: read `INPUTS` in `dir` once, write
/// `out_bytes` to `dir/out/floor.bin` (new file) and fsync it.
fn floor_body(dir: &Path, out_bytes: u64) {
    use std::io::{Read, Write};
    let mut buf = vec![0u8; FLOOR_READ_BYTES];
    let mut read = 0u64;
    for name in INPUTS {
        let mut f = std::fs::File::open(dir.join(name)).unwrap();
        loop {
            let n = f.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            read += n as u64;
        }
    }
    // Write what was read (not a constant page) so nothing can shortcut the copy.
    let mut out = std::fs::File::create_new(dir.join("out/floor.bin")).unwrap();
    let mut left = out_bytes;
    while left > 0 {
        let n = left.min(buf.len() as u64) as usize;
        out.write_all(&buf[..n]).unwrap();
        left -= n as u64;
    }
    out.sync_all().unwrap();
    assert!(read > 0);
}

/// One timed floor process: whole wall time s (process start to exit, as for the runs).
fn floor_once(dir: &Path, out_bytes: u64) -> f64 {
    let _ = std::fs::remove_file(dir.join("out/floor.bin"));
    let started = std::time::Instant::now();
    let status = Command::new(std::env::current_exe().unwrap())
        .env(FLOOR_ENV, out_bytes.to_string())
        .current_dir(dir)
        .status()
        .unwrap();
    assert!(status.success());
    let wall = started.elapsed().as_secs_f64();
    std::fs::remove_file(dir.join("out/floor.bin")).unwrap();
    wall
}

/// One timed run: (returns/s georeferenced, whole wall time s, peak RSS MB).
fn run_once(dir: &Path, file: &str, threads: usize) -> (f64, f64, f64) {
    // Each run starts from the same state: replacing a multi-GB LAS still in the page cache
    // makes the kernel's write copy 2-3x slower on a small VM, whichever run came before.
    let _ = std::fs::remove_file(dir.join("out/cloud.las"));
    let _ = std::fs::remove_file(dir.join("out/cloud.laz"));
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
    let rss = report["peak_rss_bytes"]
        .as_u64()
        .expect("the run report has no peak_rss_bytes (no /proc/self/status here)")
        as f64
        / 1e6;
    (rps, wall, rss)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (v[(n - 1) / 2] + v[n / 2]) / 2.0
}

/// `(median, min, max)` of per-repetition ratios `a[i] / b[i]`.
fn ratio_stats(a: &[f64], b: &[f64]) -> (f64, f64, f64) {
    let r: Vec<f64> = a.iter().zip(b).map(|(a, b)| a / b).collect();
    let lo = r.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = r.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (median(r), lo, hi)
}

fn fmt_ratio((med, lo, hi): (f64, f64, f64)) -> String {
    format!("{med:.2}x [{lo:.2}-{hi:.2}]")
}

fn main() {
    if let Some(bytes) = std::env::var_os(FLOOR_ENV) {
        let bytes = bytes.to_str().unwrap().parse().unwrap();
        floor_body(&std::env::current_dir().unwrap(), bytes);
        return;
    }
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
    if reps == 0 {
        return; // the survey only (profiling, memory measurements)
    }
    if std::env::var("KINESCAN_BENCH_CASE").is_ok_and(|c| c == "laz") {
        return laz_case(dir, reps);
    }
    if std::env::var("KINESCAN_BENCH_CASE").is_ok_and(|c| c == "day") {
        return day_case(dir, reps);
    }
    if std::env::var("KINESCAN_BENCH_CASE").is_ok_and(|c| c == "tpu") {
        return tpu_case(dir, reps);
    }
    // The floor writes as many bytes as the run without uncertainty (the 3.0x criterion's run).
    run_once(dir, "pipeline.toml", 2);
    let las_bytes = std::fs::metadata(dir.join("out/cloud.las")).unwrap().len();
    let input_bytes: u64 = INPUTS
        .iter()
        .map(|f| std::fs::metadata(dir.join(f)).unwrap().len())
        .sum();
    println!(
        "end_to_end: {n} returns ({:.2} GB input, {:.2} GB LAS without uncertainty), \
         medians of {reps} interleaved repetitions; [min-max] of the per-repetition ratios",
        input_bytes as f64 / 1e9,
        las_bytes as f64 / 1e9
    );
    let files = ["pipeline.toml", "uncertainty.toml", "all_fields.toml"];
    let configs: Vec<(usize, &str)> = [1, 2]
        .into_iter()
        .flat_map(|t| files.iter().map(move |f| (t, *f)))
        .collect();
    let mut floor = Vec::new();
    let mut runs = vec![Vec::new(); configs.len()];
    for _ in 0..reps {
        floor.push(floor_once(dir, las_bytes));
        for (k, (threads, file)) in configs.iter().enumerate() {
            runs[k].push(run_once(dir, file, *threads));
        }
    }
    print_tables(&floor, &runs, &configs, files.len());
    laz_case(dir, reps);
}

/// The markdown tables of docs/performance.md: one row per configuration, then every ratio of
/// issue #13's acceptance against its target. `configs` is 1 thread then 2 threads, `per_threads`
/// files each, the run without uncertainty first.
fn print_tables(
    floor: &[f64],
    runs: &[Vec<(f64, f64, f64)>],
    configs: &[(usize, &str)],
    per_threads: usize,
) {
    let walls: Vec<Vec<f64>> = runs
        .iter()
        .map(|r| r.iter().map(|r| r.1).collect())
        .collect();
    println!(
        "\n| | wall (median) | M returns/s | run/floor [min-max] | vs no uncertainty | peak RSS |"
    );
    println!("|---|---|---|---|---|---|");
    println!("| I/O floor | {:.3} s | | 1 | | |", median(floor.to_vec()));
    for (k, ((threads, file), r)) in configs.iter().zip(runs).enumerate() {
        let base = k - k % per_threads;
        println!(
            "| {file}, {threads} thread(s) | {:.3} s | {:.2} | {} | {} | {:.0} MB |",
            median(walls[k].clone()),
            median(r.iter().map(|r| r.0).collect()) / 1e6,
            fmt_ratio(ratio_stats(&walls[k], floor)),
            fmt_ratio(ratio_stats(&walls[k], &walls[base])),
            median(r.iter().map(|r| r.2).collect()),
        );
    }
    let two = per_threads; // index of the run without uncertainty on 2 threads
    let mut acceptance = vec![(
        "run/floor, no uncertainty, 2 threads".to_string(),
        ratio_stats(&walls[two], floor),
        "<= 3.0x",
    )];
    for k in 0..per_threads {
        let name = format!("2 threads / 1 thread, {}", configs[k].1);
        acceptance.push((name, ratio_stats(&walls[k], &walls[k + two]), ">= 1.8x"));
    }
    for (k, target) in [(1, "<= 1.25x"), (2, "<= 1.5x")] {
        for base in [0, two] {
            let (threads, file) = configs[base + k];
            let name = format!("{file} / pipeline.toml, {threads} thread(s)");
            acceptance.push((name, ratio_stats(&walls[base + k], &walls[base]), target));
        }
    }
    println!("\n| acceptance (issue #13) | median [min-max] | target |");
    println!("|---|---|---|");
    for (name, ratio, target) in acceptance {
        println!("| {name} | {} | {target} |", fmt_ratio(ratio));
    }
}

/// `output.format = "laz"` against LAS (both on 2 threads) and LAZ on 1 against 2 threads,
/// alternated in every repetition: medians of the wall times, of the compression stage
/// (`stages.compress` of the report) and the sizes.
fn laz_case(dir: &Path, reps: usize) {
    let las = std::fs::read_to_string(dir.join("pipeline.toml")).unwrap();
    let laz = las.replace("[output]\n", "[output]\nformat = \"laz\"\n");
    std::fs::write(dir.join("laz.toml"), laz).unwrap();
    let configs = [("pipeline.toml", 2), ("laz.toml", 2), ("laz.toml", 1)];
    let (mut walls, mut compress_s, mut bytes) = (vec![Vec::new(); 3], vec![Vec::new(); 3], [0; 3]);
    for _ in 0..reps {
        for (k, (file, threads)) in configs.iter().enumerate() {
            walls[k].push(run_once(dir, file, *threads).1);
            let report = std::fs::read(dir.join("out/cloud.report.json")).unwrap();
            let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
            let stages = report["stages"].as_array().unwrap();
            let compress = stages.iter().find(|s| s["stage"] == "compress");
            compress_s[k].push(compress.map_or(0.0, |s| s["seconds"].as_f64().unwrap()));
            bytes[k] = report["outputs"][0]["bytes"].as_u64().unwrap();
        }
    }
    println!("LAZ case, medians of {reps} alternated repetitions; [min-max] of the ratios");
    for (k, (file, threads)) in configs.iter().enumerate() {
        println!(
            "{file}, {threads} thread(s): {:.3} s, compress stage {:.3} s, {:.1} MB",
            median(walls[k].clone()),
            median(compress_s[k].clone()),
            bytes[k] as f64 / 1e6
        );
    }
    println!(
        "LAZ / LAS (2 threads): wall {}, size {:.3}",
        fmt_ratio(ratio_stats(&walls[1], &walls[0])),
        bytes[1] as f64 / bytes[0] as f64
    );
    println!(
        "LAZ 2 threads / 1 thread speed-up: wall {}, compress stage {}",
        fmt_ratio(ratio_stats(&walls[2], &walls[1])),
        fmt_ratio(ratio_stats(&compress_s[2], &compress_s[1]))
    );
}

/// `kinescan day` (the survey as one pass, per-pass layout: units, journal, merge) against
/// `kinescan run` of the same pipeline, both on 2 threads, alternated: medians and the ratio.
/// `KINESCAN_BENCH_DAY_TEMPLATE` names the pipeline (default `pipeline.toml`, no uncertainty;
/// `uncertainty.toml` adds the sigmas and the day's sigma histograms), `KINESCAN_BENCH_DAY_UNIT_S`
/// the work unit length (default 60 s: the pass is one unit; shorter: several units, written
/// one after another into the pass's file; at 5e6 returns, 2.5 s of scanning, 0.8 s gives four).
fn day_case(dir: &Path, reps: usize) {
    let template =
        std::env::var("KINESCAN_BENCH_DAY_TEMPLATE").unwrap_or_else(|_| "pipeline.toml".into());
    let unit_s: f64 = std::env::var("KINESCAN_BENCH_DAY_UNIT_S")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(60.0);
    let day = format!(
        "[day]\ntemplate = \"{template}\"\nout = \"night\"\nunit_s = {unit_s:?}\n\
         layout = {{ kind = \"per_pass\" }}\n\n[[passes]]\nname = \"p\"\n\
         profiles = [\"p.ksprof\"]\n"
    );
    std::fs::write(dir.join("day.toml"), day).unwrap();
    let (mut run_s, mut day_s) = (Vec::new(), Vec::new());
    let mut steps: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for _ in 0..reps {
        run_s.push(run_once(dir, &template, 2).1);
        // A fresh night each time: with the previous journal the day would only re-merge.
        let _ = std::fs::remove_dir_all(dir.join("night"));
        let started = std::time::Instant::now();
        let status = Command::new(env!("CARGO_BIN_EXE_kinescan"))
            .args(["--quiet", "day", "day.toml", "--threads", "2"])
            .current_dir(dir)
            .status()
            .unwrap();
        assert!(status.success());
        day_s.push(started.elapsed().as_secs_f64());
        let report = std::fs::read(dir.join("night/day.report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
        for (k, step) in ["plan", "units", "merge"].iter().enumerate() {
            steps[k].push(report["timings_s"][step].as_f64().unwrap());
        }
    }
    let units = std::fs::read(dir.join("night/plan.json")).unwrap();
    let units: serde_json::Value = serde_json::from_slice(&units).unwrap();
    println!(
        "day case ({template}, {} unit(s)), medians of {reps} alternated repetitions; \
         [min-max] of the ratios",
        units["units"].as_array().unwrap().len()
    );
    println!(
        "kinescan run {:.3} s, kinescan day {:.3} s (plan {:.3} s, units {:.3} s, merge {:.3} s): \
         day / run {}",
        median(run_s.clone()),
        median(day_s.clone()),
        median(steps[0].clone()),
        median(steps[1].clone()),
        median(steps[2].clone()),
        fmt_ratio(ratio_stats(&day_s, &run_s))
    );
}

/// `kinescan tpu` beside `kinescan run` on the same points (docs/tpu.md): the run with the
/// default uncertainty fields writes the cloud once; then, alternated, that run again and
/// `tpu` on its cloud with the same pipeline (default fields), 2 threads: points/s over the
/// per-point stage (`returns_per_second`, `points_per_second` of the reports), whole wall
/// time, peak RSS.
fn tpu_case(dir: &Path, reps: usize) {
    run_once(dir, "uncertainty.toml", 2);
    std::fs::rename(dir.join("out/cloud.las"), dir.join("base.las")).unwrap();
    let tpu_once = || {
        let _ = std::fs::remove_file(dir.join("out/tpu.las"));
        let started = std::time::Instant::now();
        let status = Command::new(env!("CARGO_BIN_EXE_kinescan"))
            .args(["--quiet", "tpu", "uncertainty.toml", "--cloud", "base.las"])
            .args(["--set", "output.las=\"out/tpu.las\"", "--threads", "2"])
            .current_dir(dir)
            .status()
            .unwrap();
        assert!(status.success());
        let wall = started.elapsed().as_secs_f64();
        let report = std::fs::read(dir.join("out/tpu.report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
        let pps = report["points_per_second"].as_f64().unwrap();
        let rss = report["peak_rss_bytes"]
            .as_u64()
            .expect("the run report has no peak_rss_bytes (no /proc/self/status here)")
            as f64
            / 1e6;
        (pps, wall, rss)
    };
    let (mut run, mut tpu) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        run.push(run_once(dir, "uncertainty.toml", 2));
        tpu.push(tpu_once());
    }
    let col =
        |v: &[(f64, f64, f64)], k: usize| median(v.iter().map(|r| [r.0, r.1, r.2][k]).collect());
    println!("| command (2 threads, default fields) | M points/s | wall s | peak RSS MB |");
    println!("|---|---|---|---|");
    for (name, v) in [("run", &run), ("tpu", &tpu)] {
        println!(
            "| {name} | {:.2} | {:.2} | {:.0} |",
            col(v, 0) / 1e6,
            col(v, 1),
            col(v, 2)
        );
    }
}
