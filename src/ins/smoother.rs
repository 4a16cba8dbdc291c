//! The forward filter pass and the Rauch-Tung-Striebel smoother over its stored epochs.
//!
//! The forward pass stores, at each update epoch only, the navigation state, sensor estimates
//! and covariance after the update and the correction it applied (2.2 KB), in memory or, for
//! `kinescan trajectory`, in a temporary file ([`crate::io::spill`]): resident memory does not
//! grow with the length of the survey. Between two epochs the filter only propagated, so the
//! smoother recomputes that stretch (same code, same numbers) when it needs the per-record
//! states, covariances and transitions. Backward, from epoch i+1 to i with
//! `M = Phi(j_{i+1}, j_i)` and the prediction `P_p` at `j_{i+1}`:
//! `A = P_f M^T P_p^-1`, `s_i = A (s_{i+1} + u_{i+1})`, `P_s = P_f + A (P_s' - P_p) A^T`,
//! `s` the smoothed correction of the filtered state and `u` the update's correction; the same
//! formula with `M = Phi(j_{i+1}, j)` gives every IMU record inside the stretch. The smoothed
//! corrections and covariances of the epochs (2 KB each) go to a second store.
//!
//! Every transition is `I + [G; 0]` with `G` its 9 x 21 position, velocity and attitude rows
//! ([`super::filter::TransitionRows`]): the products are taken with `G` alone.

use super::filter::{
    apply_correction, chain_transition, dense_chain, Filter, Mat, Rows9, SensorEstimate,
    TransitionRows, UpdateOutcome, Vec21, ATT, N, POS, VEL,
};
use super::mechanisation::NavState;
use crate::io::gnss::GnssRecord;
use crate::io::imu::{ImuFile, ImuRecord};
use crate::io::spill::Spill;
use crate::{Error, Result};
use nalgebra::{Matrix3, Quaternion, SMatrix, UnitQuaternion, Vector3, Vector4};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Covariance of position (m, NED), velocity (m/s, NED) and attitude (rad, NED `phi`).
pub type Cov9 = SMatrix<f64, 9, 9>;

/// Random access to IMU records.
pub trait ImuSource {
    /// Number of records.
    fn count(&self) -> usize;
    /// Record `i`.
    fn get(&self, i: usize) -> ImuRecord;
    /// Time of record `i` (s).
    fn time_s(&self, i: usize) -> f64 {
        self.get(i).time_s
    }
    /// The records `range` will not be read again soon (a mapped file drops their pages).
    fn release(&self, _range: Range<usize>) {}
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
    fn time_s(&self, i: usize) -> f64 {
        ImuFile::time_s(self, i)
    }
    fn release(&self, range: Range<usize>) {
        ImuFile::release(self, range)
    }
}

/// Records between two releases of a mapped IMU file's pages.
const RELEASE_EVERY: usize = 1 << 16;

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
const PACKED: usize = N * (N + 1) / 2;
/// A navigation state as f64: time, latitude, longitude, height, velocity (3), quaternion (4).
const NAV: usize = 11;
/// A stored forward epoch: record index, navigation state, sensor estimates (12), update
/// correction (21), packed covariance.
const EPOCH_WIDTH: usize = 1 + NAV + 12 + N + PACKED;
/// A stored smoothed epoch: smoothed correction (21), packed covariance.
const SMOOTH_WIDTH: usize = N + PACKED;

/// The upper triangle of symmetric `p` into `out`, column by column (`p[(0..=j, j)]` for each
/// `j`: contiguous in nalgebra's column-major storage). One copy per column: written as a
/// double loop over `(i, j)` with a running index, LLVM unrolled its 231 checked stores and
/// spent 12 of the crate's 13 minutes of release build in `IndVarSimplify` on it.
fn pack(p: &Mat, out: &mut [f64]) {
    let mut k = 0;
    for (j, column) in p.as_slice().chunks_exact(N).enumerate() {
        out[k..=k + j].copy_from_slice(&column[..=j]);
        k += j + 1;
    }
}

/// The symmetric matrix whose upper triangle [`pack`] wrote to `v`.
fn unpack(v: &[f64]) -> Mat {
    let mut p = Mat::zeros();
    let mut k = 0;
    for (j, column) in p.as_mut_slice().chunks_exact_mut(N).enumerate() {
        column[..=j].copy_from_slice(&v[k..=k + j]);
        k += j + 1;
    }
    p.fill_lower_triangle_with_upper_triangle();
    p
}

