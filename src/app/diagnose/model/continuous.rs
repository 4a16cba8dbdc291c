//! `X^T C^-1 X` when the navigation errors are first-order Gauss-Markov processes in time
//! ([`ObservationSet::nav_tau_s`]), continuous within and between visits (docs/diagnosis.md,
//! "The residual model").
//!
//! Each error component `k` (north, east, down (m); roll, pitch, heading (rad)) is
//! `z_k(t) = s_k(t) zeta_k(t)`, `zeta_k` a unit Gauss-Markov process of correlation time
//! `tau_k`, `s_k` the SMRMSG sigma. It is represented by its values at knots on a grid of
//! `knot_s` seconds ([`knot_spacing_s`]; the grid points either side of every return) and
//! linear between them;
//! what the line leaves out (a Brownian bridge, variance `q (t - t_a)(t_b - t) / (t_b - t_a)`
//! along the return's gradient, `q = 2 s^2 / tau`) is added to the return's independent
//! variance. A return's residual is then `x theta + h^T u + e`, `u` the knot values
//! (`h`: the navigation gradient times the two interpolation weights), `e ~ N(0, D)`. `D` is
//! block diagonal: the returns interpolated between the same two trajectory records share
//! their bridge (covariance `q min(w) (1 - max(w)) knot_s`, `w` the weights of the right
//! knot) and the white navigation noise of the records ([`ObservationSet::nav_white_share`]),
//! and such a group's block is whitened by its Cholesky factor before it is summed. The bridge
//! between returns of different groups (other records within the same knot interval) is left
//! out: the spacing is chosen so that the bridge is a small share of a return's variance.
//!
//! The knots of one component form a Markov chain: the prior precision `Q` of `u` is block
//! tridiagonal (6 x 6 blocks, knots in time order), and so is `M = Q + H^T D^-1 H`, since a
//! return touches two neighbouring knots. `X^T C^-1 X = X^T D^-1 X - B^T M^-1 B`,
//! `B = H^T D^-1 X`, with `M` factorised by block Cholesky: O(n p^2 + K 6^3 p) for `n` returns,
//! `p` columns and `K` knots, whatever the survey's length.
//!
//! A second, slow process per block ([`ObservationSet::nav_slow`]) is a second chain on the
//! same knots: the knot state is then the two processes' values (12 x 12 blocks), a return's
//! row the same gradient on both (`H^T D^-1 H` and `B` repeat), and only the solve changes.

use super::design::RowFn;
use super::{white_nav_cov_m2, Observation, ObservationSet, SlowNav};
use nalgebra::{DMatrix, Matrix6, SMatrix, SVector};
use rayon::prelude::*;

/// Widest spacing of the knots (s).
pub const MAX_KNOT_S: f64 = 0.1;
/// Narrowest spacing of the knots (s): four records of a 200 Hz trajectory.
pub const MIN_KNOT_S: f64 = 0.02;
/// Largest mean share of a return's scanner variance that the bridge between knots may reach
/// at mid-interval. The bridge between returns of different records in one knot interval is
/// left out of the model; its part of the held-out chi2/dof grows with this share (0.1 s knots
/// under a 10 s position process, a share of about 0.2, left 0.976 with the true model
/// held on a 15-lap survey; docs/diagnosis.md, "The residual model").
const MAX_BRIDGE_SHARE: f64 = 0.02;

/// Smallest sigma a knot gets (m or rad): a component without error would make `Q` infinite.
const MIN_SIGMA: f64 = 1e-12;

/// One return on the selected references, ready for accumulation.
struct Row<'a> {
    o: &'a Observation,
    /// Index of its left knot in the sorted knot list, and the weight of the right one.
    knot: usize,
    w: f64,
    /// Pass and first trajectory record of the returns that share its white navigation noise.
    group: Option<(usize, usize)>,
}

/// The returns on the selected references laid on the knots: made once per selection (a
/// sort of the returns), summed at any nuisance ([`KnotSums::accumulate`]).
pub(crate) struct Layout<'a> {
    /// Spacing of the knots (s).
    pub(crate) knot_s: f64,
    /// Knots (grid indices from the set's first return, ascending).
    idx: Vec<i64>,
    /// The returns grouped by the records they are interpolated between (each group on the
    /// knot interval of its earliest return: a group that straddles a knot extrapolates the
    /// line by at most one record interval, so that the returns sharing white noise share
    /// their knots).
    rows: Vec<Row<'a>>,
    /// Each knot's sigmas (from the first return touching it).
    sigma: Vec<[f64; 6]>,
}

impl<'a> Layout<'a> {
    /// The returns of `set` on `selected` on knots spaced for `process`
    /// ([`knot_spacing_s`]).
    pub(crate) fn new(set: &'a ObservationSet, selected: &[bool], process: &Process) -> Self {
        let knot_s = knot_spacing_s(set, selected, process);
        let t0 = set
            .observations
            .iter()
            .map(|o| o.covariates.time_s)
            .fold(f64::INFINITY, f64::min);
        let grid = |o: &Observation| (o.covariates.time_s - t0) / knot_s;
        let mut rows: Vec<Row> = set
            .observations
            .iter()
            .filter(|o| selected[o.reference])
            .map(|o| Row {
                o,
                knot: 0,
                w: 0.0,
                group: o.nav_record.map(|r| (o.covariates.pass, r.index)),
            })
            .collect();
        rows.sort_by_key(|r| r.group);
        let mut left = Vec::with_capacity(rows.len());
        for g in rows.chunk_by(|a, b| a.group.is_some() && a.group == b.group) {
            let first = g.iter().map(|r| grid(r.o)).fold(f64::INFINITY, f64::min);
            left.extend(std::iter::repeat_n(first.floor() as i64, g.len()));
        }
        // Within a pass the left knots do not decrease: repeats go before the sort.
        let mut idx = left.clone();
        idx.dedup();
        let mut idx: Vec<i64> = idx.iter().flat_map(|&i| [i, i + 1]).collect();
        idx.sort_unstable();
        idx.dedup();
        let mut sigma = vec![[f64::NAN; 6]; idx.len()];
        for (r, &i) in rows.iter_mut().zip(&left) {
            r.knot = idx.binary_search(&i).expect("every left knot is listed");
            r.w = (grid(r.o) - i as f64).max(0.0);
            let p = &set.visits[r.o.visit].nav_cov;
            for j in [r.knot, r.knot + 1] {
                if sigma[j][0].is_nan() {
                    sigma[j] = std::array::from_fn(|k| p[k][k].max(0.0).sqrt().max(MIN_SIGMA));
                }
            }
        }
        Layout {
            knot_s,
            idx,
            rows,
            sigma,
        }
    }
}

