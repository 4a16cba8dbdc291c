//! Observations: every return of a survey that falls on a reference planar patch (inside its
//! rectangle, near its plane) becomes one [`Observation`] with its residual from the plane, its
//! predicted variance parts and the signatures of the catalogue effects (docs/diagnosis.md).
//!
//! Two passes over the returns. The first ([`scan`]) georeferences every return with the
//! configured values (in parallel) and files those on a patch into visits as it goes
//! ([`visits`]: time-contiguous runs over one patch in one pass, long ones thinned evenly in
//! time, at most `max_observations` returns kept in all); it runs again when a patch lies off
//! its plane as a whole. The second computes each kept return's terms from the analytic
//! Jacobian of the uncertainty model (`crate::uncertainty::PointGeometry::jacobian_e`). Every
//! return read is counted in exactly one class of [`ObserveCounts`].

mod counts;
mod joint;
mod nothing_left;
mod patch_index;
mod scan;
mod targets;
mod visits;

pub use counts::{ObserveCounts, Observed};
pub use joint::observe_joint;
pub use scan::{DisplacedPatch, OFF_PLANE_SHARE};

use super::model::{Covariates, Effect, NavRecord, Observation, ObservationSet, Side, Visit};
use crate::geo::rotations::{roll_pitch_heading, wrap_pi};
use crate::georef::{ReturnTerms, Sensor};
use crate::io::patches::{read_patches, PlanarPatch};
use crate::io::points::{read_control_points, ControlPoint};
use crate::io::profiles::{ProfileFile, RawReturn};
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline, TimeModel, START_NAV_TAU_S};
use crate::pipeline::prepare::{open_profiles, PreparedInput};
use crate::pipeline::report::RejectReason;
use crate::timing::ScannerClock;
use crate::trajectory::{
    derived_rates, derived_velocity, MotionChecks, MotionSource, PoseCursor, Trajectory,
    VELOCITY_HALF_BASELINE_S,
};
use crate::uncertainty::{Input, PointGeometry, N_INPUTS};
use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use patch_index::PatchIndex;
use rayon::prelude::*;
use scan::{scan_returns, Scan};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use targets::{TargetIndex, TargetVisit};
use visits::{Hit, PendingVisit};

/// Checks that a pipeline can be diagnosed: per-point uncertainty needs `[uncertainty]` and
/// the SMRMSG file; errors name the pipeline file and the missing key.
pub fn check_pipeline(p: &LoadedPipeline) -> Result<()> {
    let source = p.path.display().to_string();
    if p.config.inputs.smrmsg.is_none() {
        let problem = "diagnosis needs the SMRMSG file (INS position and attitude sigmas): \
                       the navigation errors are part of the model every residual is tested \
                       against";
        return Err(Error::config(&source, "inputs.smrmsg", problem));
    }
    if p.config.uncertainty.is_none() {
        let problem = "diagnosis needs the [uncertainty] table (scanner noise sigmas): \
                       without predicted sigmas no gap can be measured";
        return Err(Error::config(&source, "uncertainty", problem));
    }
    Ok(())
}

/// What a survey is checked against: reference patches and, optionally, control points.
#[derive(Debug, Clone)]
pub struct References {
    /// The patch file (named in errors).
    pub patches_path: PathBuf,
    /// Its patches.
    pub patches: Vec<PlanarPatch>,
    /// The control-point file, when given (named in errors).
    pub control_points_path: Option<PathBuf>,
    /// Its control points (none without the file).
    pub control_points: Vec<ControlPoint>,
}

