//! The latency estimator (module docs of `calib::latency`): returns, passes and attitudes in,
//! `tau` per speed and combined out.

use crate::calib::sphere::{fit_sphere_robust, SphereFit, SphereRadius};
use crate::geo::rotations::q_b_to_n;
use crate::{Error, Result};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::Serialize;
use std::collections::BTreeMap;

/// One scanner return with its time tag (conventions §6 profile CSV with `time_s`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimedReturn {
    /// Profile counter.
    pub profile: u64,
    /// GPS time of the return (s).
    pub time_s: f64,
    /// Out-of-plane angle `alpha` (rad).
    pub alpha_rad: f64,
    /// Mirror angle `beta` (rad).
    pub beta_rad: f64,
    /// Measured range `rho` (m), without the zero error.
    pub range_m: f64,
}

/// One pass of the table at constant rate, from the table's log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TablePass {
    /// Start (GPS s) of the constant-rate part.
    pub t_start_s: f64,
    /// End of the pass (GPS s).
    pub t_end_s: f64,
    /// Signed rate about the table axis (rad/s), right-handed.
    pub rate_rad_s: f64,
}

/// One IMU attitude record: stamp (GPS s) and convention angles roll, pitch, true heading (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeSample {
    /// Time stamp (s); the physical attitude is that of `time_s - tau`.
    pub time_s: f64,
    /// Roll (rad).
    pub roll_rad: f64,
    /// Pitch (rad).
    pub pitch_rad: f64,
    /// True heading (rad).
    pub heading_rad: f64,
}

/// Everything a latency run records.
#[derive(Debug, Clone, Default)]
pub struct LatencyData {
    /// Scanner returns (all of them: selection is by the sphere gate).
    pub returns: Vec<TimedReturn>,
    /// Table passes, sorted by time, not overlapping.
    pub passes: Vec<TablePass>,
    /// IMU attitude stream, strictly increasing stamps.
    pub attitude: Vec<AttitudeSample>,
}

/// Sensor and target setup of a latency run (SI, convention frames).
#[derive(Debug, Clone, PartialEq)]
pub struct LatencySetup {
    /// Boresight `R_s^b` (scanner to body).
    pub r_s_to_b: Matrix3<f64>,
    /// Scanner optical centre relative to the table's rotation centre, in `b` (m).
    pub lever_arm_b_m: Vector3<f64>,
    /// Range zero error `K` (m).
    pub range_zero_error_m: f64,
    /// Unit table axis in `n`.
    pub table_axis_n: Vector3<f64>,
    /// Sphere radius, known or free.
    pub sphere_radius: SphereRadius,
    /// Latency already applied to the attitude stream (s); the result is this plus the residual.
    pub applied_latency_s: f64,
    /// Approximate sphere centre in `n` (m) and gate (m): returns farther than `radius + gate`
    /// (known radius) or `gate` (free radius) from it are not sphere returns. `None`: every
    /// return is a sphere return.
    pub sphere_gate_n_m: Option<(Vector3<f64>, f64)>,
}

/// Result for one table speed (a row of the paper's Table 2).
#[derive(Debug, Clone, Serialize)]
pub struct SpeedResult {
    /// Table speed |omega| (deg/s).
    pub rate_deg_s: f64,
    /// Returns used in the final sphere fit, + direction.
    pub n_used_plus: usize,
    /// Rejected returns, + direction.
    pub n_rejected_plus: usize,
    /// Returns used, - direction.
    pub n_used_minus: usize,
    /// Rejected returns, - direction.
    pub n_rejected_minus: usize,
    /// Fitted centres in `n` (m).
    pub centre_plus_n_m: [f64; 3],
    /// Fitted centre, - direction.
    pub centre_minus_n_m: [f64; 3],
    /// RMS per-axis centre sigma `sqrt(trace(Cov)/3)` (m), + and - direction.
    pub sigma_centre_plus_m: f64,
    /// As above, - direction.
    pub sigma_centre_minus_m: f64,
    /// Fitted radius (m) of the + and - sphere.
    pub radius_plus_m: f64,
    /// Fitted radius, - direction.
    pub radius_minus_m: f64,
    /// Centre shift `|c_minus - c_plus|` (m).
    pub shift_m: f64,
    /// Latency (s): applied + residual from this speed.
    pub latency_s: f64,
    /// 1-sigma of `latency_s` (s) from the centre covariances.
    pub sigma_latency_s: f64,
    /// The paper's eq. 4 (norm ratio, unsigned) for comparison (s), plus the applied latency.
    pub latency_eq4_s: f64,
    /// Gauss-Newton iterations of the two final fits.
    pub iterations: [usize; 2],
}

