//! Tripod target geometry (paper 002, section 4.1): from the three points `C_i` where the scan
//! plane cuts the tripod's leg axes (ellipse centres) to the apex `O` and the leg directions.
//!
//! Frame: scanner frame `s` (conventions §3). A profile scanner with `alpha = 0` scans the plane
//! `x_s = 0`, so `C_i = (0, y_i, z_i)` (m). The paper's scan-plane frame has the plane as its
//! x-z plane and the out-of-plane axis `y`; here the plane is `y_s`-`z_s` and the out-of-plane
//! axis is `x_s`.
//!
//! 1. Apex distances `d_i = |O - C_i|` from the cosine law
//!    `|C_i - C_j|^2 = d_i^2 + d_j^2 - 2 d_i d_j cos(theta_ij)` (three equations; Newton from
//!    several starts, all distinct positive roots kept: this is the three-point resection problem,
//!    which has up to four roots).
//! 2. Apex by three-sphere intersection: two linear equations (sphere 1 minus spheres 2 and 3)
//!    give `(y_O, z_O)`, then `x_O = +-sqrt(d_1^2 - (y_O - y_1)^2 - (z_O - z_1)^2)`: the apex is
//!    on one side of the scan plane or the other.
//! 3. Root choice: for every (distance root, sign) the leg directions `(C_i - O)/|C_i - O|` are
//!    taken to NED with the site's IMU attitude and the nominal boresight; the candidate whose
//!    mean leg direction is closest to the tripod axis (apex towards feet, e.g. NED down for a
//!    tripod standing on the floor) wins. A wrong side reverses all three legs (mean direction
//!    ~180 deg off); a wrong resection root tilts the tripod by tens of degrees, against a
//!    boresight prior good to a few degrees.

use crate::{Error, Result};
use nalgebra::{Matrix3, Vector2, Vector3};

/// The tripod and the boresight prior (shared by the leg fit in `ellipse` and the
/// adjustment in `boresight`).
#[derive(Debug, Clone, PartialEq)]
pub struct BoresightSetup {
    /// Cosines of the inter-leg angles for leg pairs (1,2), (1,3), (2,3).
    pub cos_leg_angles: [f64; 3],
    /// Unit tripod axis (apex towards feet) in NED.
    pub tripod_axis_n: Vector3<f64>,
    /// Nominal boresight `R_nom` (convention `R_s^b` before calibration).
    pub r_nominal_s_to_b: Matrix3<f64>,
}

/// Leg pairs of the cosine-law equations: (1,2), (1,3), (2,3) as 0-based indices.
pub const LEG_PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// Solves the cosine law for the apex distances `d` (m) by Newton from `start`;
/// `cos_leg` = cosines of the inter-leg angles of [`LEG_PAIRS`]. `None` if it does not converge
/// to positive distances.
pub fn newton_distances(
    c: &[Vector2<f64>; 3],
    cos_leg: [f64; 3],
    start: [f64; 3],
) -> Option<[f64; 3]> {
    let dd = LEG_PAIRS.map(|(i, j)| (c[i] - c[j]).norm_squared());
    let mut d = Vector3::from(start);
    for _ in 0..60 {
        let mut f = Vector3::zeros();
        let mut jac = Matrix3::zeros();
        for (k, &(i, j)) in LEG_PAIRS.iter().enumerate() {
            f[k] = d[i] * d[i] + d[j] * d[j] - 2.0 * d[i] * d[j] * cos_leg[k] - dd[k];
            jac[(k, i)] = 2.0 * d[i] - 2.0 * d[j] * cos_leg[k];
            jac[(k, j)] = 2.0 * d[j] - 2.0 * d[i] * cos_leg[k];
        }
        let step = jac.lu().solve(&f)?;
        d -= step;
        if step.norm() < 1e-13 * (1.0 + d.norm()) {
            return (d.min() > 0.0).then(|| d.into());
        }
    }
    None
}

/// All distinct positive cosine-law roots found from a fixed set of starts (m).
pub fn distance_roots(c: &[Vector2<f64>; 3], cos_leg: [f64; 3]) -> Vec<[f64; 3]> {
    // Symmetric start: each d from a pair's chord and angle, d = chord / (2 sin(theta/2)).
    let base = LEG_PAIRS
        .iter()
        .zip(cos_leg)
        .map(|(&(i, j), cs)| (c[i] - c[j]).norm() / (2.0 * ((1.0 - cs) / 2.0).sqrt().max(1e-3)))
        .sum::<f64>()
        / 3.0;
    let mut roots: Vec<[f64; 3]> = Vec::new();
    for scale in [1.0, 0.5, 2.0, 0.25, 4.0] {
        for tilt in [
            [1.0, 1.0, 1.0],
            [2.0, 1.0, 1.0],
            [1.0, 2.0, 1.0],
            [1.0, 1.0, 2.0],
            [0.5, 1.0, 2.0],
            [2.0, 0.5, 1.0],
        ] {
            let start = tilt.map(|t| t * scale * base);
            if let Some(d) = newton_distances(c, cos_leg, start) {
                let dv = Vector3::from(d);
                if roots
                    .iter()
                    .all(|r| (Vector3::from(*r) - dv).norm() > 1e-6 * dv.norm())
                {
                    roots.push(d);
                }
            }
        }
    }
    roots
}

