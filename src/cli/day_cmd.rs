//! `day`.

use anyhow::Result;
use clap::Args;
use kinescan::app::day::{self, Step};
use kinescan::pipeline::RunOptions;
use std::path::PathBuf;

/// Process a survey day: plan work units, run those not done yet (a restart resumes), merge
/// the day's LAS files and report (docs/nightly.md).
#[derive(Args)]
#[command(after_help = "Examples:
  kinescan day day.toml
  kinescan day day.toml --plan
  kinescan day day.toml --unit p01-0-0003
  kinescan day day.toml --merge")]
pub struct DayArgs {
    /// Day file (TOML).
    day: PathBuf,
    /// Only write the plan (`<out>/plan.json`).
    #[arg(long, conflicts_with_all = ["unit", "merge"])]
    plan: bool,
    /// Run one work unit of the plan (a cluster task).
    #[arg(long, value_name = "ID", conflicts_with = "merge")]
    unit: Option<String>,
    /// Merge and publish when every unit is done.
    #[arg(long)]
    merge: bool,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = crate::cli::threads)]
    threads: Option<usize>,
}

pub fn day(a: &DayArgs, quiet: bool) -> Result<()> {
    let step = match (&a.unit, a.plan, a.merge) {
        (Some(id), _, _) => Step::Unit(id.clone()),
        (None, true, _) => Step::Plan,
        (None, false, true) => Step::Merge,
        (None, false, false) => Step::All,
    };
    let opts = RunOptions {
        threads: a.threads,
        // Per pass, drawn on stderr only when it is a terminal (crate::progress).
        progress: !quiet,
        ..RunOptions::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()?;
    let report = pool.install(|| day::run(&a.day, &step, &opts))?;
    let failed: Vec<String> = report
        .iter()
        .flat_map(|r| &r.passes)
        .filter_map(|p| Some(format!("pass {}: {}", p.name, p.failed.as_ref()?)))
        .collect();
    if let (Some(r), false) = (report, quiet) {
        let t = &r.totals;
        println!(
            "{} units ({} resumed): {} returns read, {} written, {} rejected",
            r.units,
            r.units_resumed,
            t.read,
            t.written,
            t.rejected_total()
        );
        for o in &r.outputs {
            println!("wrote {} ({} points)", o.path.display(), o.points);
        }
        // One diagnosis of the day's passes (docs/nightly.md): its verdict once.
        if let Some(d) = r.diagnosis.first() {
            let passes: Vec<&str> = r.diagnosis.iter().map(|d| d.pass.as_str()).collect();
            println!(
                "diagnosis of {}: {} ({})",
                passes.join(", "),
                d.verdict,
                d.folder.join("summary.md").display()
            );
        }
        let out = &r.out_dir;
        println!(
            "morning report {} ({})",
            out.join("report.md").display(),
            out.join("report.html").display()
        );
    }
    if !failed.is_empty() {
        anyhow::bail!(
            "{} pass(es) failed, the others are published:\n  {}",
            failed.len(),
            failed.join("\n  ")
        );
    }
    Ok(())
}
