//! Ties the simulator's forward model to the pipeline's inverse: with every error source off,
//! georeferencing the simulated raw data with the pipeline's functions reproduces the true
//! coordinates to <= 0.1 mm for every return. Also: determinism across thread counts, and
//! refusal of bad scenario files with the key named.

use crate::sim_support;
use sim_support::*;

#[test]
fn error_free_survey_georeferences_onto_truth() {
    for pps in [false, true] {
        let mut sc = base();
        sc.scanner.pps_time_tags = pps;
        let dir = tempfile::tempdir().unwrap();
        run(&sc, dir.path(), 2);
        let pairs = georef_pairs(dir.path());
        assert!(pairs.len() > 50_000, "only {} valid returns", pairs.len());
        let worst = crate::common::max_of(pairs.iter().map(|p| (p.x_e - p.truth_e).norm()));
        println!(
            "pps {pps}: {} returns, worst |pipeline - truth| = {worst:.3e} m",
            pairs.len()
        );
        // The acceptance bound; float round-off alone is ~1e-9 m here.
        assert!(worst <= 1e-4, "worst error {worst} m");
    }
}

#[test]
fn same_seed_same_bytes_for_one_or_two_threads() {
    let mut sc = base();
    sc.duration_s = 6.0;
    sc.scanner.sigma_range_m = 0.01;
    sc.scanner.sigma_angle_deg = 0.01;
    sc.scanner.dropout_probability = 0.05;
    sc.nav_errors.position_sigma_m = [0.02; 3];
    sc.nav_errors.attitude_sigma_deg = [0.01; 3];
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    run(&sc, a.path(), 1);
    run(&sc, b.path(), 2);
    let mut names: Vec<_> = std::fs::read_dir(a.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert!(names.len() >= 8, "{names:?}");
    for n in names {
        let x = std::fs::read(a.path().join(&n)).unwrap();
        let y = std::fs::read(b.path().join(&n)).unwrap();
        assert!(x == y, "{n:?} differs between 1 and 2 threads");
    }
    // A different seed must change the noise.
    sc.seed += 1;
    let c = tempfile::tempdir().unwrap();
    run(&sc, c.path(), 2);
    let p = |d: &std::path::Path| std::fs::read(d.join("profiles.bin")).unwrap();
    assert_ne!(p(a.path()), p(c.path()));
}

#[test]
fn bad_scenarios_are_refused_with_the_key_named() {
    let cases = [
        (
            "[scanner]\nperiod_s = 0.02",
            "[scanner]\nperiod_s = -0.02",
            "scanner.period_s",
        ),
        (
            "[scanner]\nperiod_s = 0.02",
            "[scanner]\nperiod_s = 0.02\nmirror_speed = 3",
            "scanner.mirror_speed",
        ),
        (
            "duration_s = 14.0",
            "duration_s = 14.0\ncolour = 1",
            "colour",
        ),
        (
            "max_speed_mps = 11.0",
            "max_speed_mps = 35.0",
            "route.max_speed_mps",
        ),
        (
            "[scanner]\nperiod_s = 0.02",
            "[scanner]\nperiod_s = 0.02\nmax_range_m = -5.0",
            "scanner.max_range_m",
        ),
        (
            "points_per_profile = 300",
            "points_per_profile = 0",
            "scanner.points_per_profile",
        ),
        (
            "[route]\n",
            "[effects]\nlatency_s = 0.01\n[route]\n",
            "effects.latency_s",
        ),
        (
            "max_speed_mps = 11.0",
            "max_speed_mps = \"fast\"",
            "route.max_speed_mps",
        ),
    ];
    for (from, to, key) in cases {
        assert!(BASE.contains(from), "{from}");
        let text = BASE.replacen(from, to, 1);
        let err = kinescan::sim::Scenario::parse(&text, "bad.toml").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains(&format!("key `{key}`")), "{key}: {msg}");
        assert!(msg.starts_with("bad.toml"), "{msg}");
    }
}

/// `SimOptions::duration_s` replaces the duration of an already loaded scenario too, not only
/// of one `simulate` loads (a bench once got the scenario's own length for every size it asked
/// for): the same survey as the scenario edited to that duration, profile for profile and
/// return for return; a bad duration is refused naming the option.
#[test]
fn the_duration_option_replaces_a_loaded_scenario_s() {
    use kinescan::sim::{simulate_scenario, SimOptions};
    let dir = tempfile::tempdir().unwrap();
    let sc = sim_support::base();
    let opts = |d: f64| SimOptions {
        duration_s: Some(d),
        ..Default::default()
    };
    let half_s = sc.duration_s / 2.0;
    let short = simulate_scenario(&sc, &dir.path().join("a"), &opts(half_s)).unwrap();
    let mut edited = sc.clone();
    edited.duration_s = half_s;
    let by_hand =
        simulate_scenario(&edited, &dir.path().join("c"), &SimOptions::default()).unwrap();
    let full = simulate_scenario(&sc, &dir.path().join("d"), &SimOptions::default()).unwrap();
    assert_eq!(
        (short.profiles, short.returns),
        (by_hand.profiles, by_hand.returns)
    );
    assert!(short.profiles < full.profiles, "{short:?} {full:?}");
    let e = simulate_scenario(&sc, &dir.path().join("b"), &opts(-1.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--duration-s"), "{e}");
}
