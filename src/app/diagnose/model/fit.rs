//! Generalised least squares under the residual model of [`super`]. Without
//! correlation times the returns of one visit share a navigation error `z_v ~ N(0, P_v)` and
//! visits are independent: the covariance of a visit is `C = D + G P_v G^T`, inverted by
//! Woodbury with `P_v = L L^T`: `C^-1 = D^-1 - D^-1 G L (I + L^T G^T D^-1 G L)^-1 L^T G^T D^-1`,
//! so every product `X^T C^-1 X` needs only per-visit sums (`X^T D^-1 X`, `G^T D^-1 X`,
//! `G^T D^-1 G`: O(n p^2) in all), never O(n^2). With correlation times
//! ([`ObservationSet::nav_tau_s`]) the navigation errors are Gauss-Markov processes in time,
//! within and between visits: [`super::continuous`].

use super::continuous;
use super::design::{catalogue_row, RowFn};
use super::{signature_index, Effect, ObservationSet, N_EFFECTS};
use crate::{Error, Result};
use nalgebra::{DMatrix, DVector, Matrix6, SymmetricEigen};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Per-visit sums on the columns its rows touch: `X^T D^-1 X`, `G^T D^-1 X`, `G^T D^-1 G`.
struct VisitStats {
    columns: Vec<usize>,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    k: Matrix6<f64>,
}

fn visit_stats(set: &ObservationSet, members: &[usize], p: usize, row: &RowFn) -> VisitStats {
    let mut local = vec![usize::MAX; p];
    let mut columns = Vec::new();
    let mut row_entries: Vec<(usize, f64)> = Vec::new();
    let mut rows = Vec::with_capacity(members.len());
    let mut entries = Vec::new();
    for &i in members {
        let o = &set.observations[i];
        row_entries.clear();
        row(o, &mut row_entries);
        let start = entries.len();
        for &(c, x) in &row_entries {
            if local[c] == usize::MAX {
                local[c] = columns.len();
                columns.push(c);
            }
            entries.push((local[c], x));
        }
        rows.push((start, entries.len(), 1.0 / o.var_white_m2, &o.nav_gradient));
    }
    let m = columns.len();
    let mut a = DMatrix::<f64>::zeros(m, m);
    let mut b = DMatrix::<f64>::zeros(6, m);
    let mut k = Matrix6::<f64>::zeros();
    for &(start, end, w, g) in &rows {
        let e = &entries[start..end];
        for &(ca, xa) in e {
            let wx = w * xa;
            for &(cb, xb) in e {
                a[(ca, cb)] += wx * xb;
            }
            for (j, gj) in g.iter().enumerate() {
                b[(j, ca)] += gj * wx;
            }
        }
        for i in 0..6 {
            for j in 0..6 {
                k[(i, j)] += w * g[i] * g[j];
            }
        }
    }
    VisitStats { columns, a, b, k }
}

/// `X^T C^-1 X` of one visit on the columns its rows touch.
pub(crate) struct BlockGram {
    /// Global column of each local row/column of `gram`.
    pub columns: Vec<usize>,
    /// `X^T C^-1 X` (local columns).
    pub gram: DMatrix<f64>,
}

impl BlockGram {
    /// Adds this gram into a global `p x p` matrix.
    pub fn add_to(&self, total: &mut DMatrix<f64>) {
        for (a, &ca) in self.columns.iter().enumerate() {
            for (b, &cb) in self.columns.iter().enumerate() {
                total[(ca, cb)] += self.gram[(a, b)];
            }
        }
    }
}

/// `L` with `Sigma = L L^T`: Cholesky after a jitter of 1e-12 of the largest variance, else
/// the eigen-decomposition with null directions dropped.
pub(crate) fn sigma_sqrt(sigma: DMatrix<f64>) -> DMatrix<f64> {
    let n = sigma.nrows();
    let max = sigma.diagonal().max();
    if max <= 0.0 {
        return DMatrix::zeros(n, 0);
    }
    let mut jittered = sigma.clone();
    for i in 0..n {
        jittered[(i, i)] += 1e-12 * max;
    }
    if let Some(c) = jittered.cholesky() {
        return c.l();
    }
    let eig = SymmetricEigen::new(sigma);
    let keep: Vec<usize> = (0..n).filter(|&j| eig.eigenvalues[j] > 0.0).collect();
    DMatrix::from_fn(n, keep.len(), |i, j| {
        eig.eigenvectors[(i, keep[j])] * eig.eigenvalues[keep[j]].sqrt()
    })
}

