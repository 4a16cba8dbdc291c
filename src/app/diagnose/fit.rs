//! Generalised least squares under the per-visit residual model of [`super::model`]: the
//! covariance of visit `v` is `C_v = D_v + G_v P_v G_v^T`, inverted by Woodbury with
//! `P_v = L L^T`: `C_v^-1 = D^-1 - D^-1 G L (I + L^T G^T D^-1 G L)^-1 L^T G^T D^-1`, so every
//! product `X^T C^-1 X` costs O(n_v p^2) per visit: O(n k^2) overall, never O(n^2).
//!
//! The catalogue's sufficient statistics `[S | r]^T C^-1 [S | r]` are summed once per
//! reference ([`CatalogueNormals`]); any fit, chi2 or held-out evaluation on any set of
//! references is then a small (K+1)x(K+1) problem.

use super::model::{signature_index, Effect, Observation, ObservationSet, Visit, N_EFFECTS};
use crate::{Error, Result};
use nalgebra::{DMatrix, DVector, Matrix6, SymmetricEigen};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// One design row, sparse: `(column, value)` entries, each column at most once.
pub(crate) type RowFn<'a> = dyn Fn(&Observation, &mut Vec<(usize, f64)>) + Sync + 'a;

/// Columns of `L` with `P = L L^T` (eigen-decomposition of the symmetrised `P`; rounding
/// negatives clamped, null directions dropped).
fn nav_sqrt(p: &[[f64; 6]; 6]) -> Vec<[f64; 6]> {
    let m = Matrix6::from_fn(|i, j| 0.5 * (p[i][j] + p[j][i]));
    let eig = SymmetricEigen::new(m);
    (0..6)
        .filter(|&k| eig.eigenvalues[k] > 0.0)
        .map(|k| {
            let s = eig.eigenvalues[k].sqrt();
            std::array::from_fn(|i| eig.eigenvectors[(i, k)] * s)
        })
        .collect()
}

/// One visit's `X^T C^-1 X` on the columns its rows touch.
pub(crate) struct VisitGram {
    /// Global column of each local row/column of `gram`.
    pub columns: Vec<usize>,
    /// `X_v^T C_v^-1 X_v` (local columns).
    pub gram: DMatrix<f64>,
}

impl VisitGram {
    /// Adds this gram into a global `p x p` matrix.
    pub fn add_to(&self, total: &mut DMatrix<f64>) {
        for (a, &ca) in self.columns.iter().enumerate() {
            for (b, &cb) in self.columns.iter().enumerate() {
                total[(ca, cb)] += self.gram[(a, b)];
            }
        }
    }
}

fn visit_gram(
    set: &ObservationSet,
    members: &[usize],
    visit: &Visit,
    p: usize,
    row: &RowFn,
) -> VisitGram {
    let l = nav_sqrt(&visit.nav_cov);
    let q = l.len();
    let mut local = vec![usize::MAX; p];
    let mut columns = Vec::new();
    let mut entries = Vec::new();
    let mut row_entries: Vec<(usize, f64)> = Vec::new();
    let mut rows = Vec::with_capacity(members.len());
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
        let g_l: [f64; 6] = std::array::from_fn(|k| {
            l.get(k)
                .map_or(0.0, |lk| (0..6).map(|j| o.nav_gradient[j] * lk[j]).sum())
        });
        rows.push((start, entries.len(), 1.0 / o.var_white_m2, g_l));
    }
    let m = columns.len();
    let mut a = DMatrix::<f64>::zeros(m, m);
    let mut b = DMatrix::<f64>::zeros(q, m);
    let mut inner = DMatrix::<f64>::identity(q, q);
    for &(start, end, w, g) in &rows {
        let e = &entries[start..end];
        for &(ca, xa) in e {
            let wx = w * xa;
            for &(cb, xb) in e {
                a[(ca, cb)] += wx * xb;
            }
            for k in 0..q {
                b[(k, ca)] += g[k] * wx;
            }
        }
        for k in 0..q {
            for j in 0..q {
                inner[(k, j)] += w * g[k] * g[j];
            }
        }
    }
    if q > 0 {
        // I + L^T G^T D^-1 G L is symmetric positive definite (identity plus a Gram matrix).
        let chol = inner
            .cholesky()
            .expect("identity plus a Gram matrix is positive definite");
        let solved = chol.solve(&b);
        a -= b.transpose() * solved;
    }
    VisitGram { columns, gram: a }
}

/// `X_v^T C_v^-1 X_v` for every visit whose reference is in `refs`, with the visit index, in
/// visit order (computed in parallel, returned in a fixed order: sums are reproducible).
pub(crate) fn visit_grams(
    set: &ObservationSet,
    refs: &[usize],
    p: usize,
    row: &RowFn,
) -> Vec<(usize, VisitGram)> {
    let mut selected = vec![false; set.reference_ids.len()];
    for &r in refs {
        if let Some(s) = selected.get_mut(r) {
            *s = true;
        }
    }
    let members = set.visit_members();
    (0..set.visits.len())
        .into_par_iter()
        .filter(|&v| selected.get(set.visits[v].reference) == Some(&true) && !members[v].is_empty())
        .map(|v| (v, visit_gram(set, &members[v], &set.visits[v], p, row)))
        .collect()
}

