//! The built-in demo: simulate a city block with ground truth, georeference it with the
//! pipeline exactly as a user would, and compare every written point with its true position.

use crate::geo::projection::MapFrame;
use crate::io::atomic::write_atomic;
use crate::pipeline::prepare::map_frame;
use crate::pipeline::report::RunReport;
use crate::pipeline::schema::OutputSchema;
use crate::pipeline::{self, config, RunOptions};
use crate::sim::{self, files, SimOptions};
use crate::trajectory::{Trajectory, TrajectoryOptions};
use crate::{Error, Result};
use nalgebra::Vector3;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The demo scenario (also `pipelines/scenario_city_block.toml`).
pub const SCENARIO: &str = include_str!("../../pipelines/scenario_city_block.toml");
/// The demo pipeline (also `pipelines/demo_city_block.toml`), run beside the `survey` folder.
pub const PIPELINE: &str = include_str!("../../pipelines/demo_city_block.toml");

/// What the demo did and how good the result is.
#[derive(Debug, Clone)]
pub struct DemoSummary {
    /// Simulation wall time (s).
    pub simulate_s: f64,
    /// The pipeline's run report.
    pub report: RunReport,
    /// Run report path.
    pub report_path: PathBuf,
    /// Points compared with the truth.
    pub compared: u64,
    /// 3D error against the truth: RMS, 95th percentile, maximum (m).
    pub error_3d_m: [f64; 3],
    /// Horizontal and vertical RMS error (m).
    pub error_h_v_rms_m: [f64; 2],
    /// RMS of error / predicted sigma along X, Y, Z (1 for an honest uncertainty, up to the
    /// scatter of one drive's correlated navigation errors); None without `sigma_*` fields.
    pub normalised_rms_xyz: Option<[f64; 3]>,
}

/// RMS of error / sigma along X, Y, Z, when the LAS has sigma fields.
type NormalisedRms = Option<[f64; 3]>;

/// Byte offsets (in a record's extra bytes) of the extra dimensions the demo reads.
struct ExtraOffsets {
    return_index: usize,
    sigma_x: Option<usize>,
}

impl ExtraOffsets {
    fn of(schema: &OutputSchema) -> Self {
        let return_index = schema
            .return_index
            .expect("the demo pipeline writes return_index");
        ExtraOffsets {
            return_index: schema.extra_byte_offset(return_index),
            sigma_x: schema
                .uncertainty
                .map(|u| schema.extra_byte_offset(u.sigma_x)),
        }
    }
}

/// Simulates the city block into `out/survey`, runs `out/pipeline.toml` on it and compares.
pub fn run_demo(out: &Path, sim_opts: &SimOptions, run_opts: &RunOptions) -> Result<DemoSummary> {
    claim_folder(out)?;
    let scenario = out.join("scenario_city_block.toml");
    write_atomic(&scenario, SCENARIO.as_bytes())?;
    let started = Instant::now();
    sim::simulate(&scenario, &out.join("survey"), sim_opts)?;
    let simulate_s = started.elapsed().as_secs_f64();
    let pipeline = out.join("pipeline.toml");
    write_atomic(&pipeline, PIPELINE.as_bytes())?;
    let loaded = config::load(&pipeline, &[])?;
    let report = pipeline::run(&loaded, run_opts)?;
    let e = cloud_error(&loaded, &report, &out.join("survey"))?;
    Ok(DemoSummary {
        simulate_s,
        report,
        report_path: loaded.config.output.report_path(),
        compared: e.compared,
        error_3d_m: e.error_3d_m,
        error_h_v_rms_m: e.error_h_v_rms_m,
        normalised_rms_xyz: e.normalised_rms_xyz,
    })
}

/// The error of a simulated survey's cloud against the simulator's true points.
#[derive(Debug, Clone)]
pub struct CloudError {
    /// Points compared.
    pub compared: u64,
    /// 3D error: RMS, 95th percentile, maximum (m).
    pub error_3d_m: [f64; 3],
    /// Horizontal and vertical RMS (m).
    pub error_h_v_rms_m: [f64; 2],
    /// RMS of error / sigma per axis (when the cloud has sigmas).
    pub normalised_rms_xyz: Option<[f64; 3]>,
}

/// Compares the first LAS of a run (`report`) of the pipeline `loaded` (which writes
/// `return_index`) with the true points of the simulation in `survey`.
pub fn cloud_error(
    loaded: &config::LoadedPipeline,
    report: &RunReport,
    survey: &Path,
) -> Result<CloudError> {
    let traj = Trajectory::open(
        &loaded.config.inputs.sbet,
        None,
        TrajectoryOptions::default(),
    )?;
    let frame = map_frame(&loaded.config.output.frame, &traj)?;
    let truth = sim::read_truth_points(&survey.join(files::TRUTH_POINTS))?;
    let las = &report
        .outputs
        .first()
        .ok_or_else(|| Error::Invalid("the run wrote no LAS".into()))?
        .path;
    let offsets = ExtraOffsets::of(&OutputSchema::new(&loaded.config));
    let (errors, normalised) = compare(las, &truth, &frame, &offsets)?;
    Ok(CloudError {
        compared: errors.len() as u64,
        error_3d_m: stats_3d(&errors),
        error_h_v_rms_m: rms_h_v(&errors),
        normalised_rms_xyz: normalised,
    })
}