/// Apex `O` in `s` (m) from the cut points, the distances and the side (`sign` of `x_O`).
pub fn apex_s(c: &[Vector2<f64>; 3], d: &[f64; 3], sign: f64) -> Result<Vector3<f64>> {
    let a = nalgebra::Matrix2::new(
        2.0 * (c[1].x - c[0].x),
        2.0 * (c[1].y - c[0].y),
        2.0 * (c[2].x - c[0].x),
        2.0 * (c[2].y - c[0].y),
    );
    let rhs = |k: usize| d[0] * d[0] - d[k] * d[k] + c[k].norm_squared() - c[0].norm_squared();
    let yz = a
        .lu()
        .solve(&Vector2::new(rhs(1), rhs(2)))
        .ok_or_else(|| Error::Numerical {
            what: "tripod apex".into(),
            problem: "the three cut points are collinear".into(),
        })?;
    let h2 = d[0] * d[0] - (yz - c[0]).norm_squared();
    if h2 < -1e-9 * d[0] * d[0] {
        return Err(Error::Numerical {
            what: "tripod apex".into(),
            problem: "the three spheres do not intersect".into(),
        });
    }
    Ok(Vector3::new(sign * h2.max(0.0).sqrt(), yz.x, yz.y))
}

/// Unit leg directions `(C_i - O)/|C_i - O|` in `s` (apex towards the cut, i.e. towards the
/// feet).
pub fn leg_directions_s(c: &[Vector2<f64>; 3], apex: &Vector3<f64>) -> [Vector3<f64>; 3] {
    [0, 1, 2].map(|i| (Vector3::new(0.0, c[i].x, c[i].y) - apex).normalize())
}

/// The chosen reconstruction of one site.
#[derive(Debug, Clone, PartialEq)]
pub struct TripodSolution {
    /// Apex distances `d_i` (m).
    pub distances_m: [f64; 3],
    /// Side of the scan plane: sign of `x_O`.
    pub side: f64,
    /// Apex in `s` (m).
    pub apex_s_m: Vector3<f64>,
    /// Unit leg directions in `s`.
    pub legs_s: [Vector3<f64>; 3],
}

/// Reconstructs the tripod at one site and picks the root (module doc, step 3) using
/// `r_s_to_n_prior` (IMU attitude times nominal boresight) and the tripod axis in NED.
pub fn solve_site(
    c: &[Vector2<f64>; 3],
    cos_leg: [f64; 3],
    r_s_to_n_prior: &Matrix3<f64>,
    axis_n: &Vector3<f64>,
) -> Result<TripodSolution> {
    let mut best: Option<(f64, TripodSolution)> = None;
    for d in distance_roots(c, cos_leg) {
        for side in [1.0, -1.0] {
            let Ok(apex) = apex_s(c, &d, side) else {
                continue;
            };
            let legs = leg_directions_s(c, &apex);
            let mean_n = r_s_to_n_prior * (legs[0] + legs[1] + legs[2]);
            let score = mean_n.normalize().dot(axis_n);
            if best.as_ref().is_none_or(|(s, _)| score > *s) {
                best = Some((
                    score,
                    TripodSolution {
                        distances_m: d,
                        side,
                        apex_s_m: apex,
                        legs_s: legs,
                    },
                ));
            }
        }
    }
    best.map(|(_, s)| s).ok_or_else(|| Error::Numerical {
        what: "tripod apex".into(),
        problem: "the cosine-law equations have no positive solution (leg angles wrong?)".into(),
    })
}

/// Leg directions for perturbed cut points, staying on the root and side of `sol`.
pub fn legs_near(
    c: &[Vector2<f64>; 3],
    cos_leg: [f64; 3],
    sol: &TripodSolution,
) -> Result<[Vector3<f64>; 3]> {
    let d = newton_distances(c, cos_leg, sol.distances_m).ok_or_else(|| Error::Numerical {
        what: "tripod apex".into(),
        problem: "cosine-law root lost under a small perturbation".into(),
    })?;
    Ok(leg_directions_s(c, &apex_s(c, &d, sol.side)?))
}

/// Covariance (9x9, legs stacked) of the unit leg directions in `s` from independent in-plane
/// noise of covariance `cov_m2` (m^2, `(y_s, z_s)`) on each cut point, by central differences.
pub fn leg_covariance_s(
    c: &[Vector2<f64>; 3],
    cov_m2: &[nalgebra::Matrix2<f64>; 3],
    cos_leg: [f64; 3],
    sol: &TripodSolution,
) -> Result<nalgebra::SMatrix<f64, 9, 9>> {
    let h = 1e-6;
    let mut cov = nalgebra::SMatrix::<f64, 9, 9>::zeros();
    for leg in 0..3 {
        let mut g = nalgebra::SMatrix::<f64, 9, 2>::zeros();
        for axis in 0..2 {
            let mut col = nalgebra::SVector::<f64, 9>::zeros();
            for (sgn, w) in [(1.0, 0.5 / h), (-1.0, -0.5 / h)] {
                let mut cp = *c;
                cp[leg][axis] += sgn * h;
                let u = legs_near(&cp, cos_leg, sol)?;
                for (i, ui) in u.iter().enumerate() {
                    col.fixed_rows_mut::<3>(3 * i).axpy(w, ui, 1.0);
                }
            }
            g.set_column(axis, &col);
        }
        cov += g * cov_m2[leg] * g.transpose();
    }
    Ok(cov)
}