fn block_gram(stats: &[&VisitStats], sigma: DMatrix<f64>, p: usize) -> BlockGram {
    let mut local = vec![usize::MAX; p];
    let mut columns = Vec::new();
    for s in stats {
        for &c in &s.columns {
            if local[c] == usize::MAX {
                local[c] = columns.len();
                columns.push(c);
            }
        }
    }
    let m = columns.len();
    let nz = 6 * stats.len();
    let mut a = DMatrix::<f64>::zeros(m, m);
    let mut b = DMatrix::<f64>::zeros(nz, m);
    for (i, s) in stats.iter().enumerate() {
        for (x, &cx) in s.columns.iter().enumerate() {
            for (y, &cy) in s.columns.iter().enumerate() {
                a[(local[cx], local[cy])] += s.a[(x, y)];
            }
            for r in 0..6 {
                b[(6 * i + r, local[cx])] += s.b[(r, x)];
            }
        }
    }
    let l = sigma_sqrt(sigma);
    if l.ncols() == 0 {
        return BlockGram { columns, gram: a };
    }
    // K L with K = blockdiag(G_v^T D^-1 G_v).
    let mut kl = DMatrix::<f64>::zeros(nz, l.ncols());
    for (i, s) in stats.iter().enumerate() {
        let rows = l.rows(6 * i, 6);
        kl.rows_mut(6 * i, 6)
            .copy_from(&(DMatrix::from_fn(6, 6, |r, c| s.k[(r, c)]) * rows));
    }
    let lt = l.transpose();
    let mut inner = &lt * kl;
    for j in 0..l.ncols() {
        inner[(j, j)] += 1.0;
    }
    let bl = &lt * b;
    // I + L^T K L is symmetric positive definite (identity plus a Gram matrix).
    let chol = inner
        .cholesky()
        .expect("identity plus a Gram matrix is positive definite");
    a -= bl.transpose() * chol.solve(&bl);
    BlockGram { columns, gram: a }
}

/// `X^T C^-1 X` of each visit on `refs`, visits independent (computed in parallel, returned
/// in visit order: sums are reproducible).
fn visit_grams(set: &ObservationSet, selected: &[bool], p: usize, row: &RowFn) -> Vec<BlockGram> {
    let members = set.visit_members();
    (0..set.visits.len())
        .into_par_iter()
        .filter(|&v| selected[set.visits[v].reference] && !members[v].is_empty())
        .map(|v| {
            let pv = &set.visits[v].nav_cov;
            let sigma = DMatrix::from_fn(6, 6, |k, l| 0.5 * (pv[k][l] + pv[l][k]));
            block_gram(&[&visit_stats(set, &members[v], p, row)], sigma, p)
        })
        .collect()
}

/// `X^T C^-1 X` over the returns on `refs` (`p x p`): the exact product for those returns
/// alone.
pub(crate) fn total_gram(
    set: &ObservationSet,
    refs: &[usize],
    p: usize,
    row: &RowFn,
) -> DMatrix<f64> {
    let mut selected = vec![false; set.reference_ids.len()];
    for &r in refs {
        if let Some(s) = selected.get_mut(r) {
            *s = true;
        }
    }
    if let Some(tau) = set.nav_tau_s {
        return continuous::gram(set, &selected, p, row, tau);
    }
    let mut total = DMatrix::zeros(p, p);
    for g in visit_grams(set, &selected, p, row) {
        g.add_to(&mut total);
    }
    total
}

/// Number of observations on `refs`.
pub(crate) fn count_on(set: &ObservationSet, refs: &[usize]) -> usize {
    let mut selected = vec![false; set.reference_ids.len()];
    for &r in refs {
        if let Some(s) = selected.get_mut(r) {
            *s = true;
        }
    }
    set.observations
        .iter()
        .filter(|o| selected.get(o.reference) == Some(&true))
        .count()
}

/// `[S | r]^T C^-1 [S | r]` on a set of references, and its number of observations.
#[derive(Debug, Clone)]
pub struct Normals {
    /// Number of observations.
    pub n: usize,
    /// `(K+1) x (K+1)`: signatures in [`Effect::ALL`] order, then the residual.
    pub m: DMatrix<f64>,
}

