//! Observations: every return of a survey that falls on a reference planar patch (inside its
//! rectangle, near its plane) becomes one [`Observation`] with its residual from the plane, its
//! predicted variance parts and the signatures of the catalogue effects (docs/diagnosis.md).
//!
//! Two passes over the returns: the first georeferences every return with the configured
//! values (in parallel) and keeps those on a patch; the second groups them into visits
//! (time-contiguous runs over one patch in one pass), thins long visits evenly in time and
//! computes each kept return's terms from the analytic Jacobian of the uncertainty model
//! (`crate::uncertainty::PointGeometry::jacobian_e`). Every return read is counted in exactly
//! one class of [`ObserveCounts`].

mod counts;
mod patch_index;

pub use counts::{ObserveCounts, Observed};

use super::model::{Covariates, Effect, Observation, ObservationSet, Side, Visit};
use crate::geo::rotations::{roll_pitch_heading, wrap_pi};
use crate::georef::{ReturnTerms, Sensor};
use crate::io::patches::PlanarPatch;
use crate::io::profiles::{ProfileFile, RawReturn};
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline, TimeModel};
use crate::pipeline::prepare::{open_profiles, PreparedInput};
use crate::pipeline::report::RejectReason;
use crate::timing::ScannerClock;
use crate::trajectory::{PoseCursor, Trajectory};
use crate::uncertainty::{Input, PointGeometry, N_INPUTS};
use crate::{Error, Result};
use nalgebra::Vector3;
use patch_index::{PatchFrame, PatchIndex, Place};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// Returns per parallel work item of the first pass.
const CHUNK_RETURNS: usize = 1 << 15;

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

/// Observes every return of pipeline `p` that falls on one of `patches` (read from
/// `patches_path`, named in errors).
pub fn observe(
    p: &LoadedPipeline,
    patches: &[PlanarPatch],
    patches_path: &Path,
    opts: &DiagnoseConfig,
) -> Result<Observed> {
    check_pipeline(p)?;
    let c = &p.config;
    let traj_opts = c.trajectory.options();
    let traj = Trajectory::open(&c.inputs.sbet, c.inputs.smrmsg.as_deref(), traj_opts)?;
    let staging = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
    let files = open_profiles(c, staging.path())?;
    let index = PatchIndex::new(patches, opts);
    let mut counts = ObserveCounts {
        patches_read: patches.len(),
        ..Default::default()
    };
    let mut hits = Vec::new();
    for (pass, input) in files.iter().enumerate() {
        let model = ReturnModel::new(p, &traj, &input.file)?;
        let on = first_pass(&model, &input.file, &index, &mut counts);
        hits.extend(on.into_iter().map(|h| (pass, h)));
    }
    if hits.is_empty() {
        let problem = format!(
            "no return of the survey falls on any of its {} patches (inside the rectangle less \
             {} m, within {} m of the plane): the patches are not where the survey scanned, \
             or in another datum",
            patches.len(),
            opts.edge_margin_m,
            opts.plane_tolerance_m
        );
        return Err(Error::bad_file(patches_path, problem));
    }
    let visits = group_visits(hits, opts, &mut counts);
    let set = second_pass(p, &traj, &files, patches, &index, visits, &mut counts)?;
    counts.patches_without_observations = patches
        .iter()
        .filter(|pt| !set.reference_ids.contains(&pt.id))
        .map(|pt| pt.id.clone())
        .collect();
    Ok(Observed { set, counts })
}

/// One return on a patch, from the first pass.
#[derive(Debug, Clone, Copy)]
struct Hit {
    index: usize,
    patch: usize,
    t_s: f64,
}

