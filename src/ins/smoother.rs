//! The forward filter pass and the Rauch-Tung-Striebel smoother over its stored epochs.
//!
//! Memory stays proportional to the number of GNSS updates, not IMU records: the forward pass
//! stores, at each update epoch, the navigation state, sensor estimates and covariance after
//! the update and the correction it applied. Between two epochs the filter only propagated,
//! so the smoother recomputes that stretch (same code, same numbers) when it needs the
//! per-record states, covariances and transitions. Backward, from epoch i+1 to i with
//! `M = Phi(j_{i+1}, j_i)` and the prediction `P_p` at `j_{i+1}`:
//! `A = P_f M^T P_p^-1`, `s_i = A (s_{i+1} + u_{i+1})`, `P_s = P_f + A (P_s' - P_p) A^T`,
//! `s` the smoothed correction of the filtered state and `u` the update's correction; the same
//! formula with `M = Phi(j_{i+1}, j)` gives every IMU record inside the stretch.

use super::filter::{
    apply_correction, Filter, Mat, SensorEstimate, UpdateOutcome, Vec21, ATT, POS, VEL,
};
use super::mechanisation::NavState;
use crate::io::gnss::GnssRecord;
use crate::io::imu::{ImuFile, ImuRecord};
use crate::{Error, Result};
use nalgebra::{Matrix3, SMatrix, Vector3};

/// Covariance of position (m, NED), velocity (m/s, NED) and attitude (rad, NED `phi`).
pub type Cov9 = SMatrix<f64, 9, 9>;

/// Random access to IMU records.
pub trait ImuSource {
    /// Number of records.
    fn count(&self) -> usize;
    /// Record `i`.
    fn get(&self, i: usize) -> ImuRecord;
}

impl ImuSource for [ImuRecord] {
    fn count(&self) -> usize {
        self.len()
    }
    fn get(&self, i: usize) -> ImuRecord {
        self[i]
    }
}

impl ImuSource for ImuFile {
    fn count(&self) -> usize {
        self.len()
    }
    fn get(&self, i: usize) -> ImuRecord {
        self.record(i)
    }
}

/// One output sample (filtered or smoothed).
#[derive(Debug, Clone, Copy)]
pub struct Estimate {
    /// Navigation state.
    pub nav: NavState,
    /// Corrected specific force of the record ending here (m/s^2, body).
    pub f_b: Vector3<f64>,
    /// Corrected angular rate (rad/s, body).
    pub w_b: Vector3<f64>,
    /// Covariance of position, velocity, attitude.
    pub cov: Cov9,
}

/// The filter's start: its state at the time of IMU record `index`.
#[derive(Debug, Clone)]
pub struct Start {
    /// Filter (navigation state, sensor estimates, covariance, noise, lever arm, gate).
    pub filter: Filter,
    /// IMU record whose time is the state's time.
    pub index: usize,
}

/// Counts of the forward pass.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct FilterStats {
    /// GNSS fixes within the IMU span.
    pub gnss_fixes: usize,
    /// Fixes used.
    pub gnss_used: usize,
    /// Fixes rejected by the innovation test.
    pub gnss_rejected: usize,
    /// Times of the rejected fixes (s).
    pub rejected_times_s: Vec<f64>,
    /// Longest run of consecutive rejected fixes.
    pub longest_rejected_run: usize,
    /// IMU records processed.
    pub imu_records: usize,
}

/// Packed upper triangle of a covariance.
const PACKED: usize = super::filter::N * (super::filter::N + 1) / 2;

fn pack(p: &Mat, out: &mut Vec<f64>) {
    for i in 0..super::filter::N {
        for j in i..super::filter::N {
            out.push(p[(i, j)]);
        }
    }
}

fn unpack(v: &[f64]) -> Mat {
    let mut p = Mat::zeros();
    let mut k = 0;
    for i in 0..super::filter::N {
        for j in i..super::filter::N {
            p[(i, j)] = v[k];
            p[(j, i)] = v[k];
            k += 1;
        }
    }
    p
}

