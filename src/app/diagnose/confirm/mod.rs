//! The verdict on the re-observed gap (docs/diagnosis.md, "Confirmed on the survey observed
//! again"): an explanation the selection proposes is applied to the pipeline, the survey is
//! observed again with it (same screening, same navigation model), the same effects are fitted
//! again there and added until the estimate moves by less than [`SETTLED_SIGMA`] of its sigma
//! (at most [`MAX_ROUNDS`] rounds), and the verdict is taken on the held-out gap of that last
//! observation, not on a linear prediction of it, with the correction's own error counted as
//! noise (the first fit's covariance carried into the held-out covariance).

use super::model::fit::Normals;
use super::model::metrics::{chi2_sf_spread, gap, Gap};
use super::model::{Effect, ObservationSet};
use super::observe::{self, References};
use crate::pipeline::config::{DiagnoseConfig, LoadedPipeline};
use crate::Result;
use nalgebra::DMatrix;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

pub mod reprocess;

/// The estimate has settled when the re-fit at the re-observed state moves every effect by
/// less than this many of its sigmas.
pub const SETTLED_SIGMA: f64 = 0.1;
/// Most rounds of correction and observation (each re-processes the survey).
pub const MAX_ROUNDS: usize = 3;

/// The diagnosis' screening and navigation model applied to a survey observed again, and the
/// variance the model's sampling error adds to `r^T C^-1 r` on the held-out references named.
pub type Prepare<'a> = dyn Fn(ObservationSet, &[String]) -> (ObservationSet, f64) + 'a;

/// What to apply and where to judge it.
pub struct Proposal<'a> {
    /// The explanation's effects (one member of each group) and their estimates.
    pub applied: Vec<(Effect, f64)>,
    /// The estimates' covariance as reported (names' units, in `applied`'s order).
    pub covariance: &'a DMatrix<f64>,
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
    /// Held-out gap there, the variance the learned navigation model's sampling error adds to
    /// its `r^T C^-1 r`, the chi-square with the correction's covariance in the held-out
    /// covariance (`Normals::chi2_given_correction_cov`), and the p-value of that under the
    /// model (`chi2_sf_spread`).
    pub after: Gap,
    pub after_chi2_var: f64,
    pub after_chi2_given_estimate: f64,
    pub p_value: f64,
}