/// Latency calibration result: what a pipeline (`latency_s`) and the uncertainty model
/// (`sigma_latency_s`) take (conventions §2 sign: attitude evaluated at `t + latency_s`).
#[derive(Debug, Clone, Serialize)]
pub struct LatencyReport {
    /// Total IMU-to-scanner latency `tau` (s).
    pub latency_s: f64,
    /// 1-sigma of `latency_s` (s).
    pub sigma_latency_s: f64,
    /// Latency that was applied when placing the returns (s).
    pub applied_latency_s: f64,
    /// Chi-square of the per-speed estimates about the weighted mean.
    pub chi2: f64,
    /// Its degrees of freedom (speeds - 1).
    pub dof: usize,
    /// Per-speed results, increasing speed.
    pub speeds: Vec<SpeedResult>,
    /// Returns read (missing returns, range 0, are not counted).
    pub n_returns: usize,
    /// Returns outside any table pass or attitude coverage.
    pub n_outside_passes: usize,
    /// Returns outside the sphere gate.
    pub n_outside_gate: usize,
}

/// Attitude stream interpolated by slerp (conventions §4).
struct AttitudeStream {
    t: Vec<f64>,
    q: Vec<UnitQuaternion<f64>>,
}

impl AttitudeStream {
    fn new(samples: &[AttitudeSample]) -> Result<Self> {
        if samples.len() < 2 || samples.windows(2).any(|w| w[1].time_s <= w[0].time_s) {
            return Err(Error::Invalid(
                "attitude stream: need >= 2 records with strictly increasing time".into(),
            ));
        }
        Ok(Self {
            t: samples.iter().map(|s| s.time_s).collect(),
            q: samples
                .iter()
                .map(|s| q_b_to_n(s.roll_rad, s.pitch_rad, s.heading_rad))
                .collect(),
        })
    }

    /// `R_b^n` at stamp `t`, `None` outside the stream.
    fn at(&self, t: f64) -> Option<Matrix3<f64>> {
        let k = self.t.partition_point(|&x| x <= t);
        if k == 0 || k == self.t.len() && t > self.t[k - 1] {
            return None;
        }
        let k = k.min(self.t.len() - 1);
        let (t0, t1) = (self.t[k - 1], self.t[k]);
        let f = (t - t0) / (t1 - t0);
        Some(
            *self.q[k - 1]
                .slerp(&self.q[k], f)
                .to_rotation_matrix()
                .matrix(),
        )
    }
}

/// Index of the pass containing `t`.
fn pass_at(passes: &[TablePass], t: f64) -> Option<usize> {
    let k = passes.partition_point(|p| p.t_start_s <= t);
    (k > 0 && t <= passes[k - 1].t_end_s).then(|| k - 1)
}

/// Sphere candidates per speed key (mdeg/s) and direction: points in `n` and pass rates.
type Groups = BTreeMap<i64, [(Vec<Vector3<f64>>, f64, usize); 2]>;

/// Estimates the latency `tau` (s) from a rotating-table run (module doc for the model).
///
/// Errors: a zero table rate, a speed without both directions, fewer than 20 returns on a
/// sphere, a degenerate geometry (sphere on the table axis).
pub fn estimate_latency(data: &LatencyData, setup: &LatencySetup) -> Result<LatencyReport> {
    let stream = AttitudeStream::new(&data.attitude)?;
    for (i, p) in data.passes.iter().enumerate() {
        if p.rate_rad_s.abs() < 1e-9 || !p.rate_rad_s.is_finite() {
            return Err(Error::Invalid(format!("table pass {i}: zero table speed")));
        }
        if i > 0 && p.t_start_s < data.passes[i - 1].t_end_s {
            return Err(Error::Invalid(format!(
                "table pass {i}: overlaps the previous pass"
            )));
        }
    }
    let mut groups: Groups = BTreeMap::new();
    let (mut n_outside_passes, mut n_outside_gate) = (0, 0);
    for r in &data.returns {
        let Some(pi) = pass_at(&data.passes, r.time_s) else {
            n_outside_passes += 1;
            continue;
        };
        let Some(r_b_n) = stream.at(r.time_s + setup.applied_latency_s) else {
            n_outside_passes += 1;
            continue;
        };
        let x_n = point_n(setup, &r_b_n, r);
        if !in_gate(setup, &x_n) {
            n_outside_gate += 1;
            continue;
        }
        let rate = data.passes[pi].rate_rad_s;
        let key = (rate.abs().to_degrees() * 1000.0).round() as i64;
        let slot = &mut groups.entry(key).or_default()[usize::from(rate < 0.0)];
        slot.0.push(x_n);
        slot.1 += rate;
        slot.2 += 1;
    }
    let speeds = groups
        .into_iter()
        .map(|(key, g)| speed_result(setup, key, g))
        .collect::<Result<Vec<_>>>()?;
    combine(
        setup,
        speeds,
        data.returns.len(),
        n_outside_passes,
        n_outside_gate,
    )
}

/// `x_n = R_b^n (l_b + R_s^b (rho + K) u_s(alpha, beta))` (m).
fn point_n(setup: &LatencySetup, r_b_n: &Matrix3<f64>, r: &TimedReturn) -> Vector3<f64> {
    let x_s = (r.range_m + setup.range_zero_error_m) * beam_s(r.alpha_rad, r.beta_rad);
    r_b_n * (setup.lever_arm_b_m + setup.r_s_to_b * x_s)
}

