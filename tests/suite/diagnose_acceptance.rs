//! Acceptance of the diagnosis on the simulator (docs/diagnosis.md, "Acceptance on the
//! simulator"): every catalogue effect injected at a size that moves points by 1-5 cm, no
//! effect, effects outside the catalogue and two effects at once, over seeds, on the 15-minute
//! acceptance survey (`pipelines/scenario_acceptance.toml`); prints the table of rates and
//! asserts the thresholds of the acceptance.
//!
//! About 14 s per seed and case with the navigation model learned (2 cores), 19 cases x 5
//! seeds: a quarter of an hour, so it is `#[ignore]`d in `cargo test`; CI (`.ci/run`) runs seeds
//! 1-2 of every case, the full table is
//! `KINESCAN_ACCEPT_SEEDS=10 cargo test --release --test suite -- --ignored diagnosis_acceptance --nocapture`.

use kinescan::app::diagnose::model::Effect;
use kinescan::app::diagnose::report::{Diagnosis, Verdict};
use kinescan::app::diagnose::{self, Request};
use kinescan::pipeline::config;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
use kinescan::testing::short_of;
use std::path::Path;

/// What a case injects and what a correct diagnosis says.
#[derive(Debug, Clone)]
pub struct Case {
    /// Row label.
    pub label: String,
    /// Lines of the scenario's `[effects]` table.
    pub effects_toml: String,
    /// What should be found.
    pub expect: Expect,
}

