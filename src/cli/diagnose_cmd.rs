//! `diagnose`.

use anyhow::{bail, Result};
use clap::Args;
use kinescan::app::diagnose::{self, Request};
use kinescan::pipeline::config;
use std::path::PathBuf;

/// Where a survey departs from its model, which catalogue effect causes it, and how far the gap
/// shrinks once it is added (docs/diagnosis.md). Writes DIR/diagnosis.json, DIR/summary.md,
/// PNG plots and DIR/corrected.toml.
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan diagnose work/demo/pipeline.toml --patches work/demo/survey/patches.csv --out work/diag
  kinescan diagnose day.toml --patches facades.csv --set diagnose.plane_tolerance_m=0.1")]
pub struct DiagnoseArgs {
    /// Pipeline file (TOML); needs [uncertainty] and inputs.smrmsg.
    pipeline: PathBuf,
    /// Reference planar patches (patch CSV); default diagnose.patches in the pipeline.
    #[arg(long)]
    patches: Option<PathBuf>,
    /// Control points (control-point CSV): flat retro-reflective targets found by intensity,
    /// optional references besides the patches; default diagnose.control_points.
    #[arg(long)]
    control_points: Option<PathBuf>,
    /// Output folder (created if missing); default diagnose.out in the pipeline, else
    /// `diagnosis`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override a pipeline value, KEY=VALUE with a dotted key (repeatable), as in `run`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

pub fn diagnose(a: &DiagnoseArgs, quiet: bool) -> Result<()> {
    let loaded = config::load(&a.pipeline, &a.set)?;
    let Some(req) = Request::of(
        &loaded,
        a.patches.clone(),
        a.control_points.clone(),
        a.out.clone(),
    ) else {
        bail!(
            "{}: no reference patches: give --patches FILE or diagnose.patches",
            a.pipeline.display()
        );
    };
    if req.out_dir.exists() && !req.out_dir.is_dir() {
        bail!(
            "--out {}: is a file, not a folder: the diagnosis writes a folder of files \
             (diagnosis.json, summary.md, plots); give a new or existing folder",
            req.out_dir.display()
        );
    }
    crate::cli::remove_stale_temps(&req.out_dir)?;
    let started = std::time::Instant::now();
    let bar = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        kinescan::progress::stages(0, "diagnosing")
    };
    let d = diagnose::run_with_progress(&loaded, &req, &bar)?;
    if !quiet {
        let (b, f) = (&d.gap.before, &d.gap.after);
        println!("verdict   {}", d.headline());
        println!(
            "held out  chi2/dof {:.2} -> {:.2}, RMS {:.1} -> {:.1} mm, 95% coverage {:.0}% -> {:.0}% ({} observations)",
            b.chi2_per_dof,
            f.chi2_per_dof,
            b.rms_m * 1e3,
            f.rms_m * 1e3,
            b.coverage_95 * 100.0,
            f.coverage_95 * 100.0,
            f.n
        );
        for line in &d.set {
            println!("set       {line}");
        }
        println!(
            "report    {} ({:.1} s)",
            req.out_dir.join(diagnose::report::SUMMARY_MD).display(),
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
