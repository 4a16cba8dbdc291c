//! Which catalogue effect explains the gap: after the observability of the catalogue
//! ([`self::observability`]), candidates (each group alone, every pair, greedy forward
//! additions) fitted on the fit references and judged on the held-out references, with likelihood-ratio significance under Holm control, and the verdict
//! `effect` | `none` | `unexplained` (docs/conventions.md §8; method: docs/diagnosis.md,
//! "Statistics").

use self::observability::{observability_of, Group, Observability};
use super::model::fit::{Fit, Normals, Split};
use super::model::metrics::{chi2_sf, chi2_sf_spread, holm_adjusted, normal_sf};
use super::model::{signature_index, Effect, ObservationSet, Theta};
use crate::Result;
use nalgebra::DMatrix;
use std::cell::RefCell;
use std::collections::HashMap;

pub mod observability;
pub mod power;

/// Default family-wise error rate of the selection's tests.
pub const DEFAULT_ALPHA: f64 = 0.01;
/// Most groups in one explanation.
const MAX_GROUPS: usize = 4;
/// Held-out reductions closer than this many sd of their difference do not tell two
/// explanations apart ([`judge`]).
const TIE_SD: f64 = 1.0;

/// `effect`, `none` or `unexplained` (docs/conventions.md §8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Catalogue effect(s) significant on the fit references, confirmed on the held-out
    /// references, and (when the model without them is rejected) closing the held-out gap:
    /// what remains on the held-out references after the correction passes the chi2 test.
    Effect,
    /// The model holds on the held-out references and no effect is significant.
    None,
    /// The model is rejected on the held-out references and no catalogue combination closes
    /// the gap, or the structure the fit references located is confirmed on the held-out
    /// references (`app::diagnose`, docs/diagnosis.md "Selection and verdict" step 8): no
    /// effect is named.
    Unexplained,
}

impl Verdict {
    /// The report's word.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Effect => "effect",
            Verdict::None => "none",
            Verdict::Unexplained => "unexplained",
        }
    }
}

/// One explanation tried.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Indices into [`Observability::groups`].
    pub groups: Vec<usize>,
    /// GLS fit on the fit references of one member per group: the preferred, unless the
    /// held-out references support another better (`Context::candidate`).
    pub fit: Fit,
    /// Likelihood-ratio p-value on the fit references (of the groups' preferred members,
    /// which these references cannot tell from the others): against no effect for a single group;
    /// for a pair, the largest of that and each member's test given the other (both needed);
    /// for a greedy addition, the added group given the rest. Each test's p-value is the
    /// largest over the navigation models the survey cannot reject (the estimate's and the
    /// others given to [`select`]).
    pub p_value: f64,
    /// Holm-adjusted `p_value` among the candidates of its step.
    pub p_holm: f64,
    /// Significant under Holm control: `p_holm <= alpha`.
    pub significant: bool,
    /// Held-out `chi2` with the fit's estimates.
    pub chi2_held_out: f64,
    /// Held-out chi2 removed, relative to the model it extends (no effect, or the smaller
    /// explanation for a greedy addition).
    pub held_out_reduction: f64,
    /// One-sided p-value of the held-out score along the correction (the held-out data were
    /// not used to fit it: N(0, 1) under no effect).
    pub held_out_p_value: f64,
}

impl Candidate {
    fn supported(&self, alpha: f64) -> bool {
        self.held_out_reduction > 0.0 && self.held_out_p_value < alpha
    }
}

/// The test of the model without any effect on the held-out references.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NullTest {
    /// Held-out `r^T C^-1 r`.
    pub chi2: f64,
    /// Held-out returns (degrees of freedom).
    pub n: usize,
    /// Variance the learned navigation model's sampling error adds to `chi2` (0: known).
    pub extra_var: f64,
    /// `P(chi2 exceeded)` under the null model: `chi2_n`, its variance widened by what the
    /// learned navigation model's sampling error adds (`metrics::chi2_sf_spread`).
    pub p_value: f64,
    /// `p_value < alpha`.
    pub rejected: bool,
}

impl NullTest {
    /// An error when `chi2` or `extra_var` is not finite (`metrics::chi2_sf_spread`).
    fn new(chi2: f64, n: usize, alpha: f64, extra_var: f64, what: &str) -> Result<Self> {
        let p_value = chi2_sf_spread(chi2, n, extra_var, || what.to_string())?;
        Ok(NullTest {
            chi2,
            n,
            extra_var,
            p_value,
            rejected: p_value < alpha,
        })
    }
}

