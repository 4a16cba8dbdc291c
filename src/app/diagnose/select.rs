//! Which catalogue effect explains the gap: observability before solving (condition number,
//! variance inflation, pairwise correlations, inseparable groups), then candidates (each group
//! alone, every pair, greedy forward additions) fitted on the fit references and judged on the
//! held-out references, with likelihood-ratio significance under Holm control, and the verdict
//! `effect` | `none` | `unexplained` (docs/conventions.md §8; method: docs/diagnosis.md,
//! "Statistics").

use super::fit::{Fit, Normals, Split};
use super::metrics::{chi2_sf, holm_adjusted, normal_sf};
use super::model::{Effect, ObservationSet, Theta, N_EFFECTS};
use crate::Result;
use nalgebra::{DMatrix, SymmetricEigen};

/// Effects whose estimates correlate beyond this (in absolute value) when fitted together are
/// one inseparable group.
pub const GROUP_CORRELATION: f64 = 0.9;
/// Default family-wise error rate of the selection's tests.
pub const DEFAULT_ALPHA: f64 = 0.01;
/// Share of the held-out excess chi2 an explanation must remove to "close" a rejected gap
/// (unless what remains passes the chi2 test).
pub const CLOSES_SHARE: f64 = 0.5;
/// Most groups in one explanation.
const MAX_GROUPS: usize = 4;
/// Condition numbers and variance inflations above this are reported as infinite.
const SINGULAR: f64 = 1e12;

/// Which member of an inseparable group is named first: the more common cause in practice
/// first. Mounting angles move whenever a scanner is re-mounted; instrument zeros (encoder,
/// range) are calibration constants that age; a timing latency is often never measured; a
/// lever arm is taped to a centimetre; a heading offset needs a mis-aligned INS; a range
/// scale, a clock offset or drift, and a cone error are factory quantities that rarely change.
pub const PREFERENCE: [Effect; N_EFFECTS] = [
    Effect::BoresightX,
    Effect::BoresightY,
    Effect::BoresightZ,
    Effect::EncoderOffset,
    Effect::RangeZero,
    Effect::AttitudeLatency,
    Effect::LeverArmX,
    Effect::LeverArmY,
    Effect::LeverArmZ,
    Effect::HeadingOffset,
    Effect::RangeScale,
    Effect::PositionLatency,
    Effect::ClockOffset,
    Effect::ClockDrift,
    Effect::Cone,
];

fn preference_rank(e: Effect) -> usize {
    PREFERENCE
        .iter()
        .position(|&p| p == e)
        .expect("PREFERENCE lists every effect")
}

/// How an effect moves a point, for the hint of what would separate two of them.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Grows with the platform's motion (speed, rotation rates) or with time.
    Timing,
    /// An angle: grows with range.
    Angle,
    /// A fixed offset: independent of range.
    Offset,
    /// Proportional to range.
    Scale,
}

fn kind(e: Effect) -> Kind {
    match e {
        Effect::AttitudeLatency
        | Effect::PositionLatency
        | Effect::ClockOffset
        | Effect::ClockDrift => Kind::Timing,
        Effect::BoresightX
        | Effect::BoresightY
        | Effect::BoresightZ
        | Effect::EncoderOffset
        | Effect::Cone
        | Effect::HeadingOffset => Kind::Angle,
        Effect::LeverArmX | Effect::LeverArmY | Effect::LeverArmZ | Effect::RangeZero => {
            Kind::Offset
        }
        Effect::RangeScale => Kind::Scale,
    }
}

/// The data that would separate two effects of the given kinds.
fn separating_data(a: Kind, b: Kind) -> &'static str {
    use Kind::*;
    match (a, b) {
        (Timing, Timing) => "a turn at another speed and a longer survey (attitude latency follows the rotation rate, position latency and clock offset the speed, clock drift grows with time)",
        (Timing, _) | (_, Timing) => "a turn and a change of speed (timing errors grow with the motion, mounting errors do not)",
        (Angle, Angle) => "a pass in the opposite direction and returns on both scan sides",
        (Offset, Offset) => "a pass in the opposite direction and patches of other orientations and heights (walls and ground)",
        (Scale, Scale) => "targets at other ranges",
        (Angle, _) | (_, Angle) => "targets at other ranges (angular errors grow with range) and a pass in the opposite direction",
        (Offset, Scale) | (Scale, Offset) => "targets at other ranges (a scale error grows with range, an offset does not)",
    }
}

