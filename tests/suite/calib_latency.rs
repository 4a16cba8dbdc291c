//! Latency calibration acceptance on the rotating-table scenario.

use kinescan::calib::latency::{estimate_latency, read_passes, LatencyReport};
use kinescan::calib::sim_table::{simulate_table, TableScenario};

fn run(sc: &TableScenario) -> LatencyReport {
    let data = simulate_table(sc).unwrap();
    estimate_latency(&data, &sc.calibration_setup()).unwrap()
}

fn print_table(r: &LatencyReport) {
    println!("omega_deg_s  latency_ms  sigma_ms  sigma_centre_um(+/-)  n(+/-)");
    for s in &r.speeds {
        println!(
            "{:>6}  {:>9.4}  {:>7.4}  {:>6.1}/{:<6.1}  {}/{}",
            s.rate_deg_s,
            s.latency_s * 1e3,
            s.sigma_latency_s * 1e3,
            s.sigma_centre_plus_m * 1e6,
            s.sigma_centre_minus_m * 1e6,
            s.n_used_plus,
            s.n_used_minus
        );
    }
    println!(
        "combined {:.4} +- {:.4} ms, chi2 {:.2} / {}",
        r.latency_s * 1e3,
        r.sigma_latency_s * 1e3,
        r.chi2,
        r.dof
    );
}

/// Paper 000's Table 2 (Seube et al. 2012, /work/shared/papers/000_*.txt): sphere centre STD
/// (1e-5 m) and latency STD (ms) at 2, 4, 6, 10, 14, 18 deg/s.
const PAPER_CENTRE_STD_UM: [f64; 6] = [23.3, 31.2, 40.4, 52.2, 61.4, 70.3];
const PAPER_LATENCY_STD_MS: [f64; 6] = [0.49, 0.33, 0.25, 0.19, 0.12, 0.09];

/// The paper's experiment (Table 2) against the table's values: the simulated table (5 mm
/// per-return noise, docs/calibration.md) gives centre STDs at 0.7-0.9 of the paper's at every
/// speed (measured 0.79-0.84: the noise was chosen to land near 80 %), a latency STD at most
/// the paper's at every speed and within 20 % of it at 18 deg/s (0.087 vs 0.09 ms; our STD
/// falls as 1/sqrt(omega), the paper's faster at low speed), and the paper's total latency,
/// 4.21 ms, recovered: per speed within 4 of its own sigmas (a 4-sigma band is exceeded by
/// chance with p = 6e-5 per speed), combined within 4 sigma with a sigma under 0.1 ms. The
/// sigma falls with speed.
#[test]
fn table_two_reproduction() {
    let sc = TableScenario::default();
    let r = run(&sc);
    print_table(&r);
    let rates: Vec<f64> = r.speeds.iter().map(|s| s.rate_deg_s).collect();
    assert_eq!(rates, [2.0, 4.0, 6.0, 10.0, 14.0, 18.0], "Table 2's speeds");
    for (k, s) in r.speeds.iter().enumerate() {
        let centre_um =
            ((s.sigma_centre_plus_m.powi(2) + s.sigma_centre_minus_m.powi(2)) / 2.0).sqrt() * 1e6;
        let ratio = centre_um / PAPER_CENTRE_STD_UM[k];
        assert!(
            (0.7..=0.9).contains(&ratio),
            "{} deg/s: centre STD {centre_um:.1} um vs the paper's {} ({ratio:.2})",
            s.rate_deg_s,
            PAPER_CENTRE_STD_UM[k]
        );
        let latency_ms = s.sigma_latency_s * 1e3;
        assert!(
            latency_ms > 0.0 && latency_ms <= PAPER_LATENCY_STD_MS[k],
            "{} deg/s: latency STD {latency_ms} ms vs the paper's {}",
            s.rate_deg_s,
            PAPER_LATENCY_STD_MS[k]
        );
    }
    let at_18 = r.speeds[5].sigma_latency_s * 1e3 / PAPER_LATENCY_STD_MS[5];
    assert!(
        (0.8..=1.2).contains(&at_18),
        "18 deg/s: {at_18:.2} of the paper's STD"
    );
    assert_eq!(sc.latency_ms, 4.21, "the paper's total latency");
    assert!(
        r.sigma_latency_s > 0.0 && r.sigma_latency_s < 1e-4,
        "{}",
        r.sigma_latency_s
    );
    let truth = sc.latency_ms * 1e-3;
    for s in &r.speeds {
        assert!(
            (s.latency_s - truth).abs() < 4.0 * s.sigma_latency_s,
            "{} deg/s",
            s.rate_deg_s
        );
    }
    assert!(r
        .speeds
        .windows(2)
        .all(|w| w[1].sigma_latency_s < w[0].sigma_latency_s));
    assert!((r.latency_s - truth).abs() < 4.0 * r.sigma_latency_s);
}

