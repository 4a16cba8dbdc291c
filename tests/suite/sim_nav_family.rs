//! The navigation error family of the simulator (docs/simulator.md, "Navigation errors"): each
//! model's injected errors (SBET minus truth) have the standard deviation the SMRMSG states
//! (divided by `smrmsg_factor`) and the autocorrelation of the model; `zero_rate_fields`
//! zeroes exactly the SBET's rate and acceleration fields; `vehicle.vibration_hz` puts the
//! roll and pitch vibration at that frequency. Every run is short (a few seconds in all): one
//! return per profile, no truth points.

use crate::sim_support;
use kinescan::io::sbet::SbetFile;
use kinescan::io::smrmsg::{SmrmsgFile, RAD_PER_ARCMIN};
use kinescan::sim::scenario::NavErrorModel;
use kinescan::sim::Scenario;
use kinescan::testing::max_abs;
use sim_support::*;
use std::path::Path;

const SIGMA_POS_M: [f64; 3] = [0.02, 0.03, 0.05];
const SIGMA_ATT_DEG: [f64; 3] = [0.005, 0.007, 0.012];

/// The six configured sigmas (m, rad).
fn sigmas() -> [f64; 6] {
    let a = SIGMA_ATT_DEG.map(f64::to_radians);
    [
        SIGMA_POS_M[0],
        SIGMA_POS_M[1],
        SIGMA_POS_M[2],
        a[0],
        a[1],
        a[2],
    ]
}

/// The base scenario made cheap (one return per profile, no truth points) with errors on.
fn nav_scenario(seed: u64, duration_s: f64) -> Scenario {
    let mut sc = base();
    sc.seed = seed;
    sc.duration_s = duration_s;
    sc.scanner.period_s = 1.0 / 33.0;
    sc.scanner.points_per_profile = 1;
    sc.output.truth_points = false;
    sc.nav_errors.position_sigma_m = SIGMA_POS_M;
    sc.nav_errors.attitude_sigma_deg = SIGMA_ATT_DEG;
    sc
}

/// SMRMSG records as (time since start, the six stated sigmas in m and rad).
fn stated(dir: &Path) -> Vec<(f64, [f64; 6])> {
    let smr = SmrmsgFile::open(&dir.join("trajectory.smrmsg")).unwrap();
    let t0 = smr.time_s(0);
    (0..smr.len())
        .map(|j| {
            let r = smr.record(j).to_array();
            let s = std::array::from_fn(|i| {
                r[smrmsg_col(i)] * if i < 3 { 1.0 } else { RAD_PER_ARCMIN }
            });
            (r[0] - t0, s)
        })
        .collect()
}

/// Pooled lag-`lag` autocorrelation of unit series.
fn autocorrelation(series: &[Vec<f64>], lag: usize) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for z in series {
        num += z.windows(lag + 1).map(|w| w[0] * w[lag]).sum::<f64>();
        den += z[..z.len() - lag].iter().map(|v| v * v).sum::<f64>();
    }
    num / den
}

/// Two Gauss-Markov processes (0.25 s and 2.5 s, half the variance each) stated 1.5x in the
/// SMRMSG. Two seeds x 500 s x 6 components.
///
/// Tolerances: for a stationary process observed over T, the variance estimate and the lag-L
/// autocorrelation have standard errors at most sqrt(2 I / T), I = integral of rho^2 over the
/// real line = 2 [(1-s)^2 t1/2 + s^2 t2/2 + 2 s (1-s) t1 t2/(t1+t2)] = 0.914 s here: 0.060 per
/// component of 500 s, 0.017 over the 12 pooled. The bounds (0.07) sit at 4 standard errors;
/// one process of 0.25 s would give 0.37 and 0.00 at the two lags instead of 0.64 and 0.18.
#[test]
fn two_gauss_markov_errors_have_the_mixture_statistics_and_the_factor_scales_the_smrmsg_only() {
    const T1: f64 = 0.25;
    const T2: f64 = 2.5;
    const SHARE: f64 = 0.5;
    const FACTOR: f64 = 1.5;
    let sigma = sigmas();
    let mut series = vec![];
    let mut dt = 0.0;
    for seed in [11, 12] {
        let mut sc = nav_scenario(seed, 500.0);
        let e = &mut sc.nav_errors;
        e.model = NavErrorModel::TwoGaussMarkov;
        (e.position_tau_s, e.attitude_tau_s) = (T1, T1);
        (e.position_tau2_s, e.attitude_tau2_s) = (T2, T2);
        e.second_share = SHARE;
        e.smrmsg_factor = FACTOR;
        let dir = tempfile::tempdir().unwrap();
        run(&sc, dir.path(), 2);
        for (j, (_, s)) in stated(dir.path()).iter().enumerate() {
            for i in 0..6 {
                let want = FACTOR * sigma[i];
                assert!(
                    (s[i] - want).abs() <= 1e-12 * want,
                    "smrmsg record {j} axis {i}: {} vs {want}",
                    s[i]
                );
            }
        }
        let truth = SbetFile::open(&dir.path().join("truth.sbet")).unwrap();
        dt = truth.time_s(1) - truth.time_s(0);
        let err = nav_errors(dir.path());
        for (i, s) in sigma.iter().enumerate() {
            series.push(err.iter().map(|e| e[i] / s).collect::<Vec<f64>>());
        }
    }
    let n: usize = series.iter().map(Vec::len).sum();
    let var = series.iter().flatten().map(|z| z * z).sum::<f64>() / n as f64;
    println!("two GM: variance / sigma^2 {var:.4} (stated {FACTOR} sigma)");
    assert!((var - 1.0).abs() < 0.07, "variance ratio {var}");
    for lag_s in [T1, T2] {
        let lag = (lag_s / dt).round() as usize;
        let want = (1.0 - SHARE) * (-lag_s / T1).exp() + SHARE * (-lag_s / T2).exp();
        let got = autocorrelation(&series, lag);
        println!("two GM: rho({lag_s} s) {got:.4}, model {want:.4}");
        assert!((got - want).abs() < 0.07, "rho({lag_s} s) {got} vs {want}");
    }
}