/// The knot spacing (s) at which the Brownian bridge between knots of `process`, at
/// mid-interval, is on average [`MAX_BRIDGE_SHARE`] of the scanner variance of the returns on
/// `selected`, within [`MIN_KNOT_S`]..=[`MAX_KNOT_S`] (the bridge variance grows linearly with
/// the spacing).
pub(crate) fn knot_spacing_s(set: &ObservationSet, selected: &[bool], process: &Process) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for o in set.observations.iter().filter(|o| selected[o.reference]) {
        let nav_var = &set.visits[o.visit].nav_cov;
        let at_one_s = (o, nav_var, 0.5);
        sum += bridge_cov_m2(at_one_s, at_one_s, process, 1.0) / o.var_white_m2;
        n += 1;
    }
    let share_per_s = sum / n.max(1) as f64;
    if share_per_s > 0.0 {
        (MAX_BRIDGE_SHARE / share_per_s).clamp(MIN_KNOT_S, MAX_KNOT_S)
    } else {
        MAX_KNOT_S
    }
}

/// The navigation error process that the knots' prior and the bridge variances are taken at,
/// relative to the navigation covariances of the set it is applied to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Process {
    /// Correlation times of the first process (s; position, attitude block).
    pub tau: [f64; 2],
    /// Scale of its sigmas (position, attitude block).
    pub scale: [f64; 2],
    /// The second, slow process: its shares are of the unscaled variances.
    pub slow: Option<SlowNav>,
}

impl Process {
    /// The process a set declares (scales 1).
    pub(crate) fn of(set: &ObservationSet, tau: [f64; 2]) -> Self {
        Process {
            tau,
            scale: [1.0; 2],
            slow: set.nav_slow,
        }
    }
}

/// Diffusion of both processes of `process` per navigation component, relative to the
/// navigation variance (1/s): `2 a^2 / tau`, plus `2 share / tau2` of the slow process.
fn diffusion_per_s(process: &Process) -> [f64; 6] {
    std::array::from_fn(|k| {
        let b = k / 3;
        let a2 = process.scale[b] * process.scale[b];
        let mut diffusion = 2.0 * a2 / process.tau[b];
        if let Some(slow) = &process.slow {
            diffusion += 2.0 * slow.share[b] / slow.tau_s[b];
        }
        diffusion
    })
}

/// A return's bridge factors (m / sqrt(s)) per navigation component: its gradient times the
/// square root of the diffusion (`diffusion_per_s`) times its visit's navigation variance.
fn bridge_factors(o: &Observation, nav_var: &[[f64; 6]; 6], diffusion: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|k| o.nav_gradient[k] * (diffusion[k] * nav_var[k][k].max(0.0)).sqrt())
}

/// The bridge's share of the knot interval that two returns (at weights `w1`, `w2` of the
/// right knot) have in common (s): `knot_s min(w) (1 - max(w))`, zero beyond the right knot (a
/// group's extrapolation, at most a record interval).
fn bridge_shape_s(w1: f64, w2: f64, knot_s: f64) -> f64 {
    (w1.min(w2) * (1.0 - w1.max(w2))).max(0.0) * knot_s
}

/// Covariance (m^2) of the Brownian bridges between the knots (`knot_s` apart) of two returns
/// on the same knot interval (at weights `w1`, `w2` of the right knot) along their gradients,
/// of both processes of `process`, the navigation variances `nav_var1`, `nav_var2` of their
/// visits: `q knot_s min(w) (1 - max(w))` per component, `q` the diffusion; with `w1 = w2`
/// and one return, its variance.
fn bridge_cov_m2(
    (o1, nav_var1, w1): (&Observation, &[[f64; 6]; 6], f64),
    (o2, nav_var2, w2): (&Observation, &[[f64; 6]; 6], f64),
    process: &Process,
    knot_s: f64,
) -> f64 {
    let shape = bridge_shape_s(w1, w2, knot_s);
    if shape == 0.0 {
        return 0.0;
    }
    let diffusion = diffusion_per_s(process);
    let (u1, u2) = (
        bridge_factors(o1, nav_var1, &diffusion),
        bridge_factors(o2, nav_var2, &diffusion),
    );
    shape * dot6(&u1, &u2)
}

