//! The refined estimator: every return on a sync target, georeferenced with the clock
//! parameters `theta = (a, T[, tau])` (`t0 = t_ref + a`), must lie on the target's surveyed
//! plane: residual `r_k = n . (x_k(theta) - c)`. Measurement model per sighting (returns of
//! one pass over one target): `r = J dtheta + e + 1 (n . dp - n . dc) + A dphi`, with
//! independent range/angle noise `e` (diagonal `D`), and, common to the sighting, the
//! navigation position error `dp` (SMRMSG sigmas, ECEF), the survey error of the target
//! centre `dc` (sigma_m) and the attitude error `dphi` (SMRMSG sigmas, body axes), so the
//! residual covariance is `C = D + (n' S_p n + s_c^2) 1 1' + A S_phi A'`. Sightings are
//! independent (navigation errors decorrelate between passes). Gauss-Newton minimises
//! `sum r' C^-1 r`; the covariance of theta is `(sum J' C^-1 J)^-1`, which is also the
//! Cramer-Rao bound of this Gaussian model when evaluated at the true theta.

use super::geometry::{attitude_cov_b, nav_sigma, position_cov_e, return_point, TargetReturn};
use crate::geo::rotations::skew;
use crate::georef::{r_b_to_e, Sensor};
use crate::timing::Mirror;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use nalgebra::{DMatrix, DVector, Vector3};

/// The surveyed plane of a target: centre and unit normal (ECEF), centre sigma (m) and,
/// when returns near its edges are to be dropped, its half length and half height (m).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Plane {
    pub c_e: Vector3<f64>,
    pub n_e: Vector3<f64>,
    pub sigma_m: f64,
    pub half_size_m: Option<[f64; 2]>,
}

/// Returns this close to a face's edge (in the face, m) may have hit its sides (a plate has
/// a thickness) and are not used.
const EDGE_MARGIN_M: f64 = 0.02;

impl Plane {
    /// Whether the in-face position of `x_e` is at least [`EDGE_MARGIN_M`] inside the edges
    /// (always, without half sizes). In-face axes: horizontal `h = up x n`, `v = n x h`.
    fn inside(&self, x_e: &Vector3<f64>) -> bool {
        let Some([hl, hh]) = self.half_size_m else {
            return true;
        };
        let h = self.c_e.normalize().cross(&self.n_e).normalize();
        let v = self.n_e.cross(&h);
        let d = x_e - self.c_e;
        d.dot(&h).abs() <= hl - EDGE_MARGIN_M && d.dot(&v).abs() <= hh - EDGE_MARGIN_M
    }
}

/// Everything the misfit needs besides theta.
pub(crate) struct Model<'a> {
    pub traj: &'a Trajectory,
    pub sensor: &'a Sensor,
    pub mirror: Mirror,
    pub t_ref_s: f64,
    pub sigma_range_m: f64,
    pub sigma_angle_rad: f64,
    /// Attitude latency used when it is not a parameter (s).
    pub tau_fixed_s: f64,
}

/// Finite-difference step for time derivatives (s): the trajectory is linear between
/// records 5 ms or more apart, so 0.1 ms differences are exact inside an interval.
const H_S: f64 = 1e-4;

/// Returns further than this many of their noise sigmas from their sighting's median residual
/// are not on the front face.
const EDGE_SIGMAS: f64 = 3.0;

/// A sighting's returns and its target's plane.
pub(crate) type SightingData = (Vec<TargetReturn>, Plane);

