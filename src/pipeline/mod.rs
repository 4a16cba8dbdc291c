//! The staged batch processor: `kinescan run`.
//!
//! A run is six stages, each a module with a typed output, in data-flow order:
//!
//! 1. **load** ([`config::load`]): the pipeline file parsed, `--set` overrides applied, every
//!    key and value checked, paths resolved -> [`config::LoadedPipeline`].
//! 2. **prepare** (`prepare::run`): the trajectory opened and validated, the output frame
//!    fixed, profile files memory-mapped (CSV files imported) -> `prepare::Prepared`.
//! 3. **sync** (`sync::run`): the clock of every input resolved (t0, T, latencies and their
//!    covariances; estimated from sync targets with `[sync]`) before anything is built from
//!    it -> `sync::Synced`.
//! 4. **georeference** (+ uncertainty) ([`georeference::ReturnGeoreferencer`], one per
//!    input): per return the time model, the pose, the conventions §4 equation, the map projection
//!    and the per-point sigmas -> [`georeference::GeoreferencedReturn`], filled into a LAS
//!    point by the `schema::OutputSchema`'s `schema::PointFill`.
//! 5. **write** (`write::LasSink`): encoded records written in input order, split into
//!    files as configured, each atomically -> [`report::OutputReport`]s.
//! 6. **report** ([`report`]): the run report assembled and written to
//!    [`config::OutputConfig::report_path`] -> [`report::RunReport`].
//!
//! Stages 4 and 5 run together in the `executor`: chunks of returns in parallel, written in
//! input order by one writer thread (the output bytes do not depend on the thread count).
//! docs/pipeline.md documents the stages and every option.

pub mod config;
pub(crate) mod executor;
pub(crate) mod files;
pub mod georeference;
mod point_batch;
pub(crate) mod prepare;
pub(crate) mod publish;
pub mod report;
pub(crate) mod schema;
pub(crate) mod sync;
pub(crate) mod write;

pub use config::{load, LoadedPipeline};
pub use sync::ResolvedClock;
pub use write::survey_date;

use georeference::ReturnGeoreferencer;
use report::{OutputReport, ReturnCounts, RunReport, StageTiming};
use schema::OutputSchema;
use std::time::Instant;
use write::{LasSink, SinkSettings};

/// How a run is executed (not what it computes: that is the pipeline file).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Worker threads (None: all cores).
    pub threads: Option<usize>,
    /// Show a progress bar (only drawn when stderr is a terminal).
    pub progress: bool,
    /// Returns per parallel work item (default 16,384). A batch of 8 items per thread is in
    /// flight while the writer takes the previous one: small items keep both workers busy
    /// while the writer thread shares their cores.
    pub chunk_returns: usize,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            threads: None,
            progress: true,
            chunk_returns: 1 << 14,
        }
    }
}

/// Runs a loaded pipeline: every stage after load; the LAS output(s) and the run report (at
/// [`config::OutputConfig::report_path`]) are published as one set (`publish`) when every
/// stage succeeded; gives the report.
pub fn run(p: &LoadedPipeline, opts: &RunOptions) -> crate::Result<RunReport> {
    let threads = opts
        .threads
        .unwrap_or_else(rayon::current_num_threads)
        .max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| crate::Error::Invalid(format!("cannot start {threads} threads: {e}")))?;
    publish::publish_run(p, |staged| {
        pool.install(|| run_stages(staged, opts, threads))
    })
}

/// Opens and checks every input of a pipeline without georeferencing (`kinescan validate`):
/// no output overwrites an input, the trajectory, the map frame, the sync points and targets, each profile file (CSV files
/// parsed completely) and the time model's needs.
pub fn check_inputs(p: &LoadedPipeline) -> crate::Result<()> {
    files::check_collisions_of(p)?;
    prepare::check_inputs(p)?;
    sync::check_inputs(&p.config)
}

