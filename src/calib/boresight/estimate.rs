//! The boresight estimator (module docs of `calib::boresight`): sites in, `R_s^b` and its
//! covariance out.

use crate::calib::tripod::{leg_covariance_s, solve_site, BoresightSetup, TripodSolution};
use crate::geo::rotations::{r_b_to_n, r_zyx, skew, zyx_angles};
use crate::{Error, Result};
use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Rotation3, SMatrix, SVector, Vector2, Vector3};
use serde::Serialize;

/// Gauss-Newton iteration limit.
pub const MAX_ITERATIONS: usize = 20;
/// Convergence: every parameter step below this share of the parameter's sigma (the estimate
/// then moves by 0.1 % of its own uncertainty).
const STEP_TOL_SIGMAS: f64 = 1e-3;
/// Sites closer than this in attitude are "identical" (rad, 1 deg).
const MIN_SITE_ROTATION_RAD: f64 = 0.017_453_292_519_943_295;
/// Relative-rotation axes closer than this are "collinear" (sine of 5 deg).
const MIN_AXIS_SPREAD_SIN: f64 = 0.087_155_742_747_658_17;

/// One static site: ellipse centres of the three legs and the IMU attitude.
#[derive(Debug, Clone, PartialEq)]
pub struct TripodSite {
    /// Site id.
    pub site: u64,
    /// Ellipse centres `(y_s, z_s)` (m) of legs 1, 2, 3 in the scan plane.
    pub centres_s_m: [Vector2<f64>; 3],
    /// In-plane covariance of each centre, `(y_s, z_s)` (m^2); a `centres` file gives
    /// `sigma_m^2 I`, a fit from `scans` its full covariance.
    pub cov_centre_s_m2: [Matrix2<f64>; 3],
    /// IMU roll, pitch, heading (rad).
    pub attitude_rad: [f64; 3],
    /// 1-sigma of the attitude angles (rad).
    pub sigma_attitude_rad: [f64; 3],
}

/// Per-site diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct SiteResult {
    /// Site id.
    pub site: u64,
    /// Apex in the scanner frame (m).
    pub apex_s_m: [f64; 3],
    /// Apex distances to the cut points (m).
    pub apex_distances_m: [f64; 3],
    /// Angle between each leg's direction at this site and the adjusted one (deg).
    pub leg_residual_deg: [f64; 3],
}

/// Boresight calibration result.
#[derive(Debug, Clone, Serialize)]
pub struct BoresightReport {
    /// convention boresight `[bx, by, bz]` (deg): `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    pub boresight_deg: [f64; 3],
    /// Covariance of `boresight_deg` (deg^2), by first-order propagation.
    pub cov_boresight_deg2: [[f64; 3]; 3],
    /// 1-sigma of `boresight_deg` (deg).
    pub sigma_boresight_deg: [f64; 3],
    /// False near `by = +-90 deg`, where bx and bz are not separable and their covariance blows
    /// up: use `r_s_to_b` and the misalignment covariance there.
    pub spec_angles_well_conditioned: bool,
    /// The estimated `R_s^b` (row-major).
    pub r_s_to_b: [[f64; 3]; 3],
    /// Misalignment about body x, y, z on top of the nominal mounting (deg).
    pub misalignment_deg: [f64; 3],
    /// Its covariance (deg^2).
    pub cov_misalignment_deg2: [[f64; 3]; 3],
    /// Its 1-sigma (deg).
    pub sigma_misalignment_deg: [f64; 3],
    /// Nominal boresight used (deg).
    pub nominal_boresight_deg: [f64; 3],
    /// Gauss-Newton iterations (counting the converged step).
    pub iterations: usize,
    /// Weighted sum of squared residuals / degrees of freedom (expect ~1).
    pub variance_factor: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Adjusted leg directions in NED.
    pub legs_n: [[f64; 3]; 3],
    /// Per-site diagnostics.
    pub sites: Vec<SiteResult>,
}

type M9 = SMatrix<f64, 9, 9>;
type V9 = SVector<f64, 9>;

/// Everything the adjustment needs of one site.
struct SiteData {
    r_b_n: Matrix3<f64>,
    legs_s: [Vector3<f64>; 3],
    cov_legs_s: M9,
    sol: TripodSolution,
    attitude: [f64; 3],
    sigma_attitude: [f64; 3],
}

