//! `kinescan day DAY.toml`: a survey day processed overnight in resumable work units
//! (docs/nightly.md).
//!
//! 1. **load** ([`config`]): the day file and its pipeline template, every key checked and
//!    every profile file present.
//! 2. **plan** ([`plan`]): every pass prepared and checked (within the trajectory, no two
//!    passes overlapping in time) before any work; clocks resolved (synchronised with
//!    `[sync]`); passes cut into work units; `<out>/plan.json`. A restart reads the plan back.
//! 3. **units** ([`units`]): each unit not yet in the journal ([`journal`]) georeferenced into
//!    `<out>/units/<id>.las` (atomically) or, run in plan order with a per-pass layout,
//!    straight into its pass's file after the pass's previous unit; then journalled with its
//!    hash and counts.
//! 4. **merge** ([`merge`]): the day's LAS files (per pass or tiles) from the unit outputs in
//!    plan order (a pass file written by its units only gets its header), and the day report,
//!    published as one set (`io::publish`).

pub mod config;
pub mod health;
pub mod journal;
pub mod merge;
pub mod morning;
pub mod night;
pub mod plan;
pub mod quality;
pub mod units;

use crate::io::atomic::{write_atomic, write_json};
use crate::io::publish::{conclude, prepare_folder, previous_outputs, OutputSet, StemLock};
use crate::pipeline::prepare::Prepared;
use crate::pipeline::report::ReturnCounts;
use crate::pipeline::RunOptions;
use crate::{Error, Result};
use config::{Layout, LoadedDay};
use journal::Entry;
use plan::Plan;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;
use units::Target;

/// What a `day` invocation does.
#[derive(Debug, Clone, Default)]
pub enum Step {
    /// Plan, run every unit not done, merge and publish.
    #[default]
    All,
    /// Plan only (write the plan file).
    Plan,
    /// Run one unit of the existing plan (a cluster task).
    Unit(String),
    /// Merge and publish; every unit must be done.
    Merge,
}

/// The day report (`<out>/day.report.json`).
#[derive(Debug, Clone, Serialize)]
pub struct DayReport {
    /// kinescan version.
    pub kinescan_version: String,
    /// The day file.
    pub day_file: PathBuf,
    /// The day's output folder (`day.out`): the files, `report.md`, `report.html` (not in the
    /// JSON: the files' paths name it).
    #[serde(skip)]
    pub out_dir: PathBuf,
    /// Survey date (UTC, `YYYY-MM-DD`) of the trajectory's first record, from the template's
    /// `inputs.gps_week`; None without it.
    pub survey_date: Option<String>,
    /// The output CRS as the LAS files state it (name, EPSG code, geoid grid).
    pub crs: String,
    /// Work units planned.
    pub units: usize,
    /// Units found done in the journal (not run again by this invocation).
    pub units_resumed: usize,
    /// Per pass, in day-file order.
    pub passes: Vec<PassReport>,
    /// The day's counts: `read = written + rejected`.
    pub totals: ReturnCounts,
    /// LAS files written.
    pub outputs: Vec<OutputFile>,
    /// Seconds per step: plan, units, merge.
    pub timings_s: BTreeMap<String, f64>,
    /// Sigma statistics per pass, then per tile (none without `[uncertainty]`).
    pub sigma: Vec<quality::SigmaStats>,
    /// The night's diagnosis per pass (with `day.night.diagnose`).
    pub diagnosis: Vec<night::PassDiagnosis>,
}

/// One pass in the day report.
#[derive(Debug, Clone, Serialize)]
pub struct PassReport {
    /// Pass name.
    pub name: String,
    /// Why the pass failed and its file is not published (its rejected share); none when
    /// published.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failed: Option<String>,
    /// Its work units.
    pub units: usize,
    /// Its counts (sum of its units').
    pub counts: ReturnCounts,
    /// Seconds spent in its units (summed over the runs that did them).
    pub unit_seconds: f64,
    /// GPS time of its first and last record (s); None for a pass without records.
    pub time_span_s: Option<[f64; 2]>,
    /// GNSS outages (SMRMSG) and SBET gaps within the pass.
    pub trajectory: health::TrajectoryHealth,
}