impl References {
    /// Reads the patch file and the control-point file; an id used in both is refused (the
    /// report and the split name references by id).
    pub fn read(patches_path: &Path, control_points_path: Option<&Path>) -> Result<Self> {
        let patches = read_patches(patches_path)?;
        let control_points = match control_points_path {
            Some(path) => read_control_points(path)?,
            None => Vec::new(),
        };
        let patch_ids: BTreeSet<&str> = patches.iter().map(|p| p.id.as_str()).collect();
        if let Some(both) = control_points
            .iter()
            .find(|c| patch_ids.contains(c.id.as_str()))
        {
            let path = control_points_path.expect("control points come from a file");
            let problem = format!(
                "id {:?} is also a patch id in {}: references are named by id, so patch and \
                 control-point ids must differ",
                both.id,
                patches_path.display()
            );
            return Err(Error::bad_file(path, problem));
        }
        Ok(References {
            patches_path: patches_path.to_path_buf(),
            patches,
            control_points_path: control_points_path.map(Path::to_path_buf),
            control_points,
        })
    }
}

/// Observes every return of pipeline `p` that falls on one of the reference patches or on a
/// control point's target.
pub fn observe(p: &LoadedPipeline, refs: &References, opts: &DiagnoseConfig) -> Result<Observed> {
    check_pipeline(p)?;
    let c = &p.config;
    let traj_opts = c.trajectory.options();
    let traj = Trajectory::open(&c.inputs.sbet, c.inputs.smrmsg.as_deref(), traj_opts)?;
    let staging = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let files = open_profiles(c, staging.path())?;
    let mut index = PatchIndex::new(&refs.patches, opts);
    let targets = TargetIndex::new(&refs.control_points, opts);
    let counts = ObserveCounts {
        patches_read: refs.patches.len(),
        control_points_read: refs.control_points.len(),
        ..Default::default()
    };
    let motion = traj.motion_checks();
    let at = (&mut index, &targets);
    let scan = scan_returns(p, &traj, &files, at, &refs.patches, opts, counts)?;
    let Scan {
        mut counts,
        visits,
        target_visits,
    } = scan;
    if counts.on_patches == 0 {
        nothing_left::check_rejected(p, &counts)?;
    }
    check_found(refs, opts, &counts)?;
    let any_visit = !visits.is_empty() || !target_visits.is_empty();
    nothing_left::check_visits(p, opts, &counts, any_visit)?;
    let mut set = second_pass(p, &traj, &files, &refs.patches, &index, visits, &mut counts)?;
    let refs_ctx = (&refs.control_points[..], &targets);
    add_targets(
        p,
        &traj,
        &files,
        refs_ctx,
        target_visits,
        &mut set,
        &mut counts,
    )?;
    let without = |ids: &mut dyn Iterator<Item = &String>| -> Vec<String> {
        ids.filter(|id| !set.reference_ids.contains(id))
            .cloned()
            .collect()
    };
    counts.patches_without_observations = without(&mut refs.patches.iter().map(|p| &p.id));
    counts.control_points_without_observations =
        without(&mut refs.control_points.iter().map(|c| &c.id));
    set.validate()?;
    Ok(Observed {
        set,
        counts,
        motion,
    })
}

/// Refuses references no return reaches: patches none lies on, control points (when given)
/// none is found near.
fn check_found(refs: &References, opts: &DiagnoseConfig, counts: &ObserveCounts) -> Result<()> {
    if counts.on_patches == 0 {
        let problem = format!(
            "no return of the survey falls on any of its {} patches (inside the rectangle less \
             {} m, within {} m of the plane): the patches are not where the survey scanned, \
             or in another datum",
            refs.patches.len(),
            opts.edge_margin_m,
            opts.plane_tolerance_m
        );
        return Err(Error::bad_file(&refs.patches_path, problem));
    }
    if let (Some(path), 0) = (&refs.control_points_path, counts.on_targets) {
        let problem = format!(
            "no return of the survey is found on any of its {} control points' targets (at \
             least diagnose.target_min_intensity = {} bright, within diagnose.target_radius_m \
             = {} m of the point): the points are not targets the survey scanned, or in \
             another datum",
            refs.control_points.len(),
            opts.target_min_intensity,
            opts.target_radius_m
        );
        return Err(Error::bad_file(path, problem));
    }
    Ok(())
}

