use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// How to draw a set.
#[derive(Clone)]
pub struct Scenario {
    pub references: usize,
    pub passes: usize,
    pub returns_per_visit: usize,
    /// White noise sigma (m).
    pub sigma_white_m: f64,
    /// Navigation position sigma (m) and attitude sigma (rad).
    pub sigma_pos_m: f64,
    pub sigma_att_rad: f64,
    /// Injected effects and their values.
    pub truth: Vec<(Effect, f64)>,
    /// Second effect whose signature is made nearly equal to the first's (correlation
    /// above 0.9), when given.
    pub twin: Option<(Effect, Effect)>,
    /// The twin's own part, relative to the first's signature: 0.15 (the default) keeps their
    /// correlation above 0.9; larger shares lower it.
    pub twin_own: f64,
    /// Amplitude (m) of an out-of-model residual periodic in range (period 12 m).
    pub range_cyclic_m: f64,
    /// Navigation errors correlated across visits (Gauss-Markov, position and attitude
    /// correlation times, s); also what the drawn set declares.
    pub nav_tau_s: Option<[f64; 2]>,
    /// True / declared sigma of the navigation position and attitude errors (the SMRMSG
    /// misstating them).
    pub nav_scale: [f64; 2],
    /// White navigation noise, one draw per trajectory record ([`RECORD_HZ`]) interpolated
    /// to the returns, as shares of each block's true variance (of the visits' median, as
    /// [`ObservationSet::white_nav_var`]); the drawn set does not
    /// declare it (its `nav_white_share` stays 0).
    pub nav_white: [f64; 2],
    /// `Some(k)`: a visit's returns come `k` at a time in profiles [`PROFILE_S`] apart (and
    /// share their records' white navigation noise); `None`: each at its own random time.
    pub returns_per_profile: Option<usize>,
    /// Time (s) between the returns of one profile on a patch (the mirror's sweep across it):
    /// with a spacing, a profile's returns straddle a record boundary and share the white
    /// noise of the record between.
    pub return_spacing_s: f64,
    /// A second, slow Gauss-Markov process per block beside the one of `nav_tau_s` (its
    /// shares of the declared variances); the drawn set does not declare it.
    pub nav_slow: Option<SlowNav>,
}

/// Rate of the drawn trajectory records (Hz): the simulator's SBET rate.
pub const RECORD_HZ: f64 = 200.0;
/// Spacing of the profiles when returns come in profiles (s): the simulator's.
pub const PROFILE_S: f64 = 0.01;

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            references: 24,
            passes: 3,
            returns_per_visit: 40,
            sigma_white_m: 0.01,
            sigma_pos_m: 0.02,
            sigma_att_rad: 1e-4,
            truth: Vec::new(),
            twin: None,
            twin_own: 0.15,
            range_cyclic_m: 0.0,
            nav_tau_s: None,
            nav_scale: [1.0, 1.0],
            nav_white: [0.0, 0.0],
            returns_per_profile: None,
            return_spacing_s: 0.0,
            nav_slow: None,
        }
    }
}

/// Period of the out-of-model range term (m).
pub const RANGE_PERIOD_M: f64 = 12.0;

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Signatures: a distinct smooth function of the covariates per effect, so that no two
/// effects correlate above 0.9 unless `twin` asks for it.
fn signatures(c: &Covariates, u: [f64; 3]) -> [f64; N_EFFECTS] {
    let r = c.range_m / 25.0;
    let b = c.beta_deg.to_radians();
    let h = c.heading_deg.to_radians();
    let t = c.time_s / 300.0;
    [
        c.yaw_rate_dps * r / 10.0,
        c.speed_mps / 10.0 * u[0],
        (c.speed_mps - 9.0) / 6.0,
        (t - 1.0) * c.speed_mps / 10.0,
        r * b.sin(),
        r * b.cos(),
        r * u[1],
        h.cos() * u[2],
        h.sin(),
        b.cos() * 0.8 - u[2] * 0.3,
        1.0,
        r - 0.6,
        r * (2.0 * b).sin(),
        r * b.sin() * b.sin() - 0.3,
        r * h.sin() * u[1],
    ]
}

