//! The profile scanner's forward model: for profile `n` and return `j` of it, the recorded
//! mirror angle, the true time, the true pose (`trajectory::interpolate` of the true samples),
//! the true beam (`georef::beam_e` with the true sensor), the ray cast in the scene, and the
//! recorded range and intensity. Uses the same functions as the pipeline's inverse, so with
//! every error source off the pipeline reproduces the true points.
//!
//! Recorded angles lie on a grid: `beta_j = beta_start + dir * 2 pi j / P`. The true beam is
//! at `beta_j - encoder_offset + noise`, `alpha0 + cone_error + noise`. True time of a return:
//! `t = t0 + T' nu + q (T' nu)^2 + A sin(2 pi T' nu / P_w) + clock_offset`,
//! `nu = n + f(beta_j - encoder_offset)`, `T' = T (1 + drift_ppm 1e-6)` (docs/conventions.md §2
//! when the effects are off). Recorded range:
//! `rho = d (1 + scale_ppm 1e-6) - K_true + A_c sin(2 pi d / L_c) + A_i sin^2(i) + noise`, `d`
//! the true distance to the surface, `i` the incidence angle.

use super::dynamics::Frame;
use super::foreign::Foreign;
use super::scenario::Scenario;
use super::scene::{Scene, GROUND};
use crate::georef::{beam_e, Sensor};
use crate::io::profiles::{encode, RawReturn, PROFILE_RECORD_BYTES};
use crate::timing::{Mirror, MirrorDirection, ScannerClock};
use crate::trajectory::{interpolate, NavSample, Pose};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::TAU;

/// Scanner parameters as configured (what the pipeline is given) and as they truly are.
#[derive(Debug, Clone)]
pub struct ScannerModel {
    /// Sensor the pipeline is configured with.
    pub configured: Sensor,
    /// Sensor as it truly is (configured + injected effects).
    pub truth: Sensor,
    /// Configured clock: t0, nominal period, mirror.
    pub clock: ScannerClock,
    /// True mirror period (s).
    pub true_period_s: f64,
    quad_per_s: f64,
    wobble: [f64; 2],
    encoder_offset_rad: f64,
    clock_offset_s: f64,
    range_scale: f64,
    range_cyclic_m: [f64; 2],
    range_incidence_m: f64,
    points: u32,
    max_range_m: f64,
    min_range_m: f64,
    sigma_range_m: f64,
    sigma_angle_rad: f64,
    dropout: f64,
    ref_range_m: f64,
    pps: bool,
    seed: u64,
}

impl ScannerModel {
    /// The model of a scenario.
    pub fn new(sc: &Scenario) -> ScannerModel {
        let s = &sc.scanner;
        let fx = &sc.effects;
        let v3 = |a: [f64; 3]| Vector3::new(a[0], a[1], a[2]);
        let deg3 = |a: [f64; 3]| v3(a.map(f64::to_radians));
        let configured = Sensor::new(
            v3(s.lever_arm_b_m),
            deg3(s.boresight_deg),
            s.alpha0_deg.to_radians(),
            s.range_zero_m,
        );
        let truth = Sensor::new(
            configured.lever_arm_b_m + v3(fx.lever_arm_error_m.unwrap_or([0.0; 3])),
            configured.boresight_rad + deg3(fx.boresight_error_deg.unwrap_or([0.0; 3])),
            configured.alpha0_rad + fx.cone_error_deg.unwrap_or(0.0).to_radians(),
            s.range_zero_m + fx.range_zero_error_m.unwrap_or(0.0),
        );
        let direction = if s.direction > 0 {
            MirrorDirection::Increasing
        } else {
            MirrorDirection::Decreasing
        };
        let clock = ScannerClock {
            t0_s: sc.start_time_s + s.t0_offset_s,
            period_s: s.period_s,
            mirror: Mirror {
                beta_start_rad: s.beta_start_deg.to_radians(),
                direction,
            },
        };
        ScannerModel {
            configured,
            truth,
            clock,
            true_period_s: s.period_s * (1.0 + fx.clock_drift_ppm.unwrap_or(0.0) * 1e-6),
            quad_per_s: fx.clock_drift_quadratic_per_s.unwrap_or(0.0),
            wobble: fx.mirror_wobble_s.unwrap_or([0.0, 1.0]),
            encoder_offset_rad: fx.encoder_offset_deg.unwrap_or(0.0).to_radians(),
            clock_offset_s: fx.clock_offset_s.unwrap_or(0.0),
            range_scale: 1.0 + fx.range_scale_ppm.unwrap_or(0.0) * 1e-6,
            range_cyclic_m: fx.range_cyclic_m.unwrap_or([0.0, 1.0]),
            range_incidence_m: fx.range_incidence_m.unwrap_or(0.0),
            points: s.points_per_profile,
            max_range_m: s.max_range_m,
            min_range_m: s.min_range_m,
            sigma_range_m: s.sigma_range_m,
            sigma_angle_rad: s.sigma_angle_deg.to_radians(),
            dropout: s.dropout_probability,
            ref_range_m: s.intensity_ref_range_m,
            pps: s.pps_time_tags,
            seed: sc.seed,
        }
    }

