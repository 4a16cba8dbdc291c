//! Running work units: a unit's records georeferenced with the plan's clock into its own LAS
//! file (`<out>/units/<id>.las`, written atomically), then journalled.

use super::config::LoadedDay;
use super::journal::{self, Entry};
use super::plan::{pass_pipeline, Plan, Unit};
use crate::pipeline::executor::process_records;
use crate::pipeline::georeference::ReturnGeoreferencer;
use crate::pipeline::prepare::Prepared;
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::sync::ResolvedClock;
use crate::pipeline::write::{LasSink, SinkSettings};
use crate::pipeline::RunOptions;
use crate::Result;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the output of unit `id` goes.
pub fn unit_path(out: &Path, id: &str) -> PathBuf {
    out.join("units").join(format!("{id}.las"))
}

/// Runs `unit` of `plan` on its prepared pass and journals it.
pub fn run_unit(
    day: &LoadedDay,
    plan: &Plan,
    unit: &Unit,
    prepared: &Prepared,
    opts: &RunOptions,
) -> Result<Entry> {
    let started = Instant::now();
    let out = &day.config.day.out;
    let path = unit_path(out, &unit.id);
    let p = pass_pipeline(day, unit.pass, &path);
    let c = &p.config;
    let planned = &plan.inputs[unit.input];
    let first_of_pass = plan.inputs.iter().position(|i| i.pass == unit.pass);
    let input = &prepared.inputs[unit.input - first_of_pass.unwrap_or(0)];
    let clock = planned.clock.applied_to(ResolvedClock::configured(c));
    let geo = ReturnGeoreferencer::new(
        &prepared.traj,
        &c.sensor,
        input.file.columns(),
        clock,
        prepared.frame,
        c.uncertainty.as_ref(),
    )
    .with_geoid(prepared.geoid.as_ref());
    let schema = OutputSchema::new(c);
    let fill = schema.fill(input.point_source_id);
    let mut sink = LasSink::new(SinkSettings::new(
        c,
        &schema,
        &prepared.frame,
        prepared.geoid.as_ref(),
        &prepared.traj,
    )?);
    sink.start_input(&input.original)?;
    let records = unit.records[0]..unit.records[1];
    let hidden = indicatif::ProgressBar::hidden();
    let strictness = c.output.strictness;
    let report = process_records(
        &geo, &fill, input, records, opts, strictness, &mut sink, &hidden,
    )
    .map_err(|e| crate::pipeline::prepare::on_user_line(e, input))?;
    sink.finish()?;
    let sha256 = journal::file_sha256(&path)
        .ok_or_else(|| crate::Error::bad_file(&path, "unit output vanished after writing"))?;
    let entry = Entry {
        unit: unit.id.clone(),
        sha256,
        counts: report.counts,
        seconds: started.elapsed().as_secs_f64(),
    };
    journal::append(&out.join("journal.jsonl"), &entry)?;
    Ok(entry)
}