/// Effects the data cannot tell apart.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Members, the preferred ([`PREFERENCE`]) first; one member when the effect is separable.
    pub members: Vec<Effect>,
    /// Largest pairwise |correlation| inside the group (0 for one member).
    pub max_abs_correlation: f64,
    /// What data would separate the members (empty for one member).
    pub separating_data: Vec<&'static str>,
}

/// How well the effects can be estimated on a set of references, before any solving.
#[derive(Debug, Clone, PartialEq)]
pub struct Observability {
    /// The observable effects the other fields describe, in the order asked.
    pub effects: Vec<Effect>,
    /// Effects without any signature on these references.
    pub unobservable: Vec<Effect>,
    /// Condition number of the Jacobi-scaled normal matrix of all `effects` together
    /// (infinite above 1e12).
    pub condition_number: f64,
    /// Variance inflation of each effect in the joint fit of all `effects`:
    /// `(N^-1)_jj N_jj = 1 / (1 - R_j^2)` (infinite above 1e12).
    pub vif: Vec<f64>,
    /// Correlation of the estimates of each pair when the two are fitted together (diagonal 1).
    pub correlation: DMatrix<f64>,
    /// Inseparable groups (|correlation| > [`GROUP_CORRELATION`], linked transitively),
    /// ordered by their preferred member.
    pub groups: Vec<Group>,
}

/// The observability of `effects` on `refs`.
pub fn observability(
    set: &ObservationSet,
    refs: &[usize],
    effects: &[Effect],
) -> Result<Observability> {
    Ok(observability_of(&Normals::of(set, refs)?, effects))
}

pub(crate) fn observability_of(normals: &Normals, effects: &[Effect]) -> Observability {
    let col = |e: Effect| super::model::signature_index(e);
    let (observable, unobservable): (Vec<Effect>, Vec<Effect>) = effects
        .iter()
        .partition(|&&e| normals.m[(col(e), col(e))] > 0.0);
    let k = observable.len();
    let scaled = DMatrix::from_fn(k, k, |i, j| {
        let (a, b) = (col(observable[i]), col(observable[j]));
        normals.m[(a, b)] / (normals.m[(a, a)] * normals.m[(b, b)]).sqrt()
    });
    let correlation = DMatrix::from_fn(k, k, |i, j| if i == j { 1.0 } else { -scaled[(i, j)] });
    let (condition_number, vif) = inflation(&scaled);
    let groups = group(&observable, &correlation);
    Observability {
        effects: observable,
        unobservable,
        condition_number,
        vif,
        correlation,
        groups,
    }
}

/// Condition number and variance inflations of a correlation-scaled normal matrix.
fn inflation(scaled: &DMatrix<f64>) -> (f64, Vec<f64>) {
    let k = scaled.nrows();
    if k == 0 {
        return (1.0, Vec::new());
    }
    let eig = SymmetricEigen::new(scaled.clone());
    let max = eig.eigenvalues.max();
    let min = eig.eigenvalues.min();
    let capped = |x: f64| {
        if x.is_finite() && x < SINGULAR {
            x
        } else {
            f64::INFINITY
        }
    };
    let condition = if min > 0.0 {
        capped(max / min)
    } else {
        f64::INFINITY
    };
    let floor = max / SINGULAR;
    let vif = (0..k)
        .map(|j| {
            capped(
                (0..k)
                    .map(|m| {
                        eig.eigenvectors[(j, m)].powi(2) / eig.eigenvalues[m].max(floor * 1e-3)
                    })
                    .sum(),
            )
        })
        .collect();
    (condition, vif)
}

