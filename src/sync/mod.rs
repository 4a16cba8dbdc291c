//! Object-space time synchronisation (conventions §2; paper 004, section 3.2): estimates the scanner
//! clock `t = t0 + T (n + f(beta))` from a few surveyed sync targets, so that no timing
//! hardware is needed. Times are GPS seconds, angles radians, positions ECEF metres.
//!
//! Steps of [`estimate`]: (1) plane crossings: when the scan plane sweeps each sync point,
//! from the trajectory (zeros of the orthogonal distance `d_p(t)`); (2) detection: the
//! high-intensity cluster near the profile where the approximate clock puts each crossing;
//! (3) the paper's regression `t_c = t0 + T (n_i + f(beta_i))` with leave-one-out outlier
//! rejection and re-association of clusters with the fitted clock; (4) optionally the refined
//! estimator (`refined`) using every return on the targets' surveyed planes, jointly with
//! the attitude latency when the platform's rotation makes it observable; (5) with hardware
//! (PPS) profile tags, a comparison of both. docs/sync.md gives the method and an example.
//!
//! Modules: `options` (targets, settings), `result`, `sightings` (the paper's method),
//! `refined_estimate` (the refined method, on the `refined` model), `detect`, `geometry`,
//! `paper`, `hardware`, `plots`.

pub(crate) mod detect;
pub(crate) mod geometry;
pub(crate) mod hardware;
mod options;
pub(crate) mod paper;
pub mod plots;
pub(crate) mod refined;
mod refined_estimate;
mod result;
mod sightings;

pub use geometry::TargetReturn;
pub use hardware::HardwareComparison;
pub use options::{Method, SyncOptions, SyncTarget};
pub use refined_estimate::cramer_rao_bound;
pub use result::{ClockEstimate, RefinedEstimate, Sighting, SightingStatus, SyncResult};

use crate::georef::Sensor;
use crate::io::profiles::ProfileFile;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use detect::{Cluster, DetectParams};
use geometry::Crossing;
use nalgebra::Vector3;
use options::check_options;
use refined_estimate::refine;
use sightings::{associate, check_usable, sightings};

/// Estimates the scanner clock from the sync targets seen in `file` (module docs).
pub fn estimate(
    traj: &Trajectory,
    sensor: &Sensor,
    file: &ProfileFile,
    targets: &[SyncTarget],
    o: &SyncOptions,
) -> Result<SyncResult> {
    check_options(o)?;
    if file.is_empty() {
        return Err(Error::bad_file(file.path(), "sync: no returns"));
    }
    let (n_first, n_last) = (file.get(0).profile, file.get(file.len() - 1).profile);
    let (span_a, span_b) = traj.span_s();
    let t_a = (o.t0_approx_s + o.period_approx_s * n_first as f64 - o.window_s).max(span_a);
    let t_b = (o.t0_approx_s + o.period_approx_s * (n_last + 1) as f64 + o.window_s).min(span_b);
    let pts: Vec<(Vector3<f64>, f64)> = targets.iter().map(|t| (t.centre_e_m, t.sigma_m)).collect();
    let step = 0.02;
    let tau = o.attitude_latency_s;
    let crossings = geometry::crossings(
        traj,
        sensor,
        tau,
        &pts,
        t_a,
        t_b - step,
        step,
        o.max_range_m,
    )?;
    let params = DetectParams {
        min_intensity: o.min_intensity,
        window_profiles: o.window_s / o.period_approx_s,
        beta_gate_rad: 20f64.to_radians(),
        cluster_gap_m: o.cluster_gap_m,
        alpha0_rad: sensor.alpha0_rad,
        use_alpha_column: file.columns().alpha,
    };
    let predict =
        |c: &Crossing, t0: f64, period: f64| (c.t_s - t0) / period - o.mirror.fraction(c.beta_rad);
    let cands: Vec<Vec<Cluster>> = crossings
        .iter()
        .map(|c| {
            detect::candidates(
                file,
                c,
                predict(c, o.t0_approx_s, o.period_approx_s),
                &params,
            )
        })
        .collect();
    let t_ref = o.t0_approx_s;
    let (fit, chosen, outliers) = associate(&crossings, &cands, o, t_ref, &predict)?;
    let mut sightings = sightings(
        targets, &crossings, &cands, &chosen, &outliers, &fit, o, t_ref,
    );
    check_usable(&sightings, o)?;
    let dof = sightings
        .iter()
        .filter(|s| s.status == SightingStatus::Accepted)
        .count()
        - 2;
    let paper = ClockEstimate::new(t_ref + fit.x[0], fit.x[1], &fit.cov, fit.chi2, dof);
    let (refined, fallback) = match o.method {
        Method::Paper => (None, None),
        Method::Refined => (
            Some(refine(traj, sensor, targets, &mut sightings, &paper, o)?),
            None,
        ),
        Method::Auto => match refine(traj, sensor, targets, &mut sightings, &paper, o) {
            Ok(r) => (Some(r), None),
            Err(Error::Numerical { problem, .. }) => {
                sightings.iter_mut().for_each(|s| s.refined_returns.clear());
                (None, Some(problem))
            }
            Err(e) => return Err(e),
        },
    };
    let clock = refined.as_ref().map_or(paper, |r| r.clock);
    let hardware = file
        .columns()
        .time
        .then(|| {
            hardware::compare(
                &hardware::profile_tags(file),
                clock.t0_s,
                clock.period_s,
                &clock.cov(),
            )
        })
        .flatten();
    Ok(SyncResult {
        method: if refined.is_some() {
            Method::Refined
        } else {
            Method::Paper
        },
        fallback,
        clock,
        attitude_latency_s: refined.as_ref().and_then(|r| r.attitude_latency_s),
        sigma_attitude_latency_s: refined.as_ref().and_then(|r| r.sigma_attitude_latency_s),
        paper,
        refined,
        sightings,
        hardware,
    })
}
