//! The plan of a day: every pass's inputs with their resolved clock, cut into work units
//! (pass, input, records of whole profiles covering about `day.unit_s` seconds), computed up
//! front and written to `<out>/plan.json`. A restart reads the plan back (the clocks are not
//! estimated again); a plan made from other inputs is refused.

use super::config::LoadedDay;
use crate::io::profiles::ProfileFile;
use crate::pipeline::config::{LoadedPipeline, OutputFormat, SplitMode};
use crate::pipeline::prepare::{self, Prepared};
use crate::pipeline::sync::{self, ResolvedClock, SyncStageReport};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The plan file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// SHA-256 of the day file, the template and every profile file's path and size.
    pub fingerprint: String,
    /// Returns per executor chunk: unit cuts are multiples of it, units run with it.
    pub chunk_returns: usize,
    /// Every profile file of the day, pass by pass.
    pub inputs: Vec<PlannedInput>,
    /// The work units, in output order.
    pub units: Vec<Unit>,
}

/// One profile file of a pass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedInput {
    /// Index of the pass in the day file.
    pub pass: usize,
    /// Profile file.
    pub profiles: PathBuf,
    /// Point source id of its points.
    pub point_source_id: u16,
    /// The clock its returns are timed with (estimated with `[sync]`).
    pub clock: PlannedClock,
    /// The sync that estimated it (with `[sync]`), for the morning report.
    #[serde(default)]
    pub sync: Option<PlannedSync>,
}

/// What the morning report shows of a sync.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedSync {
    /// The method that answered (`paper` or `refined`).
    pub method: crate::sync::Method,
    /// Chi-square of the answer and its degrees of freedom.
    pub chi2: f64,
    /// Degrees of freedom of `chi2`.
    pub dof: usize,
    /// With `method = "auto"`: why the refined estimator did not answer.
    pub fallback: Option<String>,
}

/// The numbers of a [`ResolvedClock`] that a sync may change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlannedClock {
    /// Time of profile 0 (s).
    pub t0_s: f64,
    /// Mirror period (s).
    pub period_s: f64,
    /// Attitude latency (s).
    pub attitude_latency_s: f64,
    /// Covariance of (t0, T) (s^2).
    pub clock_covariance_s2: [[f64; 2]; 2],
    /// 1-sigma of the attitude latency (s).
    pub sigma_attitude_latency_s: f64,
}

impl PlannedClock {
    fn of(c: &ResolvedClock) -> Self {
        let m = &c.clock_covariance_s2;
        PlannedClock {
            t0_s: c.clock.clock.t0_s,
            period_s: c.clock.clock.period_s,
            attitude_latency_s: c.attitude_latency_s,
            clock_covariance_s2: [[m[(0, 0)], m[(0, 1)]], [m[(1, 0)], m[(1, 1)]]],
            sigma_attitude_latency_s: c.sigma_attitude_latency_s,
        }
    }

    /// `configured` with this plan's numbers.
    pub fn applied_to(&self, mut configured: ResolvedClock) -> ResolvedClock {
        configured.clock.clock.t0_s = self.t0_s;
        configured.clock.clock.period_s = self.period_s;
        configured.attitude_latency_s = self.attitude_latency_s;
        configured.clock_covariance_s2 =
            nalgebra::Matrix2::from(self.clock_covariance_s2).transpose();
        configured.sigma_attitude_latency_s = self.sigma_attitude_latency_s;
        configured
    }
}

impl Plan {
    /// The unit before `unit` in its pass (plan order); none for the pass's first.
    pub fn previous_in_pass(&self, unit: &Unit) -> Option<&Unit> {
        let k = self.units.iter().position(|u| u.id == unit.id)?;
        let previous = &self.units[k.checked_sub(1)?];
        (previous.pass == unit.pass).then_some(previous)
    }
}

/// A work unit: records `records` of input `input`, whole profiles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unit {
    /// `<pass name>-<input in pass>-<unit in input>`, e.g. `p01-0-0003`.
    pub id: String,
    /// Index of the pass in the day file.
    pub pass: usize,
    /// Index in [`Plan::inputs`].
    pub input: usize,
    /// First and one-past-last record.
    pub records: [usize; 2],
    /// GPS time of its first and last record (s).
    pub time_window_s: [f64; 2],
}