/// Stages 2 to 6 on the current thread pool.
fn run_stages(p: &LoadedPipeline, opts: &RunOptions, threads: usize) -> crate::Result<RunReport> {
    let c = &p.config;
    let mut stages = Vec::new();
    let mut timed = |stage: &str, started: Instant| {
        stages.push(StageTiming {
            stage: stage.into(),
            seconds: started.elapsed().as_secs_f64(),
        })
    };
    let started = Instant::now();
    let prepared = prepare::run(p)?;
    timed("prepare", started);

    let started = Instant::now();
    let synced = sync::run(c, &prepared)?;
    if c.sync.is_some() {
        timed("sync", started);
    }

    let started = Instant::now();
    let schema = OutputSchema::new(c);
    let geoid = prepared.geoid.as_ref();
    let settings = SinkSettings::new(c, &schema, &prepared.frame, geoid, &prepared.traj)?;
    let mut sink = LasSink::new(settings);
    let total = prepared.inputs.iter().map(|i| i.file.len() as u64).sum();
    let bar = progress_bar(opts.progress, total);
    let mut inputs = Vec::new();
    for (input, clock) in prepared.inputs.iter().zip(&synced.clocks) {
        let geo = ReturnGeoreferencer::new(
            &prepared.traj,
            &c.sensor,
            input.file.columns(),
            *clock,
            prepared.frame,
            c.uncertainty.as_ref(),
        )
        .with_geoid(geoid);
        let fill = schema.fill(input.point_source_id);
        sink.start_input(&input.original)?;
        let strictness = c.output.strictness;
        let report = executor::process_input(&geo, &fill, input, opts, strictness, &mut sink, &bar)
            .map_err(|e| prepare::on_user_line(e, input))?;
        inputs.push(report);
    }
    bar.finish_and_clear();
    check_rejected_share(p, &inputs, &synced.clocks, prepared.traj.span_s())?;
    check_not_empty(p, &inputs)?;
    let summaries = sink.finish()?;
    let georef_s = started.elapsed().as_secs_f64();
    timed("georeference_and_write", started);

    let started = Instant::now();
    let summaries = write::into_format(c.output.format, summaries)?;
    if c.output.format != config::OutputFormat::Las {
        timed("compress", started);
    }

    let mut totals = ReturnCounts::default();
    inputs.iter().for_each(|i| totals.merge(&i.counts));
    let outputs = summaries
        .into_iter()
        .map(|s| {
            Ok(OutputReport {
                sha256: crate::io::digest::FileRecord::of("las", &s.path)?.sha256,
                path: s.path,
                points: s.point_count,
                min_m: s.min_m,
                max_m: s.max_m,
                bytes: s.file_bytes,
            })
        })
        .collect::<crate::Result<_>>()?;
    Ok(RunReport {
        kinescan_version: env!("CARGO_PKG_VERSION").into(),
        files: prepared.files,
        overrides: p.overrides.clone(),
        parameters: c.clone(),
        frame: prepared.frame.to_string(),
        epsg: prepared.frame.epsg(),
        geoid_grid: geoid.map(|g| g.name().to_string()),
        trajectory_span_s: prepared.traj.span_s(),
        inputs,
        totals: totals.clone(),
        outputs,
        threads,
        stages,
        returns_per_second: totals.read as f64 / georef_s.max(1e-9),
        peak_rss_bytes: report::peak_rss_bytes(),
        sync: synced.reports,
    })
}

/// Refuses a run whose returns are rejected (for any reason but a missing return) in a share
/// above `output.max_rejected_share`, naming the main reason's likely cause: for returns
/// outside the trajectory, the clock (`time.t0_s`: absolute time, a wrong week, another day).
fn check_rejected_share(
    p: &LoadedPipeline,
    inputs: &[report::InputReport],
    clocks: &[sync::ResolvedClock],
    (traj_start, traj_end): (f64, f64),
) -> crate::Result<()> {
    use report::RejectReason;
    let max = p.config.output.max_rejected_share;
    let source = p.path.display().to_string();
    for (k, (input, clock)) in inputs.iter().zip(clocks).enumerate() {
        let Some(excess) = input.counts.excess_rejected(max) else {
            continue;
        };
        let what = format!("inputs.profiles[{k}] ({})", input.file.path.display());
        let what = excess.describe(&what, max);
        let software = clock.clock.model == crate::timing::TimeModel::Software;
        let first = input.profile_range.map(|(first, _)| first);
        let (key, cause) = match (excess.reason, first) {
            (RejectReason::OutsideTrajectory, Some(first)) if software => {
                let s = &clock.clock.clock;
                let t = s.t0_s + s.period_s * f64::from(first);
                let week = 604_800.0;
                let off = t - 0.5 * (traj_start + traj_end);
                let weeks = (off / week).round();
                let hint = if weeks != 0.0 && (off - weeks * week).abs() < traj_end - traj_start {
                    format!("; that is {weeks} GPS week(s) off: the week of t0_s is wrong")
                } else {
                    String::new()
                };
                let cause = format!(
                    "the clock puts profile {first} at {t:.3} s but the trajectory spans \
                     {traj_start:.3}..{traj_end:.3} s of the week{hint}: check time.t0_s and \
                     time.period_s (or [sync])"
                );
                ("time.t0_s", cause)
            }
            (reason, _) => {
                let (key, cause) = reason.likely_cause();
                (key, cause.to_string())
            }
        };
        return Err(crate::Error::config(
            source,
            key,
            format!("{what}: {cause}; nothing was published"),
        ));
    }
    Ok(())
}

/// Refuses a run that wrote no point unless `output.allow_empty` (before anything is
/// published, so the previous output stays).
fn check_not_empty(p: &LoadedPipeline, inputs: &[report::InputReport]) -> crate::Result<()> {
    let mut totals = ReturnCounts::default();
    inputs.iter().for_each(|i| totals.merge(&i.counts));
    if totals.written > 0 || p.config.output.allow_empty {
        return Ok(());
    }
    let reasons: Vec<String> = totals
        .rejected
        .iter()
        .map(|(reason, n)| format!("{n} {}", reason.describe()))
        .collect();
    let why = if reasons.is_empty() {
        String::new()
    } else {
        format!(" (rejected: {})", reasons.join("; "))
    };
    Err(crate::Error::config(
        p.path.display().to_string(),
        "output.allow_empty",
        format!(
            "no point written from {} returns read{why}: the previous output is kept; fix the \
             inputs or set output.allow_empty = true to write an empty output",
            totals.read
        ),
    ))
}

fn progress_bar(enabled: bool, total: u64) -> indicatif::ProgressBar {
    if enabled {
        crate::progress::bar(total, "georeferencing returns")
    } else {
        indicatif::ProgressBar::hidden()
    }
}