/// The result of [`select`].
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The verdict.
    pub verdict: Verdict,
    /// Named effects (verdict `effect`): every member of each chosen group, the one the
    /// explanation takes (and the re-run corrects) first.
    pub effects: Vec<Effect>,
    /// Estimate of each named effect (fit references), in the unit of its name: a
    /// group's other member's estimate is from the same explanation with it in place of the
    /// first.
    pub estimate: Vec<f64>,
    /// 1-sigma of each estimate.
    pub sigma: Vec<f64>,
    /// The chosen explanation's effects, estimates and sigmas as `effects`, `estimate` and
    /// `sigma` give them, whatever the verdict: the verdict here is judged on the linearised
    /// held-out gap, and the diagnosis judges it again on the survey observed with the
    /// correction applied (`app::diagnose::confirm`).
    pub proposed: Option<Named>,
    /// The explanation to re-process with (one member of each chosen group, fitted on the
    /// fit references); also set when the verdict is `unexplained` but a partial explanation
    /// was significant, so a report can say how little it closes.
    pub chosen: Option<Fit>,
    /// Share of the held-out excess chi2 (`chi2 - n`) the chosen explanation removes, when the
    /// excess is positive.
    pub closure: Option<f64>,
    /// The model without any effect, on the held-out references.
    pub null: NullTest,
    /// The same test after the chosen explanation (held-out references, estimates from the
    /// fit references).
    pub remaining: Option<NullTest>,
    /// The chosen explanation's groups, each joined by the groups the residuals cannot reject
    /// in its place ([`Group::rivals`]), in the order of `chosen`'s effects; empty without an
    /// explanation.
    pub named_groups: Vec<Group>,
    /// Observability on the fit references.
    pub observability: Observability,
    /// Every candidate tried, largest held-out reduction first.
    pub candidates: Vec<Candidate>,
    /// Family-wise error rate used.
    pub alpha: f64,
}

impl Selection {
    /// The correction `theta` of the named explanation (none unless the verdict is `effect`).
    pub fn correction(&self) -> Option<Theta<'_>> {
        match (&self.chosen, self.verdict) {
            (Some(f), Verdict::Effect) => Some(Theta {
                effects: &f.effects,
                values: &f.estimate,
            }),
            _ => None,
        }
    }
}

/// The covariance of every fit made on one set of fit references (`None`: inseparable). It
/// depends on the signatures alone, so that [`power`] runs the selection on many draws of
/// the residuals with one.
type Covariances = RefCell<HashMap<Vec<Effect>, Option<DMatrix<f64>>>>;

/// The fit references' normals under a navigation model the survey cannot reject besides the
/// estimate's: each test on the fit references takes its largest p-value over these and the
/// estimate's ([`select`]).
#[derive(Debug, Clone)]
pub struct OtherModel {
    /// `X^T C^-1 X` of the fit references under the model.
    pub normals: Normals,
    /// Whether each estimate's sigma is the larger of this model's and the estimate's (a
    /// model of another structure than the estimate's: `nuisance::slow_alternative`).
    pub widens_sigma: bool,
}

/// The fit references' normals under a node of the quadrature over the navigation model's
/// sampling distribution (`nuisance::sampling_nodes`): each reported sigma is the root of the
/// weighted mean, over the nodes and the estimate, of the fit's variance there plus its
/// estimate's squared distance from the estimate's (the law of total variance), so that it
/// carries what the survey could not tell about the model.
#[derive(Debug, Clone)]
pub struct Node {
    /// `X^T C^-1 X` of the fit references under the node's model.
    pub normals: Normals,
    /// The node's weight (the estimate takes what the nodes leave of 1).
    pub weight: f64,
}

/// The fit references' normals under one navigation model, and the covariances of the fits
/// made on them.
#[derive(Clone, Copy)]
struct Model<'a> {
    normals: &'a Normals,
    covariances: &'a Covariances,
    widens_sigma: bool,
}

impl Model<'_> {
    /// The GLS fit of `effects`; `None` when inseparable.
    fn fit_of(&self, effects: &[Effect]) -> Option<Fit> {
        let cov = self
            .covariances
            .borrow_mut()
            .entry(effects.to_vec())
            .or_insert_with(|| self.normals.covariance(effects).ok())
            .clone()?;
        Some(self.normals.fit_with(effects, cov))
    }

    /// `chi2` of the GLS fit of `effects` (of no effect when empty); `None` when inseparable.
    fn chi2_of(&self, effects: &[Effect]) -> Option<f64> {
        if effects.is_empty() {
            return Some(self.normals.chi2_null());
        }
        self.fit_of(effects).map(|f| f.chi2)
    }
}

