//! Each injected systematic effect moves the georeferenced points as its physics says. The
//! pipeline georeferences with the configured (nominal) parameters; the displacement
//! `D = pipeline point - true point` of every return is compared with a hand-derived
//! expectation built from the pipeline's own pose and beam and, for the time-like effects, the
//! true trajectory's velocity and rotation rate.

use crate::sim_support;
use kinescan::geo::ellipsoid::r_n_to_e;
use kinescan::geo::rotations::r_zyx;
use kinescan::sim::Scenario;
use kinescan::timing::{Mirror, MirrorDirection};
use kinescan::trajectory::{Trajectory, TrajectoryOptions};
use nalgebra::{Rotation3, Vector3};
use sim_support::*;

/// Runs `sc` and checks `|D - expect(pair)| <= rel |expect| + abs_m` for every return
/// (skipping those `skip` rejects); returns the largest |D| seen.
fn check(
    sc: &Scenario,
    name: &str,
    rel: f64,
    abs_m: f64,
    expect: impl Fn(&Pair, &Trajectory) -> Option<Vector3<f64>>,
) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    run(sc, dir.path(), 2);
    let truth = Trajectory::open(
        &dir.path().join("truth.sbet"),
        None,
        TrajectoryOptions::default(),
    )
    .unwrap();
    let pairs = georef_pairs(dir.path());
    assert!(pairs.len() > 50_000);
    let mut largest: f64 = 0.0;
    let mut checked = 0;
    for p in &pairs {
        let Some(e) = expect(p, &truth) else { continue };
        let d = p.x_e - p.truth_e;
        let miss = (d - e).norm();
        assert!(
            miss <= rel * e.norm() + abs_m,
            "{name}: profile {} beta {:.4}: D {d:?} expected {e:?} (miss {miss:.2e} m)",
            p.profile,
            p.beta_rad
        );
        crate::common::raise_max(&mut largest, d.norm());
        checked += 1;
    }
    println!("{name}: {checked} returns, largest displacement {largest:.4} m");
    assert!(checked > 50_000);
    largest
}

/// Mean true rotation-rate vector over `[t_a, t_b]` (ECEF, rad/s): the rotation of the
/// body over the interval divided by its length.
fn mean_rate(truth: &Trajectory, t_a: f64, t_b: f64) -> Vector3<f64> {
    let mut c = truth.cursor();
    let (a, b) = (c.at(t_a).unwrap(), c.at(t_b).unwrap());
    let d = Rotation3::from_matrix(&(rot(&b) * rot(&a).transpose()));
    d.scaled_axis() / (t_b - t_a)
}

/// `R_b^e` of a nav state.
fn rot(s: &kinescan::trajectory::NavSample) -> nalgebra::Matrix3<f64> {
    r_n_to_e(s.lat_rad, s.lon_rad) * s.q_b_to_n.to_rotation_matrix().matrix()
}

/// Displacement of a body-fixed point whose time the pipeline takes `dt` (s) off the truth:
/// the true body's motion over the shift, `r(t + dt) - r(t) + (R(t + dt) R(t)^T - I) lever`,
/// to first order `dt (v + omega x lever)`.
fn shift(truth: &Trajectory, p: &Pair, dt: f64) -> Vector3<f64> {
    let mut c = truth.cursor();
    let (a, b) = (c.at(p.t_s - dt).unwrap(), c.at(p.t_s).unwrap());
    let lever = p.truth_e - a.r_e_m;
    b.r_e_m - a.r_e_m + (rot(&b) * rot(&a).transpose()) * lever - lever
}

fn dist(p: &Pair) -> f64 {
    (p.truth_e - p.beam_e.0).norm()
}

#[test]
fn range_zero_and_scale_act_along_the_beam() {
    let mut sc = base();
    sc.effects.range_zero_error_m = Some(0.05);
    // Pipeline uses K - 0.05: the point comes 5 cm back along the beam (float noise only).
    check(&sc, "range_zero", 0.0, 1e-7, |p, _| {
        Some(-p.beam_e.1 * 0.05)
    });
    let mut sc = base();
    sc.effects.range_scale_ppm = Some(500.0);
    check(&sc, "range_scale", 0.0, 1e-7, |p, _| {
        Some(p.beam_e.1 * dist(p) * 500e-6)
    });
}

