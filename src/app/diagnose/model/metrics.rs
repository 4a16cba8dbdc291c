//! Gap metrics (docs/conventions.md §8 "G") and the tools of the tests: chi-square and normal
//! tail probabilities (with logarithms for tails below 1e-300) and Holm's multiple-testing
//! control.

use super::fit::{count_on, total_gram};
use super::{Observation, ObservationSet, Theta};
use crate::{Error, Result};

/// The sim-to-real gap on a set of references.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gap {
    /// `r^T C^-1 r / n` with the full block covariance (navigation errors shared per visit);
    /// 1 when the model holds.
    pub chi2_per_dof: f64,
    /// Root mean square of the residuals (m).
    pub rms_m: f64,
    /// Mean residual (m).
    pub mean_m: f64,
    /// Share of returns with `|r| < 1.96 sigma`, sigma the per-return marginal
    /// `sqrt(var_white + g P g^T)`; 0.95 when the model holds.
    pub coverage_95: f64,
    /// Number of returns.
    pub n: usize,
}

/// The gap on `refs`, residuals corrected by `theta` when given.
pub fn gap(set: &ObservationSet, refs: &[usize], theta: Option<Theta>) -> Result<Gap> {
    match theta {
        Some(t) => gap_corrected(set, refs, &|o| t.corrected(o)),
        None => gap_corrected(set, refs, &|o| o.residual_m),
    }
}

/// The per-return marginal variance `var_white + g P g^T` (m^2).
pub(crate) fn marginal_var_m2(set: &ObservationSet) -> impl Fn(&Observation) -> f64 + Sync + '_ {
    let independent = set.independent_var_m2();
    move |o| {
        let p = &set.visits[o.visit].nav_cov;
        let g = &o.nav_gradient;
        let gpg: f64 = (0..6)
            .map(|i| (0..6).map(|j| g[i] * p[i][j] * g[j]).sum::<f64>())
            .sum();
        independent(o) + gpg.max(0.0)
    }
}

/// The gap on `refs` of the residuals `corrected(o)` (validated set).
pub(crate) fn gap_corrected(
    set: &ObservationSet,
    refs: &[usize],
    corrected: &(dyn Fn(&Observation) -> f64 + Sync),
) -> Result<Gap> {
    let n = count_on(set, refs);
    if n == 0 {
        return Err(Error::Numerical {
            what: "gap metrics".to_string(),
            problem: "no returns on the given references".to_string(),
        });
    }
    let chi2 = total_gram(set, refs, 1, &|o, out| out.push((0, corrected(o))))[(0, 0)];
    let mut selected = vec![false; set.reference_ids.len()];
    for &r in refs {
        selected[r] = true;
    }
    let (mut sum, mut sum2, mut inside) = (0.0, 0.0, 0usize);
    let var_m2 = marginal_var_m2(set);
    for o in set.observations.iter().filter(|o| selected[o.reference]) {
        let r = corrected(o);
        sum += r;
        sum2 += r * r;
        if r * r < 1.96 * 1.96 * var_m2(o) {
            inside += 1;
        }
    }
    let nf = n as f64;
    Ok(Gap {
        chi2_per_dof: chi2 / nf,
        rms_m: (sum2 / nf).sqrt(),
        mean_m: sum / nf,
        coverage_95: inside as f64 / nf,
        n,
    })
}

/// `ln Gamma(x)`, x > 0 (Lanczos, g = 7, 9 terms: relative error below 1e-14).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let a = C[0] + (1..9).map(|i| C[i] / (x + i as f64)).sum::<f64>();
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// `ln Q(a, x)`: logarithm of the regularised upper incomplete gamma function
/// (series for `x < a + 1`, Lentz continued fraction otherwise; relative accuracy 1e-14).
fn ln_gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let ln_prefactor = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        let p = (ln_prefactor + sum.ln()).exp();
        (-p).ln_1p()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        ln_prefactor + h.ln()
    }
}

/// `ln P(chi2_k > x)`; NaN for a NaN `x` (never a pass: `f64::max` would make it 0 and p 1).
pub fn ln_chi2_sf(x: f64, k: usize) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if k == 0 {
        return 0.0;
    }
    ln_gamma_q(0.5 * k as f64, 0.5 * x.max(0.0))
}

/// `chi2` when finite, else an [`Error::Numerical`] naming the test `what`: a goodness-of-fit
/// test passes on a large p-value, so a non-finite statistic must stop the diagnosis, not pass.
pub fn finite_chi2(chi2: f64, what: impl FnOnce() -> String) -> Result<f64> {
    if chi2.is_finite() {
        Ok(chi2)
    } else {
        Err(Error::Numerical {
            what: what(),
            problem: format!("the chi-square is {chi2}"),
        })
    }
}

/// `P(chi2_k > x)`; NaN for a NaN `x`.
pub fn chi2_sf(x: f64, k: usize) -> f64 {
    ln_chi2_sf(x, k).exp()
}

/// `P(X > x)` for `X = c chi2_nu` with mean `n` and variance `2 n + extra_var` (Satterthwaite's
/// scaled chi-square): the held-out statistic `r^T C^-1 r` of `n` returns under a navigation
/// model learned with a sampling error that adds `extra_var` to its variance
/// (`nuisance::chi2_variance`); [`chi2_sf`] when `extra_var` is 0. A non-finite `x` or
/// `extra_var` is an error naming the test `what` ([`finite_chi2`]).
pub fn chi2_sf_spread(x: f64, n: usize, extra_var: f64, what: impl Fn() -> String) -> Result<f64> {
    let x = finite_chi2(x, &what)?;
    let extra_var = finite_chi2(extra_var, || format!("{} (its added variance)", what()))?;
    if n == 0 {
        return Ok(1.0);
    }
    let c = 1.0 + extra_var.max(0.0) / (2.0 * n as f64);
    Ok(ln_gamma_q(0.5 * n as f64 / c, 0.5 * (x / c).max(0.0)).exp())
}

