//! Control points as references (docs/diagnosis.md, "Control points"): the returns of a
//! flat retro-reflective target are found by intensity near its surveyed centre; each pass
//! over it (a visit) gives the centroid of its returns, whose offset from the control point
//! is observed along three axes: the target's normal (fitted to the returns) and two in-face
//! axes, horizontal `h = up x n` and `v = n x h`.
//!
//! Along the normal the centroid is as precise as its returns. In the face it is limited by
//! the sampling: returns fall on a lattice (profile to profile, and along a profile) whose
//! phase against the target's edges is random per visit, so the centroid of the returns on a
//! face of width `W` sampled every `s` is off by `(u1 - u2) s / 2`, `u1`, `u2` the gaps at the
//! two edges in units of `s`; over the phase and over `W / s` its variance is `s^2 / 24`
//! (docs/diagnosis.md gives the derivation and the check on the simulator).

use super::{
    beam_e, covariates, denoised_ranges_m, observation_along, release_visit, visit_nav_cov, Hit,
    PendingVisit, ReturnModel, Surface,
};
use crate::app::diagnose::model::{Covariates, Observation, Visit, N_EFFECTS};
use crate::geo::ellipsoid::{geodetic_to_ecef, r_enu_to_e, Geodetic};
use crate::io::points::ControlPoint;
use crate::io::profiles::{ProfileFile, RawReturn};
use crate::pipeline::config::DiagnoseConfig;
use crate::{Error, Result};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Variance of an in-face centroid per squared sampling step (module doc).
const SAMPLING_VAR_PER_STEP2: f64 = 1.0 / 24.0;

/// The control points in ECEF and how their returns are recognised.
pub(super) struct TargetIndex {
    centres_e: Vec<Vector3<f64>>,
    /// Local up (ECEF unit vector) at each control point.
    up_e: Vec<Vector3<f64>>,
    sigma_m: Vec<f64>,
    radius_m: f64,
    min_intensity: u16,
}

impl TargetIndex {
    pub(super) fn new(points: &[ControlPoint], opts: &DiagnoseConfig) -> Self {
        let geodetic = |p: &ControlPoint| Geodetic {
            lat_rad: p.lat_rad,
            lon_rad: p.lon_rad,
            h_m: p.h_m,
        };
        TargetIndex {
            centres_e: points
                .iter()
                .map(|p| geodetic_to_ecef(geodetic(p)))
                .collect(),
            up_e: points
                .iter()
                .map(|p| r_enu_to_e(p.lat_rad, p.lon_rad).column(2).into_owned())
                .collect(),
            sigma_m: points.iter().map(|p| p.sigma_m).collect(),
            radius_m: opts.target_radius_m,
            min_intensity: opts.target_min_intensity,
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.centres_e.is_empty()
    }

    /// The control point whose target a return at `x_e` of `intensity` is on: at least
    /// `target_min_intensity` bright and within `target_radius_m` (the nearest such).
    pub(super) fn find(&self, x_e: &Vector3<f64>, intensity: u16) -> Option<usize> {
        if intensity < self.min_intensity {
            return None;
        }
        self.centres_e
            .iter()
            .map(|c| (x_e - c).norm())
            .enumerate()
            .filter(|&(_, d)| d <= self.radius_m)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, _)| k)
    }
}

/// An observed target visit: the visit and its one to three centroid observations (normal
/// first).
pub(super) type TargetVisit = (Visit, Vec<Observation>);

/// A located return of a target visit.
struct OnTarget {
    raw: RawReturn,
    loc: super::Located,
    /// Range (m) its Jacobian is evaluated at (set once the face is known).
    range_m: f64,
}