/// An update epoch of the forward pass.
#[derive(Debug, Clone)]
struct Epoch {
    j: usize,
    nav: NavState,
    sens: SensorEstimate,
    u: Vec21,
    p: Mat,
}

impl Epoch {
    fn encode(&self, out: &mut [f64]) {
        let n = &self.nav;
        out[0] = self.j as f64;
        out[1..1 + NAV].copy_from_slice(&[
            n.time_s,
            n.lat_rad,
            n.lon_rad,
            n.h_m,
            n.v_n.x,
            n.v_n.y,
            n.v_n.z,
            n.q_b_n.coords[0],
            n.q_b_n.coords[1],
            n.q_b_n.coords[2],
            n.q_b_n.coords[3],
        ]);
        let s = &self.sens;
        let mut k = 1 + NAV;
        for v in [&s.b_g, &s.b_a, &s.s_g, &s.s_a] {
            out[k..k + 3].copy_from_slice(v.as_slice());
            k += 3;
        }
        out[k..k + N].copy_from_slice(self.u.as_slice());
        pack(&self.p, &mut out[k + N..]);
    }

    fn decode(v: &[f64]) -> Epoch {
        let n = &v[1..1 + NAV];
        let nav = NavState {
            time_s: n[0],
            lat_rad: n[1],
            lon_rad: n[2],
            h_m: n[3],
            v_n: Vector3::new(n[4], n[5], n[6]),
            q_b_n: UnitQuaternion::new_unchecked(Quaternion::from(Vector4::new(
                n[7], n[8], n[9], n[10],
            ))),
        };
        let k = 1 + NAV;
        let v3 = |a: usize| Vector3::new(v[a], v[a + 1], v[a + 2]);
        Epoch {
            j: v[0] as usize,
            nav,
            sens: SensorEstimate {
                b_g: v3(k),
                b_a: v3(k + 3),
                s_g: v3(k + 6),
                s_a: v3(k + 9),
            },
            u: Vec21::from_column_slice(&v[k + 12..k + 12 + N]),
            p: unpack(&v[k + 12 + N..]),
        }
    }
}

/// The stored forward pass.
pub struct Forward {
    template: Filter,
    epochs: Spill,
    scratch: Option<PathBuf>,
    end: usize,
    /// Counts.
    pub stats: FilterStats,
}

