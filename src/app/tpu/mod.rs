//! `kinescan tpu PIPELINE --cloud FILE` (SPEC §9, docs/tpu.md): per-point total propagated
//! uncertainty for a cloud georeferenced elsewhere. For every point of a LAS/LAZ cloud: the
//! pose at its GPS time (latencies applied), the scanner-frame vector by inverting the
//! georeferencing equation, the beam parameters and fit check of the scanner kind, and the
//! covariance by `run`'s own propagator (`uncertainty::batch`), written as `run`'s uncertainty
//! extra dimensions into a copy of the cloud that keeps every record, VLR and EVLR.
//!
//! Modules: `cloud` (open, time, CRS), `scanner` (scanner kinds behind one trait), `recover`
//! (one point back to its measurement), `write` (the output layout), `report`.
//!
//! The cloud is memory-mapped and processed in chunks in parallel (the current rayon pool),
//! written in order; mapped pages are released as chunks are done, so memory stays flat. The
//! output and the report are published as one set (`io::publish`), only when every point was
//! processed.

pub mod cloud;
pub mod recover;
pub mod report;
pub mod scanner;
pub mod write;

use crate::io::atomic::{create_temp_dir, AtomicFile};
use crate::io::digest::FileRecord;
use crate::io::las::read::LasInput;
use crate::io::las::{encode_extra, GpsTimeConvention, LasPoint};
use crate::io::paths::check_collisions;
use crate::io::publish::{
    conclude, prepare_folder, previous_outputs, stem_owns, OutputSet, StemLock,
};
use crate::pipeline::config::{LoadedTpuPipeline, OutputFormat, Strictness};
use crate::pipeline::report::{OutputReport, StageTiming};
use crate::pipeline::schema::{OutputSchema, PointFill};
use crate::trajectory::Trajectory;
use crate::uncertainty::batch::{VarianceBatch, BATCH_RETURNS};
use crate::uncertainty::propagate::Propagator;
use crate::{Error, Result};
use nalgebra::Vector3;
use rayon::prelude::*;
use recover::{ClockPartials, PointReject, Recoverer};
use report::{CloudReport, FitSummary, PointCounts, TpuReport};
use std::path::{Path, PathBuf};
use std::time::Instant;
use write::OutputLayout;

/// How `tpu` runs (not what it computes).
#[derive(Debug, Clone)]
pub struct TpuOptions {
    /// Worker threads (None: all cores).
    pub threads: Option<usize>,
    /// Progress bar (drawn only on a terminal).
    pub progress: bool,
    /// Points per parallel work item.
    pub chunk_points: usize,
}

impl Default for TpuOptions {
    fn default() -> Self {
        TpuOptions {
            threads: None,
            progress: true,
            chunk_points: 1 << 15,
        }
    }
}

