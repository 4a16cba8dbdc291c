//! Simulated GNSS positions: the antenna phase centre (IMU position plus `R_b^n` times the
//! lever arm) with white noise of the configured sigmas, none inside an outage, and with a
//! given probability an outlier (multipath) of a fixed size in a uniformly random direction.

use super::scenario::RawCfg;
use crate::ins::mechanisation::NavState;
use crate::io::gnss::GnssRecord;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// GNSS fix generator.
#[derive(Debug, Clone)]
pub struct GnssGen {
    sigma: [f64; 3],
    lever_b: Vector3<f64>,
    outages: Vec<[f64; 2]>,
    outlier_probability: f64,
    outlier_m: f64,
    rng: ChaCha8Rng,
    /// Times of the outlier fixes written (s).
    pub outlier_times: Vec<f64>,
}

impl GnssGen {
    /// Generator for the `[raw]` table over `duration_s`, stream from `seed`.
    pub fn new(cfg: &RawCfg, duration_s: f64, seed: u64) -> Self {
        GnssGen {
            sigma: cfg.gnss_sigma_m,
            lever_b: Vector3::from(cfg.antenna_lever_arm_b_m),
            outages: cfg.outages(duration_s),
            outlier_probability: cfg.outlier_probability,
            outlier_m: cfg.outlier_m,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x6A55_0003),
            outlier_times: Vec::new(),
        }
    }

    /// The outages [start, end] (s from the start).
    pub fn outages(&self) -> &[[f64; 2]] {
        &self.outages
    }

    /// The fix at the true state `s`, `rel_s` seconds after the start; None in an outage.
    pub fn fix(&mut self, s: &NavState, rel_s: f64) -> Option<GnssRecord> {
        if self.outages.iter().any(|o| rel_s >= o[0] && rel_s < o[1]) {
            return None;
        }
        let mut d = s.q_b_n * self.lever_b;
        for (i, sig) in self.sigma.iter().enumerate() {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            d[i] += sig * n;
        }
        if self.outlier_probability > 0.0 && self.rng.random::<f64>() < self.outlier_probability {
            let u = Vector3::from_fn(|_, _| StandardNormal.sample(&mut self.rng));
            d += u.normalize() * self.outlier_m;
            self.outlier_times.push(s.time_s);
        }
        let mut a = *s;
        a.shift_ned(&d);
        Some(GnssRecord {
            time_s: s.time_s,
            lat_rad: a.lat_rad,
            lon_rad: a.lon_rad,
            h_m: a.h_m,
            sigma_ned_m: self.sigma,
        })
    }
}