/// The fit and held-out statistics under the estimated navigation model, the fit
/// references' under the others the survey cannot reject, and the groups.
struct Context<'a> {
    fit: Model<'a>,
    others: Vec<Model<'a>>,
    nodes: Vec<(Model<'a>, f64)>,
    held: &'a Normals,
    groups: &'a [Group],
}

impl<'a> Context<'a> {
    /// `fit` and `covariances` under the estimated model; `others` the other models' fit
    /// normals, each with its own covariances and whether it widens the sigmas.
    fn new(
        (fit, covariances): (&'a Normals, &'a Covariances),
        others: impl IntoIterator<Item = (&'a Normals, &'a Covariances, bool)>,
        held: &'a Normals,
        groups: &'a [Group],
    ) -> Self {
        Context {
            fit: Model {
                normals: fit,
                covariances,
                widens_sigma: false,
            },
            others: others
                .into_iter()
                .map(|(normals, covariances, widens_sigma)| Model {
                    normals,
                    covariances,
                    widens_sigma,
                })
                .collect(),
            nodes: Vec::new(),
            held,
            groups,
        }
    }

    /// `self` with each sigma averaged over `nodes` (normals, covariances, weight: [`Node`]).
    fn averaged_over(
        mut self,
        nodes: impl IntoIterator<Item = (&'a Normals, &'a Covariances, f64)>,
    ) -> Self {
        self.nodes = nodes
            .into_iter()
            .map(|(normals, covariances, weight)| {
                let m = Model {
                    normals,
                    covariances,
                    widens_sigma: false,
                };
                (m, weight)
            })
            .collect();
        self
    }

    /// The preferred members of `groups`: what the fit references' tests take them as.
    fn effects(&self, groups: &[usize]) -> Vec<Effect> {
        groups.iter().map(|&g| self.groups[g].members[0]).collect()
    }

    /// `chi2` of the fit of the preferred members of `groups` on the fit references (the
    /// likelihood-ratio tests'); `None` when inseparable.
    fn preferred_chi2(&self, groups: &[usize]) -> Option<f64> {
        self.fit.chi2_of(&self.effects(groups))
    }

    /// Every way of taking `groups` as one member each, the preferred members first; a group
    /// with a member in `fixed` (the explanation extended) keeps it.
    fn representations(&self, groups: &[usize], fixed: &[Effect]) -> Vec<Vec<Effect>> {
        let mut out = vec![Vec::new()];
        for &g in groups {
            let members = &self.groups[g].members;
            let choices = match members.iter().find(|m| fixed.contains(m)) {
                Some(&m) => vec![m],
                None => members.clone(),
            };
            out = out
                .iter()
                .flat_map(|r| {
                    choices.iter().map(move |&m| {
                        let mut r = r.clone();
                        r.push(m);
                        r
                    })
                })
                .collect();
        }
        out
    }

    /// The sd from the held-out noise of the difference of two corrections' held-out
    /// reductions, `chi2(b) - chi2(a)`: `2 sqrt(d^T C^-1 d)`, `d` the difference of the
    /// corrections.
    fn reduction_sd(&self, a: &Fit, b: &Fit) -> f64 {
        let effects: Vec<Effect> = a.effects.iter().chain(&b.effects).copied().collect();
        let delta: Vec<f64> = a
            .estimate
            .iter()
            .copied()
            .chain(b.estimate.iter().map(|x| -x))
            .collect();
        2.0 * self.held.quadratic(&effects, &delta).max(0.0).sqrt()
    }

    /// The largest |correlation| on the fit references between a member of group `a` and one
    /// of group `b`, each pair fitted together.
    fn largest_correlation(&self, a: usize, b: usize) -> f64 {
        let m = &self.fit.normals.m;
        let mut largest: f64 = 0.0;
        for &x in &self.groups[a].members {
            for &y in &self.groups[b].members {
                let (i, j) = (signature_index(x), signature_index(y));
                largest = largest.max(m[(i, j)].abs() / (m[(i, i)] * m[(j, j)]).sqrt());
            }
        }
        largest
    }

