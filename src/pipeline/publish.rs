//! A run's outputs published as one set (`io::publish`): the stages write every file (LAS
//! parts, report, sync plots) into staging folders beside the destinations; only a run that
//! succeeded renames them into place, the report last, and removes the files of the previous
//! run with the same stem that this run did not produce. A lock per output stem keeps two runs
//! apart; the stale temporaries of dead runs are removed from the folders written.

use super::config::LoadedPipeline;
use super::report::RunReport;
use crate::io::publish::{conclude, prepare_folder, previous_outputs, OutputSet, StemLock};
use crate::Result;
use std::path::Path;

/// Runs `stages` on the pipeline with its outputs redirected into staging folders and
/// publishes them when it succeeds. Errors name the user's paths, never a staging folder.
pub fn publish_run(
    p: &LoadedPipeline,
    stages: impl FnOnce(&LoadedPipeline) -> Result<RunReport>,
) -> Result<RunReport> {
    let c = &p.config;
    super::files::check_collisions_of(p)?;
    let las = &c.output.las;
    let report_path = c.output.report_path();
    let _lock = StemLock::acquire(las)?;
    for dir in [parent(las), parent(&report_path)] {
        prepare_folder(dir)?;
    }
    let stem = c.output.stem();
    let owned = |name: &str| {
        let named = name
            .strip_prefix(&*stem)
            .is_some_and(|rest| rest.starts_with('.') || rest.starts_with('_'));
        named && [".las", ".laz", ".png"].iter().any(|e| name.ends_with(e))
    };
    let inputs = super::files::inputs(p);
    let previous = previous_outputs(&report_path, parent(las), owned, &inputs);
    let mut set = OutputSet::new(&c.output.stem());
    let mut staged = p.clone();
    staged.config.output.las = set.stage(las)?.into();
    let staged_report = set.stage(&report_path)?;
    staged.config.output.report = Some(staged_report.clone().into());
    let result = stages(&staged).and_then(|mut report| {
        report.parameters = c.clone();
        for o in &mut report.outputs {
            o.path = set.final_path(&o.path);
        }
        for s in &mut report.sync {
            for plot in &mut s.plots {
                *plot = set.final_path(plot);
            }
        }
        report.write(&staged_report)?;
        crate::interrupt::check()?;
        Ok(report)
    });
    conclude(set, result, &report_path, &previous)
}

fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}