/// Bias and sigma at 18 deg/s over 300 seeds at the paper's noise level.
#[test]
fn bias_and_sigma_at_18_deg_s_over_seeds() {
    // 300 seeds: the standard error of the mean is sigma/sqrt(300) = 0.005 ms for sigma ~0.087 ms,
    // so the 0.02 ms bias bound is 4 standard errors; the standard error of a sample sigma is
    // sigma/sqrt(2*300) = 4.1 %, so the 20 % predicted/empirical band is 4.9 standard errors and
    // the 0.1 ms sigma bound (15 % above 0.087 ms) is 3.5.
    const SEEDS: u64 = 300;
    let truth_ms = 4.21;
    let (mut est, mut pred) = (Vec::new(), Vec::new());
    for seed in 0..SEEDS {
        let sc = TableScenario {
            seed,
            speeds_deg_s: vec![18.0],
            ..TableScenario::default()
        };
        let r = run(&sc);
        est.push(r.latency_s * 1e3);
        pred.push(r.sigma_latency_s * 1e3);
    }
    let n = SEEDS as f64;
    let mean = est.iter().sum::<f64>() / n;
    let emp = (est.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let pred_rms = (pred.iter().map(|p| p * p).sum::<f64>() / n).sqrt();
    println!(
        "18 deg/s over {SEEDS} seeds: bias {:.4} ms, empirical sigma {emp:.4} ms, predicted {pred_rms:.4} ms, ratio {:.3}",
        mean - truth_ms,
        pred_rms / emp
    );
    assert!((mean - truth_ms).abs() <= 0.02);
    assert!(emp <= 0.1 && pred_rms <= 0.1);
    assert!((pred_rms / emp - 1.0).abs() < 0.2);
}

/// Any rotation axis: a tilted table axis, an IMU mounted askew on it, the optical centre off
/// the axis, a non-identity boresight and a stand under the sphere (returns off the sphere
/// inside the gate, removed by the robust fit).
#[test]
fn tilted_axis_offset_scanner_and_stand() {
    let sc = TableScenario {
        seed: 7,
        speeds_deg_s: vec![6.0, 18.0],
        table_axis_n: [0.2, -0.3, 1.0],
        imu_mount_deg: [3.0, -5.0, 40.0],
        boresight_deg: [1.0, -2.0, 0.5],
        lever_arm_b_m: [0.05, -0.03, -0.1],
        stand_radius_m: 0.015,
        ..TableScenario::default()
    };
    let r = run(&sc);
    print_table(&r);
    let rejected: usize = r
        .speeds
        .iter()
        .map(|s| s.n_rejected_plus + s.n_rejected_minus)
        .sum();
    assert!(
        rejected > 100,
        "the stand must produce returns to reject ({rejected})"
    );
    // 4 sigma: chance exceedance p = 6e-5.
    assert!((r.latency_s - sc.latency_ms * 1e-3).abs() < 4.0 * r.sigma_latency_s);
}

#[test]
fn zero_table_speed_and_too_few_returns_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("passes.csv");
    std::fs::write(
        &p,
        "pass,t_start_s,t_end_s,table_rate_deg_s\n0,1,2,6\n1,2,3,0\n",
    )
    .unwrap();
    let e = read_passes(&p).unwrap_err().to_string();
    assert!(
        e.contains("passes.csv") && e.contains("line 3") && e.contains("zero table speed"),
        "{e}"
    );

    // A sphere seen by fewer than 20 returns per direction: 10 profiles/s at 18 deg/s, 2 deg
    // mirror steps and a single pass each way leave about 12.
    let sc = TableScenario {
        speeds_deg_s: vec![18.0],
        passes_per_direction: 1,
        profile_rate_hz: 10.0,
        beta_step_deg: 2.0,
        ..TableScenario::default()
    };
    let data = simulate_table(&sc).unwrap();
    let e = estimate_latency(&data, &sc.calibration_setup())
        .unwrap_err()
        .to_string();
    assert!(e.contains("18 deg/s") && e.contains("at least 20"), "{e}");
}

/// A latency already applied to the stream and a free sphere radius: the total is recovered.
#[test]
fn applied_latency_and_free_radius() {
    let sc = TableScenario {
        seed: 3,
        speeds_deg_s: vec![10.0, 18.0],
        ..TableScenario::default()
    };
    let data = simulate_table(&sc).unwrap();
    let mut setup = sc.calibration_setup();
    setup.applied_latency_s = 0.0035;
    setup.sphere_radius = kinescan::calib::sphere::SphereRadius::Free;
    // With a free radius the gate is the whole distance from the approximate centre.
    setup.sphere_gate_n_m = setup.sphere_gate_n_m.map(|(c, _)| (c, 0.15));
    let r = estimate_latency(&data, &setup).unwrap();
    print_table(&r);
    // 4 sigma: chance exceedance p = 6e-5.
    assert!((r.latency_s - sc.latency_ms * 1e-3).abs() < 4.0 * r.sigma_latency_s);
    assert!(r
        .speeds
        .iter()
        .all(|s| (s.radius_plus_m - 0.1).abs() < 1e-3));
}
