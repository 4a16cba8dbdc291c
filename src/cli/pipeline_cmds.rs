//! `run`, `validate`, `import`, `info`.

use anyhow::Result;
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

/// Convert CSV profiles (docs/formats.md, "Scanner profiles, CSV") to the memory-mapped binary
/// form; prints the binary file as `kinescan info` does.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan import pass1.csv pass1.ksprof
  kinescan import pass1.csv pass1.ksprof --json")]
pub struct ImportArgs {
    /// CSV profile file.
    csv: PathBuf,
    /// Binary profile file to write.
    output: PathBuf,
    /// Print JSON instead of text (as `kinescan info --json`).
    #[arg(long)]
    json: bool,
}

/// Summarise an SBET (span, rate, gaps, attitude and rate ranges), SMRMSG (RMS ranges),
/// profile, control-point or LAS/LAZ/COPC file (header, CRS, counts, extent, extra dimensions).
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan info trajectory.sbet
  kinescan info out/city_block.las
  kinescan info pass1.ksprof --json")]
pub struct InfoArgs {
    /// File to describe, or an output folder: whether its sets are whole (each file a report
    /// lists there with its SHA-256, no publication interrupted).
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// `e` with a hint when `path` is a day file (a `[day]` table) given where a pipeline is due.
fn day_file_hint(path: &std::path::Path, e: kinescan::Error) -> anyhow::Error {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    if text.lines().any(|l| l.trim() == "[day]") {
        return anyhow::anyhow!(
            "{e}\n  hint: {} is a day file (it has a [day] table), not a pipeline: run \
             `kinescan day {}`",
            path.display(),
            path.display()
        );
    }
    e.into()
}

/// "1 thread", "2 threads".
fn threads_text(n: usize) -> String {
    format!("{n} thread{}", if n == 1 { "" } else { "s" })
}

pub fn run(a: &RunArgs, quiet: bool) -> Result<()> {
    let loaded = config::load(&a.pipeline, &a.set).map_err(|e| day_file_hint(&a.pipeline, e))?;
    let opts = RunOptions {
        threads: a.threads,
        progress: !quiet,
        ..RunOptions::default()
    };
    let report = pipeline::run(&loaded, &opts)?;
    if !quiet {
        let t = &report.totals;
        println!(
            "{} returns read, {} written, {} rejected ({} on {})",
            t.read,
            t.written,
            t.rejected_total(),
            kinescan::progress::rate_text(report.returns_per_second).replace("/s", " returns/s"),
            threads_text(report.threads)
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
    let loaded = config::load(&a.pipeline, &a.set).map_err(|e| day_file_hint(&a.pipeline, e))?;
    // Errors name the pipeline file and key themselves.
    pipeline::check_inputs(&loaded)?;
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
    kinescan::io::profiles_csv::import_csv(&a.csv, &a.output)?;
    if !quiet {
        let i = kinescan::io::info::describe(&a.output)?;
        if a.json {
            println!("{}", serde_json::to_string_pretty(&i)?);
        } else {
            println!("wrote {}\n{i}", a.output.display());
        }
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
