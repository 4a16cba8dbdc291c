//! Variance-based (Sobol) sensitivity by Monte Carlo (Saltelli et al. 2010).
//!
//! Inputs are independent, normal with mean 0 and the given sigmas. For `n` base rows, two
//! independent matrices `A` and `B` are drawn; for each factor `F` (one input or a group of
//! inputs varied together) `AB_F` is `A` with the columns of `F` taken from `B`. The model is
//! run on every row of `A`, `B` and each `AB_F` (`n (F + 2)` runs). With outputs centred on
//! their overall mean (as SALib does) and `V = var([f(A); f(B)])`:
//! - first order (Saltelli 2010): `S_F = mean(f(B) (f(AB_F) - f(A))) / V`;
//! - total effect (Jansen 1999): `ST_F = mean((f(A) - f(AB_F))^2) / (2 V)`.
//!
//! Confidence half-widths are `1.96 x` the standard deviation of the estimates over bootstrap
//! resamples of the base rows (95%, as SALib's `S1_conf`, `ST_conf`). Each model output is
//! analysed on its own; the combined index of a 3-vector output sums numerators and variances
//! over the components (the variance-weighted mean of the per-component indices).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// Number of model outputs (a 3-vector: map or ENU axes).
pub const N_OUT: usize = 3;

/// Normal quantile of 0.975 (95% two-sided intervals).
const Z95: f64 = 1.959_963_984_540_054;

/// The Saltelli design: base matrices `A` and `B` (row-major, `n x dim`) and the factors.
#[derive(Debug, Clone)]
pub struct SaltelliDesign {
    /// Number of base rows.
    pub n: usize,
    /// Number of model inputs.
    pub dim: usize,
    /// Factors: each a list of input indices varied together.
    pub factors: Vec<Vec<usize>>,
    a: Vec<f64>,
    b: Vec<f64>,
}

/// Which row of the design.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Row {
    /// Row of `A`.
    A,
    /// Row of `B`.
    B,
    /// Row of `AB_F` for factor `F`.
    Ab(usize),
}

impl SaltelliDesign {
    /// Draws `A` and `B` (`n` rows of independent `N(0, sigma_i^2)`), seeded.
    pub fn new(sigmas: &[f64], factors: Vec<Vec<usize>>, n: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let dim = sigmas.len();
        let draw = |rng: &mut ChaCha8Rng| -> Vec<f64> {
            (0..n * dim)
                .map(|k| {
                    let z: f64 = StandardNormal.sample(rng);
                    z * sigmas[k % dim]
                })
                .collect()
        };
        let a = draw(&mut rng);
        let b = draw(&mut rng);
        SaltelliDesign {
            n,
            dim,
            factors,
            a,
            b,
        }
    }

    /// Input vector of base row `j` for `row`.
    pub fn row(&self, j: usize, row: Row) -> Vec<f64> {
        let span = j * self.dim..(j + 1) * self.dim;
        match row {
            Row::A => self.a[span].to_vec(),
            Row::B => self.b[span].to_vec(),
            Row::Ab(f) => {
                let mut x = self.a[span.clone()].to_vec();
                let b = &self.b[span];
                self.factors[f].iter().for_each(|&i| x[i] = b[i]);
                x
            }
        }
    }

    /// Runs `model` on every row (in parallel; the result does not depend on the threads).
    pub fn evaluate<M>(&self, model: M) -> Evaluations
    where
        M: Fn(&[f64]) -> [f64; N_OUT] + Sync,
    {
        let per_row: Vec<Vec<[f64; N_OUT]>> = (0..self.n)
            .into_par_iter()
            .map(|j| {
                let mut out = vec![model(&self.row(j, Row::A)), model(&self.row(j, Row::B))];
                out.extend((0..self.factors.len()).map(|f| model(&self.row(j, Row::Ab(f)))));
                out
            })
            .collect();
        Evaluations {
            factors: self.factors.len(),
            y: per_row,
        }
    }
}

/// Model outputs of a design: per base row, `[f(A), f(B), f(AB_0), f(AB_1), ...]`.
#[derive(Debug, Clone)]
pub struct Evaluations {
    factors: usize,
    y: Vec<Vec<[f64; N_OUT]>>,
}

/// Indices of one factor for one output, with 95% bootstrap half-widths.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct FactorIndices {
    /// First-order index.
    pub first: f64,
    /// Its 95% confidence half-width.
    pub first_conf: f64,
    /// Total-effect index.
    pub total: f64,
    /// Its 95% confidence half-width.
    pub total_conf: f64,
}

/// Indices for every factor: `per_output[k][f]` for output component `k`, and `combined[f]`
/// for the 3-vector.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SobolIndices {
    /// Per output component, per factor.
    pub per_output: [Vec<FactorIndices>; N_OUT],
    /// Variance-weighted over the components, per factor.
    pub combined: Vec<FactorIndices>,
    /// Output variances (m^2 for a point), per component.
    pub variance: [f64; N_OUT],
}