/// An update epoch of the forward pass.
#[derive(Debug, Clone)]
struct Epoch {
    j: usize,
    nav: NavState,
    sens: SensorEstimate,
    u: Vec21,
}

/// The stored forward pass.
pub struct Forward {
    template: Filter,
    epochs: Vec<Epoch>,
    p_f: Vec<f64>,
    end: usize,
    /// Counts.
    pub stats: FilterStats,
}

impl Forward {
    /// Number of stored update epochs (the start included).
    pub fn epochs(&self) -> usize {
        self.epochs.len()
    }
    /// Bytes held by the stored epochs.
    pub fn bytes(&self) -> usize {
        self.epochs.capacity() * std::mem::size_of::<Epoch>() + self.p_f.capacity() * 8
    }
}

/// Covariance of position, velocity, attitude out of the full one.
#[inline]
fn cov9(p: &Mat) -> Cov9 {
    p.fixed_view::<9, 9>(0, 0).into_owned()
}

/// Runs the filter from `start` over the IMU records, updating with the fixes (sorted by
/// time); calls `sink` with every filtered state (record `start.index` on). Stops with an
/// error after `max_rejected_run` consecutive rejected fixes (a diverged filter: wrong initial
/// heading, wrong lever arm, or a GNSS file of another survey).
pub fn forward(
    imu: &(impl ImuSource + ?Sized),
    gnss: &[GnssRecord],
    start: Start,
    max_rejected_run: usize,
    sink: &mut dyn FnMut(&Estimate),
) -> Result<Forward> {
    let n = imu.count();
    let mut f = start.filter;
    let mut stats = FilterStats::default();
    let mut epochs = Vec::new();
    let mut p_f = Vec::new();
    let half = |j: usize| {
        let a = if j > 0 {
            imu.get(j).time_s - imu.get(j - 1).time_s
        } else {
            0.0
        };
        let b = if j + 1 < n {
            imu.get(j + 1).time_s - imu.get(j).time_s
        } else {
            0.0
        };
        0.5 * a.max(b)
    };
    let t0 = f.nav.time_s;
    let mut g = gnss.partition_point(|x| x.time_s < t0 - half(start.index));
    let mut run = 0usize;
    let mut rec = imu.get(start.index);
    for j in start.index..n {
        if j > start.index {
            rec = imu.get(j);
            f.propagate(&rec);
        }
        let h = half(j);
        let mut u = Vec21::zeros();
        let mut updated = false;
        while g < gnss.len() && gnss[g].time_s <= f.nav.time_s + h {
            stats.gnss_fixes += 1;
            match f.update(&gnss[g]) {
                UpdateOutcome::Accepted(c) => {
                    u += c;
                    updated = true;
                    stats.gnss_used += 1;
                    run = 0;
                }
                UpdateOutcome::Rejected(_) => {
                    stats.gnss_rejected += 1;
                    stats.rejected_times_s.push(gnss[g].time_s);
                    run += 1;
                    stats.longest_rejected_run = stats.longest_rejected_run.max(run);
                    if run >= max_rejected_run {
                        return Err(Error::Numerical {
                            what: "INS/GNSS filter".into(),
                            problem: format!(
                                "{run} consecutive GNSS fixes rejected by the innovation test \
                                 (last at {:.3} s): the filter has diverged from the GNSS \
                                 positions. Check the initial heading ([alignment]), the \
                                 antenna lever arm and that the IMU and GNSS files are of the \
                                 same survey",
                                gnss[g].time_s
                            ),
                        });
                    }
                }
            }
            g += 1;
        }
        if j == start.index || updated {
            epochs.push(Epoch {
                j,
                nav: f.nav,
                sens: f.sens,
                u,
            });
            pack(&f.p, &mut p_f);
        }
        let (w, fb) = f.sens.correct(&rec);
        sink(&Estimate {
            nav: f.nav,
            f_b: fb,
            w_b: w,
            cov: cov9(&f.p),
        });
        crate::interrupt::check()?;
    }
    stats.imu_records = n - start.index;
    let mut template = f;
    template.p = Mat::zeros();
    Ok(Forward {
        template,
        epochs,
        p_f,
        end: n,
        stats,
    })
}

