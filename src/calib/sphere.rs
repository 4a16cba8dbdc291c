//! Sphere fitting by iterative least squares (paper 000, section 2.3, eq. 5).
//!
//! Observation per return `X_i` (m, any Cartesian frame): `r_i = |X_i - c| - R`. Gauss-Newton
//! starts from the barycentre of the returns (the paper's start) and solves the linearised
//! (N, 3) system for the centre `c` with a known radius, or the (N, 4) system for `(c, R)` with
//! a free radius. A step that raises the sum of squares is halved until it does not.
//!
//! Covariance comes from the residuals, by the sandwich (heteroscedasticity-consistent) estimator
//! `Cov = N/(N-p) (J^T J)^-1 (sum r_i^2 j_i j_i^T) (J^T J)^-1`, `p` = 3 or 4. The plain
//! `sigma0^2 (J^T J)^-1` is wrong here: range noise acts along the beam, so a return's residual
//! noise is `sigma_range * |cos(incidence)|`, small at the grazing rim where returns carry most of
//! the lateral information; the plain form overstates the lateral sigma by ~25 % and understates
//! the along-beam one by ~30 % (measured on the paper's geometry). The sandwich needs no scanner
//! position and reduces to the plain form for equal noise.
//!
//! Robust scheme ([`fit_sphere_robust`]), for returns off the sphere (stand, table, background):
//! fit all returns, then repeat: scale `s = 1.4826 * median|r_i - median r|` (the MAD, a
//! consistent sigma for Gaussian residuals that ignores up to half the returns being off the
//! sphere), keep returns with `|r_i| <= k s` (`k` = [`ROBUST_CUT_SIGMAS`]), refit the kept
//! returns from the current centre (after 3 rounds a rejected return stays rejected, so the kept
//! set cannot cycle), until the kept set stops changing or the centre moves by less
//! than 5 % of its own sigma (returns at the threshold may otherwise flip in and out forever;
//! the last move is then far below the statistical error).
//! The covariance is that of the final plain fit on the kept returns.

use crate::{Error, Result};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

/// Fewest returns accepted on one sphere: below this the centre covariance from residuals is not
/// trustworthy (and a free-radius fit has almost no redundancy).
pub const MIN_SPHERE_RETURNS: usize = 20;
/// Rejection threshold of the robust scheme, in MAD sigmas: 3 keeps 99.7 % of Gaussian returns.
pub const ROBUST_CUT_SIGMAS: f64 = 3.0;
/// Gauss-Newton stops when the step is below this (m).
const STEP_TOL_M: f64 = 1e-10;
/// Gauss-Newton iteration limit (a failure to converge is reported, not hidden).
const MAX_ITERATIONS: usize = 50;
/// Robust rounds limit.
const MAX_ROBUST_ROUNDS: usize = 50;
/// Rounds in which a rejected return may come back; later rounds only reject, so the kept set
/// cannot cycle.
const FREE_ROBUST_ROUNDS: usize = 3;
/// Iterations of the start fit of the robust scheme.
pub const ROBUST_START_ITERATIONS: usize = 10;

/// Whether the sphere radius is known (m) or estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SphereRadius {
    /// Radius known from the target's certificate (m).
    Known(f64),
    /// Radius estimated with the centre.
    Free,
}

/// A fitted sphere. Frame and units are those of the input points (m).
#[derive(Debug, Clone, PartialEq)]
pub struct SphereFit {
    /// Centre (m).
    pub centre_m: Vector3<f64>,
    /// Radius (m): the known one, or the estimate.
    pub radius_m: f64,
    /// 1-sigma radius (m) when the radius is free, `None` when known.
    pub sigma_radius_m: Option<f64>,
    /// Centre covariance (m^2) from the residuals.
    pub cov_centre_m2: Matrix3<f64>,
    /// Residual standard deviation `sigma0` (m).
    pub sigma_residual_m: f64,
    /// Gauss-Newton iterations of the (final) fit, counting the converged step.
    pub iterations: usize,
    /// Returns used in the final fit.
    pub n_used: usize,
    /// Returns rejected as off the sphere (robust fit only, else 0).
    pub n_rejected: usize,
}

/// Plain least-squares sphere fit from the barycentre of `points` (m).
///
/// Errors: fewer than [`MIN_SPHERE_RETURNS`] points, a singular system (points on a line or a
/// plane circle with free radius), or no convergence.
pub fn fit_sphere(points: &[Vector3<f64>], radius: SphereRadius) -> Result<SphereFit> {
    check_count(points.len())?;
    let bary = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    fit_from(points, radius, bary)
}

