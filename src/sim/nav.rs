//! The navigation solution as an INS/GNSS Kalman smoother would output it: the true samples
//! plus first-order Gauss-Markov position (north, east, down) and attitude (roll, pitch,
//! heading) errors, larger inside GNSS outages, plus the navigation-level systematic effects
//! (attitude latency, heading bias, drift in outages). Written as SBET + SMRMSG; the SMRMSG
//! sigmas are exactly the injected processes' standard deviations.
//!
//! Each error is `sigma(t) * z(t)` with `z` a unit-variance Gauss-Markov process sampled
//! exactly: `z_{k+1} = phi z_k + sqrt(1 - phi^2) w_k`, `phi = exp(-dt / tau)`, `z_0 ~ N(0, 1)`.
//! `sigma(t)` is linear between SMRMSG records, where it is the configured sigma times
//! `outage_sigma_factor` inside an outage and 1 outside.
//!
//! `nav_errors.model` replaces the unit process `z` ([`UnitProcess`]): the sum of two
//! Gauss-Markov processes (`sqrt(1 - s) z1 + sqrt(s) z2`, unit variance), or a random walk
//! from zero plus white noise, whose variance `w + (1 - w) t / t_mid` grows with the time `t`
//! since the start (`w` the white share, `t_mid` half the duration: 1 at mid survey and on
//! average over the survey, so the configured sigma is the survey's RMS). The SMRMSG states
//! `smrmsg_factor` times the true standard deviation at each epoch.

use super::dynamics::TruthGen;
use super::scenario::{NavErrorCfg, NavErrorModel, Scenario};
use crate::geo::ellipsoid::{meridian_radius_m, prime_vertical_radius_m};
use crate::geo::rotations::roll_pitch_heading;
use crate::io::sbet::{SbetRecord, SbetWriter};
use crate::io::smrmsg::{SmrmsgRecord, SmrmsgWriter};
use crate::trajectory::{interpolate, NavSample};
use crate::Result;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::VecDeque;
use std::path::Path;

/// Unit-variance first-order Gauss-Markov process with exact discretisation.
#[derive(Debug, Clone)]
pub struct GaussMarkov {
    phi: f64,
    drive: f64,
    z: f64,
}

impl GaussMarkov {
    /// Process with correlation time `tau_s` sampled every `dt_s`, started from its
    /// stationary distribution.
    pub fn new(tau_s: f64, dt_s: f64, rng: &mut ChaCha8Rng) -> Self {
        let phi = (-dt_s / tau_s).exp();
        GaussMarkov {
            phi,
            drive: (1.0 - phi * phi).sqrt(),
            z: StandardNormal.sample(rng),
        }
    }
    /// Current value.
    pub fn value(&self) -> f64 {
        self.z
    }
    /// Advances one step.
    pub fn step(&mut self, rng: &mut ChaCha8Rng) {
        let w: f64 = StandardNormal.sample(rng);
        self.z = self.phi * self.z + self.drive * w;
    }
}

/// The unit process of one error component under `nav_errors.model`: its value has standard
/// deviation [`UnitProcess::std`] (1 for the stationary models).
#[derive(Debug, Clone)]
enum UnitProcess {
    /// One Gauss-Markov process.
    Gm(GaussMarkov),
    /// Weighted sum of two independent Gauss-Markov processes (weights squared sum to 1).
    TwoGm {
        a: GaussMarkov,
        b: GaussMarkov,
        wa: f64,
        wb: f64,
    },
    /// `sqrt(w) white + sqrt((1 - w) / t_mid) walk`, `walk` a unit Wiener process from 0.
    RwWhite {
        walk: f64,
        white: f64,
        w: f64,
        t_mid: f64,
        sqrt_dt: f64,
    },
}

impl UnitProcess {
    /// The process of a component with (first, second) correlation times `tau`. The first
    /// Gauss-Markov process draws from `rng` (as the default model always did), everything
    /// else from `rng2`.
    fn new(
        e: &NavErrorCfg,
        tau: [f64; 2],
        dt: f64,
        duration_s: f64,
        rng: &mut ChaCha8Rng,
        rng2: &mut ChaCha8Rng,
    ) -> Self {
        match e.model {
            NavErrorModel::GaussMarkov => UnitProcess::Gm(GaussMarkov::new(tau[0], dt, rng)),
            NavErrorModel::TwoGaussMarkov => UnitProcess::TwoGm {
                a: GaussMarkov::new(tau[0], dt, rng),
                b: GaussMarkov::new(tau[1], dt, rng2),
                wa: (1.0 - e.second_share).sqrt(),
                wb: e.second_share.sqrt(),
            },
            NavErrorModel::RandomWalkWhite => UnitProcess::RwWhite {
                walk: 0.0,
                white: StandardNormal.sample(rng2),
                w: e.white_share,
                t_mid: duration_s / 2.0,
                sqrt_dt: dt.sqrt(),
            },
        }
    }
    fn value(&self) -> f64 {
        match self {
            UnitProcess::Gm(g) => g.value(),
            UnitProcess::TwoGm { a, b, wa, wb } => wa * a.value() + wb * b.value(),
            UnitProcess::RwWhite {
                walk,
                white,
                w,
                t_mid,
                ..
            } => w.sqrt() * white + ((1.0 - w) / t_mid).sqrt() * walk,
        }
    }
    /// Standard deviation of [`Self::value`] at `tr` seconds after the start.
    fn std(&self, tr: f64) -> f64 {
        match self {
            UnitProcess::Gm(_) | UnitProcess::TwoGm { .. } => 1.0,
            UnitProcess::RwWhite { w, t_mid, .. } => (w + (1.0 - w) * tr / t_mid).sqrt(),
        }
    }
    fn step(&mut self, rng: &mut ChaCha8Rng, rng2: &mut ChaCha8Rng) {
        match self {
            UnitProcess::Gm(g) => g.step(rng),
            UnitProcess::TwoGm { a, b, .. } => {
                a.step(rng);
                b.step(rng2);
            }
            UnitProcess::RwWhite {
                walk,
                white,
                sqrt_dt,
                ..
            } => {
                let dw: f64 = StandardNormal.sample(rng);
                *walk += *sqrt_dt * dw;
                *white = StandardNormal.sample(rng2);
            }
        }
    }
}

