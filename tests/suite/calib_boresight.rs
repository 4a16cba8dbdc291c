//! Tripod boresight acceptance: Monte Carlo of paper 002's simulation.

use kinescan::calib::boresight::estimate_boresight;
use kinescan::calib::sim_tripod::{
    run_monte_carlo, simulate_sites, MonteCarloSummary, SiteRotation, TripodScenario,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// 1000 trials per noise level: the standard error of a sample sigma is sigma/sqrt(2000) = 2.2 %,
/// so the 20 % predicted/empirical band is 9 standard errors; the mean error is tested against
/// [`BIAS_Z`] standard errors (sigma/sqrt(1000)) per angle.
const TRIALS: usize = 1000;

/// The bias checks: 3 angles in each of the 4 Monte Carlo runs ([`check`]'s callers), 12 in
/// all. At 2 standard errors each, an unbiased estimator fails at least one of the 12 with
/// probability 1 - 0.9545^12 = 43 % (passing seeds would have to be picked). Bonferroni at a
/// family-wise false-failure probability of 1 %: two-sided 0.01 / 12 per check, z = 3.34.
/// A bias of 0.15 sigma (4.7 standard errors) fails with probability 0.92 per angle.
const BIAS_Z: f64 = 3.34;

/// Cramer-Rao bound (1 sigma, deg, at 1 mm centre noise; scales with the noise) of the default
/// scenario's geometry with the paper's sites composed the conventions' way (`zyx`) and in the order of
/// the paper's printed matrix (`xyz`), from the independent `tests/oracle/boresight_crb.py`.
pub(crate) const BOUND_ZYX_1MM_DEG: [f64; 3] = [0.07589, 0.02814, 0.85173];
const BOUND_XYZ_1MM_DEG: [f64; 3] = [0.0254, 0.03448, 0.03822];

/// Unbiasedness and predicted covariance (issue acceptance) and a printout of the error levels
/// against the paper's (not asserted: no physically consistent reading of the paper's geometry
/// reaches them, see docs/calibration.md).
fn check(mc: &MonteCarloSummary, paper_deg: [f64; 3]) {
    println!(
        "sigma_centre {} m: mean {:.5?} sd {:.5?} pred {:.5?} p99 {:.5?} (paper {paper_deg:?}) max {:.5?} conv<=5 {} max it {}",
        mc.sigma_centre_m, mc.mean_error_deg, mc.empirical_sigma_deg, mc.predicted_sigma_deg,
        mc.p99_abs_error_deg, mc.max_abs_error_deg, mc.share_converged_within_5, mc.max_iterations
    );
    for k in 0..3 {
        let se = mc.empirical_sigma_deg[k] / (mc.trials as f64).sqrt();
        assert!(
            mc.mean_error_deg[k].abs() < BIAS_Z * se,
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

/// The estimator is efficient: its empirical sigma is the Cramer-Rao bound. In the linear
/// regime the ratio is 1 up to sampling: 10 % is 4.5 standard errors of a 1000-trial sigma.
fn attains_bound(mc: &MonteCarloSummary, bound_1mm_deg: [f64; 3]) {
    for (k, b) in bound_1mm_deg.iter().enumerate() {
        let bound = b * mc.sigma_centre_m / 1e-3;
        let ratio = mc.empirical_sigma_deg[k] / bound;
        assert!(
            (ratio - 1.0).abs() < 0.1,
            "angle {k}: empirical/bound {ratio}"
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
    attains_bound(&mc, BOUND_ZYX_1MM_DEG);
    // Issue acceptance: <= 5 iterations in >= 99 % of trials. (At 1 cm this reading of the
    // sites gives heading errors of ~9 deg sigma, far outside the linear regime; there ~99 %
    // converge within 5: printed by `monte_carlo_1_cm`, not asserted.)
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

/// The paper's sites composed in the order of its printed matrix (`Rx Ry Rz`): the relative
/// rotations between sites are no longer all within 5.4 deg of the body z axis, the heading is
/// observable, and both noise levels stay in the linear regime: unbiased, predicted = empirical
/// = the bound, <= 5 iterations in >= 99 % of trials (the acceptance) at 1 mm and 1 cm.
#[test]
fn paper_site_order_xyz() {
    for (seed, sigma, paper) in [(21, 0.001, [0.01, 0.01, 0.05]), (22, 0.01, [0.1, 0.1, 0.5])] {
        let sc = TripodScenario {
            sigma_centre_m: sigma,
            seed,
            site_rotation: SiteRotation::Xyz,
            ..TripodScenario::default()
        };
        let mc = run_monte_carlo(&sc, TRIALS).unwrap();
        check(&mc, paper);
        attains_bound(&mc, BOUND_XYZ_1MM_DEG);
        assert!(mc.share_converged_within_5 >= 0.99);
    }
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
    sites
        .iter_mut()
        .for_each(|s| s.cov_centre_s_m2 = [nalgebra::Matrix2::identity() * 1e-6; 3]);
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