/// First-order and total indices per factor: `[per output component..., combined]`.
type FirstTotal = (Vec<[f64; N_OUT + 1]>, Vec<[f64; N_OUT + 1]>);

/// Sums for the estimators over a set of base rows: per output, V numerators.
struct Sums {
    var: [f64; N_OUT],
    first: Vec<[f64; N_OUT]>,
    total: Vec<[f64; N_OUT]>,
}

impl Evaluations {
    /// Output `k` of base row `j` for `row`.
    pub fn value(&self, j: usize, row: Row, k: usize) -> f64 {
        let i = match row {
            Row::A => 0,
            Row::B => 1,
            Row::Ab(f) => 2 + f,
        };
        self.y[j][i][k]
    }

    fn centre(&self) -> [f64; N_OUT] {
        let mut m = [0.0; N_OUT];
        let count = (self.y.len() * (self.factors + 2)) as f64;
        for row in &self.y {
            for v in row {
                (0..N_OUT).for_each(|k| m[k] += v[k]);
            }
        }
        m.map(|s| s / count)
    }

    /// Estimator means over the base rows `rows` (with repetition for the bootstrap).
    fn sums(&self, rows: &[usize], c: &[f64; N_OUT]) -> Sums {
        let n = rows.len() as f64;
        let mut mean = [0.0; N_OUT];
        let mut sq = [0.0; N_OUT];
        let mut first = vec![[0.0; N_OUT]; self.factors];
        let mut total = vec![[0.0; N_OUT]; self.factors];
        for &j in rows {
            let y = &self.y[j];
            for k in 0..N_OUT {
                let (ya, yb) = (y[0][k] - c[k], y[1][k] - c[k]);
                mean[k] += ya + yb;
                sq[k] += ya * ya + yb * yb;
                for f in 0..self.factors {
                    let yab = y[2 + f][k] - c[k];
                    first[f][k] += yb * (yab - ya);
                    total[f][k] += (ya - yab) * (ya - yab);
                }
            }
        }
        let var = std::array::from_fn(|k| sq[k] / (2.0 * n) - (mean[k] / (2.0 * n)).powi(2));
        first.iter_mut().flatten().for_each(|v| *v /= n);
        total.iter_mut().flatten().for_each(|v| *v /= 2.0 * n);
        Sums { var, first, total }
    }

    /// First-order and total indices (per output and combined) from base rows `rows`.
    fn indices(&self, rows: &[usize], c: &[f64; N_OUT]) -> FirstTotal {
        let s = self.sums(rows, c);
        let ratio = |num: f64, den: f64| if den > 0.0 { num / den } else { 0.0 };
        let vsum: f64 = s.var.iter().sum();
        let mut first = Vec::with_capacity(self.factors);
        let mut total = Vec::with_capacity(self.factors);
        for f in 0..self.factors {
            let mut fi = [0.0; 4];
            let mut ti = [0.0; 4];
            for k in 0..N_OUT {
                fi[k] = ratio(s.first[f][k], s.var[k]);
                ti[k] = ratio(s.total[f][k], s.var[k]);
            }
            fi[N_OUT] = ratio(s.first[f].iter().sum(), vsum);
            ti[N_OUT] = ratio(s.total[f].iter().sum(), vsum);
            first.push(fi);
            total.push(ti);
        }
        (first, total)
    }

    /// Sobol indices with `bootstrap` resamples (seeded) for the confidence half-widths.
    pub fn analyze(&self, bootstrap: usize, seed: u64) -> SobolIndices {
        let n = self.y.len();
        let c = self.centre();
        let all: Vec<usize> = (0..n).collect();
        let (first, total) = self.indices(&all, &c);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let resamples: Vec<Vec<usize>> = (0..bootstrap)
            .map(|_| (0..n).map(|_| rng.random_range(0..n)).collect())
            .collect();
        let boots: Vec<_> = resamples
            .par_iter()
            .map(|rows| self.indices(rows, &c))
            .collect();
        let conf = |pick: &dyn Fn(&FirstTotal) -> f64| -> f64 {
            if boots.len() < 2 {
                return f64::NAN;
            }
            let m = boots.iter().map(pick).sum::<f64>() / boots.len() as f64;
            let v =
                boots.iter().map(|b| (pick(b) - m).powi(2)).sum::<f64>() / (boots.len() - 1) as f64;
            Z95 * v.sqrt()
        };
        let make = |k: usize| -> Vec<FactorIndices> {
            (0..self.factors)
                .map(|f| FactorIndices {
                    first: first[f][k],
                    first_conf: conf(&|b| b.0[f][k]),
                    total: total[f][k],
                    total_conf: conf(&|b| b.1[f][k]),
                })
                .collect()
        };
        let s = self.sums(&all, &c);
        SobolIndices {
            per_output: std::array::from_fn(make),
            combined: make(N_OUT),
            variance: s.var,
        }
    }
}
