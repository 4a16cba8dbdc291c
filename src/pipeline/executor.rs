//! The parallel executor: chunks of memory-mapped returns georeferenced with rayon, written in
//! input order, so the output bytes do not depend on the number of threads.

use super::config::{FrameConfig, LoadedPipeline, Strictness, TimeModel};
use super::report::{
    FileRecord, InputReport, OutputReport, RejectReason, ReturnCounts, RunReport, StageTiming,
};
use super::sink::{ExtraSlots, LasSink, SinkSettings};
use crate::geo::local::LocalProjection;
use crate::geo::projection::MapFrame;
use crate::geo::rotations::wrap_pi;
use crate::georef::{ReturnTerms, Sensor};
use crate::io::las::{encode_points, ChunkStats, LasPoint, PointLayout};
use crate::io::profiles::{ProfileColumns, ProfileFile, RawReturn};
use crate::io::profiles_csv::RecordLines;
use crate::timing::ScannerClock;
use crate::trajectory::{NavGap, PoseCursor, SigmaCursor, Trajectory};
use crate::uncertainty::model::FrameCache;
use crate::uncertainty::propagate::{AxisVariances, Propagator, TVU95_FACTOR};
use crate::{Error, Result};
use nalgebra::Vector3;
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::time::Instant;

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

/// Everything needed to turn one raw return into a LAS point.
struct Georeferencer<'a> {
    traj: &'a Trajectory,
    sensor: Sensor,
    clock: ScannerClock,
    model: TimeModel,
    columns: ProfileColumns,
    attitude_latency_s: f64,
    position_latency_s: f64,
    min_range_m: f64,
    max_range_m: f64,
    frame: MapFrame,
    point_source_id: u16,
    slots: ExtraSlots,
    uncertainty: Option<UncertaintyOut>,
}

/// Per-point uncertainty (present with an `[uncertainty]` table).
struct UncertaintyOut {
    propagator: Propagator,
    write_95: bool,
    write_shares: bool,
    /// Index in `LasPoint::extra` of `sigma_x`.
    first_dim: usize,
}

impl UncertaintyOut {
    /// Writes the uncertainty extra dimensions of `var` into `extra` (order of
    /// [`super::sink::uncertainty_dims`]).
    fn fill(&self, var: &AxisVariances, extra: &mut [f64]) {
        let mut values = [0.0; 11];
        let sigma = var.sigma_xyz_m();
        values[..3].copy_from_slice(sigma.as_slice());
        let mut n = 3;
        if self.write_95 {
            let tvu95 = TVU95_FACTOR * sigma.z; // = var.tvu95_m() without a second sqrt
            values[n..n + 2].copy_from_slice(&[var.thu95_m(), tvu95]);
            n += 2;
        }
        if self.write_shares {
            values[n..n + 6].copy_from_slice(&var.shares());
            n += 6;
        }
        extra[self.first_dim..self.first_dim + n].copy_from_slice(&values[..n]);
    }
}

/// The result of one chunk of returns: its LAS records, already encoded.
struct ChunkOut {
    records: Vec<u8>,
    stats: ChunkStats,
    counts: [u64; RejectReason::ALL.len()],
    first_reject: Option<(usize, RejectReason)>,
    profiles: Option<(u32, u32)>,
    counter_decrease: Option<(usize, u32, u32)>,
    jumps: Vec<(usize, u32, u32)>,
    time_span_s: Option<(f64, f64)>,
}

fn reason_index(r: RejectReason) -> usize {
    RejectReason::ALL
        .iter()
        .position(|x| *x == r)
        .expect("listed")
}

impl From<NavGap> for RejectReason {
    fn from(g: NavGap) -> Self {
        match g {
            NavGap::OutsideTrajectory => RejectReason::OutsideTrajectory,
            NavGap::TrajectoryGap => RejectReason::TrajectoryGap,
            NavGap::OutsideAccuracy => RejectReason::OutsideAccuracy,
        }
    }
}