/// The file that marks a folder as the demo's (written when the demo makes it).
pub const MARKER: &str = ".kinescan-demo";

/// Makes `out` the demo's folder: a new or empty folder gets the [`MARKER`]; a folder that
/// holds anything else without it (a project's `pipeline.toml`, `survey/`...) is refused, as
/// the demo would replace those files.
fn claim_folder(out: &Path) -> Result<()> {
    let mut entries: Vec<String> = match std::fs::read_dir(out) {
        Ok(entries) => entries
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(Error::io(out, e)),
    };
    if !entries.is_empty() && !entries.iter().any(|e| e == MARKER) {
        entries.sort();
        entries.truncate(5);
        return Err(Error::bad_file(
            out,
            format!(
                "not empty ({}...) and not made by `kinescan demo` (no {MARKER} in it): the \
                 demo writes pipeline.toml, scenario_city_block.toml, survey/ and its outputs \
                 there and would replace such files; give `--out` a new or empty folder",
                entries.join(", ")
            ),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    write_atomic(&out.join(MARKER), b"made by kinescan demo\n")
}

/// Map-frame error vectors of every LAS point against the truth of its raw return (found
/// through the `return_index` extra dimension), and the RMS of error / sigma per axis.
fn compare(
    las: &Path,
    truth: &[[f64; 3]],
    frame: &MapFrame,
    at: &ExtraOffsets,
) -> Result<(Vec<Vector3<f64>>, NormalisedRms)> {
    let bad = |e: las::Error| Error::bad_file(las, e.to_string());
    let mut reader = las::Reader::from_path(las).map_err(bad)?;
    let mut errors = Vec::new();
    let mut normalised = Vector3::zeros();
    for p in reader.read_all().map_err(bad)?.points() {
        let p = p.map_err(bad)?;
        let f64_at =
            |o: usize| f64::from_le_bytes(p.extra_bytes[o..o + 8].try_into().expect("8 bytes"));
        let f32_at = |o: usize| {
            f32::from_le_bytes(p.extra_bytes[o..o + 4].try_into().expect("4 bytes")) as f64
        };
        let index = f64_at(at.return_index) as usize;
        let t = truth.get(index).ok_or_else(|| {
            Error::bad_file(las, format!("return_index {index} beyond the truth"))
        })?;
        let e = Vector3::new(p.x, p.y, p.z) - frame.ecef_to_map(&Vector3::from(*t));
        if let Some(o) = at.sigma_x {
            let sigma = Vector3::new(f32_at(o), f32_at(o + 4), f32_at(o + 8));
            normalised += e.component_div(&sigma).map(|v| v * v);
        }
        errors.push(e);
    }
    let n = errors.len().max(1) as f64;
    let normalised = at.sigma_x.map(|_| (normalised / n).map(f64::sqrt).into());
    Ok((errors, normalised))
}

fn stats_3d(errors: &[Vector3<f64>]) -> [f64; 3] {
    let mut norms: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
    norms.sort_by(f64::total_cmp);
    let n = norms.len().max(1) as f64;
    let rms = (norms.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    let p95 = norms
        .get(((norms.len() as f64 * 0.95) as usize).min(norms.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    [rms, p95, norms.last().copied().unwrap_or(0.0)]
}

fn rms_h_v(errors: &[Vector3<f64>]) -> [f64; 2] {
    let n = errors.len().max(1) as f64;
    let h = errors.iter().map(|e| e.x * e.x + e.y * e.y).sum::<f64>() / n;
    let v = errors.iter().map(|e| e.z * e.z).sum::<f64>() / n;
    [h.sqrt(), v.sqrt()]
}

impl fmt::Display for DemoSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = &self.report.totals;
        let run_s: f64 = self.report.stages.iter().map(|s| s.seconds).sum();
        writeln!(
            f,
            "kinescan demo: a one-minute city-block survey, simulated with ground truth"
        )?;
        writeln!(f, "  simulated        {:.1} s", self.simulate_s)?;
        writeln!(f, "  georeferenced    {} returns read, {} written, {} rejected in {:.1} s ({:.1} M returns/s)", t.read, t.written, t.rejected_total(), run_s, self.report.returns_per_second / 1e6)?;
        for (reason, n) in &t.rejected {
            writeln!(f, "    rejected {n:>9}  {}", reason.describe())?;
        }
        let [rms, p95, max] = self.error_3d_m;
        let [h, v] = self.error_h_v_rms_m;
        if let Some([x, y, z]) = self.normalised_rms_xyz {
            writeln!(f, "  error / sigma    RMS {x:.2} (X), {y:.2} (Y), {z:.2} (Z): the per-point sigma_x/y/z against the true errors")?;
        }
        writeln!(f, "  error vs truth   3D RMS {:.1} mm, 95th percentile {:.1} mm, max {:.1} mm (horizontal RMS {:.1} mm, vertical RMS {:.1} mm) over {} points", rms * 1e3, p95 * 1e3, max * 1e3, h * 1e3, v * 1e3, self.compared)?;
        for o in &self.report.outputs {
            writeln!(
                f,
                "  LAS              {} ({} points, {})",
                o.path.display(),
                o.points,
                self.report.frame
            )?;
        }
        write!(f, "  run report       {}", self.report_path.display())
    }
}