/// A correct diagnosis.
#[derive(Debug, Clone)]
pub enum Expect {
    /// Catalogue effects with the correction to add (in the name's unit).
    Effects(Vec<(Effect, f64)>),
    /// Verdict `none`.
    Nothing,
    /// Verdict `unexplained`, located in this covariate.
    Unexplained(&'static str),
}

/// One diagnosis of one case and seed, scored.
#[derive(Debug, Clone, Default)]
pub struct Score {
    /// Verdict as expected (`effect` / `none` / `unexplained`).
    pub verdict_ok: bool,
    /// Every expected effect named (first, or in the first group, for a single effect).
    pub named_ok: bool,
    /// Per expected effect: (estimate - truth) / sigma.
    pub normalised_errors: Vec<f64>,
    /// Share of the held-out excess chi2 (chi2/dof - 1) closed after the correction (after
    /// re-processing with the named effects, or by the model-free correction for
    /// `unexplained`); `None` when the held-out gap before was not significant (no excess to
    /// close) or the expected effects were not named (no re-processing with them). A
    /// non-finite share is kept: it scores as a failure to close (see [`run_case`]).
    pub closed: Option<f64>,
    /// A catalogue effect was named.
    pub named_any: bool,
    /// The expected covariate is the leading one (`unexplained`).
    pub located_ok: bool,
}

/// The acceptance survey: the demo's city block, 15 laps, sparse profiles (the file says why).
pub const ACCEPTANCE_SCENARIO: &str = include_str!("../../pipelines/scenario_acceptance.toml");

/// The acceptance survey with `effects` injected, `seed`, simulated into `dir/survey`
/// with the demo pipeline beside it.
pub fn simulate_case(dir: &Path, effects: &str, seed: u64) {
    simulate_text(dir, &with_effects(ACCEPTANCE_SCENARIO, effects), seed, None).unwrap();
}

/// Scenario `text` with `effects` as its `[effects]` table.
pub fn with_effects(text: &str, effects: &str) -> String {
    text.replace(
        "[nav_errors]",
        &format!("[effects]\n{effects}\n\n[nav_errors]"),
    )
}

/// Simulates scenario `text` with `seed` (and `duration_s` instead of its own) into
/// `dir/survey`, with the demo pipeline beside it.
pub fn simulate_text(
    dir: &Path,
    text: &str,
    seed: u64,
    duration_s: Option<f64>,
) -> kinescan::Result<()> {
    let mut sc = Scenario::parse(text, "acceptance")?;
    sc.seed = seed;
    if let Some(d) = duration_s {
        sc.duration_s = d;
    }
    simulate_scenario(&sc, &dir.join("survey"), &SimOptions::default())?;
    std::fs::write(dir.join("pipeline.toml"), kinescan::app::demo::PIPELINE).unwrap();
    Ok(())
}

/// Diagnoses the survey in `dir` as a user would: the navigation error model learned from
/// the survey, but for what `overrides` (`--set` lines) give.
pub fn diagnose_dir(dir: &Path, overrides: &[String]) -> kinescan::Result<Diagnosis> {
    let p = config::load(&dir.join("pipeline.toml"), overrides)?;
    let req = Request {
        patches: dir.join("survey/patches.csv"),
        control_points: None,
        out_dir: dir.join("diagnosis"),
    };
    diagnose::run(&p, &req)
}

/// Scores diagnosis `d` against `expect`.
pub fn score(d: &Diagnosis, expect: &Expect) -> Score {
    let (b, a) = (d.gap.before.chi2_per_dof, d.gap.after.chi2_per_dof);
    let closed = excess_is_significant(&d.gap.before).then(|| (b - a) / (b - 1.0));
    let mut s = Score {
        closed,
        named_any: !d.effects.is_empty(),
        ..Default::default()
    };
    match expect {
        Expect::Effects(truth) => {
            s.verdict_ok = d.verdict == Verdict::Effect;
            s.named_ok = s.verdict_ok
                && truth
                    .iter()
                    .all(|(e, _)| d.effects.iter().any(|n| n == e.name()));
            if truth.len() == 1 && s.named_ok {
                // A single effect: named first, or a member of the group named first.
                let first_group = d
                    .groups
                    .iter()
                    .find(|g| g.members.first() == d.effects.first());
                s.named_ok = d.effects.first().map(String::as_str) == Some(truth[0].0.name())
                    || first_group
                        .is_some_and(|g| g.members.iter().any(|m| m == truth[0].0.name()));
            }
            if !s.named_ok {
                // Not re-processed with the effect: a miss, counted by `named`, not by `closed`.
                s.closed = None;
            }
            for (e, x) in truth {
                // A missing or non-finite estimate or sigma is a miss: an infinite normalised
                // error, outside 2 sigma (left out of the std, counted as `missed`).
                let z = match (d.estimate.get(e.name()), d.sigma.get(e.name())) {
                    (Some(est), Some(sig)) => (est - x) / sig,
                    _ => f64::INFINITY,
                };
                s.normalised_errors
                    .push(if z.is_finite() { z } else { f64::INFINITY });
            }
        }
        Expect::Nothing => s.verdict_ok = d.verdict == Verdict::None,
        Expect::Unexplained(cov) => {
            s.verdict_ok = d.verdict == Verdict::Unexplained && d.effects.is_empty();
            s.located_ok = d.located_in.first().map(String::as_str) == Some(*cov);
            s.closed = match &d.model_free {
                Some(m) => s.closed.map(|_| m.closed_fraction),
                None => Some(0.0), // none applied: closes nothing, excess or not
            };
        }
    }
    s
}

/// The held-out chi2/dof before exceeds 1 by more than 3 of its standard deviations
/// (`sqrt(2 / n)`): an excess to close. Below that the "closed" share is a ratio of noise.
pub fn excess_is_significant(g: &kinescan::app::diagnose::report::GapMetrics) -> bool {
    g.chi2_per_dof - 1.0 > 3.0 * (2.0 / g.n as f64).sqrt()
}

/// Rates of one case over its seeds.
#[derive(Debug, Clone)]
pub struct Row {
    /// Case label.
    pub label: String,
    /// Seeds run.
    pub seeds: usize,
    /// Share with the expected verdict.
    pub verdict: f64,
    /// Share with every expected effect named.
    pub named: f64,
    /// Share naming any catalogue effect.
    pub named_any: f64,
    /// Share of expected estimates within 2 sigma of the truth.
    pub within_2_sigma: f64,
    /// The normalised estimate errors `(estimate - truth) / sigma`.
    pub errors: Vec<f64>,
    /// Standard deviation of the finite normalised estimate errors (a missed estimate is
    /// infinite: outside 2 sigma, left out of the std).
    pub normalised_std: f64,
    /// Seeds with a significant held-out excess and the right answer (where "closed" is
    /// defined).
    pub with_excess: usize,
    /// Median share of the held-out excess chi2 closed, over the seeds with an excess.
    pub closed_median: f64,
    /// Share located in the right covariate (`unexplained` cases).
    pub located: f64,
}

/// Runs `case` over `seeds` (each in its own temporary folder).
pub fn run_case(case: &Case, seeds: std::ops::Range<u64>) -> Row {
    let scores: Vec<Score> = seeds
        .clone()
        .map(|seed| {
            let dir = tempfile::tempdir().unwrap();
            simulate_case(dir.path(), &case.effects_toml, seed);
            let d = match diagnose_dir(dir.path(), &[]) {
                Ok(d) => d,
                Err(e) => {
                    // Counted as a failure of every rate, with the reason printed.
                    println!("  {} seed {seed}: error: {e}", case.label);
                    return Score::default();
                }
            };
            let s = score(&d, &case.expect);
            println!(
                "  {} seed {seed}: {} {:?} est {:?} sigma {:?} chi2/dof {:.2} -> {:.2} located {:?}",
                case.label,
                serde_json::to_string(&d.verdict).unwrap(),
                d.effects,
                d.estimate,
                d.sigma,
                d.gap.before.chi2_per_dof,
                d.gap.after.chi2_per_dof,
                d.located_in
            );
            s
        })
        .collect();
    let n = scores.len() as f64;
    let share = |f: &dyn Fn(&Score) -> bool| scores.iter().filter(|s| f(s)).count() as f64 / n;
    let errors: Vec<f64> = scores
        .iter()
        .flat_map(|s| s.normalised_errors.clone())
        .collect();
    // Where a closure is defined, a non-finite one counts as closing nothing (-inf sorts
    // first), not as a seed without an excess.
    let closed: Vec<f64> = scores
        .iter()
        .filter_map(|s| s.closed)
        .map(|c| if c.is_finite() { c } else { f64::NEG_INFINITY })
        .collect();
    Row {
        label: case.label.clone(),
        seeds: scores.len(),
        verdict: share(&|s| s.verdict_ok),
        named: share(&|s| s.named_ok),
        named_any: share(&|s| s.named_any),
        within_2_sigma: within_2_sigma(&errors),
        normalised_std: std(&errors),
        errors,
        with_excess: closed.len(),
        closed_median: median(closed),
        located: share(&|s| s.located_ok),
    }
}

/// Sample standard deviation of the finite values (NaN for fewer than two).
pub fn std(x: &[f64]) -> f64 {
    let x: Vec<f64> = x.iter().copied().filter(|e| e.is_finite()).collect();
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (x.len() as f64 - 1.0)).sqrt()
}