/// `R_s^b(d) = Rz(dz) Ry(dy) Rx(dx) R_nom`.
fn r_s_b(d: &Vector3<f64>, nominal: &Matrix3<f64>) -> Matrix3<f64> {
    r_zyx(d.x, d.y, d.z) * nominal
}

/// Estimates the boresight from `>= 3` tripod sites (module doc).
pub fn estimate_boresight(sites: &[TripodSite], setup: &BoresightSetup) -> Result<BoresightReport> {
    check_sites(sites)?;
    let data = sites
        .iter()
        .map(|s| prepare_site(s, setup))
        .collect::<Result<Vec<_>>>()?;
    let nom = setup.r_nominal_s_to_b;
    let start = hand_eye_start(&data)?;
    let mut d = Vector3::from(<[f64; 3]>::from(zyx_angles(&(start * nom.transpose()))));
    let mut w: [Vector3<f64>; 3] = data[0].legs_s.map(|u| data[0].r_b_n * start * u);
    for it in 1..=MAX_ITERATIONS {
        let (n, b, _, _) = normal_equations(&data, &d, &w, &nom)?;
        let chol = n.clone().cholesky().ok_or_else(unobservable)?;
        let step = chol.solve(&(-b));
        let sigma = chol.inverse().diagonal().map(f64::sqrt);
        d += step.fixed_rows::<3>(0);
        let spin = Rotation3::new(Vector3::new(step[3], step[4], step[5]));
        w = w.map(|wi| spin * wi);
        if step
            .iter()
            .zip(sigma.iter())
            .all(|(st, sg)| st.abs() < STEP_TOL_SIGMAS * sg)
        {
            return report(&data, sites, setup, d, w, it);
        }
    }
    Err(Error::Numerical {
        what: "boresight".into(),
        problem: format!("Gauss-Newton did not converge in {MAX_ITERATIONS} iterations"),
    })
}