/// The pipeline of pass `pass` of the day: the template with the pass's profile files, its
/// point source ids and `las` as output (one file, possibly empty).
pub fn pass_pipeline(day: &LoadedDay, pass: usize, las: &Path) -> LoadedPipeline {
    let mut p = day.template.clone();
    let c = &mut p.config;
    let before: usize = day.config.passes[..pass]
        .iter()
        .map(|p| p.profiles.len())
        .sum();
    c.inputs.first_point_source_id += before as u16;
    c.inputs.profiles = day.config.passes[pass].profiles.clone();
    c.output.las = las.to_path_buf().into();
    c.output.report = None;
    c.output.split = SplitMode::None;
    c.output.max_points_per_file = None;
    c.output.format = OutputFormat::Las;
    c.output.allow_empty = true;
    if !day.config.day.night.sync {
        c.sync = None;
    }
    p
}

/// The clock before any sync: the configured one, with `[sync]`'s approximate t0 and period.
fn approximate_clock(p: &LoadedPipeline) -> ResolvedClock {
    let c = &p.config;
    let mut clock = ResolvedClock::configured(c);
    if let Some(sy) = &c.sync {
        let approx = &mut clock.clock.clock;
        approx.t0_s = sy.t0_approx_s.or(c.time.t0_s).unwrap_or(approx.t0_s);
        approx.period_s = sy.period_approx_s.unwrap_or(approx.period_s);
    }
    clock
}

/// First and last finite return time of `file` (s), none for a file without one.
fn time_span(file: &ProfileFile, clock: &ResolvedClock) -> Option<(f64, f64)> {
    let t = |i: usize| Some(clock.clock.time_of(&file.get(i))).filter(|t| t.is_finite());
    let n = file.len();
    let first = (0..n).find_map(t)?;
    let last = (0..n).rev().find_map(t)?;
    Some((first.min(last), first.max(last)))
}

/// Checks every pass before any work: each lies (at least partly) within the trajectory and
/// no two passes' time windows overlap. Errors name the day file and the pass key.
pub fn check_passes(day: &LoadedDay, prepared: &[Prepared]) -> Result<()> {
    let mut windows = Vec::new();
    for (i, prep) in prepared.iter().enumerate() {
        let p = pass_pipeline(day, i, Path::new("unused.las"));
        let clock = approximate_clock(&p);
        let spans = prep
            .inputs
            .iter()
            .filter_map(|inp| time_span(&inp.file, &clock));
        let Some(window) = spans.reduce(|a, b| (a.0.min(b.0), a.1.max(b.1))) else {
            continue;
        };
        let (t_first, t_last) = prep.traj.span_s();
        if window.1 < t_first || window.0 > t_last {
            let problem = format!(
                "the pass spans {:.3} to {:.3} s, outside the trajectory {} ({t_first:.3} to \
                 {t_last:.3} s)",
                window.0,
                window.1,
                p.config.inputs.sbet.display()
            );
            return Err(Error::config(&day.source, format!("passes[{i}]"), problem));
        }
        windows.push((window, i));
    }
    windows.sort_by(|a, b| a.0 .0.total_cmp(&b.0 .0));
    for pair in windows.windows(2) {
        let ((a, i), (b, j)) = (pair[0], pair[1]);
        if b.0 <= a.1 {
            let problem = format!(
                "its time window {:.3} to {:.3} s overlaps passes[{i}] ({:.3} to {:.3} s)",
                b.0, b.1, a.0, a.1
            );
            return Err(Error::config(&day.source, format!("passes[{j}]"), problem));
        }
    }
    Ok(())
}

/// Plans the day from its prepared passes: clocks resolved (synchronised with `[sync]`),
/// inputs cut into units. Gives the plan and the sync reports.
pub fn make(
    day: &LoadedDay,
    prepared: &[Prepared],
    fingerprint: String,
    chunk_returns: usize,
) -> Result<(Plan, Vec<SyncStageReport>)> {
    let mut plan = Plan {
        fingerprint,
        chunk_returns,
        inputs: Vec::new(),
        units: Vec::new(),
    };
    let mut reports = Vec::new();
    for (pass, prep) in prepared.iter().enumerate() {
        let name = &day.config.passes[pass].name;
        let plots = day.config.day.out.join(format!("sync_{name}.las"));
        let synced = sync::run(&pass_pipeline(day, pass, &plots).config, prep)?;
        for (k, (input, clock)) in prep.inputs.iter().zip(&synced.clocks).enumerate() {
            let index = plan.inputs.len();
            let cuts = unit_cuts(&input.file, clock, day.config.day.unit_s, chunk_returns)?;
            for (u, pair) in cuts.windows(2).enumerate() {
                let t = |i: usize| clock.clock.time_of(&input.file.get(i));
                plan.units.push(Unit {
                    id: format!("{name}-{k}-{u:04}"),
                    pass,
                    input: index,
                    records: [pair[0], pair[1]],
                    time_window_s: [t(pair[0]), t(pair[1] - 1)],
                });
            }
            let sync = (synced.reports.len() == prep.inputs.len()).then(|| {
                let r = &synced.reports[k].result;
                PlannedSync {
                    method: r.method,
                    chi2: r.clock.chi2,
                    dof: r.clock.dof,
                    fallback: r.fallback.clone(),
                }
            });
            plan.inputs.push(PlannedInput {
                pass,
                profiles: input.original.clone(),
                point_source_id: input.point_source_id,
                clock: PlannedClock::of(clock),
                sync,
            });
        }
        reports.extend(synced.reports);
    }
    Ok((plan, reports))
}