/// Normalised errors that are not finite: missed estimates.
fn missed(x: &[f64]) -> usize {
    x.iter().filter(|e| !e.is_finite()).count()
}

/// Share of normalised errors inside +-2, a missed estimate outside (NaN for none).
pub fn within_2_sigma(x: &[f64]) -> f64 {
    x.iter().filter(|e| e.abs() < 2.0).count() as f64 / x.len() as f64
}

/// Median (NaN for none).
pub fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    x.get(x.len().saturating_sub(1) / 2)
        .copied()
        .unwrap_or(f64::NAN)
}

/// Prints the table of rates.
pub fn print_table(rows: &[Row]) {
    println!(
        "| case | seeds | verdict | named | within 2 sigma | std(err/sigma) | seeds with excess | closed (median) | located |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        println!(
            "| {} | {} | {:.0}% | {:.0}% | {:.0}% | {:.2} | {} | {:.0}% | {:.0}% |",
            r.label,
            r.seeds,
            r.verdict * 100.0,
            r.named * 100.0,
            r.within_2_sigma * 100.0,
            r.normalised_std,
            r.with_excess,
            r.closed_median * 100.0,
            r.located * 100.0
        );
    }
}

/// A catalogue case: `toml` injected in the simulator, `(effect, correction)` expected.
pub fn catalogue(label: &str, toml: &str, effect: Effect, correction: f64) -> Case {
    Case {
        label: label.into(),
        effects_toml: toml.into(),
        expect: Expect::Effects(vec![(effect, correction)]),
    }
}

