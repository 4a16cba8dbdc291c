//! Simulator throughput and memory: the survey-day scenario at two durations, returns/s with
//! 1 and 2 threads and peak RSS (VmHWM) of each run, each run in its own process.
//!
//! Output goes to a temporary directory in `KINESCAN_SIM_BENCH_DIR`, else `/dev/shm` when it
//! exists (generation speed, not the disk's), else the system temp dir. CPU seconds (user +
//! system) are printed beside wall-clock time: on a shared machine they show the work done.
//!
//! `cargo bench --bench sim`; `KINESCAN_SIM_BENCH_S="20,80"` sets the two durations (s).
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use kinescan::sim::{simulate, SimOptions};
use std::path::Path;
use std::process::Command;
#[path = "support/proc_stats.rs"]
mod proc_stats;
use proc_stats::{cpu_s, peak_rss_mib};

fn out_root() -> std::path::PathBuf {
    match std::env::var_os("KINESCAN_SIM_BENCH_DIR") {
        Some(d) => d.into(),
        None if Path::new("/dev/shm").is_dir() => "/dev/shm".into(),
        None => std::env::temp_dir(),
    }
}

fn child(duration_s: f64, threads: usize) {
    let dir = tempfile::tempdir_in(out_root()).unwrap();
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenario_survey_day.toml");
    let opts = SimOptions {
        threads: Some(threads),
        duration_s: Some(duration_s),
        ..Default::default()
    };
    let s = simulate(&scenario, dir.path(), &opts).unwrap();
    println!(
        "duration {duration_s:>6.0} s  threads {threads}  returns {:>11}  wall {:>7.2} s  {:>6.2} M returns/s  CPU {:>7.2} s ({:>5.2} M returns per CPU s)  peak RSS {:>6.1} MiB",
        s.returns,
        s.elapsed_s,
        s.returns as f64 / s.elapsed_s / 1e6,
        cpu_s(),
        s.returns as f64 / cpu_s() / 1e6,
        peak_rss_mib()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--child") {
        child(args[i + 1].parse().unwrap(), args[i + 2].parse().unwrap());
        return;
    }
    let durations: Vec<f64> = std::env::var("KINESCAN_SIM_BENCH_S")
        .unwrap_or_else(|_| "20,80".into())
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    let exe = std::env::current_exe().unwrap();
    let runs = [(durations[0], 1), (durations[0], 2), (durations[1], 2)];
    for (d, t) in runs {
        let status = Command::new(&exe)
            .args(["--child", &d.to_string(), &t.to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    }
}