/// One LAS file of the day.
#[derive(Debug, Clone, Serialize)]
pub struct OutputFile {
    /// Path.
    pub path: PathBuf,
    /// Points.
    pub points: u64,
    /// File size (bytes).
    pub bytes: u64,
    /// Header minimum X, Y, Z (file units).
    pub min: [f64; 3],
    /// Header maximum X, Y, Z (file units).
    pub max: [f64; 3],
    /// SHA-256 of the file, hex: `kinescan info FOLDER` checks the set against it.
    pub sha256: String,
}

/// Runs `step` of the day file `path`; gives the report when the day was published.
pub fn run(path: &Path, step: &Step, opts: &RunOptions) -> Result<Option<DayReport>> {
    let day = config::load(path)?;
    config::check_files(&day)?;
    let out = day.config.day.out.to_path_buf();
    std::fs::create_dir_all(out.join("units")).map_err(|e| Error::io(&out, e))?;
    let _lock = match step {
        Step::Unit(_) => None,
        _ => Some(StemLock::acquire_in(&out, "day", &out)?),
    };
    let diagnosis = out.join(night::DIAGNOSIS_FOLDER);
    for dir in [out.clone(), out.join("units"), diagnosis] {
        prepare_folder(&dir)?;
    }
    let mut timings = BTreeMap::new();
    let started = Instant::now();
    let (plan, prepared) = plan_day(&day, !matches!(step, Step::Unit(_)), opts)?;
    let mut prepared: Vec<Option<Prepared>> = match prepared {
        Some(all) => all.into_iter().map(Some).collect(),
        None => day.config.passes.iter().map(|_| None).collect(),
    };
    let opts = &RunOptions {
        chunk_returns: plan.chunk_returns,
        ..opts.clone()
    };
    timings.insert("plan".to_string(), started.elapsed().as_secs_f64());
    let mut done = finished_units(&day, &plan)?;
    let resumed = done.len();
    let started = Instant::now();
    let pending: Vec<&plan::Unit> = match step {
        Step::Plan => return Ok(None),
        Step::Merge => Vec::new(),
        Step::All => plan.units.iter().collect(),
        Step::Unit(id) => vec![plan.units.iter().find(|u| &u.id == id).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: no work unit `{id}` in the plan",
                path.display()
            ))
        })?],
    };
    let mut ctx = units::UnitContext {
        day: &day,
        plan: &plan,
        opts,
        bar: indicatif::ProgressBar::hidden(),
    };
    let mut bar_pass = None;
    for unit in pending {
        if done.contains_key(&unit.id) {
            continue;
        }
        crate::interrupt::check()?;
        if bar_pass != Some(unit.pass) {
            ctx.bar.finish();
            let what = "georeferencing returns";
            ctx.bar = pass_bar(&day, &plan, unit.pass, &done, what, opts);
            bar_pass = Some(unit.pass);
        }
        let pass = match &mut prepared[unit.pass] {
            Some(p) => p,
            slot => slot.insert(plan::prepare_pass(&day, unit.pass)?),
        };
        // One process runs the units in plan order: with a file per pass they go straight
        // into it (a cluster's units finish in any order: each into its own file).
        let target = match (step, day.config.day.layout) {
            (Step::All, Layout::PerPass) => Target::in_order(&plan, unit, &done),
            _ => Target::OwnFile,
        };
        let entry = units::run_unit(&ctx, unit, None, pass, target)?;
        done.insert(unit.id.clone(), entry);
    }
    ctx.bar.finish();
    timings.insert("units".to_string(), started.elapsed().as_secs_f64());
    if matches!(step, Step::Unit(_)) {
        return Ok(None);
    }
    check_all_done(&day, &plan, &done)?;
    let failed = rejected_passes(&day, &plan, &done);
    let started = Instant::now();
    let diagnosis = night::diagnosis(&day, &plan, &failed, opts.progress)?;
    if day.config.day.night.diagnose {
        timings.insert("diagnose".to_string(), started.elapsed().as_secs_f64());
    }
    let started = Instant::now();
    if correct_passes(&day, &plan, &diagnosis, &mut done, opts)? {
        let seconds = started.elapsed().as_secs_f64();
        timings.insert("corrected_units".to_string(), seconds);
    }
    let started = Instant::now();
    let run = DayRun {
        done: &done,
        failed: &failed,
        resumed,
    };
    let report = publish(&day, &plan, &run, timings, diagnosis, started)?;
    Ok(Some(report))
}