/// The configured georeferencing of one profile file's returns (docs/conventions.md §2, §4).
struct ReturnModel<'a> {
    traj: &'a Trajectory,
    sensor: Sensor,
    clock: ScannerClock,
    model: TimeModel,
    alpha_column: bool,
    attitude_latency_s: f64,
    position_latency_s: f64,
    range_limits_m: (f64, f64),
    white: WhiteSigmas,
    /// Correlation times of the INS position and attitude errors (s).
    nav_tau_s: [f64; 2],
    /// Half-step (s) of the central differences that replace the SBET's rate fields when
    /// they are empty or disagree with its attitude; `None`: the fields are used.
    derived_rates_h_s: Option<f64>,
    /// Half-step (s) of the central differences that replace the SBET's velocity fields when
    /// they are empty or disagree with its positions; `None`: the fields are used.
    derived_velocity_h_s: Option<f64>,
}

/// The scanner noise sigmas (`[uncertainty]`) that make the white part of a residual's
/// variance: alpha and beta (rad), range (m).
struct WhiteSigmas {
    alpha_rad: f64,
    beta_rad: f64,
    range_m: f64,
}

/// A georeferenced return.
struct Located {
    t_s: f64,
    /// Partials of `t` with respect to (t0, T).
    dt_dclock: [f64; 2],
    alpha_rad: f64,
    pose: crate::trajectory::Pose,
    terms: ReturnTerms,
    x_e: Vector3<f64>,
}

impl<'a> ReturnModel<'a> {
    fn new(p: &LoadedPipeline, traj: &'a Trajectory, file: &ProfileFile) -> Result<Self> {
        let MotionChecks { rates, velocities } = traj.motion_checks();
        let c = &p.config;
        let alpha_column = file.columns().alpha;
        if c.time.model != TimeModel::Software && !file.columns().time {
            let msg = format!(
                "time.model = {:?} needs a time_s column, which this file lacks",
                c.time.model
            );
            return Err(Error::bad_file(file.path(), msg));
        }
        Ok(ReturnModel {
            traj,
            sensor: c.sensor.sensor(),
            clock: ScannerClock {
                t0_s: c.time.t0_s.unwrap_or(0.0),
                period_s: c.time.period_s,
                mirror: c.time.mirror(c.sensor.encoder_offset_deg),
            },
            model: c.time.model,
            alpha_column,
            attitude_latency_s: c.latency.attitude_s,
            position_latency_s: c.latency.position_s,
            range_limits_m: (c.sensor.min_range_m, c.sensor.max_range_m),
            derived_rates_h_s: (rates.source == MotionSource::Trajectory)
                .then(|| traj.record_spacing_s()),
            derived_velocity_h_s: (velocities.source == MotionSource::Trajectory)
                .then(|| VELOCITY_HALF_BASELINE_S.max(traj.record_spacing_s())),
            nav_tau_s: c.diagnose.as_ref().map_or(START_NAV_TAU_S, |d| {
                [
                    d.nav_position_tau_s.unwrap_or(START_NAV_TAU_S[0]),
                    d.nav_attitude_tau_s.unwrap_or(START_NAV_TAU_S[1]),
                ]
            }),
            white: c.uncertainty.as_ref().map_or(
                WhiteSigmas {
                    alpha_rad: 0.0,
                    beta_rad: 0.0,
                    range_m: 0.0,
                },
                |u| WhiteSigmas {
                    alpha_rad: u.sigma_alpha_deg.to_radians(),
                    beta_rad: u.sigma_beta_deg.to_radians(),
                    range_m: u.sigma_range_m,
                },
            ),
        })
    }