/// A GLS fit of some effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// The effects fitted.
    pub effects: Vec<Effect>,
    /// Estimates, in the unit of each name.
    pub estimate: Vec<f64>,
    /// 1-sigma uncertainties (sqrt of the covariance diagonal).
    pub sigma: Vec<f64>,
    /// Covariance of the estimates.
    pub cov: DMatrix<f64>,
    /// Minimum `r^T C^-1 r` after the fit (NaN when the normals' residual column is).
    pub chi2: f64,
    /// Degrees of freedom: observations minus effects.
    pub dof: usize,
}

impl Fit {
    /// Each sigma the larger of its own and `other`'s, the covariance scaled with it (its
    /// correlations kept).
    pub fn widen_sigma(&mut self, other: &[f64]) {
        let wider: Vec<f64> = self
            .sigma
            .iter()
            .zip(other)
            .map(|(s, o)| s.max(*o))
            .collect();
        self.set_sigma(&wider);
    }

    /// The sigmas set to `sigma`, the covariance scaled with them (its correlations kept).
    pub fn set_sigma(&mut self, sigma: &[f64]) {
        let factor: Vec<f64> = self.sigma.iter().zip(sigma).map(|(s, o)| o / s).collect();
        for (i, fi) in factor.iter().enumerate() {
            self.sigma[i] *= fi;
            for (j, fj) in factor.iter().enumerate() {
                self.cov[(i, j)] *= fi * fj;
            }
        }
    }
}

impl Normals {
    /// The catalogue's statistics on the returns of `refs`.
    pub fn of(set: &ObservationSet, refs: &[usize]) -> Result<Normals> {
        Ok(Normals {
            n: count_on(set, refs),
            m: total_gram(set, refs, N_EFFECTS + 1, &catalogue_row),
        })
    }

    /// `r^T C^-1 r` with no effect.
    pub fn chi2_null(&self) -> f64 {
        self.m[(N_EFFECTS, N_EFFECTS)]
    }

    fn columns(effects: &[Effect]) -> Vec<usize> {
        effects.iter().map(|&e| signature_index(e)).collect()
    }

    /// `S_A^T C^-1 S_A` and `S_A^T C^-1 r`.
    fn system(&self, effects: &[Effect]) -> (DMatrix<f64>, DVector<f64>) {
        let c = Self::columns(effects);
        let n = DMatrix::from_fn(c.len(), c.len(), |i, j| self.m[(c[i], c[j])]);
        let b = DVector::from_fn(c.len(), |i, _| self.m[(c[i], N_EFFECTS)]);
        (n, b)
    }

    /// `(r - S theta)^T C^-1 (r - S theta)`.
    pub fn chi2_at(&self, effects: &[Effect], values: &[f64]) -> f64 {
        let (n, b) = self.system(effects);
        let x = DVector::from_column_slice(values);
        self.chi2_null() - 2.0 * b.dot(&x) + (n * &x).dot(&x)
    }

    /// `r^T (C + S_A Sigma S_A^T)^-1 r` (Woodbury: `r^T C^-1 r - b^T Sigma (I + N Sigma)^-1 b`,
    /// `N = S_A^T C^-1 S_A`, `b = S_A^T C^-1 r`): the chi-square of residuals that carry a
    /// correction of `effects` estimated elsewhere with covariance `sigma_cov` (in the names'
    /// units). A right correction's own error then counts as the noise it is, so the statistic
    /// is a chi-square on `n` under the model however well these returns see that error.
    /// `None` when `I + N Sigma` is singular.
    pub fn chi2_given_correction_cov(
        &self,
        effects: &[Effect],
        sigma_cov: &DMatrix<f64>,
    ) -> Option<f64> {
        let (n, b) = self.system(effects);
        let k = effects.len();
        let x = (DMatrix::identity(k, k) + &n * sigma_cov).lu().solve(&b)?;
        Some(self.chi2_null() - (sigma_cov * x).dot(&b))
    }

    /// `theta^T S^T C^-1 S theta`: the squared Mahalanobis size of a correction.
    pub fn quadratic(&self, effects: &[Effect], values: &[f64]) -> f64 {
        let (n, _) = self.system(effects);
        let x = DVector::from_column_slice(values);
        (n * &x).dot(&x)
    }

    /// GLS fit of `effects`; an error when they cannot be separated on these references.
    pub fn fit(&self, effects: &[Effect]) -> Result<Fit> {
        Ok(self.fit_with(effects, self.covariance(effects)?))
    }

