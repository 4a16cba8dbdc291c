//! The selection's statistical tests on observations drawn from the model itself.
use super::*;
use crate::app::diagnose::locate::{locate, model_free, DEFAULT_BINS};
use crate::app::diagnose::model::fit::{fit, split};
use crate::app::diagnose::model::metrics::gap;
use crate::app::diagnose::model::synthetic::{draw, fill_residuals, Scenario};
use crate::app::diagnose::model::{signature_index, Covariate, N_EFFECTS};
use crate::app::diagnose::select::observability::observability;

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

/// The selection on `set` split by `seed`, the navigation model known (no other models, no
/// nodes).
fn select_on_own_split(set: &ObservationSet, seed: u64) -> Selection {
    select(
        set,
        &split(set, seed).unwrap(),
        DEFAULT_ALPHA,
        0.0,
        (&[], &[]),
    )
    .unwrap()
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
        let sel = select(&set, &sp, DEFAULT_ALPHA, 0.0, (&[], &[])).unwrap();
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
fn a_non_finite_null_statistic_is_an_error_not_none() {
    let set = draw(&Scenario::default(), 1);
    let sp = split(&set, 1).unwrap();
    let err = select(&set, &sp, DEFAULT_ALPHA, f64::NAN, (&[], &[])).unwrap_err();
    let text = err.to_string();
    assert!(
        text.starts_with("held-out gap without any effect"),
        "{text}"
    );
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
        let sel = select_on_own_split(&set, seed);
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
    let sel = select_on_own_split(&set, 8);
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
    let (mut named, mut preferred_first) = (0, 0);
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
        // Either member the cause: the group is named, its members first in either order
        // (the held-out references may support the twin better than the preferred member);
        // the preferred member the cause, it is the one corrected.
        for (cause, other) in [(pair.1, pair.0), (pair.0, pair.1)] {
            let truth = size_for(&set, cause, 0.02);
            fill_residuals(
                &mut set,
                &Scenario {
                    twin: Some(pair),
                    truth: vec![(cause, truth)],
                    ..Default::default()
                },
                seed + 50,
            );
            let sel = select_on_own_split(&set, seed);
            let first_two = sel.effects.get(..2);
            if sel.verdict == Verdict::Effect
                && (first_two == Some(&[cause, other][..])
                    || first_two == Some(&[other, cause][..]))
            {
                named += 1;
                preferred_first += usize::from(cause == pair.0 && sel.effects[0] == pair.0);
                assert_eq!(sel.estimate.len(), sel.effects.len());
            }
        }
    }
    assert!(named >= 18, "group named in {named}/20");
    assert!(
        preferred_first >= 9,
        "the preferred cause corrected in {preferred_first}/10"
    );
}

/// A group's other member, which the fit references cannot tell from the preferred one and
/// the held-out references can, is named first, estimated and corrected: the held-out
/// references judge each member's fit ([`Context::candidate`]). Judged as the preferred
/// member alone, whose fitted correction the held-out references reject, such an effect was
/// never named at any size (a range scale beside the range zero on a 15-minute survey,
/// docs/diagnosis.md, *Selection and verdict*, 3). Where the held-out references cannot
/// tell the members apart either, the preferred member stays first
/// (`correlated_effects_form_one_group_named_together`).
#[test]
fn a_group_member_the_held_out_references_separate_is_named_first() {
    let pair = (Effect::BoresightX, Effect::EncoderOffset);
    let seeds = 20;
    let (mut first, mut z) = (0, Vec::new());
    for seed in 0..seeds {
        let mut set = draw(
            &Scenario {
                twin: Some(pair),
                ..Default::default()
            },
            seed,
        );
        let sp = split(&set, seed).unwrap();
        // On the held-out references the twin changes sign with the scan side.
        for o in set.observations.iter_mut() {
            if sp.held_out.contains(&o.reference) && o.covariates.beta_deg < 0.0 {
                o.signature[signature_index(pair.1)] *= -1.0;
            }
        }
        let fit_n = Normals::of(&set, &sp.fit).unwrap();
        let grouped = observability_of(&fit_n, &Effect::ALL)
            .groups
            .iter()
            .any(|g| g.members == vec![pair.0, pair.1]);
        assert!(
            grouped,
            "seed {seed}: the fit references do not group the pair"
        );
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
        let sel = select(&set, &sp, DEFAULT_ALPHA, 0.0, (&[], &[])).unwrap();
        if sel.verdict == Verdict::Effect && sel.effects.first() == Some(&pair.1) {
            first += 1;
            z.push((sel.estimate[0] - truth) / sel.sigma[0]);
            assert_eq!(sel.chosen.as_ref().unwrap().effects[0], pair.1);
        }
    }
    let (mean, sd) = mean_std(&z);
    println!("named first in {first}/{seeds}; normalised error mean {mean:.2}, sd {sd:.2}");
    assert!(first >= 18, "named first in {first}/{seeds}");
    // 18 or more draws of N(0, 1): the mean within 3 / sqrt(18) = 0.71, the sd within 0.5-1.6.
    assert!(mean.abs() < 0.71 && (0.5..1.6).contains(&sd), "{mean} {sd}");
}