/// Closed-form start (hand-eye `AX = XB`): for site pairs `(j, k)` the scanner-frame triad
/// rotation `A = T_j T_k^-1` and the body-frame IMU rotation `B = R_j^T R_k` satisfy
/// `B = R_s^b A (R_s^b)^T`, so `log B = R_s^b log A`; `R_s^b` from all pairs by SVD (Kabsch).
fn hand_eye_start(data: &[SiteData]) -> Result<Matrix3<f64>> {
    let triad = |s: &SiteData| Matrix3::from_columns(&s.legs_s);
    let mut h = Matrix3::zeros();
    for j in 0..data.len() {
        for k in j + 1..data.len() {
            let tk_inv = triad(&data[k]).try_inverse().ok_or_else(unobservable)?;
            let a = Rotation3::from_matrix(&(triad(&data[j]) * tk_inv)).scaled_axis();
            let b =
                Rotation3::from_matrix(&(data[j].r_b_n.transpose() * data[k].r_b_n)).scaled_axis();
            h += a * b.transpose();
        }
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (
        svd.u.ok_or_else(unobservable)?,
        svd.v_t.ok_or_else(unobservable)?,
    );
    let v = v_t.transpose();
    let fix = Matrix3::from_diagonal(&Vector3::new(
        1.0,
        1.0,
        (v * u.transpose()).determinant().signum(),
    ));
    Ok(v * fix * u.transpose())
}

fn unobservable() -> Error {
    Error::Numerical {
        what: "boresight".into(),
        problem: "singular normal matrix: the sites do not determine all three angles".into(),
    }
}

/// Refuses fewer than 3 sites, identical sites and sites whose relative rotations share one axis.
fn check_sites(sites: &[TripodSite]) -> Result<()> {
    if sites.len() < 3 {
        return Err(Error::Invalid(format!(
            "boresight: {} tripod sites, at least 3 needed",
            sites.len()
        )));
    }
    let r: Vec<Rotation3<f64>> = sites
        .iter()
        .map(|s| {
            Rotation3::from_matrix_unchecked(r_b_to_n(
                s.attitude_rad[0],
                s.attitude_rad[1],
                s.attitude_rad[2],
            ))
        })
        .collect();
    let mut axes: Vec<Vector3<f64>> = Vec::new();
    for i in 0..r.len() {
        for j in i + 1..r.len() {
            let rel = r[i].inverse() * r[j];
            if rel.angle() < MIN_SITE_ROTATION_RAD {
                return Err(Error::Invalid(format!(
                    "boresight: sites {} and {} have identical attitudes (within 1 deg)",
                    sites[i].site, sites[j].site
                )));
            }
            axes.push(rel.scaled_axis().normalize());
        }
    }
    if axes
        .iter()
        .all(|a| a.cross(&axes[0]).norm() < MIN_AXIS_SPREAD_SIN)
    {
        return Err(Error::Invalid(
            "boresight: collinear sites: all rotations between sites are about one axis \
             (within 5 deg), so the boresight about that axis is not observable; add a site \
             tilted about another axis"
                .into(),
        ));
    }
    Ok(())
}

fn prepare_site(s: &TripodSite, setup: &BoresightSetup) -> Result<SiteData> {
    let [r, p, h] = s.attitude_rad;
    let r_b_n = r_b_to_n(r, p, h);
    let sol = solve_site(
        &s.centres_s_m,
        setup.cos_leg_angles,
        &(r_b_n * setup.r_nominal_s_to_b),
        &setup.tripod_axis_n,
    )
    .map_err(|e| Error::Invalid(format!("boresight: site {}: {e}", s.site)))?;
    let cov_legs_s = leg_covariance_s(
        &s.centres_s_m,
        &s.cov_centre_s_m2,
        setup.cos_leg_angles,
        &sol,
    )?;
    Ok(SiteData {
        r_b_n,
        legs_s: sol.legs_s,
        cov_legs_s,
        sol,
        attitude: s.attitude_rad,
        sigma_attitude: s.sigma_attitude_rad,
    })
}

/// Site residual `[R_k R_s^b u_i - w_i]`.
fn residual(
    r_b_n: &Matrix3<f64>,
    rsb: &Matrix3<f64>,
    legs: &[Vector3<f64>; 3],
    w: &[Vector3<f64>; 3],
) -> V9 {
    let mut r = V9::zeros();
    for i in 0..3 {
        r.fixed_rows_mut::<3>(3 * i)
            .copy_from(&(r_b_n * rsb * legs[i] - w[i]));
    }
    r
}

/// Residual covariance of a site: leg-direction part rotated to NED plus the attitude part.
fn residual_cov(s: &SiteData, rsb: &Matrix3<f64>) -> M9 {
    let mut q = M9::zeros();
    let rot = s.r_b_n * rsb;
    for i in 0..3 {
        q.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&rot);
    }
    let mut cov = q * s.cov_legs_s * q.transpose();
    let h = 1e-7;
    for k in 0..3 {
        let mut a = s.attitude;
        a[k] += h;
        let rp = r_b_to_n(a[0], a[1], a[2]);
        let col = (residual(&rp, rsb, &s.legs_s, &[Vector3::zeros(); 3])
            - residual(&s.r_b_n, rsb, &s.legs_s, &[Vector3::zeros(); 3]))
            / h;
        cov += col * col.transpose() * s.sigma_attitude[k].powi(2);
    }
    cov
}

/// Pseudo-inverse of a symmetric PSD matrix and its rank (eigenvalues below 1e-9 of the largest
/// are null: a rigid triad of unit vectors only varies by rotation).
fn pinv(m: &M9) -> (M9, usize) {
    let eig = m.symmetric_eigen();
    let tol = eig.eigenvalues.amax() * 1e-9;
    let mut out = M9::zeros();
    let mut rank = 0;
    for k in 0..9 {
        if eig.eigenvalues[k] > tol {
            let v = eig.eigenvectors.column(k);
            out += v * v.transpose() / eig.eigenvalues[k];
            rank += 1;
        }
    }
    (out, rank)
}

