//! Object-space time synchronisation (conventions §2; paper 004, section 3.2): estimates the scanner
//! clock `t = t0 + T (n + f(beta))` from a few surveyed sync targets, so that no timing
//! hardware is needed. Times are GPS seconds, angles radians, positions ECEF metres.
//!
//! Steps of [`estimate`]: (1) plane crossings: when the scan plane sweeps each sync point,
//! from the trajectory (zeros of the orthogonal distance `d_p(t)`); (2) detection: the
//! high-intensity cluster near the profile where the approximate clock puts each crossing;
//! (3) the paper's regression `t_c = t0 + T (n_i + f(beta_i))` with leave-one-out outlier
//! rejection and re-association of clusters with the fitted clock; (4) optionally the refined
//! estimator ([`refined`]) using every return on the targets' surveyed planes, jointly with
//! the attitude latency when the platform's rotation makes it observable; (5) with hardware
//! (PPS) profile tags, a comparison of both. docs/sync.md gives the method and an example.

pub mod detect;
pub mod geometry;
pub mod hardware;
pub mod paper;
pub mod plots;
pub mod refined;

use crate::geo::ellipsoid::{geodetic_to_ecef, r_enu_to_e, Geodetic};
use crate::georef::Sensor;
use crate::io::patches::PlanarPatch;
use crate::io::points::ControlPoint;
use crate::io::profiles::ProfileFile;
use crate::timing::Mirror;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use detect::{Cluster, DetectParams};
use geometry::{Crossing, TargetReturn};
pub use hardware::HardwareComparison;
use nalgebra::{DVector, Matrix2, Vector3};
use paper::Obs;
use refined::{Model, Plane, SightingData};
use serde::{Deserialize, Serialize};

/// Which estimate the result carries as its answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// One observation per sighting (the paper's method).
    Paper,
    /// Every return on the targets' surveyed planes.
    Refined,
}

/// A surveyed sync target: its centre (sync point) and, for the refined estimator, the unit
/// normal of its flat face.
#[derive(Debug, Clone, PartialEq)]
pub struct SyncTarget {
    /// Identifier (from the control-point file).
    pub id: String,
    /// Centre (ECEF, m).
    pub centre_e_m: Vector3<f64>,
    /// 1-sigma position uncertainty of the centre (m).
    pub sigma_m: f64,
    /// Unit normal of the face (ECEF), when surveyed.
    pub normal_e: Option<Vector3<f64>>,
    /// Half length (horizontal, in the face) and half height of the face (m), when surveyed:
    /// returns within `EDGE_MARGIN_M` of its boundary are not used by the refined estimator.
    pub half_size_m: Option<[f64; 2]>,
}

impl SyncTarget {
    /// Targets from control points, with face normals from the patches of the same id.
    pub fn from_surveys(points: &[ControlPoint], patches: &[PlanarPatch]) -> Vec<SyncTarget> {
        points
            .iter()
            .map(|p| {
                let patch = patches.iter().find(|q| q.id == p.id);
                let normal_e = patch.map(|q| {
                    let n = Vector3::from(q.normal_enu);
                    (r_enu_to_e(q.lat_rad, q.lon_rad) * n).normalize()
                });
                SyncTarget {
                    id: p.id.clone(),
                    centre_e_m: geodetic_to_ecef(Geodetic {
                        lat_rad: p.lat_rad,
                        lon_rad: p.lon_rad,
                        h_m: p.h_m,
                    }),
                    sigma_m: p.sigma_m,
                    normal_e,
                    half_size_m: patch.map(|q| [q.half_length_m, q.half_height_m]),
                }
            })
            .collect()
    }
}

/// Settings of [`estimate`].
#[derive(Debug, Clone, PartialEq)]
pub struct SyncOptions {
    /// Approximate t0 (s): where detection looks.
    pub t0_approx_s: f64,
    /// Approximate (nominal) mirror period (s).
    pub period_approx_s: f64,
    /// Mirror geometry.
    pub mirror: Mirror,
    /// Detection looks this far (s) either side of the predicted sighting.
    pub window_s: f64,
    /// Returns at or above this intensity can belong to a target.
    pub min_intensity: u16,
    /// Targets further than this from the scanner are not looked for (m).
    pub max_range_m: f64,
    /// Largest gap between returns of one target across the profile (m).
    pub cluster_gap_m: f64,
    /// Which estimate is the answer.
    pub method: Method,
    /// Estimate the attitude latency jointly (refined method only).
    pub estimate_latency: bool,
    /// Attitude latency assumed when not estimated (s).
    pub attitude_latency_s: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Mirror and cone angle noise, 1 sigma (rad).
    pub sigma_angle_rad: f64,
    /// Sightings must span at least this long (s), or T is not constrained.
    pub min_span_s: f64,
    /// Normalised residual above which a sighting is an outlier.
    pub outlier_sigma: f64,
    /// The latency is reported only with a sigma below this (s).
    pub max_latency_sigma_s: f64,
}

