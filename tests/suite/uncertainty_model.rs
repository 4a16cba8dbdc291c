//! Acceptance of the error model at the equation level: the analytic Jacobian against finite
//! differences of the exact equation, the linear covariance against Monte Carlo, and the
//! calibration of the predicted 95% ellipsoid on simulated errors.

use kinescan::geo::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, r_n_to_e, Geodetic};
use kinescan::geo::projection::MapFrame;
use kinescan::geo::rotations::{r_zyx, zyx_angles};
use kinescan::trajectory::NavSigma;
use kinescan::uncertainty::model::{r_e_to_map_axes, LocalLevel, PointGeometry, N_INPUTS};
use kinescan::uncertainty::propagate::{covariance_of, Propagator, UncertaintyInputs};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A random but plausible-to-extreme return: any latitude below 85 deg, any attitude,
/// boresight and mirror angle, ranges 1-300 m, speeds to 30 m/s, rates to 1 rad/s.
fn random_geometry(rng: &mut ChaCha8Rng) -> PointGeometry {
    let mut u = |a: f64, b: f64| a + (b - a) * rng.random::<f64>();
    let g = Geodetic {
        lat_rad: u(-85.0, 85.0).to_radians(),
        lon_rad: u(-180.0, 180.0).to_radians(),
        h_m: u(-50.0, 3000.0),
    };
    let pi = std::f64::consts::PI;
    PointGeometry {
        r_e_m: geodetic_to_ecef(g),
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        r_b_to_n: r_zyx(u(-0.8, 0.8), u(-0.8, 0.8), u(0.0, 2.0 * pi)),
        v_n_mps: Vector3::new(u(-30.0, 30.0), u(-30.0, 30.0), u(-2.0, 2.0)),
        omega_b_radps: Vector3::new(u(-1.0, 1.0), u(-1.0, 1.0), u(-1.0, 1.0)),
        lever_arm_b_m: Vector3::new(u(-2.0, 2.0), u(-2.0, 2.0), u(-2.0, 2.0)),
        r_s_to_b: r_zyx(u(-pi, pi), u(-1.4, 1.4), u(-pi, pi)),
        alpha_rad: u(-0.3, 0.3),
        beta_rad: u(-pi, pi),
        range_m: u(1.0, 300.0),
        range_zero_m: u(-0.1, 0.1),
    }
}