    fn cursor(&self) -> PoseCursor<'a> {
        PoseCursor::new(self.traj, self.attitude_latency_s, self.position_latency_s)
    }

    /// Time (s) of a return and its partials with respect to (t0, T) per the time model.
    fn time_of(&self, r: &RawReturn) -> (f64, [f64; 2]) {
        let clock = crate::timing::ReturnClock {
            model: self.model,
            clock: self.clock,
        };
        clock.time_and_partials(r)
    }

    /// d t / d beta (s/rad): the mirror fraction moves with the encoder angle.
    fn dt_dbeta(&self) -> f64 {
        match self.model {
            TimeModel::HardwareReturn => 0.0,
            _ => self.clock.period_s * self.clock.mirror.direction.sign() / std::f64::consts::TAU,
        }
    }

    /// Georeferences record `index` of `file` again (the first pass located it); an error
    /// naming the record if it no longer can be.
    fn relocate(
        &self,
        file: &ProfileFile,
        index: usize,
        cursor: &mut PoseCursor,
    ) -> Result<(RawReturn, Located)> {
        let r = file.get(index);
        let loc = self.locate(&r, cursor).map_err(|reason| {
            Error::bad_record(file.path(), format!("record {index}"), reason.describe())
        })?;
        Ok((r, loc))
    }

    /// Georeferences `r` with the configured values, or says why it cannot be.
    fn locate(&self, r: &RawReturn, cursor: &mut PoseCursor) -> Result<Located, RejectReason> {
        let alpha_rad = if self.alpha_column {
            r.alpha_rad
        } else {
            self.sensor.alpha0_rad
        };
        let finite = r.beta_rad.is_finite() && r.range_m.is_finite() && alpha_rad.is_finite();
        if !finite || (self.model != TimeModel::Software && !r.time_s.is_finite()) {
            return Err(RejectReason::NonFinite);
        }
        if r.range_m == 0.0 {
            return Err(RejectReason::MissingReturn);
        }
        let (lo, hi) = self.range_limits_m;
        if !(lo..=hi).contains(&r.range_m) {
            return Err(RejectReason::RangeOutOfLimits);
        }
        let (t_s, dt_dclock) = self.time_of(r);
        let mut pose = cursor.at(t_s).map_err(RejectReason::from)?;
        if let Some(h) = self.derived_rates_h_s {
            pose.omega_b_radps = derived_rates(cursor, t_s, h).map_err(RejectReason::from)?;
        }
        if let Some(h) = self.derived_velocity_h_s {
            pose.nav.v_n_mps = derived_velocity(cursor, t_s, h).map_err(RejectReason::from)?;
        }
        let terms = ReturnTerms::of_pose(
            &pose,
            &self.sensor,
            r.range_m,
            alpha_rad.sin_cos(),
            r.beta_rad,
        );
        let x_e = terms.point_e(&pose.nav.r_e_m);
        Ok(Located {
            t_s,
            dt_dclock,
            alpha_rad,
            pose,
            terms,
            x_e,
        })
    }
}

/// Seconds either side of a visit whose trajectory records it releases ([`observe_visit`]).
const TRAJECTORY_MARGIN_S: f64 = 1.0;

/// Visits observed side by side in [`second_pass`] before their observations join the set.
const VISIT_BATCH: usize = 256;

