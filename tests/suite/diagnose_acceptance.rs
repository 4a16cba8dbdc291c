//! Acceptance of the diagnosis on the simulator (docs/diagnosis.md, "Acceptance"): every
//! catalogue effect injected at a size that moves points by 1-5 cm, no effect, effects outside
//! the catalogue and two effects at once, over seeds; prints the table of rates.
//!
//! The full run (`full_acceptance_table`, >= 10 seeds per case) is an `#[ignore]`d
//! MEASUREMENT, not a test: it prints the rates and asserts none of the thresholds,
//! some of which are not met (docs/diagnosis.md, "Acceptance on the simulator": the measured
//! table and why). Run it with
//! `KINESCAN_ACCEPT_SEEDS=10 cargo test --test suite -- --ignored full_acceptance_table --nocapture`
//! (about 9 s per seed and case); it is not in CI until its thresholds can be asserted.

use kinescan::app::diagnose::model::Effect;
use kinescan::app::diagnose::report::{Diagnosis, Verdict};
use kinescan::app::diagnose::{self, Request};
use kinescan::pipeline::config;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
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
    /// Share of the held-out excess chi2 (chi2/dof - 1) closed after the correction.
    pub closed: f64,
    /// The expected covariate is the leading one (`unexplained`).
    pub located_ok: bool,
}

/// The demo's city block scenario with `effects` injected, `seed`, simulated into `dir/survey`
/// with the demo pipeline beside it.
pub fn simulate_case(dir: &Path, effects: &str, seed: u64) {
    let text = kinescan::app::demo::SCENARIO.replace(
        "[nav_errors]",
        &format!("[effects]\n{effects}\n\n[nav_errors]"),
    );
    let mut sc = Scenario::parse(&text, "city block").unwrap();
    sc.seed = seed;
    let opts = SimOptions::default();
    simulate_scenario(&sc, &dir.join("survey"), &opts).unwrap();
    std::fs::write(dir.join("pipeline.toml"), kinescan::app::demo::PIPELINE).unwrap();
}

/// Diagnoses the survey in `dir`.
pub fn diagnose_dir(dir: &Path) -> kinescan::Result<Diagnosis> {
    let p = config::load(&dir.join("pipeline.toml"), &[])?;
    let req = Request {
        patches: dir.join("survey/patches.csv"),
        out_dir: dir.join("diagnosis"),
    };
    diagnose::run(&p, &req)
}

/// Scores diagnosis `d` against `expect`.
pub fn score(d: &Diagnosis, expect: &Expect) -> Score {
    let (b, a) = (d.gap.before.chi2_per_dof, d.gap.after.chi2_per_dof);
    let closed = if b > 1.0 {
        (b - a) / (b - 1.0)
    } else {
        f64::NAN
    };
    let mut s = Score {
        closed,
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
            for (e, x) in truth {
                if let (Some(est), Some(sig)) = (d.estimate.get(e.name()), d.sigma.get(e.name())) {
                    s.normalised_errors.push((est - x) / sig);
                }
            }
        }
        Expect::Nothing => s.verdict_ok = d.verdict == Verdict::None,
        Expect::Unexplained(cov) => {
            s.verdict_ok = d.verdict == Verdict::Unexplained && d.effects.is_empty();
            s.located_ok = d.located_in.first().map(String::as_str) == Some(*cov);
            s.closed = match &d.model_free {
                Some(m) => m.closed_fraction,
                None => 0.0,
            };
        }
    }
    s
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
    /// Share of expected estimates within 2 sigma of the truth.
    pub within_2_sigma: f64,
    /// Standard deviation of the normalised estimate errors.
    pub normalised_std: f64,
    /// Median share of the held-out excess chi2 closed.
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
            let d = match diagnose_dir(dir.path()) {
                Ok(d) => d,
                Err(e) => {
                    // Counted as a failure of every rate, with the reason printed.
                    println!("  {} seed {seed}: error: {e}", case.label);
                    return Score {
                        closed: f64::NAN,
                        ..Default::default()
                    };
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
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    let var =
        errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (errors.len().max(2) - 1) as f64;
    let mut closed: Vec<f64> = scores.iter().map(|s| s.closed).collect();
    closed.retain(|c| c.is_finite());
    closed.sort_by(f64::total_cmp);
    closed.push(f64::NAN); // the median of none is NaN
    Row {
        label: case.label.clone(),
        seeds: scores.len(),
        verdict: share(&|s| s.verdict_ok),
        named: share(&|s| s.named_ok),
        within_2_sigma: errors.iter().filter(|e| e.abs() < 2.0).count() as f64
            / errors.len().max(1) as f64,
        normalised_std: var.sqrt(),
        closed_median: closed[(closed.len() - 1) / 2],
        located: share(&|s| s.located_ok),
    }
}

/// Prints the table of rates.
pub fn print_table(rows: &[Row]) {
    println!(
        "| case | seeds | verdict | named | within 2 sigma | std(err/sigma) | closed (median) | located |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        println!(
            "| {} | {} | {:.0}% | {:.0}% | {:.0}% | {:.2} | {:.0}% | {:.0}% |",
            r.label,
            r.seeds,
            r.verdict * 100.0,
            r.named * 100.0,
            r.within_2_sigma * 100.0,
            r.normalised_std,
            r.closed_median * 100.0,
            r.located * 100.0
        );
    }
}

/// A catalogue case: `toml` injected in the simulator, `(effect, correction)` expected.
fn catalogue(label: &str, toml: &str, effect: Effect, correction: f64) -> Case {
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
            "lever_arm_error_m = [0.0, 0.0, 0.03]",
            Effect::LeverArmZ,
            0.03,
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
        // 50 ppm over 60 s: 3 ms, 3 cm at 11 m/s.
        catalogue(
            "clock_drift_ppm",
            "clock_drift_ppm = 50.0",
            Effect::ClockDrift,
            50.0,
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

/// No effect, effects outside the catalogue, and two at once.
pub fn other_cases() -> Vec<Case> {
    vec![
        Case {
            label: "none".into(),
            effects_toml: String::new(),
            expect: Expect::Nothing,
        },
        Case {
            // A clock running fast then slow: the time error is quadratic in time.
            label: "out: clock_drift_quadratic".into(),
            effects_toml: "clock_drift_quadratic_per_s = 2e-6".into(),
            expect: Expect::Unexplained("time_s"),
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

/// The acceptance table over `KINESCAN_ACCEPT_SEEDS` seeds (default 10) per case;
/// `KINESCAN_ACCEPT_CASES=label,label` runs some cases only.
#[test]
#[ignore = "measurement of the acceptance rates (prints, asserts nothing); minutes in release"]
fn full_acceptance_table() {
    let seeds: u64 = std::env::var("KINESCAN_ACCEPT_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    let only = std::env::var("KINESCAN_ACCEPT_CASES").unwrap_or_default();
    let rows: Vec<Row> = catalogue_cases()
        .iter()
        .chain(&other_cases())
        .filter(|c| only.is_empty() || only.split(',').any(|o| c.label == o))
        .map(|c| run_case(c, 1..seeds + 1))
        .collect();
    print_table(&rows);
}
