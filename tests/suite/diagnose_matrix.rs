//! The diagnosis on surveys it was not tuned to (docs/diagnosis.md, "The matrix"): the
//! acceptance survey simulated under navigation error processes other than the one-GM-per-axis
//! model the diagnosis fits (correlation times set independently over 10-300 s, random walk
//! plus white noise, two time scales, SMRMSG sigmas stated 0.7x and 1.5x, zero SBET rate
//! fields with roll/pitch vibration), with and without foreign returns on the references, on
//! one lap and on the 15-minute survey; per cell and seed: no effect, every catalogue effect at
//! twice, once and 0.4 times the size the diagnosis of the same survey without effect reports
//! as `detectable`, and the two effects outside the catalogue; the navigation model always
//! learned from the survey.
//!
//! Sizes in units of `detectable` (`D`): naming takes the fit test at Holm's first level and
//! the held-out test, so `D` is about 5 sigmas of the fit estimate; 2 D is about 10 sigmas (the
//! ">= 5 sigma" rows), 0.4 D about 2 sigmas (the "below 3 sigma" rows), and an effect of size
//! `D` is named in 90% of seeds when `detectable` is honest.
//!
//! The full matrix is 9 x 2 x 2 cells of 48 cases x 5 seeds: hours on 2 cores. `cargo test`
//! skips it (`#[ignore]`); CI runs a fixed sample (3 models, foreign off and on, one lap, no
//! effect, attitude latency, boresight_x and range zero at 2 D, D and 0.4 D, the cyclic range
//! error, 5 seeds: 330 diagnoses, about 17 minutes of CPU; a 90% line is then decided by 90 cases, not
//! by one), and the full table is made by
//! `KINESCAN_MATRIX=full cargo test --release --test suite -- --ignored diagnosis_matrix
//! --nocapture` (docs/diagnosis.md). Environment: `KINESCAN_MATRIX_MODELS`,
//! `KINESCAN_MATRIX_FOREIGN` (`off,on`), `KINESCAN_MATRIX_LENGTHS` (`lap,survey`),
//! `KINESCAN_MATRIX_SIZES` (`2,1,0.4`), `KINESCAN_MATRIX_EFFECTS` (effect names, `none`,
//! `out: range_cyclic`, `out: range_incidence`), `KINESCAN_MATRIX_SEEDS` (a count, default 5, or a
//! range of seed ordinals `a-b`), the others each a comma list selecting labels (an unknown
//! label fails); `KINESCAN_MATRIX_REASON` (set: each diagnosis' `reason` is printed too);
//! `KINESCAN_MATRIX_SET` (`KEY=VALUE` lines separated by `;`, applied to every diagnosis as
//! `--set` would be: the experiments with a navigation parameter given rather than learned).

use super::diagnose_acceptance::{
    catalogue_cases, diagnose_dir, excess_is_significant, other_cases, score, simulate_text,
    with_effects, Case, Expect, ACCEPTANCE_SCENARIO,
};
use kinescan::app::diagnose::report::{Diagnosis, Verdict};
use kinescan::testing::short_of;

/// A navigation error process of the simulator: lines replacing the acceptance scenario's
/// correlation times in `[nav_errors]`, and a `[vehicle]` table.
#[derive(Debug, Clone, Copy)]
pub struct NavModel {
    pub label: &'static str,
    pub nav_errors: &'static str,
    pub vehicle: &'static str,
}