/// A visit before its observations are computed: patch, pass and the kept returns.
struct PendingVisit {
    patch: usize,
    pass: usize,
    hits: Vec<Hit>,
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
            nav_tau_s: c.diagnose.as_ref().map_or_else(
                || {
                    let d = DiagnoseConfig::default();
                    [d.nav_position_tau_s, d.nav_attitude_tau_s]
                },
                |d| [d.nav_position_tau_s, d.nav_attitude_tau_s],
            ),
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
        let pose = cursor.at(t_s).map_err(RejectReason::from)?;
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

/// Per-chunk tallies of the first pass.
#[derive(Default)]
struct ChunkTally {
    rejected: BTreeMap<RejectReason, u64>,
    off_patches: u64,
    off_plane: u64,
    hits: Vec<Hit>,
}

/// Georeferences every return of one file and keeps those on a patch (in file order).
fn first_pass(
    model: &ReturnModel,
    file: &ProfileFile,
    index: &PatchIndex,
    counts: &mut ObserveCounts,
) -> Vec<Hit> {
    let n = file.len();
    let tallies: Vec<ChunkTally> = (0..n.div_ceil(CHUNK_RETURNS))
        .into_par_iter()
        .map(|k| {
            let mut tally = ChunkTally::default();
            let mut cursor = model.cursor();
            for i in k * CHUNK_RETURNS..((k + 1) * CHUNK_RETURNS).min(n) {
                match model.locate(&file.get(i), &mut cursor) {
                    Err(reason) => *tally.rejected.entry(reason).or_default() += 1,
                    Ok(loc) => match index.place(&loc.x_e) {
                        Place::Off => tally.off_patches += 1,
                        Place::OffPlane => tally.off_plane += 1,
                        Place::On(patch) => tally.hits.push(Hit {
                            index: i,
                            patch,
                            t_s: loc.t_s,
                        }),
                    },
                }
            }
            tally
        })
        .collect();
    counts.returns_read += n as u64;
    let mut hits = Vec::new();
    for t in tallies {
        for (reason, k) in t.rejected {
            *counts.rejected.entry(reason).or_default() += k;
        }
        counts.off_patches += t.off_patches;
        counts.off_plane += t.off_plane;
        counts.on_patches += t.hits.len() as u64;
        hits.extend(t.hits);
    }
    hits
}

/// Splits the hits of one pass into visits, drops short ones and thins long ones; `hits` are
/// tagged with their pass.
fn group_visits(
    hits: Vec<(usize, Hit)>,
    opts: &DiagnoseConfig,
    counts: &mut ObserveCounts,
) -> Vec<PendingVisit> {
    let mut by_patch: BTreeMap<(usize, usize), Vec<Hit>> = BTreeMap::new();
    for (pass, h) in hits {
        by_patch.entry((h.patch, pass)).or_default().push(h);
    }
    let mut visits = Vec::new();
    for ((patch, pass), mut list) in by_patch {
        list.sort_by(|a, b| a.t_s.total_cmp(&b.t_s).then(a.index.cmp(&b.index)));
        let mut start = 0;
        for k in 1..=list.len() {
            let split = k == list.len()
                || list[k].t_s - list[k - 1].t_s > opts.visit_gap_s
                || list[k].t_s - list[start].t_s > opts.max_visit_s;
            if !split {
                continue;
            }
            let run = &list[start..k];
            start = k;
            if run.len() < opts.min_per_visit {
                counts.in_short_visits += run.len() as u64;
                continue;
            }
            let kept = thin_evenly(run, opts.max_per_visit);
            counts.thinned += (run.len() - kept.len()) as u64;
            visits.push(PendingVisit {
                patch,
                pass,
                hits: kept,
            });
        }
    }
    visits
}

/// At most `max` of `run`, evenly spaced by position (first one kept).
fn thin_evenly(run: &[Hit], max: usize) -> Vec<Hit> {
    if run.len() <= max {
        return run.to_vec();
    }
    (0..max).map(|k| run[k * run.len() / max]).collect()
}

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
    let per_visit: Vec<Result<(Visit, Vec<Observation>)>> = visits
        .par_iter()
        .enumerate()
        .map(|(v, pv)| {
            let reference = reference_of[pv.patch].expect("listed above");
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
    let mut set = ObservationSet {
        reference_ids,
        passes: files.len(),
        // The navigation errors are shared between visits closer than a few of these.
        nav_tau_s: Some(models[0].nav_tau_s),
        ..Default::default()
    };
    for r in per_visit {
        let (visit, obs) = r?;
        set.visits.push(visit);
        set.observations.extend(obs);
    }
    counts.observations = set.observations.len() as u64;
    Ok(set)
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
    let nav_cov = visit_nav_cov(model.traj, t_mid, frame)
        .map_err(|reason| Error::Invalid(format!("visit at {t_first} s: {}", reason.describe())))?;
    let mut cursor = model.cursor();
    let mut obs = Vec::with_capacity(pv.hits.len());
    for h in &pv.hits {
        let r = file.get(h.index);
        let loc = model.locate(&r, &mut cursor).map_err(|reason| {
            Error::bad_record(
                file.path(),
                format!("record {}", h.index),
                reason.describe(),
            )
        })?;
        let cov = Covariates {
            reference_id: reference,
            pass: pv.pass,
            ..covariates(&loc, model, frame, &r)
        };
        obs.push(observation(&loc, model, frame, &r, (reference, visit), cov));
    }
    let v = Visit {
        reference,
        pass: pv.pass,
        nav_cov,
    };
    Ok((v, obs))
}

/// `P_v`: SMRMSG variances at `t_mid` plus the patch's survey variance along its normal
/// (a plane offset along `n` is indistinguishable from an INS position error along `n`).
fn visit_nav_cov(
    traj: &Trajectory,
    t_mid: f64,
    frame: &PatchFrame,
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
    let s2 = frame.sigma_m.powi(2);
    let n = &frame.normal_n;
    let p = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let diag = if i == j { nav_var[i] } else { 0.0 };
            let patch = if i < 3 && j < 3 {
                s2 * n[i] * n[j]
            } else {
                0.0
            };
            diag + patch
        })
    });
    Ok(p)
}

