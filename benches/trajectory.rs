//! `kinescan trajectory` throughput and memory: the raw city block (200 Hz tactical IMU,
//! 10 Hz GNSS, one 30 s outage) simulated for each duration, then the whole command (read,
//! align, filter, smooth, write SBET + SMRMSG + report + error model) timed in its own
//! process: real-time factor (span / wall-clock), CPU seconds, peak RSS (VmHWM), the stored
//! forward pass in memory and spilled to the temporary file.
//!
//! `cargo bench --bench trajectory`; `KINESCAN_TRAJ_BENCH_S="600,1800"` sets the durations (s);
//! files go to `KINESCAN_TRAJ_BENCH_DIR`, else the system temp dir (not /dev/shm: the spill
//! file would count as memory there).
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use std::path::Path;
use std::process::Command;
#[path = "support/proc_stats.rs"]
mod proc_stats;
use proc_stats::{cpu_s, peak_rss_mib};

fn simulate(dir: &Path, duration_s: f64) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("pipelines/scenario_raw_city_block.toml"))
        .unwrap()
        .replace("duration_s = 120.0", &format!("duration_s = {duration_s}"));
    let sc = kinescan::sim::Scenario::parse(&text, "bench").unwrap();
    kinescan::sim::raw::write_raw(&sc, dir).unwrap();
    std::fs::write(
        dir.join("trajectory.toml"),
        "[inputs]\nimu = \"imu.bin\"\ngnss = \"gnss.bin\"\n[gnss]\n\
         lever_arm_b_m = [0.3, 0.0, -1.2]\n[output]\nsbet = \"out/smoothed.sbet\"\n\
         smrmsg = \"out/smoothed.smrmsg\"\n",
    )
    .unwrap();
}

fn child(dir: &Path) {
    let r = kinescan::ins::run(&dir.join("trajectory.toml"), &[]).unwrap();
    println!(
        "span {:>7.0} s  records {:>9}  wall {:>7.2} s  {:>6.1}x real time  CPU {:>7.2} s ({:>6.1}x per CPU s)  peak RSS {:>6.1} MiB  stored in memory {:>6.1} MiB, spilled {:>7.1} MiB",
        r.span_s,
        r.records,
        r.elapsed_s,
        r.realtime_factor,
        cpu_s(),
        r.span_s / cpu_s(),
        peak_rss_mib(),
        r.stored_bytes as f64 / 1048576.0,
        r.spilled_bytes as f64 / 1048576.0
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--child") {
        child(Path::new(&args[i + 1]));
        return;
    }
    let durations: Vec<f64> = std::env::var("KINESCAN_TRAJ_BENCH_S")
        .unwrap_or_else(|_| "600,1800".into())
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    let root =
        std::env::var_os("KINESCAN_TRAJ_BENCH_DIR").map_or_else(std::env::temp_dir, Into::into);
    let exe = std::env::current_exe().unwrap();
    for d in durations {
        let dir = tempfile::tempdir_in(&root).unwrap();
        simulate(dir.path(), d);
        let status = Command::new(&exe)
            .args(["--child", dir.path().to_str().unwrap()])
            .status()
            .unwrap();
        assert!(status.success());
    }
}
