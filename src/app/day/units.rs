//! Running work units: a unit's records georeferenced with the plan's clock into its own LAS
//! file (`<out>/units/<id>.las`, written atomically) or, when the units of its pass run one
//! after another, straight into its pass's file (`<out>/units/<pass>.pass.las`, written in
//! parts: each unit's records right after the previous unit's, the header written by the
//! merge); then journalled with the digest of its points and their sigma histograms, both
//! filled from the records as they are written.

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
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where the output of unit `id` goes when in its own file.
pub fn unit_path(out: &Path, id: &str) -> PathBuf {
    out.join("units").join(format!("{id}.las"))
}

/// The file of pass `pass` (its name) written in parts by its units (no unit id or pass name
/// has a dot, so it is no unit's file).
pub fn pass_file(out: &Path, pass: &str) -> PathBuf {
    out.join("units").join(format!("{pass}.pass.las"))
}

/// Where a unit writes its points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// Its own LAS file, `units/<id>.las`, written atomically.
    OwnFile,
    /// Its pass's file ([`pass_file`]), in place, right after the records of the pass's
    /// previous unit, which end at this byte (`None`: the pass's first unit).
    PassFile(Option<u64>),
}

impl Target {
    /// Where `unit` goes when the units of its pass run one after another, `done` holding the
    /// units done so far: into its pass's file when it is the pass's first unit or the pass's
    /// previous unit is in that file; into its own file otherwise.
    pub fn in_order(plan: &Plan, unit: &Unit, done: &BTreeMap<String, Entry>) -> Target {
        match plan.previous_in_pass(unit) {
            None => Target::PassFile(None),
            Some(previous) => match done.get(&previous.id).and_then(|e| e.range) {
                Some([_, end]) => Target::PassFile(Some(end)),
                None => Target::OwnFile,
            },
        }
    }
}

/// What every unit of a day runs with: the day, its plan, the run options and the progress
/// bar that counts the returns written (hidden unless stderr is a terminal).
pub struct UnitContext<'a> {
    /// The day.
    pub day: &'a LoadedDay,
    /// Its plan.
    pub plan: &'a Plan,
    /// Threads and chunk size.
    pub opts: &'a RunOptions,
    /// Advanced by each record written.
    pub bar: indicatif::ProgressBar,
}

/// Runs `unit` of the context's plan on its prepared pass into `target` (re-processed with
/// `correction` when given, into its own file: `prepared` is then the corrected pipeline's)
/// and journals it.
pub fn run_unit(
    ctx: &UnitContext,
    unit: &Unit,
    correction: Option<&Correction>,
    prepared: &Prepared,
    target: Target,
) -> Result<Entry> {
    let (day, plan, opts) = (ctx.day, ctx.plan, ctx.opts);
    let started = Instant::now();
    let out = &day.config.day.out;
    let id = correction.map_or_else(|| unit.id.clone(), |k| k.unit_id(unit));
    let path = match target {
        Target::OwnFile => unit_path(out, &id),
        Target::PassFile(_) => pass_file(out, &day.config.passes[unit.pass].name),
    };
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
    let settings = SinkSettings::new(
        c,
        &schema,
        &prepared.frame,
        prepared.geoid.as_ref(),
        &prepared.traj,
    )?;
    let mut sink = match target {
        Target::OwnFile => LasSink::new(settings),
        Target::PassFile(previous_end) => LasSink::part(settings, previous_end),
    };
    sink.start_input(&input.original)?;
    let records = unit.records[0]..unit.records[1];
    let offsets = SigmaOffsets::of(&schema);
    let record_len = sink.layout().record_len();
    let (mut digest, mut sigma) = (UnitDigest::default(), SigmaHistograms::default());
    // Written records as they come; the unit's every return once it is done.
    let (bar, bar_start) = (ctx.bar.clone(), ctx.bar.position());
    let mut on_records = |records: &[u8]| {
        bar.inc((records.len() / record_len.max(1)) as u64);
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
    ctx.bar
        .set_position(bar_start + (unit.records[1] - unit.records[0]) as u64);
    let las = sink
        .finish()?
        .pop()
        .ok_or_else(|| Error::bad_file(&path, "no file written"))?;
    let (sha256, range) = match target {
        Target::OwnFile => {
            let (map, layout) = map_las(&path)?;
            (digest.finish(&map[..layout.offset_to_points]), None)
        }
        Target::PassFile(_) => {
            let start = las.file_bytes - las.point_count * record_len as u64;
            (digest.finish(&[]), Some([start, las.file_bytes]))
        }
    };
    let entry = Entry {
        unit: id,
        sha256,
        range,
        counts,
        seconds: started.elapsed().as_secs_f64(),
        las,
        sigma,
    };
    journal::append(&out.join("journal.jsonl"), &entry)?;
    Ok(entry)
}
