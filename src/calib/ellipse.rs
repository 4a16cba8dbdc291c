//! Tripod leg cross-sections from raw static scan returns: clustering and ellipse-centre fit.
//!
//! Frame: scanner frame `s`, `alpha0 = 0`: a return `(beta, rho)` is the in-plane point
//! `(rho + K) * (-sin beta, cos beta)` in `(y_s, z_s)` (m), conventions §3.
//!
//! **Clustering.** Returns are sorted by `beta` (cyclically: a leg across `beta = +-pi` stays
//! whole) and split into runs wherever two neighbours differ in range by more than
//! `jump = max(4 r, 10 sigma_range)`, a return is missing, or `beta` jumps by more than twice
//! the median step. A run
//! is a leg candidate when it has `>= MIN_LEG_RETURNS` returns, its chord is at most
//! `MAX_CHORD_RADII r` (the cut of a leg up to ~84 deg from its normal section is an ellipse
//! up to `2 r / cos 84 deg` long) and it is in the foreground: on both sides the neighbour is
//! missing or farther by more than `jump` (a leg occludes what is behind it; a piece of ground
//! or wall between two legs has nearer neighbours, a long ground run is too wide; ground seen
//! at grazing incidence breaks into runs shorter than `MIN_LEG_RETURNS`). The three candidates with the most returns are the legs; fewer than three is an error.
//!
//! **Fit.** The plane cuts a cylinder of radius `r` in an ellipse with minor semi-axis `r`
//! across the leg's in-plane direction and major semi-axis `r / |cos gamma|` along it (`gamma`
//! = angle between leg axis and plane normal). With the shape known only the centre is free (2
//! parameters), which the near-side arc determines. Gauss-Newton on range residuals
//! `rho_i + K - t_i(c)` (`t_i` = distance along the beam to the model ellipse; a beam that
//! misses the model gets its closest-approach distance, continuous at the tangent), covariance
//! `sigma_range^2 (J^T J)^-1`. The first and last return of a run (grazing, mixed-pixel edges)
//! are dropped. The shape comes from the tripod itself: a start from 10 steps with a circle of
//! radius `r`, then the tripod solution's leg directions give each ellipse, and the centres are
//! refitted, until they move by less than 0.1 um ([`fit_site_centres`]). A circle alone is
//! not good enough: noise-free, a circle of radius `r = 25 mm` fitted to the near side of a cut
//! with `a / r = 1.2` is off by 3.6-4.7 mm, with `a / r = 4` by 12 mm or does not converge (the
//! near side of an ellipse is flatter than the circle). With the shape from the tripod the
//! remaining bias is second order in the leg-direction error, below the test's resolution
//! (a third of the centre sigma, `tests/calib_tripod_scans.rs`).
//!
//! Range noise only: the covariance ignores beam-angle noise and the leg radius's tolerance
//! (a radius error of `dr` shifts every centre by ~`dr` along the mean beam).

use super::tripod::{solve_site, BoresightSetup};
use crate::{Error, Result};
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Fewest returns (before the two edge returns are dropped) for a leg candidate.
pub const MIN_LEG_RETURNS: usize = 6;
/// Longest leg run, in leg radii.
pub const MAX_CHORD_RADII: f64 = 20.0;

/// One return of a static scan (conventions §6 fields).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanReturn {
    /// Mirror angle (rad).
    pub beta_rad: f64,
    /// Range (m); 0 or non-finite = missing.
    pub range_m: f64,
}

/// What the fit knows of the scanner and the legs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegScanModel {
    /// Leg radius `r` (m).
    pub leg_radius_m: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Range zero error `K` (m).
    pub range_zero_error_m: f64,
}

/// In-plane ellipse shape of a leg cut: unit major direction in `(y_s, z_s)` and semi-axes (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutShape {
    /// Unit major-axis direction.
    pub major_dir: Vector2<f64>,
    /// Semi-major axis (m).
    pub semi_major_m: f64,
    /// Semi-minor axis (m): the leg radius.
    pub semi_minor_m: f64,
}