/// Single-linkage groups of |correlation| > [`GROUP_CORRELATION`].
fn group(effects: &[Effect], correlation: &DMatrix<f64>) -> Vec<Group> {
    let k = effects.len();
    let mut label: Vec<usize> = (0..k).collect();
    for i in 0..k {
        for j in i + 1..k {
            if correlation[(i, j)].abs() > GROUP_CORRELATION {
                let (from, to) = (label[j], label[i]);
                label
                    .iter_mut()
                    .filter(|l| **l == from)
                    .for_each(|l| *l = to);
            }
        }
    }
    let mut groups: Vec<Group> = Vec::new();
    for l in 0..k {
        let mut idx: Vec<usize> = (0..k).filter(|&i| label[i] == l).collect();
        if idx.is_empty() {
            continue;
        }
        idx.sort_by_key(|&i| preference_rank(effects[i]));
        let mut max_abs_correlation: f64 = 0.0;
        let mut separating: Vec<&'static str> = Vec::new();
        for (a, &i) in idx.iter().enumerate() {
            for &j in &idx[a + 1..] {
                max_abs_correlation = max_abs_correlation.max(correlation[(i, j)].abs());
                let hint = separating_data(kind(effects[i]), kind(effects[j]));
                if correlation[(i, j)].abs() > GROUP_CORRELATION && !separating.contains(&hint) {
                    separating.push(hint);
                }
            }
        }
        groups.push(Group {
            members: idx.iter().map(|&i| effects[i]).collect(),
            max_abs_correlation,
            separating_data: separating,
        });
    }
    groups.sort_by_key(|g| preference_rank(g.members[0]));
    groups
}

/// `effect`, `none` or `unexplained` (docs/conventions.md §8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Catalogue effect(s) significant on the fit references, confirmed on the held-out
    /// references, and (when the model without them is rejected) closing the held-out gap:
    /// removing at least [`CLOSES_SHARE`] of its excess chi2, or leaving a chi2 the test
    /// accepts.
    Effect,
    /// The model holds on the held-out references and no effect is significant.
    None,
    /// The model is rejected on the held-out references and no catalogue combination closes
    /// the gap: no effect is named.
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
    /// GLS fit of the groups' preferred members on the fit references.
    pub fit: Fit,
    /// Likelihood-ratio p-value on the fit references: against no effect for a single group;
    /// for a pair, the largest of that and each member's test given the other (both needed);
    /// for a greedy addition, the added group given the rest.
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
    /// `P(chi2_n > chi2)`.
    pub p_value: f64,
    /// `p_value < alpha`.
    pub rejected: bool,
}

impl NullTest {
    fn new(chi2: f64, n: usize, alpha: f64) -> Self {
        let p_value = chi2_sf(chi2, n);
        NullTest {
            chi2,
            n,
            p_value,
            rejected: p_value < alpha,
        }
    }
}

/// The result of [`select`].
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The verdict.
    pub verdict: Verdict,
    /// Named effects (verdict `effect`): every member of each chosen group, the preferred first.
    pub effects: Vec<Effect>,
    /// Estimate of each named effect (fit references), in the unit of its name: a
    /// non-preferred member's estimate is from the same explanation with it in place of the
    /// preferred member.
    pub estimate: Vec<f64>,
    /// 1-sigma of each estimate.
    pub sigma: Vec<f64>,
    /// The explanation to re-process with (the chosen groups' preferred members, fitted on the
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

/// The fit and held-out statistics, the groups, and the model every candidate extends.
struct Context<'a> {
    fit: &'a Normals,
    held: &'a Normals,
    groups: &'a [Group],
}

impl Context<'_> {
    fn effects(&self, groups: &[usize]) -> Vec<Effect> {
        groups.iter().map(|&g| self.groups[g].members[0]).collect()
    }

    /// Fits `groups` on the fit references and judges them on the held-out ones against
    /// `base` (the explanation they extend: `None` = no effect). `None` when inseparable.
    fn candidate(&self, groups: Vec<usize>, base: Option<&Fit>, p_value: f64) -> Option<Candidate> {
        let fit = self.fit.fit(&self.effects(&groups)).ok()?;
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
            groups,
            fit,
            p_value,
            p_holm: 1.0,
            significant: false,
            chi2_held_out,
            held_out_reduction,
            held_out_p_value,
        })
    }

    /// Likelihood-ratio p-value of `larger` against `smaller` on the fit references.
    fn lr(&self, larger: &Fit, smaller_chi2: f64) -> f64 {
        let dof = larger.effects.len();
        chi2_sf(smaller_chi2 - larger.chi2, dof)
    }
}

