//! `sensitivity`.

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

/// Sobol sensitivity (first-order and total, with bootstrap intervals) and linear variance
/// shares of the georeferenced point to every input (docs/uncertainty.md).
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan sensitivity pipelines/sensitivity_parking_lot_expected.toml --out work/sens_expected
  kinescan sensitivity pipelines/sensitivity_parking_lot_ideal.toml --out work/sens_ideal")]
pub struct SensitivityArgs {
    /// Study file (TOML).
    config: PathBuf,
    /// Output folder (created if missing).
    #[arg(long, default_value = "sensitivity")]
    out: PathBuf,
}

pub fn sensitivity(a: &SensitivityArgs, quiet: bool) -> Result<()> {
    crate::cli::remove_stale_temps(&a.out)?;
    let report = kinescan::app::sensitivity::run_sensitivity(&a.config, &a.out)?;
    if !quiet {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}