#[test]
fn lever_arm_and_boresight_errors_move_points_rigidly() {
    let mut sc = base();
    let dl = Vector3::new(0.03, -0.02, 0.05);
    sc.effects.lever_arm_error_m = Some([dl.x, dl.y, dl.z]);
    check(&sc, "lever_arm", 0.0, 1e-7, |p, _| Some(-(p.r_b_e * dl)));
    // Boresight angles off by db: the beam the pipeline uses is rotated by
    // R(b) R(b + db)^T against the true one, about the scanner's optical centre.
    let mut sc = base();
    let db = [0.02f64, -0.03, 0.05];
    sc.effects.boresight_error_deg = Some(db);
    let b = sc.scanner.boresight_deg.map(f64::to_radians);
    let r_cfg = r_zyx(b[0], b[1], b[2]);
    let r_true = r_zyx(
        b[0] + db[0].to_radians(),
        b[1] + db[1].to_radians(),
        b[2] + db[2].to_radians(),
    );
    check(&sc, "boresight", 0.0, 1e-7, |p, _| {
        let v_b = p.r_b_e.transpose() * (p.truth_e - p.beam_e.0);
        Some(p.r_b_e * (r_cfg * r_true.transpose() - nalgebra::Matrix3::identity()) * v_b)
    });
}

#[test]
fn encoder_offset_and_cone_error_tilt_the_beam() {
    // Encoder reads delta too much: D = d * delta * du/dbeta (first order; second-order
    // term d delta^2 / 2 < 2e-6 m at 80 m), plus the body's motion over the time error: the
    // true time follows the true angle beta - delta (docs/conventions.md §3), which wraps to
    // the end of the profile for returns recorded within delta after beta_start.
    let delta = 0.01f64.to_radians();
    let mut sc = base();
    sc.effects.encoder_offset_deg = Some(0.01);
    let alpha = sc.scanner.alpha0_deg.to_radians();
    let r_sb = {
        let b = sc.scanner.boresight_deg.map(f64::to_radians);
        r_zyx(b[0], b[1], b[2])
    };
    let mirror = Mirror {
        beta_start_rad: sc.scanner.beta_start_deg.to_radians(),
        direction: if sc.scanner.direction > 0 {
            MirrorDirection::Increasing
        } else {
            MirrorDirection::Decreasing
        },
    };
    let (t0, period) = (
        sc.start_time_s + sc.scanner.t0_offset_s,
        sc.scanner.period_s,
    );
    check(&sc, "encoder_offset", 0.0, 3e-6, |p, tr| {
        let du = Vector3::new(
            0.0,
            -alpha.cos() * p.beta_rad.cos(),
            -alpha.cos() * p.beta_rad.sin(),
        );
        let t_true = t0 + period * (p.profile as f64 + mirror.fraction(p.beta_rad - delta));
        Some(p.r_b_e * r_sb * du * (dist(p) * delta) + shift(tr, p, p.t_s - t_true))
    });
    // True cone angle alpha0 + delta: D = -d * delta * du/dalpha.
    let mut sc = base();
    sc.effects.cone_error_deg = Some(0.01);
    check(&sc, "cone", 0.0, 3e-6, |p, _| {
        let (sa, ca) = alpha.sin_cos();
        let du = Vector3::new(ca, sa * p.beta_rad.sin(), -sa * p.beta_rad.cos());
        Some(-(p.r_b_e * r_sb * du) * (dist(p) * delta))
    });
}