    /// The GLS fit of `effects` on the fit references; `None` when inseparable.
    fn fit_of(&self, effects: &[Effect]) -> Option<Fit> {
        self.fit.fit_of(effects).map(|f| self.widened(f))
    }

    /// `fit` with each sigma averaged over the nodes ([`Node`]; a node where the effects are
    /// inseparable, or whose fit is not finite, counts as the estimate), then the largest of that and those of the same
    /// fit under the other models that widen it (the covariance scaled to match, its
    /// correlations kept).
    fn widened(&self, mut fit: Fit) -> Fit {
        if !self.nodes.is_empty() {
            let centre = 1.0 - self.nodes.iter().map(|(_, w)| w).sum::<f64>();
            let mut var: Vec<f64> = fit.sigma.iter().map(|s| centre * s * s).collect();
            for (m, w) in &self.nodes {
                let at = m
                    .fit_of(&fit.effects)
                    .filter(|o| o.sigma.iter().chain(&o.estimate).all(|v| v.is_finite()));
                for (i, v) in var.iter_mut().enumerate() {
                    *v += w * at.as_ref().map_or(fit.sigma[i].powi(2), |o| {
                        o.sigma[i].powi(2) + (o.estimate[i] - fit.estimate[i]).powi(2)
                    });
                }
            }
            fit.set_sigma(&var.iter().map(|v| v.sqrt()).collect::<Vec<_>>());
        }
        for m in self.others.iter().filter(|m| m.widens_sigma) {
            if let Some(other) = m.fit_of(&fit.effects) {
                fit.widen_sigma(&other.sigma);
            }
        }
        fit
    }

    /// The likelihood-ratio p-value of `larger` against the nested `smaller` on the fit
    /// references, `drop` being the estimated model's fall of chi2 from one to the other: the
    /// largest of the estimated model's and the other models' (1 where a model cannot separate
    /// the effects or gives no finite drop).
    fn p_over_models(&self, drop: f64, larger: &[Effect], smaller: &[Effect]) -> f64 {
        let dof = larger.len() - smaller.len();
        // A non-finite drop is no evidence for the larger explanation.
        let p_of = |drop: f64| {
            if drop.is_finite() {
                chi2_sf(drop, dof)
            } else {
                1.0
            }
        };
        self.others.iter().fold(p_of(drop), |worst, m| {
            let q = match (m.chi2_of(smaller), m.chi2_of(larger)) {
                (Some(s), Some(l)) => p_of(s - l),
                _ => 1.0,
            };
            worst.max(q)
        })
    }

    /// Fits `groups` on the fit references and judges them on the held-out ones against
    /// `base` (the explanation they extend: `None` = no effect). Each group is taken as its
    /// preferred member unless the held-out references support another member better by more
    /// than [`TIE_SD`] sd of the difference ([`Self::reduction_sd`]): the fit references cannot
    /// tell a group's members apart, the held-out ones may (other ranges, other headings).
    /// `None` when the preferred members are inseparable.
    fn candidate(&self, groups: Vec<usize>, base: Option<&Fit>, p_value: f64) -> Option<Candidate> {
        let fixed = base.map_or(&[][..], |b| &b.effects[..]);
        let mut judged = self
            .representations(&groups, fixed)
            .into_iter()
            .map(|effects| self.judged(&effects, base));
        let mut best = judged.next().flatten()?;
        for other in judged.flatten() {
            let gain = other.held_out_reduction - best.held_out_reduction;
            if gain > TIE_SD * self.reduction_sd(&best.fit, &other.fit) {
                best = other;
            }
        }
        Some(Candidate {
            groups,
            p_value,
            ..best
        })
    }