impl SyncOptions {
    /// Defaults for everything but the approximate clock and mirror.
    pub fn new(t0_approx_s: f64, period_approx_s: f64, mirror: Mirror) -> Self {
        SyncOptions {
            t0_approx_s,
            period_approx_s,
            mirror,
            window_s: 1.0,
            min_intensity: 60000,
            max_range_m: 30.0,
            cluster_gap_m: 0.3,
            method: Method::Refined,
            estimate_latency: false,
            attitude_latency_s: 0.0,
            sigma_range_m: 0.005,
            sigma_angle_rad: 0.002f64.to_radians(),
            min_span_s: 30.0,
            outlier_sigma: 5.0,
            max_latency_sigma_s: 0.002,
        }
    }
}

/// What became of a predicted pass over a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SightingStatus {
    /// Used in the fit.
    Accepted,
    /// Detected but inconsistent with the others (false target or wrong cluster).
    Outlier,
    /// No high-intensity cluster in the search window.
    NotFound,
}

/// One predicted pass over a sync target and its detection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sighting {
    /// Target id.
    pub target: String,
    /// Pass over this target, from 1, in route order.
    pub pass: u32,
    /// Plane-crossing time from the trajectory (s).
    pub crossing_time_s: f64,
    /// Range to the target at the crossing (m).
    pub range_m: f64,
    /// Profile where the approximate clock puts the crossing.
    pub predicted_profile: f64,
    /// Clusters found in the search window.
    pub candidates: usize,
    /// Sighting profile `n_i` (rounded mean profile of the chosen cluster).
    pub profile: Option<u32>,
    /// Mean mirror angle of the chosen cluster (deg).
    pub beta_deg: Option<f64>,
    /// `n_i + f(beta_i)`: where in the profile sequence the sighting lies (profiles).
    pub profile_position: Option<f64>,
    /// Returns in the chosen cluster.
    pub returns_count: usize,
    /// Residual of the crossing time against the paper fit (s).
    pub residual_s: Option<f64>,
    /// Residual / its sigma.
    pub normalised_residual: Option<f64>,
    /// 1-sigma of the observation (quantisation, navigation, survey) (s).
    pub sigma_s: f64,
    /// Outcome.
    pub status: SightingStatus,
    /// The chosen cluster's returns (not serialised).
    #[serde(skip)]
    pub returns: Vec<TargetReturn>,
    /// Of those, the front-face returns the refined estimator used (not serialised).
    #[serde(skip)]
    pub refined_returns: Vec<TargetReturn>,
}

/// An estimate of (t0, T) with its covariance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ClockEstimate {
    /// GPS time of the start of profile 0 (s).
    pub t0_s: f64,
    /// Mirror period (s).
    pub period_s: f64,
    /// 1-sigma of t0 (s).
    pub sigma_t0_s: f64,
    /// 1-sigma of T (s).
    pub sigma_period_s: f64,
    /// Covariance of (t0, T): [[s^2, s^2], [s^2, s^2]].
    pub cov_t0_period: [[f64; 2]; 2],
    /// Correlation of t0 and T.
    pub correlation: f64,
    /// Sum of squared normalised residuals.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
}

impl ClockEstimate {
    fn new(t0_s: f64, period_s: f64, cov: &Matrix2<f64>, chi2: f64, dof: usize) -> Self {
        let (s0, s1) = (cov[(0, 0)].sqrt(), cov[(1, 1)].sqrt());
        ClockEstimate {
            t0_s,
            period_s,
            sigma_t0_s: s0,
            sigma_period_s: s1,
            cov_t0_period: [[cov[(0, 0)], cov[(0, 1)]], [cov[(1, 0)], cov[(1, 1)]]],
            correlation: cov[(0, 1)] / (s0 * s1),
            chi2,
            dof,
        }
    }

    /// Covariance of (t0, T) as a matrix.
    pub fn cov(&self) -> Matrix2<f64> {
        let c = self.cov_t0_period;
        Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1])
    }
}

/// The refined estimate and what the data constrain.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinedEstimate {
    /// (t0, T) and covariance.
    pub clock: ClockEstimate,
    /// Attitude latency (s), when estimated and constrained.
    pub attitude_latency_s: Option<f64>,
    /// Its 1-sigma (s).
    pub sigma_attitude_latency_s: Option<f64>,
    /// Why the latency is not reported, when it was asked for but is not constrained.
    pub latency_note: Option<String>,
    /// Parameters of the final fit, in order.
    pub parameters: Vec<String>,
    /// Correlation matrix of the parameters.
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the unit-diagonal information matrix.
    pub condition_number: f64,
    /// Variance inflation factor of each parameter.
    pub variance_inflation: Vec<f64>,
    /// Returns used.
    pub returns_used: usize,
}