#[test]
fn attitude_latency_and_heading_bias_rotate_about_the_imu() {
    // Stamps lag the attitude by tau: the pipeline's attitude is the true one tau earlier,
    // D = (Rot(-tau * omega) - I) * lever of the point: the body turned by tau * omega,
    // omega the mean true rate over [t - tau, t]; first order, -tau * omega x lever.
    let tau = 0.005;
    let mut sc = base();
    sc.effects.attitude_latency_s = Some(tau);
    let big = check(&sc, "attitude_latency", 1e-4, 1e-6, |p, truth| {
        let back = Rotation3::from_scaled_axis(-mean_rate(truth, p.t_s - tau, p.t_s) * tau);
        Some(back * (p.truth_e - p.imu_e) - (p.truth_e - p.imu_e))
    });
    assert!(big > 0.002, "latency moved no point measurably ({big} m)");
    // Heading bias: rotation by +bias about the local down axis through the IMU.
    let bias = 0.05f64.to_radians();
    let mut sc = base();
    sc.effects.heading_bias_deg = Some(0.05);
    check(&sc, "heading_bias", 0.0, bias * bias * 100.0, |p, _| {
        let g = kinescan::geo::ellipsoid::ecef_to_geodetic(&p.imu_e);
        let down = r_n_to_e(g.lat_rad, g.lon_rad).column(2).into_owned();
        Some(down.cross(&(p.truth_e - p.imu_e)) * bias)
    });
}

#[test]
fn clock_effects_shift_points_along_the_motion() {
    let mut sc = base();
    let t0 = sc.start_time_s + sc.scanner.t0_offset_s;
    let period = sc.scanner.period_s;
    // The pipeline's time is off by dt = t_nominal - t_true: D is the body's true motion
    // over dt (float noise only, 1 um allowed).
    let nu = |p: &Pair| (p.t_s - t0) / period;
    sc.effects.clock_drift_ppm = Some(200.0);
    let big = check(&sc, "clock_drift", 1e-3, 1e-6, |p, tr| {
        Some(shift(tr, p, -period * 200e-6 * nu(p)))
    });
    assert!(big > 0.005);
    let mut sc = base();
    sc.effects.clock_drift_quadratic_per_s = Some(2e-5);
    check(&sc, "clock_quadratic", 1e-3, 1e-6, |p, tr| {
        let tau = period * nu(p);
        Some(shift(tr, p, -2e-5 * tau * tau))
    });
    let mut sc = base();
    sc.effects.mirror_wobble_s = Some([5e-4, 3.0]);
    check(&sc, "mirror_wobble", 1e-3, 1e-6, |p, tr| {
        let tau = period * nu(p);
        Some(shift(
            tr,
            p,
            -5e-4 * (std::f64::consts::TAU * tau / 3.0).sin(),
        ))
    });
}

#[test]
fn outage_drift_grows_inside_outages_only() {
    let mut sc = base();
    let (a, b) = (4.0, 10.0);
    sc.nav_errors.outages_s = vec![[a, b]];
    let drift = Vector3::new(0.02, -0.01, 0.015);
    sc.effects.outage_drift_mps = Some([drift.x, drift.y, drift.z]);
    let start = sc.start_time_s;
    let big = check(&sc, "outage_drift", 0.0, 1e-5, |p, _| {
        let tr = p.t_s - start;
        // Returns within one nav interval of an edge see the interpolated jump: skipped.
        if (tr - a).abs() < 0.006 || (tr - b).abs() < 0.006 {
            return None;
        }
        let g = kinescan::geo::ellipsoid::ecef_to_geodetic(&p.imu_e);
        let ramp = if tr > a && tr < b { tr - a } else { 0.0 };
        Some(r_n_to_e(g.lat_rad, g.lon_rad) * drift * ramp)
    });
    assert!(big > 0.1);
}

#[test]
fn position_latency_and_clock_offset_shift_along_the_motion() {
    // SBET positions lag the truth by tau_p: the pipeline's IMU is where the truth was tau_p
    // earlier, attitude unchanged: D = r(t - tau_p) - r(t). The pipeline interpolates the
    // shifted SBET samples linearly, the expectation interpolates the truth samples at
    // t - tau_p: each is off the true path by at most a dt^2 / 8, so they differ by at most
    // 2 * 2.5 m/s^2 (the base scenario's max_acc_mps2) * (5 ms)^2 / 8 = 1.6e-5 m.
    let tau_p = 0.004;
    let mut sc = base();
    sc.effects.position_latency_s = Some(tau_p);
    let big = check(&sc, "position_latency", 0.0, 1.6e-5, |p, tr| {
        let mut c = tr.cursor();
        Some(c.at(p.t_s - tau_p).unwrap().r_e_m - c.at(p.t_s).unwrap().r_e_m)
    });
    assert!(
        big > 0.02,
        "position latency moved no point measurably ({big} m)"
    );
    // True time = configured + c: the pipeline is c early (float noise only).
    let c = 0.003;
    let mut sc = base();
    sc.effects.clock_offset_s = Some(c);
    check(&sc, "clock_offset", 1e-3, 1e-6, |p, tr| {
        Some(shift(tr, p, -c))
    });
}