/// `sum_v X_v^T C_v^-1 X_v` over the visits of `refs` (`p x p`).
pub(crate) fn total_gram(
    set: &ObservationSet,
    refs: &[usize],
    p: usize,
    row: &RowFn,
) -> DMatrix<f64> {
    let mut total = DMatrix::zeros(p, p);
    for (_, g) in visit_grams(set, refs, p, row) {
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

/// The catalogue's design row: every signature, then the residual (column [`N_EFFECTS`]).
fn catalogue_row(o: &Observation, out: &mut Vec<(usize, f64)>) {
    out.extend(o.signature.iter().copied().enumerate());
    out.push((N_EFFECTS, o.residual_m));
}

/// `[S | r]^T C^-1 [S | r]` summed per reference: the sufficient statistics of every GLS fit
/// of catalogue effects.
#[derive(Debug, Clone)]
pub struct CatalogueNormals {
    by_reference: Vec<DMatrix<f64>>,
    n_by_reference: Vec<usize>,
}

impl CatalogueNormals {
    /// Validates `set` and accumulates its statistics (O(n K^2)).
    pub fn new(set: &ObservationSet) -> Result<Self> {
        set.validate()?;
        let p = N_EFFECTS + 1;
        let refs = set.observed_references();
        let mut by_reference = vec![DMatrix::zeros(p, p); set.reference_ids.len()];
        for (v, g) in visit_grams(set, &refs, p, &catalogue_row) {
            g.add_to(&mut by_reference[set.visits[v].reference]);
        }
        let mut n_by_reference = vec![0; set.reference_ids.len()];
        for o in &set.observations {
            n_by_reference[o.reference] += 1;
        }
        Ok(CatalogueNormals {
            by_reference,
            n_by_reference,
        })
    }

    /// The statistics summed over `refs`.
    pub fn on(&self, refs: &[usize]) -> Normals {
        let p = N_EFFECTS + 1;
        let mut m = DMatrix::zeros(p, p);
        let mut n = 0;
        for &r in refs {
            m += &self.by_reference[r];
            n += self.n_by_reference[r];
        }
        Normals { n, m }
    }
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
    /// Minimum `r^T C^-1 r` after the fit.
    pub chi2: f64,
    /// Degrees of freedom: observations minus effects.
    pub dof: usize,
}

impl Normals {
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

    /// `theta^T S^T C^-1 S theta`: the squared Mahalanobis size of a correction.
    pub fn quadratic(&self, effects: &[Effect], values: &[f64]) -> f64 {
        let (n, _) = self.system(effects);
        let x = DVector::from_column_slice(values);
        (n * &x).dot(&x)
    }

    /// GLS fit of `effects`; an error when they cannot be separated on these references.
    pub fn fit(&self, effects: &[Effect]) -> Result<Fit> {
        let (n, b) = self.system(effects);
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
        let cov = DMatrix::from_fn(n.nrows(), n.ncols(), |i, j| {
            scaled_inv[(i, j)] * d[i] * d[j]
        });
        let estimate = &cov * &b;
        let chi2 = (self.chi2_null() - b.dot(&estimate)).max(0.0);
        Ok(Fit {
            effects: effects.to_vec(),
            sigma: cov.diagonal().iter().map(|v| v.sqrt()).collect(),
            estimate: estimate.iter().copied().collect(),
            cov,
            chi2,
            dof: self.n.saturating_sub(effects.len()),
        })
    }
}

/// GLS fit of `effects` on the references `refs` (convenience over [`CatalogueNormals`]).
pub fn fit(set: &ObservationSet, refs: &[usize], effects: &[Effect]) -> Result<Fit> {
    CatalogueNormals::new(set)?.on(refs).fit(effects)
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
    use super::super::model::synthetic::{draw, Scenario};
    use super::*;

    /// Dense reference: `X^T C^-1 X` with the full `C` of one visit.
    fn dense_gram(set: &ObservationSet, v: usize) -> DMatrix<f64> {
        let idx: Vec<usize> = set.visit_members()[v].clone();
        let p = N_EFFECTS + 1;
        let x = DMatrix::from_fn(idx.len(), p, |i, j| {
            let o = &set.observations[idx[i]];
            if j < N_EFFECTS {
                o.signature[j]
            } else {
                o.residual_m
            }
        });
        let g = DMatrix::from_fn(idx.len(), 6, |i, j| {
            set.observations[idx[i]].nav_gradient[j]
        });
        let pm = DMatrix::from_fn(6, 6, |i, j| set.visits[v].nav_cov[i][j]);
        let mut c = &g * pm * g.transpose();
        for (i, &k) in idx.iter().enumerate() {
            c[(i, i)] += set.observations[k].var_white_m2;
        }
        x.transpose() * c.try_inverse().unwrap() * x
    }

    #[test]
    fn woodbury_equals_the_dense_inverse() {
        let set = draw(&Scenario::default(), 3);
        let grams = visit_grams(&set, &[0], N_EFFECTS + 1, &catalogue_row);
        let (v, g) = &grams[0];
        let mut total = DMatrix::zeros(N_EFFECTS + 1, N_EFFECTS + 1);
        g.add_to(&mut total);
        let dense = dense_gram(&set, *v);
        let scale = dense.abs().max();
        // Both are exact up to rounding of a 40x40 inverse with condition ~1e4.
        assert!((total - &dense).abs().max() < 1e-8 * scale);
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
}
