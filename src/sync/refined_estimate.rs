//! The refined estimate (method `refined`): every return on the targets' surveyed faces, with
//! the attitude latency when it is constrained; the Cramer-Rao bound of that model.

use super::options::{SyncOptions, SyncTarget};
use super::refined::{self, Model, Plane, SightingData};
use super::result::{ClockEstimate, RefinedEstimate, Sighting, SightingStatus, SyncResult};
use crate::georef::Sensor;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use nalgebra::{DVector, Matrix2};

/// The refined estimate from the accepted sightings of targets with a surveyed face normal;
/// records in each sighting the returns it used. Two passes: from the paper's clock with
/// returns far from their sighting's median dropped, then, at that solution (accurate to
/// millimetres along the route), also without returns near the face's edges.
pub(super) fn refine(
    traj: &Trajectory,
    sensor: &Sensor,
    targets: &[SyncTarget],
    sightings: &mut [Sighting],
    paper: &ClockEstimate,
    o: &SyncOptions,
) -> Result<RefinedEstimate> {
    let model = model(traj, sensor, o);
    let theta = DVector::from_vec(vec![paper.t0_s - o.t0_approx_s, paper.period_s]);
    let first = refined_data(&model, &theta, targets, sightings, false)?;
    if first.is_empty() {
        return Err(Error::Numerical {
            what: "sync refined estimator".into(),
            problem: "no accepted sighting of a target with a surveyed face normal (give the \
                      targets' planes as patches with the sync points' ids, or use method = \
                      \"paper\")"
                .into(),
        });
    }
    let limit_s = paper.sigma_t0_s.min(o.period_approx_s);
    let view = |d: &[(usize, SightingData)]| d.iter().map(|x| x.1.clone()).collect::<Vec<_>>();
    check_clock_constrained(&model.normal(&theta, &view(&first))?.0, limit_s)?;
    let (theta, _, _) = model.solve(theta, &view(&first))?;
    let used = refined_data(&model, &theta, targets, sightings, true)?;
    for (i, d) in &used {
        sightings[*i].refined_returns = d.0.clone();
    }
    let data = view(&used);
    let mut latency_note = None;
    if o.estimate_latency {
        // Observability first, at the starting point: an unconstrained latency would only
        // make Gauss-Newton wander.
        let with_tau = DVector::from_vec(vec![theta[0], theta[1], o.attitude_latency_s]);
        let (h, _, _) = model.normal(&with_tau, &data)?;
        let (_, vif) = refined::conditioning(&h);
        let sigma = refined::invert_scaled(&h).map_or(f64::INFINITY, |c| c[(2, 2)].sqrt());
        if sigma <= o.max_latency_sigma_s && vif[2] < 1e4 {
            let (th, _, _) = model.solve(with_tau, &data)?;
            return finish(&model, th, &data, o, None, limit_s);
        }
        latency_note = Some(format!(
            "attitude latency not constrained by these sightings (sigma {sigma:.3e} s > \
             {:.1e} s, or variance inflation {:.1e}): the platform hardly rotates while the \
             targets are scanned; t0 and T are reported with the latency fixed at {} s",
            o.max_latency_sigma_s, vif[2], o.attitude_latency_s
        ));
    }
    let (th, _, _) = model.solve(theta, &data)?;
    finish(&model, th, &data, o, latency_note, limit_s)
}

/// Refuses (t0, T) when the information matrix `h` (t0, T first) leaves them unconstrained:
/// a variance inflation of 1e6 or more, or sigma t0 not below `limit_s` (the paper method's
/// sigma: the target faces then add no timing information of their own, and what is left
/// comes from second-order effects where the linearisation does not hold).
fn check_clock_constrained(h: &nalgebra::DMatrix<f64>, limit_s: f64) -> Result<()> {
    let (_, vif) = refined::conditioning(h);
    let sigma_t0 = refined::invert_scaled(h).map_or(f64::INFINITY, |c| c[(0, 0)].sqrt());
    if vif[..2].iter().all(|v| *v < 1e6) && sigma_t0 < limit_s {
        return Ok(());
    }
    Err(Error::Numerical {
        what: "sync refined estimator".into(),
        problem: format!(
            "t0 and T are not constrained by the target returns (sigma t0 {sigma_t0:.2e} s, \
             not below {limit_s:.2e} s; variance inflation {:.1e}, {:.1e}): are the target \
             faces parallel to the \
             driving direction? Use method = \"paper\" or targets turned towards the route",
            vif[0], vif[1]
        ),
    })
}

