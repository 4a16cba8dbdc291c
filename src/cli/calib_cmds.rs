//! `calibrate latency|boresight|simulate-table|simulate-tripod`.

use anyhow::Result;
use clap::{Args, Subcommand};
use kinescan::calib::{boresight, latency, sim_table, sim_tripod};
use std::path::PathBuf;

/// Calibrate the IMU-to-scanner latency or the boresight (docs/calibration.md).
#[derive(Args)]
pub struct CalibrateArgs {
    #[command(subcommand)]
    what: CalibrateCommand,
}

#[derive(Subcommand)]
enum CalibrateCommand {
    /// Latency from sphere scans on a table turning at +-omega (docs/calibration.md, "Latency:
    /// lab guide").
    #[command(after_help = "Examples:
  kinescan calibrate latency pipelines/calib_latency.toml --out work/latency
  kinescan calibrate simulate-table pipelines/calib_sim_table.toml --out work/table && \\
    kinescan calibrate latency work/table/calib_latency.toml --out work/latency")]
    Latency(Job),
    /// Boresight from static scans of a tripod at three or more sites (docs/calibration.md,
    /// "Boresight: lab guide").
    #[command(after_help = "Examples:
  kinescan calibrate boresight pipelines/calib_boresight.toml --out work/boresight
  kinescan calibrate simulate-tripod pipelines/calib_sim_tripod.toml --out work/tripod")]
    Boresight(Job),
    /// Simulate a rotating-table latency session (writes the files `calibrate latency` reads).
    #[command(after_help = "Example:
  kinescan calibrate simulate-table pipelines/calib_sim_table.toml --out work/table")]
    SimulateTable(Job),
    /// Simulate tripod boresight sites, and the Monte Carlo study if configured.
    #[command(after_help = "Example:
  kinescan calibrate simulate-tripod pipelines/calib_sim_tripod.toml --out work/tripod")]
    SimulateTripod(Job),
}

#[derive(Args)]
struct Job {
    /// Configuration file (TOML).
    config: PathBuf,
    /// Output folder (created if missing).
    #[arg(long, default_value = "calibration")]
    out: PathBuf,
}

pub fn calibrate(a: &CalibrateArgs, quiet: bool) -> Result<()> {
    let print = |v: serde_json::Value| {
        if !quiet {
            println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        }
    };
    let job = match &a.what {
        CalibrateCommand::Latency(j)
        | CalibrateCommand::Boresight(j)
        | CalibrateCommand::SimulateTable(j)
        | CalibrateCommand::SimulateTripod(j) => j,
    };
    crate::cli::remove_stale_temps(&job.out)?;
    match &a.what {
        CalibrateCommand::Latency(j) => print(serde_json::to_value(
            latency::run_latency_calibration(&j.config, &j.out)?,
        )?),
        CalibrateCommand::Boresight(j) => print(serde_json::to_value(
            boresight::run_boresight_calibration(&j.config, &j.out)?,
        )?),
        CalibrateCommand::SimulateTable(j) => print(serde_json::to_value(
            sim_table::run_table_simulation(&j.config, &j.out)?,
        )?),
        CalibrateCommand::SimulateTripod(j) => {
            let mc = sim_tripod::run_tripod_simulation(&j.config, &j.out)?;
            print(serde_json::json!({ "monte_carlo": mc, "out": j.out }))
        }
    }
    Ok(())
}