    /// `effects` fitted on the fit references and judged on the held-out ones against `base`
    /// (groups and p-value left for [`Self::candidate`]); `None` when inseparable.
    fn judged(&self, effects: &[Effect], base: Option<&Fit>) -> Option<Candidate> {
        let fit = self.fit_of(effects)?;
        let chi2_held_out = self.held.chi2_at(&fit.effects, &fit.estimate);
        // The change of the correction relative to the base, in the fit's effect order.
        let delta: Vec<f64> = fit
            .effects
            .iter()
            .zip(&fit.estimate)
            .map(|(e, x)| {
                let before =
                    base.and_then(|b| b.effects.iter().position(|f| f == e).map(|i| b.estimate[i]));
                x - before.unwrap_or(0.0)
            })
            .collect();
        let chi2_base = base.map_or(self.held.chi2_null(), |b| {
            self.held.chi2_at(&b.effects, &b.estimate)
        });
        let held_out_reduction = chi2_base - chi2_held_out;
        // reduction = 2 d'C^-1 r' - d'C^-1 d, d = S delta: the score z = d'C^-1 r' / |d|.
        let quad = self.held.quadratic(&fit.effects, &delta);
        let z = (held_out_reduction + quad) / (2.0 * quad.sqrt());
        let held_out_p_value = if quad > 0.0 { normal_sf(z) } else { 1.0 };
        Some(Candidate {
            groups: Vec::new(),
            fit,
            p_value: 1.0,
            p_holm: 1.0,
            significant: false,
            chi2_held_out,
            held_out_reduction,
            held_out_p_value,
        })
    }
}

/// Marks the Holm-significant candidates; returns the index of the chosen one. Among the
/// significant, supported candidates, the held-out references cannot tell apart the one
/// with the largest held-out reduction and those whose reduction falls short of it by less
/// than [`TIE_SD`] sd of the difference; of these, the fit references choose the one with the
/// smallest fit chi2 plus 2 per effect (docs/diagnosis.md, "Selection and verdict").
fn judge(cx: &Context, candidates: &mut [Candidate], alpha: f64) -> Option<usize> {
    let p: Vec<f64> = candidates.iter().map(|c| c.p_value).collect();
    for (c, q) in candidates.iter_mut().zip(holm_adjusted(&p)) {
        c.p_holm = q;
        c.significant = q <= alpha;
    }
    let eligible: Vec<usize> = (0..candidates.len())
        .filter(|&i| candidates[i].significant && candidates[i].supported(alpha))
        .collect();
    let best = *eligible.iter().max_by(|&&a, &&b| {
        candidates[a]
            .held_out_reduction
            .total_cmp(&candidates[b].held_out_reduction)
    })?;
    let b = &candidates[best];
    let tied = |c: &Candidate| {
        b.held_out_reduction - c.held_out_reduction <= TIE_SD * cx.reduction_sd(&b.fit, &c.fit)
    };
    let penalised = |c: &Candidate| c.fit.chi2 + 2.0 * c.fit.effects.len() as f64;
    eligible
        .into_iter()
        .filter(|&i| tied(&candidates[i]))
        .min_by(|&a, &b| penalised(&candidates[a]).total_cmp(&penalised(&candidates[b])))
}

/// Each group alone and every pair (the pair's p-value requires both members). The
/// likelihood ratios are those of the groups' preferred members ([`Context::candidate`] may
/// take another member for the estimate and the held-out judgement).
fn first_step(cx: &Context) -> Vec<Candidate> {
    let null_chi2 = cx.fit.normals.chi2_null();
    let singles: Vec<Option<(Candidate, f64)>> = (0..cx.groups.len())
        .map(|g| {
            let c = cx.candidate(vec![g], None, 1.0)?;
            let chi2 = cx.preferred_chi2(&[g])?;
            let p = cx.p_over_models(null_chi2 - chi2, &cx.effects(&[g]), &[]);
            Some((Candidate { p_value: p, ..c }, chi2))
        })
        .collect();
    let mut out: Vec<Candidate> = Vec::new();
    for a in 0..cx.groups.len() {
        for b in a + 1..cx.groups.len() {
            let (Some((_, chi2_a)), Some((_, chi2_b))) = (&singles[a], &singles[b]) else {
                continue;
            };
            let (Some(c), Some(chi2)) = (
                cx.candidate(vec![a, b], None, 1.0),
                cx.preferred_chi2(&[a, b]),
            ) else {
                continue;
            };
            let pair = cx.effects(&[a, b]);
            let p = [
                cx.p_over_models(null_chi2 - chi2, &pair, &[]),
                cx.p_over_models(chi2_a - chi2, &pair, &cx.effects(&[a])),
                cx.p_over_models(chi2_b - chi2, &pair, &cx.effects(&[b])),
            ]
            .into_iter()
            .fold(0.0, f64::max);
            out.push(Candidate { p_value: p, ..c });
        }
    }
    singles
        .into_iter()
        .flatten()
        .map(|(c, _)| c)
        .chain(out)
        .collect()
}