impl Georeferencer<'_> {
    /// Uses a synchronisation result: its clock (and latency, when estimated) for the time
    /// model, and its covariances for the timing term of the uncertainty.
    fn apply_sync(&mut self, s: &crate::sync::SyncResult) {
        self.clock.t0_s = s.clock.t0_s;
        self.clock.period_s = s.clock.period_s;
        let latency = s.attitude_latency_s.zip(s.sigma_attitude_latency_s);
        if let Some((tau, _)) = latency {
            self.attitude_latency_s = tau;
        }
        if let Some(u) = self.uncertainty.as_mut() {
            let clock = nalgebra::Matrix2::from(s.clock.cov_t0_period);
            u.propagator
                .set_timing(clock, latency.map(|(_, sigma)| sigma));
        }
    }

    /// GPS time (s) of a return, per the configured time model, and its partials with
    /// respect to the clock parameters (t0, T) (the mirror fraction is computed once).
    #[inline]
    fn time_of(&self, r: &RawReturn) -> (f64, [f64; 2]) {
        match self.model {
            TimeModel::Software => {
                let (t, (a, b)) = self.clock.time_and_partials(r.profile, r.beta_rad);
                (t, [a, b])
            }
            TimeModel::HardwareProfile => {
                let (t, f) = self
                    .clock
                    .time_from_profile_tag_and_partial(r.time_s, r.beta_rad);
                (t, [0.0, f])
            }
            TimeModel::HardwareReturn => (r.time_s, [0.0, 0.0]),
        }
    }

    #[inline]
    fn point(
        &self,
        r: &RawReturn,
        cursor: &mut PoseCursor,
        local: &mut Option<LocalProjection>,
        sigmas: Option<&mut (SigmaCursor, FrameCache)>,
        p: &mut LasPoint,
    ) -> Result<f64, RejectReason> {
        let alpha = if self.columns.alpha {
            r.alpha_rad
        } else {
            self.sensor.alpha0_rad
        };
        let finite = r.beta_rad.is_finite() && r.range_m.is_finite() && alpha.is_finite();
        if !finite || (self.columns.time && !r.time_s.is_finite()) {
            return Err(RejectReason::NonFinite);
        }
        if r.range_m == 0.0 {
            return Err(RejectReason::MissingReturn);
        }
        if !(self.min_range_m..=self.max_range_m).contains(&r.range_m) {
            return Err(RejectReason::RangeOutOfLimits);
        }
        let (t, dt_dclock) = self.time_of(r);
        let pose = cursor.at(t)?;
        let nav_sigma = match sigmas {
            Some((cursor, frames)) => Some((cursor.at(t)?, frames)),
            None => None,
        };
        let terms = ReturnTerms::of_pose(&pose, &self.sensor, r.range_m, alpha, r.beta_rad);
        let x_e = terms.point_e(&pose.nav.r_e_m);
        let x_m = self
            .local_projection(local, &pose.nav.r_e_m)
            .ecef_to_map(&x_e);
        // Filled in place: a LasPoint is ~190 bytes, moving it per return costs more than
        // the georeferencing arithmetic.
        (p.x, p.y, p.z) = (x_m.x, x_m.y, x_m.z);
        p.intensity = r.intensity;
        p.scan_angle_deg = wrap_pi(r.beta_rad).to_degrees();
        p.gps_time = t;
        p.point_source_id = self.point_source_id;
        if let Some(k) = self.slots.range {
            p.extra[k] = r.range_m;
        }
        if let (Some(u), Some((nav_sigma, frames))) = (&self.uncertainty, nav_sigma) {
            // Reuses the georeferencing terms; the map axes and the local-level turn come
            // from the cache.
            let (r_n_to_map, dtheta) = frames.frames(&x_e, &pose.nav);
            let var = u.propagator.variances(
                r_n_to_map,
                dtheta,
                &terms,
                &pose.omega_b_radps,
                &pose.nav.v_n_mps,
                &nav_sigma,
                dt_dclock,
            );
            u.fill(&var, &mut p.extra);
        }
        Ok(t)
    }

    /// The map projection expanded about the vehicle, re-expanded when it has moved
    /// [`RECENTRE_M`] from the expansion centre.
    #[inline]
    fn local_projection<'p>(
        &self,
        local: &'p mut Option<LocalProjection>,
        vehicle_e: &Vector3<f64>,
    ) -> &'p LocalProjection {
        let stale = local
            .as_ref()
            .is_none_or(|l| (l.centre_e() - vehicle_e).norm_squared() > RECENTRE_M * RECENTRE_M);
        if stale {
            *local = Some(LocalProjection::new(self.frame, *vehicle_e));
        }
        local.as_ref().expect("set above")
    }

    fn chunk(
        &self,
        file: &ProfileFile,
        range: std::ops::Range<usize>,
        layout: &PointLayout,
        pool: &BufferPool,
    ) -> Result<ChunkOut> {
        let mut records = pool.take();
        records.reserve(range.len() * layout.record_len());
        let mut out = ChunkOut {
            records,
            stats: ChunkStats::empty(layout.record_len()),
            counts: [0; RejectReason::ALL.len()],
            first_reject: None,
            profiles: None,
            counter_decrease: None,
            jumps: Vec::new(),
            time_span_s: None,
        };
        let mut cursor =
            PoseCursor::new(self.traj, self.attitude_latency_s, self.position_latency_s);
        let mut local = None;
        let mut batch = vec![LasPoint::default(); ENCODE_BATCH];
        let mut batch_records = [0usize; ENCODE_BATCH];
        let mut filled = 0;
        let mut sigmas = self
            .uncertainty
            .as_ref()
            .and_then(|_| self.traj.sigma_cursor())
            .map(|c| (c, FrameCache::new(self.frame)));
        let mut prev: Option<u32> = None;
        let (mut t_min, mut t_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in range {
            let r = file.get(i);
            if let Some(p) = prev {
                if r.profile < p {
                    out.counter_decrease = Some((i, p, r.profile));
                    break;
                }
                if r.profile > p + 1 {
                    out.jumps.push((i, p, r.profile));
                }
            }
            prev = Some(r.profile);
            out.profiles = Some((out.profiles.map_or(r.profile, |p| p.0), r.profile));
            let p = &mut batch[filled];
            match self.point(&r, &mut cursor, &mut local, sigmas.as_mut(), p) {
                Ok(t) => {
                    if let Some(k) = self.slots.return_index {
                        p.extra[k] = i as f64;
                    }
                    batch_records[filled] = i;
                    filled += 1;
                    if filled == ENCODE_BATCH {
                        encode_into(&batch, &batch_records, layout, &mut out, file)?;
                        filled = 0;
                    }
                    t_min = t_min.min(t);
                    t_max = t_max.max(t);
                }
                Err(reason) => {
                    out.counts[reason_index(reason)] += 1;
                    out.first_reject.get_or_insert((i, reason));
                }
            }
        }
        encode_into(&batch[..filled], &batch_records, layout, &mut out, file)?;
        if t_min <= t_max {
            out.time_span_s = Some((t_min, t_max));
        }
        Ok(out)
    }
}