/// Where and how a return was measured (`reference_id` and `pass` are set by the caller).
fn covariates(loc: &Located, model: &ReturnModel, frame: &PatchFrame, r: &RawReturn) -> Covariates {
    let beam_b = model.sensor.r_s_to_b * loc.terms.u_s();
    let beam_e = loc.terms.r_n_to_e * (loc.terms.r_b_to_n * beam_b);
    let n_e = frame.axes_e.row(2).transpose();
    let w = loc.pose.omega_b_radps.map(f64::to_degrees);
    let (_, _, heading) = roll_pitch_heading(&loc.pose.q_b_to_n);
    Covariates {
        time_s: loc.t_s,
        range_m: r.range_m,
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

/// The observation of one located return: residual, white variance, navigation gradient and
/// effect signatures, all from `n^T J` with `J` the analytic Jacobian of the uncertainty model.
fn observation(
    loc: &Located,
    model: &ReturnModel,
    frame: &PatchFrame,
    r: &RawReturn,
    ids: (usize, usize),
    covariates: Covariates,
) -> Observation {
    let geom = PointGeometry::from_pose(
        &loc.pose,
        &model.sensor,
        loc.alpha_rad,
        r.beta_rad,
        r.range_m,
    );
    let j = geom.jacobian_e();
    let n_e = frame.axes_e.row(2).transpose();
    let g: [f64; N_INPUTS] = std::array::from_fn(|k| n_e.dot(&j.column(k)));
    let w = &model.white;
    let var_white_m2 = (g[Input::Alpha as usize] * w.alpha_rad).powi(2)
        + (g[Input::Beta as usize] * w.beta_rad).powi(2)
        + (g[Input::Range as usize] * w.range_m).powi(2);
    Observation {
        reference: ids.0,
        visit: ids.1,
        residual_m: n_e.dot(&(loc.x_e - frame.centre_e)),
        var_white_m2,
        nav_gradient: std::array::from_fn(|k| g[k]),
        signature: Effect::ALL.map(|e| signature(e, &g, loc, model)),
        covariates,
    }
}

/// How far a return moves along `n` (m) per unit of effect `e` present in the data but not in
/// the configuration: `-n^T d x_e / d p` with `p` the configured value the effect corrects
/// (georeferencing with `p` too small by `delta` puts the point at `x(p_true) - J delta`).
/// `g` = `n^T J` over the uncertainty model's inputs.
fn signature(e: Effect, g: &[f64; N_INPUTS], loc: &Located, model: &ReturnModel) -> f64 {
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
        Effect::RangeScale => g[I::Range as usize] * loc.terms.range_total_m * 1e-6,
        Effect::EncoderOffset => (g[I::Beta as usize] + d_time * model.dt_dbeta()) * deg,
        Effect::Cone => g[I::Alpha as usize] * deg,
        Effect::HeadingOffset => g[I::InsHeading as usize] * deg,
    };
    -d_p
}