/// `a . b` of two six-vectors.
fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The prior of the knot values: the precision `Q` (diagonal blocks and the blocks coupling
/// each knot to the next, both diagonal: the components are independent) and `ln det` of the
/// covariance (per component a Markov chain: `sum_j 2 ln s_j + sum_j ln(1 - rho_j^2)` over its
/// knots and neighbouring pairs).
struct Prior {
    diag: Vec<[f64; 6]>,
    next: Vec<[f64; 6]>,
    log_det: f64,
}

impl Prior {
    fn new((idx, knot_s): (&[i64], f64), sigma: &[[f64; 6]], tau: [f64; 2]) -> Self {
        let mut diag = vec![[1.0; 6]; idx.len()];
        let mut next = vec![[0.0; 6]; idx.len().saturating_sub(1)];
        // One logarithm per knot: of the product of its six sigmas.
        let mut log_det: f64 = sigma
            .iter()
            .map(|s| 2.0 * s.iter().product::<f64>().ln())
            .sum();
        for (j, n) in next.iter_mut().enumerate() {
            let gap_s = (idx[j + 1] - idx[j]) as f64 * knot_s;
            for (block, tau) in tau.iter().enumerate() {
                let rho = (-gap_s / tau).exp();
                let c = 1.0 - rho * rho;
                log_det += 3.0 * c.ln();
                for k in 3 * block..3 * block + 3 {
                    diag[j][k] += rho * rho / c;
                    diag[j + 1][k] += rho * rho / c;
                    n[k] = -rho / c / (sigma[j][k] * sigma[j + 1][k]);
                }
            }
        }
        for (d, s) in diag.iter_mut().zip(sigma) {
            for k in 0..6 {
                d[k] /= s[k] * s[k];
            }
        }
        Prior {
            diag,
            next,
            log_det,
        }
    }
}

/// `X^T C^-1 X` (`p x p`) of the returns on `selected` under the continuous-time model.
pub(crate) fn gram(
    set: &ObservationSet,
    selected: &[bool],
    p: usize,
    row: &RowFn,
    tau: [f64; 2],
) -> DMatrix<f64> {
    gram_and_log_det(set, selected, p, row, tau).0
}

/// [`gram`] and `ln det C` of the same returns, by the matrix determinant lemma
/// `det C = det D det M / det Q`, `M = Q + H^T D^-1 H` factorised anyway.
pub(crate) fn gram_and_log_det(
    set: &ObservationSet,
    selected: &[bool],
    p: usize,
    row: &RowFn,
    tau: [f64; 2],
) -> (DMatrix<f64>, f64) {
    let process = Process::of(set, tau);
    let layout = Layout::new(set, selected, &process);
    KnotSums::accumulate(set, &layout, p, row, &process, set.nav_white_share).solve(&process)
}

/// The returns on the selected references summed knot by knot, their independent variances
/// `D` (scanner, white navigation noise and bridge) fixed at the correlation times, scales and
/// white shares they were accumulated with: all that `X^T C^-1 X` and `ln det C` need besides
/// the knots' prior, so that the likelihood of the nuisance (`app::diagnose::nuisance`) costs
/// O(K 6 p^2) per evaluation instead of a pass over the returns.
pub(crate) struct KnotSums {
    /// Knots (grid indices, ascending, `knot_s` seconds apart) and their sigmas before any
    /// scale.
    knot_s: f64,
    idx: Vec<i64>,
    sigma: Vec<[f64; 6]>,
    /// The sums over all knots (`first_knot` 0).
    sums: Sums,
}

/// Pieces the returns are summed in, in parallel, and then added in order: a fixed number, so
/// that the rounding of the sums (and every byte written from them) does not depend on the
/// number of threads.
const PIECES: usize = 32;
/// Pieces summed side by side before they are added (each holds `B` over its own knots).
const PIECES_AT_ONCE: usize = 4;

/// Sums over the returns whose knots lie in `first_knot ..= first_knot + h_d_h_diag.len() - 1`.
struct Sums {
    first_knot: usize,
    /// `X^T D^-1 X` (`p x p`).
    x_d_x: DMatrix<f64>,
    /// Diagonal and next-knot blocks of `H^T D^-1 H`.
    h_d_h_diag: Vec<Matrix6<f64>>,
    h_d_h_next: Vec<Matrix6<f64>>,
    /// `B = H^T D^-1 X` (`6 K x p`, `K` the knots of the range).
    h_d_x: DMatrix<f64>,
    /// `ln det D`.
    log_det_d: f64,
}

/// What a return's independent variance needs besides the return: the bridge's correlation
/// times and scales (position, attitude) and the white navigation variance per component.
struct Noise<'a> {
    set: &'a ObservationSet,
    knot_s: f64,
    white_var: [f64; 6],
    /// `diffusion_per_s` of the process.
    diffusion: [f64; 6],
}

impl KnotSums {
    /// Sums over the returns on `selected`, `D`'s bridge variances at `process` and white
    /// navigation noise of shares `white` (position, attitude) of the set's navigation
    /// variances ([`ObservationSet::white_nav_var`]; not scaled). The returns are summed in
    /// [`PIECES`] pieces in parallel.
    pub(crate) fn accumulate(
        set: &ObservationSet,
        layout: &Layout,
        p: usize,
        row: &RowFn,
        process: &Process,
        white: [f64; 2],
    ) -> Self {
        let noise = Noise {
            set,
            knot_s: layout.knot_s,
            white_var: set.white_nav_var(white),
            diffusion: diffusion_per_s(process),
        };
        let bounds = piece_bounds(&layout.rows);
        let mut sums = Sums::zeros(0, layout.idx.len(), p);
        // A few pieces at a time, so that their knot blocks add little to the total's memory.
        for batch in bounds.windows(2).collect::<Vec<_>>().chunks(PIECES_AT_ONCE) {
            let pieces: Vec<Sums> = batch
                .par_iter()
                .map(|w| Sums::over(&layout.rows[w[0]..w[1]], p, row, &noise))
                .collect();
            for piece in &pieces {
                sums.add(piece);
            }
        }
        KnotSums {
            knot_s: layout.knot_s,
            idx: layout.idx.clone(),
            sigma: layout.sigma.clone(),
            sums,
        }
    }

