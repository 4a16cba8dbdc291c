//! `simulate` and `demo`.

use anyhow::Result;
use clap::Args;
use kinescan::pipeline::RunOptions;
use kinescan::sim::{self, SimOptions};
use std::path::PathBuf;

/// Simulate a survey with ground truth: SBET, SMRMSG, raw profiles, control points, reference
/// patches, truth.json and per-return true coordinates (docs/simulator.md).
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan simulate pipelines/scenario_city_block.toml --out work/city
  kinescan simulate pipelines/scenario_survey_day.toml --out work/day --duration-s 600 --csv")]
pub struct SimulateArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Output folder (created if missing).
    #[arg(long, default_value = "simulated")]
    out: PathBuf,
    /// Replace the scenario's duration (s).
    #[arg(long)]
    duration_s: Option<f64>,
    /// Also write the profiles as CSV.
    #[arg(long)]
    csv: bool,
    /// Worker threads (default: all cores; the output does not depend on it).
    #[arg(long, value_parser = crate::cli::threads)]
    threads: Option<usize>,
}

/// The built-in demo: simulate a city block, georeference it, compare with the truth.
#[derive(Args)]
#[command(after_help = "Example:
  kinescan demo --out work/demo")]
pub struct DemoArgs {
    /// Work folder (created if missing).
    #[arg(long, default_value = "work/demo")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = crate::cli::threads)]
    threads: Option<usize>,
}

fn progress(quiet: bool, what: &'static str) -> Option<sim::Progress> {
    if quiet {
        return None;
    }
    let bar = kinescan::progress::bar(0, what);
    Some(Box::new(move |done, total| {
        bar.set_length(total);
        bar.set_position(done);
        if done == total {
            bar.finish_and_clear();
        }
    }))
}

pub fn simulate(a: &SimulateArgs, quiet: bool) -> Result<()> {
    crate::cli::remove_stale_temps(&a.out)?;
    let opts = SimOptions {
        threads: a.threads,
        progress: progress(quiet, "simulating profiles"),
        profiles_csv: a.csv,
        duration_s: a.duration_s,
    };
    let s = sim::simulate(&a.scenario, &a.out, &opts)?;
    if !quiet {
        println!(
            "{} profiles, {} returns ({} with a range) in {:.1} s -> {}",
            s.profiles,
            s.returns,
            s.valid_returns,
            s.elapsed_s,
            s.out_dir.display()
        );
    }
    Ok(())
}

pub fn demo(a: &DemoArgs, quiet: bool) -> Result<()> {
    for dir in [a.out.clone(), a.out.join("survey")] {
        crate::cli::remove_stale_temps(&dir)?;
    }
    let run = RunOptions {
        threads: a.threads,
        progress: !quiet,
        ..RunOptions::default()
    };
    let sim = SimOptions {
        threads: a.threads,
        progress: progress(quiet, "simulating the city block"),
        ..SimOptions::default()
    };
    let d = kinescan::app::demo::run_demo(&a.out, &sim, &run)?;
    if !quiet {
        println!("{d}");
    }
    Ok(())
}