/// Draws a set from the model with `seed`.
pub fn draw(s: &Scenario, seed: u64) -> ObservationSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut set = ObservationSet {
        reference_ids: (0..s.references).map(|r| format!("P{r}")).collect(),
        passes: s.passes,
        nav_tau_s: s.nav_tau_s,
        ..Default::default()
    };
    let att2 = s.sigma_att_rad * s.sigma_att_rad;
    let pos2 = s.sigma_pos_m * s.sigma_pos_m;
    for reference in 0..s.references {
        let normal_dir: [f64; 3] = [
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
            1.0,
        ];
        for pass in 0..s.passes {
            let v = set.visits.len();
            let mut nav_cov = [[0.0; 6]; 6];
            for (k, row) in nav_cov.iter_mut().enumerate() {
                row[k] = if k < 3 { pos2 } else { att2 } * rng.random_range(0.5..1.5);
            }
            let heading = rng.random_range(0.0..360.0);
            let speed = rng.random_range(3.0..15.0);
            let yaw_rate = rng.random_range(-10.0..10.0);
            let t0 = rng.random_range(0.0..600.0);
            set.visits.push(Visit {
                reference,
                pass,
                nav_cov,
            });
            for i in 0..s.returns_per_visit {
                let beta: f64 = rng.random_range(-90.0..90.0);
                let time_s = match s.returns_per_profile {
                    Some(k) => {
                        t0 + (i / k) as f64 * PROFILE_S + (i % k) as f64 * s.return_spacing_s
                    }
                    None => t0 + rng.random_range(0.0..2.0),
                };
                let covariates = Covariates {
                    time_s,
                    range_m: rng.random_range(5.0..50.0),
                    beta_deg: beta,
                    incidence_deg: rng.random_range(0.0..80.0),
                    speed_mps: speed,
                    yaw_rate_dps: yaw_rate + rng.random_range(-1.0..1.0),
                    roll_rate_dps: rng.random_range(-2.0..2.0),
                    pitch_rate_dps: rng.random_range(-2.0..2.0),
                    heading_deg: heading,
                    side: if beta < 0.0 { Side::Left } else { Side::Right },
                    pass,
                    reference_id: reference,
                };
                let u = [normal(&mut rng), normal(&mut rng), normal(&mut rng)];
                let mut signature = signatures(&covariates, u);
                if let Some((a, b)) = s.twin {
                    signature[signature_index(b)] = 1.3 * signature[signature_index(a)]
                        + s.twin_own
                            * normal(&mut rng)
                            * signature[signature_index(a)].abs().max(0.3);
                }
                let lever = covariates.range_m;
                let nav_gradient = [
                    normal_dir[0],
                    normal_dir[1],
                    normal_dir[2],
                    lever * rng.random_range(-1.0..1.0),
                    lever * rng.random_range(-1.0..1.0),
                    lever * rng.random_range(-0.3..0.3),
                ];
                let var_white_m2 = (s.sigma_white_m * rng.random_range(0.7..1.4)).powi(2);
                set.observations.push(Observation {
                    reference,
                    visit: v,
                    record: set.observations.len(),
                    residual_m: 0.0,
                    var_white_m2,
                    nav_gradient,
                    signature,
                    covariates,
                    nav_record: Some(NavRecord {
                        index: (time_s * RECORD_HZ).floor() as usize,
                        w: (time_s * RECORD_HZ).fract(),
                    }),
                    plane_uv_m: spread_on_patch(set.observations.len()),
                });
            }
        }
    }
    fill_residuals(&mut set, s, seed ^ 0x5eed);
    set
}

/// Where the `i`th return lies on its 4 m x 4 m patch (m): a low-discrepancy (R2) sequence,
/// spread evenly and drawn from no generator (the random draws stay today's).
fn spread_on_patch(i: usize) -> [f32; 2] {
    const R2: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_3];
    R2.map(|a| (4.0 * ((i as f64 + 0.5) * a).fract() - 2.0) as f32)
}