    /// `X^T C^-1 X` and `ln det C` with the knots' prior at `process` (exact at the process
    /// accumulated with; elsewhere `D`'s bridge variances stay at that one).
    pub(crate) fn solve(&self, process: &Process) -> (DMatrix<f64>, f64) {
        let p = self.sums.x_d_x.nrows();
        let sigma: Vec<[f64; 6]> = self
            .sigma
            .iter()
            .map(|s| std::array::from_fn(|k| s[k] * process.scale[k / 3]))
            .collect();
        let knots = (self.idx.as_slice(), self.knot_s);
        let q = Prior::new(knots, &sigma, process.tau);
        // ln det Q = -ln det(prior covariance).
        let mut log_det_c = self.sums.log_det_d + q.log_det;
        let (h_diag, h_next) = (&self.sums.h_d_h_diag, &self.sums.h_d_h_next);
        let n = h_diag.len();
        let plus = |q: &[f64; 6], h: &Matrix6<f64>| Matrix6::from_diagonal(&(*q).into()) + h;
        let (whitened, log_det_m) = match &process.slow {
            None => whitened_gram(
                n,
                |j| plus(&q.diag[j], &h_diag[j]),
                |j| plus(&q.next[j], &h_next[j]),
                p,
                |j, c| self.sums.h_d_x.fixed_view::<6, 1>(6 * j, c).into_owned(),
            ),
            Some(slow) => {
                let slow_sigma: Vec<[f64; 6]> = self
                    .sigma
                    .iter()
                    .map(|s| {
                        std::array::from_fn(|k| (s[k] * slow.share[k / 3].sqrt()).max(MIN_SIGMA))
                    })
                    .collect();
                let s = Prior::new(knots, &slow_sigma, slow.tau_s);
                log_det_c += s.log_det;
                let two = |q: &[f64; 6], s: &[f64; 6], h: &Matrix6<f64>| {
                    let mut m = SMatrix::<f64, 12, 12>::zeros();
                    for (r, c) in [(0, 0), (0, 6), (6, 0), (6, 6)] {
                        m.fixed_view_mut::<6, 6>(r, c).copy_from(h);
                    }
                    for k in 0..6 {
                        m[(k, k)] += q[k];
                        m[(6 + k, 6 + k)] += s[k];
                    }
                    m
                };
                whitened_gram(
                    n,
                    |j| two(&q.diag[j], &s.diag[j], &h_diag[j]),
                    |j| two(&q.next[j], &s.next[j], &h_next[j]),
                    p,
                    |j, c| {
                        let b = self.sums.h_d_x.fixed_view::<6, 1>(6 * j, c);
                        SVector::<f64, 12>::from_fn(|k, _| b[k % 6])
                    },
                )
            }
        };
        log_det_c += log_det_m;
        (&self.sums.x_d_x - whitened, log_det_c)
    }
}

/// Where the pieces of `rows` begin (and the last ends): [`PIECES`] of about equal size, each
/// boundary moved on to the next group so that a group is summed whole.
fn piece_bounds(rows: &[Row]) -> Vec<usize> {
    let same_group = |i: usize| rows[i].group.is_some() && rows[i].group == rows[i - 1].group;
    let mut bounds = vec![0];
    for i in 1..PIECES {
        let mut b = (i * rows.len() / PIECES).max(*bounds.last().expect("starts at 0"));
        while b > 0 && b < rows.len() && same_group(b) {
            b += 1;
        }
        if b > *bounds.last().expect("starts at 0") && b < rows.len() {
            bounds.push(b);
        }
    }
    bounds.push(rows.len());
    bounds
}

impl Sums {
    fn zeros(first_knot: usize, knots: usize, p: usize) -> Self {
        Sums {
            first_knot,
            x_d_x: DMatrix::zeros(p, p),
            h_d_h_diag: vec![Matrix6::zeros(); knots],
            h_d_h_next: vec![Matrix6::zeros(); knots.saturating_sub(1)],
            h_d_x: DMatrix::zeros(6 * knots, p),
            log_det_d: 0.0,
        }
    }

    /// Sums over `rows` (whole groups), on the knots they touch.
    fn over(rows: &[Row], p: usize, row: &RowFn, noise: &Noise) -> Self {
        let first = rows.iter().map(|r| r.knot).min().unwrap_or(0);
        let knots = rows.iter().map(|r| r.knot + 2 - first).max().unwrap_or(0);
        let mut sums = Sums::zeros(first, knots, p);
        let mut scratch = Scratch::default();
        for group in rows.chunk_by(|a, b| a.group.is_some() && a.group == b.group) {
            sums.add_group(group, row, noise, &mut scratch);
        }
        sums.x_d_x.fill_lower_triangle_with_upper_triangle();
        sums
    }

    /// Adds the sums of `piece` (on its knots) to these.
    fn add(&mut self, piece: &Sums) {
        let off = piece.first_knot - self.first_knot;
        self.x_d_x += &piece.x_d_x;
        self.log_det_d += piece.log_det_d;
        for (j, b) in piece.h_d_h_diag.iter().enumerate() {
            self.h_d_h_diag[off + j] += b;
        }
        for (j, b) in piece.h_d_h_next.iter().enumerate() {
            self.h_d_h_next[off + j] += b;
        }
        let mut b = self.h_d_x.view_mut((6 * off, 0), piece.h_d_x.shape());
        b += &piece.h_d_x;
    }

    /// Adds returns that share their white navigation noise (or one return): their
    /// covariance `D_g` (scanner, bridge, white navigation noise) is factorised, `D_g = L L^T`,
    /// and the rows `L^-1 [X H]` added as independent rows of unit variance.
    fn add_group(&mut self, group: &[Row], row: &RowFn, noise: &Noise, s: &mut Scratch) {
        let knot = group[0].knot - self.first_knot;
        let m = group.len();
        s.design(group, row);
        let nc = s.cols.len();
        // `[X H]` row by row (`w` = nc + 12 wide), and the lower triangle of `D_g`.
        let w = nc + 12;
        s.y.clear();
        s.y.resize(m * w, 0.0);
        s.d.clear();
        s.d.resize(m * m, 0.0);
        s.u.clear();
        for (a, r) in group.iter().enumerate() {
            let ya = &mut s.y[a * w..(a + 1) * w];
            for (i, &(_, v)) in s.entries[s.starts[a]..s.starts[a + 1]].iter().enumerate() {
                ya[s.slot[s.starts[a] + i]] = v;
            }
            for k in 0..6 {
                ya[nc + k] = r.o.nav_gradient[k] * (1.0 - r.w);
                ya[nc + 6 + k] = r.o.nav_gradient[k] * r.w;
            }
            let nav_var = &noise.set.visits[r.o.visit].nav_cov;
            s.u.push(bridge_factors(r.o, nav_var, &noise.diffusion));
            for (b, q) in group[..=a].iter().enumerate() {
                // Two returns between the same records share their bridge (the same knot
                // interval, a few ms apart) and their white navigation noise.
                let bridge = bridge_shape_s(r.w, q.w, noise.knot_s) * dot6(&s.u[a], &s.u[b]);
                let scanner = if a == b { r.o.var_white_m2 } else { 0.0 };
                s.d[a * m + b] = scanner + bridge + white_nav_cov_m2(r.o, q.o, &noise.white_var);
            }
        }
        self.log_det_d += cholesky_in_place(&mut s.d, m);
        forward_substitute(&s.d, m, &mut s.y, w);
        for a in 0..m {
            let ya = &s.y[a * w..(a + 1) * w];
            let hl = SMatrix::<f64, 6, 1>::from_column_slice(&ya[nc..nc + 6]);
            let hr = SMatrix::<f64, 6, 1>::from_column_slice(&ya[nc + 6..]);
            self.add_unit_row(knot, &hl, &hr, &s.cols, &ya[..nc]);
        }
    }