/// Every catalogue effect the simulator injects, each at a size that moves points by 1-5 cm
/// on the city block (ranges 3-60 m, speed up to 11 m/s, turns up to ~30 deg/s), with the
/// correction a correct diagnosis names (docs/simulator.md gives each simulator key's sign).
pub fn catalogue_cases() -> Vec<Case> {
    vec![
        // 5 ms at 30 deg/s in the corners, 20 m: 5 cm.
        catalogue(
            "attitude_latency_s",
            "attitude_latency_s = 0.005",
            Effect::AttitudeLatency,
            0.005,
        ),
        // 0.05 deg at 30 m: 2.6 cm.
        catalogue(
            "boresight_x_deg",
            "boresight_error_deg = [0.05, 0.0, 0.0]",
            Effect::BoresightX,
            0.05,
        ),
        catalogue(
            "boresight_y_deg",
            "boresight_error_deg = [0.0, 0.05, 0.0]",
            Effect::BoresightY,
            0.05,
        ),
        catalogue(
            "boresight_z_deg",
            "boresight_error_deg = [0.0, 0.0, 0.05]",
            Effect::BoresightZ,
            0.05,
        ),
        catalogue(
            "lever_arm_x_m",
            "lever_arm_error_m = [0.03, 0.0, 0.0]",
            Effect::LeverArmX,
            0.03,
        ),
        catalogue(
            "lever_arm_y_m",
            "lever_arm_error_m = [0.0, 0.03, 0.0]",
            Effect::LeverArmY,
            0.03,
        ),
        catalogue(
            "lever_arm_z_m",
            "lever_arm_error_m = [0.0, 0.0, 0.05]",
            Effect::LeverArmZ,
            0.05,
        ),
        catalogue(
            "range_zero_m",
            "range_zero_error_m = 0.03",
            Effect::RangeZero,
            0.03,
        ),
        // Recorded range = true * (1 + ppm 1e-6) - K: the correction is -ppm. 1000 ppm at 30 m: 3 cm.
        catalogue(
            "range_scale_ppm",
            "range_scale_ppm = 1000.0",
            Effect::RangeScale,
            -1000.0,
        ),
        // Recorded beta = true + offset: the correction is -offset.
        catalogue(
            "encoder_offset_deg",
            "encoder_offset_deg = 0.05",
            Effect::EncoderOffset,
            -0.05,
        ),
        catalogue("cone_deg", "cone_error_deg = 0.05", Effect::Cone, 0.05),
        // 3 ppm over the 930 s survey: up to 2.8 ms, 3 cm at 11 m/s.
        catalogue(
            "clock_drift_ppm",
            "clock_drift_ppm = 3.0",
            Effect::ClockDrift,
            3.0,
        ),
        // SBET position stamped late by 3 ms: 3.3 cm at 11 m/s.
        catalogue(
            "position_latency_s",
            "position_latency_s = 0.003",
            Effect::PositionLatency,
            0.003,
        ),
        // True time = configured + 3 ms: 3.3 cm at 11 m/s.
        catalogue(
            "clock_offset_s",
            "clock_offset_s = 0.003",
            Effect::ClockOffset,
            0.003,
        ),
        // SBET heading = true + bias: the correction is -bias. 0.05 deg at 30 m: 2.6 cm.
        catalogue(
            "heading_offset_deg",
            "heading_bias_deg = 0.05",
            Effect::HeadingOffset,
            -0.05,
        ),
    ]
}