/// The navigation error processes of the matrix (docs/simulator.md, `[nav_errors]`).
pub const NAV_MODELS: [NavModel; 9] = [
    NavModel {
        label: "gm 60/30",
        nav_errors: "position_tau_s = 60.0\nattitude_tau_s = 30.0",
        vehicle: "",
    },
    NavModel {
        label: "gm 10/300",
        nav_errors: "position_tau_s = 10.0\nattitude_tau_s = 300.0",
        vehicle: "",
    },
    NavModel {
        label: "gm 300/10",
        nav_errors: "position_tau_s = 300.0\nattitude_tau_s = 10.0",
        vehicle: "",
    },
    NavModel {
        label: "gm 20/120",
        nav_errors: "position_tau_s = 20.0\nattitude_tau_s = 120.0",
        vehicle: "",
    },
    NavModel {
        label: "rw+white",
        nav_errors: "model = \"random_walk_white\"\nposition_tau_s = 60.0\nattitude_tau_s = 30.0",
        vehicle: "",
    },
    NavModel {
        label: "two gm",
        nav_errors: "model = \"two_gauss_markov\"\nposition_tau_s = 15.0\nattitude_tau_s = 10.0\n\
                     position_tau2_s = 600.0\nattitude_tau2_s = 300.0",
        vehicle: "",
    },
    NavModel {
        label: "smrmsg x0.7",
        nav_errors: "position_tau_s = 60.0\nattitude_tau_s = 30.0\nsmrmsg_factor = 0.7",
        vehicle: "",
    },
    NavModel {
        label: "smrmsg x1.5",
        nav_errors: "position_tau_s = 60.0\nattitude_tau_s = 30.0\nsmrmsg_factor = 1.5",
        vehicle: "",
    },
    NavModel {
        label: "zero rates + vibration",
        nav_errors: "position_tau_s = 60.0\nattitude_tau_s = 30.0\nzero_rate_fields = true",
        vehicle: "vibration_deg = [0.3, 0.3]\nvibration_hz = 3.0",
    },
];

/// Share of a reference's returns from foreign things when foreign returns are on.
pub const FOREIGN_SHARE: f64 = 0.003;

/// One lap of the acceptance route (s), or the whole 15-lap survey.
fn duration(length: &str) -> Option<f64> {
    match length {
        "lap" => Some(62.0),
        _ => None,
    }
}

/// The acceptance scenario under `model`, foreign returns `foreign`, with `effects`.
pub fn scenario(model: &NavModel, foreign: bool, effects: &str) -> String {
    let mut text = with_effects(ACCEPTANCE_SCENARIO, effects)
        .replace("position_tau_s = 60.0\n", "")
        .replace("attitude_tau_s = 30.0\n", "")
        .replace(
            "[nav_errors]\n",
            &format!("[nav_errors]\n{}\n", model.nav_errors),
        );
    if foreign {
        text = text.replace(
            "[scene]\n",
            &format!("[scene]\nforeign_share = {FOREIGN_SHARE}\n"),
        );
    }
    if !model.vehicle.is_empty() {
        text.push_str(&format!("\n[vehicle]\n{}\n", model.vehicle));
    }
    text
}

/// `text` with every decimal number (a `.` in it) multiplied by `factor`.
fn scale_numbers(text: &str, factor: f64) -> String {
    let is_num = |c: char| c.is_ascii_digit() || c == '.' || c == '-';
    let (mut out, mut token) = (String::new(), String::new());
    for c in text.chars().chain(std::iter::once('\n')) {
        if is_num(c) {
            token.push(c);
            continue;
        }
        match token.parse::<f64>() {
            Ok(v) if token.contains('.') => out.push_str(&format!("{:?}", v * factor)),
            _ => out.push_str(&token),
        }
        token.clear();
        out.push(c);
    }
    out.pop();
    out
}

/// `case` (a catalogue case) with its sizes scaled by `factor` (zeros stay zero) and its
/// correction with them.
fn scaled(case: &Case, factor: f64) -> Case {
    let expect = match &case.expect {
        Expect::Effects(e) => Expect::Effects(e.iter().map(|(e, x)| (*e, x * factor)).collect()),
        other => other.clone(),
    };
    Case {
        label: case.label.clone(),
        effects_toml: scale_numbers(&case.effects_toml, factor),
        expect,
    }
}