/// Applies `proposal` to every pipeline of `ps` (the surveys of one mount, diagnosed jointly),
/// observes `refs` again (`prepare`: the diagnosis' screening and navigation model, and the
/// variance its sampling error adds to the chi-square on the held-out references named) until
/// the estimate settles, and returns the last observation's gap.
pub fn confirm(
    ps: &[LoadedPipeline],
    refs: &References,
    cfg: &DiagnoseConfig,
    out_dir: &Path,
    proposal: &Proposal,
    prepare: &Prepare,
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
        let observed = observe::observe_joint(&corrected, refs, cfg)?.set;
        let (set, after_chi2_var) = prepare(observed, proposal.held_out_ids);
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
            // `I + N Sigma` is regular for positive semi-definite `N` and `Sigma`; should
            // rounding make it singular, the raw chi-square (never smaller) is tested.
            let after_chi2_given_estimate = Normals::of(&set, &held_out)?
                .chi2_given_correction_cov(&effects, proposal.covariance)
                .unwrap_or(after.chi2_per_dof * after.n as f64);
            let p_value =
                chi2_sf_spread(after_chi2_given_estimate, after.n, after_chi2_var, || {
                    "held-out gap re-observed with the correction applied".to_string()
                })?;
            return Ok(Confirmation {
                applied,
                set_lines,
                corrected,
                rounds,
                last_move_sigma,
                set,
                held_out,
                after,
                after_chi2_var,
                after_chi2_given_estimate,
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

/// The held-out gaps before and after on the same returns: the observations on `before_held`
/// of `before` and on `after_held` of `after` (the survey observed again) that are of one
/// return in both (same reference id, pass and record; a control point's observations in
/// their order). A correction moves returns onto and off the patches, and a visit that
/// gained or lost one is thinned at other returns, so the two observations' own held-out
/// returns differ; RMS and mean are only comparable on the returns they share. None when
/// they share none.
pub fn matched_gaps(
    (before, before_held): (&ObservationSet, &[usize]),
    (after, after_held): (&ObservationSet, &[usize]),
) -> Result<Option<(Gap, Gap)>> {
    let before_keys = return_keys(before, before_held, &Some);
    let by_id: Vec<Option<usize>> = after
        .reference_ids
        .iter()
        .map(|id| before.reference_ids.iter().position(|r| r == id))
        .collect();
    let after_keys = return_keys(after, after_held, &|r| by_id[r]);
    let shared = |keys: &[Option<ReturnKey>], other: &[Option<ReturnKey>]| -> Vec<bool> {
        let other: BTreeSet<ReturnKey> = other.iter().flatten().copied().collect();
        keys.iter()
            .map(|k| k.is_some_and(|k| other.contains(&k)))
            .collect()
    };
    let (keep_before, keep_after) = (
        shared(&before_keys, &after_keys),
        shared(&after_keys, &before_keys),
    );
    if !keep_before.contains(&true) {
        return Ok(None);
    }
    let b = gap(&subset(before, &keep_before), before_held, None)?;
    let a = gap(&subset(after, &keep_after), after_held, None)?;
    Ok(Some((b, a)))
}

/// Which return an observation is: (reference index in the first set, pass, record, its rank
/// among the observations with the same three).
type ReturnKey = (usize, usize, usize, usize);

/// The key of every observation of `set` on `refs` (None elsewhere, or when `reference`
/// maps its reference to none).
fn return_keys(
    set: &ObservationSet,
    refs: &[usize],
    reference: &dyn Fn(usize) -> Option<usize>,
) -> Vec<Option<ReturnKey>> {
    let mut on = vec![false; set.reference_ids.len()];
    for &r in refs {
        on[r] = true;
    }
    let mut seen: BTreeMap<(usize, usize, usize), usize> = BTreeMap::new();
    set.observations
        .iter()
        .map(|o| {
            let r = reference(o.reference).filter(|_| on[o.reference])?;
            let id = (r, o.covariates.pass, o.record);
            let rank = seen.entry(id).or_default();
            *rank += 1;
            Some((id.0, id.1, id.2, *rank))
        })
        .collect()
}

/// `set` with only the observations `keep` marks (visits and references kept).
fn subset(set: &ObservationSet, keep: &[bool]) -> ObservationSet {
    ObservationSet {
        observations: set
            .observations
            .iter()
            .zip(keep)
            .filter(|(_, &k)| k)
            .map(|(o, _)| o.clone())
            .collect(),
        ..set.clone_without_observations()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::diagnose::model::synthetic::{draw, Scenario};

    #[test]
    fn before_and_after_are_over_the_returns_both_observations_found() {
        let before = draw(&Scenario::default(), 3);
        let refs = before.observed_references();
        // Observed again: every third return lost, every fifth one another record (thinned
        // elsewhere), the residuals halved by the correction.
        let mut after = before.clone();
        after.observations.retain(|o| o.record % 3 != 0);
        for o in &mut after.observations {
            o.residual_m *= 0.5;
            if o.record % 5 == 0 {
                o.record += before.observations.len();
            }
        }
        let matched = matched_gaps((&before, &refs), (&after, &refs));
        let (b, a) = matched.unwrap().expect("returns in common");
        let shared: Vec<f64> = before
            .observations
            .iter()
            .filter(|o| o.record % 3 != 0 && o.record % 5 != 0)
            .map(|o| o.residual_m)
            .collect();
        let n = shared.len();
        let rms = (shared.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
        let mean = shared.iter().sum::<f64>() / n as f64;
        assert_eq!((b.n, a.n), (n, n));
        assert!((b.rms_m - rms).abs() <= 1e-12 * rms, "{} {rms}", b.rms_m);
        assert!(
            (a.rms_m - 0.5 * rms).abs() <= 1e-12 * rms,
            "{} {rms}",
            a.rms_m
        );
        assert!((a.mean_m - 0.5 * mean).abs() <= 1e-12 * rms);
        // Nothing in common: no matched gaps.
        for o in &mut after.observations {
            o.record += 2 * before.observations.len();
        }
        assert!(matched_gaps((&before, &refs), (&after, &refs))
            .unwrap()
            .is_none());
    }
}