/// No effect, effects outside the catalogue, and two at once. The simulator's quadratic clock
/// drift is no case of `unexplained`: its best offset + drift fit over the survey leaves 1/36
/// of its mean square, so the catalogue's clock effects are its right first-order description
/// (docs/diagnosis.md, "Acceptance on the simulator").
pub fn other_cases() -> Vec<Case> {
    vec![
        Case {
            label: "none".into(),
            effects_toml: String::new(),
            expect: Expect::Nothing,
        },
        Case {
            // 2 cm cyclic in range, period 12 m.
            label: "out: range_cyclic".into(),
            effects_toml: "range_cyclic_m = [0.02, 12.0]".into(),
            expect: Expect::Unexplained("range_m"),
        },
        Case {
            // 3 cm at grazing incidence, 0 head-on.
            label: "out: range_incidence".into(),
            effects_toml: "range_incidence_m = 0.03".into(),
            expect: Expect::Unexplained("incidence_deg"),
        },
        Case {
            label: "latency + lever_arm_y".into(),
            effects_toml: "attitude_latency_s = 0.005\nlever_arm_error_m = [0.0, 0.03, 0.0]".into(),
            expect: Expect::Effects(vec![
                (Effect::AttitudeLatency, 0.005),
                (Effect::LeverArmY, 0.03),
            ]),
        },
    ]
}