/// Random walk + white noise (white share 0.3) stated 0.7x: the SMRMSG states 0.7 x the
/// growing std `sigma sqrt(w + (1 - w) t / t_mid)` exactly; the white share shows in the
/// lag-1 increments (variance `2 w + (1 - w) dt / t_mid` in sigma^2) and the walk in the
/// increments of 4 s block means (`(2/3) b (1 - w) / t_mid + 2 w / B` for blocks of b seconds
/// and B samples: a Wiener process' consecutive block means differ by 2b/3 per unit
/// diffusion). Two seeds x 400 s x 6 components.
///
/// Tolerances: ~960 k lag-1 increments (neighbours correlated -1/2, squares 1/4): relative
/// standard error sqrt(2 x 1.5 / 960 k) = 0.2%, bound 1.5%; 1188 block-mean increments
/// (neighbours correlated 1/4): relative standard error 4.4%, bound 18% (4 standard errors).
/// A stationary process with the same variance would have block increments near 0.
#[test]
fn random_walk_white_errors_have_the_stated_growing_std_and_their_increments() {
    const W: f64 = 0.3;
    const D: f64 = 400.0;
    const FACTOR: f64 = 0.7;
    const BLOCK_S: f64 = 4.0;
    let sigma = sigmas();
    let t_mid = D / 2.0;
    let mut series = vec![];
    let mut dt = 0.0;
    for seed in [21, 22] {
        let mut sc = nav_scenario(seed, D);
        sc.nav_errors.model = NavErrorModel::RandomWalkWhite;
        sc.nav_errors.white_share = W;
        sc.nav_errors.smrmsg_factor = FACTOR;
        let dir = tempfile::tempdir().unwrap();
        run(&sc, dir.path(), 2);
        for (t, s) in stated(dir.path()) {
            for i in 0..6 {
                let want = FACTOR * sigma[i] * (W + (1.0 - W) * t / t_mid).sqrt();
                assert!(
                    (s[i] - want).abs() <= 1e-9 * want,
                    "smrmsg at {t} s axis {i}: {} vs {want}",
                    s[i]
                );
            }
        }
        let truth = SbetFile::open(&dir.path().join("truth.sbet")).unwrap();
        dt = truth.time_s(1) - truth.time_s(0);
        let err = nav_errors(dir.path());
        for (i, s) in sigma.iter().enumerate() {
            series.push(err.iter().map(|e| e[i] / s).collect::<Vec<f64>>());
        }
    }
    let mean_sq = |v: &mut dyn Iterator<Item = f64>| {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        s / n as f64
    };
    let white = mean_sq(
        &mut series
            .iter()
            .flat_map(|z| z.windows(2).map(|w| w[1] - w[0])),
    );
    let want_white = 2.0 * W + (1.0 - W) * dt / t_mid;
    println!("rw+white: lag-1 increments {white:.5}, model {want_white:.5}");
    assert!(
        (white / want_white - 1.0).abs() < 0.015,
        "lag-1 increments {white} vs {want_white}"
    );
    let b = (BLOCK_S / dt).round() as usize;
    let walk = mean_sq(&mut series.iter().flat_map(|z| {
        let means: Vec<f64> = z
            .chunks_exact(b)
            .map(|c| c.iter().sum::<f64>() / b as f64)
            .collect();
        means.windows(2).map(|w| w[1] - w[0]).collect::<Vec<f64>>()
    }));
    let want_walk = 2.0 / 3.0 * BLOCK_S * (1.0 - W) / t_mid + 2.0 * W / b as f64;
    println!("rw+white: {BLOCK_S} s block-mean increments {walk:.5}, model {want_walk:.5}");
    assert!(
        (walk / want_walk - 1.0).abs() < 0.18,
        "block-mean increments {walk} vs {want_walk}"
    );
}