/// The recomputed stretch from an epoch to (excluding) record `j_end`.
struct Stretch {
    navs: Vec<NavState>,
    fw: Vec<(Vector3<f64>, Vector3<f64>)>,
    ps: Vec<Mat>,
    phis: Vec<Mat>,
    p_pred: Mat,
}

fn recompute(
    imu: &(impl ImuSource + ?Sized),
    fwd: &Forward,
    i: usize,
    j_end: usize,
    out: &mut Stretch,
) {
    let e = &fwd.epochs[i];
    let mut f = fwd.template.clone();
    f.nav = e.nav;
    f.sens = e.sens;
    f.p = unpack(&fwd.p_f[i * PACKED..(i + 1) * PACKED]);
    out.navs.clear();
    out.fw.clear();
    out.ps.clear();
    out.phis.clear();
    let mut rec = imu.get(e.j);
    for j in e.j..j_end {
        out.navs.push(f.nav);
        out.fw.push(f.sens.correct(&rec));
        out.ps.push(f.p);
        if j + 1 < fwd.end {
            rec = imu.get(j + 1);
            if j + 1 < j_end || j_end < fwd.end {
                out.phis.push(f.propagate(&rec));
            }
        }
    }
    out.p_pred = f.p;
}

fn inverse_spd(p: &Mat) -> Result<Mat> {
    let c = p.cholesky().ok_or_else(|| Error::Numerical {
        what: "RTS smoother".into(),
        problem: "predicted covariance is not positive definite".into(),
    })?;
    Ok(c.inverse())
}

/// Euler-angle Jacobian: (roll, pitch, heading) errors = `E * phi` for the attitude `q`.
pub fn euler_jacobian(nav: &NavState) -> Matrix3<f64> {
    let (_, pitch, heading) = super::mechanisation::euler(nav);
    let rz = crate::geo::rotations::rot_z(heading);
    let ry = crate::geo::rotations::rot_y(pitch);
    let mut m = Matrix3::zeros();
    m.set_column(0, &(rz * ry * Vector3::x()));
    m.set_column(1, &(rz * Vector3::y()));
    m.set_column(2, &Vector3::z());
    // R_est = R(-phi) R_true: the n-frame rotation from truth to estimate is -phi.
    -m.try_inverse().unwrap_or_else(Matrix3::identity)
}

/// Output components of the autocorrelation: position, velocity NED, roll/pitch/heading.
pub const COMPONENTS: [&str; 9] = [
    "north_m",
    "east_m",
    "down_m",
    "vel_north_mps",
    "vel_east_mps",
    "vel_down_mps",
    "roll_rad",
    "pitch_rad",
    "heading_rad",
];

/// The smoothed errors' autocorrelation, gathered from the smoother's lag cross-covariances
/// `Cov(e_i, e_m) = A_i A_{i+1} ... A_{m-1} P_s(m)` at update epochs.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AutoCorrelation {
    /// Lags (s): mean time between the epochs of each lag.
    pub lags_s: Vec<f64>,
    /// Mean correlation coefficient per component (in [`COMPONENTS`] order) and lag.
    pub rho: Vec<Vec<f64>>,
    /// Lag where each component's correlation falls to 1/e (s), log-interpolated; None when
    /// it stays above 1/e over every lag.
    pub correlation_time_s: Vec<Option<f64>>,
    /// RMS of each component's smoothed sigma over the run (m, m/s, rad).
    pub sigma_rms: Vec<f64>,
    /// Number of (anchor, lag) pairs averaged per lag.
    pub pairs: Vec<usize>,
}

struct Anchor {
    g: Mat,
    var: [f64; 9],
    e: Matrix3<f64>,
    t: f64,
    age: usize,
}

struct AcfAccumulator {
    lags: Vec<usize>,
    every: usize,
    anchors: Vec<Anchor>,
    sum: Vec<[f64; 9]>,
    dt_sum: Vec<f64>,
    count: Vec<usize>,
    var_sum: [f64; 9],
    var_n: usize,
}