/// Points encoded at a time (keeps the per-thread point buffer in cache).
const ENCODE_BATCH: usize = 1024;
/// Distance (m) the vehicle may move from the local projection's centre before re-expanding;
/// points further than `EXPANSION_RADIUS_M - RECENTRE_M` from the vehicle may fall back to the
/// exact projection.
const RECENTRE_M: f64 = 100.0;

/// Encodes `batch` (the returns `records` of `file`), appending its records and stats to
/// `out`. A point that cannot be encoded is named by its record, and a coordinate beyond the
/// LAS range by the keys that fix it.
fn encode_into(
    batch: &[LasPoint],
    records: &[usize],
    layout: &PointLayout,
    out: &mut ChunkOut,
    file: &ProfileFile,
) -> Result<()> {
    match encode_points(batch, layout, &mut out.records) {
        Ok(stats) => {
            out.stats.merge(&stats);
            Ok(())
        }
        Err(e) => Err(name_encode_error(e, batch, records, layout, file)),
    }
}

fn name_encode_error(
    e: Error,
    batch: &[LasPoint],
    records: &[usize],
    layout: &PointLayout,
    file: &ProfileFile,
) -> Error {
    let failing = (0..batch.len())
        .find(|&k| encode_points(&batch[k..=k], layout, &mut Vec::new()).is_err())
        .unwrap_or(0);
    let mut problem = e.to_string();
    if let Some((_, what)) = problem.split_once(" of the chunk: ") {
        problem = what.to_string();
    }
    if problem.contains("beyond what LAS can store") {
        let p = &batch[failing];
        let near = [p.x, p.y, p.z].map(|v| (v / 1000.0).round() * 1000.0);
        problem += &format!(
            ": set output.offset_m near the data (e.g. [{}, {}, {}]) or a coarser output.scale_m",
            near[0], near[1], near[2]
        );
    }
    Error::bad_record(file.path(), format!("record {}", records[failing]), problem)
}