/// Result of [`estimate`]: the answer (per `method`) and everything behind it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SyncResult {
    /// Method of the answer.
    pub method: Method,
    /// The answer: t0, T and their covariance (feeds georeferencing and uncertainty).
    pub clock: ClockEstimate,
    /// Attitude latency (s) when estimated and constrained.
    pub attitude_latency_s: Option<f64>,
    /// Its 1-sigma (s).
    pub sigma_attitude_latency_s: Option<f64>,
    /// The paper's method.
    pub paper: ClockEstimate,
    /// The refined estimator, when asked for.
    pub refined: Option<RefinedEstimate>,
    /// Every predicted pass and its detection.
    pub sightings: Vec<Sighting>,
    /// Hardware (PPS) comparison, when the profiles carry time tags.
    pub hardware: Option<HardwareComparison>,
}

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
    let refined = match o.method {
        Method::Paper => None,
        Method::Refined => Some(refine(traj, sensor, targets, &mut sightings, &paper, o)?),
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
        method: o.method,
        clock,
        attitude_latency_s: refined.as_ref().and_then(|r| r.attitude_latency_s),
        sigma_attitude_latency_s: refined.as_ref().and_then(|r| r.sigma_attitude_latency_s),
        paper,
        refined,
        sightings,
        hardware,
    })
}

fn check_options(o: &SyncOptions) -> Result<()> {
    let bad = |k: &str, m: String| Err(Error::config("sync options", k, m));
    if !(o.period_approx_s > 0.0 && o.period_approx_s <= 1.0) {
        return bad(
            "period_approx_s",
            format!("must be in (0, 1] s, got {}", o.period_approx_s),
        );
    }
    if !o.t0_approx_s.is_finite() {
        return bad("t0_approx_s", "must be finite".into());
    }
    if !(o.window_s > 0.0 && o.window_s.is_finite()) {
        return bad("window_s", format!("must be > 0, got {}", o.window_s));
    }
    if o.estimate_latency && o.method == Method::Paper {
        return bad(
            "estimate_latency",
            "the latency is estimated by the refined method only".into(),
        );
    }
    Ok(())
}

type Predict<'a> = dyn Fn(&Crossing, f64, f64) -> f64 + 'a;

/// Chooses a cluster per crossing (nearest the predicted profile), fits, and re-associates
/// with the fitted clock until the choice is stable.
fn associate(
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    o: &SyncOptions,
    t_ref: f64,
    predict: &Predict,
) -> Result<(paper::LineFit, Vec<Option<usize>>, Vec<usize>)> {
    let mut clock = (o.t0_approx_s, o.period_approx_s);
    let mut chosen: Vec<Option<usize>> = Vec::new();
    for _ in 0..10 {
        let next: Vec<Option<usize>> = crossings
            .iter()
            .zip(cands)
            .map(|(c, cs)| {
                let n = predict(c, clock.0, clock.1);
                (0..cs.len()).min_by(|&a, &b| {
                    (cs[a].mean_profile - n)
                        .abs()
                        .total_cmp(&(cs[b].mean_profile - n).abs())
                })
            })
            .collect();
        let obs = observations(crossings, cands, &next, o, t_ref);
        let active: Vec<usize> = (0..obs.len()).filter(|&i| next[i].is_some()).collect();
        if active.len() < 2 {
            return Err(not_enough(active.len(), crossings.len(), o));
        }
        let (fit, outliers) =
            paper::robust_fit(&obs, &active, o.outlier_sigma).ok_or_else(|| Error::Numerical {
                what: "sync".into(),
                problem: "all sightings lie at one place: the mirror period T is not \
                          constrained; survey sync points seen at times far apart"
                    .into(),
            })?;
        let stable = next == chosen;
        chosen = next;
        clock = (t_ref + fit.x[0], fit.x[1]);
        if stable {
            return Ok((fit, chosen, outliers));
        }
    }
    Err(Error::Numerical {
        what: "sync detection".into(),
        problem: "the choice of target clusters does not settle; check the targets".into(),
    })
}