/// Observes one visit of target `pv.patch` (an index into `index`); none when its returns do
/// not lie on one plane within `target_flatness_m` (rms). The observations' and the visit's
/// reference and visit indices are left 0 for the caller to set.
pub(super) fn observe_target(
    model: &ReturnModel,
    file: &ProfileFile,
    index: &TargetIndex,
    pv: &PendingVisit,
    opts: &DiagnoseConfig,
) -> Result<Option<TargetVisit>> {
    let ids = (0, 0, pv.hits[0].index);
    let returns = locate_all(model, file, &pv.hits)?;
    let n = returns.len() as f64;
    let mean = returns.iter().map(|r| r.loc.x_e).sum::<Vector3<f64>>() / n;
    let (normal, flatness) = best_plane(&returns, &mean);
    if flatness > opts.target_flatness_m {
        return Ok(None);
    }
    let mid = &returns[returns.len() / 2];
    let normal = facing_the_scanner(normal, model, mid);
    let (h, v) = face_axes(&normal, &index.up_e[pv.patch]);
    let centre = &index.centres_e[pv.patch];
    let mut returns = returns;
    let pairs = returns.iter().map(|r| (&r.raw, &r.loc));
    let ranges = denoised_ranges_m(pairs, model, &normal, centre);
    for (r, range_m) in returns.iter_mut().zip(ranges) {
        r.range_m = range_m;
    }
    let mid = &returns[returns.len() / 2];
    let t_mean = returns.iter().map(|r| r.loc.t_s).sum::<f64>() / n;
    let nav_cov = visit_nav_cov(model.traj, t_mean, &Matrix3::zeros()).map_err(|reason| {
        Error::Invalid(format!("target visit at {t_mean} s: {}", reason.describe()))
    })?;
    let cov = Covariates {
        time_s: t_mean,
        reference_id: ids.0,
        pass: pv.pass,
        ..covariates(&mid.loc, model, &normal, &mid.raw, mid.range_m)
    };
    let survey_var = index.sigma_m[pv.patch].powi(2);
    let steps = Steps::of(&returns);
    let mut obs = vec![centroid(
        &returns, model, &normal, centre, ids, cov, survey_var,
    )];
    for axis in [h, v] {
        if let Some(s2) = steps.sampling_step2(&returns, &axis) {
            let extra = survey_var + SAMPLING_VAR_PER_STEP2 * s2;
            obs.push(centroid(&returns, model, &axis, centre, ids, cov, extra));
        }
    }
    let visit = Visit {
        reference: ids.0,
        pass: pv.pass,
        nav_cov,
    };
    Ok(Some((visit, obs)))
}

fn locate_all(model: &ReturnModel, file: &ProfileFile, hits: &[Hit]) -> Result<Vec<OnTarget>> {
    let mut cursor = model.cursor();
    let returns = hits
        .iter()
        .map(|h| {
            let (raw, loc) = model.relocate(file, h.index, &mut cursor)?;
            let range_m = raw.range_m;
            Ok(OnTarget { raw, loc, range_m })
        })
        .collect();
    release_visit(file, hits);
    returns
}