impl CutShape {
    /// Circle of radius `r` (m).
    pub fn circle(r: f64) -> Self {
        Self {
            major_dir: Vector2::x(),
            semi_major_m: r,
            semi_minor_m: r,
        }
    }

    /// Cut of a cylinder of radius `r` (m) with unit axis `leg_s` (frame `s`) by the plane
    /// `x_s = 0`. `None` if the leg lies within ~3 deg of the plane.
    pub fn of_leg(leg_s: &Vector3<f64>, r: f64) -> Option<Self> {
        let cos_gamma = leg_s.x.abs();
        let p = Vector2::new(leg_s.y, leg_s.z);
        (cos_gamma > 0.05).then(|| Self {
            major_dir: if p.norm() > 1e-9 {
                p.normalize()
            } else {
                Vector2::x()
            },
            semi_major_m: r / cos_gamma,
            semi_minor_m: r,
        })
    }

    /// Near-intersection quadratic of the unit beam `u` from the origin with the ellipse
    /// centred at `c`: (distance to the near root or closest approach, discriminant).
    fn beam_quadratic(&self, c: &Vector2<f64>, u: &Vector2<f64>) -> (f64, f64) {
        let m = self.major_dir;
        let n = Vector2::new(-m.y, m.x);
        let (a2, b2) = (self.semi_major_m.powi(2), self.semi_minor_m.powi(2));
        let (um, un, cm, cn) = (u.dot(&m), u.dot(&n), c.dot(&m), c.dot(&n));
        let qa = um * um / a2 + un * un / b2;
        let qb = -2.0 * (cm * um / a2 + cn * un / b2);
        let qc = cm * cm / a2 + cn * cn / b2 - 1.0;
        let disc = qb * qb - 4.0 * qa * qc;
        ((-qb - disc.max(0.0).sqrt()) / (2.0 * qa), disc)
    }

    /// Distance along the unit beam `u` from the origin to the ellipse centred at `c`: the
    /// near intersection, or the closest approach when the beam misses.
    fn beam_distance(&self, c: &Vector2<f64>, u: &Vector2<f64>) -> f64 {
        self.beam_quadratic(c, u).0
    }

    /// Distance (m) along the unit beam `u` to the ellipse centred at `c`, if the beam hits it
    /// in front of the origin.
    pub fn beam_hit(&self, c: &Vector2<f64>, u: &Vector2<f64>) -> Option<f64> {
        let (t, disc) = self.beam_quadratic(c, u);
        (disc >= 0.0 && t > 0.0).then_some(t)
    }
}

/// Fitted centre of one leg cut.
#[derive(Debug, Clone, PartialEq)]
pub struct LegFit {
    /// Ellipse centre `(y_s, z_s)` (m).
    pub centre_s_m: Vector2<f64>,
    /// Its covariance (m^2).
    pub cov_s_m2: Matrix2<f64>,
    /// Returns used.
    pub n_returns: usize,
    /// RMS range residual (m).
    pub rms_m: f64,
}

/// A leg candidate: beams `u` (unit, in-plane) and measured distances `rho + K` (m), in beta order.
#[derive(Debug, Clone, PartialEq)]
pub struct LegRun {
    /// Unit beam directions `(y_s, z_s)`.
    pub beams: Vec<Vector2<f64>>,
    /// `rho + K` (m).
    pub dist_m: Vec<f64>,
}

/// In-plane unit beam `(y_s, z_s)` of mirror angle `beta` (rad), `alpha0 = 0`.
pub fn beam(beta: f64) -> Vector2<f64> {
    Vector2::new(-beta.sin(), beta.cos())
}