#[test]
fn catalogue_sizes_scale_and_zeros_stay() {
    assert_eq!(
        scale_numbers("boresight_error_deg = [0.05, 0.0, -0.5]", 2.0),
        "boresight_error_deg = [0.1, 0.0, -1.0]"
    );
    assert_eq!(
        scale_numbers("range_scale_ppm = 1000.0", 0.5),
        "range_scale_ppm = 500.0"
    );
}

/// One diagnosis of the matrix, scored.
#[derive(Debug, Clone)]
struct Outcome {
    model: &'static str,
    foreign: bool,
    length: &'static str,
    /// `none`, the effect's name, or the out-of-catalogue label.
    case: String,
    /// Size in units of `detectable` (catalogue effects), else 0.
    size: f64,
    seed: u64,
    /// `None`: the diagnosis failed, or (`no_size`) was not run.
    d: Option<Diagnosis>,
    expect: Expect,
    /// A catalogue case at 2 D or more whose survey reports no `detectable` size (it would
    /// name the effect at no size): not run, and counted as not named (nor estimated, nor
    /// closed) at 2 D, since the survey cannot name it at 5 sigmas either.
    no_size: bool,
}

impl Outcome {
    fn score(&self) -> Option<super::diagnose_acceptance::Score> {
        self.d.as_ref().map(|d| score(d, &self.expect))
    }

    /// The held-out gap after re-processing within 3 sds of an honest model: the chi2/dof the
    /// verdict tests (the estimate's own covariance in the held-out covariance) against the sd
    /// the report gives, `sqrt(2 / n)` widened by the learned navigation model's sampling error.
    fn after_honest(&self) -> bool {
        self.d.as_ref().is_some_and(|d| {
            let sd = d.gap.after_chi2_per_dof_sd;
            sd.is_finite() && (d.gap.after_chi2_per_dof_given_estimate - 1.0).abs() <= 3.0 * sd
        })
    }

    /// The same with the raw held-out chi2/dof (the estimate taken as exact), printed beside.
    fn after_honest_raw(&self) -> bool {
        self.d.as_ref().is_some_and(|d| {
            let sd = d.gap.after_chi2_per_dof_sd;
            sd.is_finite() && (d.gap.after.chi2_per_dof - 1.0).abs() <= 3.0 * sd
        })
    }

    /// A catalogue effect other than the expected one (or its group) named.
    fn wrong_name(&self) -> bool {
        let Some(d) = &self.d else { return false };
        let Expect::Effects(truth) = &self.expect else {
            return !d.effects.is_empty();
        };
        let group_of = |name: &str| -> Vec<String> {
            d.groups
                .iter()
                .find(|g| g.members.iter().any(|m| m == name))
                .map_or(vec![name.to_string()], |g| g.members.clone())
        };
        let allowed: Vec<String> = truth.iter().flat_map(|(e, _)| group_of(e.name())).collect();
        d.effects.iter().any(|e| !allowed.contains(e))
    }
}

