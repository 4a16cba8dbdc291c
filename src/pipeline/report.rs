//! Stage 6, **report**: the JSON run report, what was read (sizes, hashes), every parameter
//! used, what happened to every return (read = written + rejected by reason), time spans and
//! stage timings. Written to `OutputConfig::report_path`.

use super::config::PipelineConfig;
pub use super::sync::SyncStageReport;
use crate::io::atomic::write_json;
pub use crate::io::digest::{hex, FileRecord};
use crate::Result;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a return was not written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RejectReason {
    /// Range 0 or empty: the scanner recorded no echo (conventions §6).
    MissingReturn,
    /// A non-finite angle, range or time tag.
    NonFinite,
    /// Range outside `[sensor.min_range_m, sensor.max_range_m]`.
    RangeOutOfLimits,
    /// Return time before the first or after the last trajectory record.
    OutsideTrajectory,
    /// Return time inside a trajectory gap longer than `trajectory.max_gap_s`.
    TrajectoryGap,
    /// Return time outside the SMRMSG span (uncertainty requested).
    OutsideAccuracy,
    /// The geoid grid (`output.geoid`) has no value at the point (a no-data node).
    NoGeoidValue,
}

impl RejectReason {
    /// Every reason, in report order.
    pub const ALL: [RejectReason; 7] = [
        RejectReason::MissingReturn,
        RejectReason::NonFinite,
        RejectReason::RangeOutOfLimits,
        RejectReason::OutsideTrajectory,
        RejectReason::TrajectoryGap,
        RejectReason::OutsideAccuracy,
        RejectReason::NoGeoidValue,
    ];

    /// Position in [`Self::ALL`].
    #[inline]
    pub fn index(self) -> usize {
        self as usize
    }

    /// A sentence for error messages.
    pub fn describe(self) -> &'static str {
        match self {
            RejectReason::MissingReturn => "missing return (range 0)",
            RejectReason::NonFinite => "non-finite angle, range or time tag",
            RejectReason::RangeOutOfLimits => "range outside sensor.min_range_m..max_range_m",
            RejectReason::OutsideTrajectory => "return time outside the trajectory span",
            RejectReason::TrajectoryGap => {
                "return time inside a trajectory gap longer than trajectory.max_gap_s"
            }
            RejectReason::OutsideAccuracy => "return time outside the SMRMSG span",
            RejectReason::NoGeoidValue => "no geoid undulation at the point (output.geoid)",
        }
    }

    /// The key to check first when many returns are rejected for this reason, and what to
    /// check (the run's, the day's and the diagnosis's refusals of a high rejected share).
    pub fn likely_cause(self) -> (&'static str, &'static str) {
        match self {
            RejectReason::OutsideTrajectory | RejectReason::TrajectoryGap => (
                "inputs.sbet",
                "the trajectory does not cover the scanner's times: check the trajectory \
                 file and the clock (time.t0_s, time.period_s)",
            ),
            RejectReason::RangeOutOfLimits => (
                "sensor.max_range_m",
                "check sensor.min_range_m and sensor.max_range_m against the scanner's ranges",
            ),
            RejectReason::OutsideAccuracy => (
                "inputs.smrmsg",
                "the SMRMSG file does not cover the scanner's times",
            ),
            RejectReason::NoGeoidValue => (
                "output.geoid",
                "the geoid grid has no value under the points",
            ),
            RejectReason::MissingReturn | RejectReason::NonFinite => (
                "output.max_rejected_share",
                "check the profile file; raise output.max_rejected_share to accept it",
            ),
        }
    }
}

/// Returns rejected for a reason other than a missing return, in a share above
/// `output.max_rejected_share` (a run, a pass of a day or a diagnosis refuses them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcessRejected {
    /// Returns read.
    pub read: u64,
    /// Share of them rejected for a reason other than a missing return.
    pub share: f64,
    /// The most frequent such reason and its count.
    pub reason: RejectReason,
    /// Returns rejected for `reason`.
    pub count: u64,
}

impl ExcessRejected {
    /// "37.0% of the 1000 returns of WHAT are rejected (more than output.max_rejected_share =
    /// MAX), 370 of them as REASON".
    pub fn describe(&self, what: &str, max: f64) -> String {
        format!(
            "{:.1}% of the {} returns of {what} are rejected (more than \
             output.max_rejected_share = {max}), {} of them as {}",
            self.share * 100.0,
            self.read,
            self.count,
            self.reason.describe()
        )
    }
}

/// Counts of returns by fate.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReturnCounts {
    /// Returns read.
    pub read: u64,
    /// Returns written to LAS.
    pub written: u64,
    /// Returns not written, by reason.
    pub rejected: BTreeMap<RejectReason, u64>,
}