/// Record indices where units start, and the file's length: about every `unit_s / period`
/// profiles (binary search on the profile counter), moved to the nearest multiple of `grid`
/// returns, the executor's chunk grid, so that every chunk is the one `kinescan run` computes
/// and the points are bit-identical (the projection caches start afresh at each chunk). A
/// counter that decreases across a cut is refused here, within a unit by the executor.
fn unit_cuts(
    file: &ProfileFile,
    clock: &ResolvedClock,
    unit_s: f64,
    grid: usize,
) -> Result<Vec<usize>> {
    let n = file.len();
    let mut cuts = vec![0];
    let profile = |i: usize| u64::from(file.get(i).profile);
    let per_unit = (unit_s / clock.clock.clock.period_s).round().max(1.0) as u64;
    let mut target = if n > 0 {
        profile(0) + per_unit
    } else {
        u64::MAX
    };
    while n > 0 && target <= profile(n - 1) {
        let start = *cuts.last().expect("starts with 0");
        let at = start + partition(n - start, |i| profile(start + i) < target);
        let cut = (at + grid / 2) / grid * grid;
        if cut > start && cut < n {
            if profile(cut - 1) > profile(cut) {
                let msg = format!(
                    "profile counter decreases from {} to {}: counter wrap or reordered file",
                    profile(cut - 1),
                    profile(cut)
                );
                return Err(Error::bad_record(file.path(), format!("record {cut}"), msg));
            }
            cuts.push(cut);
        }
        target = profile(cut.clamp(start + 1, n - 1)).max(target) + per_unit;
    }
    cuts.push(n);
    cuts.dedup();
    Ok(cuts)
}

/// The first `i` in `0..n` where `before(i)` is false (`before` true then false).
fn partition(n: usize, before: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if before(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The fingerprint of a day's inputs: SHA-256 of the day file, the template and each profile
/// file's path and size (contents are not hashed: too slow for a nightly start).
pub fn fingerprint(day: &LoadedDay) -> Result<String> {
    let mut h = Sha256::new();
    for file in [&day.path, &day.template.path] {
        h.update(std::fs::read(file).map_err(|e| Error::io(file, e))?);
    }
    for file in day.config.passes.iter().flat_map(|p| &p.profiles) {
        let len = std::fs::metadata(file)
            .map_err(|e| Error::io(file, e))?
            .len();
        h.update(file.to_string_lossy().as_bytes());
        h.update(len.to_le_bytes());
    }
    Ok(crate::io::digest::hex(&h.finalize()))
}

/// Prepares every pass ([`prepare_pass`]).
pub fn prepare_passes(day: &LoadedDay) -> Result<Vec<Prepared>> {
    (0..day.config.passes.len())
        .map(|i| prepare_pass(day, i))
        .collect()
}

/// Prepares pass `pass` (trajectory, frame, profile files mapped; no file hashed: the plan's
/// fingerprint identifies the inputs).
pub fn prepare_pass(day: &LoadedDay, pass: usize) -> Result<Prepared> {
    let units = day.config.day.out.join("units");
    prepare::open(&pass_pipeline(day, pass, &units.join("x.las")))
}

/// The plan at `path`, if one is there; refused when made from other inputs.
pub fn read_existing(path: &Path, fingerprint: &str) -> Result<Option<Plan>> {
    let text = match std::fs::read(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(path, e)),
    };
    let plan: Plan = serde_json::from_slice(&text)
        .map_err(|e| Error::bad_file(path, format!("not a day plan: {e}")))?;
    if plan.fingerprint != fingerprint {
        let problem = "made from another day file, template or profile files: remove the \
                       output folder's plan.json, journal.jsonl and units/ to start the day again";
        return Err(Error::bad_file(path, problem));
    }
    Ok(Some(plan))
}
