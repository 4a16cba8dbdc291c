//! Running work units: a unit's records georeferenced with the plan's clock into its own LAS
//! file (`<out>/units/<id>.las`, written atomically), then journalled with the file's digest
//! and the sigma histograms of its points, both filled from the records as they are written.

use super::config::LoadedDay;
use super::journal::{self, Entry, UnitDigest};
use super::night::Correction;
use super::plan::{pass_pipeline, Plan, Unit};
use super::quality::{SigmaHistograms, SigmaOffsets};
use crate::io::laz::map_las;
use crate::pipeline::executor::process_records;
use crate::pipeline::georeference::ReturnGeoreferencer;
use crate::pipeline::prepare::Prepared;
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::sync::ResolvedClock;
use crate::pipeline::write::{LasSink, SinkSettings};
use crate::pipeline::RunOptions;
use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the output of unit `id` goes.
pub fn unit_path(out: &Path, id: &str) -> PathBuf {
    out.join("units").join(format!("{id}.las"))
}

/// Runs `unit` of `plan` on its prepared pass (re-processed with `correction` when given:
/// `prepared` is then the corrected pipeline's) and journals it.
pub fn run_unit(
    day: &LoadedDay,
    plan: &Plan,
    unit: &Unit,
    correction: Option<&Correction>,
    prepared: &Prepared,
    opts: &RunOptions,
) -> Result<Entry> {
    let started = Instant::now();
    let out = &day.config.day.out;
    let id = correction.map_or_else(|| unit.id.clone(), |k| k.unit_id(unit));
    let path = unit_path(out, &id);
    let (p, planned) = match correction {
        None => (
            pass_pipeline(day, unit.pass, &path),
            plan.inputs[unit.input].clock,
        ),
        Some(k) => {
            let mut p = k.pipeline.clone();
            p.config.output.las = path.clone().into();
            (p, k.clock(&plan.inputs[unit.input].clock))
        }
    };
    let c = &p.config;
    let first_of_pass = plan.inputs.iter().position(|i| i.pass == unit.pass);
    let input = &prepared.inputs[unit.input - first_of_pass.unwrap_or(0)];
    let clock = planned.applied_to(ResolvedClock::configured(c));
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
    let offsets = SigmaOffsets::of(&schema);
    let record_len = sink.layout().record_len();
    let (mut digest, mut sigma) = (UnitDigest::default(), SigmaHistograms::default());
    let mut on_records = |records: &[u8]| {
        digest.records(records);
        if let Some(at) = offsets {
            sigma.add_records(records, record_len, at);
        }
    };
    let strictness = c.output.strictness;
    let counts = process_records(
        &geo,
        &fill,
        input,
        records,
        opts,
        strictness,
        &mut sink,
        &mut on_records,
    )
    .map_err(|e| crate::pipeline::prepare::on_user_line(e, input))?;
    let las = sink
        .finish()?
        .pop()
        .ok_or_else(|| Error::bad_file(&path, "no file written"))?;
    let (map, layout) = map_las(&path)?;
    let entry = Entry {
        unit: id,
        sha256: digest.finish(&map[..layout.offset_to_points]),
        counts,
        seconds: started.elapsed().as_secs_f64(),
        las,
        sigma,
    };
    journal::append(&out.join("journal.jsonl"), &entry)?;
    Ok(entry)
}