/// Runs `tpu` on `cloud` with the pipeline `p`; publishes the output cloud and the report as
/// one set; gives the report.
pub fn tpu(p: &LoadedTpuPipeline, cloud: &Path, opts: &TpuOptions) -> Result<TpuReport> {
    let threads = opts
        .threads
        .unwrap_or_else(rayon::current_num_threads)
        .max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Invalid(format!("cannot start {threads} threads: {e}")))?;
    let c = &p.config;
    let out = c.output.cloud_path();
    let report_path = c.output.report_path();
    let mut inputs = vec![
        ("pipeline file".to_string(), p.path.clone()),
        ("inputs.sbet".to_string(), c.inputs.sbet.to_path_buf()),
        ("--cloud".to_string(), cloud.to_path_buf()),
    ];
    if let Some(s) = &c.inputs.smrmsg {
        inputs.push(("inputs.smrmsg".into(), s.to_path_buf()));
    }
    let outputs = vec![
        ("output.las".to_string(), out.clone()),
        ("output.report".to_string(), report_path.clone()),
    ];
    check_collisions(&inputs, &outputs)?;
    let _lock = StemLock::acquire(&c.output.las)?;
    for dir in [parent(&out), parent(&report_path)] {
        prepare_folder(dir)?;
    }
    // A previous report's list is a hint: only this stem's clouds, in this folder, never an
    // input (docs/robustness.md).
    let stem = c.output.stem();
    let owned = |name: &str| stem_owns(&stem, name, &[".las", ".laz"]);
    let previous = previous_outputs(&report_path, parent(&c.output.las), owned, &inputs);
    let mut set = OutputSet::new(&c.output.stem());
    let staged_las = set.stage(&c.output.las)?;
    let staged_report = set.stage(&report_path)?;
    let result = pool
        .install(|| stages(p, cloud, &staged_las, opts, threads))
        .and_then(|mut report| {
            for o in &mut report.outputs {
                o.path = set.final_path(&o.path);
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

/// Everything between the lock and the publication.
fn stages(
    p: &LoadedTpuPipeline,
    cloud: &Path,
    staged_las: &Path,
    opts: &TpuOptions,
    threads: usize,
) -> Result<TpuReport> {
    let c = &p.config;
    let u = c.uncertainty.as_ref().expect("checked on load");
    let mut stages = Vec::new();
    let mut timed = |stage: &str, started: Instant| {
        stages.push(StageTiming {
            stage: stage.into(),
            seconds: started.elapsed().as_secs_f64(),
        })
    };
    let started = Instant::now();
    let scratch_dir = create_temp_dir(parent(staged_las), "tpu-cloud")?;
    let opened = Opened::open(p, cloud, &scratch_dir.path().join("cloud.las"))?;
    let (traj, input, time_at, convention, frame) = (
        &opened.traj,
        &opened.input,
        opened.time_at,
        opened.convention,
        opened.frame,
    );
    let crs_source = opened.crs_source.clone();
    let schema = OutputSchema::uncertainty_only(u);
    let layout = OutputLayout::new(input, schema.dims())?;
    check_format(c.output.format, input, &p.path)?;
    let mut files = vec![
        FileRecord::of("pipeline", &p.path)?,
        FileRecord::of("sbet", &c.inputs.sbet)?,
    ];
    if let Some(s) = &c.inputs.smrmsg {
        files.push(FileRecord::of("smrmsg", s)?);
    }
    let cloud_record = FileRecord::of("cloud", cloud)?;
    timed("prepare", started);

    let started = Instant::now();
    let sensor = c.sensor.sensor();
    let scanner = scanner::scanner_of(&c.tpu, sensor.alpha0_rad);
    let recoverer = opened.recoverer(p, scanner.as_ref());
    let propagator = propagator_of(u, &sensor, scanner.as_ref());
    let fill = schema.fill(0);
    let job = Job {
        input,
        layout: &layout,
        recoverer: &recoverer,
        propagator: &propagator,
        fill: &fill,
        time_at,
        strictness: c.output.strictness,
    };
    let (totals, fit) = job.run(staged_las, opts, threads)?;
    if totals.with_sigma == 0 && totals.read > 0 && !c.output.allow_empty {
        let reasons: Vec<String> = totals
            .rejected
            .iter()
            .map(|(r, n)| format!("{n} {}", r.describe()))
            .collect();
        return Err(Error::bad_file(
            cloud,
            format!(
                "no point could be given a sigma ({}): nothing published; set \
                 output.allow_empty = true to write the copy anyway",
                reasons.join("; ")
            ),
        ));
    }
    let process_s = started.elapsed().as_secs_f64();
    timed("recover_propagate_write", started);

    let started = Instant::now();
    let final_path = into_format(c.output.format, staged_las)?;
    if c.output.format != OutputFormat::Las {
        timed("compress", started);
    }
    let bytes = std::fs::metadata(&final_path)
        .map_err(|e| Error::io(&final_path, e))?
        .len();
    let min_max = |at: usize| -> f64 {
        let b = &layout.prefix;
        f64::from_le_bytes(b[at..at + 8].try_into().expect("8"))
    };
    let sha256 = FileRecord::of("las", &final_path)?.sha256;
    let outputs = vec![OutputReport {
        path: final_path,
        points: input.point_count,
        min_m: [min_max(187), min_max(203), min_max(219)],
        max_m: [min_max(179), min_max(195), min_max(211)],
        bytes,
        sha256,
    }];
    Ok(TpuReport {
        kinescan_version: env!("CARGO_PKG_VERSION").into(),
        command: "tpu".into(),
        files,
        cloud: CloudReport {
            file: cloud_record,
            las_version: format!("{}.{}", input.version.0, input.version.1),
            point_format: input.point_format,
            record_len: (input.record_len, layout.record_len),
            gps_time: match convention {
                GpsTimeConvention::WeekSeconds => "week_seconds".into(),
                GpsTimeConvention::AdjustedStandard { gps_week } => {
                    format!("adjusted_standard (GPS week {gps_week})")
                }
            },
            crs_source,
            replaced_dimensions: layout.replaced.clone(),
            added_dimensions: schema.dims().iter().map(|d| d.name.clone()).collect(),
        },
        overrides: p.overrides.clone(),
        parameters: c.clone(),
        scanner: scanner.name().into(),
        frame: frame.to_string(),
        epsg: frame.epsg(),
        trajectory_span_s: traj.span_s(),
        fit: (totals.with_sigma > 0).then_some(fit),
        points_per_second: totals.read as f64 / process_s.max(1e-9),
        totals,
        outputs,
        threads,
        stages,
        peak_rss_bytes: crate::pipeline::report::peak_rss_bytes(),
    })
}

/// The trajectory and the cloud opened and checked (time, CRS, times against the SBET).
pub struct Opened {
    /// Trajectory with its SMRMSG.
    pub traj: Trajectory,
    /// The cloud (LAZ: its decompressed copy, errors naming the LAZ).
    pub input: LasInput,
    /// Offset of GPS time in a record.
    pub time_at: usize,
    /// Stored time convention.
    pub convention: GpsTimeConvention,
    /// The cloud's map frame.
    pub frame: crate::geo::projection::MapFrame,
    /// Where the frame came from.
    pub crs_source: String,
}

impl Opened {
    /// Opens the pipeline's trajectory and `cloud` (a LAZ decompressed to `scratch`).
    pub fn open(p: &LoadedTpuPipeline, cloud: &Path, scratch: &Path) -> Result<Opened> {
        let c = &p.config;
        let traj = Trajectory::open(
            &c.inputs.sbet,
            c.inputs.smrmsg.as_deref(),
            c.trajectory.options(),
        )?;
        let input = cloud::open(cloud, scratch)?;
        let time_at = input.time_offset()?;
        let convention = input.time_convention(c.inputs.gps_week)?;
        let (frame, crs_source) = cloud::frame_of(&input, &c.output.frame, &traj)?;
        cloud::check_times(&input, time_at, convention, &traj)?;
        Ok(Opened {
            traj,
            input,
            time_at,
            convention,
            frame,
            crs_source,
        })
    }

    /// The per-point recovery with the pipeline's sensor, latencies and time model.
    pub fn recoverer<'a>(
        &'a self,
        p: &LoadedTpuPipeline,
        scanner: &'a dyn scanner::ScannerGeometry,
    ) -> Recoverer<'a> {
        let c = &p.config;
        Recoverer {
            traj: &self.traj,
            sensor: c.sensor.sensor(),
            scanner,
            frame: self.frame,
            time: self.convention,
            clock: ClockPartials::of(c.time.as_ref(), c.sensor.encoder_offset_deg),
            attitude_latency_s: c.latency.attitude_s,
            position_latency_s: c.latency.position_s,
            range_limits_m: (c.sensor.min_range_m, c.sensor.max_range_m),
        }
    }
}

/// One point as `tpu` sees it (for tests, the docs' worked example and diagnosis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inspected {
    /// What was recovered.
    pub recovered: recover::Recovered,
    /// Its propagated variances along the cloud's axes.
    pub variances: crate::uncertainty::propagate::AxisVariances,
}

