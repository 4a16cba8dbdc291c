//! Stage 3, **sync**: the clock of every input, resolved before anything is built from it.
//!
//! Without `[sync]` every input gets the `[time]` and `[latency]` values of the pipeline file
//! (and the `[uncertainty]` clock covariance). With `[sync]`, the sync library
//! ([`crate::sync::estimate`]) is run on each profile file; its clock (and latency, when
//! estimated and constrained) and their covariances replace the configured ones for that file
//! (docs/sync.md).

use super::config::PipelineConfig;
use super::prepare::Prepared;
use crate::io::patches::read_patches;
use crate::io::points::read_control_points;
use crate::sync::{estimate, SyncOptions, SyncResult, SyncTarget};
use crate::timing::{ReturnClock, ScannerClock};
use crate::{Error, Result};
use nalgebra::Matrix2;
use serde::Serialize;
use std::path::PathBuf;

/// The clock of one input, as georeferencing uses it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedClock {
    /// Time model and clock parameters (t0, T, mirror).
    pub clock: ReturnClock,
    /// Attitude latency tau (s): attitude at `t + tau`.
    pub attitude_latency_s: f64,
    /// Position latency (s): position at `t + position_latency_s`.
    pub position_latency_s: f64,
    /// Covariance of (t0, T) (s^2), for the uncertainty's timing term.
    pub clock_covariance_s2: Matrix2<f64>,
    /// 1-sigma of tau (s), for the uncertainty's timing term.
    pub sigma_attitude_latency_s: f64,
}

impl ResolvedClock {
    /// The clock as configured in `[time]`, `[latency]` and `[uncertainty]` (zero covariances
    /// without `[uncertainty]`).
    pub fn configured(c: &PipelineConfig) -> Self {
        let t = &c.time;
        let clock = ScannerClock {
            t0_s: t.t0_s.unwrap_or(0.0),
            period_s: t.period_s,
            mirror: t.mirror(c.sensor.encoder_offset_deg),
        };
        let (cov, sigma_tau) = c.uncertainty.as_ref().map_or((Matrix2::zeros(), 0.0), |u| {
            let i = u.inputs();
            (i.clock_covariance_s2, i.sigma_attitude_latency_s)
        });
        ResolvedClock {
            clock: ReturnClock {
                model: t.model,
                clock,
            },
            attitude_latency_s: c.latency.attitude_s,
            position_latency_s: c.latency.position_s,
            clock_covariance_s2: cov,
            sigma_attitude_latency_s: sigma_tau,
        }
    }

    /// This clock with a synchronisation's estimate: t0, T and their covariance; the attitude
    /// latency and its sigma when both were estimated.
    pub fn synchronised(mut self, s: &SyncResult) -> Self {
        self.clock.clock.t0_s = s.clock.t0_s;
        self.clock.clock.period_s = s.clock.period_s;
        self.clock_covariance_s2 = Matrix2::from(s.clock.cov_t0_period);
        if let Some((tau, sigma)) = s.attitude_latency_s.zip(s.sigma_attitude_latency_s) {
            self.attitude_latency_s = tau;
            self.sigma_attitude_latency_s = sigma;
        }
        self
    }
}

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

/// The sync stage's output: one clock per input, in input order, and the reports.
#[derive(Debug, Clone)]
pub struct Synced {
    /// The clock of input `k`.
    pub clocks: Vec<ResolvedClock>,
    /// Per input, when `[sync]` is present (else empty).
    pub reports: Vec<SyncStageReport>,
}

/// Resolves the clock of every prepared input; with `[sync]`, estimates it (plots go beside
/// the LAS output, named after its stem and the input's index).
pub fn run(c: &PipelineConfig, prepared: &Prepared) -> Result<Synced> {
    let configured = ResolvedClock::configured(c);
    let Some(sy) = &c.sync else {
        return Ok(Synced {
            clocks: vec![configured; prepared.inputs.len()],
            reports: Vec::new(),
        });
    };
    let points = read_control_points(&sy.points)?;
    let patches = sy.targets.as_deref().map(read_patches).transpose()?;
    let targets = SyncTarget::from_surveys(&points, patches.as_deref().unwrap_or(&[]));
    let o = options(c)?;
    let sensor = c.sensor.sensor();
    let plot_stem = c
        .output
        .las
        .file_stem()
        .unwrap_or_default()
        .to_string_lossy();
    let mut synced = Synced {
        clocks: Vec::new(),
        reports: Vec::new(),
    };
    for (k, input) in prepared.inputs.iter().enumerate() {
        let original = &input.original;
        let result = estimate(&prepared.traj, &sensor, &input.file, &targets, &o)
            .map_err(|e| Error::Invalid(format!("sync of {}: {e}", original.display())))?;
        let plots = if sy.plots {
            let stem = format!("{plot_stem}_sync{k}");
            crate::sync::plots::write_plots(&result, &prepared.out_dir, &stem)?
        } else {
            Vec::new()
        };
        synced.clocks.push(configured.synchronised(&result));
        synced.reports.push(SyncStageReport {
            profiles: original.clone(),
            result,
            plots,
        });
    }
    Ok(synced)
}

/// The sync library's options from `[sync]`, `[time]`, `[latency]` and `[sensor]`.
fn options(c: &PipelineConfig) -> Result<SyncOptions> {
    let sy = c.sync.as_ref().expect("called with [sync]");
    let t0 = sy.t0_approx_s.or(c.time.t0_s).ok_or_else(|| {
        Error::config(
            "pipeline",
            "sync.t0_approx_s",
            "an approximate t0 is needed",
        )
    })?;
    let period = sy.period_approx_s.unwrap_or(c.time.period_s);
    let mut o = SyncOptions::new(t0, period, c.time.mirror(c.sensor.encoder_offset_deg));
    o.window_s = sy.window_s;
    o.method = sy.method;
    o.estimate_latency = sy.estimate_latency;
    o.attitude_latency_s = c.latency.attitude_s;
    o.min_intensity = sy.min_intensity;
    o.max_range_m = sy.max_range_m.min(c.sensor.max_range_m);
    o.sigma_range_m = sy.sigma_range_m;
    o.sigma_angle_rad = sy.sigma_angle_deg.to_radians();
    o.min_span_s = sy.min_span_s;
    Ok(o)
}

/// Reads the sync points and targets (for `kinescan validate`).
pub fn check_inputs(c: &PipelineConfig) -> Result<()> {
    if let Some(sync) = &c.sync {
        read_control_points(&sync.points)?;
        if let Some(t) = &sync.targets {
            read_patches(t)?;
        }
    }
    Ok(())
}
