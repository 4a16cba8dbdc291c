//! The first pass: every return georeferenced with the configured values (in parallel) and
//! filed into the visits of the patch or control point's target it falls on.
//!
//! A patch whose returns lie off its plane as a whole (more than [`OFF_PLANE_SHARE`] of those
//! inside its rectangle and within 1 m of its plane beyond `plane_tolerance_m`) is a
//! configuration grossly off, or a patch file that is: a lever arm 0.2 m off moves every
//! ground patch 0.2 m. Cutting those returns at the tolerance would leave that patch without
//! observations and the diagnosis blind to the very effect that moved it. The pass is then
//! run again with such patches centred: each visit keeps the returns within the tolerance of
//! its own median distance from the plane (docs/diagnosis.md, "Patches off their plane").

use super::patch_index::{PatchIndex, Place};
use super::targets::TargetIndex;
use super::visits::{Closed, Hit, PendingVisit, VisitRule, Visits};
use super::{ObserveCounts, ReturnModel};
use crate::io::patches::PlanarPatch;
use crate::io::profiles::ProfileFile;
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::pipeline::prepare::PreparedInput;
use crate::pipeline::report::RejectReason;
use crate::trajectory::Trajectory;
use crate::Result;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Share of a patch's near returns (inside its rectangle, within 1 m of its plane) beyond the
/// plane tolerance above which the patch is taken as lying off its plane as a whole: its
/// median return is off the plane. A patch only partly beyond (a range scale's far side) keeps
/// the cut about its plane: centring those let through returns 0.15-0.3 m off that the screen
/// did not all set aside (docs/diagnosis.md, "Patches off their plane").
pub const OFF_PLANE_SHARE: f64 = 0.5;

/// A patch observed about its visits' own median distance from its plane.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DisplacedPatch {
    /// Its id in the patch file.
    pub id: String,
    /// Share of its near returns beyond `plane_tolerance_m` of its plane.
    pub off_plane_share: f64,
    /// Median over its visits of each visit's median distance from the plane (m, along the
    /// patch's normal).
    pub median_offset_m: f64,
}

/// What the first pass found.
pub(super) struct Scan {
    pub counts: ObserveCounts,
    pub visits: Vec<PendingVisit>,
    pub target_visits: Vec<PendingVisit>,
}

/// Per patch, its returns within the plane tolerance (`on`) and those inside its rectangle,
/// within 1 m of its plane but beyond the tolerance (`off`).
struct NearPlane {
    on: Vec<u64>,
    off: Vec<u64>,
}

/// Runs the first pass over every file, and again with the displaced patches centred when
/// there are any (`index` then takes their near returns); `counts` holds what the references
/// are.
pub(super) fn scan_returns(
    p: &LoadedPipeline,
    traj: &Trajectory,
    files: &[PreparedInput],
    (index, targets): (&mut PatchIndex, &TargetIndex),
    patches: &[PlanarPatch],
    opts: &DiagnoseConfig,
    counts: ObserveCounts,
) -> Result<Scan> {
    let at = (&*index, targets);
    let (scan, near, _) = scan_once(p, traj, files, at, opts, counts.clone(), Vec::new())?;
    let share = |k: usize| near.off[k] as f64 / (near.on[k] + near.off[k]).max(1) as f64;
    let displaced: Vec<bool> = (0..patches.len())
        .map(|k| near.off[k] >= opts.min_per_visit as u64 && share(k) > OFF_PLANE_SHARE)
        .collect();
    if !displaced.contains(&true) {
        return Ok(scan);
    }
    index.widen(&displaced);
    let at = (&*index, targets);
    let (mut scan, _, medians) = scan_once(p, traj, files, at, opts, counts, displaced)?;
    scan.counts.displaced_patches = medians
        .into_iter()
        .map(|(k, mut of_visits)| {
            of_visits.sort_by(f64::total_cmp);
            DisplacedPatch {
                id: patches[k].id.clone(),
                off_plane_share: share(k),
                median_offset_m: of_visits[(of_visits.len() - 1) / 2],
            }
        })
        .collect();
    Ok(scan)
}