/// `zero_rate_fields` writes the SBET's six acceleration and angular-rate fields as 0 and
/// changes nothing else: every other field of the SBET, the SMRMSG and the truth SBET are
/// those of the same survey without it (where the rate fields are not zero).
#[test]
fn zero_rate_fields_zeroes_exactly_the_rate_and_acceleration_fields() {
    let plain = nav_scenario(31, 10.0);
    let mut zero = plain.clone();
    zero.nav_errors.zero_rate_fields = true;
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    run(&plain, a.path(), 1);
    run(&zero, b.path(), 1);
    for f in ["truth.sbet", "trajectory.smrmsg"] {
        let same =
            std::fs::read(a.path().join(f)).unwrap() == std::fs::read(b.path().join(f)).unwrap();
        assert!(same, "{f} differs");
    }
    let p = SbetFile::open(&a.path().join("trajectory.sbet")).unwrap();
    let z = SbetFile::open(&b.path().join("trajectory.sbet")).unwrap();
    assert_eq!(p.len(), z.len());
    let mut rates_seen = vec![];
    for k in 0..p.len() {
        let (rp, rz) = (p.record(k).to_array(), z.record(k).to_array());
        for c in 0..17 {
            if c >= 11 {
                assert_eq!(rz[c].to_bits(), 0, "record {k} field {c} not zero");
                rates_seen.push(rp[c]);
            } else {
                assert_eq!(rz[c].to_bits(), rp[c].to_bits(), "record {k} field {c}");
            }
        }
    }
    assert!(
        max_abs(rates_seen) > 0.01,
        "the plain SBET's rate fields are zero too"
    );
}

/// `vehicle.vibration_hz`: on a long straight at top speed, the true roll and pitch minus
/// their means are one sinusoid at the set frequency with the set amplitude. The periodogram's
/// peak over 0.5-10 Hz (0.01 Hz grid, 12 s: resolution 1/12 Hz) lies within 0.03 Hz of it and
/// the least-squares amplitude there is within 2% (deterministic: no noise; what is left is the
/// local-level conversion and the window's partial cycle, measured below 0.3%).
#[test]
fn vibration_peaks_at_the_set_frequency_with_the_set_amplitude() {
    const AMP_DEG: [f64; 2] = [0.3, 0.5];
    for hz in [1.5, 4.0] {
        let mut sc = nav_scenario(41, 20.0);
        sc.nav_errors.position_sigma_m = [0.0; 3];
        sc.nav_errors.attitude_sigma_deg = [0.0; 3];
        sc.route.waypoints_m = vec![[0.0, 0.0], [400.0, 0.0], [400.0, 92.0], [0.0, 92.0]];
        sc.vehicle.vibration_deg = AMP_DEG;
        sc.vehicle.vibration_hz = Some(hz);
        let dir = tempfile::tempdir().unwrap();
        run(&sc, dir.path(), 1);
        let truth = SbetFile::open(&dir.path().join("truth.sbet")).unwrap();
        let t0 = truth.time_s(0);
        let top = sc.route.max_speed_mps;
        let (mut t, mut ch) = (vec![], [vec![], vec![]]);
        for k in 0..truth.len() {
            let r = truth.record(k);
            let v = r.vel_x_mps.hypot(r.vel_y_mps);
            if r.time_s - t0 >= 5.0 && r.time_s - t0 < 17.0 {
                assert!(
                    (v / top - 1.0).abs() < 1e-3,
                    "not at top speed at {} s: {v}",
                    r.time_s - t0
                );
                t.push(r.time_s - t0);
                ch[0].push(r.roll_rad);
                ch[1].push(r.pitch_rad);
            }
        }
        for (c, x) in ch.iter_mut().enumerate() {
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            x.iter_mut().for_each(|v| *v -= mean);
            // Least-squares amplitude of a sinusoid at f (sine and cosine, the mean removed).
            let amplitude = |f: f64| {
                let (mut ss, mut cc, mut sc_, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for (ti, yi) in t.iter().zip(x.iter()) {
                    let (s, co) = (std::f64::consts::TAU * f * ti).sin_cos();
                    (ss, cc, sc_) = (ss + s * s, cc + co * co, sc_ + s * co);
                    (ys, yc) = (ys + yi * s, yc + yi * co);
                }
                let det = ss * cc - sc_ * sc_;
                let (a, b) = ((ys * cc - yc * sc_) / det, (yc * ss - ys * sc_) / det);
                a.hypot(b)
            };
            let grid: Vec<f64> = (50..=1000).map(|i| i as f64 / 100.0).collect();
            let powers: Vec<f64> = grid.iter().map(|&f| amplitude(f)).collect();
            let peak =
                grid[powers
                    .iter()
                    .enumerate()
                    .fold(0, |best, (i, p)| if *p > powers[best] { i } else { best })];
            let amp = amplitude(hz).to_degrees();
            println!("vibration {hz} Hz channel {c}: peak {peak} Hz, amplitude {amp:.5} deg");
            assert!(
                (peak - hz).abs() <= 0.03,
                "channel {c}: peak at {peak} Hz, set {hz}"
            );
            assert!(
                (amp / AMP_DEG[c] - 1.0).abs() < 0.02,
                "channel {c}: amplitude {amp} deg, set {}",
                AMP_DEG[c]
            );
        }
    }
}