fn model<'a>(traj: &'a Trajectory, sensor: &'a Sensor, o: &SyncOptions) -> Model<'a> {
    Model {
        traj,
        sensor,
        mirror: o.mirror,
        t_ref_s: o.t0_approx_s,
        sigma_range_m: o.sigma_range_m,
        sigma_angle_rad: o.sigma_angle_rad,
        tau_fixed_s: o.attitude_latency_s,
    }
}

/// The front-face returns of the accepted sightings of targets with a face normal, judged
/// at `theta`, with their sighting's index; `edges`: also drop returns near the face's edges.
fn refined_data(
    model: &Model,
    theta: &DVector<f64>,
    targets: &[SyncTarget],
    sightings: &[Sighting],
    edges: bool,
) -> Result<Vec<(usize, SightingData)>> {
    let mut out = Vec::new();
    for (i, s) in sightings.iter().enumerate() {
        let Some(plane) = plane_of(targets, s, edges) else {
            continue;
        };
        let kept = model.front_face(theta, &s.returns, &plane)?;
        if !kept.is_empty() {
            out.push((i, (kept, plane)));
        }
    }
    Ok(out)
}

/// The surveyed plane of an accepted sighting's target, if it has a face normal.
fn plane_of(targets: &[SyncTarget], s: &Sighting, edges: bool) -> Option<Plane> {
    if s.status != SightingStatus::Accepted {
        return None;
    }
    let t = targets.iter().find(|t| t.id == s.target)?;
    Some(Plane {
        c_e: t.centre_e_m,
        n_e: t.normal_e?,
        sigma_m: t.sigma_m,
        half_size_m: if edges { t.half_size_m } else { None },
    })
}

fn finish(
    model: &Model,
    th: DVector<f64>,
    data: &[SightingData],
    o: &SyncOptions,
    latency_note: Option<String>,
    limit_s: f64,
) -> Result<RefinedEstimate> {
    let (h, _, chi2) = model.normal(&th, data)?;
    let cov = refined::invert_scaled(&h)?;
    let (cond, vif) = refined::conditioning(&h);
    let p = th.len();
    let names = ["t0", "period", "attitude_latency"][..p]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let correlation = (0..p)
        .map(|i| {
            (0..p)
                .map(|j| cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt())
                .collect()
        })
        .collect();
    let returns_used: usize = data.iter().map(|d| d.0.len()).sum();
    let c2 = Matrix2::new(cov[(0, 0)], cov[(0, 1)], cov[(1, 0)], cov[(1, 1)]);
    check_clock_constrained(&h, limit_s)?;
    let dof = returns_used.saturating_sub(p);
    Ok(RefinedEstimate {
        clock: ClockEstimate::new(o.t0_approx_s + th[0], th[1], &c2, chi2, dof),
        attitude_latency_s: (p > 2).then(|| th[2]),
        sigma_attitude_latency_s: (p > 2).then(|| cov[(2, 2)].sqrt()),
        latency_note,
        parameters: names,
        correlation,
        condition_number: cond,
        variance_inflation: vif,
        returns_used,
    })
}

/// Cramer-Rao bound of the refined measurement model at a given clock `(t0_s, period_s)`
/// (and latency, which is then a parameter): the inverse information `(sum J' C^-1 J)^-1`
/// over the returns the refined estimator of `result` used, parameters (t0, T[, tau]). For
/// tests against truth.
pub fn cramer_rao_bound(
    traj: &Trajectory,
    sensor: &Sensor,
    targets: &[SyncTarget],
    result: &SyncResult,
    o: &SyncOptions,
    (t0_s, period_s): (f64, f64),
    attitude_latency_s: Option<f64>,
) -> Result<nalgebra::DMatrix<f64>> {
    let model = model(traj, sensor, o);
    let data: Vec<SightingData> = result
        .sightings
        .iter()
        .filter(|s| !s.refined_returns.is_empty())
        .filter_map(|s| Some((s.refined_returns.clone(), plane_of(targets, s, true)?)))
        .collect();
    let mut v = vec![t0_s - o.t0_approx_s, period_s];
    v.extend(attitude_latency_s);
    let (h, _, _) = model.normal(&DVector::from_vec(v), &data)?;
    refined::invert_scaled(&h)
}