impl Model<'_> {
    fn tau(&self, theta: &DVector<f64>) -> f64 {
        if theta.len() > 2 {
            theta[2]
        } else {
            self.tau_fixed_s
        }
    }

    /// The returns of a sighting inside the face's edge margin (when its size is known) and
    /// within `EDGE_SIGMAS` of their own noise sigma of the sighting's median residual at
    /// `theta`: drops hits on a plate's sides (a plate has a thickness; its sides are not the
    /// surveyed front plane); Gaussian noise loses 0.3% of its returns to the second test.
    pub fn front_face(
        &self,
        theta: &DVector<f64>,
        returns: &[TargetReturn],
        plane: &Plane,
    ) -> Result<Vec<TargetReturn>> {
        let tau = self.tau(theta);
        let mut inside = Vec::with_capacity(returns.len());
        for ret in returns {
            let nu = ret.profile as f64 + self.mirror.fraction(ret.beta_rad);
            let t = self.t_ref_s + theta[0] + theta[1] * nu;
            let x = return_point(self.traj, self.sensor, ret, t, tau)?.0;
            if plane.inside(&x) {
                inside.push(*ret);
            }
        }
        if inside.is_empty() {
            return Ok(inside);
        }
        let (r, _, _, d) = self.sighting(theta, &inside, plane)?;
        let mut sorted: Vec<f64> = r.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        Ok(inside
            .iter()
            .enumerate()
            .filter(|(k, _)| (r[*k] - median).abs() <= EDGE_SIGMAS * d[*k].sqrt())
            .map(|(_, ret)| *ret)
            .collect())
    }

    /// Residuals, Jacobian, residual covariance and independent noise variances of one
    /// sighting.
    #[allow(clippy::type_complexity)]
    pub fn sighting(
        &self,
        theta: &DVector<f64>,
        returns: &[TargetReturn],
        plane: &Plane,
    ) -> Result<(DVector<f64>, DMatrix<f64>, DMatrix<f64>, DVector<f64>)> {
        let (m, p) = (returns.len(), theta.len());
        let tau = self.tau(theta);
        let mut r = DVector::zeros(m);
        let mut j = DMatrix::zeros(m, p);
        let mut d = DVector::zeros(m);
        let mut a_rows = DMatrix::zeros(m, 3);
        let n = plane.n_e;
        let mut t_mid = 0.0;
        for (k, ret) in returns.iter().enumerate() {
            let nu = ret.profile as f64 + self.mirror.fraction(ret.beta_rad);
            let t = self.t_ref_s + theta[0] + theta[1] * nu;
            t_mid += t / m as f64;
            let (x, pose) = return_point(self.traj, self.sensor, ret, t, tau)?;
            let x_plus = return_point(self.traj, self.sensor, ret, t + H_S, tau)?.0;
            let x_minus = return_point(self.traj, self.sensor, ret, t - H_S, tau)?.0;
            let dr_dt = n.dot(&(x_plus - x_minus)) / (2.0 * H_S);
            r[k] = n.dot(&(x - plane.c_e));
            j[(k, 0)] = dr_dt;
            j[(k, 1)] = dr_dt * nu;
            if p > 2 {
                let xp = return_point(self.traj, self.sensor, ret, t, tau + H_S)?.0;
                let xm = return_point(self.traj, self.sensor, ret, t, tau - H_S)?.0;
                j[(k, 2)] = n.dot(&(xp - xm)) / (2.0 * H_S);
            }
            let r_s_e = r_b_to_e(&pose) * self.sensor.r_s_to_b;
            let (sa, ca) = ret.alpha_rad.sin_cos();
            let beta = self.sensor.beta_rad(ret.beta_rad);
            let (sb, cb) = beta.sin_cos();
            let u = r_s_e * crate::georef::beam_s(ret.alpha_rad, beta);
            let du_b = r_s_e * Vector3::new(0.0, -ca * cb, -ca * sb);
            let du_a = r_s_e * Vector3::new(ca, sa * sb, -sa * cb);
            let rho = self.sensor.range_total_m(ret.range_m);
            let sa2 = (rho * self.sigma_angle_rad).powi(2);
            d[k] = (self.sigma_range_m * n.dot(&u)).powi(2)
                + sa2 * (n.dot(&du_b).powi(2) + n.dot(&du_a).powi(2));
            // x = r + R_b^e v_b; a body rotation error dphi moves x by -R_b^e [v_b]x dphi.
            let x_s = crate::georef::point_s(self.sensor, ret.range_m, ret.alpha_rad, ret.beta_rad);
            let v_b = self.sensor.lever_arm_b_m + self.sensor.r_s_to_b * x_s;
            let row = -(n.transpose() * r_b_to_e(&pose) * skew(&v_b));
            a_rows.set_row(k, &row);
        }
        let pose = super::geometry::pose_at(self.traj, tau, t_mid, "sighting")?;
        let s = nav_sigma(self.traj, t_mid);
        let common = (n.transpose() * position_cov_e(&pose, &s) * n)[0] + plane.sigma_m.powi(2);
        let s_att = DMatrix::from_iterator(3, 3, attitude_cov_b(&s).iter().copied());
        let mut c = &a_rows * s_att * a_rows.transpose();
        c.add_scalar_mut(common);
        d.apply(|v| *v = v.max(1e-12));
        for k in 0..m {
            c[(k, k)] += d[k];
        }
        Ok((r, j, c, d))
    }

    /// Information matrix `sum J' C^-1 J`, gradient `sum J' C^-1 r` and `chi^2`.
    pub fn normal(
        &self,
        theta: &DVector<f64>,
        sightings: &[SightingData],
    ) -> Result<(DMatrix<f64>, DVector<f64>, f64)> {
        let p = theta.len();
        let (mut h, mut g, mut chi2) = (DMatrix::zeros(p, p), DVector::zeros(p), 0.0);
        for (returns, plane) in sightings {
            let (r, j, c, _) = self.sighting(theta, returns, plane)?;
            let chol = c.cholesky().ok_or_else(|| Error::Numerical {
                what: "sync refined estimator".into(),
                problem: "a sighting's residual covariance is not positive definite".into(),
            })?;
            let cj = chol.solve(&j);
            let cr = chol.solve(&r);
            h += j.transpose() * &cj;
            g += j.transpose() * &cr;
            chi2 += r.dot(&cr);
        }
        Ok((h, g, chi2))
    }

    /// Gauss-Newton from `theta`; returns theta, its covariance and chi^2 at the solution.
    pub fn solve(
        &self,
        mut theta: DVector<f64>,
        sightings: &[SightingData],
    ) -> Result<(DVector<f64>, DMatrix<f64>, f64)> {
        for _ in 0..30 {
            let (h, g, _) = self.normal(&theta, sightings)?;
            let cov = invert_scaled(&h)?;
            let step = -(&cov * g);
            theta += &step;
            let small = (0..theta.len()).all(|i| step[i].abs() <= 1e-4 * cov[(i, i)].sqrt());
            if small {
                let (h, _, chi2) = self.normal(&theta, sightings)?;
                return Ok((theta, invert_scaled(&h)?, chi2));
            }
        }
        Err(Error::Numerical {
            what: "sync refined estimator".into(),
            problem: "Gauss-Newton did not converge in 30 iterations".into(),
        })
    }
}