/// A small effect seen through a correlated one (|correlation| about 0.8 on these
/// references, under the groups' 0.9) is named with it, never in its stead: the chosen effect,
/// added with the truth in its place, is not significant, so the truth is its rival
/// ([`named_groups`]). The truth is injected at 3 sigma of its own fit: on some seeds the
/// chosen explanation alone is the other effect (the case guarded, counted so that the test
/// can tell); the truth is always among the named effects. (The other effect named beside
/// the truth as a significant second effect, not as a rival, is a false positive at the test
/// level, which `alpha` bounds: 1 of 400 seeds here.)
#[test]
fn a_small_effect_seen_through_a_correlated_one_is_named_with_it() {
    let pair = (Effect::BoresightX, Effect::EncoderOffset);
    let scenario = Scenario {
        twin: Some(pair),
        twin_own: 0.9,
        ..Default::default()
    };
    let seeds = 400;
    let (mut named, mut chosen_other, mut replaced) = (0, 0, 0);
    let mut correlations = Vec::new();
    for seed in 0..seeds {
        let mut set = draw(&scenario, seed);
        let sp = split(&set, seed).unwrap();
        let fit_n = Normals::of(&set, &sp.fit).unwrap();
        let obs = observability_of(&fit_n, &Effect::ALL);
        let at = |e: Effect| obs.effects.iter().position(|&f| f == e).unwrap();
        correlations.push(obs.correlation[(at(pair.0), at(pair.1))].abs());
        let sigma = fit_n.fit(&[pair.1]).unwrap().sigma[0];
        let truth = Scenario {
            truth: vec![(pair.1, 3.0 * sigma)],
            ..scenario.clone()
        };
        fill_residuals(&mut set, &truth, seed + 500);
        let sel = select(&set, &sp, DEFAULT_ALPHA, 0.0, (&[], &[])).unwrap();
        if sel.verdict != Verdict::Effect {
            continue;
        }
        named += 1;
        let chosen = &sel.chosen.as_ref().unwrap().effects;
        let truth_first = obs
            .groups
            .iter()
            .find(|g| g.members.contains(&pair.1))
            .unwrap()
            .members[0];
        chosen_other += usize::from(!chosen.contains(&truth_first));
        replaced += usize::from(!sel.effects.contains(&pair.1));
    }
    let (corr, _) = mean_std(&correlations);
    println!(
        "truth at 3 sigma, |correlation| {corr:.2}: named in {named}/{seeds}, the chosen \
         explanation another than the truth in {chosen_other}, the truth not named in \
         {replaced}"
    );
    assert!((0.7..0.9).contains(&corr), "|correlation| {corr}");
    assert!(chosen_other > 0, "the guarded case did not occur");
    assert_eq!(replaced, 0);
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
        let sel = select(&set, &sp, DEFAULT_ALPHA, 0.0, (&[], &[])).unwrap();
        unexplained += usize::from(sel.verdict == Verdict::Unexplained && sel.effects.is_empty());
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

/// The tie rule of [`judge`] on its own: of two significant candidates whose held-out
/// reductions differ by less than [`TIE_SD`] sd of the difference, the one with the smaller
/// fit chi2 plus 2 per effect is chosen; by more, the larger reduction; a candidate that is
/// not significant on the fit references, or not supported on the held-out ones, is never
/// chosen, however good its fit.
#[test]
fn held_out_ties_are_broken_by_the_fit_references() {
    let set = draw(&Scenario::default(), 3);
    let sp = split(&set, 3).unwrap();
    let fit_n = Normals::of(&set, &sp.fit).unwrap();
    let held = Normals::of(&set, &sp.held_out).unwrap();
    let groups = observability_of(&fit_n, &Effect::ALL).groups;
    let covariances = Covariances::default();
    let cx = Context::new((&fit_n, &covariances), [], &held, &groups);
    let (a, b) = (Effect::AttitudeLatency, Effect::ClockDrift);
    let (size_a, size_b) = (size_for(&set, a, 0.005), size_for(&set, b, 0.005));
    let candidate = |effect: Effect, size: f64, fit_chi2: f64, reduction: f64| Candidate {
        groups: Vec::new(),
        fit: Fit {
            effects: vec![effect],
            estimate: vec![size],
            sigma: vec![size / 20.0],
            cov: DMatrix::from_element(1, 1, (size / 20.0).powi(2)),
            chi2: fit_chi2,
            dof: 1000,
        },
        p_value: 1e-9,
        p_holm: 1.0,
        significant: false,
        chi2_held_out: 0.0,
        held_out_reduction: reduction,
        held_out_p_value: 1e-6,
    };
    // The sd of the difference of the two reductions (2 sqrt(d^T C^-1 d)).
    let sd = 2.0 * held.quadratic(&[a, b], &[size_a, -size_b]).sqrt();
    assert!(
        sd > 1.0,
        "the two corrections differ on the held-out references: sd {sd}"
    );
    // `b` behind `a`'s held-out reduction by `behind` sd, its fit chi2 smaller by
    // `fit_better`, its held-out and fit p-values: the effect chosen.
    let judged = |a_sd: f64, behind: f64, fit_better: f64, held_out_p: f64, fit_p: f64| {
        let mut pair = [
            candidate(a, size_a, 1000.0, a_sd * sd),
            candidate(b, size_b, 1000.0 - fit_better, (a_sd - behind) * sd),
        ];
        (pair[1].held_out_p_value, pair[1].p_value) = (held_out_p, fit_p);
        let chosen = judge(&cx, &mut pair, DEFAULT_ALPHA).expect("a is significant, supported");
        pair[chosen].fit.effects[0]
    };
    // Tied on the held-out references: the fit chooses.
    assert_eq!(judged(10.0, 0.5, 10.0, 1e-6, 1e-9), b);
    assert_eq!(judged(10.0, 0.5, -10.0, 1e-6, 1e-9), a);
    // Tied, without held-out support of its own (p 0.02 > alpha): never chosen.
    assert_eq!(judged(10.0, 0.5, 10.0, 0.02, 1e-9), a);
    // Told apart by the held-out references: the larger reduction, whatever the fit.
    assert_eq!(judged(10.0, 1.5, 10.0, 1e-6, 1e-9), a);
    // Not significant on the fit references, or reducing the held-out chi2 by less than
    // nothing: never chosen.
    assert_eq!(judged(10.0, 0.0, 10.0, 1e-6, 0.5), a);
    assert_eq!(judged(0.5, 0.7, 10.0, 1e-6, 1e-9), a);
}

/// A set of `scenario` drawn with `seed` in which `effect` moves a return as a roll error of
/// the navigation does (a constant attitude error is a mounting angle), present at 1 cm rms
/// (residuals drawn with `seed + 1000`); with the effect's size.
fn mounting_angle_as_roll(scenario: &Scenario, seed: u64, effect: Effect) -> (ObservationSet, f64) {
    let mut set = draw(scenario, seed);
    for o in &mut set.observations {
        // m per degree from m per radian.
        o.signature[signature_index(effect)] = o.nav_gradient[3] * std::f64::consts::PI / 180.0;
    }
    let truth = size_for(&set, effect, 0.01);
    let with = Scenario {
        truth: vec![(effect, truth)],
        ..scenario.clone()
    };
    fill_residuals(&mut set, &with, seed + 1000);
    (set, truth)
}

/// The estimate of `effect` fitted alone by the selection under `models`, and its normalised
/// error against `truth`.
fn fitted_alone(
    set: &ObservationSet,
    sp: &Split,
    models: (&[OtherModel], &[Node]),
    (effect, truth): (Effect, f64),
) -> (f64, f64) {
    let sel = select(set, sp, DEFAULT_ALPHA, 0.0, models).unwrap();
    let c = sel
        .candidates
        .iter()
        .find(|c| c.fit.effects == [effect])
        .expect("fitted alone");
    let x = c.fit.estimate[0];
    (x, (x - truth) / c.fit.sigma[0])
}

/// A slow navigation error that the estimate's model leaves out (drawn: 5 s and 600 / 300 s
/// processes, half the variance each; the set declares the 5 s process alone at the whole
/// variance), and a mounting angle whose signature is the navigation's roll gradient: its
/// estimate carries the slow error's mean over the span, which
/// the estimate's sigma does not hold. With the model that has the slow process among the
/// others, widening the sigmas, the normalised errors have sd near 1; the estimates are the
/// same.
#[test]
fn a_slow_process_the_model_leaves_out_widens_the_sigmas() {
    use crate::app::diagnose::model::SlowNav;
    let scenario = Scenario {
        references: 80,
        passes: 4,
        nav_tau_s: Some([5.0, 5.0]),
        nav_scale: [0.5f64.sqrt(); 2],
        nav_slow: Some(SlowNav {
            share: [0.5, 0.5],
            tau_s: [600.0, 300.0],
        }),
        ..Default::default()
    };
    let effect = Effect::BoresightX;
    let (mut alone, mut widened) = (Vec::new(), Vec::new());
    for seed in 0..40 {
        let (set, truth) = mounting_angle_as_roll(&scenario, 700 + seed, effect);
        let sp = split(&set, seed).unwrap();
        // The drawn process: the fast part at half the declared variance, the slow beside it
        // (its share relative to the halved variances).
        let mut slow_set = set.clone();
        for v in &mut slow_set.visits {
            v.nav_cov.iter_mut().flatten().for_each(|c| *c *= 0.5);
        }
        slow_set.nav_slow = Some(SlowNav {
            share: [1.0, 1.0],
            tau_s: [600.0, 300.0],
        });
        let slow = OtherModel {
            normals: Normals::of(&slow_set, &sp.fit).unwrap(),
            widens_sigma: true,
        };
        let z = |others: &[OtherModel]| fitted_alone(&set, &sp, (others, &[]), (effect, truth));
        let (a, w) = (z(&[]), z(std::slice::from_ref(&slow)));
        assert_eq!(a.0, w.0, "the estimate is the estimate model's");
        alone.push(a.1);
        widened.push(w.1);
    }
    let (sd_alone, sd_widened) = (mean_std(&alone).1, mean_std(&widened).1);
    println!("normalised errors' sd: {sd_alone:.2} alone, {sd_widened:.2} widened");
    // 40 draws: the sd of a unit sample's sd is about 0.11.
    assert!(sd_alone > 2.0, "{sd_alone}");
    assert!((0.7..1.35).contains(&sd_widened), "{sd_widened}");
}

/// The attitude scale drawn over the range real SMRMSG sigmas are off by (true / stated
/// 0.6-1.6), an attitude error slow against the survey (300 s over 600 s), and a mounting
/// angle whose signature is the navigation's roll gradient (its error is the attitude
/// error's mean over the span): learned from each set, the correlation time and the scale
/// are poorly determined (the correlation time 15-1800 s), and the plug-in sigmas are short
/// (normalised errors' sd 1.38). Averaged over the model's sampling distribution
/// (`nuisance::sampling_nodes`), the normalised errors have sd near 1; the estimates are
/// the same.
#[test]
fn sigmas_averaged_over_the_models_sampling_distribution_cover_an_unknown_model() {
    use crate::app::diagnose::nuisance::{apply, estimate, normals_under, sampling_nodes, Held};
    let effect = Effect::BoresightX;
    let scales = [0.6, 0.8, 1.0, 1.25, 1.6];
    let (mut plug_in, mut averaged) = (Vec::new(), Vec::new());
    for seed in 0..40u64 {
        let scenario = Scenario {
            references: 30,
            passes: 2,
            nav_tau_s: Some([20.0, 300.0]),
            nav_scale: [1.0, scales[seed as usize % scales.len()]],
            ..Default::default()
        };
        let (mut set, truth) = mounting_angle_as_roll(&scenario, 900 + seed, effect);
        let sp = split(&set, seed).unwrap();
        let n = estimate(&set, &sp.fit, &Held::default(), [20.0, 300.0]).unwrap();
        let nodes: Vec<Node> = sampling_nodes(&n)
            .iter()
            .map(|(m, weight)| Node {
                normals: normals_under(&mut set, m, &sp.fit).unwrap(),
                weight: *weight,
            })
            .collect();
        let applied = apply(set, &n);
        let z = |nodes: &[Node]| fitted_alone(&applied, &sp, (&[], nodes), (effect, truth));
        let (a, w) = (z(&[]), z(&nodes));
        assert_eq!(a.0, w.0, "the estimate is the learned model's");
        assert!(a.1.is_finite() && w.1.is_finite(), "{a:?} {w:?}");
        plug_in.push(a.1);
        averaged.push(w.1);
    }
    let (sd_plug_in, sd_averaged) = (mean_std(&plug_in).1, mean_std(&averaged).1);
    let within = |z: &[f64]| z.iter().filter(|z| z.abs() < 2.0).count();
    println!(
        "normalised errors' sd: {sd_plug_in:.2} plug-in, {sd_averaged:.2} averaged; within 2 \
         sigma {} and {} of 40",
        within(&plug_in),
        within(&averaged)
    );
    // 40 draws: the sd of a unit sample's sd is about 0.11.
    assert!(
        sd_plug_in > 1.25,
        "the plug-in sigmas are short here: {sd_plug_in}"
    );
    assert!((0.75..1.25).contains(&sd_averaged), "{sd_averaged}");
}