fn not_enough(found: usize, predicted: usize, o: &SyncOptions) -> Error {
    Error::Numerical {
        what: "sync".into(),
        problem: format!(
            "{found} sighting(s) detected for {predicted} predicted pass(es) over the sync \
             points: need at least 2 usable sync points seen at times far apart. Check that \
             the approximate t0 ({:.3} s) and period ({} s) are within window_s = {} s of \
             the truth, that the targets are within max_range_m = {} m of the route and \
             brighter than min_intensity = {}",
            o.t0_approx_s, o.period_approx_s, o.window_s, o.max_range_m, o.min_intensity
        ),
    }
}

fn observations(
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    chosen: &[Option<usize>],
    o: &SyncOptions,
    t_ref: f64,
) -> Vec<Obs> {
    crossings
        .iter()
        .zip(cands)
        .zip(chosen)
        .map(|((c, cs), ch)| {
            let (nu, _) = ch.map_or((0.0, 0), |k| {
                let cl = &cs[k];
                (cl.profile as f64 + o.mirror.fraction(cl.beta_rad), 0)
            });
            Obs {
                nu,
                y_s: c.t_s - t_ref,
                sigma_s: observation_sigma(c, o.period_approx_s),
            }
        })
        .collect()
}

/// Sighting sigma (s): profile quantisation `T / sqrt(12)` and `sigma_d / |d'|`.
fn observation_sigma(c: &Crossing, period: f64) -> f64 {
    (period * period / 12.0 + (c.sigma_d_m / c.rate_mps).powi(2)).sqrt()
}

#[allow(clippy::too_many_arguments)]
fn sightings(
    targets: &[SyncTarget],
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    chosen: &[Option<usize>],
    outliers: &[usize],
    fit: &paper::LineFit,
    o: &SyncOptions,
    t_ref: f64,
) -> Vec<Sighting> {
    let obs = observations(crossings, cands, chosen, o, t_ref);
    let mut passes = vec![0u32; targets.len()];
    crossings
        .iter()
        .enumerate()
        .map(|(i, c)| {
            passes[c.point] += 1;
            let cl = chosen[i].map(|k| &cands[i][k]);
            let status = match (cl, outliers.contains(&i)) {
                (None, _) => SightingStatus::NotFound,
                (Some(_), true) => SightingStatus::Outlier,
                (Some(_), false) => SightingStatus::Accepted,
            };
            let z = cl.map(|_| fit.z(&obs[i]));
            Sighting {
                target: targets[c.point].id.clone(),
                pass: passes[c.point],
                crossing_time_s: c.t_s,
                range_m: c.range_m,
                predicted_profile: (c.t_s - o.t0_approx_s) / o.period_approx_s
                    - o.mirror.fraction(c.beta_rad),
                candidates: cands[i].len(),
                profile: cl.map(|k| k.profile),
                beta_deg: cl.map(|k| k.beta_rad.to_degrees()),
                profile_position: cl.map(|_| obs[i].nu),
                returns_count: cl.map_or(0, |k| k.returns.len()),
                residual_s: z.map(|z| z * obs[i].sigma_s),
                normalised_residual: z,
                sigma_s: obs[i].sigma_s,
                status,
                returns: cl.map_or(Vec::new(), |k| k.returns.clone()),
                refined_returns: Vec::new(),
            }
        })
        .collect()
}

/// Fewer than 2 sync points, or all sightings at one place: a clear error.
fn check_usable(s: &[Sighting], o: &SyncOptions) -> Result<()> {
    let ok: Vec<&Sighting> = s
        .iter()
        .filter(|s| s.status == SightingStatus::Accepted)
        .collect();
    let mut ids: Vec<&str> = ok.iter().map(|s| s.target.as_str()).collect();
    ids.sort();
    ids.dedup();
    if ids.len() < 2 {
        return Err(Error::Numerical {
            what: "sync".into(),
            problem: format!(
                "only {} usable sync point(s) ({}) among {} predicted passes: need at least 2 \
                 sync points, each detected as a bright cluster, to estimate t0 and T",
                ids.len(),
                ids.join(", "),
                s.len()
            ),
        });
    }
    let (lo, hi) = ok
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
            (a.min(s.crossing_time_s), b.max(s.crossing_time_s))
        });
    if hi - lo < o.min_span_s {
        return Err(Error::Numerical {
            what: "sync".into(),
            problem: format!(
                "all sightings lie within {:.1} s of each other (one place): the mirror period \
                 T is not constrained; sync points must be seen at least min_span_s = {} s \
                 apart (e.g. at the start and the end of the route)",
                hi - lo,
                o.min_span_s
            ),
        });
    }
    Ok(())
}

/// The refined estimate from the accepted sightings of targets with a surveyed face normal;
/// records in each sighting the returns it used. Two passes: from the paper's clock with
/// returns far from their sighting's median dropped, then, at that solution (accurate to
/// millimetres along the route), also without returns near the face's edges.
fn refine(
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