/// Counts of navigation records written.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct NavCounts {
    /// SBET records (nav solution and truth each).
    pub sbet_records: u64,
    /// SMRMSG records.
    pub smrmsg_records: u64,
}

/// Where the navigation files go.
pub struct NavPaths<'a> {
    /// Nav solution SBET.
    pub sbet: &'a Path,
    /// Its SMRMSG.
    pub smrmsg: &'a Path,
    /// True trajectory SBET, if wanted.
    pub truth_sbet: Option<&'a Path>,
}

/// Number of SBET records: covers the duration, ends on an SMRMSG record.
pub fn sample_count(sc: &Scenario) -> u64 {
    let m = smrmsg_every(sc);
    let n = (sc.duration_s * sc.vehicle.nav_rate_hz).ceil() as u64;
    n.div_ceil(m) * m + 1
}

fn smrmsg_every(sc: &Scenario) -> u64 {
    (sc.vehicle.nav_rate_hz / sc.nav_errors.smrmsg_rate_hz).round() as u64
}

/// Outage factor on the sigmas at relative time `tr` (s), on the SMRMSG grid.
fn outage_factor(sc: &Scenario, tr: f64) -> f64 {
    let e = &sc.nav_errors;
    if e.outages_s.iter().any(|o| tr >= o[0] && tr < o[1]) {
        e.outage_sigma_factor
    } else {
        1.0
    }
}