/// `P(Z > z)` for a standard normal `Z`.
pub fn normal_sf(z: f64) -> f64 {
    let tail = 0.5 * ln_gamma_q(0.5, 0.5 * z * z).exp();
    if z >= 0.0 {
        tail
    } else {
        1.0 - tail
    }
}

/// Holm's step-down procedure: which of `p` are rejected at family-wise error rate `alpha`.
pub fn holm(p: &[f64], alpha: f64) -> Vec<bool> {
    holm_adjusted(p).into_iter().map(|q| q <= alpha).collect()
}

/// Holm-adjusted p-values: `max_{j <= i} min(1, (m - j) p_(j))` over the sorted `p`; a
/// hypothesis is rejected at family-wise level `alpha` when its adjusted p-value is <= alpha.
/// A NaN p-value counts as 1 (never rejected; `f64::max` would give it its predecessor's).
pub fn holm_adjusted(p: &[f64]) -> Vec<f64> {
    let p: Vec<f64> = p
        .iter()
        .map(|&x| if x.is_nan() { 1.0 } else { x })
        .collect();
    let mut order: Vec<usize> = (0..p.len()).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut adjusted = vec![1.0; p.len()];
    let mut running: f64 = 0.0;
    for (rank, &i) in order.iter().enumerate() {
        running = running.max(((p.len() - rank) as f64 * p[i]).min(1.0));
        adjusted[i] = running;
    }
    adjusted
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::diagnose::model::synthetic::{draw, Scenario};

    #[test]
    fn holm_steps_down() {
        assert_eq!(holm(&[0.001, 0.04, 0.03], 0.05), vec![true, false, false]);
        assert_eq!(holm(&[0.001, 0.04, 0.012], 0.05), vec![true, true, true]);
        let q = holm_adjusted(&[0.01, 0.04, 0.03]);
        assert!(
            (q[0] - 0.03).abs() < 1e-15
                && (q[1] - 0.06).abs() < 1e-15
                && (q[2] - 0.06).abs() < 1e-15
        );
        assert_eq!(holm(&[0.03, 0.04], 0.05), vec![false, false]);
        // A NaN is never rejected, and does not inherit a smaller p-value's adjustment.
        assert_eq!(holm_adjusted(&[f64::NAN, 0.001]), vec![1.0, 0.002]);
        assert_eq!(holm(&[0.001, f64::NAN], 0.05), vec![true, false]);
    }

    #[test]
    fn a_non_finite_chi_square_never_passes() {
        assert!(ln_chi2_sf(f64::NAN, 3).is_nan() && chi2_sf(f64::NAN, 3).is_nan());
        for (x, extra) in [(f64::NAN, 0.0), (f64::INFINITY, 0.0), (10.0, f64::NAN)] {
            let err = chi2_sf_spread(x, 10, extra, || "held-out gap".to_string()).unwrap_err();
            assert!(err.to_string().starts_with("held-out gap"), "{err}");
        }
        assert_eq!(chi2_sf_spread(0.0, 0, 0.0, String::new).unwrap(), 1.0);
    }

    #[test]
    fn tail_probabilities_match_tables() {
        // Reference values: scipy.stats (norm.sf, chi2.sf).
        assert!((normal_sf(1.96) - 0.024_997_895).abs() < 1e-8);
        assert!((normal_sf(-1.0) - 0.841_344_746).abs() < 1e-8);
        assert!((chi2_sf(3.841_458_82, 1) - 0.05).abs() < 1e-9);
        assert!((chi2_sf(23.209_251, 10) - 0.01).abs() < 1e-8);
        assert!((chi2_sf(1100.0, 1000) - 0.014_614_408_126).abs() < 1e-9);
        // The spread form: chi2_n itself without extra variance; with 2n more, X = 2 chi2_{n/2}.
        let spread = |x, n, v| chi2_sf_spread(x, n, v, String::new).unwrap();
        assert_eq!(spread(1100.0, 1000, 0.0), chi2_sf(1100.0, 1000));
        let doubled = spread(2.0 * 550.0, 1000, 2000.0);
        assert!((doubled - chi2_sf(550.0, 500)).abs() < 1e-12, "{doubled}");
        // Far tail: ln P(chi2_1 > 2000) = ln erfc(sqrt(1000)) ~ -1000 - ln(sqrt(1000 pi)).
        let expected = -1000.0 - (1000.0 * std::f64::consts::PI).sqrt().ln();
        assert!((ln_chi2_sf(2000.0, 1) - expected).abs() < 1e-3);
    }

    #[test]
    fn null_gap_is_consistent_with_the_model() {
        let set = draw(&Scenario::default(), 11);
        let g = gap(&set, &set.observed_references(), None).unwrap();
        // n = 2880 returns: chi2/dof has sd sqrt(2/n) = 0.026; coverage sd ~ 0.004 per return
        // but visits correlate returns, so allow 4 sd of each.
        assert!((g.chi2_per_dof - 1.0).abs() < 0.11, "{g:?}");
        assert!((g.coverage_95 - 0.95).abs() < 0.03, "{g:?}");
        assert_eq!(g.n, set.observations.len());
    }
}