    /// The covariance of a GLS fit of `effects`, `(S^T C^-1 S)^-1`: what does not depend on
    /// the residuals; an error when they cannot be separated on these references.
    pub fn covariance(&self, effects: &[Effect]) -> Result<DMatrix<f64>> {
        let (n, _) = self.system(effects);
        let names = || {
            effects
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let unobservable = |problem: &str| Error::Numerical {
            what: format!("GLS fit of {}", names()),
            problem: problem.to_string(),
        };
        if n.diagonal().iter().any(|&x| x.is_nan() || x <= 0.0) {
            return Err(unobservable(
                "an effect has no signature on these references",
            ));
        }
        // Jacobi scaling keeps the Cholesky test meaningful across units.
        let d = DVector::from_fn(n.nrows(), |i, _| 1.0 / n[(i, i)].sqrt());
        let scaled = DMatrix::from_fn(n.nrows(), n.ncols(), |i, j| n[(i, j)] * d[i] * d[j]);
        let chol = scaled
            .cholesky()
            .filter(|c| c.l().diagonal().iter().all(|&x| x > 1e-7))
            .ok_or_else(|| {
                unobservable(
                    "the effects cannot be separated on these references (singular normal matrix)",
                )
            })?;
        let scaled_inv = chol.inverse();
        Ok(DMatrix::from_fn(n.nrows(), n.ncols(), |i, j| {
            scaled_inv[(i, j)] * d[i] * d[j]
        }))
    }

    /// The GLS fit of `effects` with `cov` their [`Self::covariance`] (on these normals, or on
    /// others with the same signatures: only the residual column may differ).
    pub fn fit_with(&self, effects: &[Effect], cov: DMatrix<f64>) -> Fit {
        let c = Self::columns(effects);
        let b = DVector::from_fn(c.len(), |i, _| self.m[(c[i], N_EFFECTS)]);
        let estimate = &cov * &b;
        // Rounding can take it below 0; a NaN stays NaN (no evidence for the fit in
        // `select`), where `f64::max` would make it a perfect fit.
        let chi2 = self.chi2_null() - b.dot(&estimate);
        let chi2 = if chi2 < 0.0 { 0.0 } else { chi2 };
        Fit {
            effects: effects.to_vec(),
            sigma: cov.diagonal().iter().map(|v| v.sqrt()).collect(),
            estimate: estimate.iter().copied().collect(),
            cov,
            chi2,
            dof: self.n.saturating_sub(effects.len()),
        }
    }
}

/// GLS fit of `effects` on the references `refs`.
pub fn fit(set: &ObservationSet, refs: &[usize], effects: &[Effect]) -> Result<Fit> {
    Normals::of(set, refs)?.fit(effects)
}

/// The references used to fit and the references held out to check.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    /// References the effects are fitted on (ascending).
    pub fit: Vec<usize>,
    /// References the fits are judged on (ascending).
    pub held_out: Vec<usize>,
}