fn output_vars(p: &Mat, e: &Matrix3<f64>) -> [f64; 9] {
    let att = e * p.fixed_view::<3, 3>(ATT, ATT) * e.transpose();
    std::array::from_fn(|c| match c {
        0..=2 => p[(POS + c, POS + c)],
        3..=5 => p[(VEL + c - 3, VEL + c - 3)],
        _ => att[(c - 6, c - 6)],
    })
}

impl AcfAccumulator {
    fn new(epochs: usize) -> Self {
        let lags: Vec<usize> = [
            1, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100, 150, 200, 300, 500, 700, 1000, 1500, 2000,
            3000,
        ]
        .into_iter()
        .filter(|&l| l <= epochs / 2)
        .collect();
        let max = lags.last().copied().unwrap_or(1);
        AcfAccumulator {
            every: (max / 4).max(1),
            sum: vec![[0.0; 9]; lags.len()],
            dt_sum: vec![0.0; lags.len()],
            count: vec![0; lags.len()],
            lags,
            anchors: Vec::new(),
            var_sum: [0.0; 9],
            var_n: 0,
        }
    }

    /// Backward step to epoch `i` (time `t`, state `nav`) with gain `a` and smoothed `ps`.
    fn step(&mut self, i: usize, t: f64, nav: &NavState, a: &Mat, ps: &Mat) {
        let e = euler_jacobian(nav);
        let var = output_vars(ps, &e);
        for (s, v) in self.var_sum.iter_mut().zip(var) {
            *s += v.max(0.0).sqrt();
        }
        self.var_n += 1;
        let max = self.lags.last().copied().unwrap_or(0);
        for an in self.anchors.iter_mut() {
            an.g = a * an.g;
            an.age += 1;
            if let Ok(k) = self.lags.binary_search(&an.age) {
                let att = e * an.g.fixed_view::<3, 3>(ATT, ATT) * an.e.transpose();
                for (c, sum) in self.sum[k].iter_mut().enumerate() {
                    let cov = if c < 6 {
                        an.g[(c, c)]
                    } else {
                        att[(c - 6, c - 6)]
                    };
                    let den = (var[c] * an.var[c]).sqrt();
                    if den > 0.0 {
                        *sum += cov / den;
                    }
                }
                self.dt_sum[k] += an.t - t;
                self.count[k] += 1;
            }
        }
        self.anchors.retain(|an| an.age < max);
        if i.is_multiple_of(self.every) && !self.lags.is_empty() {
            self.anchors.push(Anchor {
                g: *ps,
                var,
                e,
                t,
                age: 0,
            });
        }
    }

    fn finish(self) -> AutoCorrelation {
        let lags_s: Vec<f64> = (0..self.lags.len())
            .map(|k| self.dt_sum[k] / self.count[k].max(1) as f64)
            .collect();
        let rho: Vec<Vec<f64>> = (0..9)
            .map(|c| {
                (0..self.lags.len())
                    .map(|k| self.sum[k][c] / self.count[k].max(1) as f64)
                    .collect()
            })
            .collect();
        let e_inv = (-1.0f64).exp();
        let correlation_time_s = rho
            .iter()
            .map(|r| {
                let mut prev = (0.0, 1.0);
                for (k, &v) in r.iter().enumerate() {
                    if self.count[k] == 0 {
                        continue;
                    }
                    if v <= e_inv {
                        let (t0, r0): (f64, f64) = prev;
                        let (t1, r1) = (lags_s[k], v.max(1e-6));
                        let w = (r0.ln() + 1.0) / (r0.ln() - r1.ln());
                        return Some(t0 + w * (t1 - t0));
                    }
                    prev = (lags_s[k], v);
                }
                None
            })
            .collect();
        AutoCorrelation {
            lags_s,
            rho,
            correlation_time_s,
            sigma_rms: self
                .var_sum
                .iter()
                .map(|s| s / self.var_n.max(1) as f64)
                .collect(),
            pairs: self.count,
        }
    }
}