/// The acceptance table over `KINESCAN_ACCEPT_SEEDS` seeds (default 10; CI runs 2) per case, with the
/// acceptance thresholds asserted; `KINESCAN_ACCEPT_CASES=label,label` runs some cases only
/// (and asserts only theirs).
#[test]
#[ignore = "the diagnosis acceptance: 19 cases x 5-10 seeds, a quarter of an hour; run by CI"]
fn diagnosis_acceptance() {
    let seeds: u64 = std::env::var("KINESCAN_ACCEPT_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    let only = std::env::var("KINESCAN_ACCEPT_CASES").unwrap_or_default();
    let pick = |c: &&Case| only.is_empty() || only.split(',').any(|o| c.label == o);
    // A label that selects no case (a typo) fails, rather than running and asserting nothing.
    let labels: Vec<String> = catalogue_cases()
        .into_iter()
        .chain(other_cases())
        .map(|c| c.label)
        .collect();
    let unknown: Vec<&str> = only
        .split(',')
        .filter(|o| !o.is_empty() && !labels.iter().any(|l| l == o))
        .collect();
    assert!(
        unknown.is_empty(),
        "KINESCAN_ACCEPT_CASES names no case {unknown:?}; the cases are {labels:?}"
    );
    let run = |cases: Vec<Case>| -> Vec<(Case, Row)> {
        cases
            .iter()
            .filter(pick)
            .map(|c| (c.clone(), run_case(c, 1..seeds + 1)))
            .collect()
    };
    let catalogue = run(catalogue_cases());
    let other = run(other_cases());
    let rows: Vec<Row> = catalogue
        .iter()
        .chain(&other)
        .map(|(_, r)| r.clone())
        .collect();
    assert!(!rows.is_empty(), "no case selected");
    print_table(&rows);
    let failures: Vec<String> = catalogue_failures(&catalogue)
        .into_iter()
        .chain(other.iter().flat_map(|(c, r)| other_failures(c, r)))
        .collect();
    assert!(failures.is_empty(), "not met:\n{}", failures.join("\n"));
}

/// The catalogue's thresholds. Rates are pooled over every effect and seed (150 diagnoses at
/// 10 seeds, 75 at CI's 5): per effect, 10 seeds cannot carry them (a right estimator passes
/// "within 2 sigma in >= 90%" of 10 with probability 0.92, a sample std of 10 inside 0.8-1.25
/// with 0.64), so each effect is held to a floor that catches a systematic miss instead: named
/// in >= 80% (8 of 10, 4 of 5).
fn catalogue_failures(rows: &[(Case, Row)]) -> Vec<String> {
    if rows.is_empty() {
        return Vec::new();
    }
    let mut out = Vec::new();
    let n: usize = rows.iter().map(|(_, r)| r.seeds).sum();
    let named = rows
        .iter()
        .map(|(_, r)| r.named * r.seeds as f64)
        .sum::<f64>()
        / n as f64;
    let errors: Vec<f64> = rows.iter().flat_map(|(_, r)| r.errors.clone()).collect();
    let (within, sd) = (within_2_sigma(&errors), std(&errors));
    println!(
        "catalogue pooled: named {:.1}% of {n}, within 2 sigma {:.1}% and std {sd:.3} of {} estimates ({} missed)",
        named * 100.0,
        within * 100.0,
        errors.len(),
        missed(&errors)
    );
    // Rates compared NaN-proof (`short_of`): no diagnosis at all fails.
    if short_of(named, 0.95) {
        out.push(format!("catalogue named first {:.1}% < 95%", named * 100.0));
    }
    if short_of(within, 0.90) {
        out.push(format!(
            "catalogue within 2 sigma {:.1}% < 90%",
            within * 100.0
        ));
    }
    if !(0.8..=1.25).contains(&sd) {
        out.push(format!(
            "catalogue normalised error std {sd:.3} outside 0.8-1.25"
        ));
    }
    for (c, r) in rows {
        if short_of(r.named, 0.8) {
            out.push(format!("{}: named {:.0}% < 80%", c.label, r.named * 100.0));
        }
        if r.with_excess > 0 && short_of(r.closed_median, 0.8) {
            out.push(format!(
                "{}: re-processing closes {:.0}% < 80% of the held-out excess (median of {})",
                c.label,
                r.closed_median * 100.0,
                r.with_excess
            ));
        }
    }
    out
}

/// The thresholds of the other cases: no effect `none` in >= 95%; an effect outside the
/// catalogue never named, `unexplained` and located in >= 90%, the model-free correction
/// closing >= 50% (median); two effects both named in >= 80%. As counts over 10 seeds (at 5:
/// 5/5, 5/5, 4/5), with the chance a diagnosis right at the given rate fails them: `none` 10/10 (0.096 at 99%,
/// the measured no-effect rate), 9/10 (0.004 at 99%), 8/10 (0.012 at 95%).
fn other_failures(case: &Case, r: &Row) -> Vec<String> {
    let mut out = Vec::new();
    let mut check = |ok: bool, what: String| {
        if !ok {
            out.push(format!("{}: {what}", case.label));
        }
    };
    match &case.expect {
        Expect::Nothing => check(
            r.verdict >= 0.95,
            format!("none {:.0}% < 95%", r.verdict * 100.0),
        ),
        Expect::Unexplained(_) => {
            check(
                r.named_any == 0.0,
                format!("a catalogue effect named in {:.0}%", r.named_any * 100.0),
            );
            check(
                r.verdict >= 0.9,
                format!("unexplained {:.0}% < 90%", r.verdict * 100.0),
            );
            check(
                r.located >= 0.9,
                format!("located {:.0}% < 90%", r.located * 100.0),
            );
            check(
                r.closed_median >= 0.5,
                format!(
                    "model-free closes {:.0}% < 50% (median)",
                    r.closed_median * 100.0
                ),
            );
        }
        Expect::Effects(_) => check(
            r.named >= 0.8,
            format!("both named {:.0}% < 80%", r.named * 100.0),
        ),
    }
    out
}