    /// Returns per profile.
    pub fn points_per_profile(&self) -> u32 {
        self.points
    }

    /// Recorded mirror angle of return `j` (rad, [0, 2 pi)).
    #[inline]
    pub fn beta_of(&self, j: u32) -> f64 {
        let m = &self.clock.mirror;
        let b = m.beta_start_rad + m.direction.sign() * TAU * j as f64 / self.points as f64;
        crate::geo::rotations::wrap_two_pi(b)
    }

    /// True GPS time (s) of a return of profile `n` recorded at mirror angle `beta_rad`: the
    /// time model at the TRUE mirror angle (recorded minus the encoder offset, as
    /// docs/conventions.md §3 has the pipeline add `dbeta` in `f(beta)` too).
    #[inline]
    pub fn true_time(&self, n: u32, beta_rad: f64) -> f64 {
        let beta_true = beta_rad - self.encoder_offset_rad;
        self.time_at(n as f64 + self.clock.mirror.fraction(beta_true))
    }

    /// True GPS time (s) at `nu` profiles (counter + fraction) since profile 0.
    #[inline]
    fn time_at(&self, nu: f64) -> f64 {
        let mut t = self.clock.t0_s + self.true_period_s * nu;
        if self.quad_per_s != 0.0 || self.wobble[0] != 0.0 {
            let tau = self.true_period_s * nu;
            t += self.quad_per_s * tau * tau + self.wobble[0] * (TAU * tau / self.wobble[1]).sin();
        }
        t + self.clock_offset_s
    }

    /// Earliest and latest true time (s) of the returns of profile `n`: its first and last
    /// recorded angles; with an encoder offset (which can wrap the first angle to the end of
    /// the profile) the whole profile `[nu = n, nu = n + 1]`.
    pub fn time_bounds(&self, n: u32) -> (f64, f64) {
        if self.encoder_offset_rad == 0.0 {
            let last = self.beta_of(self.points - 1);
            (self.true_time(n, self.beta_of(0)), self.true_time(n, last))
        } else {
            (self.time_at(n as f64), self.time_at(n as f64 + 1.0))
        }
    }

    /// Range errors outside the catalogue (m) at true distance `d_m` and incidence cosine
    /// `cos_incidence`: `A sin(2 pi d / L) + B sin^2(i)`; exactly 0 when both are off.
    #[inline]
    fn uncatalogued_range_error_m(&self, d_m: f64, cos_incidence: f64) -> f64 {
        let [a, l] = self.range_cyclic_m;
        let b = self.range_incidence_m;
        if a == 0.0 && b == 0.0 {
            return 0.0;
        }
        a * (TAU * d_m / l).sin() + b * (1.0 - cos_incidence * cos_incidence)
    }

    /// Profiles whose every return falls in `[t_a, t_b]` of true time: `n_first..n_end`.
    pub fn profile_span(&self, t_a: f64, t_b: f64) -> (u32, u32) {
        let mut n_end = ((t_b - self.clock.t0_s) / self.true_period_s).max(0.0) as u32 + 2;
        while n_end > 0 && self.time_bounds(n_end - 1).1 > t_b {
            n_end -= 1;
        }
        let first = (0..n_end).find(|&n| self.time_bounds(n).0 >= t_a);
        (first.unwrap_or(n_end), n_end)
    }
}

/// True samples around a stretch of time, with the pipeline's interpolation.
pub struct TruthWindow<'a> {
    /// Consecutive true samples.
    pub samples: &'a [NavSample],
}

impl TruthWindow<'_> {
    /// Approximate index of the sample at or before `t`.
    pub fn index_hint(&self, t: f64) -> usize {
        let s = self.samples;
        let dt = (s[s.len() - 1].t_s - s[0].t_s) / (s.len() - 1) as f64;
        ((t - s[0].t_s) / dt).max(0.0) as usize
    }

    /// True pose at `t` (no latency): the same bracketing as the pipeline's cursor,
    /// `t_i <= t < t_{i+1}`.
    #[inline]
    pub fn pose(&self, t: f64, hint: &mut usize) -> Pose {
        let s = self.samples;
        let mut i = (*hint).min(s.len() - 2);
        while i + 2 < s.len() && s[i + 1].t_s <= t {
            i += 1;
        }
        while i > 0 && s[i].t_s > t {
            i -= 1;
        }
        *hint = i;
        Pose::of(&interpolate(&s[i], &s[i + 1], t))
    }
}

