//! The `kinescan tpu` report (JSON beside the output, like `run`'s): what was read, every
//! parameter, the cloud's frame and time, what happened to every point (read = with sigma +
//! rejected by reason, the first points of each reason named), the recovered geometry's
//! ranges, the extra dimensions replaced, the output, timings.

use super::recover::PointReject;
use crate::io::atomic::write_json;
use crate::io::digest::FileRecord;
use crate::pipeline::config::TpuPipelineConfig;
use crate::pipeline::report::{OutputReport, StageTiming};
use crate::Result;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Points named per rejection reason.
pub const EXAMPLES_PER_REASON: usize = 10;

/// Counts of points by fate.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PointCounts {
    /// Points read.
    pub read: u64,
    /// Points given a sigma.
    pub with_sigma: u64,
    /// Points given no sigma (their uncertainty dimensions are NaN), by reason.
    pub rejected: BTreeMap<PointReject, u64>,
    /// The first points (0-based record index) of each reason.
    pub rejected_examples: BTreeMap<PointReject, Vec<u64>>,
}

impl PointCounts {
    /// Counts a rejection of point `index`.
    pub fn reject(&mut self, reason: PointReject, index: u64) {
        *self.rejected.entry(reason).or_default() += 1;
        let ex = self.rejected_examples.entry(reason).or_default();
        if ex.len() < EXAMPLES_PER_REASON {
            ex.push(index);
        }
    }

    /// Adds `other` (a later chunk: its examples come after this one's).
    pub fn merge(&mut self, other: &PointCounts) {
        self.read += other.read;
        self.with_sigma += other.with_sigma;
        for (k, v) in &other.rejected {
            *self.rejected.entry(*k).or_default() += v;
        }
        for (k, v) in &other.rejected_examples {
            let ex = self.rejected_examples.entry(*k).or_default();
            let room = EXAMPLES_PER_REASON.saturating_sub(ex.len());
            ex.extend(v.iter().take(room));
        }
    }

    /// Total rejected.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }
}

/// Extent of the recovered geometry over the points given a sigma.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitSummary {
    /// Recovered range min, max (m).
    pub range_m: (f64, f64),
    /// Recovered mirror angle min, max (deg, wrapped to (-180, 180]).
    pub mirror_angle_deg: (f64, f64),
    /// Recovered out-of-plane angle min, max (deg).
    pub alpha_deg: (f64, f64),
    /// Largest distance from the beam cone (m).
    pub max_off_cone_m: f64,
}

impl Default for FitSummary {
    fn default() -> Self {
        let empty = (f64::INFINITY, f64::NEG_INFINITY);
        FitSummary {
            range_m: empty,
            mirror_angle_deg: empty,
            alpha_deg: empty,
            max_off_cone_m: 0.0,
        }
    }
}

fn widen(r: &mut (f64, f64), v: f64) {
    r.0 = r.0.min(v);
    r.1 = r.1.max(v);
}

impl FitSummary {
    /// Adds a point.
    #[inline]
    pub fn add(&mut self, range_m: f64, beta_deg: f64, alpha_deg: f64, off_cone_m: f64) {
        widen(&mut self.range_m, range_m);
        widen(&mut self.mirror_angle_deg, beta_deg);
        widen(&mut self.alpha_deg, alpha_deg);
        self.max_off_cone_m = self.max_off_cone_m.max(off_cone_m);
    }

    /// Adds `other`.
    pub fn merge(&mut self, o: &FitSummary) {
        for (a, b) in [
            (&mut self.range_m, o.range_m),
            (&mut self.mirror_angle_deg, o.mirror_angle_deg),
            (&mut self.alpha_deg, o.alpha_deg),
        ] {
            widen(a, b.0);
            widen(a, b.1);
        }
        self.max_off_cone_m = self.max_off_cone_m.max(o.max_off_cone_m);
    }
}

/// The cloud as read.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CloudReport {
    /// The file (LAS or LAZ).
    pub file: FileRecord,
    /// LAS version.
    pub las_version: String,
    /// Point data record format.
    pub point_format: u8,
    /// Bytes per record as read, and as written.
    pub record_len: (usize, usize),
    /// `week_seconds` or `adjusted_standard` (with the GPS week used).
    pub gps_time: String,
    /// The CRS as found (`WKT` or `GeoTIFF key <id>: EPSG:<code>`).
    pub crs_source: String,
    /// Extra dimensions of the cloud with our names, replaced by ours.
    pub replaced_dimensions: Vec<String>,
    /// Extra dimensions appended.
    pub added_dimensions: Vec<String>,
}

/// The whole `tpu` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TpuReport {
    /// kinescan version.
    pub kinescan_version: String,
    /// The command.
    pub command: String,
    /// Pipeline, trajectory and accuracy files.
    pub files: Vec<FileRecord>,
    /// The cloud.
    pub cloud: CloudReport,
    /// `--set` overrides applied, as given.
    pub overrides: Vec<String>,
    /// Every parameter used.
    pub parameters: TpuPipelineConfig,
    /// The scanner kind.
    pub scanner: String,
    /// The cloud's frame, in words.
    pub frame: String,
    /// Its EPSG code, if any.
    pub epsg: Option<u32>,
    /// Trajectory span (s of week).
    pub trajectory_span_s: (f64, f64),
    /// Points by fate.
    pub totals: PointCounts,
    /// Recovered geometry of the points given a sigma.
    pub fit: Option<FitSummary>,
    /// Files written.
    pub outputs: Vec<OutputReport>,
    /// Threads used.
    pub threads: usize,
    /// Stage wall times.
    pub stages: Vec<StageTiming>,
    /// Points per second over the recover-and-write stage.
    pub points_per_second: f64,
    /// Peak resident memory (bytes; Linux `VmHWM`), when known.
    pub peak_rss_bytes: Option<u64>,
}

impl TpuReport {
    /// Writes the report as pretty JSON, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_json(path, self)
    }

    /// The final path of a staged output.
    pub fn output_paths(&self) -> Vec<PathBuf> {
        self.outputs.iter().map(|o| o.path.clone()).collect()
    }
}