/// Record buffers handed back by the writer for reuse: a fresh multi-megabyte buffer per chunk
/// costs a page fault and a page clear per 4 KiB, more than writing it.
#[derive(Default)]
struct BufferPool(std::sync::Mutex<Vec<Vec<u8>>>);

impl BufferPool {
    fn take(&self) -> Vec<u8> {
        self.0
            .lock()
            .map(|mut v| v.pop())
            .ok()
            .flatten()
            .unwrap_or_default()
    }

    fn give(&self, mut buf: Vec<u8>) {
        buf.clear();
        if let Ok(mut v) = self.0.lock() {
            v.push(buf);
        }
    }
}

/// Runs a loaded pipeline: georeferences every profile file and publishes the LAS file(s) and
/// the report (at `output.report_path()`) as one set.
pub fn run(p: &LoadedPipeline, opts: &RunOptions) -> Result<RunReport> {
    let threads = opts
        .threads
        .unwrap_or_else(rayon::current_num_threads)
        .max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Invalid(format!("cannot start {threads} threads: {e}")))?;
    super::publish::publish_run(p, |staged| {
        pool.install(|| run_in_pool(staged, opts, threads))
    })
}

fn run_in_pool(p: &LoadedPipeline, opts: &RunOptions, threads: usize) -> Result<RunReport> {
    let c = &p.config;
    let mut stages = Vec::new();
    let started = Instant::now();
    let traj_opts = c.trajectory.options();
    let traj = Trajectory::open(&c.inputs.sbet, c.inputs.smrmsg.as_deref(), traj_opts)?;
    let mut files = vec![
        FileRecord::of("pipeline", &p.path)?,
        FileRecord::of("sbet", &c.inputs.sbet)?,
    ];
    if let Some(s) = &c.inputs.smrmsg {
        files.push(FileRecord::of("smrmsg", s)?);
    }
    let frame = map_frame(&c.output.frame, &traj)?;
    check_frame_near_data(p, &frame, &traj)?;
    let out_dir = c
        .output
        .las
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    let staging = crate::io::atomic::create_temp_dir(&out_dir, "import")?;
    let (profile_files, record_lines) =
        open_profiles_with_lines(&c.inputs.profiles, staging.path())?;
    stages.push(StageTiming {
        stage: "prepare".into(),
        seconds: started.elapsed().as_secs_f64(),
    });

    let sync_started = Instant::now();
    let stem = c.output.stem();
    let sync = crate::sync::stage::run(c, &traj, &profile_files, &out_dir, &stem)?;
    if c.sync.is_some() {
        stages.push(StageTiming {
            stage: "sync".into(),
            seconds: sync_started.elapsed().as_secs_f64(),
        });
    }

    let georef_started = Instant::now();
    let settings = SinkSettings::new(c, &frame, &traj, &p.path)?;
    let mut sink = LasSink::new(settings);
    let total: u64 = profile_files.iter().map(|f| f.1.len() as u64).sum();
    let bar = progress_bar(opts.progress, total);
    let mut inputs = Vec::new();
    for (k, (original, file)) in profile_files.iter().enumerate() {
        let psid = c.inputs.first_point_source_id.saturating_add(k as u16);
        let user = |e| on_user_line(e, file.path(), original, record_lines[k].as_ref());
        let mut g = georeferencer(p, &traj, &frame, file, psid).map_err(user)?;
        if let Some(s) = sync.get(k) {
            g.apply_sync(&s.result);
        }
        sink.start_input(original)?;
        let report = process_file(
            &g,
            file,
            original,
            opts,
            &mut sink,
            &bar,
            c.output.strictness,
        )
        .map_err(user)?;
        inputs.push(report);
    }
    bar.finish_and_clear();
    check_not_empty(p, &inputs)?;
    let summaries = sink.finish()?;
    let georef_s = georef_started.elapsed().as_secs_f64();
    stages.push(StageTiming {
        stage: "georeference_and_write".into(),
        seconds: georef_s,
    });

    let mut totals = ReturnCounts::default();
    inputs
        .iter()
        .for_each(|i: &InputReport| totals.merge(&i.counts));
    let outputs = summaries
        .into_iter()
        .map(|s| OutputReport {
            path: s.path,
            points: s.point_count,
            min_m: s.min_m,
            max_m: s.max_m,
            bytes: s.file_bytes,
        })
        .collect();
    Ok(RunReport {
        kinescan_version: env!("CARGO_PKG_VERSION").into(),
        files,
        overrides: p.overrides.clone(),
        parameters: c.clone(),
        frame: frame.to_string(),
        epsg: frame.epsg(),
        trajectory_span_s: traj.span_s(),
        inputs,
        totals: totals.clone(),
        outputs,
        threads,
        stages,
        returns_per_second: totals.read as f64 / georef_s.max(1e-9),
        peak_rss_bytes: super::report::peak_rss_bytes(),
        sync,
    })
}

