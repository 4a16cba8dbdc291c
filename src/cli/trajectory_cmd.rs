//! `trajectory`: raw IMU + GNSS to the smoothed SBET + SMRMSG (docs/trajectory.md).

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

/// Process raw IMU and GNSS records into a trajectory: loosely coupled Kalman filter and
/// Rauch-Tung-Striebel smoother; SBET + SMRMSG at the IMU rate, a run report and the smoothed
/// errors' autocorrelation (docs/trajectory.md).
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan simulate pipelines/scenario_raw_city_block.toml --out work/raw
  kinescan trajectory pipelines/trajectory_raw_city_block.toml
  kinescan trajectory traj.toml --set gnss.lever_arm_b_m=[0.1,0.0,-1.2]")]
pub struct TrajectoryArgs {
    /// Trajectory configuration (TOML).
    config: PathBuf,
    /// Override a configuration value, KEY=VALUE with a dotted key (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

pub fn trajectory(a: &TrajectoryArgs, quiet: bool) -> Result<()> {
    let r = kinescan::ins::run(&a.config, &a.set)?;
    if !quiet {
        let f = &r.filter;
        println!(
            "{} records over {:.1} s in {:.1} s ({:.0}x real time); GNSS: {} fixes used, {} rejected by the innovation test; {} GNSS gaps",
            r.records,
            r.span_s,
            r.elapsed_s,
            r.realtime_factor,
            f.gnss_used,
            f.gnss_rejected,
            r.gnss_gaps.len()
        );
        for p in &r.outputs {
            println!("  {}", p.display());
        }
    }
    Ok(())
}