/// Greedy forward additions to `current`, one group at a time.
fn extend(
    cx: &Context,
    mut current: Candidate,
    alpha: f64,
    tried: &mut Vec<Candidate>,
) -> Candidate {
    while current.groups.len() < MAX_GROUPS {
        let Some(chi2_current) = cx.preferred_chi2(&current.groups) else {
            break;
        };
        let current_effects = cx.effects(&current.groups);
        let mut step: Vec<Candidate> = (0..cx.groups.len())
            .filter(|g| !current.groups.contains(g))
            .filter_map(|g| {
                let mut groups = current.groups.clone();
                groups.push(g);
                let c = cx.candidate(groups.clone(), Some(&current.fit), 1.0)?;
                let drop = chi2_current - cx.preferred_chi2(&groups)?;
                let p = cx.p_over_models(drop, &cx.effects(&groups), &current_effects);
                Some(Candidate { p_value: p, ..c })
            })
            .collect();
        let best = judge(cx, &mut step, alpha);
        let next = best.map(|i| step[i].clone());
        tried.append(&mut step);
        match next {
            Some(n) => current = n,
            None => break,
        }
    }
    current
}

/// The selection's search on `cx`: each group alone and every pair, judged under Holm
/// control; the best supported one extended by greedy additions. Every candidate tried, and
/// the chosen explanation.
fn choose(cx: &Context, alpha: f64) -> (Vec<Candidate>, Option<Candidate>) {
    let mut candidates = first_step(cx);
    let best = judge(cx, &mut candidates, alpha).map(|i| candidates[i].clone());
    let chosen = best.map(|b| extend(cx, b, alpha, &mut candidates));
    (candidates, chosen)
}

/// The chosen explanation's groups, each joined by its rivals: the groups not chosen that the
/// residuals cannot reject in its place. A group `h` is a rival of the chosen `g` when `g`,
/// added to the explanation with `h` in its place, is not significant at `alpha` (the
/// likelihood ratio on the fit references, its largest p-value over the navigation models),
/// or cannot be separated there. A rival is joined to the first chosen group it stands in
/// for. Whatever the geometry's correlation, the residuals then do not tell the two apart: a
/// small effect seen through a correlated one is named with it, not instead of it.
fn named_groups(cx: &Context, chosen: &Candidate, alpha: f64) -> Vec<Group> {
    let rep = |g: usize| cx.groups[g].members[0];
    let effects = chosen.fit.effects.clone();
    let mut taken: Vec<usize> = chosen.groups.clone();
    let mut out = Vec::with_capacity(chosen.groups.len());
    for (slot, &g) in chosen.groups.iter().enumerate() {
        // The member the explanation takes (the one corrected) first.
        let mut named = cx.groups[g].clone();
        named.members.retain(|&m| m != effects[slot]);
        named.members.insert(0, effects[slot]);
        for h in 0..cx.groups.len() {
            if taken.contains(&h) {
                continue;
            }
            let mut swap = effects.clone();
            swap[slot] = rep(h);
            let Some(chi2_swap) = cx.fit.chi2_of(&swap) else {
                continue;
            };
            let mut both = swap.clone();
            both.push(effects[slot]);
            let p = match cx.fit.chi2_of(&both) {
                Some(chi2_both) => cx.p_over_models(chi2_swap - chi2_both, &both, &swap),
                None => 1.0,
            };
            if p > alpha {
                named.join_rival(&cx.groups[h], cx.largest_correlation(g, h));
                taken.push(h);
            }
        }
        out.push(named);
    }
    out
}