/// One generated profile, encoded.
#[derive(Default)]
pub struct ProfileOut {
    /// Binary profile records.
    pub records: Vec<u8>,
    /// Truth sidecar records (ECEF x, y, z f64; NaN when missing).
    pub truth: Vec<u8>,
    /// Surface keys hit (object * 8 + face), ground excluded.
    pub surfaces: Vec<u32>,
    /// Returns with a range.
    pub valid: u32,
    /// Mixed returns at the edges of foreign things.
    pub mixed: u32,
}

/// Generates profile `n`.
pub fn profile(
    m: &ScannerModel,
    scene: &Scene,
    foreign: Option<&Foreign>,
    frame: &Frame,
    window: &TruthWindow,
    n: u32,
    want_truth: bool,
) -> ProfileOut {
    let mut rng = ChaCha8Rng::seed_from_u64(m.seed ^ 0x5CA9_0000_0000_0004);
    rng.set_stream(n as u64);
    let p = m.points as usize;
    let mut out = ProfileOut {
        records: Vec::with_capacity(p * PROFILE_RECORD_BYTES),
        truth: Vec::with_capacity(if want_truth { p * 24 } else { 0 }),
        ..Default::default()
    };
    let t_n = m.pps.then(|| m.time_at(n as f64));
    let mut hint = window.index_hint(m.time_bounds(n).0);
    let noise = |rng: &mut ChaCha8Rng, s: f64| {
        if s > 0.0 {
            let z: f64 = StandardNormal.sample(rng);
            s * z
        } else {
            0.0
        }
    };
    let r_e_enu = frame.r_enu_to_e.transpose();
    for j in 0..m.points {
        let beta = m.beta_of(j);
        let mut rec = RawReturn {
            profile: n,
            beta_rad: beta,
            time_s: t_n.unwrap_or(0.0),
            ..Default::default()
        };
        let mut truth = [f64::NAN; 3];
        let beta_true = beta - m.encoder_offset_rad + noise(&mut rng, m.sigma_angle_rad);
        let alpha_true = m.truth.alpha0_rad + noise(&mut rng, m.sigma_angle_rad);
        let range_noise = noise(&mut rng, m.sigma_range_m);
        let dropped = m.dropout > 0.0 && rng.random::<f64>() < m.dropout;
        if !dropped {
            let t = m.true_time(n, beta);
            let pose = window.pose(t, &mut hint);
            let (o_e, d_e) = beam_e(&pose, &m.truth, alpha_true, beta_true);
            let o = r_e_enu * (o_e - frame.origin_e);
            let d = r_e_enu * d_e;
            let key = ((n as u64) << 24) ^ j as u64 ^ m.seed.rotate_left(17);
            if let Some(mut h) = scene.cast(&o, &d, m.min_range_m, m.max_range_m, key) {
                if let Some(t) = foreign.and_then(|f| f.mixed_range(scene, &h, &o, &d)) {
                    h.t_m = t;
                    out.mixed += 1;
                }
                let cos_incidence = h.normal.dot(&d).abs();
                let rho = h.t_m * m.range_scale - m.truth.range_zero_m
                    + m.uncatalogued_range_error_m(h.t_m, cos_incidence)
                    + range_noise;
                if rho > 0.0 {
                    let x = o_e + d_e * h.t_m;
                    let refl = if h.object == GROUND {
                        if let Some(k) = foreign.and_then(|f| f.square_of(&(o + d * h.t_m), &x)) {
                            out.surfaces.push(k);
                        }
                        scene.ground_reflectance
                    } else {
                        out.surfaces.push(h.object * 8 + h.face as u32);
                        scene.objects[h.object as usize].reflectance
                    };
                    let fall = (m.ref_range_m / h.t_m).powi(2).min(1.0);
                    let level = (refl * cos_incidence * fall).min(1.0);
                    rec.range_m = rho;
                    rec.intensity = (level * 65535.0).round() as u16;
                    truth = [x.x, x.y, x.z];
                    out.valid += 1;
                }
            }
        }
        out.records.extend_from_slice(&encode(&rec));
        if want_truth {
            for v in truth {
                out.truth.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}