    /// Adds a row of unit variance: `x` (values of columns `cols`), navigation rows `hl`,
    /// `hr` on knots `knot`, `knot + 1` (counted from `first_knot`). `X^T D^-1 X` gains its
    /// upper triangle only ([`Sums::over`] fills the lower).
    fn add_unit_row(
        &mut self,
        knot: usize,
        hl: &SMatrix<f64, 6, 1>,
        hr: &SMatrix<f64, 6, 1>,
        cols: &[usize],
        x: &[f64],
    ) {
        self.h_d_h_diag[knot] += hl * hl.transpose();
        self.h_d_h_diag[knot + 1] += hr * hr.transpose();
        self.h_d_h_next[knot] += hl * hr.transpose();
        // Column-major storage: entry (i, j) of a matrix with `n` rows is element `j n + i`.
        let (p, n_b) = (self.x_d_x.nrows(), self.h_d_x.nrows());
        let (x_d_x, h_d_x) = (self.x_d_x.as_mut_slice(), self.h_d_x.as_mut_slice());
        for (&ca, &xa) in cols.iter().zip(x) {
            for (&cb, &xb) in cols.iter().zip(x) {
                if cb <= ca {
                    x_d_x[ca * p + cb] += xa * xb;
                }
            }
            // Rows 6 knot .. 6 knot + 12 of column `ca`: the two knots' six components.
            let b = &mut h_d_x[ca * n_b + 6 * knot..ca * n_b + 6 * knot + 12];
            for k in 0..6 {
                b[k] += hl[k] * xa;
                b[6 + k] += hr[k] * xa;
            }
        }
    }
}

/// Buffers of [`Sums::add_group`], kept from group to group.
#[derive(Default)]
struct Scratch {
    /// The members' design rows one after the other, member `a`'s from `starts[a]`.
    entries: Vec<(usize, f64)>,
    starts: Vec<usize>,
    /// The columns of the group's design, and each entry's place among them.
    cols: Vec<usize>,
    slot: Vec<usize>,
    /// `[X H]` (row-major), the lower triangle of `D_g` (row-major), the bridge factors.
    y: Vec<f64>,
    d: Vec<f64>,
    u: Vec<[f64; 6]>,
}

impl Scratch {
    /// The design rows of `group`'s members and their columns: the first member's, when every
    /// member has the same (the catalogue's rows do), else their sorted union.
    fn design(&mut self, group: &[Row], row: &RowFn) {
        self.entries.clear();
        self.starts.clear();
        for r in group {
            self.starts.push(self.entries.len());
            row(r.o, &mut self.entries);
        }
        self.starts.push(self.entries.len());
        let first = &self.entries[..self.starts[1]];
        let same = self.starts.windows(2).all(|w| {
            let e = &self.entries[w[0]..w[1]];
            e.len() == first.len() && e.iter().zip(first).all(|(a, b)| a.0 == b.0)
        });
        self.cols.clear();
        self.slot.clear();
        if same {
            self.cols.extend(first.iter().map(|e| e.0));
            let n = first.len();
            self.slot
                .extend((0..self.entries.len()).map(|i| i % n.max(1)));
        } else {
            self.cols.extend(self.entries.iter().map(|e| e.0));
            self.cols.sort_unstable();
            self.cols.dedup();
            let cols = &self.cols;
            self.slot.extend(
                self.entries
                    .iter()
                    .map(|e| cols.binary_search(&e.0).expect("listed")),
            );
        }
    }
}

/// Factorises the symmetric positive definite `m x m` matrix whose lower triangle `d` holds
/// (row-major) as `L L^T`, `L` in its place; returns `ln det`.
fn cholesky_in_place(d: &mut [f64], m: usize) -> f64 {
    let mut log_det = 0.0;
    for a in 0..m {
        for b in 0..=a {
            let dot: f64 = (0..b).map(|k| d[a * m + k] * d[b * m + k]).sum();
            let v = d[a * m + b] - dot;
            if a == b {
                assert!(
                    v > 0.0,
                    "scanner variance plus a covariance is positive definite"
                );
                d[a * m + a] = v.sqrt();
                log_det += v.ln();
            } else {
                d[a * m + b] = v / d[b * m + b];
            }
        }
    }
    log_det
}

/// `Y <- L^-1 Y` for the lower triangular `m x m` `l` (row-major) and `Y` of `m` rows of
/// `w` (row-major).
fn forward_substitute(l: &[f64], m: usize, y: &mut [f64], w: usize) {
    for a in 0..m {
        let (done, rest) = y.split_at_mut(a * w);
        let ya = &mut rest[..w];
        for b in 0..a {
            let lab = l[a * m + b];
            for (v, yb) in ya.iter_mut().zip(&done[b * w..(b + 1) * w]) {
                *v -= lab * yb;
            }
        }
        let inv = l[a * m + a].recip();
        ya.iter_mut().for_each(|v| *v *= inv);
    }
}

/// Knots whose rows of `Y` are gathered before they are added to `Y^T Y` as one product.
const GRAM_CHUNK: usize = 64;
/// Knots from which [`whitened_gram`] eliminates the chain from both ends at once.
const SPLIT_KNOTS: usize = 256;