/// The progress bar of pass `pass` doing `what`: the returns of its units not `done` (hidden
/// without `opts.progress` or when stderr is not a terminal).
fn pass_bar(
    day: &LoadedDay,
    plan: &Plan,
    pass: usize,
    done: &BTreeMap<String, Entry>,
    what: &str,
    opts: &RunOptions,
) -> indicatif::ProgressBar {
    if !opts.progress {
        return indicatif::ProgressBar::hidden();
    }
    let units = plan.units.iter().filter(|u| u.pass == pass);
    let pending = units.filter(|u| !done.contains_key(&u.id));
    let returns: usize = pending.map(|u| u.records[1] - u.records[0]).sum();
    let name = &day.config.passes[pass].name;
    crate::progress::bar(returns as u64, &format!("pass {name}: {what}"))
}

/// The units done and the passes failed, as the merge and the report take them.
struct DayRun<'a> {
    /// Per unit of the plan, the entry of the unit file that stands for it.
    done: &'a BTreeMap<String, Entry>,
    /// Per pass, why it is not published (see [`rejected_passes`]).
    failed: &'a [Option<String>],
    /// Units found done in the journal.
    resumed: usize,
}

/// Per pass of the day, why it fails (none: it is published): its returns rejected for a
/// reason other than a missing return in a share above the template's
/// `output.max_rejected_share`, as `kinescan run` refuses a run (issue #23). A failed pass is
/// not diagnosed, corrected or merged; the other passes are published, the morning report and
/// the console name it and `day` exits with an error.
fn rejected_passes(
    day: &LoadedDay,
    plan: &Plan,
    done: &BTreeMap<String, Entry>,
) -> Vec<Option<String>> {
    let max = day.template.config.output.max_rejected_share;
    let mut counts = vec![ReturnCounts::default(); day.config.passes.len()];
    for u in &plan.units {
        counts[u.pass].merge(&done[&u.id].counts);
    }
    counts
        .iter()
        .zip(&day.config.passes)
        .map(|(c, p)| {
            let excess = c.excess_rejected(max)?;
            let (key, cause) = excess.reason.likely_cause();
            let what = excess.describe(&format!("pass {}", p.name), max);
            Some(format!(
                "{what} (check `{key}`: {cause}); its file is not published"
            ))
        })
        .collect()
}

/// Re-processes the passes whose diagnosed correction the night applies: every unit of such a
/// pass runs again with the correction (unless the journal has it done) and stands for the
/// plan's unit in `done`. Whether a pass was corrected.
fn correct_passes(
    day: &LoadedDay,
    plan: &Plan,
    diagnosis: &[night::PassDiagnosis],
    done: &mut BTreeMap<String, Entry>,
    opts: &RunOptions,
) -> Result<bool> {
    let out = &day.config.day.out;
    let journalled = journal::read(&out.join("journal.jsonl"))?;
    let mut corrected = false;
    let mut ctx = units::UnitContext {
        day,
        plan,
        opts,
        bar: indicatif::ProgressBar::hidden(),
    };
    for d in diagnosis {
        let Some(k) = night::Correction::of(day, plan, d)? else {
            continue;
        };
        corrected = true;
        let mut prepared = None;
        let name = &day.config.passes[k.pass].name;
        let what = "re-processing with the correction";
        ctx.bar = pass_bar(day, plan, k.pass, &BTreeMap::new(), what, opts);
        for unit in plan.units.iter().filter(|u| u.pass == k.pass) {
            let journalled = journalled.get(&k.unit_id(unit));
            let entry = match journalled.filter(|e| verified(out, e, name)) {
                Some(e) => e.clone(),
                None => {
                    crate::interrupt::check()?;
                    let pass = match &mut prepared {
                        Some(p) => p,
                        slot => slot.insert(crate::pipeline::prepare::open(&k.pipeline)?),
                    };
                    units::run_unit(&ctx, unit, Some(&k), pass, Target::OwnFile)?
                }
            };
            done.insert(unit.id.clone(), entry);
        }
        ctx.bar.finish();
    }
    Ok(corrected)
}