/// Inverse of a symmetric positive matrix through its unit-diagonal scaling.
pub(crate) fn invert_scaled(h: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let (hs, s) = scaled(h);
    let inv = hs.try_inverse().ok_or_else(|| Error::Numerical {
        what: "sync refined estimator".into(),
        problem: "singular information matrix: the targets do not constrain the clock".into(),
    })?;
    Ok(DMatrix::from_diagonal(&s) * inv * DMatrix::from_diagonal(&s))
}

/// `H` scaled to unit diagonal, and the scale `1 / sqrt(diag H)`.
pub(crate) fn scaled(h: &DMatrix<f64>) -> (DMatrix<f64>, DVector<f64>) {
    let s = h
        .diagonal()
        .map(|v| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 });
    let d = DMatrix::from_diagonal(&s);
    (&d * h * &d, s)
}

/// Condition number of the unit-diagonal information matrix and each parameter's variance
/// inflation factor (how much correlation with the others multiplies its variance).
pub(crate) fn conditioning(h: &DMatrix<f64>) -> (f64, Vec<f64>) {
    let (hs, _) = scaled(h);
    let eig = hs.clone().symmetric_eigen();
    let (lo, hi) = eig
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    let vif = match hs.try_inverse() {
        Some(inv) => inv.diagonal().iter().copied().collect(),
        None => vec![f64::INFINITY; h.nrows()],
    };
    let cond = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    (cond, vif)
}