impl Forward {
    /// Number of stored update epochs (the start included).
    pub fn epochs(&self) -> usize {
        self.epochs.len()
    }
    /// Bytes held in memory by the stored epochs.
    pub fn bytes(&self) -> usize {
        self.epochs.memory_bytes()
    }
    /// Bytes of the stored epochs written to the temporary file.
    pub fn spilled_bytes(&self) -> usize {
        self.epochs.file_bytes()
    }
    fn epoch(&self, i: usize, buf: &mut [f64]) -> Result<Epoch> {
        self.epochs.get(i, buf)?;
        Ok(Epoch::decode(buf))
    }
    fn store(&self, label: &str, width: usize) -> Result<Spill> {
        match &self.scratch {
            Some(d) => Spill::file_in(d, label, width),
            None => Ok(Spill::memory(width)),
        }
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
/// heading, wrong lever arm, or a GNSS file of another survey). The epochs are held in memory.
pub fn forward(
    imu: &(impl ImuSource + ?Sized),
    gnss: &[GnssRecord],
    start: Start,
    max_rejected_run: usize,
    sink: &mut dyn FnMut(&Estimate),
) -> Result<Forward> {
    forward_in(imu, gnss, start, max_rejected_run, None, sink)
}

/// [`forward`] with the stored epochs (and the smoother's) in temporary files inside
/// `scratch` when given: memory flat in the survey's length.
pub fn forward_in(
    imu: &(impl ImuSource + ?Sized),
    gnss: &[GnssRecord],
    start: Start,
    max_rejected_run: usize,
    scratch: Option<&Path>,
    sink: &mut dyn FnMut(&Estimate),
) -> Result<Forward> {
    let n = imu.count();
    let mut f = start.filter;
    let mut stats = FilterStats::default();
    let mut epochs = match scratch {
        Some(d) => Spill::file_in(d, "trajectory-forward", EPOCH_WIDTH)?,
        None => Spill::memory(EPOCH_WIDTH),
    };
    let mut buf = vec![0.0; EPOCH_WIDTH];
    let half = |j: usize| {
        let a = if j > 0 {
            imu.time_s(j) - imu.time_s(j - 1)
        } else {
            0.0
        };
        let b = if j + 1 < n {
            imu.time_s(j + 1) - imu.time_s(j)
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
            let e = Epoch {
                j,
                nav: f.nav,
                sens: f.sens,
                u,
                p: f.p,
            };
            e.encode(&mut buf);
            epochs.push(&buf)?;
        }
        let (w, fb) = f.sens.correct(&rec);
        sink(&Estimate {
            nav: f.nav,
            f_b: fb,
            w_b: w,
            cov: cov9(&f.p),
        });
        if j % RELEASE_EVERY == 0 && j > RELEASE_EVERY {
            imu.release(0..j - RELEASE_EVERY);
        }
        crate::interrupt::check()?;
    }
    stats.imu_records = n - start.index;
    let mut template = f;
    template.p = Mat::zeros();
    Ok(Forward {
        template,
        epochs,
        scratch: scratch.map(Path::to_path_buf),
        end: n,
        stats,
    })
}

/// The filter at a stored epoch.
fn filter_at(fwd: &Forward, e: &Epoch) -> Filter {
    let mut f = fwd.template.clone();
    f.nav = e.nav;
    f.sens = e.sens;
    f.p = e.p;
    f
}

/// Top rows of the identity.
fn identity_rows() -> Rows9 {
    let mut m = Rows9::zeros();
    m.fixed_view_mut::<9, 9>(0, 0).fill_with_identity();
    m
}

/// The prediction at record `j_end` from epoch `e` and the stretch's transition rows
/// (`M = Phi(j_end, e.j)`).
fn predict(
    imu: &(impl ImuSource + ?Sized),
    fwd: &Forward,
    e: &Epoch,
    j_end: usize,
) -> (Mat, Rows9) {
    let mut f = filter_at(fwd, e);
    let mut m_top = identity_rows();
    for j in e.j + 1..=j_end {
        let g = f.propagate(&imu.get(j));
        chain_transition(&mut m_top, &g);
    }
    (f.p, m_top)
}

/// The recomputed stretch from an epoch to (excluding) record `j_end`: per record the state,
/// corrected rates, the top rows of the covariance and (when it ends at an epoch) the
/// transition rows to the next record.
struct Stretch {
    navs: Vec<NavState>,
    fw: Vec<(Vector3<f64>, Vector3<f64>)>,
    p9: Vec<Rows9>,
    gs: Vec<TransitionRows>,
    p_pred: Mat,
}

fn recompute(
    imu: &(impl ImuSource + ?Sized),
    fwd: &Forward,
    e: &Epoch,
    j_end: usize,
    out: &mut Stretch,
) {
    let mut f = filter_at(fwd, e);
    out.navs.clear();
    out.fw.clear();
    out.p9.clear();
    out.gs.clear();
    let to_epoch = j_end < fwd.end;
    let mut rec = imu.get(e.j);
    for j in e.j..j_end {
        out.navs.push(f.nav);
        out.fw.push(f.sens.correct(&rec));
        out.p9.push(f.p.fixed_rows::<9>(0).into_owned());
        if j + 1 < j_end || to_epoch {
            rec = imu.get(j + 1);
            let g = f.propagate(&rec);
            if to_epoch {
                out.gs.push(g);
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
    let ne = fwd.epochs();
    let last = ne - 1;
    let mut ebuf = vec![0.0; EPOCH_WIDTH];
    let mut sbuf = vec![0.0; SMOOTH_WIDTH];
    // Backward pass: smoothed correction and covariance at every epoch, stored in reverse
    // order (record `last - i` is epoch i).
    let mut smoothed = fwd.store("trajectory-smoothed", SMOOTH_WIDTH)?;
    let mut next = fwd.epoch(last, &mut ebuf)?;
    let (mut s_next, mut ps_next) = (Vec21::zeros(), next.p);
    sbuf[..N].fill(0.0);
    pack(&ps_next, &mut sbuf[N..]);
    smoothed.push(&sbuf)?;
    let mut acf = AcfAccumulator::new(ne);
    let mut released = fwd.end;
    for i in (0..last).rev() {
        let e = fwd.epoch(i, &mut ebuf)?;
        let (p_pred, m_top) = predict(imu, fwd, &e, next.j);
        let pp_inv = inverse_spd(&p_pred)?;
        let a = e.p * dense_chain(&m_top).transpose() * pp_inv;
        let s = a * (s_next + next.u);
        let mut ps = e.p + a * (ps_next - p_pred) * a.transpose();
        super::filter::symmetrise(&mut ps);
        acf.step(i, e.nav.time_s, &e.nav, &a, &ps);
        sbuf[..N].copy_from_slice(s.as_slice());
        pack(&ps, &mut sbuf[N..]);
        smoothed.push(&sbuf)?;
        (s_next, ps_next, next) = (s, ps, e);
        if released > next.j + 2 * RELEASE_EVERY {
            imu.release(next.j + RELEASE_EVERY..released);
            released = next.j + RELEASE_EVERY;
        }
        crate::interrupt::check()?;
    }
    // Output pass, forward.
    let mut st = Stretch {
        navs: Vec::new(),
        fw: Vec::new(),
        p9: Vec::new(),
        gs: Vec::new(),
        p_pred: Mat::zeros(),
    };
    let mut buf: Vec<Estimate> = Vec::new();
    let mut e = fwd.epoch(0, &mut ebuf)?;
    for i in 0..=last {
        let next = if i < last {
            Some(fwd.epoch(i + 1, &mut ebuf)?)
        } else {
            None
        };
        let j_end = next.as_ref().map_or(fwd.end, |x| x.j);
        recompute(imu, fwd, &e, j_end, &mut st);
        buf.clear();
        let len = st.navs.len();
        if let Some(nx) = &next {
            smoothed.get(last - (i + 1), &mut sbuf)?;
            let c = Vec21::from_column_slice(&sbuf[..N]) + nx.u;
            let pp_inv = inverse_spd(&st.p_pred)?;
            // s_m = C_m lambda, P_s(m) = P_m + C_m W C_m^T with C_m = P9_m Phi(end, m)^T.
            let lambda = pp_inv * c;
            let w = pp_inv * (unpack(&sbuf[N..]) - st.p_pred) * pp_inv;
            let mut t = identity_rows();
            for m in (0..len).rev() {
                let tg = t.fixed_columns::<9>(0) * st.gs[m];
                t += tg;
                let p9 = &st.p9[m];
                let mut cm = *p9;
                cm.fixed_columns_mut::<9>(0)
                    .copy_from(&(p9 * t.transpose()));
                let s9 = cm * lambda;
                let mut s = Vec21::zeros();
                s.fixed_rows_mut::<9>(0).copy_from(&s9);
                let mut cov = p9.fixed_columns::<9>(0) + (cm * w) * cm.transpose();
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
                    cov: st.p9[m].fixed_columns::<9>(0).into_owned(),
                });
            }
        }
        for x in &buf {
            sink(x)?;
        }
        if e.j > 2 * RELEASE_EVERY && i % 64 == 0 {
            imu.release(0..e.j - RELEASE_EVERY);
        }
        if let Some(nx) = next {
            e = nx;
        }
        crate::interrupt::check()?;
    }
    Ok(acf.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric matrix comes back from its packed upper triangle exactly, and the packing
    /// fills the packed length with the upper triangle's entries, each once.
    #[test]
    fn packed_covariance_round_trips() {
        let a = Mat::from_fn(|i, j| (i * N + j) as f64 + 0.5);
        let p = a + a.transpose();
        let mut v = vec![f64::NAN; PACKED + 1];
        pack(&p, &mut v);
        assert!(v[..PACKED].iter().all(|x| x.is_finite()));
        assert!(v[PACKED].is_nan(), "wrote beyond the packed length");
        assert_eq!(unpack(&v), p);
        let mut upper: Vec<f64> = (0..N)
            .flat_map(|j| (0..=j).map(move |i| (i, j)))
            .map(|ij| p[ij])
            .collect();
        let mut packed = v[..PACKED].to_vec();
        upper.sort_by(f64::total_cmp);
        packed.sort_by(f64::total_cmp);
        assert_eq!(packed, upper);
    }
}
