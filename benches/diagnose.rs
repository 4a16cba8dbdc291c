//! The city-block demo survey diagnosed end to end (observations, statistics, re-processing,
//! report and plots): wall time and CPU time of `kinescan diagnose`, medians of a few runs.
//! Not a timed test: the budget (60 s on 2 cores, docs/diagnosis.md) is checked by reading the
//! printed numbers.
//!
//! `cargo bench --bench diagnose`; `KINESCAN_BENCH_REPS` (default 3) runs.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

use kinescan::app::diagnose::{self, Request};
use kinescan::pipeline::config;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
use std::time::Instant;
#[path = "support/proc_stats.rs"]
#[allow(dead_code)] // peak_rss_mib is for the other benches
mod proc_stats;
use proc_stats::cpu_s;

fn main() {
    let reps: usize = std::env::var("KINESCAN_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
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
    wall.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    println!(
        "median of {reps}: {:.2} s wall, {:.2} s CPU on {} threads (budget 60 s on 2 cores)",
        wall[reps / 2],
        cpu[reps / 2],
        rayon::current_num_threads()
    );
}