/// Normal matrix, gradient, weighted sum of squares and total rank over the sites.
fn normal_equations(
    data: &[SiteData],
    d: &Vector3<f64>,
    w: &[Vector3<f64>; 3],
    nom: &Matrix3<f64>,
) -> Result<(DMatrix<f64>, DVector<f64>, f64, usize)> {
    let mut n = DMatrix::<f64>::zeros(6, 6);
    let mut b = DVector::<f64>::zeros(6);
    let (mut ss, mut rank) = (0.0, 0);
    let rsb = r_s_b(d, nom);
    for s in data {
        let r = residual(&s.r_b_n, &rsb, &s.legs_s, w);
        let (wt, rk) = pinv(&residual_cov(s, &rsb));
        let mut j = SMatrix::<f64, 9, 6>::zeros();
        let h = 1e-7;
        for k in 0..3 {
            let mut dp = *d;
            dp[k] += h;
            let mut dm = *d;
            dm[k] -= h;
            let col = (residual(&s.r_b_n, &r_s_b(&dp, nom), &s.legs_s, w)
                - residual(&s.r_b_n, &r_s_b(&dm, nom), &s.legs_s, w))
                / (2.0 * h);
            j.set_column(k, &col);
        }
        for (i, wi) in w.iter().enumerate() {
            // d(-Rot(phi) w_i)/dphi at phi = 0 is [w_i]x.
            j.fixed_view_mut::<3, 3>(3 * i, 3).copy_from(&skew(wi));
        }
        let jt_w = j.transpose() * wt;
        n += DMatrix::from_column_slice(6, 6, (jt_w * j).as_slice());
        b += DVector::from_column_slice((jt_w * r).as_slice());
        ss += (r.transpose() * wt * r)[0];
        rank += rk;
    }
    Ok((n, b, ss, rank))
}

fn report(
    data: &[SiteData],
    sites: &[TripodSite],
    setup: &BoresightSetup,
    d: Vector3<f64>,
    w: [Vector3<f64>; 3],
    iterations: usize,
) -> Result<BoresightReport> {
    let nom = setup.r_nominal_s_to_b;
    let (n, _, ss, rank) = normal_equations(data, &d, &w, &nom)?;
    let inv = n.try_inverse().ok_or_else(unobservable)?;
    let cov_d: Matrix3<f64> = inv.fixed_view::<3, 3>(0, 0).into();
    let rsb = r_s_b(&d, &nom);
    let spec = |r: &Matrix3<f64>| Vector3::from(<[f64; 3]>::from(zyx_angles(r)));
    let b = spec(&rsb);
    // Jacobian of the convention angles with respect to the misalignment (central differences).
    let mut g = Matrix3::zeros();
    for k in 0..3 {
        let mut e = Vector3::zeros();
        e[k] = 1e-7;
        let diff = (spec(&r_s_b(&(d + e), &nom)) - spec(&r_s_b(&(d - e), &nom)))
            .map(crate::geo::rotations::wrap_pi);
        g.set_column(k, &(diff / 2e-7));
    }
    let cov_b = g * cov_d * g.transpose();
    let deg2 = |m: Matrix3<f64>| -> [[f64; 3]; 3] {
        let m = m.map(|v| v.to_degrees().to_degrees());
        [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]])
    };
    let sig = |m: &Matrix3<f64>| [0, 1, 2].map(|k| m[(k, k)].sqrt().to_degrees());
    let dof = rank - 6;
    let site_results = data
        .iter()
        .zip(sites)
        .map(|(s, site)| SiteResult {
            site: site.site,
            apex_s_m: s.sol.apex_s_m.into(),
            apex_distances_m: s.sol.distances_m,
            leg_residual_deg: [0, 1, 2]
                .map(|i| (s.r_b_n * rsb * s.legs_s[i]).angle(&w[i]).to_degrees()),
        })
        .collect();
    Ok(BoresightReport {
        boresight_deg: b.map(f64::to_degrees).into(),
        cov_boresight_deg2: deg2(cov_b),
        sigma_boresight_deg: sig(&cov_b),
        spec_angles_well_conditioned: b.y.cos().abs() > 0.05,
        r_s_to_b: [0, 1, 2].map(|i| [rsb[(i, 0)], rsb[(i, 1)], rsb[(i, 2)]]),
        misalignment_deg: d.map(f64::to_degrees).into(),
        cov_misalignment_deg2: deg2(cov_d),
        sigma_misalignment_deg: sig(&cov_d),
        nominal_boresight_deg: spec(&nom).map(f64::to_degrees).into(),
        iterations,
        variance_factor: if dof > 0 { ss / dof as f64 } else { f64::NAN },
        dof,
        legs_n: w.map(|v| v.into()),
        sites: site_results,
    })
}