/// Converged Gauss-Newton fit from `start`, with covariance.
fn fit_from(
    points: &[Vector3<f64>],
    radius: SphereRadius,
    start: Vector3<f64>,
) -> Result<SphereFit> {
    let (c, r, iterations, converged) = gauss_newton(points, radius, start, MAX_ITERATIONS)?;
    if !converged {
        return Err(Error::Numerical {
            what: "sphere fit".into(),
            problem: format!("no convergence in {MAX_ITERATIONS} iterations"),
        });
    }
    finish(points, c, r, radius == SphereRadius::Free, iterations)
}

/// Robust sphere fit (module doc): rejects returns off the sphere by a MAD-scaled cut.
///
/// The first fit on all returns may be pulled far off by them and converge slowly: its first
/// [`ROBUST_START_ITERATIONS`] iterations only give the start of the rejection rounds.
pub fn fit_sphere_robust(points: &[Vector3<f64>], radius: SphereRadius) -> Result<SphereFit> {
    check_count(points.len())?;
    let bary = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
    let (c, r, _, _) = gauss_newton(points, radius, bary, ROBUST_START_ITERATIONS)?;
    let mut fit = SphereFit {
        centre_m: c,
        radius_m: r,
        sigma_radius_m: None,
        cov_centre_m2: Matrix3::zeros(),
        sigma_residual_m: 0.0,
        iterations: 0,
        n_used: points.len(),
        n_rejected: 0,
    };
    let mut kept: Vec<bool> = vec![true; points.len()];
    for round in 0..MAX_ROBUST_ROUNDS {
        let res: Vec<f64> = points
            .iter()
            .map(|p| (p - fit.centre_m).norm() - fit.radius_m)
            .collect();
        let scale = mad_sigma(&res);
        let cut = ROBUST_CUT_SIGMAS * scale;
        let mut new_kept: Vec<bool> = res.iter().map(|r| r.abs() <= cut).collect();
        if round >= FREE_ROBUST_ROUNDS {
            new_kept.iter_mut().zip(&kept).for_each(|(n, k)| *n &= *k);
        }
        if round > 0 && new_kept == kept {
            fit.n_rejected = points.len() - fit.n_used;
            return Ok(fit);
        }
        kept = new_kept;
        let inliers: Vec<Vector3<f64>> = points
            .iter()
            .zip(&kept)
            .filter(|(_, &k)| k)
            .map(|(p, _)| *p)
            .collect();
        check_count(inliers.len())?;
        let previous = fit.centre_m;
        fit = fit_from(&inliers, radius, previous)?;
        let moved = (fit.centre_m - previous).norm();
        if round > 0 && moved < 0.05 * fit.cov_centre_m2.trace().sqrt() {
            fit.n_rejected = points.len() - fit.n_used;
            return Ok(fit);
        }
    }
    Err(Error::Numerical {
        what: "robust sphere fit".into(),
        problem: format!("the kept set did not settle in {MAX_ROBUST_ROUNDS} rounds"),
    })
}

fn check_count(n: usize) -> Result<()> {
    if n < MIN_SPHERE_RETURNS {
        return Err(Error::Invalid(format!(
            "sphere fit: {n} returns on the sphere, at least {MIN_SPHERE_RETURNS} needed"
        )));
    }
    Ok(())
}

/// MAD-based sigma `1.4826 * median|r - median r|`.
fn mad_sigma(res: &[f64]) -> f64 {
    let med = median(res.to_vec());
    median(res.iter().map(|r| (r - med).abs()).collect()) * 1.4826
}

fn median(mut v: Vec<f64>) -> f64 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// Sum of squares, normal matrix `J^T J` (4x4, radius column last) and gradient `J^T r`.
fn normal_system(
    points: &[Vector3<f64>],
    c: &Vector3<f64>,
    r: f64,
) -> Result<(f64, Matrix4<f64>, Vector4<f64>)> {
    let mut ss = 0.0;
    let mut n = Matrix4::zeros();
    let mut g = Vector4::zeros();
    for p in points {
        let d = p - c;
        let dist = d.norm();
        if dist < 1e-12 {
            return Err(Error::Numerical {
                what: "sphere fit".into(),
                problem: "a return coincides with the centre estimate".into(),
            });
        }
        let u = d / dist;
        let j = Vector4::new(-u.x, -u.y, -u.z, -1.0);
        let res = dist - r;
        ss += res * res;
        n += j * j.transpose();
        g += j * res;
    }
    Ok((ss, n, g))
}

/// Mean distance from `c` to the points: the free-radius start value.
fn mean_distance(points: &[Vector3<f64>], c: &Vector3<f64>) -> f64 {
    points.iter().map(|p| (p - c).norm()).sum::<f64>() / points.len() as f64
}

