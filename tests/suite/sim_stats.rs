//! The injected navigation errors have their stated statistics: over a long run, each of the
//! six Gauss-Markov errors (SBET minus true trajectory) has the configured sigma within 5% and
//! correlation time within 10%, inside and outside a GNSS outage, and the SMRMSG sigmas are
//! the injected ones.
//!
//! Sizing: each half of the run spans 4000 correlation times. For a Gauss-Markov process
//! observed over T = 4000 tau, the relative standard error of the RMS is
//! 0.5 sqrt(2 tau / T) = 1.1% and that of the lag-1 correlation-time estimate is
//! sqrt(2 tau / T) = 2.2%: the 5% and 10% bounds sit at 4.5 standard errors.

use crate::sim_support;
use kinescan::io::sbet::SbetFile;
use kinescan::io::smrmsg::{SmrmsgFile, RAD_PER_ARCMIN};
use sim_support::*;

const TAU_S: f64 = 0.25;
const HALF_S: f64 = 1000.0;
const FACTOR: f64 = 4.0;

#[test]
fn gauss_markov_errors_have_their_stated_statistics() {
    let mut sc = base();
    sc.duration_s = 2.0 * HALF_S;
    sc.scanner.period_s = 1.0 / 33.0;
    sc.scanner.points_per_profile = 1;
    sc.output.truth_points = false;
    let e = &mut sc.nav_errors;
    e.position_sigma_m = [0.02, 0.03, 0.05];
    e.attitude_sigma_deg = [0.005, 0.007, 0.012];
    e.position_tau_s = TAU_S;
    e.attitude_tau_s = TAU_S;
    e.outages_s = vec![[HALF_S, 3.0 * HALF_S]];
    e.outage_sigma_factor = FACTOR;
    let sigma = [
        0.02,
        0.03,
        0.05,
        0.005f64.to_radians(),
        0.007f64.to_radians(),
        0.012f64.to_radians(),
    ];
    let dir = tempfile::tempdir().unwrap();
    run(&sc, dir.path(), 2);
    let truth = SbetFile::open(&dir.path().join("truth.sbet")).unwrap();
    let smr = SmrmsgFile::open(&dir.path().join("trajectory.smrmsg")).unwrap();
    let errors = nav_errors(dir.path());
    let t_start = truth.time_s(0);
    let dt = truth.time_s(1) - t_start;
    // Errors normalised by the SMRMSG sigma (linear between records): unit GM processes.
    let mut series = vec![Vec::new(); 6];
    let mut raw = vec![[Vec::new(), Vec::new()]; 6];
    let every = (smr.time_s(1) - smr.time_s(0)) / dt;
    let every = every.round() as usize;
    for (k, err) in errors.iter().enumerate() {
        let b = truth.record(k);
        let (j, w) = (k / every, (k % every) as f64 / every as f64);
        let s0 = smr.record(j).to_array();
        let s1 = smr.record((j + 1).min(smr.len() - 1)).to_array();
        for i in 0..6 {
            let unit = if i < 3 { 1.0 } else { RAD_PER_ARCMIN };
            let s = (s0[smrmsg_col(i)] + w * (s1[smrmsg_col(i)] - s0[smrmsg_col(i)])) * unit;
            series[i].push(err[i] / s);
            let inside = b.time_s - t_start >= HALF_S;
            raw[i][inside as usize].push(err[i]);
        }
    }
    // SMRMSG states the injected sigmas, times the factor in the outage.
    for (j, f) in [(0usize, 1.0), (smr.len() - 2, FACTOR)] {
        let s = smr.record(j).to_array();
        for i in 0..6 {
            let unit = if i < 3 { 1.0 } else { RAD_PER_ARCMIN };
            let got = s[smrmsg_col(i)] * unit;
            assert!(
                (got - f * sigma[i]).abs() < 1e-12 * sigma[i],
                "smrmsg {j} axis {i}: {got} vs {}",
                f * sigma[i]
            );
        }
    }
    for i in 0..6 {
        for (half, f) in [(0, 1.0), (1, FACTOR)] {
            let x = &raw[i][half];
            let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
            let ratio = rms / (f * sigma[i]);
            println!("axis {i} half {half}: sigma ratio {ratio:.4}");
            assert!(
                (ratio - 1.0).abs() < 0.05,
                "axis {i} half {half}: sigma ratio {ratio}"
            );
        }
        let z = &series[i];
        let num: f64 = z.windows(2).map(|w| w[0] * w[1]).sum();
        let den: f64 = z[..z.len() - 1].iter().map(|v| v * v).sum();
        let tau = -dt / (num / den).ln();
        println!("axis {i}: tau ratio {:.4}", tau / TAU_S);
        assert!((tau / TAU_S - 1.0).abs() < 0.10, "axis {i}: tau {tau} s");
    }
}