/// Splits the observed references in two halves (the fit half gets the odd one), shuffled
/// with `seed`. At least two observed references are needed.
pub fn split(set: &ObservationSet, seed: u64) -> Result<Split> {
    let mut refs = set.observed_references();
    if refs.len() < 2 {
        return Err(Error::Numerical {
            what: "diagnosis split".to_string(),
            problem: format!(
                "cannot tell: {} reference patch(es) have returns; at least 2 are needed to fit on one and check on another",
                refs.len()
            ),
        });
    }
    refs.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let n_fit = refs.len().div_ceil(2);
    let mut fit = refs[..n_fit].to_vec();
    let mut held_out = refs[n_fit..].to_vec();
    fit.sort_unstable();
    held_out.sort_unstable();
    Ok(Split { fit, held_out })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::diagnose::model::synthetic::{draw, Scenario};

    /// Dense reference: `X^T C^-1 X` with the full covariance of the returns on `refs`.
    fn dense_gram(set: &ObservationSet, refs: &[usize]) -> DMatrix<f64> {
        let idx: Vec<usize> = (0..set.observations.len())
            .filter(|&i| refs.contains(&set.observations[i].reference))
            .collect();
        let x = DMatrix::from_fn(idx.len(), N_EFFECTS + 1, |i, j| {
            let o = &set.observations[idx[i]];
            if j < N_EFFECTS {
                o.signature[j]
            } else {
                o.residual_m
            }
        });
        let c = DMatrix::from_fn(idx.len(), idx.len(), |i, j| {
            let (a, b) = (&set.observations[idx[i]], &set.observations[idx[j]]);
            let pv = &set.visits[a.visit].nav_cov;
            let mut v: f64 = if a.visit == b.visit {
                (0..6)
                    .map(|k| {
                        (0..6)
                            .map(|l| a.nav_gradient[k] * pv[k][l] * b.nav_gradient[l])
                            .sum::<f64>()
                    })
                    .sum()
            } else {
                0.0
            };
            if i == j {
                v += a.var_white_m2;
            }
            v
        });
        x.transpose() * c.try_inverse().unwrap() * x
    }

    #[test]
    fn woodbury_equals_the_dense_inverse() {
        // Independent visits (the Gauss-Markov case has its own test in `continuous`).
        let set = draw(&Scenario::default(), 3);
        let blocked = total_gram(&set, &[0, 1], N_EFFECTS + 1, &catalogue_row);
        let dense = dense_gram(&set, &[0, 1]);
        let scale = crate::testing::max_abs(dense.iter().copied());
        // Both exact up to rounding of a 240x240 inverse with condition ~1e4.
        assert!(crate::testing::max_abs((blocked - &dense).iter().copied()) < 1e-8 * scale);
    }

    #[test]
    fn split_is_by_reference_deterministic_and_refuses_one_reference() {
        let set = draw(&Scenario::default(), 3);
        let a = split(&set, 9).unwrap();
        assert_eq!(a, split(&set, 9).unwrap());
        assert_eq!(a.fit.len(), 12);
        assert!(a.fit.iter().all(|r| !a.held_out.contains(r)));
        let mut one = set.clone();
        one.observations.retain(|o| o.reference == 0);
        let e = split(&one, 9).unwrap_err().to_string();
        assert!(e.contains("cannot tell"), "{e}");
    }

    #[test]
    fn fit_recovers_an_injected_effect_within_its_sigma() {
        let truth = 0.02;
        let s = Scenario {
            truth: vec![(Effect::RangeZero, truth)],
            ..Default::default()
        };
        let set = draw(&s, 5);
        let all = set.observed_references();
        let f = fit(&set, &all, &[Effect::RangeZero]).unwrap();
        // 4 sigma: a single draw.
        assert!((f.estimate[0] - truth).abs() < 4.0 * f.sigma[0], "{f:?}");
        assert_eq!(f.dof, set.observations.len() - 1);
    }
    #[test]
    fn a_nan_residual_column_gives_a_nan_fit_chi2_not_a_perfect_fit() {
        let set = draw(&Scenario::default(), 5);
        let mut normals = Normals::of(&set, &set.observed_references()).unwrap();
        normals.m[(0, N_EFFECTS)] = f64::NAN;
        let f = normals.fit(&[Effect::ALL[0]]).unwrap();
        assert!(f.chi2.is_nan(), "{}", f.chi2);
    }
    #[test]
    fn chi2_given_a_correction_cov_is_the_dense_quadratic_form() {
        // C = I, three returns, two effects: r^T (I + S Sigma S^T)^-1 r by a dense inverse.
        let s = DMatrix::from_row_slice(3, 2, &[1.0, 0.5, -2.0, 1.0, 0.3, 3.0]);
        let r = DVector::from_column_slice(&[0.7, -1.2, 2.5]);
        let sigma = DMatrix::from_row_slice(2, 2, &[0.4, 0.1, 0.1, 0.9]);
        let dense = (DMatrix::identity(3, 3) + &s * &sigma * s.transpose())
            .try_inverse()
            .unwrap();
        let expected = (&dense * &r).dot(&r);
        let mut m = DMatrix::zeros(N_EFFECTS + 1, N_EFFECTS + 1);
        let effects = [Effect::ALL[0], Effect::ALL[1]];
        let (st_s, st_r) = (s.transpose() * &s, s.transpose() * &r);
        for i in 0..2 {
            for j in 0..2 {
                m[(i, j)] = st_s[(i, j)];
            }
            m[(i, N_EFFECTS)] = st_r[i];
            m[(N_EFFECTS, i)] = st_r[i];
        }
        m[(N_EFFECTS, N_EFFECTS)] = r.dot(&r);
        let normals = Normals { n: 3, m };
        let got = normals.chi2_given_correction_cov(&effects, &sigma).unwrap();
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
        // No uncertainty: the plain chi-square.
        let zero = DMatrix::zeros(2, 2);
        let plain = normals.chi2_given_correction_cov(&effects, &zero).unwrap();
        assert!((plain - r.dot(&r)).abs() < 1e-12);
    }
}