/// The plan read back, or made (passes prepared and checked first) when `may_plan`; the
/// prepared passes when they were needed to make it.
fn plan_day(
    day: &LoadedDay,
    may_plan: bool,
    opts: &RunOptions,
) -> Result<(Plan, Option<Vec<Prepared>>)> {
    let plan_path = day.config.day.out.join("plan.json");
    let fingerprint = plan::fingerprint(day)?;
    if let Some(p) = plan::read_existing(&plan_path, &fingerprint)? {
        return Ok((p, None));
    }
    if !may_plan {
        let problem = "no plan: run `kinescan day DAY.toml --plan` first";
        return Err(Error::bad_file(plan_path, problem));
    }
    let prepared = plan::prepare_passes(day)?;
    plan::check_passes(day, &prepared)?;
    let (p, _sync_reports) = plan::make(day, &prepared, fingerprint, opts.chunk_returns.max(1))?;
    write_json(&plan_path, &p)?;
    Ok((p, Some(prepared)))
}

/// The plan's units done: in the journal, their points there with the journalled digest. A
/// unit in its pass's file counts only when it is the pass's first or follows the pass's
/// previous unit, done, in that file (its records start where that unit's end), so the pass
/// file holds every record before its own.
fn finished_units(day: &LoadedDay, plan: &Plan) -> Result<BTreeMap<String, Entry>> {
    let out = &day.config.day.out;
    let journalled = journal::read(&out.join("journal.jsonl"))?;
    let mut done: BTreeMap<String, Entry> = BTreeMap::new();
    for u in &plan.units {
        let Some(e) = journalled.get(&u.id) else {
            continue;
        };
        if let Some([start, _]) = e.range {
            let previous = plan.previous_in_pass(u);
            let previous_end = previous.map(|p| done.get(&p.id).and_then(|d| d.range));
            if previous_end.is_some_and(|r| r.map(|[_, end]| end) != Some(start)) {
                continue;
            }
        }
        if verified(out, e, &day.config.passes[u.pass].name) {
            done.insert(u.id.clone(), e.clone());
        }
    }
    Ok(done)
}

/// Whether the points of the journal's entry `e` (a unit of the pass named `pass`) are there
/// with the journalled digest.
fn verified(out: &Path, e: &Entry, pass: &str) -> bool {
    let digest = match e.range {
        None => journal::file_digest(&units::unit_path(out, &e.unit)),
        Some(range) => journal::part_digest(&units::pass_file(out, pass), range),
    };
    digest.is_some_and(|d| d == e.sha256)
}

/// Refuses to go on (diagnose, merge) before every unit of the plan is done.
fn check_all_done(day: &LoadedDay, plan: &Plan, done: &BTreeMap<String, Entry>) -> Result<()> {
    let missing: Vec<&str> = plan
        .units
        .iter()
        .filter(|u| !done.contains_key(&u.id))
        .map(|u| u.id.as_str())
        .collect();
    if !missing.is_empty() {
        let problem = format!("work units not done yet: {}", missing.join(", "));
        return Err(Error::bad_file(
            day.config.day.out.join("journal.jsonl"),
            problem,
        ));
    }
    Ok(())
}

/// Merges, checks the counts add up, writes the report and publishes the set. `done` holds,
/// per unit of the plan, the entry of the unit file that stands for it (the plan's unit, or
/// its corrected re-run).
fn publish(
    day: &LoadedDay,
    plan: &Plan,
    run: &DayRun,
    mut timings: BTreeMap<String, f64>,
    diagnosis: Vec<night::PassDiagnosis>,
    started: Instant,
) -> Result<DayReport> {
    let out = day.config.day.out.to_path_buf();
    let report_path = out.join("day.report.json");
    let previous = previous_outputs(&report_path, &out, las_of_day, &config::inputs(day));
    let mut set = OutputSet::new("day");
    let result = merge::merge(day, plan, run.done, run.failed, &mut set);
    let result = result.and_then(|(summaries, sigma)| {
        let mut report = day_report(day, plan, run, &summaries, &set)?;
        report.sigma = sigma;
        report.diagnosis = diagnosis;
        timings.insert("merge".to_string(), started.elapsed().as_secs_f64());
        report.timings_s = timings;
        write_json(&set.stage(&report_path)?, &report)?;
        write_atomic(
            &set.stage(&out.join("report.md"))?,
            morning::markdown(&report, plan).as_bytes(),
        )?;
        write_atomic(
            &set.stage(&out.join("report.html"))?,
            morning::html(&report, plan)?.as_bytes(),
        )?;
        crate::interrupt::check()?;
        Ok(report)
    });
    conclude(set, result, &report_path, &previous)
}