/// `B^T M^-1 B` for the symmetric positive definite block-tridiagonal `M` of `k` knots
/// (`N x N` diagonal blocks `diag(j)`, `next(j)` = the block of row `j`, column `j + 1`;
/// `b(j, c)` the `N` rows of column `c` of `B` at knot `j`), and `ln det M`. The knots before
/// and after a middle knot `s` are eliminated side by side ([`eliminate`], one from each
/// end), then `s` with what both left on it: with `A`, `C` the two sides, `S = M_ss - M_sA M_AA^-1 M_As - M_sC M_CC^-1
/// M_Cs` and `r = B_s - M_sA M_AA^-1 B_A - M_sC M_CC^-1 B_C`,
/// `B^T M^-1 B = B_A^T M_AA^-1 B_A + B_C^T M_CC^-1 B_C + r^T S^-1 r` and
/// `ln det M = ln det M_AA + ln det M_CC + ln det S`: exact, and the same arithmetic
/// whatever the number of threads.
fn whitened_gram<const N: usize>(
    k: usize,
    diag: impl Fn(usize) -> SMatrix<f64, N, N> + Sync,
    next: impl Fn(usize) -> SMatrix<f64, N, N> + Sync,
    p: usize,
    b: impl Fn(usize, usize) -> SVector<f64, N> + Sync,
) -> (DMatrix<f64>, f64) {
    if k < SPLIT_KNOTS {
        let whole = eliminate(k, &diag, |j| (j + 1 < k).then(|| next(j)), p, &b);
        return (whole.gram, whole.log_det);
    }
    let s = k / 2;
    let (before, after) = rayon::join(
        || eliminate(s, &diag, |j| Some(next(j)), p, &b),
        || {
            let knot = |i: usize| k - 1 - i;
            let b_rev = |i: usize, c: usize| b(knot(i), c);
            eliminate(
                k - 1 - s,
                &|i| diag(knot(i)),
                |i| Some(next(knot(i) - 1).transpose()),
                p,
                &b_rev,
            )
        },
    );
    let mut rest = diag(s);
    for side in [&before, &after] {
        let lb = side
            .l_below
            .as_ref()
            .expect("both sides end on the middle knot");
        rest -= lb * lb.transpose();
    }
    let l = rest
        .cholesky()
        .expect("prior precision plus a Gram matrix is positive definite")
        .l();
    let mut y = DMatrix::<f64>::zeros(N, p);
    for c in 0..p {
        let mut rhs = b(s, c);
        for side in [&before, &after] {
            rhs -= side.l_below.as_ref().expect("as above") * side.y[c];
        }
        let y_c = l
            .solve_lower_triangular(&rhs)
            .expect("Cholesky factor is invertible");
        y.fixed_view_mut::<N, 1>(0, c).copy_from(&y_c);
    }
    let mut gram = before.gram + after.gram;
    add_gram(&mut gram, &y, N);
    let log_det =
        before.log_det + after.log_det + 2.0 * l.diagonal().iter().map(|x| x.ln()).sum::<f64>();
    (gram, log_det)
}

/// What eliminating a chain of knots leaves: `Y^T Y` and `ln det` of its part of `M`, and
/// for the knot after its last one, `L_{n, n-1}` (the coupling `next(n - 1)` times the last
/// factor's inverse transpose) and the last knot's `Y` column by column.
struct Eliminated<const N: usize> {
    gram: DMatrix<f64>,
    log_det: f64,
    l_below: Option<SMatrix<f64, N, N>>,
    y: Vec<SVector<f64, N>>,
}

/// Block Cholesky `M = L L^T` of the chain of `n` knots (`diag(j)` its diagonal blocks,
/// `next(j)` the block of row `j`, column `j + 1`, `None` past the chain's end), `Y = L^-1 B`
/// by forward substitution, `Y^T Y`, `ln det = 2 sum ln diag L`.
fn eliminate<const N: usize>(
    n: usize,
    diag: &impl Fn(usize) -> SMatrix<f64, N, N>,
    next: impl Fn(usize) -> Option<SMatrix<f64, N, N>>,
    p: usize,
    b: &impl Fn(usize, usize) -> SVector<f64, N>,
) -> Eliminated<N> {
    let mut gram = DMatrix::<f64>::zeros(p, p);
    let mut log_det = 0.0;
    let mut chunk = DMatrix::<f64>::zeros(N * GRAM_CHUNK, p);
    let mut filled = 0;
    // Y at the last knot, column by column, and L_{j, j-1} carried from knot j - 1.
    let mut y = vec![SVector::<f64, N>::zeros(); p];
    let mut l_below: Option<SMatrix<f64, N, N>> = None;
    for j in 0..n {
        let mut s = diag(j);
        if let Some(lb) = &l_below {
            s -= lb * lb.transpose();
        }
        let l = s
            .cholesky()
            .expect("prior precision plus a Gram matrix is positive definite")
            .l();
        log_det += 2.0 * l.diagonal().iter().map(|x| x.ln()).sum::<f64>();
        let l_inv = l
            .solve_lower_triangular(&SMatrix::<f64, N, N>::identity())
            .expect("Cholesky factor is invertible");
        for (c, y_c) in y.iter_mut().enumerate() {
            let mut rhs = b(j, c);
            if let Some(lb) = &l_below {
                rhs -= lb * *y_c;
            }
            *y_c = l_inv * rhs;
            chunk.fixed_view_mut::<N, 1>(N * filled, c).copy_from(y_c);
        }
        filled += 1;
        if filled == GRAM_CHUNK || j + 1 == n {
            add_gram(&mut gram, &chunk, N * filled);
            filled = 0;
        }
        // L_{j+1, j} = M_{j+1, j} L_jj^-T = (L_jj^-1 M_{j, j+1})^T.
        l_below = next(j).map(|m| (l_inv * m).transpose());
    }
    Eliminated {
        gram,
        log_det,
        l_below,
        y,
    }
}