/// The points `range` of `cloud` recovered and propagated as `tpu` does, without writing
/// anything (a LAZ is decompressed to a temporary folder).
pub fn inspect(
    p: &LoadedTpuPipeline,
    cloud: &Path,
    range: std::ops::Range<usize>,
) -> Result<Vec<std::result::Result<Inspected, PointReject>>> {
    let c = &p.config;
    let u = c.uncertainty.as_ref().expect("checked on load");
    let scratch = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let opened = Opened::open(p, cloud, &scratch.path().join("cloud.las"))?;
    let sensor = c.sensor.sensor();
    let scanner = scanner::scanner_of(&c.tpu, sensor.alpha0_rad);
    let recoverer = opened.recoverer(p, scanner.as_ref());
    let propagator = propagator_of(u, &sensor, scanner.as_ref());
    let mut cursors = recoverer
        .cursors()
        .ok_or_else(|| Error::Invalid("tpu needs inputs.smrmsg".into()))?;
    let input = &opened.input;
    let end = range.end.min(input.point_count as usize);
    Ok((range.start..end)
        .map(|i| {
            let rec = input.record(i);
            let xyz = input.xyz(rec);
            let t = input.stored_time(rec, opened.time_at);
            let x_map = Vector3::new(xyz[0], xyz[1], xyz[2]);
            recoverer
                .recover(&x_map, t, &mut cursors)
                .map(|(inputs, recovered)| Inspected {
                    recovered,
                    variances: if propagator.with_groups() {
                        propagator.variances_of::<true>(&inputs)
                    } else {
                        propagator.variances_of::<false>(&inputs)
                    },
                })
        })
        .collect())
}

