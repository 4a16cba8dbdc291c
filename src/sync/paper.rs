//! The paper's method (004, eq. 7-8): every sighting gives one observation
//! `t_c = t0 + T (n_i + f(beta_i))`, `t_c` the plane-crossing time from the trajectory, `n_i`
//! the sighting profile and `beta_i` its mirror angle (the helix correction); weighted least
//! squares over all sightings, with leave-one-out outlier rejection.

use nalgebra::{Matrix2, Vector2};

/// One observation of the regression.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Obs {
    /// `n_i + f(beta_i)` (profiles).
    pub nu: f64,
    /// Crossing time minus the reference time (s).
    pub y_s: f64,
    /// 1-sigma of the observation (s).
    pub sigma_s: f64,
}

/// A weighted line fit `y = a + T nu`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineFit {
    /// (a, T).
    pub x: Vector2<f64>,
    /// Covariance of (a, T).
    pub cov: Matrix2<f64>,
    /// Sum of squared normalised residuals.
    pub chi2: f64,
}

impl LineFit {
    /// Normalised residual of `o`.
    pub fn z(&self, o: &Obs) -> f64 {
        (o.y_s - self.x[0] - self.x[1] * o.nu) / o.sigma_s
    }
}

/// Weighted least squares of `obs`; None when the normal matrix is singular.
pub(crate) fn fit(obs: &[&Obs]) -> Option<LineFit> {
    let mut n = Matrix2::zeros();
    let mut b = Vector2::zeros();
    for o in obs {
        let w = 1.0 / (o.sigma_s * o.sigma_s);
        let a = Vector2::new(1.0, o.nu);
        n += a * a.transpose() * w;
        b += a * (o.y_s * w);
    }
    let scale = Vector2::new(n[(0, 0)].sqrt(), n[(1, 1)].sqrt());
    let s = Matrix2::from_diagonal(&scale.map(|v| 1.0 / v));
    let ns = s * n * s;
    if ns.determinant() < 1e-12 {
        return None;
    }
    let cov = s * ns.try_inverse()? * s;
    let x = cov * b;
    let mut f = LineFit { x, cov, chi2: 0.0 };
    f.chi2 = obs.iter().map(|o| f.z(o).powi(2)).sum();
    Some(f)
}

/// Fits `obs[active]`, removing one observation at a time while the largest normalised
/// residual exceeds `k` and at least 3 remain (the removal that leaves the smallest chi^2).
/// Returns the fit and the indices judged outliers.
pub(crate) fn robust_fit(obs: &[Obs], active: &[usize], k: f64) -> Option<(LineFit, Vec<usize>)> {
    let mut act: Vec<usize> = active.to_vec();
    let mut outliers = Vec::new();
    loop {
        let sel: Vec<&Obs> = act.iter().map(|&i| &obs[i]).collect();
        let f = fit(&sel)?;
        let worst = sel.iter().map(|o| f.z(o).abs()).fold(0.0, f64::max);
        if worst <= k || act.len() <= 3 {
            return Some((f, outliers));
        }
        let best = (0..act.len())
            .filter_map(|j| {
                let rest: Vec<&Obs> = act
                    .iter()
                    .enumerate()
                    .filter(|(m, _)| *m != j)
                    .map(|(_, &i)| &obs[i])
                    .collect();
                fit(&rest).map(|g| (j, g.chi2))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        outliers.push(act.remove(best.0));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(t0: f64, period: f64, nus: &[f64]) -> Vec<Obs> {
        nus.iter()
            .map(|&nu| Obs {
                nu,
                y_s: t0 + period * nu,
                sigma_s: 0.01,
            })
            .collect()
    }

    #[test]
    fn exact_line_is_recovered_with_the_textbook_covariance() {
        let obs = line(0.3, 0.0303, &[100.0, 120.0, 9000.0, 9030.0]);
        let f = fit(&obs.iter().collect::<Vec<_>>()).unwrap();
        assert!((f.x[0] - 0.3).abs() < 1e-12 && (f.x[1] - 0.0303).abs() < 1e-15);
        // var(T) = sigma^2 / sum (nu - mean)^2 for equal weights.
        let mean = (100.0 + 120.0 + 9000.0 + 9030.0) / 4.0;
        let sxx: f64 = [100.0, 120.0, 9000.0, 9030.0]
            .iter()
            .map(|n: &f64| (n - mean).powi(2))
            .sum();
        assert!((f.cov[(1, 1)] / (1e-4 / sxx) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn one_gross_outlier_is_removed_and_one_place_is_singular() {
        let mut obs = line(0.3, 0.0303, &[100.0, 120.0, 5000.0, 9000.0, 9030.0]);
        obs[2].y_s += 0.33;
        let all: Vec<usize> = (0..obs.len()).collect();
        let (f, out) = robust_fit(&obs, &all, 5.0).unwrap();
        assert_eq!(out, vec![2]);
        assert!((f.x[1] - 0.0303).abs() < 1e-15);
        let same = line(0.3, 0.0303, &[100.0, 100.0, 100.0]);
        assert!(fit(&same.iter().collect::<Vec<_>>()).is_none());
    }
}