/// Adds `A^T A` to the symmetric `out`, `A` the first `rows` rows of `chunk`: the upper
/// triangle by dot products, mirrored.
fn add_gram(out: &mut DMatrix<f64>, chunk: &DMatrix<f64>, rows: usize) {
    for i in 0..chunk.ncols() {
        let a = chunk.column(i);
        let a = a.rows(0, rows);
        for j in i..chunk.ncols() {
            let d = a.dot(&chunk.column(j).rows(0, rows));
            out[(i, j)] += d;
            if j != i {
                out[(j, i)] += d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::diagnose::model::design::catalogue_row;
    use crate::app::diagnose::model::synthetic::{draw, Scenario};
    use crate::app::diagnose::model::N_EFFECTS;

    /// Dense reference: `C = D + H Sigma H^T` with `Sigma` the Gauss-Markov covariance of the
    /// knots, `s_i s_j exp(-|t_i - t_j| / tau)` (whose inverse the block solve uses), plus
    /// the slow process's `share s_i s_j exp(-|t_i - t_j| / tau_slow)`.
    fn dense_gram(set: &ObservationSet, selected: &[bool], tau: [f64; 2]) -> (DMatrix<f64>, f64) {
        let process = Process::of(set, tau);
        let Layout {
            knot_s,
            idx,
            rows,
            sigma,
        } = Layout::new(set, selected, &process);
        let (n, nk) = (rows.len(), idx.len());
        let mut h = DMatrix::<f64>::zeros(n, 6 * nk);
        let mut x = DMatrix::<f64>::zeros(n, N_EFFECTS + 1);
        let mut c = DMatrix::<f64>::zeros(n, n);
        let mut entries = Vec::new();
        for (i, r) in rows.iter().enumerate() {
            for k in 0..6 {
                h[(i, 6 * r.knot + k)] = (1.0 - r.w) * r.o.nav_gradient[k];
                h[(i, 6 * r.knot + 6 + k)] = r.w * r.o.nav_gradient[k];
            }
            entries.clear();
            catalogue_row(r.o, &mut entries);
            for &(col, v) in &entries {
                x[(i, col)] = v;
            }
            let nav_var = &set.visits[r.o.visit].nav_cov;
            let own = (r.o, nav_var, r.w);
            c[(i, i)] = r.o.var_white_m2 + bridge_cov_m2(own, own, &process, knot_s);
            let white_var = set.white_nav_var(set.nav_white_share);
            for (j, q) in rows.iter().enumerate() {
                c[(i, j)] += white_nav_cov_m2(r.o, q.o, &white_var);
                if j != i && r.group.is_some() && r.group == q.group {
                    let q_var = &set.visits[q.o.visit].nav_cov;
                    let (a, b) = ((r.o, nav_var, r.w), (q.o, q_var, q.w));
                    c[(i, j)] += bridge_cov_m2(a, b, &process, knot_s);
                }
            }
        }
        let prior = DMatrix::from_fn(6 * nk, 6 * nk, |i, j| {
            let (ki, kj) = (i % 6, j % 6);
            if ki != kj {
                return 0.0;
            }
            let dt = ((idx[i / 6] - idx[j / 6]) as f64 * knot_s).abs();
            let slow = set
                .nav_slow
                .map_or(0.0, |s| s.share[ki / 3] * (-dt / s.tau_s[ki / 3]).exp());
            sigma[i / 6][ki] * sigma[j / 6][kj] * ((-dt / tau[ki / 3]).exp() + slow)
        });
        c += &h * prior * h.transpose();
        let chol = c.clone().cholesky().unwrap();
        let log_det = 2.0 * chol.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
        (x.transpose() * c.try_inverse().unwrap() * x, log_det)
    }

    #[test]
    fn block_tridiagonal_solve_equals_the_dense_inverse() {
        let tau = [60.0, 30.0];
        let mut set = draw(
            &Scenario {
                nav_tau_s: Some(tau),
                returns_per_profile: Some(3),
                ..Default::default()
            },
            3,
        );
        // Returns three to a profile share their records' white navigation noise.
        set.nav_white_share = [0.4, 0.2];
        solve_equals_dense(&set, tau);
        // A second, slow process per block: 12 x 12 knot blocks.
        set.nav_slow = Some(SlowNav {
            share: [0.7, 0.3],
            tau_s: [900.0, 400.0],
        });
        solve_equals_dense(&set, tau);
    }

    fn solve_equals_dense(set: &ObservationSet, tau: [f64; 2]) {
        let mut selected = vec![false; set.reference_ids.len()];
        (selected[0], selected[1]) = (true, true);
        let (fast, fast_log_det) =
            gram_and_log_det(set, &selected, N_EFFECTS + 1, &catalogue_row, tau);
        let (dense, dense_log_det) = dense_gram(set, &selected, tau);
        let scale = crate::testing::max_abs(dense.iter().copied());
        // Both exact up to the rounding of a 240 x 240 inverse.
        let err = crate::testing::max_abs((fast - &dense).iter().copied());
        assert!(
            err < 1e-8 * scale,
            "largest difference {err:e} of {scale:e}"
        );
        // ln det C of a 240 x 240 matrix: the lemma against a dense Cholesky, to rounding
        // (the sum runs over 240 logarithms of about -10 each).
        let d = (fast_log_det - dense_log_det).abs();
        assert!(
            d < 1e-8 * dense_log_det.abs(),
            "ln det C {fast_log_det} vs dense {dense_log_det}"
        );
    }

    /// The chain eliminated from both ends and joined at its middle knot gives what one
    /// chain from the start gives, on a random diagonally dominant block-tridiagonal `M`
    /// long enough to be split (the one chain is checked against the dense inverse above).
    #[test]
    fn two_ended_elimination_equals_one_chain() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let k = 2 * SPLIT_KNOTS + 3;
        let mut draw_block = || Matrix6::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let next: Vec<Matrix6<f64>> = (0..k - 1).map(|_| draw_block()).collect();
        // Diagonally dominant: |entries| of the two coupling blocks sum to at most 12 a row.
        let diag: Vec<Matrix6<f64>> = (0..k)
            .map(|_| {
                let a = draw_block();
                a * a.transpose() + Matrix6::identity() * 14.0
            })
            .collect();
        let p = 5;
        let b_all = DMatrix::<f64>::from_fn(6 * k, p, |_, _| rng.random_range(-1.0..1.0));
        let b = |j: usize, c: usize| b_all.fixed_view::<6, 1>(6 * j, c).into_owned();
        let (split, split_log_det) = whitened_gram(k, |j| diag[j], |j| next[j], p, b);
        let one = eliminate(k, &|j| diag[j], |j| next.get(j).copied(), p, &b);
        let scale = crate::testing::max_abs(one.gram.iter().copied());
        let err = crate::testing::max_abs((split - &one.gram).iter().copied());
        // Rounding of sums over 515 knots, in another order.
        assert!(
            err < 1e-11 * scale,
            "largest difference {err:e} of {scale:e}"
        );
        let d = (split_log_det - one.log_det).abs();
        assert!(
            d < 1e-11 * one.log_det.abs(),
            "ln det {split_log_det} vs {}",
            one.log_det
        );
    }

    /// The spacing rule: a shorter process (a larger diffusion) gets finer knots, in
    /// proportion between the bounds, with the mean bridge share at mid-interval equal to
    /// [`MAX_BRIDGE_SHARE`] there; the bounds hold outside; no navigation variance, the widest.
    #[test]
    fn knots_are_finer_for_a_shorter_process() {
        let set = draw(&Scenario::default(), 6);
        let selected = vec![true; set.reference_ids.len()];
        let spacing = |tau: f64| knot_spacing_s(&set, &selected, &Process::of(&set, [tau; 2]));
        let mean_share = |tau: f64, knot_s: f64| {
            let process = Process::of(&set, [tau; 2]);
            let shares: Vec<f64> = set
                .observations
                .iter()
                .map(|o| {
                    let mid = (o, &set.visits[o.visit].nav_cov, 0.5);
                    bridge_cov_m2(mid, mid, &process, knot_s) / o.var_white_m2
                })
                .collect();
            shares.iter().sum::<f64>() / shares.len() as f64
        };
        // The correlation time at which this set's knots fall mid-range (spacing ~ tau).
        let tau_1 = 1.0;
        let s_1 = MAX_BRIDGE_SHARE / mean_share(tau_1, 1.0);
        let tau_mid = tau_1 * 0.05 / s_1;
        let (s_mid, s_half) = (spacing(tau_mid), spacing(tau_mid / 2.0));
        assert!((s_mid - 0.05).abs() < 1e-9, "{s_mid}");
        assert!((s_half - 0.025).abs() < 1e-9, "{s_half}");
        let share = mean_share(tau_mid, s_mid);
        assert!((share - MAX_BRIDGE_SHARE).abs() < 1e-9, "{share}");
        assert_eq!(spacing(tau_mid * 100.0), MAX_KNOT_S);
        assert_eq!(spacing(tau_mid / 100.0), MIN_KNOT_S);
        let mut still = set.clone();
        still
            .visits
            .iter_mut()
            .for_each(|v| v.nav_cov = [[0.0; 6]; 6]);
        let still_spacing = knot_spacing_s(&still, &selected, &Process::of(&still, [10.0; 2]));
        assert_eq!(still_spacing, MAX_KNOT_S);
    }

    /// The pieces summed in parallel cover every return once and never split the returns
    /// that share a record's white noise.
    #[test]
    fn pieces_cover_the_returns_and_keep_groups_whole() {
        let set = draw(
            &Scenario {
                returns_per_profile: Some(3),
                ..Default::default()
            },
            4,
        );
        let selected = vec![true; set.reference_ids.len()];
        let layout = Layout::new(&set, &selected, &Process::of(&set, [60.0, 30.0]));
        let bounds = piece_bounds(&layout.rows);
        assert_eq!(bounds.first(), Some(&0));
        assert_eq!(bounds.last(), Some(&layout.rows.len()));
        assert!(bounds.len() > 2 && bounds.len() <= PIECES + 1, "{bounds:?}");
        for w in bounds.windows(2) {
            assert!(w[0] < w[1], "{bounds:?}");
            let (a, b) = (&layout.rows[w[1] - 1], layout.rows.get(w[1]));
            assert!(b.is_none_or(|b| a.group.is_none() || a.group != b.group));
        }
        assert_eq!(piece_bounds(&[]), vec![0, 0]);
    }

    /// Sums accumulated on the unscaled set with a scale equal the sums of the set whose
    /// navigation covariances carry that scale (what `nuisance::apply` produces), and a
    /// solve at other correlation times and scales equals the full pass there up to the
    /// bridge variances held (a few per cent of the navigation variance over 0.1 s knots).
    #[test]
    fn knot_sums_carry_the_scale_of_the_navigation_sigmas() {
        let (tau, scale) = ([45.0, 20.0], [0.7, 1.4]);
        let base = draw(&Scenario::default(), 5);
        let mut scaled = base.clone();
        for v in scaled.visits.iter_mut() {
            for k in 0..6 {
                for l in 0..6 {
                    v.nav_cov[k][l] *= scale[k / 3] * scale[l / 3];
                }
            }
        }
        let selected = vec![true; base.reference_ids.len()];
        let p = N_EFFECTS + 1;
        let (want, want_log_det) = gram_and_log_det(&scaled, &selected, p, &catalogue_row, tau);
        let process = Process {
            tau,
            scale,
            slow: None,
        };
        let layout = Layout::new(&base, &selected, &process);
        let sums = KnotSums::accumulate(&base, &layout, p, &catalogue_row, &process, [0.0; 2]);
        let (got, got_log_det) = sums.solve(&process);
        let size = crate::testing::max_abs(want.iter().copied());
        let err = crate::testing::max_abs((&got - &want).iter().copied());
        // The same sums in another order of scaling: rounding only.
        assert!(err < 1e-10 * size, "largest difference {err:e} of {size:e}");
        assert!((got_log_det - want_log_det).abs() < 1e-10 * want_log_det.abs());
        // Solved away from where it was summed: close, not equal (bridge variances held).
        let far = KnotSums::accumulate(
            &base,
            &layout,
            p,
            &catalogue_row,
            &Process::of(&base, [60.0, 30.0]),
            [0.0; 2],
        );
        let (approx, _) = far.solve(&process);
        let rel = crate::testing::max_abs((&approx - &want).iter().copied()) / size;
        assert!(rel > 0.0 && rel < 0.05, "relative difference {rel:e}");
    }
}