/// `run`'s propagator for the sensor, in the scanner kind's beam frame.
fn propagator_of(
    u: &crate::pipeline::config::UncertaintyConfig,
    sensor: &crate::georef::Sensor,
    scanner: &dyn scanner::ScannerGeometry,
) -> Propagator {
    let p = Propagator::new(
        u.inputs(),
        u.write_shares,
        sensor.lever_arm_b_m,
        sensor.r_s_to_b,
    );
    match scanner.beam_axes() {
        Some(q) => p.with_beam_axes(&q),
        None => p,
    }
}

/// LAZ and COPC output compress the LAS copy (`io::laz`, `io::copc`), which needs LAS 1.4
/// point formats 6 to 8 without EVLRs; refused before any work otherwise.
fn check_format(format: OutputFormat, input: &LasInput, pipeline: &Path) -> Result<()> {
    if format == OutputFormat::Las {
        return Ok(());
    }
    let ok = input.version == (1, 4) && (6..=8).contains(&input.point_format);
    if ok && input.evlrs.is_empty() && input.header_size == 375 {
        return Ok(());
    }
    Err(Error::config(
        pipeline.display().to_string(),
        "output.format",
        format!(
            "{} output needs a LAS 1.4 cloud of point format 6 to 8 without EVLRs; {} is LAS \
             {}.{} format {}{}: use format = \"las\"",
            format.extension(),
            input.path().display(),
            input.version.0,
            input.version.1,
            input.point_format,
            if input.evlrs.is_empty() {
                ""
            } else {
                " with EVLRs"
            }
        ),
    ))
}

/// The LAS at `las` in `format` (beside it), the LAS removed when compressed.
fn into_format(format: OutputFormat, las: &Path) -> Result<PathBuf> {
    if format == OutputFormat::Las {
        return Ok(las.to_path_buf());
    }
    let out = las.with_extension(format.extension());
    match format {
        OutputFormat::Copc => {
            crate::io::copc::write_copc(las, &out, crate::io::copc::LEAF_POINTS)?;
        }
        _ => {
            crate::io::laz::compress_las(las, &out)?;
        }
    }
    std::fs::remove_file(las).map_err(|e| Error::io(las, e))?;
    Ok(out)
}

/// The per-point work over the whole cloud.
struct Job<'a> {
    input: &'a LasInput,
    layout: &'a OutputLayout,
    recoverer: &'a Recoverer<'a>,
    propagator: &'a Propagator,
    fill: &'a PointFill,
    time_at: usize,
    strictness: Strictness,
}

/// One chunk's output.
struct ChunkOut {
    bytes: Vec<u8>,
    counts: PointCounts,
    fit: FitSummary,
}