impl ReturnCounts {
    /// Total rejected.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Adds a chunk of `read` returns of which `written` were written and `rejected[k]` were
    /// rejected for reason `RejectReason::ALL[k]`.
    pub fn add_chunk(
        &mut self,
        read: u64,
        written: u64,
        rejected: &[u64; RejectReason::ALL.len()],
    ) {
        for (reason, n) in RejectReason::ALL.iter().zip(rejected) {
            if *n > 0 {
                *self.rejected.entry(*reason).or_default() += n;
            }
        }
        self.read += read;
        self.written += written;
    }

    /// The returns rejected for a reason other than a missing return when their share of
    /// those read is above `max` (`output.max_rejected_share`).
    pub fn excess_rejected(&self, max: f64) -> Option<ExcessRejected> {
        let missing = self
            .rejected
            .get(&RejectReason::MissingReturn)
            .copied()
            .unwrap_or(0);
        let share = (self.rejected_total() - missing) as f64 / self.read.max(1) as f64;
        if share <= max {
            return None;
        }
        let (&reason, &count) = self
            .rejected
            .iter()
            .filter(|(r, _)| **r != RejectReason::MissingReturn)
            .max_by_key(|(_, n)| **n)?;
        Some(ExcessRejected {
            read: self.read,
            share,
            reason,
            count,
        })
    }

    /// Adds `other`.
    pub fn merge(&mut self, other: &ReturnCounts) {
        self.read += other.read;
        self.written += other.written;
        for (k, v) in &other.rejected {
            *self.rejected.entry(*k).or_default() += v;
        }
    }
}

/// One profile file's processing summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InputReport {
    /// The profile file as read.
    pub file: FileRecord,
    /// Point source id given to its points.
    pub point_source_id: u16,
    /// Returns by fate.
    pub counts: ReturnCounts,
    /// First and last profile counter.
    pub profile_range: Option<(u32, u32)>,
    /// Profile counter increments larger than 1 (lost profiles), count.
    pub counter_jumps: u64,
    /// The first few counter jumps: (0-based record, from, to).
    pub counter_jump_examples: Vec<(u64, u32, u32)>,
    /// GPS time span of the georeferenced returns (s of week).
    pub time_span_s: Option<(f64, f64)>,
}

/// A LAS file written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutputReport {
    /// Path.
    pub path: PathBuf,
    /// Points written.
    pub points: u64,
    /// Header bounds min X, Y, Z (m).
    pub min_m: [f64; 3],
    /// Header bounds max X, Y, Z (m).
    pub max_m: [f64; 3],
    /// Size (bytes).
    pub bytes: u64,
    /// SHA-256 of the file, hex: `kinescan info FOLDER` checks the set against it.
    pub sha256: String,
}

/// Wall time of one stage.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageTiming {
    /// Stage name.
    pub stage: String,
    /// Wall time (s).
    pub seconds: f64,
}

/// The whole run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport {
    /// kinescan version.
    pub kinescan_version: String,
    /// Pipeline, trajectory and accuracy files.
    pub files: Vec<FileRecord>,
    /// `--set` overrides applied, as given.
    pub overrides: Vec<String>,
    /// Every parameter used (defaults filled in, paths resolved).
    pub parameters: PipelineConfig,
    /// Mapping frame, in words, and its EPSG code if any.
    pub frame: String,
    /// EPSG code of the output CRS, if any.
    pub epsg: Option<u32>,
    /// The geoid grid's file name when heights are orthometric (`output.geoid`); `None`:
    /// WGS84 ellipsoidal heights.
    pub geoid_grid: Option<String>,
    /// Trajectory span (s of week).
    pub trajectory_span_s: (f64, f64),
    /// Per profile file.
    pub inputs: Vec<InputReport>,
    /// All inputs together.
    pub totals: ReturnCounts,
    /// LAS files written.
    pub outputs: Vec<OutputReport>,
    /// Threads used.
    pub threads: usize,
    /// Stage wall times.
    pub stages: Vec<StageTiming>,
    /// Returns per second over the georeference-and-write stage.
    pub returns_per_second: f64,
    /// Peak resident memory of the process (bytes; Linux `VmHWM`), when known.
    pub peak_rss_bytes: Option<u64>,
    /// Object-space synchronisation, per profile file (when `[sync]` is present).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sync: Vec<SyncStageReport>,
}

/// Peak resident set size of this process (bytes), from `/proc/self/status` on Linux.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

impl RunReport {
    /// Writes the report as pretty JSON, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_json(path, self)
    }
}