/// Computes the observations and visit covariances of the kept returns.
fn second_pass(
    p: &LoadedPipeline,
    traj: &Trajectory,
    files: &[PreparedInput],
    patches: &[PlanarPatch],
    index: &PatchIndex,
    visits: Vec<PendingVisit>,
    counts: &mut ObserveCounts,
) -> Result<ObservationSet> {
    let models = files
        .iter()
        .map(|input| ReturnModel::new(p, traj, &input.file))
        .collect::<Result<Vec<_>>>()?;
    // Reference indices: patches with at least one visit, in patch-file order.
    let mut reference_of = vec![None; patches.len()];
    let mut reference_ids = Vec::new();
    let mut used: Vec<usize> = visits.iter().map(|v| v.patch).collect();
    used.sort_unstable();
    used.dedup();
    for k in used {
        reference_of[k] = Some(reference_ids.len());
        reference_ids.push(patches[k].id.clone());
    }
    let mut set = ObservationSet {
        reference_ids,
        passes: files.len(),
        // The navigation errors are shared between visits closer than a few of these.
        nav_tau_s: Some(models[0].nav_tau_s),
        ..Default::default()
    };
    // One observation per hit: the set takes its final size at once, and the visits are
    // observed a batch at a time, so that only a batch's observations exist twice (growing
    // the set by doubling beside every visit's observations had been the diagnosis' peak).
    set.observations
        .reserve_exact(visits.iter().map(|v| v.hits.len()).sum());
    set.visits.reserve_exact(visits.len());
    for (b, batch) in visits.chunks(VISIT_BATCH).enumerate() {
        let per_visit: Vec<Result<(Visit, Vec<Observation>)>> = batch
            .par_iter()
            .enumerate()
            .map(|(k, pv)| {
                let reference = reference_of[pv.patch].expect("listed above");
                let v = b * VISIT_BATCH + k;
                observe_visit(
                    &models[pv.pass],
                    &files[pv.pass].file,
                    index,
                    pv,
                    v,
                    reference,
                )
            })
            .collect();
        for r in per_visit {
            let (visit, obs) = r?;
            set.visits.push(visit);
            set.observations.extend(obs);
        }
    }
    counts.observations = set.observations.len() as u64;
    Ok(set)
}

/// Adds the observations of the target visits to `set`, their control points as references
/// after the patches (in control-point file order).
fn add_targets(
    p: &LoadedPipeline,
    traj: &Trajectory,
    files: &[PreparedInput],
    (points, targets): (&[ControlPoint], &TargetIndex),
    visits: Vec<PendingVisit>,
    set: &mut ObservationSet,
    counts: &mut ObserveCounts,
) -> Result<()> {
    if targets.is_empty() {
        return Ok(());
    }
    let opts = p.config.diagnose.clone().unwrap_or_default();
    let models = files
        .iter()
        .map(|input| ReturnModel::new(p, traj, &input.file))
        .collect::<Result<Vec<_>>>()?;
    let first_visit = set.visits.len();
    let outcomes: Vec<Result<Option<TargetVisit>>> = visits
        .par_iter()
        .map(|pv| {
            targets::observe_target(&models[pv.pass], &files[pv.pass].file, targets, pv, &opts)
        })
        .collect();
    let mut observed = Vec::new();
    for (pv, outcome) in visits.iter().zip(outcomes) {
        match outcome? {
            None => {
                counts.target_returns_unused += pv.hits.len() as u64;
                counts.target_visits_not_flat += 1;
            }
            Some((visit, obs)) => {
                counts.target_returns_used += pv.hits.len() as u64;
                observed.push((pv.patch, visit, obs));
            }
        }
    }
    let used: BTreeSet<usize> = observed.iter().map(|(point, _, _)| *point).collect();
    let reference_of: BTreeMap<usize, usize> = used
        .iter()
        .enumerate()
        .map(|(k, &point)| (point, set.reference_ids.len() + k))
        .collect();
    set.reference_ids
        .extend(used.iter().map(|&point| points[point].id.clone()));
    for (v, (point, mut visit, mut obs)) in observed.into_iter().enumerate() {
        let reference = reference_of[&point];
        visit.reference = reference;
        for o in &mut obs {
            o.reference = reference;
            o.visit = first_visit + v;
            o.covariates.reference_id = reference;
        }
        counts.target_observations += obs.len() as u64;
        set.visits.push(visit);
        set.observations.extend(obs);
    }
    counts.target_visits = (set.visits.len() - first_visit) as u64;
    Ok(())
}