/// Fourth-order central difference of column `k`. The step moves the point ~0.1 m but at most
/// 0.01 (rad, s or m): truncation ~h^4/30 relative for the rotations (3e-10) and ECEF rounding
/// (1e-9 m over steps of >= 1 mm of motion) stay far below 1e-6.
fn fd_column(g: &PointGeometry, k: usize, scale: f64) -> Vector3<f64> {
    let h = crate::common::min_of([0.1 / crate::common::max_of([scale, 1e-3]), 0.01]);
    let at = |x: f64| {
        let mut e = [0.0; N_INPUTS];
        e[k] = x;
        g.point_e(&e)
    };
    (at(-2.0 * h) - at(2.0 * h) + (at(h) - at(-h)) * 8.0) / (12.0 * h)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Every Jacobian column agrees with finite differences of the exact equation to 1e-6
    /// relative (the acceptance bound).
    #[test]
    fn jacobian_matches_finite_differences(seed in any::<u64>()) {
        let g = random_geometry(&mut ChaCha8Rng::seed_from_u64(seed));
        let j = g.jacobian_e();
        for k in 0..N_INPUTS {
            let col = j.column(k).into_owned();
            let fd = fd_column(&g, k, col.norm());
            let rel = (col - fd).norm() / col.norm();
            prop_assert!(rel <= 1e-6, "input {k}: relative error {rel:e}, J {col:?}, fd {fd:?}");
        }
    }

    /// The pipeline's fast propagation (body-frame sums, diagonal only) gives the reference
    /// `J Q J^T` diagonal and group variances to round-off (1e-12 relative of the total), in
    /// UTM axes, for random geometries and random sigmas of every input.
    #[test]
    fn propagator_equals_the_reference(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let g = random_geometry(&mut rng);
        let mut u = |a: f64| a * rng.random::<f64>();
        let inputs = UncertaintyInputs {
            sigma_lever_arm_b_m: Vector3::new(u(0.05), u(0.05), u(0.05)),
            sigma_boresight_rad: Vector3::new(u(0.01), u(0.01), u(0.01)),
            sigma_alpha_rad: u(0.01),
            sigma_beta_rad: u(0.01),
            sigma_range_m: u(0.05),
            sigma_range_zero_m: u(0.05),
            clock_covariance_s2: Matrix3::from_diagonal(&Vector3::new(u(1e-6), u(1e-12), 0.0))
                .fixed_view::<2, 2>(0, 0)
                .into_owned(),
            sigma_attitude_latency_s: u(0.005),
        };
        let nav = NavSigma {
            pos_ned_m: Vector3::new(u(0.1), u(0.1), u(0.1)),
            att_rph_rad: Vector3::new(u(1e-3), u(1e-3), u(1e-3)),
        };
        let dt_dclock = [1.0, u(1e5)];
        let zone = ((g.lon_rad.to_degrees() + 180.0) / 6.0).floor() as u8 % 60 + 1;
        let frame = MapFrame::utm(zone, g.lat_rad >= 0.0).unwrap();
        let local = LocalLevel::at(g.lat_rad, g.lon_rad, g.h_m);
        let terms = g.terms(local.r_n_to_e);
        let out = r_e_to_map_axes(&frame, &terms.point_e(&g.r_e_m));
        let j = g.jacobian_in_axes(&out, &local.dtheta_per_m, &terms);
        let want = covariance_of(&j, &inputs.sigmas(&nav, dt_dclock)).axes();
        let fast = Propagator::new(inputs, true, g.lever_arm_b_m, g.r_s_to_b).variances(
            &(out * local.r_n_to_e),
            &local.dtheta_per_m,
            &terms,
            &g.omega_b_radps,
            &g.v_n_mps,
            &nav,
            dt_dclock,
        );
        let total = want.var_m2.sum();
        prop_assert!(crate::common::max_abs((fast.var_m2 - want.var_m2).iter().copied()) <= 1e-12 * total,
            "fast {:?} reference {:?}", fast.var_m2, want.var_m2);
        for (a, b) in fast.group_variance_m2.iter().zip(&want.group_variance_m2) {
            prop_assert!((a - b).abs() <= 1e-12 * total, "groups fast {a} reference {b}");
        }
    }
}

/// A survey-like geometry (van, mid-latitude, turning) with sigmas inflated so every group
/// matters: position 3 cm, attitude 0.02 deg, lever 2 cm, boresight 0.05 deg, angles
/// 0.01 deg, range 1 cm, K 1 cm, clock 2 ms, latency 2 ms.
fn survey_case(rng: &mut ChaCha8Rng) -> (PointGeometry, [f64; N_INPUTS]) {
    let mut g = random_geometry(rng);
    let heading = 7.0 * rng.random::<f64>();
    g.r_b_to_n = r_zyx(
        0.1 * (rng.random::<f64>() - 0.5),
        0.1 * (rng.random::<f64>() - 0.5),
        heading,
    );
    g.range_m = 2.0 + 118.0 * rng.random::<f64>();
    g.omega_b_radps *= 0.3;
    let d = 1f64.to_radians();
    let sigmas = [
        0.03,
        0.03,
        0.04,
        0.02 * d,
        0.02 * d,
        0.04 * d,
        0.02,
        0.02,
        0.02,
        0.05 * d,
        0.05 * d,
        0.05 * d,
        0.01 * d,
        0.01 * d,
        0.01,
        0.01,
        0.002,
        0.002,
    ];
    (g, sigmas)
}

fn draw(rng: &mut ChaCha8Rng, sigmas: &[f64; N_INPUTS]) -> [f64; N_INPUTS] {
    std::array::from_fn(|k| {
        let z: f64 = StandardNormal.sample(rng);
        z * sigmas[k]
    })
}