/// Refuses a run that wrote no point unless `output.allow_empty` (before anything is
/// published, so the previous output stays).
fn check_not_empty(p: &LoadedPipeline, inputs: &[InputReport]) -> Result<()> {
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
    Err(Error::config(
        p.path.display().to_string(),
        "output.allow_empty",
        format!(
            "no point written from {} returns read{why}: the previous output is kept; fix the \
             inputs or set output.allow_empty = true to write an empty output",
            totals.read
        ),
    ))
}

/// Farthest a trajectory position may lie from a UTM zone's central meridian (deg): the
/// zone's own 3 deg plus a 1 deg margin (scale error there about 1e-3; beyond it coordinates
/// lose meaning fast: zone 60 at 11.6 E is 180 deg away).
pub const UTM_MAX_OFFSET_DEG: f64 = 4.0;
/// Latitude (deg) beyond which data on the other side of the equator than the configured
/// hemisphere is refused.
const HEMISPHERE_MARGIN_DEG: f64 = 1.0;

/// Refuses a UTM frame far from the trajectory (every record checked), naming the key to
/// change.
fn check_frame_near_data(p: &LoadedPipeline, frame: &MapFrame, traj: &Trajectory) -> Result<()> {
    let sbet = traj.sbet();
    let (mut worst, mut lat_min, mut lat_max) = (0.0f64, f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..sbet.len() {
        let r = sbet.record(i);
        if let Some(d) = frame.utm_offset_deg(r.lon_rad) {
            worst = if d.abs() > worst.abs() { d } else { worst };
        }
        lat_min = lat_min.min(r.lat_rad.to_degrees());
        lat_max = lat_max.max(r.lat_rad.to_degrees());
    }
    let source = p.path.display().to_string();
    if worst.abs() > UTM_MAX_OFFSET_DEG {
        return Err(Error::config(
            source,
            "output.frame.zone",
            format!(
                "{frame}: the trajectory reaches {worst:.1} deg from the zone's central meridian \
                 (at most +-{UTM_MAX_OFFSET_DEG} deg: the zone's 3 deg plus a margin); give the \
                 zone that contains the data, or leave it out to take it from the trajectory"
            ),
        ));
    }
    if let MapFrame::Utm { north, .. } = *frame {
        let wrong = if north {
            lat_min < -HEMISPHERE_MARGIN_DEG
        } else {
            lat_max > HEMISPHERE_MARGIN_DEG
        };
        if wrong {
            return Err(Error::config(
                source,
                "output.frame.north",
                format!(
                    "{frame}: the trajectory's latitudes {lat_min:.2} .. {lat_max:.2} deg are in \
                     the other hemisphere; set north = {} or leave it out",
                    !north
                ),
            ));
        }
    }
    Ok(())
}

/// The output mapping frame: UTM zone and hemisphere from the first trajectory record unless
/// configured.
pub fn map_frame(f: &FrameConfig, traj: &Trajectory) -> Result<MapFrame> {
    let first = traj.sbet().record(0);
    match *f {
        FrameConfig::Utm { zone, north } => {
            let auto = MapFrame::utm_for(first.lon_rad, first.lat_rad)?;
            let MapFrame::Utm {
                zone: z0,
                north: n0,
            } = auto
            else {
                unreachable!("utm_for gives UTM")
            };
            MapFrame::utm(zone.unwrap_or(z0), north.unwrap_or(n0))
        }
        FrameConfig::Ecef => Ok(MapFrame::Ecef),
        FrameConfig::Enu { .. } => MapFrame::local_enu(f.enu_origin().expect("enu")),
        FrameConfig::Epsg { code } => MapFrame::from_epsg(code),
    }
}

/// Profile files as named in the pipeline, each with the binary file read.
type OpenedProfiles = Vec<(PathBuf, ProfileFile)>;

/// Maps binary profile files; CSV files are first imported into `staging`.
pub fn open_profiles(paths: &[PathBuf], staging: &Path) -> Result<OpenedProfiles> {
    Ok(open_profiles_with_lines(paths, staging)?.0)
}

/// [`open_profiles`], with the CSV line of every record of each imported file (`None` for a
/// binary file), to name the user's line in messages ([`on_user_line`]).
fn open_profiles_with_lines(
    paths: &[PathBuf],
    staging: &Path,
) -> Result<(OpenedProfiles, Vec<Option<RecordLines>>)> {
    let mut files = Vec::new();
    let mut lines = Vec::new();
    for (k, path) in paths.iter().enumerate() {
        let is_csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        if is_csv {
            let bin = staging.join(format!("input{k}.ksprof"));
            let summary = crate::io::profiles_csv::import_csv(path, &bin)?;
            files.push((path.clone(), ProfileFile::open(&bin)?));
            lines.push(Some(summary.lines));
        } else {
            files.push((path.clone(), ProfileFile::open(path)?));
            lines.push(None);
        }
    }
    Ok((files, lines))
}

/// An error about the binary import `file` of the user's CSV file `original` told in the
/// user's terms: the CSV file and its line instead of the import and its record.
fn on_user_line(e: Error, file: &Path, original: &Path, lines: Option<&RecordLines>) -> Error {
    let Some(lines) = lines else { return e };
    match e {
        Error::BadRecord { path, at, problem } if path == file => {
            let at = match at.strip_prefix("record ").map(str::parse::<u64>) {
                Some(Ok(record)) => format!("line {}", lines.line_of(record)),
                _ => at,
            };
            Error::bad_record(original, at, problem)
        }
        Error::BadFile { path, problem } if path == file => Error::bad_file(original, problem),
        other => other,
    }
}

fn georeferencer<'a>(
    p: &LoadedPipeline,
    traj: &'a Trajectory,
    frame: &MapFrame,
    file: &ProfileFile,
    point_source_id: u16,
) -> Result<Georeferencer<'a>> {
    let c = &p.config;
    let s = &c.sensor;
    let columns = file.columns();
    if c.time.model != TimeModel::Software && !columns.time {
        let msg = format!(
            "time.model = \"{}\" needs a time_s column, which this file lacks",
            c.time.model.name()
        );
        return Err(Error::bad_file(file.path(), msg));
    }
    let sensor = s.sensor();
    let mirror = c.time.mirror(c.sensor.encoder_offset_deg);
    let clock = ScannerClock {
        t0_s: c.time.t0_s.unwrap_or(0.0),
        period_s: c.time.period_s,
        mirror,
    };
    Ok(Georeferencer {
        traj,
        sensor,
        clock,
        model: c.time.model,
        columns,
        attitude_latency_s: c.latency.attitude_s,
        position_latency_s: c.latency.position_s,
        min_range_m: s.min_range_m,
        max_range_m: s.max_range_m,
        frame: *frame,
        point_source_id,
        slots: ExtraSlots::for_config(c).0,
        uncertainty: c.uncertainty.as_ref().map(|u| UncertaintyOut {
            propagator: Propagator::new(
                u.inputs(),
                u.write_shares,
                sensor.lever_arm_b_m,
                sensor.r_s_to_b,
            ),
            write_95: u.write_95,
            write_shares: u.write_shares,
            first_dim: ExtraSlots::for_config(c).0.uncertainty.unwrap_or(0),
        }),
    })
}