/// The observations of one visit and its navigation covariance.
fn observe_visit(
    model: &ReturnModel,
    file: &ProfileFile,
    index: &PatchIndex,
    pv: &PendingVisit,
    visit: usize,
    reference: usize,
) -> Result<(Visit, Vec<Observation>)> {
    let frame = &index.frames[pv.patch];
    let (t_first, t_last) = (pv.hits[0].t_s, pv.hits[pv.hits.len() - 1].t_s);
    let t_mid = 0.5 * (t_first + t_last);
    let survey_ned = frame.normal_n * frame.normal_n.transpose() * frame.sigma_m.powi(2);
    let nav_cov = visit_nav_cov(model.traj, t_mid, &survey_ned)
        .map_err(|reason| Error::Invalid(format!("visit at {t_first} s: {}", reason.describe())))?;
    let mut cursor = model.cursor();
    let located = pv
        .hits
        .iter()
        .map(|h| model.relocate(file, h.index, &mut cursor))
        .collect::<Result<Vec<_>>>()?;
    release_visit(file, &pv.hits);
    // The visits of a batch lie all over the day: each visit's trajectory pages are released
    // with its returns' (a fault maps up to a 2 MiB folio of the SBET); the margin covers the
    // latencies and the SMRMSG's coarser records.
    model
        .traj
        .release_times(t_first, t_last, TRAJECTORY_MARGIN_S);
    let n_e = frame.axes_e.row(2).transpose();
    let pairs = located.iter().map(|(r, loc)| (r, loc));
    let ranges = denoised_ranges_m(pairs, model, &n_e, &frame.centre_e);
    let mut obs = Vec::with_capacity(located.len());
    for (((r, loc), range_m), h) in located.iter().zip(ranges).zip(&pv.hits) {
        let cov = Covariates {
            reference_id: reference,
            pass: pv.pass,
            ..covariates(loc, model, &n_e, r, range_m)
        };
        let ids = (reference, visit, h.index);
        let at = Surface {
            axis_e: &n_e,
            centre_e: &frame.centre_e,
            range_m,
        };
        let offset_e = loc.x_e - frame.centre_e;
        obs.push(Observation {
            plane_uv_m: [0, 1].map(|k| frame.axes_e.row(k).transpose().dot(&offset_e) as f32),
            ..observation_along(loc, model, &at, r, ids, cov)
        });
    }
    let v = Visit {
        reference,
        pass: pv.pass,
        nav_cov,
    };
    Ok((v, obs))
}

/// Releases the pages of the records a visit read, and the neighbours their faults mapped
/// after them: the second pass reads a few returns per page and jumps between visits, and
/// what it left resident grew with the survey (150 MB of a 4.8 GB file at 1.2e8 returns).
fn release_visit(file: &ProfileFile, hits: &[Hit]) {
    let (lo, hi) = hits.iter().fold((usize::MAX, 0), |(lo, hi), h| {
        (lo.min(h.index), hi.max(h.index + 1))
    });
    if lo < hi {
        file.release_around(lo..hi);
    }
}

/// `P_v`: SMRMSG variances at `t_mid` plus `survey_ned` (m^2, NED) in the position block: a
/// patch's survey variance along its normal (a plane offset along `n` is indistinguishable
/// from an INS position error along `n`).
fn visit_nav_cov(
    traj: &Trajectory,
    t_mid: f64,
    survey_ned: &Matrix3<f64>,
) -> Result<[[f64; 6]; 6], RejectReason> {
    let mut cursor = traj.sigma_cursor().ok_or(RejectReason::OutsideAccuracy)?;
    let s = cursor.at(t_mid).map_err(RejectReason::from)?;
    let nav_var: [f64; 6] = std::array::from_fn(|k| {
        if k < 3 {
            s.pos_ned_m[k].powi(2)
        } else {
            s.att_rph_rad[k - 3].powi(2)
        }
    });
    let p = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let diag = if i == j { nav_var[i] } else { 0.0 };
            let survey = if i < 3 && j < 3 {
                survey_ned[(i, j)]
            } else {
                0.0
            };
            diag + survey
        })
    });
    Ok(p)
}