/// The returns sorted by `beta`, rotated to start at a missing return (else at the largest
/// range jump) so that a leg across `beta = +-pi` stays in one run.
fn cyclic_order(returns: &[ScanReturn], valid: &dyn Fn(&ScanReturn) -> bool) -> Vec<ScanReturn> {
    let mut rs: Vec<ScanReturn> = returns.to_vec();
    rs.sort_by(|a, b| a.beta_rad.total_cmp(&b.beta_rad));
    let n = rs.len();
    let start = rs.iter().position(|r| !valid(r)).unwrap_or_else(|| {
        (0..n)
            .max_by(|&i, &j| {
                let d = |k: usize| (rs[k].range_m - rs[(k + n - 1) % n].range_m).abs();
                d(i).total_cmp(&d(j))
            })
            .unwrap_or(0)
    });
    rs.rotate_left(start);
    rs
}

/// Median `beta` step between sorted returns (rad).
fn median_step(rs: &[ScanReturn]) -> f64 {
    let mut d: Vec<f64> = rs
        .windows(2)
        .map(|w| crate::geo::rotations::wrap_pi(w[1].beta_rad - w[0].beta_rad).abs())
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// Finds the three leg runs in one site's returns (module doc); `site` names the site in errors.
pub fn leg_runs(site: u64, returns: &[ScanReturn], m: &LegScanModel) -> Result<[LegRun; 3]> {
    let valid = |r: &ScanReturn| r.range_m.is_finite() && r.range_m > 0.0;
    let jump = (4.0 * m.leg_radius_m).max(10.0 * m.sigma_range_m);
    let rs = cyclic_order(returns, &valid);
    let step = median_step(&rs);
    let adjacent = |i: usize| {
        crate::geo::rotations::wrap_pi(rs[i].beta_rad - rs[i - 1].beta_rad).abs() <= 2.0 * step
    };
    // Runs of consecutive valid returns without a range jump, as index ranges.
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut start = None;
    for i in 0..=rs.len() {
        let cont = i < rs.len()
            && valid(&rs[i])
            && start.is_some()
            && adjacent(i)
            && (rs[i].range_m - rs[i - 1].range_m).abs() <= jump;
        if !cont {
            if let Some(s) = start.take() {
                runs.push((s, i));
            }
            if i < rs.len() && valid(&rs[i]) {
                start = Some(i);
            }
        }
    }
    let point = |i: usize| beam(rs[i].beta_rad) * (rs[i].range_m + m.range_zero_error_m);
    let behind = |own: usize, other: Option<usize>| {
        other.is_none_or(|j| {
            !valid(&rs[j]) || !adjacent(own.max(j)) || rs[j].range_m > rs[own].range_m + jump
        })
    };
    let mut cands: Vec<LegRun> = runs
        .into_iter()
        .filter(|&(s, e)| {
            e - s >= MIN_LEG_RETURNS
                && (point(e - 1) - point(s)).norm() <= MAX_CHORD_RADII * m.leg_radius_m
                && behind(s, s.checked_sub(1))
                && behind(e - 1, (e < rs.len()).then_some(e))
        })
        .map(|(s, e)| LegRun {
            beams: (s + 1..e - 1).map(|i| beam(rs[i].beta_rad)).collect(),
            dist_m: (s + 1..e - 1)
                .map(|i| rs[i].range_m + m.range_zero_error_m)
                .collect(),
        })
        .collect();
    if cands.len() < 3 {
        return Err(Error::Invalid(format!(
            "tripod scan: site {site}: the scan plane must cut three legs, found {} leg \
             cross-section(s) (runs of >= {MIN_LEG_RETURNS} foreground returns at most {:.3} m wide)",
            cands.len(),
            MAX_CHORD_RADII * m.leg_radius_m
        )));
    }
    cands.sort_by_key(|c| std::cmp::Reverse(c.beams.len()));
    cands.truncate(3);
    cands
        .try_into()
        .map_err(|_| Error::Invalid("tripod scan: three legs expected".into()))
}

/// Fits the centre of a cut of known `shape` to a leg run by Gauss-Newton (module doc).
pub fn fit_leg_centre(run: &LegRun, shape: &CutShape, m: &LegScanModel) -> Result<LegFit> {
    let mean_u = run.beams.iter().sum::<Vector2<f64>>().normalize();
    let mean_d = run.dist_m.iter().sum::<f64>() / run.dist_m.len() as f64;
    fit_from(run, shape, m, mean_u * (mean_d + m.leg_radius_m))
}

/// Range residuals `rho_i + K - t_i(c)` of a run.
fn residuals(run: &LegRun, shape: &CutShape, c: &Vector2<f64>) -> Vec<f64> {
    run.beams
        .iter()
        .zip(&run.dist_m)
        .map(|(u, d)| d - shape.beam_distance(c, u))
        .collect()
}

/// One Gauss-Newton step from `c`: (step, inverse normal matrix).
fn gn_step(
    run: &LegRun,
    shape: &CutShape,
    c: &Vector2<f64>,
) -> Result<(Vector2<f64>, Matrix2<f64>)> {
    let h = 1e-7;
    let r0 = residuals(run, shape, c);
    let cols = [0, 1].map(|k| {
        let mut e = Vector2::zeros();
        e[k] = h;
        let (p, q) = (
            residuals(run, shape, &(c + e)),
            residuals(run, shape, &(c - e)),
        );
        p.iter()
            .zip(q)
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect::<Vec<_>>()
    });
    let (mut jtj, mut jtr) = (Matrix2::zeros(), Vector2::zeros());
    for (i, r) in r0.iter().enumerate() {
        let j = Vector2::new(cols[0][i], cols[1][i]);
        jtj += j * j.transpose();
        jtr += j * *r;
    }
    let inv = jtj.try_inverse().ok_or_else(|| Error::Numerical {
        what: "leg centre fit".into(),
        problem: "singular normal matrix (returns on a line?)".into(),
    })?;
    Ok((-(inv * jtr), inv))
}

/// Gauss-Newton from `c` until the step is below 1 nm (30 iterations at most).
fn fit_from(
    run: &LegRun,
    shape: &CutShape,
    m: &LegScanModel,
    mut c: Vector2<f64>,
) -> Result<LegFit> {
    for _ in 0..30 {
        let (step, inv) = gn_step(run, shape, &c)?;
        c += step;
        if step.norm() < 1e-9 {
            let r = residuals(run, shape, &c);
            return Ok(LegFit {
                centre_s_m: c,
                cov_s_m2: inv * m.sigma_range_m.powi(2),
                n_returns: r.len(),
                rms_m: (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt(),
            });
        }
    }
    Err(Error::Numerical {
        what: "leg centre fit".into(),
        problem: "Gauss-Newton did not converge in 30 iterations".into(),
    })
}

/// Approximate centre with a circle of radius `r`: 10 Gauss-Newton steps, converged or not
/// (on an elongated cut many beams miss the circle and the steps crawl; a few mm is enough
/// to get the leg directions that give the right shape).
fn circle_start(run: &LegRun, m: &LegScanModel) -> Result<Vector2<f64>> {
    let circle = CutShape::circle(m.leg_radius_m);
    let mean_u = run.beams.iter().sum::<Vector2<f64>>().normalize();
    let mean_d = run.dist_m.iter().sum::<f64>() / run.dist_m.len() as f64;
    let mut c = mean_u * (mean_d + m.leg_radius_m);
    for _ in 0..10 {
        c += gn_step(run, &circle, &c)?.0;
    }
    Ok(c)
}

/// Shape refits (centres -> tripod -> ellipse shapes -> centres) before giving up.
const MAX_SHAPE_REFITS: usize = 8;

/// Leg labellings tried by [`fit_site_centres`]: all permutations of the three runs.
const PERMUTATIONS: [[usize; 3]; 6] = [
    [0, 1, 2],
    [0, 2, 1],
    [1, 0, 2],
    [1, 2, 0],
    [2, 0, 1],
    [2, 1, 0],
];

/// Fitted centres of one site, labelled.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteCentres {
    /// Legs 1, 2, 3.
    pub fits: [LegFit; 3],
    /// Their unit directions in NED with the site's IMU attitude and the nominal boresight
    /// (the labelling reference for the next sites).
    pub legs_n_prior: [Vector3<f64>; 3],
}

/// Ellipse centres of legs 1, 2, 3 at one site from its raw returns: runs ([`leg_runs`]), a
/// circle start, then refits with the ellipse shapes from the tripod solution (`tripod::solve_site`
/// with `r_b_to_n` (the site's IMU attitude, convention) times the nominal boresight as the prior)
/// until the centres settle. Labelling: the legs are fixed in NED, so with `reference` (the
/// `legs_n_prior` of an earlier site) the permutation whose prior NED leg directions best match
/// it wins (the prior needs to be good to a few tens of degrees: legs are ~100 deg apart);
/// without (the first site) the one whose mean leg direction is closest to the tripod axis
/// (any labelling when the inter-leg angles are equal; with unequal angles a wrong labelling
/// tilts the tripod, which this catches only when the tilt is large).
pub fn fit_site_centres(
    site: u64,
    returns: &[ScanReturn],
    m: &LegScanModel,
    setup: &BoresightSetup,
    r_b_to_n: &Matrix3<f64>,
    reference: Option<&[Vector3<f64>; 3]>,
) -> Result<SiteCentres> {
    let runs = leg_runs(site, returns, m)?;
    let named = |e: Error| Error::Invalid(format!("tripod scan: site {site}: {e}"));
    let prior = r_b_to_n * setup.r_nominal_s_to_b;
    let mut c = [
        circle_start(&runs[0], m).map_err(named)?,
        circle_start(&runs[1], m).map_err(named)?,
        circle_start(&runs[2], m).map_err(named)?,
    ];
    let mut best = (f64::NEG_INFINITY, PERMUTATIONS[0]);
    for p in PERMUTATIONS {
        let centres = p.map(|k| c[k]);
        if let Ok(sol) = solve_site(&centres, setup.cos_leg_angles, &prior, &setup.tripod_axis_n) {
            let legs_n = sol.legs_s.map(|l| prior * l);
            let score = match reference {
                Some(r) => (0..3).map(|i| legs_n[i].dot(&r[i])).sum::<f64>(),
                None => legs_n
                    .iter()
                    .sum::<Vector3<f64>>()
                    .normalize()
                    .dot(&setup.tripod_axis_n),
            };
            if score > best.0 {
                best = (score, p);
            }
        }
    }
    let perm = best.1;
    c = perm.map(|k| c[k]);
    let runs = perm.map(|k| runs[k].clone());
    for _ in 0..MAX_SHAPE_REFITS {
        let sol =
            solve_site(&c, setup.cos_leg_angles, &prior, &setup.tripod_axis_n).map_err(named)?;
        let mut fits = Vec::with_capacity(3);
        for i in 0..3 {
            let shape = CutShape::of_leg(&sol.legs_s[i], m.leg_radius_m).ok_or_else(|| {
                named(Error::Invalid(format!(
                    "leg {} lies in the scan plane",
                    i + 1
                )))
            })?;
            fits.push(fit_from(&runs[i], &shape, m, c[i]).map_err(named)?);
        }
        let moved = (0..3)
            .map(|i| (fits[i].centre_s_m - c[i]).norm())
            .fold(0.0, f64::max);
        c = [0, 1, 2].map(|i| fits[i].centre_s_m);
        if moved < 1e-7 {
            let fits = fits
                .try_into()
                .map_err(|_| named(Error::Invalid("three fits expected".into())))?;
            let legs_n_prior = sol.legs_s.map(|l| prior * l);
            return Ok(SiteCentres { fits, legs_n_prior });
        }
    }
    Err(named(Error::Numerical {
        what: "leg centres".into(),
        problem: format!("centres still moving after {MAX_SHAPE_REFITS} shape refits"),
    }))
}