/// convention beam direction `u_s(alpha, beta)`.
pub fn beam_s(alpha_rad: f64, beta_rad: f64) -> Vector3<f64> {
    let (sa, ca) = alpha_rad.sin_cos();
    let (sb, cb) = beta_rad.sin_cos();
    Vector3::new(sa, -ca * sb, ca * cb)
}

fn in_gate(setup: &LatencySetup, x_n: &Vector3<f64>) -> bool {
    let Some((c, gate)) = setup.sphere_gate_n_m else {
        return true;
    };
    let r = match setup.sphere_radius {
        SphereRadius::Known(r) => r,
        SphereRadius::Free => 0.0,
    };
    (x_n - c).norm() <= r + gate
}

fn speed_result(
    setup: &LatencySetup,
    key: i64,
    [plus, minus]: [(Vec<Vector3<f64>>, f64, usize); 2],
) -> Result<SpeedResult> {
    let rate_deg_s = key as f64 / 1000.0;
    if plus.2 == 0 || minus.2 == 0 {
        return Err(Error::Invalid(format!(
            "table speed {rate_deg_s} deg/s: returns on the sphere in only one direction"
        )));
    }
    let fit = |pts: &[Vector3<f64>], dir: &str| {
        fit_sphere_robust(pts, setup.sphere_radius).map_err(|e| {
            Error::Invalid(format!(
                "table speed {rate_deg_s} deg/s, {dir} direction: {e}"
            ))
        })
    };
    let (fp, fm) = (fit(&plus.0, "+")?, fit(&minus.0, "-")?);
    let (w_plus, w_minus) = (plus.1 / plus.2 as f64, minus.1 / minus.2 as f64);
    let (dtau, var) = residual_latency(setup, &fp, &fm, w_plus, w_minus)?;
    let d = fm.centre_m - fp.centre_m;
    let g = (w_plus - w_minus)
        * setup
            .table_axis_n
            .cross(&((fp.centre_m + fm.centre_m) / 2.0));
    let rms = |f: &SphereFit| (f.cov_centre_m2.trace() / 3.0).sqrt();
    Ok(SpeedResult {
        rate_deg_s,
        n_used_plus: fp.n_used,
        n_rejected_plus: fp.n_rejected,
        n_used_minus: fm.n_used,
        n_rejected_minus: fm.n_rejected,
        centre_plus_n_m: fp.centre_m.into(),
        centre_minus_n_m: fm.centre_m.into(),
        sigma_centre_plus_m: rms(&fp),
        sigma_centre_minus_m: rms(&fm),
        radius_plus_m: fp.radius_m,
        radius_minus_m: fm.radius_m,
        shift_m: d.norm(),
        latency_s: setup.applied_latency_s + dtau,
        sigma_latency_s: var.sqrt(),
        latency_eq4_s: setup.applied_latency_s + d.norm() / g.norm(),
        iterations: [fp.iterations, fm.iterations],
    })
}

/// Residual latency `dtau` (s) and its variance (s^2) from the two fitted spheres and the
/// signed table rates (rad/s) of the two directions (module doc).
pub fn residual_latency(
    setup: &LatencySetup,
    plus: &SphereFit,
    minus: &SphereFit,
    rate_plus_rad_s: f64,
    rate_minus_rad_s: f64,
) -> Result<(f64, f64)> {
    let xbar = (plus.centre_m + minus.centre_m) / 2.0;
    let g = (rate_plus_rad_s - rate_minus_rad_s) * setup.table_axis_n.cross(&xbar);
    let g2 = g.norm_squared();
    if g2 < 1e-12 {
        return Err(Error::Numerical {
            what: "latency".into(),
            problem: "sphere centre on the table axis: rotation does not move it".into(),
        });
    }
    let d = minus.centre_m - plus.centre_m;
    let var = (g.transpose() * (plus.cov_centre_m2 + minus.cov_centre_m2) * g)[0] / (g2 * g2);
    Ok((g.dot(&d) / g2, var))
}

fn combine(
    setup: &LatencySetup,
    speeds: Vec<SpeedResult>,
    n_returns: usize,
    n_outside_passes: usize,
    n_outside_gate: usize,
) -> Result<LatencyReport> {
    if speeds.is_empty() {
        return Err(Error::Invalid(
            "latency: no sphere returns inside any table pass".into(),
        ));
    }
    let w: Vec<f64> = speeds
        .iter()
        .map(|s| 1.0 / (s.sigma_latency_s * s.sigma_latency_s))
        .collect();
    let sw: f64 = w.iter().sum();
    let tau = speeds
        .iter()
        .zip(&w)
        .map(|(s, w)| w * s.latency_s)
        .sum::<f64>()
        / sw;
    let chi2 = speeds
        .iter()
        .zip(&w)
        .map(|(s, w)| w * (s.latency_s - tau).powi(2))
        .sum();
    Ok(LatencyReport {
        latency_s: tau,
        sigma_latency_s: sw.sqrt().recip(),
        applied_latency_s: setup.applied_latency_s,
        chi2,
        dof: speeds.len() - 1,
        speeds,
        n_returns,
        n_outside_passes,
        n_outside_gate,
    })
}