/// The beam of a located return (unit vector, ECEF).
fn beam_e(loc: &Located, model: &ReturnModel) -> Vector3<f64> {
    let beam_b = model.sensor.r_s_to_b * loc.terms.u_s();
    loc.terms.r_n_to_e * (loc.terms.r_b_to_n * beam_b)
}

/// Beams closer than this to grazing (|cos| of the angle to the normal) keep their measured
/// range in [`denoised_ranges_m`].
const MIN_COS_INCIDENCE: f64 = 0.05;

/// The range (m) each return of one visit would have measured without its own noise: its
/// measured range less its residual's departure from the visit's mean residual, along the beam
/// (`rho - (r - mean r) / (n . u)`) on the surface of unit normal `n_e` through `centre_e`.
/// The range-scale signature is evaluated there and the `range_m` covariate is this range: at
/// the measured range either carries the return's own range noise, which is also in its
/// residual (errors in variables: on ground patches alone a range-scale fit of -32% came from
/// it; binned by the measured range, 15 laps without effect left chi2 50-59 on 16 dof;
/// docs/diagnosis.md, "Observations"). What the visit shares (navigation error, an effect's
/// offset) stays in the mean.
fn denoised_ranges_m<'a>(
    located: impl Iterator<Item = (&'a RawReturn, &'a Located)> + Clone,
    model: &ReturnModel,
    n_e: &Vector3<f64>,
    centre_e: &Vector3<f64>,
) -> Vec<f64> {
    let residual = |loc: &Located| n_e.dot(&(loc.x_e - centre_e));
    let (sum, count) = located
        .clone()
        .fold((0.0, 0.0), |(s, n), (_, l)| (s + residual(l), n + 1.0));
    let mean = sum / count;
    located
        .map(|(r, loc)| {
            let cos = n_e.dot(&beam_e(loc, model));
            if cos.abs() < MIN_COS_INCIDENCE {
                r.range_m
            } else {
                r.range_m - (residual(loc) - mean) / cos
            }
        })
        .collect()
}

/// Where and how a return was measured on a surface of unit normal `n_e` (ECEF), at range
/// `range_m` ([`denoised_ranges_m`]) (`reference_id` and `pass` are set by the caller).
fn covariates(
    loc: &Located,
    model: &ReturnModel,
    n_e: &Vector3<f64>,
    r: &RawReturn,
    range_m: f64,
) -> Covariates {
    let beam_b = model.sensor.r_s_to_b * loc.terms.u_s();
    let beam_e = beam_e(loc, model);
    let w = loc.pose.omega_b_radps.map(f64::to_degrees);
    let (_, _, heading) = roll_pitch_heading(&loc.pose.q_b_to_n);
    Covariates {
        time_s: loc.t_s,
        range_m,
        beta_deg: wrap_pi(r.beta_rad).to_degrees(),
        incidence_deg: n_e.dot(&beam_e).abs().min(1.0).acos().to_degrees(),
        speed_mps: loc.pose.nav.v_n_mps.norm(),
        yaw_rate_dps: w.z,
        roll_rate_dps: w.x,
        pitch_rate_dps: w.y,
        heading_deg: heading.to_degrees().rem_euclid(360.0),
        side: if beam_b.y < 0.0 {
            Side::Left
        } else {
            Side::Right
        },
        pass: 0,
        reference_id: 0,
    }
}

/// Along which axis from which reference point a return is observed, and at which range its
/// range-scale signature is evaluated.
struct Surface<'a> {
    /// Unit vector (ECEF) the residual is measured along.
    axis_e: &'a Vector3<f64>,
    /// The reference point (ECEF, m): a patch centre or a control point.
    centre_e: &'a Vector3<f64>,
    /// Range (m) at which the range-scale signature is evaluated ([`denoised_ranges_m`]).
    range_m: f64,
}