/// Smooths the forward pass: calls `sink` with every smoothed state in time order, and
/// returns the smoothed errors' autocorrelation.
pub fn smooth(
    imu: &(impl ImuSource + ?Sized),
    fwd: &Forward,
    sink: &mut dyn FnMut(&Estimate) -> Result<()>,
) -> Result<AutoCorrelation> {
    let ne = fwd.epochs.len();
    let last = ne - 1;
    // Backward pass: smoothed correction and covariance at every epoch.
    let mut s_ep = vec![Vec21::zeros(); ne];
    let mut ps_ep: Vec<f64> = vec![0.0; ne * PACKED];
    ps_ep[last * PACKED..].copy_from_slice(&fwd.p_f[last * PACKED..]);
    let mut st = Stretch {
        navs: Vec::new(),
        fw: Vec::new(),
        ps: Vec::new(),
        phis: Vec::new(),
        p_pred: Mat::zeros(),
    };
    let mut acf = AcfAccumulator::new(ne);
    for i in (0..last).rev() {
        let j_end = fwd.epochs[i + 1].j;
        recompute(imu, fwd, i, j_end, &mut st);
        let pp_inv = inverse_spd(&st.p_pred)?;
        let mut b = pp_inv;
        for phi in st.phis.iter().rev() {
            b = phi.transpose() * b;
        }
        let p_f = &st.ps[0];
        let a = p_f * b;
        let c = s_ep[i + 1] + fwd.epochs[i + 1].u;
        s_ep[i] = a * c;
        let ps_next = unpack(&ps_ep[(i + 1) * PACKED..(i + 2) * PACKED]);
        let mut ps = p_f + a * (ps_next - st.p_pred) * a.transpose();
        super::filter::symmetrise(&mut ps);
        acf.step(i, fwd.epochs[i].nav.time_s, &fwd.epochs[i].nav, &a, &ps);
        let mut packed = Vec::with_capacity(PACKED);
        pack(&ps, &mut packed);
        ps_ep[i * PACKED..(i + 1) * PACKED].copy_from_slice(&packed);
        crate::interrupt::check()?;
    }
    // Output pass, forward.
    let mut buf: Vec<Estimate> = Vec::new();
    for i in 0..=last {
        let j_end = if i < last {
            fwd.epochs[i + 1].j
        } else {
            fwd.end
        };
        recompute(imu, fwd, i, j_end, &mut st);
        buf.clear();
        let len = st.navs.len();
        if i < last {
            let pp_inv = inverse_spd(&st.p_pred)?;
            let c = s_ep[i + 1] + fwd.epochs[i + 1].u;
            let ps_next = unpack(&ps_ep[(i + 1) * PACKED..(i + 2) * PACKED]);
            let dp = ps_next - st.p_pred;
            let mut b = pp_inv;
            for m in (0..len).rev() {
                b = st.phis[m].transpose() * b;
                let a9 = st.ps[m].fixed_rows::<9>(0) * b;
                let s9 = a9 * c;
                let mut s = Vec21::zeros();
                s.fixed_rows_mut::<9>(0).copy_from(&s9);
                let mut cov = cov9(&st.ps[m]) + a9 * dp * a9.transpose();
                cov = 0.5 * (cov + cov.transpose());
                let mut nav = st.navs[m];
                let mut sens = SensorEstimate::default();
                apply_correction(&mut nav, &mut sens, &s);
                buf.push(Estimate {
                    nav,
                    f_b: st.fw[m].1,
                    w_b: st.fw[m].0,
                    cov,
                });
            }
            buf.reverse();
        } else {
            for m in 0..len {
                buf.push(Estimate {
                    nav: st.navs[m],
                    f_b: st.fw[m].1,
                    w_b: st.fw[m].0,
                    cov: cov9(&st.ps[m]),
                });
            }
        }
        for e in &buf {
            sink(e)?;
        }
        crate::interrupt::check()?;
    }
    Ok(acf.finish())
}