#[test]
fn uncatalogued_range_errors_act_along_the_beam() {
    // Cyclic in range: recorded rho = d + A sin(2 pi d / L): D = A sin(2 pi d / L) along the
    // beam (float noise only).
    let (a, l) = (0.02, 7.0);
    let mut sc = base();
    sc.effects.range_cyclic_m = Some([a, l]);
    check(&sc, "range_cyclic", 0.0, 1e-7, |p, _| {
        Some(p.beam_e.1 * a * (std::f64::consts::TAU * dist(p) / l).sin())
    });
    // Incidence: D = B sin^2(i) along the beam, 0 <= D.beam <= B.
    let b = 0.03;
    let mut sc = base();
    sc.effects.range_incidence_m = Some(b);
    check(&sc, "range_incidence", 0.0, 1e-7, |p, _| {
        let along = (p.x_e - p.truth_e).dot(&p.beam_e.1);
        assert!(
            (-1e-7..=b + 1e-7).contains(&along),
            "{along} m outside [0, {b}]"
        );
        Some(p.beam_e.1 * along)
    });
}

#[test]
fn catalogue_corrections_carry_the_signs_of_the_conventions() {
    let mut sc = base();
    let fx = &mut sc.effects;
    fx.heading_bias_deg = Some(0.05);
    fx.encoder_offset_deg = Some(0.01);
    fx.range_scale_ppm = Some(500.0);
    fx.lever_arm_error_m = Some([0.0, 0.03, 0.0]);
    let got: Vec<(&str, f64)> = fx
        .catalogue_corrections()
        .iter()
        .map(|c| (c.name, c.value))
        .collect();
    let scale = (1.0 / (1.0 + 500e-6) - 1.0) * 1e6;
    assert_eq!(
        got,
        vec![
            ("lever_arm_y_m", 0.03),
            ("range_scale_ppm", scale),
            ("encoder_offset_deg", -0.01),
            ("heading_offset_deg", -0.05)
        ]
    );
    assert!(!fx.has_uncatalogued());
    fx.range_cyclic_m = Some([0.01, 5.0]);
    assert!(fx.has_uncatalogued());
}

#[test]
fn attitude_latency_reprocessed_with_its_exact_value_lands_on_the_truth() {
    // 4 ms: not a multiple of the 5 ms nav step, so the SBET's stamps fall between the true
    // samples. Re-processed with latency.attitude_s = tau (conventions §2) the pipeline reads
    // the attitude at t + tau, which the simulator stamped there: what remains is the
    // interpolation of the resampled attitude, |delta omega| s (dt - s) / dt <= 0.8 ms times
    // the true rate's change at one 5 ms knot (the yaw rate ramps over 1 m of arc:
    // <= 0.02 rad/s here), i.e. < 2e-5 rad, 1.6 mm at the 80 m maximum range; below the
    // demo scanner's angle noise (0.002 deg = 3.5e-5 rad). Before the yaw rate was made
    // continuous, a corner's step of v / R left 1.5 cm.
    let tau = 0.004;
    let mut sc = base();
    sc.effects.attitude_latency_s = Some(tau);
    let dir = tempfile::tempdir().unwrap();
    run(&sc, dir.path(), 2);
    let largest = |tau_s: f64| {
        let pairs = georef_pairs_with_latency(dir.path(), tau_s);
        assert!(pairs.len() > 50_000);
        let mut m = 0.0;
        for p in &pairs {
            crate::common::raise_max(&mut m, (p.x_e - p.truth_e).norm());
        }
        m
    };
    let (before, after) = (largest(0.0), largest(tau));
    println!("attitude latency {tau} s: largest miss {before:.4} m, re-processed {after:.5} m");
    assert!(
        before > 0.05,
        "the latency moved no point measurably ({before} m)"
    );
    assert!(
        after < 1.6e-3,
        "re-processed with the exact latency: {after} m off the truth"
    );
}
