//! `kinescan diagnose` timed and measured.
//!
//! Default case: the city-block demo survey diagnosed end to end (observations, statistics,
//! re-processing, report and plots): wall time and CPU time, medians of a few runs. Not a
//! timed test: the budget (60 s on 2 cores, docs/diagnosis.md) is checked by reading the
//! printed numbers.
//!
//! `KINESCAN_BENCH_CASE=large` ([`large_case`]): the city block driven for longer with a
//! boresight error (so the explanation is applied and the survey observed again), at the
//! survey lengths of `KINESCAN_BENCH_RETURNS` (comma-separated, default `10000000,30000000`):
//! `kinescan run` and `kinescan diagnose` of the same pipeline alternated, each in its own
//! process; medians of wall time and peak RSS and the diagnose/run ratio
//! (docs/performance.md, docs/diagnosis.md).
//!
//! `cargo bench --bench diagnose`; `KINESCAN_BENCH_REPS` (default 3) runs.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use kinescan::app::diagnose::{self, Request};
use kinescan::pipeline::config;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
use std::path::Path;
use std::process::Command;
use std::time::Instant;
#[path = "support/proc_stats.rs"]
mod proc_stats;
use proc_stats::{cpu_s, peak_rss_mib};

/// Set (to the survey folder) in the re-executed bench process that runs one diagnosis.
const CHILD_ENV: &str = "KINESCAN_BENCH_DIAGNOSE_DIR";

fn main() {
    if let Some(dir) = std::env::var_os(CHILD_ENV) {
        return diagnose_child(Path::new(&dir));
    }
    let reps: usize = std::env::var("KINESCAN_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    if std::env::var("KINESCAN_BENCH_CASE").is_ok_and(|c| c == "large") {
        return large_case(reps);
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = Scenario::parse(kinescan::app::demo::SCENARIO, "city block").unwrap();
    simulate_scenario(&sc, &d.join("survey"), &SimOptions::default()).unwrap();
    std::fs::write(d.join("pipeline.toml"), kinescan::app::demo::PIPELINE).unwrap();
    let p = config::load(&d.join("pipeline.toml"), &[]).unwrap();
    let req = Request {
        patches: d.join("survey/patches.csv"),
        control_points: None,
        out_dir: d.join("diagnosis"),
    };
    let mut wall = Vec::new();
    let mut cpu = Vec::new();
    for _ in 0..reps {
        let (t, c) = (Instant::now(), cpu_s());
        let r = diagnose::run(&p, &req).unwrap();
        wall.push(t.elapsed().as_secs_f64());
        cpu.push(cpu_s() - c);
        println!(
            "diagnose city block: {:.2} s wall, {:.2} s CPU, {} observations, verdict {}",
            wall.last().unwrap(),
            cpu.last().unwrap(),
            r.counts.observations,
            r.headline()
        );
    }
    println!(
        "median of {reps}: {:.2} s wall, {:.2} s CPU on {} threads (budget 60 s on 2 cores)",
        median(wall),
        median(cpu),
        rayon::current_num_threads()
    );
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (v[(n - 1) / 2] + v[n / 2]) / 2.0
}

/// Returns per second of the city-block scanner (600 per profile, 100 profiles/s).
const CITY_BLOCK_RETURNS_PER_S: f64 = 60_000.0;
/// The effect the large case injects: large enough to be named and applied.
const LARGE_EFFECTS: &str = "\n[effects]\nboresight_error_deg = [0.0, 0.0, 0.03]\n\n\
    [output]\ntruth_points = false\ntruth_sbet = false\n";

/// `kinescan run` against `kinescan diagnose` on the same survey at each length, alternated.
fn large_case(reps: usize) {
    let lengths: Vec<u64> = std::env::var("KINESCAN_BENCH_RETURNS")
        .unwrap_or_else(|_| "10000000,30000000".into())
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    let mut rows = Vec::new();
    for n in lengths {
        let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
        let d = tmp.path();
        let text = kinescan::app::demo::SCENARIO.to_string() + LARGE_EFFECTS;
        let sc = Scenario::parse(&text, "city block, large").unwrap();
        let opts = SimOptions {
            duration_s: Some(n as f64 / CITY_BLOCK_RETURNS_PER_S),
            ..Default::default()
        };
        let s = simulate_scenario(&sc, &d.join("survey"), &opts).unwrap();
        std::fs::write(d.join("pipeline.toml"), kinescan::app::demo::PIPELINE).unwrap();
        let (mut run, mut diag) = (Vec::new(), Vec::new());
        for _ in 0..reps {
            run.push(run_once(d));
            diag.push(diagnose_once(d));
            println!(
                "{} returns: run {:.1} s {:.0} MB, diagnose {:.1} s {:.0} MB",
                s.returns,
                run.last().unwrap().0,
                run.last().unwrap().1,
                diag.last().unwrap().0,
                diag.last().unwrap().1
            );
        }
        let col = |v: &[(f64, f64)], k: usize| median(v.iter().map(|r| [r.0, r.1][k]).collect());
        let ratios: Vec<f64> = diag.iter().zip(&run).map(|(d, r)| d.0 / r.0).collect();
        rows.push(format!(
            "| {:.1e} | {:.1} | {:.1} | {:.2} | {:.0} | {:.0} |",
            s.returns as f64,
            col(&run, 0),
            col(&diag, 0),
            median(ratios),
            col(&run, 1),
            col(&diag, 1)
        ));
    }
    println!(
        "\nmedians of {reps} alternated repetitions, {} threads",
        rayon::current_num_threads()
    );
    println!("| returns | run s | diagnose s | diagnose / run | run peak RSS MB | diagnose peak RSS MB |");
    println!("|---|---|---|---|---|---|");
    for r in rows {
        println!("{r}");
    }
}

/// One `kinescan run` of `dir/pipeline.toml`: (whole wall time s, peak RSS MB of its report).
fn run_once(dir: &Path) -> (f64, f64) {
    let _ = std::fs::remove_dir_all(dir.join("out"));
    let started = Instant::now();
    let status = Command::new(env!("CARGO_BIN_EXE_kinescan"))
        .args(["--quiet", "run", "pipeline.toml"])
        .current_dir(dir)
        .status()
        .unwrap();
    assert!(status.success());
    let wall = started.elapsed().as_secs_f64();
    let report = std::fs::read(dir.join("out/city_block.report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
    let rss = report["peak_rss_bytes"]
        .as_u64()
        .expect("the run report has no peak_rss_bytes (no /proc/self/status here)")
        as f64
        / 1e6;
    (wall, rss)
}

/// One diagnosis of `dir` in a fresh bench process: (whole wall time s, its peak RSS MB).
fn diagnose_once(dir: &Path) -> (f64, f64) {
    let _ = std::fs::remove_dir_all(dir.join("diagnosis"));
    let started = Instant::now();
    let out = Command::new(std::env::current_exe().unwrap())
        .env(CHILD_ENV, dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let wall = started.elapsed().as_secs_f64();
    let rss_mib: f64 = String::from_utf8(out.stdout)
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    (wall, rss_mib * 1.048_576)
}

/// The child of [`diagnose_once`]: diagnoses `dir/pipeline.toml` against its survey's
/// patches and prints its peak RSS (MiB).
fn diagnose_child(dir: &Path) {
    let p = config::load(&dir.join("pipeline.toml"), &[]).unwrap();
    let req = Request {
        patches: dir.join("survey/patches.csv"),
        control_points: None,
        out_dir: dir.join("diagnosis"),
    };
    diagnose::run(&p, &req).unwrap();
    println!("{}", peak_rss_mib());
}