fn progress_bar(enabled: bool, total: u64) -> indicatif::ProgressBar {
    if enabled {
        crate::progress::bar(total, "georeferencing returns")
    } else {
        indicatif::ProgressBar::hidden()
    }
}

/// A batch of chunk results, in input order.
type Batch = Vec<(std::ops::Range<usize>, Result<ChunkOut>)>;

/// Georeferences one profile file. Batches of chunks are computed in parallel on the pool
/// while a writer thread absorbs the previous batch (counts, checks, LAS, hash), so writing
/// overlaps computing; results are absorbed strictly in input order.
#[allow(clippy::too_many_arguments)]
fn process_file(
    g: &Georeferencer,
    file: &ProfileFile,
    original: &Path,
    opts: &RunOptions,
    sink: &mut LasSink,
    bar: &indicatif::ProgressBar,
    strictness: Strictness,
) -> Result<InputReport> {
    let n = file.len();
    let chunk = opts.chunk_returns.max(1);
    let batch = chunk * rayon::current_num_threads() * 8;
    let layout = sink.layout().clone();
    let (tx, rx) = std::sync::mpsc::sync_channel::<Batch>(1);
    let mut acc = FileAccumulator::new(file, strictness);
    let pool = BufferPool::default();
    std::thread::scope(|scope| {
        let writer = scope.spawn(|| -> Result<()> {
            for batch in rx {
                for (r, out) in batch {
                    pool.give(acc.absorb(r, out, sink, bar)?);
                }
            }
            Ok(())
        });
        for batch_start in (0..n).step_by(batch) {
            let batch_end = (batch_start + batch).min(n);
            let ranges: Vec<_> = (batch_start..batch_end)
                .step_by(chunk)
                .map(|s| s..(s + chunk).min(batch_end))
                .collect();
            let outs: Batch = ranges
                .into_par_iter()
                .map(|r| (r.clone(), g.chunk(file, r, &layout, &pool)))
                .collect();
            if tx.send(outs).is_err() {
                break; // the writer stopped on an error, reported below
            }
        }
        drop(tx);
        writer.join().expect("writer thread panicked")
    })?;
    acc.finish(original, g.point_source_id)
}