/// Linear sigma per ECEF axis against the sample sigma of 1e5 draws of all inputs through the
/// exact equation, on 5 geometries: within 2% (the acceptance bound). Sampling error of a
/// sigma from 1e5 draws is 1/sqrt(2e5) = 0.22%, so 2% is a 9-sigma bound: a failure is a model
/// error, not chance.
#[test]
fn linear_sigma_matches_monte_carlo() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let draws = 100_000;
    let mut worst: f64 = 0.0;
    for case in 0..5 {
        let (g, sigmas) = survey_case(&mut rng);
        let lin = covariance_of(&g.jacobian_e(), &sigmas).cov_m2;
        let nominal = g.point_e(&[0.0; N_INPUTS]);
        let mut sum = Vector3::zeros();
        let mut sq = Vector3::zeros();
        for _ in 0..draws {
            let d = g.point_e(&draw(&mut rng, &sigmas)) - nominal;
            sum += d;
            sq += d.component_mul(&d);
        }
        let n = draws as f64;
        let var_mc = sq / n - (sum / n).component_mul(&(sum / n));
        for k in 0..3 {
            let ratio = (var_mc[k] / lin[(k, k)]).sqrt();
            crate::common::raise_max(&mut worst, (ratio - 1.0).abs());
            assert!(
                (ratio - 1.0).abs() <= 0.02,
                "case {case} axis {k}: MC/linear sigma {ratio}"
            );
        }
    }
    println!("linear vs Monte Carlo sigma: worst relative difference {worst:.4}");
}

/// Calibration: 1e5 simulated returns, each with its own geometry and one draw of every error
/// from exactly its sigma. The truth is the equation at the true inputs; the survey computes
/// the point and its covariance at the measured (true + error) inputs. The fraction of true
/// errors inside the 95% ellipsoid (chi-square 3 dof, 7.8147) must be in [94%, 96%] (standard
/// error 0.07%: 14 sigma of margin), and the whitened errors must have unit variance within 3%
/// (standard error 0.45% per component).
#[test]
fn predicted_ellipsoid_is_calibrated() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = 100_000;
    let mut inside = 0usize;
    let mut sq = Vector3::zeros();
    for _ in 0..n {
        let (truth, sigmas) = survey_case(&mut rng);
        let e = draw(&mut rng, &sigmas);
        let measured = perturbed(&truth, &e);
        let err = measured.point_e(&[0.0; N_INPUTS]) - truth.point_e(&[0.0; N_INPUTS]);
        let cov: Matrix3<f64> = covariance_of(&measured.jacobian_e(), &sigmas).cov_m2;
        let l = cov.cholesky().expect("positive definite").l();
        let w = l.solve_lower_triangular(&err).expect("invertible");
        inside += usize::from(w.norm_squared() <= 7.8147);
        sq += w.component_mul(&w);
    }
    let frac = inside as f64 / n as f64;
    let var = sq / n as f64;
    println!(
        "calibration: {:.4} inside the 95% ellipsoid, whitened variances {var:?}",
        frac
    );
    assert!((0.94..=0.96).contains(&frac), "fraction inside {frac}");
    for k in 0..3 {
        assert!(
            (var[k] - 1.0).abs() <= 0.03,
            "whitened variance {k}: {}",
            var[k]
        );
    }
}

/// The measured geometry: true inputs plus errors. Errors of the IMU position, clock and
/// latency move the measured state exactly as the equation does.
fn perturbed(t: &PointGeometry, e: &[f64; N_INPUTS]) -> PointGeometry {
    let dt = e[16];
    let d_n = Vector3::new(e[0], e[1], e[2]) + t.v_n_mps * dt;
    let r_e = t.r_e_m + r_n_to_e(t.lat_rad, t.lon_rad) * d_n;
    let g = ecef_to_geodetic(&r_e);
    let turn = nalgebra::Rotation3::new(t.omega_b_radps * (dt + e[17]));
    let add = |r: &Matrix3<f64>, d: [f64; 3]| {
        let (x, y, z) = zyx_angles(r);
        r_zyx(x + d[0], y + d[1], z + d[2])
    };
    PointGeometry {
        r_e_m: r_e,
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        r_b_to_n: add(&t.r_b_to_n, [e[3], e[4], e[5]]) * turn.matrix(),
        lever_arm_b_m: t.lever_arm_b_m + Vector3::new(e[6], e[7], e[8]),
        r_s_to_b: add(&t.r_s_to_b, [e[9], e[10], e[11]]),
        alpha_rad: t.alpha_rad + e[12],
        beta_rad: t.beta_rad + e[13],
        range_m: t.range_m + e[14],
        range_zero_m: t.range_zero_m + e[15],
        ..*t
    }
}