/// The observation of one located return along `at.axis_e` from `at.centre_e` (`ids`:
/// reference, visit, record of the return in its pass's file): residual,
/// white variance, navigation gradient and effect signatures, all from `n^T J` with `J` the
/// analytic Jacobian of the uncertainty model (the range scale's at range `at.range_m`).
fn observation_along(
    loc: &Located,
    model: &ReturnModel,
    at: &Surface,
    r: &RawReturn,
    ids: (usize, usize, usize),
    covariates: Covariates,
) -> Observation {
    let n_e = at.axis_e;
    let geom = PointGeometry::from_pose(
        &loc.pose,
        &model.sensor,
        loc.alpha_rad,
        r.beta_rad,
        r.range_m,
    );
    let j = geom.jacobian_e();
    let g: [f64; N_INPUTS] = std::array::from_fn(|k| n_e.dot(&j.column(k)));
    let w = &model.white;
    let var_white_m2 = (g[Input::Alpha as usize] * w.alpha_rad).powi(2)
        + (g[Input::Beta as usize] * w.beta_rad).powi(2)
        + (g[Input::Range as usize] * w.range_m).powi(2);
    Observation {
        reference: ids.0,
        visit: ids.1,
        record: ids.2,
        residual_m: n_e.dot(&(loc.x_e - at.centre_e)),
        var_white_m2,
        nav_gradient: std::array::from_fn(|k| g[k]),
        signature: Effect::ALL.map(|e| signature(e, &g, loc, model, at.range_m)),
        covariates,
        nav_record: model
            .traj
            .interval_at(loc.t_s + model.position_latency_s)
            .map(|(index, w)| NavRecord { index, w }),
        plane_uv_m: [f32::NAN; 2],
    }
}

/// How far a return moves along `n` (m) per unit of effect `e` present in the data but not in
/// the configuration: `-n^T d x_e / d p` with `p` the configured value the effect corrects
/// (georeferencing with `p` too small by `delta` puts the point at `x(p_true) - J delta`).
/// `g` = `n^T J` over the uncertainty model's inputs; `range_m` the (denoised) range the range
/// scale is evaluated at.
fn signature(
    e: Effect,
    g: &[f64; N_INPUTS],
    loc: &Located,
    model: &ReturnModel,
    range_m: f64,
) -> f64 {
    use Input as I;
    let deg = std::f64::consts::PI / 180.0;
    let d_time = g[I::ClockTime as usize];
    let d_pos_along_v = (0..3).map(|k| g[k] * loc.pose.nav.v_n_mps[k]).sum::<f64>();
    let d_p = match e {
        Effect::AttitudeLatency => g[I::Latency as usize],
        Effect::PositionLatency => d_pos_along_v,
        Effect::ClockOffset => d_time * loc.dt_dclock[0],
        Effect::ClockDrift => d_time * loc.dt_dclock[1] * model.clock.period_s * 1e-6,
        Effect::BoresightX => g[I::BoresightX as usize] * deg,
        Effect::BoresightY => g[I::BoresightY as usize] * deg,
        Effect::BoresightZ => g[I::BoresightZ as usize] * deg,
        Effect::LeverArmX => g[I::LeverX as usize],
        Effect::LeverArmY => g[I::LeverY as usize],
        Effect::LeverArmZ => g[I::LeverZ as usize],
        Effect::RangeZero => g[I::RangeZero as usize],
        Effect::RangeScale => g[I::Range as usize] * model.sensor.range_total_m(range_m) * 1e-6,
        Effect::EncoderOffset => (g[I::Beta as usize] + d_time * model.dt_dbeta()) * deg,
        Effect::Cone => g[I::Alpha as usize] * deg,
        Effect::HeadingOffset => g[I::InsHeading as usize] * deg,
    };
    -d_p
}
