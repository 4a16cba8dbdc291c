//! The verdict on the re-observed gap (docs/diagnosis.md, "Confirmed on the survey observed
//! again"): an explanation the selection proposes is applied to the pipeline, the survey is
//! observed again with it (same screening, same navigation model), the same effects are fitted
//! again there and added until the estimate moves by less than [`SETTLED_SIGMA`] of its sigma
//! (at most [`MAX_ROUNDS`] rounds), and the verdict is taken on the held-out gap of that last
//! observation, not on a linear prediction of it.

use super::model::fit::Normals;
use super::model::metrics::{chi2_sf, gap, Gap};
use super::model::{Effect, ObservationSet};
use super::observe::{self, References};
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::Result;
use std::path::Path;

pub mod reprocess;

/// The estimate has settled when the re-fit at the re-observed state moves every effect by
/// less than this many of its sigmas.
pub const SETTLED_SIGMA: f64 = 0.1;
/// Most rounds of correction and observation (each re-processes the survey).
pub const MAX_ROUNDS: usize = 3;

/// What to apply and where to judge it.
pub struct Proposal<'a> {
    /// The explanation's effects (each group's preferred member) and their estimates.
    pub applied: Vec<(Effect, f64)>,
    /// Reference ids fitted on and held out.
    pub fit_ids: &'a [String],
    pub held_out_ids: &'a [String],
}

/// The survey observed again with the settled correction.
pub struct Confirmation {
    /// The correction applied in the last round (the proposal plus every re-fit).
    pub applied: Vec<(Effect, f64)>,
    /// Per pipeline diagnosed, its `--set` lines and the corrected pipeline they give.
    pub set_lines: Vec<Vec<String>>,
    pub corrected: Vec<LoadedPipeline>,
    /// Rounds run, and the last re-fit's largest move in sigmas.
    pub rounds: usize,
    pub last_move_sigma: f64,
    /// The last observation (screened, navigation model applied) and its held-out references.
    pub set: ObservationSet,
    pub held_out: Vec<usize>,
    /// Held-out gap there, and `P(chi2_n > chi2)` of it.
    pub after: Gap,
    pub p_value: f64,
}

/// Applies `proposal` to every pipeline of `ps` (the surveys of one mount, diagnosed jointly),
/// observes `refs` again (`prepare`: the diagnosis' screening and navigation model) until the
/// estimate settles, and returns the last observation's gap.
pub fn confirm(
    ps: &[LoadedPipeline],
    refs: &References,
    cfg: &DiagnoseConfig,
    out_dir: &Path,
    proposal: &Proposal,
    prepare: &dyn Fn(&ObservationSet) -> ObservationSet,
) -> Result<Confirmation> {
    let effects: Vec<Effect> = proposal.applied.iter().map(|(e, _)| *e).collect();
    let mut applied = proposal.applied.clone();
    let mut rounds = 0;
    loop {
        rounds += 1;
        let set_lines = ps
            .iter()
            .map(|p| reprocess::set_lines(&p.config, &applied))
            .collect::<Result<Vec<_>>>()?;
        let corrected = ps
            .iter()
            .zip(&set_lines)
            .map(|(p, lines)| reprocess::corrected(p, lines, out_dir))
            .collect::<Result<Vec<_>>>()?;
        let set = prepare(&observe::observe_joint(&corrected, refs, cfg)?.set);
        let fit_refs = references_of(&set, proposal.fit_ids);
        let refit = Normals::of(&set, &fit_refs)?.fit(&effects)?;
        let last_move_sigma = refit
            .estimate
            .iter()
            .zip(&refit.sigma)
            .map(|(x, s)| (x / s).abs())
            // A non-finite move is never "settled" (f64::max would drop a NaN).
            .fold(0.0, |m: f64, v| if v.is_nan() || v > m { v } else { m });
        if last_move_sigma < SETTLED_SIGMA || rounds == MAX_ROUNDS {
            let held_out = references_of(&set, proposal.held_out_ids);
            let after = gap(&set, &held_out, None)?;
            let p_value = chi2_sf(after.chi2_per_dof * after.n as f64, after.n);
            return Ok(Confirmation {
                applied,
                set_lines,
                corrected,
                rounds,
                last_move_sigma,
                set,
                held_out,
                after,
                p_value,
            });
        }
        for ((_, total), x) in applied.iter_mut().zip(&refit.estimate) {
            *total += x;
        }
    }
}

/// The indices of reference ids `ids` in `set` (ids without observations there are skipped).
pub fn references_of(set: &ObservationSet, ids: &[String]) -> Vec<usize> {
    ids.iter()
        .filter_map(|id| set.reference_ids.iter().position(|r| r == id))
        .collect()
}