/// A LAS file the day may write (a pass or tile file): only those of a previous report's
/// list may be removed.
fn las_of_day(name: &str) -> bool {
    name.ends_with(".las") && config::owns(name)
}

fn day_report(
    day: &LoadedDay,
    plan: &Plan,
    run: &DayRun,
    summaries: &[crate::io::las::LasSummary],
    set: &OutputSet,
) -> Result<DayReport> {
    let mut passes: Vec<PassReport> = day
        .config
        .passes
        .iter()
        .zip(run.failed)
        .map(|(p, failed)| PassReport {
            name: p.name.clone(),
            failed: failed.clone(),
            units: 0,
            counts: ReturnCounts::default(),
            unit_seconds: 0.0,
            time_span_s: None,
            trajectory: health::TrajectoryHealth::default(),
        })
        .collect();
    let mut totals = ReturnCounts::default();
    for u in &plan.units {
        let e = &run.done[&u.id];
        let p = &mut passes[u.pass];
        p.units += 1;
        p.counts.merge(&e.counts);
        p.unit_seconds += e.seconds;
        totals.merge(&e.counts);
        let [t0, t1] = u.time_window_s;
        p.time_span_s = Some(
            p.time_span_s
                .map_or([t0, t1], |[a, b]| [a.min(t0), b.max(t1)]),
        );
    }
    let c = &day.template.config;
    let traj = crate::pipeline::prepare::open_trajectory(c)?;
    let spans: Vec<Option<[f64; 2]>> = passes.iter().map(|p| p.time_span_s).collect();
    let mut healths = health::per_pass(&traj, &spans);
    health::add_reported_gaps(
        &mut healths,
        &spans,
        &health::reported_gaps(&c.inputs.sbet)?,
    );
    for (p, h) in passes.iter_mut().zip(healths) {
        p.trajectory = h;
    }
    let first = traj.sbet().record(0);
    let frame = crate::pipeline::prepare::map_frame(&c.output.frame, &traj)?;
    let code = frame
        .epsg()
        .map_or(String::new(), |e| format!(" (EPSG:{e})"));
    let geoid = c.output.geoid.as_ref().map_or(String::new(), |g| {
        let name = g.file_name().map(|n| n.to_string_lossy().into_owned());
        format!(", heights above the geoid of {}", name.unwrap_or_default())
    });
    let unit = if frame.metres_per_unit() == 1.0 {
        String::new()
    } else {
        format!(
            ", Z and sigmas in the CRS's unit ({} m)",
            frame.metres_per_unit()
        )
    };
    let outputs: Vec<OutputFile> = summaries
        .iter()
        .map(|s| {
            Ok(OutputFile {
                path: set.final_path(&s.path),
                points: s.point_count,
                bytes: s.file_bytes,
                min: s.min_m,
                max: s.max_m,
                sha256: crate::io::digest::FileRecord::of("las", &s.path)?.sha256,
            })
        })
        .collect::<Result<_>>()?;
    let merged: u64 = outputs.iter().map(|o| o.points).sum();
    let published = passes.iter().filter(|p| p.failed.is_none());
    let published: u64 = published.map(|p| p.counts.written).sum();
    if merged != published || totals.read != totals.written + totals.rejected_total() {
        return Err(Error::Invalid(format!(
            "{}: counts do not add up: {} returns read, {} written by the units ({published} \
             of passes published), {} rejected, {merged} in the merged files",
            day.path.display(),
            totals.read,
            totals.written,
            totals.rejected_total()
        )));
    }
    Ok(DayReport {
        kinescan_version: env!("CARGO_PKG_VERSION").into(),
        day_file: day.path.clone(),
        out_dir: day.config.day.out.to_path_buf(),
        survey_date: crate::pipeline::survey_date(c.inputs.gps_week, first.time_s),
        crs: format!("{frame}{code}{geoid}{unit}"),
        units: plan.units.len(),
        units_resumed: run.resumed,
        passes,
        totals,
        outputs,
        timings_s: BTreeMap::new(),
        sigma: Vec::new(),
        diagnosis: Vec::new(),
    })
}