/// Marks the Holm-significant candidates; returns the index of the best supported one
/// (largest held-out reduction).
fn judge(candidates: &mut [Candidate], alpha: f64) -> Option<usize> {
    let p: Vec<f64> = candidates.iter().map(|c| c.p_value).collect();
    for (c, q) in candidates.iter_mut().zip(holm_adjusted(&p)) {
        c.p_holm = q;
        c.significant = q <= alpha;
    }
    (0..candidates.len())
        .filter(|&i| candidates[i].significant && candidates[i].supported(alpha))
        .max_by(|&a, &b| {
            candidates[a]
                .held_out_reduction
                .total_cmp(&candidates[b].held_out_reduction)
        })
}

/// Each group alone and every pair (the pair's p-value requires both members).
fn first_step(cx: &Context) -> Vec<Candidate> {
    let null_chi2 = cx.fit.chi2_null();
    let singles: Vec<Option<Candidate>> = (0..cx.groups.len())
        .map(|g| {
            let c = cx.candidate(vec![g], None, 1.0)?;
            let p = chi2_sf(null_chi2 - c.fit.chi2, 1);
            Some(Candidate { p_value: p, ..c })
        })
        .collect();
    let mut out: Vec<Candidate> = Vec::new();
    for a in 0..cx.groups.len() {
        for b in a + 1..cx.groups.len() {
            let (Some(sa), Some(sb)) = (&singles[a], &singles[b]) else {
                continue;
            };
            let Some(c) = cx.candidate(vec![a, b], None, 1.0) else {
                continue;
            };
            let p = [
                cx.lr(&c.fit, null_chi2),
                chi2_sf(sa.fit.chi2 - c.fit.chi2, 1),
                chi2_sf(sb.fit.chi2 - c.fit.chi2, 1),
            ]
            .into_iter()
            .fold(0.0, f64::max);
            out.push(Candidate { p_value: p, ..c });
        }
    }
    singles.into_iter().flatten().chain(out).collect()
}

/// Greedy forward additions to `current`, one group at a time.
fn extend(
    cx: &Context,
    mut current: Candidate,
    alpha: f64,
    tried: &mut Vec<Candidate>,
) -> Candidate {
    while current.groups.len() < MAX_GROUPS {
        let mut step: Vec<Candidate> = (0..cx.groups.len())
            .filter(|g| !current.groups.contains(g))
            .filter_map(|g| {
                let mut groups = current.groups.clone();
                groups.push(g);
                let c = cx.candidate(groups, Some(&current.fit), 1.0)?;
                let p = chi2_sf(current.fit.chi2 - c.fit.chi2, 1);
                Some(Candidate { p_value: p, ..c })
            })
            .collect();
        let best = judge(&mut step, alpha);
        let next = best.map(|i| step[i].clone());
        tried.append(&mut step);
        match next {
            Some(n) => current = n,
            None => break,
        }
    }
    current
}

/// Selects the explanation of the gap: fits on `split.fit`, judges on `split.held_out`, tests
/// at family-wise error rate `alpha` ([`DEFAULT_ALPHA`] by default).
pub fn select(set: &ObservationSet, split: &Split, alpha: f64) -> Result<Selection> {
    let fit_n = Normals::of(set, &split.fit)?;
    let held = Normals::of(set, &split.held_out)?;
    let observability = observability_of(&fit_n, &Effect::ALL);
    let null_chi2 = held.chi2_null();
    let null = NullTest::new(null_chi2, held.n, alpha);
    let cx = Context {
        fit: &fit_n,
        held: &held,
        groups: &observability.groups,
    };
    let mut candidates = first_step(&cx);
    let best = judge(&mut candidates, alpha).map(|i| candidates[i].clone());
    let chosen = best.map(|b| extend(&cx, b, alpha, &mut candidates));
    candidates.sort_by(|a, b| b.held_out_reduction.total_cmp(&a.held_out_reduction));

    let excess = null_chi2 - held.n as f64;
    let closure = match &chosen {
        Some(c) if excess > 0.0 => Some((null_chi2 - c.chi2_held_out) / excess),
        _ => None,
    };
    let remaining = chosen
        .as_ref()
        .map(|c| NullTest::new(c.chi2_held_out, held.n, alpha));
    let closes =
        closure.is_some_and(|c| c >= CLOSES_SHARE) || remaining.is_some_and(|r| !r.rejected);
    let verdict = match (&chosen, null.rejected) {
        (Some(_), false) => Verdict::Effect,
        (Some(_), true) if closes => Verdict::Effect,
        (_, true) => Verdict::Unexplained,
        (None, false) => Verdict::None,
    };
    let (effects, estimate, sigma) = match (&chosen, verdict) {
        (Some(c), Verdict::Effect) => named(&cx, c)?,
        _ => (Vec::new(), Vec::new(), Vec::new()),
    };
    Ok(Selection {
        verdict,
        effects,
        estimate,
        sigma,
        chosen: chosen.map(|c| c.fit),
        closure,
        null,
        remaining,
        observability,
        candidates,
        alpha,
    })
}

