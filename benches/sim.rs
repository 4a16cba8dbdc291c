//! Simulator throughput and memory: the survey-day scenario at two durations, returns/s with
//! 1 and 2 threads and peak RSS (VmHWM) of each run, each run in its own process.
//!
//! `cargo bench --bench sim`; `KINESCAN_SIM_BENCH_S="20,80"` sets the two durations (s).

use kinescan::sim::{simulate, SimOptions};
use std::path::Path;
use std::process::Command;

fn peak_rss_mib() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn child(duration_s: f64, threads: usize) {
    let dir = tempfile::tempdir().unwrap();
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/scenario_survey_day.toml");
    let opts = SimOptions {
        threads: Some(threads),
        duration_s: Some(duration_s),
        ..Default::default()
    };
    let s = simulate(&scenario, dir.path(), &opts).unwrap();
    println!(
        "duration {duration_s:>6.0} s  threads {threads}  returns {:>11}  time {:>7.2} s  {:>6.2} M returns/s  peak RSS {:>7.1} MiB",
        s.returns,
        s.elapsed_s,
        s.returns as f64 / s.elapsed_s / 1e6,
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