/// The unit normal of the least-squares plane through the returns and their rms distance
/// from it (m).
fn best_plane(returns: &[OnTarget], mean: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let scatter = returns
        .iter()
        .map(|r| {
            let d = r.loc.x_e - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / returns.len() as f64;
    let eig = SymmetricEigen::new(scatter);
    let k = eig.eigenvalues.imin();
    let normal = eig.eigenvectors.column(k).into_owned();
    (normal, eig.eigenvalues[k].max(0.0).sqrt())
}

/// `normal` turned towards the scanner (against the beam of `r`).
fn facing_the_scanner(normal: Vector3<f64>, model: &ReturnModel, r: &OnTarget) -> Vector3<f64> {
    if normal.dot(&beam_e(&r.loc, model)) > 0.0 {
        -normal
    } else {
        normal
    }
}

/// In-face axes: horizontal `h = up x n` and `v = n x h`; for a nearly horizontal face `h`
/// is the part of the local east (`z x up`) in the face.
fn face_axes(normal: &Vector3<f64>, up: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let across = up.cross(normal);
    let h = if across.norm() > 0.3 {
        across.normalize()
    } else {
        let east = Vector3::z().cross(up).normalize();
        (east - normal * normal.dot(&east)).normalize()
    };
    (h, normal.cross(&h))
}

/// The sampling lattice of a visit: the step from profile to profile (per profile number)
/// and the steps between neighbouring returns of one profile (ECEF, m).
struct Steps {
    across: Vec<Vector3<f64>>,
    along: Vec<Vector3<f64>>,
}

impl Steps {
    fn of(returns: &[OnTarget]) -> Self {
        let mut profiles: Vec<(u32, Vector3<f64>, f64)> = Vec::new();
        let mut along = Vec::new();
        for (k, r) in returns.iter().enumerate() {
            match profiles.last_mut() {
                Some((p, sum, count)) if *p == r.raw.profile => {
                    *sum += r.loc.x_e;
                    *count += 1.0;
                    along.push(r.loc.x_e - returns[k - 1].loc.x_e);
                }
                _ => profiles.push((r.raw.profile, r.loc.x_e, 1.0)),
            }
        }
        let across = profiles
            .windows(2)
            .map(|w| (w[1].1 / w[1].2 - w[0].1 / w[0].2) / f64::from(w[1].0 - w[0].0))
            .collect();
        Steps { across, along }
    }

    /// The squared sampling step along `axis` (m^2): the median profile-to-profile step plus
    /// the median step along a profile, each projected on `axis`; none when the visit cannot
    /// place the target along `axis`: fewer than three profiles, a single return per profile,
    /// or returns spanning less than two steps (fewer than three sampling levels).
    fn sampling_step2(&self, returns: &[OnTarget], axis: &Vector3<f64>) -> Option<f64> {
        if self.across.len() < 2 || self.along.is_empty() {
            return None;
        }
        let median_abs = |v: &[Vector3<f64>]| {
            let mut p: Vec<f64> = v.iter().map(|d| d.dot(axis).abs()).collect();
            p.sort_by(f64::total_cmp);
            p[p.len() / 2]
        };
        let s2 = median_abs(&self.across).powi(2) + median_abs(&self.along).powi(2);
        let (lo, hi) = returns
            .iter()
            .map(|r| r.loc.x_e.dot(axis))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x), b.max(x))
            });
        (s2 > 0.0 && (hi - lo).powi(2) >= 4.0 * s2).then_some(s2)
    }
}

/// The centroid of the returns observed along `axis`: each return's observation along `axis`
/// (residual from `centre`) averaged, its white variance divided by the count, plus `extra_var`
/// (m^2: the survey's and the sampling's).
fn centroid(
    returns: &[OnTarget],
    model: &ReturnModel,
    axis: &Vector3<f64>,
    centre: &Vector3<f64>,
    ids: (usize, usize, usize),
    cov: Covariates,
    extra_var: f64,
) -> Observation {
    let n = returns.len() as f64;
    let mut sum = Observation {
        reference: ids.0,
        visit: ids.1,
        record: ids.2,
        residual_m: 0.0,
        var_white_m2: 0.0,
        nav_gradient: [0.0; 6],
        signature: [0.0; N_EFFECTS],
        covariates: cov,
        nav_record: None,
        plane_uv_m: [f32::NAN; 2],
    };
    for r in returns {
        let at = Surface {
            axis_e: axis,
            centre_e: centre,
            range_m: r.range_m,
        };
        let o = observation_along(&r.loc, model, &at, &r.raw, ids, cov);
        sum.residual_m += o.residual_m / n;
        sum.var_white_m2 += o.var_white_m2 / (n * n);
        for (a, b) in sum.nav_gradient.iter_mut().zip(o.nav_gradient) {
            *a += b / n;
        }
        for (a, b) in sum.signature.iter_mut().zip(o.signature) {
            *a += b / n;
        }
    }
    sum.var_white_m2 += extra_var;
    sum
}