fn singular() -> Error {
    Error::Numerical {
        what: "sphere fit".into(),
        problem: "singular normal matrix (returns do not constrain a sphere)".into(),
    }
}

/// Gauss-Newton with step halving from `start`, at most `max_it` iterations:
/// `(centre, radius, iterations, converged)`.
fn gauss_newton(
    points: &[Vector3<f64>],
    radius: SphereRadius,
    start: Vector3<f64>,
    max_it: usize,
) -> Result<(Vector3<f64>, f64, usize, bool)> {
    let free = radius == SphereRadius::Free;
    let mut c = start;
    let mut r = match radius {
        SphereRadius::Known(r) => r,
        SphereRadius::Free => mean_distance(points, &c),
    };
    for it in 1..=max_it {
        let (ss, n, g) = normal_system(points, &c, r)?;
        let step = solve_step(&n, &g, free)?;
        let (mut dc, mut dr) = (step.xyz(), step.w);
        let mut accepted = false;
        for _ in 0..30 {
            let (ss_new, _, _) = normal_system(points, &(c + dc), r + dr)?;
            if ss_new <= ss * (1.0 + 1e-12) {
                accepted = true;
                break;
            }
            dc *= 0.5;
            dr *= 0.5;
        }
        if !accepted {
            return Err(Error::Numerical {
                what: "sphere fit".into(),
                problem: "no descent step from the current estimate".into(),
            });
        }
        c += dc;
        r += dr;
        if (dc.norm_squared() + dr * dr).sqrt() < STEP_TOL_M {
            return Ok((c, r, it, true));
        }
    }
    Ok((c, r, max_it, false))
}

/// Solves `N step = -g` on the 3x3 block (known radius) or the full 4x4 (free radius).
fn solve_step(n: &Matrix4<f64>, g: &Vector4<f64>, free: bool) -> Result<Vector4<f64>> {
    if free {
        n.cholesky().map(|ch| -ch.solve(g)).ok_or_else(singular)
    } else {
        let n3: Matrix3<f64> = n.fixed_view::<3, 3>(0, 0).into();
        let s = n3
            .cholesky()
            .map(|ch| -ch.solve(&g.xyz()))
            .ok_or_else(singular)?;
        Ok(Vector4::new(s.x, s.y, s.z, 0.0))
    }
}

fn finish(
    points: &[Vector3<f64>],
    c: Vector3<f64>,
    r: f64,
    free: bool,
    iterations: usize,
) -> Result<SphereFit> {
    let (ss, n, _) = normal_system(points, &c, r)?;
    let p = if free { 4 } else { 3 };
    let k = points.len() as f64 / (points.len() - p) as f64;
    let mut meat = Matrix4::zeros();
    for q in points {
        let d = q - c;
        let dist = d.norm();
        let u = d / dist;
        let j = Vector4::new(-u.x, -u.y, -u.z, if free { -1.0 } else { 0.0 });
        meat += j * j.transpose() * (dist - r).powi(2);
    }
    let (cov_centre_m2, sigma_radius_m) = if free {
        let bread = n.try_inverse().ok_or_else(singular)?;
        let cov = bread * meat * bread * k;
        (
            cov.fixed_view::<3, 3>(0, 0).into(),
            Some(cov[(3, 3)].sqrt()),
        )
    } else {
        let n3: Matrix3<f64> = n.fixed_view::<3, 3>(0, 0).into();
        let bread = n3.try_inverse().ok_or_else(singular)?;
        let m3: Matrix3<f64> = meat.fixed_view::<3, 3>(0, 0).into();
        (bread * m3 * bread * k, None)
    };
    Ok(SphereFit {
        centre_m: c,
        radius_m: r,
        sigma_radius_m,
        cov_centre_m2,
        sigma_residual_m: (ss / (points.len() - p) as f64).sqrt(),
        iterations,
        n_used: points.len(),
        n_rejected: 0,
    })
}

/// Range (m) along unit direction `dir` from `origin` to the first hit on the sphere
/// (`centre_m`, `radius_m`), or `None` on a miss. Any frame, metres.
pub fn ray_sphere_range(
    origin: &Vector3<f64>,
    dir: &Vector3<f64>,
    centre_m: &Vector3<f64>,
    radius_m: f64,
) -> Option<f64> {
    let oc = centre_m - origin;
    let along = oc.dot(dir);
    let perp_sq = oc.norm_squared() - along * along;
    let h_sq = radius_m * radius_m - perp_sq;
    if h_sq < 0.0 {
        return None;
    }
    let t = along - h_sq.sqrt();
    (t > 0.0).then_some(t)
}