/// One first pass over every file: the visits found, with the patches `centred` names
/// centred on each visit's median ([`Visits::centre_on_median`]); per patch its returns near
/// its plane; per centred patch its visits' medians.
fn scan_once(
    p: &LoadedPipeline,
    traj: &Trajectory,
    files: &[PreparedInput],
    at: (&PatchIndex, &TargetIndex),
    opts: &DiagnoseConfig,
    mut counts: ObserveCounts,
    centred: Vec<bool>,
) -> Result<(Scan, NearPlane, BTreeMap<usize, Vec<f64>>)> {
    let patches = at.0.frames.len();
    let mut near = NearPlane {
        on: vec![0; patches],
        off: vec![0; patches],
    };
    let mut visits = Visits::new(VisitRule::patches(opts));
    visits.centre_on_median(centred, opts.plane_tolerance_m);
    let mut target_visits = Visits::new(VisitRule::targets(opts));
    for (pass, input) in files.iter().enumerate() {
        let model = ReturnModel::new(p, traj, &input.file)?;
        let found = (&mut visits, &mut target_visits);
        let tallies = (&mut counts, &mut near);
        first_pass(&model, &input.file, (pass, at), found, tallies);
    }
    let patch_visits = visits.finish();
    counts.on_patches -= patch_visits.off_band;
    counts.off_plane += patch_visits.off_band;
    counts.in_short_visits = patch_visits.short;
    counts.thinned = patch_visits.thinned;
    let target_closed = target_visits.finish();
    counts.target_returns_unused = target_closed.short;
    let Closed {
        visits, medians, ..
    } = patch_visits;
    let scan = Scan {
        counts,
        visits,
        target_visits: target_closed.visits,
    };
    Ok((scan, near, medians))
}

/// Per-chunk tallies of the first pass; hits tagged with their patch or control point.
#[derive(Default)]
struct ChunkTally {
    rejected: BTreeMap<RejectReason, u64>,
    off_patches: u64,
    /// Per patch, its returns near its plane but beyond the tolerance.
    off_plane: BTreeMap<usize, u64>,
    hits: Vec<(usize, Hit)>,
    target_hits: Vec<(usize, Hit)>,
}

/// Chunks georeferenced at once before their hits are filed by reference: the chunks' own
/// lists stay bounded (64 x 32 Ki returns) whatever the survey's length.
const BATCH_CHUNKS: usize = 64;
/// Returns per parallel work item of the first pass.
const CHUNK_RETURNS: usize = 1 << 15;

/// Georeferences every return of one file (pass `pass`) and gives those on a control
/// point's target (first) or on a patch to their visits (`found`: the patches', the
/// targets'), a batch of chunks at a time.
fn first_pass(
    model: &ReturnModel,
    file: &ProfileFile,
    (pass, at): (usize, (&PatchIndex, &TargetIndex)),
    (patches, targets): (&mut Visits, &mut Visits),
    (counts, near): (&mut ObserveCounts, &mut NearPlane),
) {
    let n = file.len();
    let chunks = n.div_ceil(CHUNK_RETURNS);
    for batch in (0..chunks).step_by(BATCH_CHUNKS) {
        let tallies: Vec<ChunkTally> = (batch..(batch + BATCH_CHUNKS).min(chunks))
            .into_par_iter()
            .map(|k| {
                chunk_tally(
                    model,
                    file,
                    at,
                    k * CHUNK_RETURNS..((k + 1) * CHUNK_RETURNS).min(n),
                )
            })
            .collect();
        for t in tallies {
            for (reason, k) in t.rejected {
                *counts.rejected.entry(reason).or_default() += k;
            }
            counts.off_patches += t.off_patches;
            for (patch, k) in t.off_plane {
                counts.off_plane += k;
                near.off[patch] += k;
            }
            counts.on_patches += t.hits.len() as u64;
            counts.on_targets += t.target_hits.len() as u64;
            for (patch, h) in t.hits {
                near.on[patch] += 1;
                patches.push((patch, pass), h);
            }
            for (point, h) in t.target_hits {
                targets.push((point, pass), h);
            }
        }
        model.traj.release();
    }
    counts.returns_read += n as u64;
}

/// The first pass over records `range` of `file`; their pages are released after (the
/// resident set stays flat over the file).
fn chunk_tally(
    model: &ReturnModel,
    file: &ProfileFile,
    (index, targets): (&PatchIndex, &TargetIndex),
    range: std::ops::Range<usize>,
) -> ChunkTally {
    let mut tally = ChunkTally::default();
    let mut cursor = model.cursor();
    for i in range.clone() {
        let r = file.get(i);
        let loc = match model.locate(&r, &mut cursor) {
            Err(reason) => {
                *tally.rejected.entry(reason).or_default() += 1;
                continue;
            }
            Ok(loc) => loc,
        };
        let hit = |d_m| Hit {
            index: i,
            t_s: loc.t_s,
            d_m,
        };
        if let Some(t) = targets.find(&loc.x_e, r.intensity) {
            tally.target_hits.push((t, hit(0.0)));
            continue;
        }
        match index.place(&loc.x_e) {
            Place::Off => tally.off_patches += 1,
            Place::OffPlane(patch) => *tally.off_plane.entry(patch).or_default() += 1,
            Place::On(patch, d_m) => tally.hits.push((patch, hit(d_m))),
        }
    }
    file.release(range);
    tally
}