/// Writes the nav solution (and truth) SBET and SMRMSG from the true samples of `gen`.
pub fn write_nav(sc: &Scenario, mut gen: TruthGen, paths: &NavPaths) -> Result<NavCounts> {
    let rate = sc.vehicle.nav_rate_hz;
    let dt = 1.0 / rate;
    let e = &sc.nav_errors;
    let fx = &sc.effects;
    let tau = fx.attitude_latency_s.unwrap_or(0.0);
    let tau_p = fx.position_latency_s.unwrap_or(0.0);
    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed ^ 0x0A7E_0000_0000_0003);
    // The second stream of the richer models: the default model never draws from it.
    let mut rng2 = ChaCha8Rng::seed_from_u64(sc.seed ^ 0x0A7E_0000_0000_0013);
    let mut gm: Vec<UnitProcess> = (0..6)
        .map(|i| {
            let tau = if i < 3 {
                [e.position_tau_s, e.position_tau2_s]
            } else {
                [e.attitude_tau_s, e.attitude_tau2_s]
            };
            UnitProcess::new(e, tau, dt, sc.duration_s, &mut rng, &mut rng2)
        })
        .collect();
    let sig = [
        e.position_sigma_m[0],
        e.position_sigma_m[1],
        e.position_sigma_m[2],
        e.attitude_sigma_deg[0].to_radians(),
        e.attitude_sigma_deg[1].to_radians(),
        e.attitude_sigma_deg[2].to_radians(),
    ];
    let m = smrmsg_every(sc);
    let n = sample_count(sc);
    let mut sbet = SbetWriter::create(paths.sbet)?;
    let mut smr = SmrmsgWriter::create(paths.smrmsg)?;
    let mut truth = paths.truth_sbet.map(SbetWriter::create).transpose()?;
    let mut window = Window::default();
    let lead = (tau.min(tau_p).min(0.0).abs() * rate).ceil() as u64 + 2;
    let mut smr_count = 0;
    for k in 0..n {
        window.fill(&mut gen, k + lead);
        let t_rec = window.get(k);
        let tr = t_rec.time_s - sc.start_time_s;
        let (j, frac) = (k / m, (k % m) as f64 / m as f64);
        let knot = |j: u64| outage_factor(sc, (j * m) as f64 / rate);
        let f = knot(j) + frac * (knot(j + 1) - knot(j));
        let err: Vec<f64> = (0..6).map(|i| sig[i] * f * gm[i].value()).collect();
        let mut rec = t_rec;
        if tau != 0.0 {
            let (r, p, h) = window.attitude_at(t_rec.time_s - tau, sc.start_time_s, rate);
            (rec.roll_rad, rec.pitch_rad, rec.platform_heading_rad) = (r, p, h);
        }
        if tau_p != 0.0 {
            let (lat, lon, alt) = window.position_at(t_rec.time_s - tau_p, sc.start_time_s, rate);
            (rec.lat_rad, rec.lon_rad, rec.alt_m) = (lat, lon, alt);
        }
        let mut d_ned = [err[0], err[1], err[2]];
        if let Some(drift) = fx.outage_drift_mps {
            if let Some(o) = e.outages_s.iter().find(|o| tr >= o[0] && tr < o[1]) {
                for i in 0..3 {
                    d_ned[i] += drift[i] * (tr - o[0]);
                }
            }
        }
        let h = rec.alt_m;
        rec.lat_rad += d_ned[0] / (meridian_radius_m(rec.lat_rad) + h);
        rec.lon_rad += d_ned[1] / ((prime_vertical_radius_m(rec.lat_rad) + h) * rec.lat_rad.cos());
        rec.alt_m -= d_ned[2];
        rec.roll_rad += err[3];
        rec.pitch_rad += err[4];
        // Wrapped into [0, 2 pi) as an SBET writes it (the writer refuses a heading beyond
        // 2 pi as one in degrees).
        rec.platform_heading_rad =
            (rec.platform_heading_rad + err[5] + fx.heading_bias_deg.unwrap_or(0.0).to_radians())
                .rem_euclid(std::f64::consts::TAU);
        if e.zero_rate_fields {
            (rec.acc_x_mps2, rec.acc_y_mps2, rec.acc_z_mps2) = (0.0, 0.0, 0.0);
            (rec.rate_x_radps, rec.rate_y_radps, rec.rate_z_radps) = (0.0, 0.0, 0.0);
        }
        sbet.push(&rec)?;
        if let Some(w) = truth.as_mut() {
            w.push(&t_rec)?;
        }
        if k % m == 0 {
            // Stated = factor x true std (exactly today's numbers at the defaults: both
            // factors are then 1.0, and a product with 1.0 is exact).
            let g = gm[0].std(tr) * e.smrmsg_factor;
            let arcmin = |s: f64| s.to_degrees() * 60.0 * f * g;
            smr.push(&SmrmsgRecord {
                time_s: t_rec.time_s,
                north_m: sig[0] * f * g,
                east_m: sig[1] * f * g,
                down_m: sig[2] * f * g,
                vel_north_mps: e.velocity_sigma_mps * f,
                vel_east_mps: e.velocity_sigma_mps * f,
                vel_down_mps: e.velocity_sigma_mps * f,
                roll_arcmin: arcmin(sig[3]),
                pitch_arcmin: arcmin(sig[4]),
                heading_arcmin: arcmin(sig[5]),
            })?;
            smr_count += 1;
        }
        for g in gm.iter_mut() {
            g.step(&mut rng, &mut rng2);
        }
        window.drop_before(k.saturating_sub((tau.max(tau_p).max(0.0) * rate).ceil() as u64 + 2));
    }
    let sbet_records = sbet.finish()?;
    smr.finish()?;
    if let Some(w) = truth {
        w.finish()?;
    }
    Ok(NavCounts {
        sbet_records,
        smrmsg_records: smr_count,
    })
}

/// Sliding window of true samples `base..base + len`.
#[derive(Default)]
struct Window {
    base: u64,
    recs: VecDeque<SbetRecord>,
}

impl Window {
    fn fill(&mut self, gen: &mut TruthGen, upto: u64) {
        while gen.next_index() <= upto {
            self.recs.push_back(gen.next_sample());
        }
    }
    fn get(&self, k: u64) -> SbetRecord {
        self.recs[(k - self.base) as usize]
    }
    fn drop_before(&mut self, k: u64) {
        while self.base < k {
            self.recs.pop_front();
            self.base += 1;
        }
    }
    /// True attitude (roll, pitch, heading in [0, 2 pi)) at `t`, interpolated as the truth
    /// is; held at the first sample before the trajectory starts.
    fn attitude_at(&self, t: f64, start: f64, rate: f64) -> (f64, f64, f64) {
        roll_pitch_heading(&self.sample_at(t, start, rate).q_b_to_n)
    }

    /// True geodetic position (lat, lon (rad), height (m)) at `t`.
    fn position_at(&self, t: f64, start: f64, rate: f64) -> (f64, f64, f64) {
        let s = self.sample_at(t, start, rate);
        (s.lat_rad, s.lon_rad, s.h_m)
    }

    /// The true sample at `t`, interpolated as the pipeline does.
    fn sample_at(&self, t: f64, start: f64, rate: f64) -> NavSample {
        let k = ((t - start) * rate).floor().max(0.0) as u64;
        let k = k.clamp(self.base, self.base + self.recs.len() as u64 - 2);
        let (a, b) = (
            NavSample::from_sbet(&self.get(k)),
            NavSample::from_sbet(&self.get(k + 1)),
        );
        interpolate(&a, &b, t.max(start))
    }
}
