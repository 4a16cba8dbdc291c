//! `run`, `validate`, `import`, `info`.

use anyhow::{Context, Result};
use clap::Args;
use kinescan::pipeline::{self, config, RunOptions};
use std::path::PathBuf;

/// Georeference a survey: trajectory + raw profiles in, LAS 1.4 and a JSON run report out.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan run pipelines/demo_city_block.toml
  kinescan run day.toml --set latency.attitude_s=0.0021 --set output.las=out/day_tau21.las
  kinescan run day.toml --threads 1")]
pub struct RunArgs {
    /// Pipeline file (TOML).
    pipeline: PathBuf,
    /// Override a pipeline value, KEY=VALUE with a dotted key (repeatable). Recorded in the
    /// run report.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = crate::cli::threads)]
    threads: Option<usize>,
}

/// Check a pipeline file without running it: keys, values, and that every input opens.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan validate pipelines/demo_city_block.toml
  kinescan validate day.toml --set time.period_s=0.004")]
pub struct ValidateArgs {
    /// Pipeline file (TOML).
    pipeline: PathBuf,
    /// Override a pipeline value, KEY=VALUE (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

/// Convert CSV profiles (conventions §6) to the memory-mapped binary form.
#[derive(Args)]
#[command(after_help = "Example:
  kinescan import pass1.csv pass1.ksprof")]
pub struct ImportArgs {
    /// CSV profile file.
    csv: PathBuf,
    /// Binary profile file to write.
    output: PathBuf,
}

/// Summarise an SBET, SMRMSG, profile or control-point file: span, rate, gaps, counts.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan info trajectory.sbet
  kinescan info pass1.ksprof --json")]
pub struct InfoArgs {
    /// File to describe, or an output folder: whether its sets are whole (each file a report
    /// lists there with its SHA-256, no publication interrupted).
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &RunArgs, quiet: bool) -> Result<()> {
    let loaded = config::load(&a.pipeline, &a.set)?;
    let opts = RunOptions {
        threads: a.threads,
        progress: !quiet,
        ..RunOptions::default()
    };
    let report = pipeline::run(&loaded, &opts)?;
    if !quiet {
        let t = &report.totals;
        println!(
            "{} returns read, {} written, {} rejected ({:.2} M returns/s on {} threads)",
            t.read,
            t.written,
            t.rejected_total(),
            report.returns_per_second / 1e6,
            report.threads
        );
        for (reason, n) in &t.rejected {
            println!("  rejected {n}: {}", reason.describe());
        }
        for o in &report.outputs {
            println!("wrote {} ({} points)", o.path.display(), o.points);
        }
        println!("report {}", loaded.config.output.report_path().display());
    }
    Ok(())
}

pub fn validate(a: &ValidateArgs) -> Result<()> {
    let loaded = config::load(&a.pipeline, &a.set)?;
    pipeline::check_inputs(&loaded).with_context(|| format!("{}: inputs", a.pipeline.display()))?;
    if let Some(req) = kinescan::app::diagnose::Request::of(&loaded, None, None, None) {
        kinescan::app::diagnose::check_collisions(&loaded, &req)?;
    }
    println!("{}: valid", a.pipeline.display());
    Ok(())
}

pub fn import(a: &ImportArgs, quiet: bool) -> Result<()> {
    kinescan::io::paths::check_collisions(
        &[("CSV argument".into(), a.csv.clone())],
        &[("OUTPUT argument".into(), a.output.clone())],
    )?;
    crate::cli::remove_stale_temps(a.output.parent().unwrap_or(std::path::Path::new(".")))?;
    let s = kinescan::io::profiles_csv::import_csv(&a.csv, &a.output)?;
    if !quiet {
        println!("{}", serde_json::to_string_pretty(&s)?);
    }
    Ok(())
}

pub fn info(a: &InfoArgs) -> Result<()> {
    if a.file.is_dir() {
        let c = kinescan::app::verify::check_folder(&a.file)?;
        if c.sets.is_empty() && c.interrupted.is_empty() {
            anyhow::bail!(
                "{}: a directory without output reports (*.report.json): `info` describes a \
                 file, or the output sets of a folder that a command wrote",
                a.file.display()
            );
        }
        if a.json {
            println!("{}", serde_json::to_string_pretty(&c)?);
        } else {
            println!("{c}");
        }
        if !c.whole() {
            anyhow::bail!("{}: output sets not whole (see above)", a.file.display());
        }
        return Ok(());
    }
    let i = kinescan::io::info::describe(&a.file)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&i)?);
    } else {
        println!("{i}");
    }
    Ok(())
}