/// Every member of the chosen groups with its estimate and sigma (a non-preferred member
/// fitted in place of the preferred one, or alone when that is singular).
fn named(cx: &Context, chosen: &Candidate) -> Result<(Vec<Effect>, Vec<f64>, Vec<f64>)> {
    let (mut effects, mut estimate, mut sigma) = (Vec::new(), Vec::new(), Vec::new());
    for (slot, &g) in chosen.groups.iter().enumerate() {
        for (m, &member) in cx.groups[g].members.iter().enumerate() {
            // A member that cannot stand in for the preferred one beside the other groups
            // (singular together) is estimated alone.
            let (fit, at) = if m == 0 {
                (chosen.fit.clone(), slot)
            } else {
                let mut with = chosen.fit.effects.clone();
                with[slot] = member;
                match cx.fit.fit(&with) {
                    Ok(f) => (f, slot),
                    Err(_) => (cx.fit.fit(&[member])?, 0),
                }
            };
            effects.push(member);
            estimate.push(fit.estimate[at]);
            sigma.push(fit.sigma[at]);
        }
    }
    Ok((effects, estimate, sigma))
}

#[cfg(test)]
mod tests {
    use super::super::fit::{fit, split};
    use super::super::locate::{locate, model_free, DEFAULT_BINS};
    use super::super::metrics::gap;
    use super::super::model::synthetic::{draw, fill_residuals, Scenario};
    use super::super::model::{signature_index, Covariate};
    use super::*;

    /// The size of `effect` that moves points by `rms_m` on `set` (root mean square).
    fn size_for(set: &ObservationSet, effect: Effect, rms_m: f64) -> f64 {
        let c = signature_index(effect);
        let ms = set
            .observations
            .iter()
            .map(|o| o.signature[c].powi(2))
            .sum::<f64>()
            / set.observations.len() as f64;
        rms_m / ms.sqrt()
    }