impl Job<'_> {
    /// Processes every point, writing the copy to `path` in order.
    fn run(
        &self,
        path: &Path,
        opts: &TpuOptions,
        threads: usize,
    ) -> Result<(PointCounts, FitSummary)> {
        let n = self.input.point_count as usize;
        let chunk = opts.chunk_points.max(BATCH_RETURNS);
        let mut file: AtomicFile = AtomicFile::with_capacity(path, 1 << 20)?;
        file.write_all(&self.layout.prefix)?;
        let bar = if opts.progress {
            crate::progress::bar(n as u64, "propagating uncertainty")
        } else {
            indicatif::ProgressBar::hidden()
        };
        let mut totals = PointCounts::default();
        let mut fit = FitSummary::default();
        let per_round = chunk * threads * 4;
        let mut start = 0;
        while start < n {
            let end = (start + per_round).min(n);
            let ranges: Vec<(usize, usize)> = (start..end)
                .step_by(chunk)
                .map(|a| (a, (a + chunk).min(end)))
                .collect();
            let outs: Vec<ChunkOut> = ranges
                .par_iter()
                .map(|&(a, b)| self.chunk(a, b))
                .collect::<Result<_>>()?;
            for o in &outs {
                file.write_all(&o.bytes)?;
                totals.merge(&o.counts);
                fit.merge(&o.fit);
            }
            self.input.release(start..end);
            bar.inc((end - start) as u64);
            crate::interrupt::check()?;
            start = end;
        }
        bar.finish_and_clear();
        let b = self.input.bytes();
        file.write_all(&b[self.layout.tail_from.min(b.len())..])?;
        file.commit()?;
        Ok((totals, fit))
    }

    /// Points `a..b`.
    fn chunk(&self, a: usize, b: usize) -> Result<ChunkOut> {
        let out_len = self.layout.record_len;
        let mut bytes = vec![0u8; (b - a) * out_len];
        let mut counts = PointCounts {
            read: (b - a) as u64,
            ..Default::default()
        };
        let mut fit = FitSummary::default();
        let mut cursors = self
            .recoverer
            .cursors()
            .ok_or_else(|| Error::Invalid("tpu needs inputs.smrmsg".into()))?;
        let mut batch = VarianceBatch::default();
        let mut held: Vec<usize> = Vec::with_capacity(BATCH_RETURNS);
        let mut scratch = LasPoint::default();
        let nan = f64::NAN;
        let mut i = a;
        while i < b {
            batch.clear();
            held.clear();
            let stop = (i + BATCH_RETURNS).min(b);
            for k in i..stop {
                let rec = self.input.record(k);
                let out = &mut bytes[(k - a) * out_len..(k - a + 1) * out_len];
                self.layout.copy_kept(rec, out);
                let xyz = self.input.xyz(rec);
                let x_map = Vector3::new(xyz[0], xyz[1], xyz[2]);
                let t = self.input.stored_time(rec, self.time_at);
                match self.recoverer.recover(&x_map, t, &mut cursors) {
                    Ok((inputs, r)) => {
                        batch.push(&inputs);
                        held.push(k);
                        fit.add(
                            r.range_m,
                            crate::geo::rotations::wrap_pi(r.beta_rad).to_degrees(),
                            r.alpha_rad.to_degrees(),
                            r.off_cone_m,
                        );
                    }
                    Err(reason) => {
                        if self.strictness == Strictness::Fail {
                            return Err(reject_error(self.input.path(), k, reason));
                        }
                        counts.reject(reason, k as u64);
                        for (dim, at) in &self.layout.added {
                            encode_extra(dim.data_type, nan, &mut out[*at..]);
                        }
                    }
                }
            }
            batch.propagate(self.propagator);
            for (j, &k) in held.iter().enumerate() {
                let var = batch.variances(j);
                self.fill.uncertainty(&var, &mut scratch);
                let out = &mut bytes[(k - a) * out_len..(k - a + 1) * out_len];
                for (slot, (dim, at)) in self.layout.added.iter().enumerate() {
                    encode_extra(dim.data_type, scratch.extra[slot], &mut out[*at..]);
                }
            }
            counts.with_sigma += held.len() as u64;
            i = stop;
        }
        Ok(ChunkOut { bytes, counts, fit })
    }
}

/// The error of a rejected point under `output.strictness = "fail"`.
fn reject_error(path: &Path, index: usize, reason: PointReject) -> Error {
    Error::bad_record(
        path,
        format!("point {index}"),
        format!(
            "{} (output.strictness = \"fail\"; \"count\" writes NaN sigmas for such points and \
             counts them in the report)",
            reason.describe()
        ),
    )
}