fn selected<'a>(var: &str, all: &[&'a str], default: &[&'a str]) -> Vec<&'a str> {
    let v = std::env::var(var).unwrap_or_default();
    if v.is_empty() {
        return default.to_vec();
    }
    let picked: Vec<&str> = v.split(',').map(str::trim).collect();
    let unknown: Vec<&&str> = picked.iter().filter(|p| !all.contains(p)).collect();
    assert!(unknown.is_empty(), "{var}: no label {unknown:?} in {all:?}");
    all.iter().copied().filter(|a| picked.contains(a)).collect()
}

/// Simulates and diagnoses one case; an error is printed and kept as a failed diagnosis.
fn diagnose_case(text: &str, length: &str, seed: u64) -> Option<Diagnosis> {
    let dir = tempfile::tempdir().unwrap();
    if let Err(e) = simulate_text(dir.path(), text, seed, duration(length)) {
        println!("    seed {seed}: simulator refused: {e}");
        return None;
    }
    match diagnose_dir(dir.path(), &overrides()) {
        Ok(d) => Some(d),
        Err(e) => {
            println!("    seed {seed}: diagnosis error: {e}");
            None
        }
    }
}

/// `KINESCAN_MATRIX_SET`'s `KEY=VALUE` lines.
fn overrides() -> Vec<String> {
    std::env::var("KINESCAN_MATRIX_SET")
        .unwrap_or_default()
        .split(';')
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .map(String::from)
        .collect()
}

/// Prints one diagnosis of the matrix.
fn print_outcome(label: &str, size: f64, seed: u64, d: &Diagnosis, expect: &Expect) {
    println!(
        "  {label} x{size} seed {seed}: {} {:?} est {:?} sigma {:?} chi2/dof {:.3} (sd {:.3}, n {}) -> {:.3} (sd {:.3}) located {:?} nav tau {:.0}/{:.0} s scale {:.2}/{:.2} (log sd {}) foreign {}",
        serde_json::to_string(&d.verdict).unwrap(),
        d.effects,
        d.estimate,
        d.sigma,
        d.gap.before.chi2_per_dof,
        d.gap.before_chi2_per_dof_sd,
        d.gap.before.n,
        d.gap.after.chi2_per_dof,
        d.gap.after_chi2_per_dof_sd,
        d.located_in,
        d.nuisance.position_tau_s.value,
        d.nuisance.attitude_tau_s.value,
        d.nuisance.position_scale.value,
        d.nuisance.attitude_scale.value,
        [
            &d.nuisance.position_tau_s,
            &d.nuisance.attitude_tau_s,
            &d.nuisance.position_scale,
            &d.nuisance.attitude_scale,
        ]
        .map(|p| p.sigma.map_or("-".into(), |s| format!("{:.2}", s / p.value)))
        .join("/"),
        d.foreign.set_aside,
    );
    if std::env::var_os("KINESCAN_MATRIX_REASON").is_some() {
        println!("    reason: {}", d.reason);
    }
    if let Expect::Effects(truth) = expect {
        for (e, size) in truth {
            if let (Some(est), Some(sig)) = (d.estimate.get(e.name()), d.sigma.get(e.name())) {
                println!(
                    "    reported: {} truth {size:.4e} est {est:.4e} +- {sig:.2e} (z {:+.2})",
                    e.name(),
                    (est - size) / sig
                );
            }
            if let Some(c) = d.candidates.iter().find(|c| c.effects == [e.name()]) {
                println!(
                    "    alone: {} truth {:.4e} est {:.4e} +- {:.2e} (z {:+.2}) fit p {:.2e} held-out p {:.2e} significant {}",
                    e.name(),
                    size,
                    c.estimate[0],
                    c.sigma[0],
                    (c.estimate[0] - size) / c.sigma[0],
                    c.p_value,
                    c.held_out_p_value,
                    c.significant
                );
            }
        }
    }
}

/// Runs one cell (model, foreign, length) over `seeds` seeds from `first_seed` (each cell its
/// own, so that the cells' cases at `D` are independent draws): per seed, the survey without effect
/// (the `none` case when selected), whose `detectable` sizes that seed's catalogue cases, then
/// every selected case. `D` is what the diagnosis of the same survey reports: an honest
/// `detectable` is named in 90% of seeds at it. (A `D` from one calibration seed for all seeds
/// would test another survey's `D` as well: on one lap it varies by a factor 2 between seeds,
/// `range_zero_m` 1.4-2.9 mm on "two gm", and the power curve is steep there.)
fn run_cell(
    model: &NavModel,
    foreign: bool,
    length: &'static str,
    cases: &[Case],
    sizes: &[f64],
    (first_seed, seeds): (u64, u64),
) -> Vec<Outcome> {
    println!("cell {} / foreign {foreign} / {length}", model.label);
    let mut out = Vec::new();
    for seed in first_seed..first_seed + seeds {
        let calibration = diagnose_case(&scenario(model, foreign, ""), length, seed)
            .expect("the diagnosis of the survey without effect runs");
        let mut runs: Vec<(Case, f64)> = Vec::new();
        for case in cases {
            match &case.expect {
                Expect::Effects(e) if e.len() == 1 => {
                    let Some(Some(det)) = calibration.detectable.get(e[0].0.name()) else {
                        println!(
                            "  {} seed {seed}: no detectable size (its cases at 2 D or more count as not named)",
                            case.label
                        );
                        out.extend(sizes.iter().filter(|&&k| k >= 2.0).map(|&k| Outcome {
                            model: model.label,
                            foreign,
                            length,
                            case: case.label.clone(),
                            size: k,
                            seed,
                            d: None,
                            expect: case.expect.clone(),
                            no_size: true,
                        }));
                        continue;
                    };
                    runs.extend(
                        sizes
                            .iter()
                            .map(|&k| (scaled(case, k * det / e[0].1.abs()), k)),
                    );
                }
                _ => runs.push((case.clone(), 0.0)),
            }
        }
        for (c, size) in runs {
            let d = if c.label == "none" {
                Some(calibration.clone())
            } else {
                diagnose_case(&scenario(model, foreign, &c.effects_toml), length, seed)
            };
            if let Some(d) = &d {
                print_outcome(&c.label, size, seed, d, &c.expect);
            }
            out.push(Outcome {
                model: model.label,
                foreign,
                length,
                case: c.label.clone(),
                size,
                seed,
                d,
                expect: c.expect.clone(),
                no_size: false,
            });
        }
    }
    out
}

/// Acceptance lines the diagnosis does not meet yet (issue "The diagnosis on surveys it was
/// not tuned to" is open; measured in docs/diagnosis.md, *The matrix*): printed as NOT MET
/// with their numbers on every run, not asserted, so that CI guards every line that is met.
/// A line leaves this list when it is met; one that is met while listed is printed as such.
const NOT_YET_MET: [&str; 0] = [
    // Empty since each cell has its own seeds: named at D is judged on CI's 89 distinct
    // (effect, seed) pairs (89% of 89; docs/diagnosis.md, *The matrix*).
];

/// A rate `k / n` as text.
fn rate(k: usize, n: usize) -> String {
    if n == 0 {
        "-".into()
    } else {
        format!("{:.0}% of {n}", 100.0 * k as f64 / n as f64)
    }
}

/// The standard error of a rate over `(seed, ok)` draws, clustered by seed (points): the cases
/// of one seed share one survey's navigation errors, so they are not independent draws (on
/// one lap its z's move together across effects), and a binomial error over cases is too
/// small. `None` below two seeds.
fn clustered_se(draws: &[(u64, bool)]) -> Option<f64> {
    let mut by_seed: std::collections::BTreeMap<u64, (f64, f64)> = Default::default();
    for &(seed, ok) in draws {
        let e = by_seed.entry(seed).or_default();
        e.0 += f64::from(u8::from(ok));
        e.1 += 1.0;
    }
    let k = by_seed.len() as f64;
    let n = draws.len() as f64;
    if k < 2.0 {
        return None;
    }
    let p = by_seed.values().map(|v| v.0).sum::<f64>() / n;
    let ss: f64 = by_seed.values().map(|(ok, m)| (ok - p * m).powi(2)).sum();
    Some(100.0 * (ss * k / (k - 1.0)).sqrt() / n)
}

#[test]
fn clustered_se_counts_seeds_not_cases() {
    // Ten draws per seed: seed 1 all met, seed 2 none. Over 20 independent cases a rate of
    // 50% has a binomial se of 11 points; as two surveys, sqrt(2 (5^2 + 5^2)) / 20 = 50.
    let draws: Vec<(u64, bool)> = (0..20).map(|i| (1 + i / 10, i < 10)).collect();
    assert!((clustered_se(&draws).unwrap() - 50.0).abs() < 1e-9);
    // Every seed alike: no spread between seeds.
    let alike: Vec<(u64, bool)> = (0..20).map(|i| (i / 5, i % 5 < 2)).collect();
    assert!(clustered_se(&alike).unwrap().abs() < 1e-9);
    assert_eq!(clustered_se(&[(1, true), (1, false)]), None);
}

/// The acceptance lines of the issue over `outcomes` (one row of the printed table); returns
/// the failures.
fn judge(label: &str, outcomes: &[&Outcome]) -> Vec<String> {
    let count = |f: &dyn Fn(&Outcome) -> bool| outcomes.iter().filter(|o| f(o)).count();
    let none: Vec<&&Outcome> = outcomes.iter().filter(|o| o.case == "none").collect();
    let none_ok = none
        .iter()
        .filter(|o| o.d.as_ref().is_some_and(|d| d.verdict == Verdict::None))
        .count();
    let big: Vec<&&Outcome> = outcomes.iter().filter(|o| o.size >= 2.0).collect();
    let big_named = big
        .iter()
        .filter(|o| o.score().is_some_and(|s| s.named_ok))
        .count();
    let big_errors: Vec<f64> = big
        .iter()
        .filter_map(|o| o.score())
        .flat_map(|s| s.normalised_errors)
        .collect();
    let big_within = big_errors.iter().filter(|z| z.abs() < 2.0).count();
    let within_draws: Vec<(u64, bool)> = big
        .iter()
        .filter_map(|o| o.score().map(|s| (o.seed, s)))
        .flat_map(|(seed, s)| {
            s.normalised_errors
                .into_iter()
                .map(move |z| (seed, z.abs() < 2.0))
        })
        .collect();
    let big_honest = big.iter().filter(|o| o.after_honest()).count();
    let at_d: Vec<&&Outcome> = outcomes.iter().filter(|o| o.size == 1.0).collect();
    let at_d_named = at_d
        .iter()
        .filter(|o| o.score().is_some_and(|s| s.named_ok))
        .count();
    let small: Vec<&&Outcome> = outcomes
        .iter()
        .filter(|o| o.size > 0.0 && o.size < 1.0)
        .collect();
    let small_wrong = small.iter().filter(|o| o.wrong_name()).count();
    // Named beside the truth (its group allowed) at 2 D and D: no line of the issue, printed
    // so that a correction carrying an effect the survey does not have is seen.
    let extra = |size: f64| {
        let named: Vec<&&Outcome> = outcomes
            .iter()
            .filter(|o| o.size == size && o.score().is_some_and(|s| s.named_ok))
            .collect();
        (named.iter().filter(|o| o.wrong_name()).count(), named.len())
    };
    let out: Vec<&&Outcome> = outcomes
        .iter()
        .filter(|o| matches!(o.expect, Expect::Unexplained(_)))
        .collect();
    let out_ok = out
        .iter()
        .filter(|o| o.score().is_some_and(|s| s.verdict_ok))
        .count();
    let out_located = out
        .iter()
        .filter(|o| o.score().is_some_and(|s| s.located_ok))
        .count();
    let errors = count(&|o| o.d.is_none() && !o.no_size);
    let no_size = count(&|o| o.no_size);
    if no_size > 0 {
        println!("{label}: {no_size} case(s) at 2 D without a detectable size, counted as misses");
    }
    println!(
        "| {label} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {errors} |",
        rate(none_ok, none.len()),
        rate(big_named, big.len()),
        rate(big_within, big_errors.len()),
        rate(big_honest, big.len()),
        rate(at_d_named, at_d.len()),
        rate(small.len() - small_wrong, small.len()),
        rate(out_ok, out.len()),
        rate(out_located, out.len()),
        outcomes.len(),
    );
    let mut fail = Vec::new();
    let mut need = |k: usize, n: usize, min: f64, what: &str| {
        let short = n > 0 && short_of(k as f64 / n as f64, min);
        let line = format!(
            "{label}: {what} {} (needs >= {:.0}%)",
            rate(k, n),
            min * 100.0
        );
        match (short, NOT_YET_MET.contains(&what)) {
            (true, false) => fail.push(line),
            (true, true) => println!("NOT MET (known, not asserted): {line}"),
            (false, true) if n > 0 => println!("met although listed as not yet met: {line}"),
            _ => {}
        }
    };
    need(none_ok, none.len(), 0.95, "none");
    need(big_named, big.len(), 0.95, "named at 2 D");
    need(big_within, big_errors.len(), 0.90, "within 2 sigma at 2 D");
    need(big_honest, big.len(), 0.90, "after-gap honest at 2 D");
    need(
        small.len() - small_wrong,
        small.len(),
        1.0,
        "no wrong name at 0.4 D",
    );
    need(out_ok, out.len(), 0.90, "unexplained");
    need(out_located, out.len(), 0.90, "located");
    // `detectable` honest: named in 85-95% at D; a band of 10 points needs about 50
    // independent draws to be told from its edges (binomial sd 4%), so the band is judged once
    // 50 distinct (effect, seed) pairs are pooled (each cell has its own seeds: CI's sample
    // holds 90), and fewer are printed only.
    let pairs: std::collections::BTreeSet<(&str, u64)> =
        at_d.iter().map(|o| (o.case.as_str(), o.seed)).collect();
    for size in [2.0, 1.0] {
        let (k, n) = extra(size);
        if n > 0 {
            println!(
                "{label}: another effect named beside the truth at {size} D: {}",
                rate(k, n)
            );
        }
    }
    if !big.is_empty() {
        let raw = big.iter().filter(|o| o.after_honest_raw()).count();
        println!(
            "{label}: after-gap honest at 2 D with the estimate taken as exact: {}",
            rate(raw, big.len())
        );
    }
    let named_draws = |of: &[&&Outcome]| -> Vec<(u64, bool)> {
        of.iter()
            .map(|o| (o.seed, o.score().is_some_and(|s| s.named_ok)))
            .collect()
    };
    let se = |d: &[(u64, bool)]| clustered_se(d).map_or("-".into(), |v| format!("{v:.1}"));
    println!(
        "{label}: seed-clustered se (points): named at 2 D {}, within 2 sigma at 2 D {}, named at D {}",
        se(&named_draws(&big)),
        se(&within_draws),
        se(&named_draws(&at_d)),
    );
    if !at_d.is_empty() {
        println!(
            "{label}: named at D {} over {} (effect, seed) pairs",
            rate(at_d_named, at_d.len()),
            pairs.len()
        );
    }
    if pairs.len() >= 50 {
        let r = at_d_named as f64 / at_d.len() as f64;
        if !(0.85..=0.95).contains(&r) {
            let line = format!(
                "{label}: named at D {} outside 85-95% ({} pairs)",
                rate(at_d_named, at_d.len()),
                pairs.len()
            );
            if NOT_YET_MET.contains(&"named at D") {
                println!("NOT MET (known, not asserted): {line}");
            } else {
                fail.push(line);
            }
        }
    }
    fail
}

/// The seeds of each cell, by ordinal from 1: `KINESCAN_MATRIX_SEEDS` is a count `n` (the
/// first `n`, default 5) or a range `a-b` (the `a`-th to the `b`-th), so that more seeds can
/// be added to a table without running its first ones again.
fn seed_ordinals() -> std::ops::RangeInclusive<u64> {
    let text = std::env::var("KINESCAN_MATRIX_SEEDS").unwrap_or_else(|_| "5".into());
    let bad = || panic!("KINESCAN_MATRIX_SEEDS = {text:?}: expected a count `n` or a range `a-b`");
    let ordinal = |s: &str| s.trim().parse::<u64>().ok().filter(|&k| k >= 1);
    let (a, b) = match text.split_once('-') {
        Some((a, b)) => (ordinal(a), ordinal(b)),
        None => (Some(1), ordinal(&text)),
    };
    match (a, b) {
        (Some(a), Some(b)) if a <= b => a..=b,
        _ => bad(),
    }
}

/// The matrix (or the selected part of it): the table per cell and pooled, thresholds
/// asserted on the pooled rows.
#[test]
#[ignore = "the diagnosis matrix: hours in full; CI runs a sample (docs/diagnosis.md)"]
fn diagnosis_matrix() {
    let full = std::env::var("KINESCAN_MATRIX").as_deref() == Ok("full");
    let model_labels: Vec<&str> = NAV_MODELS.iter().map(|m| m.label).collect();
    let default_models: Vec<&str> = if full {
        model_labels.clone()
    } else {
        vec!["two gm", "smrmsg x1.5", "zero rates + vibration"]
    };
    let models = selected("KINESCAN_MATRIX_MODELS", &model_labels, &default_models);
    let foreign = selected("KINESCAN_MATRIX_FOREIGN", &["off", "on"], &["off", "on"]);
    let lengths = selected(
        "KINESCAN_MATRIX_LENGTHS",
        &["lap", "survey"],
        if full { &["lap", "survey"] } else { &["lap"] },
    );
    let sizes: Vec<f64> = selected(
        "KINESCAN_MATRIX_SIZES",
        &["2", "1", "0.4"],
        &["2", "1", "0.4"],
    )
    .iter()
    .map(|s| s.parse().unwrap())
    .collect();
    let all_cases: Vec<Case> = catalogue_cases()
        .into_iter()
        .chain(other_cases())
        .filter(|c| !matches!(&c.expect, Expect::Effects(e) if e.len() > 1))
        .collect();
    let labels: Vec<&str> = all_cases.iter().map(|c| c.label.as_str()).collect();
    let default_cases: Vec<&str> = if full {
        labels.clone()
    } else {
        vec![
            "none",
            "attitude_latency_s",
            "boresight_x_deg",
            "range_zero_m",
            "out: range_cyclic",
        ]
    };
    let picked = selected("KINESCAN_MATRIX_EFFECTS", &labels, &default_cases);
    let cases: Vec<Case> = all_cases
        .iter()
        .filter(|c| picked.contains(&c.label.as_str()))
        .cloned()
        .collect();
    let seeds = seed_ordinals();
    let mut outcomes = Vec::new();
    for (i, m) in NAV_MODELS.iter().enumerate() {
        if !models.contains(&m.label) {
            continue;
        }
        for f in &foreign {
            for l in &lengths {
                let length: &'static str = if *l == "lap" { "lap" } else { "survey" };
                // The cell's own seeds, the same whichever cells are selected.
                let cell = 4 * i as u64 + 2 * u64::from(*f == "on") + u64::from(length != "lap");
                let first_seed = 1000 * cell + seeds.start();
                let n = seeds.end() + 1 - seeds.start();
                outcomes.extend(run_cell(
                    m,
                    *f == "on",
                    length,
                    &cases,
                    &sizes,
                    (first_seed, n),
                ));
            }
        }
    }
    println!(
        "\n| cell | none | named at 2 D | within 2 sigma at 2 D | after-gap honest at 2 D | named at D | no wrong name at 0.4 D | out: unexplained | out: located | diagnoses | errors |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for m in &models {
        for f in &foreign {
            for l in &lengths {
                let cell: Vec<&Outcome> = outcomes
                    .iter()
                    .filter(|o| o.model == *m && o.foreign == (*f == "on") && o.length == *l)
                    .collect();
                judge(&format!("{m} / foreign {f} / {l}"), &cell);
            }
        }
    }
    let all: Vec<&Outcome> = outcomes.iter().collect();
    let failures = judge("pooled", &all);
    let with_excess = all
        .iter()
        .filter(|o| {
            o.d.as_ref()
                .is_some_and(|d| excess_is_significant(&d.gap.before))
        })
        .count();
    println!(
        "{with_excess} of {} diagnoses had a significant held-out excess before",
        all.len()
    );
    let seeds_seen: std::collections::BTreeSet<u64> = all.iter().map(|o| o.seed).collect();
    assert!(
        !all.is_empty() && !seeds_seen.is_empty(),
        "nothing selected"
    );
    assert!(failures.is_empty(), "not met:\n{}", failures.join("\n"));
}
