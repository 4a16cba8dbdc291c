//! The pipeline's `sync` stage: runs [`super::estimate`] on each profile file with the
//! `[sync]` options, before georeferencing; its clock (and latency, when estimated and
//! constrained) replaces `[time]` / `[latency]` for that file.

use super::{estimate, SyncOptions, SyncResult, SyncTarget};
use crate::io::patches::read_patches;
use crate::io::points::read_control_points;
use crate::io::profiles::ProfileFile;
use crate::pipeline::config::PipelineConfig;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What the sync stage did for one profile file (goes in the run report).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SyncStageReport {
    /// Profile file synchronised.
    pub profiles: PathBuf,
    /// The estimate, its sigmas, every sighting and the hardware comparison.
    pub result: SyncResult,
    /// Diagnostic PNGs written.
    pub plots: Vec<PathBuf>,
}

/// Synchronises every profile file when `[sync]` is present (else nothing); plots go to
/// `plot_dir` named after `plot_stem` and the file's index.
pub fn run(
    c: &PipelineConfig,
    traj: &Trajectory,
    files: &[(PathBuf, ProfileFile)],
    plot_dir: &Path,
    plot_stem: &str,
) -> Result<Vec<SyncStageReport>> {
    let Some(sy) = &c.sync else {
        return Ok(Vec::new());
    };
    let points = read_control_points(&sy.points)?;
    let patches = sy.targets.as_deref().map(read_patches).transpose()?;
    let targets = SyncTarget::from_surveys(&points, patches.as_deref().unwrap_or(&[]));
    let s = &c.sensor;
    let sensor = s.sensor();
    let mirror = c.time.mirror(s.encoder_offset_deg);
    let t0 = sy.t0_approx_s.or(c.time.t0_s).ok_or_else(|| {
        Error::config(
            "pipeline",
            "sync.t0_approx_s",
            "an approximate t0 is needed",
        )
    })?;
    let mut o = SyncOptions::new(t0, sy.period_approx_s.unwrap_or(c.time.period_s), mirror);
    o.window_s = sy.window_s;
    o.method = sy.method;
    o.estimate_latency = sy.estimate_latency;
    o.attitude_latency_s = c.latency.attitude_s;
    o.min_intensity = sy.min_intensity;
    o.max_range_m = sy.max_range_m.min(s.max_range_m);
    o.sigma_range_m = sy.sigma_range_m;
    o.sigma_angle_rad = sy.sigma_angle_deg.to_radians();
    o.min_span_s = sy.min_span_s;
    files
        .iter()
        .enumerate()
        .map(|(k, (original, file))| {
            let result = estimate(traj, &sensor, file, &targets, &o)
                .map_err(|e| Error::Invalid(format!("sync of {}: {e}", original.display())))?;
            let plots = if sy.plots {
                super::plots::write_plots(&result, plot_dir, &format!("{plot_stem}_sync{k}"))?
            } else {
                Vec::new()
            };
            Ok(SyncStageReport {
                profiles: original.clone(),
                result,
                plots,
            })
        })
        .collect()
}
