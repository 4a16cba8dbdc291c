//! `tpu`: per-point uncertainty for an existing cloud (SPEC §9, docs/tpu.md).

use anyhow::Result;
use clap::Args;
use kinescan::app::tpu::{tpu as run_tpu, TpuOptions};
use kinescan::pipeline::config;
use std::path::PathBuf;

/// Per-point uncertainty for a LAS/LAZ cloud georeferenced elsewhere: the pipeline file `run`
/// takes (trajectory, sensor, latency, uncertainty, output) and the cloud; writes a copy with
/// `run`'s uncertainty extra dimensions and a report.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan tpu day.toml --cloud last_year.las
  kinescan tpu airborne.toml --cloud strip.laz --set output.las=out/strip_tpu.las
  kinescan tpu day.toml --cloud day.las --set tpu.cone_tolerance_m=0.05 --threads 2")]
pub struct TpuArgs {
    /// Pipeline file (TOML): `[inputs]` sbet and smrmsg, `[sensor]`, `[latency]`,
    /// `[uncertainty]`, `[output]`, optional `[tpu]` and `[time]`.
    pipeline: PathBuf,
    /// The cloud (LAS 1.2-1.4 or LAZ, with GPS time and a CRS).
    #[arg(long)]
    cloud: PathBuf,
    /// Override a pipeline value, KEY=VALUE with a dotted key (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = crate::cli::threads)]
    threads: Option<usize>,
}

pub fn tpu(a: &TpuArgs, quiet: bool) -> Result<()> {
    let loaded = config::load_tpu(&a.pipeline, &a.set)?;
    let opts = TpuOptions {
        threads: a.threads,
        progress: !quiet,
        ..TpuOptions::default()
    };
    let report = run_tpu(&loaded, &a.cloud, &opts)?;
    if !quiet {
        let t = &report.totals;
        println!(
            "{} points read, {} given a sigma, {} rejected ({:.2} M points/s on {} threads)",
            t.read,
            t.with_sigma,
            t.rejected_total(),
            report.points_per_second / 1e6,
            report.threads
        );
        for (reason, n) in &t.rejected {
            let first = &t.rejected_examples[reason];
            println!(
                "  rejected {n}: {} (first points {first:?})",
                reason.describe()
            );
        }
        if !report.cloud.replaced_dimensions.is_empty() {
            println!(
                "replaced the cloud's dimensions {:?}",
                report.cloud.replaced_dimensions
            );
        }
        for o in &report.outputs {
            println!("wrote {} ({} points)", o.path.display(), o.points);
        }
        println!("report {}", loaded.config.output.report_path().display());
    }
    Ok(())
}