/// Selects the explanation of the gap: fits on `split.fit`, judges on `split.held_out`, tests
/// at family-wise error rate `alpha` ([`DEFAULT_ALPHA`] by default); the held-out chi-square
/// tests with `held_out_chi2_var` added to their variance (the learned navigation model's
/// sampling error, `nuisance::chi2_variance`; 0 with the model known). `others` are the fit
/// references' normals under the other navigation models the survey cannot reject
/// (`nuisance::interval_ends`, `nuisance::slow_alternative`): each test on the fit references
/// takes its largest p-value over them and the estimate's; estimates and the held-out tests
/// are the estimate's, each sigma averaged over `nodes` (the model's sampling distribution,
/// [`Node`]) and then the largest of that and those of the models that widen it.
pub fn select(
    set: &ObservationSet,
    split: &Split,
    alpha: f64,
    held_out_chi2_var: f64,
    (others, nodes): (&[OtherModel], &[Node]),
) -> Result<Selection> {
    let fit_n = Normals::of(set, &split.fit)?;
    let held = Normals::of(set, &split.held_out)?;
    let observability = observability_of(&fit_n, &Effect::ALL);
    let null_chi2 = held.chi2_null();
    let null = NullTest::new(
        null_chi2,
        held.n,
        alpha,
        held_out_chi2_var,
        "held-out gap without any effect",
    )?;
    let covariances = Covariances::default();
    let other_covariances: Vec<Covariances> =
        others.iter().map(|_| Covariances::default()).collect();
    let node_covariances: Vec<Covariances> = nodes.iter().map(|_| Covariances::default()).collect();
    let cx = Context::new(
        (&fit_n, &covariances),
        others
            .iter()
            .zip(&other_covariances)
            .map(|(m, c)| (&m.normals, c, m.widens_sigma)),
        &held,
        &observability.groups,
    )
    .averaged_over(
        nodes
            .iter()
            .zip(&node_covariances)
            .map(|(n, c)| (&n.normals, c, n.weight)),
    );
    let (mut candidates, chosen) = choose(&cx, alpha);
    candidates.sort_by(|a, b| b.held_out_reduction.total_cmp(&a.held_out_reduction));

    let excess = null_chi2 - held.n as f64;
    let closure = match &chosen {
        Some(c) if excess > 0.0 => Some((null_chi2 - c.chi2_held_out) / excess),
        _ => None,
    };
    let remaining = chosen
        .as_ref()
        .map(|c| {
            let what = "held-out gap the chosen explanation leaves";
            NullTest::new(c.chi2_held_out, held.n, alpha, held_out_chi2_var, what)
        })
        .transpose()?;
    // A rejected gap is closed only when what the explanation leaves passes the same test: a
    // right explanation leaves its estimation error alone (about k of chi2).
    let closes = remaining.is_some_and(|r| !r.rejected);
    let verdict = match (&chosen, null.rejected) {
        (Some(_), false) => Verdict::Effect,
        (Some(_), true) if closes => Verdict::Effect,
        (_, true) => Verdict::Unexplained,
        (None, false) => Verdict::None,
    };
    let named_groups = chosen
        .as_ref()
        .map_or_else(Vec::new, |c| self::named_groups(&cx, c, alpha));
    let proposed = chosen
        .as_ref()
        .map(|c| named(&cx, c, &named_groups))
        .transpose()?;
    let (effects, estimate, sigma) = match (&proposed, verdict) {
        (Some(n), Verdict::Effect) => (n.effects.clone(), n.estimate.clone(), n.sigma.clone()),
        _ => (Vec::new(), Vec::new(), Vec::new()),
    };
    Ok(Selection {
        verdict,
        effects,
        estimate,
        sigma,
        proposed,
        chosen: chosen.map(|c| c.fit),
        closure,
        null,
        remaining,
        named_groups,
        observability,
        candidates,
        alpha,
    })
}

/// Every member of an explanation's groups with its estimate and sigma.
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    /// The members, each group's corrected member first.
    pub effects: Vec<Effect>,
    /// Estimates (fit references), in each name's unit.
    pub estimate: Vec<f64>,
    /// 1-sigma of each estimate.
    pub sigma: Vec<f64>,
}

/// Every member of the chosen groups and their rivals (`groups`, [`named_groups`]) with its
/// estimate and sigma (another than the first member fitted in its place, or alone when
/// that is singular).
fn named(cx: &Context, chosen: &Candidate, groups: &[Group]) -> Result<Named> {
    let (mut effects, mut estimate, mut sigma) = (Vec::new(), Vec::new(), Vec::new());
    for (slot, group) in groups.iter().enumerate() {
        for (m, &member) in group.members.iter().enumerate() {
            // A member that cannot stand in for the first one beside the other groups
            // (singular together) is estimated alone.
            let (fit, at) = if m == 0 {
                (chosen.fit.clone(), slot)
            } else {
                let mut with = chosen.fit.effects.clone();
                with[slot] = member;
                match cx.fit.normals.fit(&with) {
                    Ok(f) => (cx.widened(f), slot),
                    Err(_) => (cx.widened(cx.fit.normals.fit(&[member])?), 0),
                }
            };
            effects.push(member);
            estimate.push(fit.estimate[at]);
            sigma.push(fit.sigma[at]);
        }
    }
    Ok(Named {
        effects,
        estimate,
        sigma,
    })
}

#[cfg(test)]
mod tests;