/// Navigation errors at every return from one Gauss-Markov process per component, sampled
/// exactly at the returns' times in time order (unit-variance AR(1) scaled by the sigma of
/// the return's visit): continuous within and between visits, as the simulator's.
fn gauss_markov(
    set: &ObservationSet,
    tau: [f64; 2],
    scale: [f64; 2],
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 6]> {
    let mut order: Vec<usize> = (0..set.observations.len()).collect();
    let time = |i: usize| set.observations[i].covariates.time_s;
    order.sort_by(|&a, &b| time(a).total_cmp(&time(b)).then(a.cmp(&b)));
    let mut z = vec![[0.0; 6]; set.observations.len()];
    let mut u = [0.0; 6];
    let mut previous: Option<f64> = None;
    for i in order {
        let p = &set.visits[set.observations[i].visit].nav_cov;
        for (k, uk) in u.iter_mut().enumerate() {
            let e = normal(rng);
            *uk = match previous {
                Some(tp) => {
                    let r = (-(time(i) - tp) / tau[k / 3]).exp();
                    r * *uk + (1.0 - r * r).sqrt() * e
                }
                None => e,
            };
            z[i][k] = scale[k / 3] * p[k][k].sqrt() * *uk;
        }
        previous = Some(time(i));
    }
    z
}

/// Draws new residuals (navigation errors, white noise) for the same returns: the
/// injected effects and the out-of-model term of `s` plus fresh noise from `seed`.
pub fn fill_residuals(set: &mut ObservationSet, s: &Scenario, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let z: Vec<[f64; 6]> = match s.nav_tau_s {
        None => {
            let per_visit: Vec<[f64; 6]> = set
                .visits
                .iter()
                .map(|v| {
                    std::array::from_fn(|k| {
                        s.nav_scale[k / 3] * v.nav_cov[k][k].sqrt() * normal(&mut rng)
                    })
                })
                .collect();
            set.observations
                .iter()
                .map(|o| per_visit[o.visit])
                .collect()
        }
        Some(tau) => {
            let mut z = gauss_markov(set, tau, s.nav_scale, &mut rng);
            if let Some(slow) = s.nav_slow {
                let scale = slow.share.map(f64::sqrt);
                for (z, z2) in z
                    .iter_mut()
                    .zip(gauss_markov(set, slow.tau_s, scale, &mut rng))
                {
                    z.iter_mut().zip(z2).for_each(|(a, b)| *a += b);
                }
            }
            z
        }
    };
    // Each record's white navigation noise (unit normals per component), drawn when first
    // needed.
    let mut white = std::collections::BTreeMap::<(usize, usize), [f64; 6]>::new();
    let white_var = set.white_nav_var(s.nav_white);
    for (o, z) in set.observations.iter_mut().zip(&z) {
        let systematic: f64 = s
            .truth
            .iter()
            .map(|&(e, x)| o.signature[signature_index(e)] * x)
            .sum();
        let mut nav: f64 = o.nav_gradient.iter().zip(z).map(|(g, z)| g * z).sum();
        if s.nav_white != [0.0; 2] {
            let r = o.nav_record.expect("drawn returns have records");
            let mut record = |i: usize| {
                *white
                    .entry((o.covariates.pass, i))
                    .or_insert_with(|| std::array::from_fn::<f64, 6, _>(|_| normal(&mut rng)))
            };
            let (a, b) = (record(r.index), record(r.index + 1));
            for k in 0..6 {
                let sd = s.nav_scale[k / 3] * white_var[k].sqrt();
                nav += o.nav_gradient[k] * sd * ((1.0 - r.w) * a[k] + r.w * b[k]);
            }
        }
        let cyclic = s.range_cyclic_m
            * (std::f64::consts::TAU * o.covariates.range_m / RANGE_PERIOD_M).sin();
        o.residual_m = systematic + nav + cyclic + o.var_white_m2.sqrt() * normal(&mut rng);
    }
}