    fn mean_std(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var.sqrt())
    }

    #[test]
    fn no_effect_gives_none_and_chi2_per_dof_near_one() {
        let seeds = 100;
        let (mut none, mut chi2) = (0, Vec::new());
        for seed in 0..seeds {
            let set = draw(&Scenario::default(), seed);
            let sp = split(&set, seed).unwrap();
            let sel = select(&set, &sp, DEFAULT_ALPHA).unwrap();
            none += usize::from(sel.verdict == Verdict::None);
            chi2.push(gap(&set, &sp.held_out, None).unwrap().chi2_per_dof);
        }
        let (mean, _) = mean_std(&chi2);
        println!("theta = 0: verdict none in {none}/{seeds}; mean held-out chi2/dof {mean:.4}");
        assert!(none * 100 >= 95 * seeds as usize, "none in {none}/{seeds}");
        // 1440 held-out returns: sd of chi2/dof sqrt(2/1440) = 0.037 per seed, 0.0037 over
        // 100 seeds: 4 sd.
        assert!((mean - 1.0).abs() < 0.015, "{mean}");
    }

    #[test]
    fn one_injected_effect_is_named_first_with_honest_sigma() {
        let seeds = 90;
        let (mut first, mut normalised) = (0, Vec::new());
        for seed in 0..seeds {
            let effect = Effect::ALL[seed as usize % N_EFFECTS];
            let mut set = draw(&Scenario::default(), seed);
            let truth = size_for(&set, effect, 0.02);
            let s = Scenario {
                truth: vec![(effect, truth)],
                ..Default::default()
            };
            fill_residuals(&mut set, &s, seed + 1000);
            let sel = select(&set, &split(&set, seed).unwrap(), DEFAULT_ALPHA).unwrap();
            let first_group = sel
                .observability
                .groups
                .iter()
                .find(|g| sel.effects.first() == Some(&g.members[0]));
            if sel.verdict == Verdict::Effect
                && first_group.is_some_and(|g| g.members.contains(&effect))
            {
                first += 1;
            }
            if let Some(i) = sel.effects.iter().position(|&e| e == effect) {
                normalised.push((sel.estimate[i] - truth) / sel.sigma[i]);
            }
        }
        let (mean, std) = mean_std(&normalised);
        println!("one effect: named first {first}/{seeds}; normalised errors ({}) mean {mean:.3} std {std:.3}", normalised.len());
        assert!(
            first * 100 >= 95 * seeds as usize,
            "named first in {first}/{seeds}"
        );
        // 90 draws: the sample sd has sd 1/sqrt(180) = 0.075; the mean has sd 0.105.
        assert!((0.8..=1.25).contains(&std), "std {std}");
        assert!(mean.abs() < 0.32, "mean {mean}");
    }

    #[test]
    fn an_effect_without_signature_is_unobservable_and_never_named() {
        let mut set = draw(
            &Scenario {
                range_cyclic_m: 0.02,
                ..Default::default()
            },
            8,
        );
        for o in &mut set.observations {
            o.signature = [0.0; N_EFFECTS];
        }
        let sel = select(&set, &split(&set, 8).unwrap(), DEFAULT_ALPHA).unwrap();
        assert_eq!(sel.observability.unobservable, Effect::ALL.to_vec());
        assert!(sel.observability.groups.is_empty() && sel.candidates.is_empty());
        assert_eq!(sel.verdict, Verdict::Unexplained);
        assert!(sel.effects.is_empty());
    }

    /// Normalised errors of `effect` (cycling over the catalogue) over `seeds` draws with
    /// navigation errors that are Gauss-Markov processes in time (within and across visits).
    fn correlated_errors(seeds: u64) -> Vec<f64> {
        let tau = Some([60.0, 30.0]);
        let mut out = Vec::new();
        for seed in 0..seeds {
            let effect = Effect::ALL[seed as usize % N_EFFECTS];
            let base = Scenario {
                nav_tau_s: tau,
                ..Default::default()
            };
            let mut set = draw(&base, seed);
            let truth = size_for(&set, effect, 0.02);
            let s = Scenario {
                truth: vec![(effect, truth)],
                ..base
            };
            fill_residuals(&mut set, &s, seed + 3000);
            let f = fit(&set, &split(&set, seed).unwrap().fit, &[effect]).unwrap();
            out.push((f.estimate[0] - truth) / f.sigma[0]);
        }
        out
    }

    #[test]
    fn correlated_navigation_errors_keep_sigmas_honest() {
        let (mean, std) = mean_std(&correlated_errors(120));
        println!("nav errors Gauss-Markov in time (tau 60/30 s): normalised errors mean {mean:.3} std {std:.3}");
        // 120 draws: the sample sd has sd 1/sqrt(240) = 0.065; the mean 0.09 (3 sd: 0.28).
        assert!((0.8..=1.25).contains(&std), "std {std}");
        assert!(mean.abs() < 0.28, "mean {mean}");
    }

    #[test]
    fn gls_sigma_is_the_cramer_rao_bound() {
        let base = draw(&Scenario::default(), 77);
        let effect = Effect::BoresightX;
        let truth = size_for(&base, effect, 0.02);
        let s = Scenario {
            truth: vec![(effect, truth)],
            ..Default::default()
        };
        let refs = base.observed_references();
        let (mut estimates, mut sigma) = (Vec::new(), 0.0);
        for seed in 0..200 {
            let mut set = base.clone();
            fill_residuals(&mut set, &s, seed);
            let f = fit(&set, &refs, &[effect]).unwrap();
            estimates.push(f.estimate[0]);
            sigma = f.sigma[0];
        }
        let (mean, std) = mean_std(&estimates);
        println!(
            "CRB: empirical std / GLS sigma = {:.3} (200 draws), bias/sigma {:.3}",
            std / sigma,
            (mean - truth) / sigma
        );
        // 200 draws: the sample sd has relative sd 1/sqrt(400) = 0.05: 3 sd.
        assert!((std / sigma - 1.0).abs() < 0.15, "{} vs {sigma}", std);
        assert!(((mean - truth) / sigma).abs() < 3.0 / 200f64.sqrt());
    }

    #[test]
    fn correlated_effects_form_one_group_named_together() {
        let pair = (Effect::BoresightX, Effect::EncoderOffset);
        let plain = draw(&Scenario::default(), 5);
        let obs = observability(&plain, &plain.observed_references(), &Effect::ALL).unwrap();
        assert!(
            obs.groups.iter().all(|g| g.members.len() == 1),
            "{:?}",
            obs.groups
        );
        let mut named = 0;
        for seed in 0..10 {
            let mut set = draw(
                &Scenario {
                    twin: Some(pair),
                    ..Default::default()
                },
                seed,
            );
            let refs = set.observed_references();
            let obs = observability(&set, &refs, &Effect::ALL).unwrap();
            let g = obs
                .groups
                .iter()
                .find(|g| g.members.contains(&pair.0))
                .unwrap();
            assert_eq!(g.members, vec![pair.0, pair.1], "preferred first");
            assert!(g.max_abs_correlation > 0.9 && !g.separating_data.is_empty());
            assert!(obs.vif[obs.effects.iter().position(|&e| e == pair.1).unwrap()] > 5.0);
            let truth = size_for(&set, pair.1, 0.02);
            fill_residuals(
                &mut set,
                &Scenario {
                    twin: Some(pair),
                    truth: vec![(pair.1, truth)],
                    ..Default::default()
                },
                seed + 50,
            );
            let sel = select(&set, &split(&set, seed).unwrap(), DEFAULT_ALPHA).unwrap();
            if sel.verdict == Verdict::Effect && sel.effects[..2] == [pair.0, pair.1] {
                named += 1;
                assert_eq!(sel.estimate.len(), sel.effects.len());
            }
        }
        assert!(named >= 9, "group named in {named}/10");
    }

    #[test]
    fn out_of_model_signal_is_unexplained_located_and_closed_model_free() {
        let seeds = 20usize;
        let (mut unexplained, mut located, mut closed) = (0, 0, 0);
        let mut closures = Vec::new();
        for seed in 0..seeds {
            let set = draw(
                &Scenario {
                    range_cyclic_m: 0.02,
                    ..Default::default()
                },
                seed as u64,
            );
            let sp = split(&set, seed as u64).unwrap();
            let sel = select(&set, &sp, DEFAULT_ALPHA).unwrap();
            unexplained +=
                usize::from(sel.verdict == Verdict::Unexplained && sel.effects.is_empty());
            let tests = locate(&set, &sp.fit, None, DEFAULT_BINS).unwrap();
            located += usize::from(tests[0].covariate == Covariate::RangeM);
            let c = model_free(&set, &sp, tests[0].covariate, None, DEFAULT_BINS).unwrap();
            let closure = c.closure.unwrap_or(0.0);
            closures.push(closure);
            closed += usize::from(closure >= 0.5);
        }
        let (mean, _) = mean_std(&closures);
        println!("out of model: unexplained {unexplained}/{seeds}, located in range_m {located}/{seeds}, closed >= 50% {closed}/{seeds} (mean closure {mean:.2})");
        assert!(
            unexplained * 100 >= 95 * seeds,
            "unexplained {unexplained}/{seeds}"
        );
        assert!(located * 100 >= 95 * seeds, "located {located}/{seeds}");
        assert!(closed * 100 >= 95 * seeds, "closed {closed}/{seeds}");
    }
}