/// What the writer side learns about one profile file.
struct FileAccumulator<'f> {
    file: &'f ProfileFile,
    strictness: Strictness,
    hasher: Sha256,
    counts: ReturnCounts,
    tracker: CounterTracker,
    span: Option<(f64, f64)>,
}

impl<'f> FileAccumulator<'f> {
    fn new(file: &'f ProfileFile, strictness: Strictness) -> Self {
        let mut hasher = Sha256::new();
        hasher.update(file.header_bytes());
        FileAccumulator {
            file,
            strictness,
            hasher,
            counts: ReturnCounts::default(),
            tracker: CounterTracker::default(),
            span: None,
        }
    }

    /// Takes one chunk's result in input order: checks, counts, writes its records and hashes
    /// its input; gives the emptied record buffer back for reuse.
    fn absorb(
        &mut self,
        r: std::ops::Range<usize>,
        out: Result<ChunkOut>,
        sink: &mut LasSink,
        bar: &indicatif::ProgressBar,
    ) -> Result<Vec<u8>> {
        let path = self.file.path();
        // A chunk's error names the file and record already.
        let out = out?;
        self.tracker.absorb(path, r.start, &out)?;
        if self.strictness == Strictness::Fail {
            if let Some((i, reason)) = out.first_reject {
                let msg = format!("{} (output.strictness = \"fail\")", reason.describe());
                return Err(Error::bad_record(path, format!("record {i}"), msg));
            }
        }
        for (k, reason) in RejectReason::ALL.iter().enumerate() {
            if out.counts[k] > 0 {
                *self.counts.rejected.entry(*reason).or_default() += out.counts[k];
            }
        }
        self.counts.read += r.len() as u64;
        self.counts.written += out.stats.count;
        if let Some((a, b)) = out.time_span_s {
            self.span = Some(self.span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
        }
        sink.write(&out.records, &out.stats)?;
        self.hasher.update(self.file.record_bytes(r.clone()));
        self.file.release(r.clone());
        bar.inc(r.len() as u64);
        Ok(out.records)
    }

    fn finish(self, original: &Path, point_source_id: u16) -> Result<InputReport> {
        let c = self.counts;
        debug_assert_eq!(c.read, c.written + c.rejected_total());
        let path = self.file.path();
        let record = if original != path {
            FileRecord::of("profiles", original)?
        } else {
            let bytes = std::fs::metadata(path)
                .map_err(|e| Error::io(path, e))?
                .len();
            let sha256 = super::report::hex(&self.hasher.finalize());
            FileRecord {
                role: "profiles".into(),
                path: path.into(),
                bytes,
                sha256,
            }
        };
        Ok(InputReport {
            file: record,
            point_source_id,
            counts: c,
            profile_range: self.tracker.range,
            counter_jumps: self.tracker.jumps,
            counter_jump_examples: self.tracker.examples,
            time_span_s: self.span,
        })
    }
}

/// Profile-counter continuity across chunks.
#[derive(Default)]
struct CounterTracker {
    range: Option<(u32, u32)>,
    jumps: u64,
    examples: Vec<(u64, u32, u32)>,
}

impl CounterTracker {
    const EXAMPLES: usize = 10;

    fn absorb(&mut self, path: &Path, start: usize, out: &ChunkOut) -> Result<()> {
        if let Some((i, from, to)) = out.counter_decrease {
            let msg = format!(
                "profile counter decreases from {from} to {to}: counter wrap or reordered file"
            );
            return Err(Error::bad_record(path, format!("record {i}"), msg));
        }
        let mut jumps: Vec<(u64, u32, u32)> = out
            .jumps
            .iter()
            .map(|&(i, a, b)| (i as u64, a, b))
            .collect();
        if let (Some((_, last)), Some((first, _))) = (self.range, out.profiles) {
            if first < last {
                let msg = format!("profile counter decreases from {last} to {first}: counter wrap or reordered file");
                return Err(Error::bad_record(path, format!("record {start}"), msg));
            }
            if first > last + 1 {
                jumps.insert(0, (start as u64, last, first));
            }
        }
        self.jumps += jumps.len() as u64;
        for j in jumps {
            if self.examples.len() < Self::EXAMPLES {
                self.examples.push(j);
            }
        }
        if let Some((first, last)) = out.profiles {
            self.range = Some((self.range.map_or(first, |r| r.0), last));
        }
        Ok(())
    }
}

/// Opens and validates every input of a pipeline without georeferencing: the trajectory, the
/// sync points and targets, each profile file (CSV files are parsed completely), the time
/// model's needs and the map frame.
pub fn check_inputs(p: &LoadedPipeline) -> Result<()> {
    let c = &p.config;
    super::files::check_collisions_of(p)?;
    let traj_opts = c.trajectory.options();
    let traj = Trajectory::open(&c.inputs.sbet, c.inputs.smrmsg.as_deref(), traj_opts)?;
    let frame = map_frame(&c.output.frame, &traj)?;
    check_frame_near_data(p, &frame, &traj)?;
    let staging = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    if let Some(sync) = &c.sync {
        crate::io::points::read_control_points(&sync.points)?;
        if let Some(t) = &sync.targets {
            crate::io::patches::read_patches(t)?;
        }
    }
    for (k, (_, file)) in open_profiles(&c.inputs.profiles, staging.path())?
        .iter()
        .enumerate()
    {
        georeferencer(p, &traj, &frame, file, k as u16)?;
    }
    Ok(())
}
