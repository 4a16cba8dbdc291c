//! What the survey could have found (docs/diagnosis.md, "Power"): for every catalogue effect,
//! the smallest size the selection would name with 90% probability, given the references, the
//! navigation error model and the test level.
//!
//! Naming an effect alone takes two tests (docs/diagnosis.md, "Selection and verdict"): its
//! likelihood ratio on the fit references, significant under Holm's correction over the `m`
//! candidates of the first step (the first Holm step is the strictest: level `alpha / m`,
//! two-sided), and the held-out score along its correction, one-sided at `alpha`. For an effect
//! of size `delta` whose fit alone has sigma `s_f` on the fit references and `s_h` on the
//! held-out ones, the two statistics are about `N(delta / s_f, 1)` and `N(delta / s_h, 1)` and
//! nearly independent (different references), so the probability of naming it is
//! `Phi(delta / s_f - z(alpha / 2m)) Phi(delta / s_h - z(alpha))` (the far tail of the
//! two-sided test neglected); `detectable` is the `delta` where that reaches 0.9. An effect in
//! an inseparable group is named with its group, by the group's fit: the same formula with the
//! preferred member's sigmas, in the member's own unit, applies to the member alone, so each
//! name gets its own fit here.

use crate::app::diagnose::model::fit::Normals;
use crate::app::diagnose::model::metrics::normal_sf;
use crate::app::diagnose::model::{Effect, N_EFFECTS};

/// The probability of naming an effect that `detectable` is defined by.
pub const POWER: f64 = 0.9;

/// Upper quantile `z` with `P(Z > z) = p` of the unit normal (bisection on [`normal_sf`]).
fn normal_isf(p: f64) -> f64 {
    let (mut lo, mut hi) = (-40.0, 40.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if normal_sf(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Probability that an effect `delta / s_f` (fit) and `delta / s_h` (held out) sigmas large is
/// named, at quantiles `z_fit` and `z_held`.
fn naming_probability(ratio_fit: f64, ratio_held: f64, z_fit: f64, z_held: f64) -> f64 {
    (1.0 - normal_sf(ratio_fit - z_fit)) * (1.0 - normal_sf(ratio_held - z_held))
}

/// The smallest `|delta|` of every catalogue effect named with probability [`POWER`], in the
/// unit of its name; `None` for an effect without signature on either half (it cannot be found
/// at any size). `candidates` is the number of first-step candidates Holm's correction runs
/// over.
pub fn detectable(
    fit: &Normals,
    held: &Normals,
    alpha: f64,
    candidates: usize,
) -> Vec<(Effect, Option<f64>)> {
    let z_fit = normal_isf(alpha / (2.0 * candidates.max(1) as f64));
    let z_held = normal_isf(alpha);
    Effect::ALL
        .iter()
        .enumerate()
        .map(|(j, &e)| {
            debug_assert!(j < N_EFFECTS);
            // Sigma of the effect fitted alone: 1 / sqrt(S^T C^-1 S).
            let info = (fit.m[(j, j)], held.m[(j, j)]);
            if !(info.0 > 0.0 && info.1 > 0.0) {
                return (e, None);
            }
            let (s_f, s_h) = (1.0 / info.0.sqrt(), 1.0 / info.1.sqrt());
            let p = |d: f64| naming_probability(d / s_f, d / s_h, z_fit, z_held);
            let (mut lo, mut hi) = (0.0, s_f.max(s_h));
            while p(hi) < POWER {
                hi *= 2.0;
            }
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if p(mid) < POWER {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            (e, Some(hi))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        // z(0.05) = 1.6449, z(0.005) = 2.5758, z(0.1) = 1.2816 (normal tables).
        for (p, z) in [(0.05, 1.644_854), (0.005, 2.575_829), (0.1, 1.281_552)] {
            assert!((normal_isf(p) - z).abs() < 1e-5, "{p}: {}", normal_isf(p));
        }
    }

    /// With equal halves the detectable size solves `Phi(d - z1) Phi(d - z2) = 0.9`; on a
    /// single test it would be `z + 1.2816` sigmas: two tests need more.
    #[test]
    fn detectable_sizes_need_both_tests() {
        let z1 = normal_isf(0.01 / (2.0 * 120.0));
        let z2 = normal_isf(0.01);
        let d = {
            let (mut lo, mut hi) = (0.0, 20.0);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if naming_probability(mid, mid, z1, z2) < 0.9 {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            hi
        };
        assert!(d > z1 + 1.2816 && d < z1 + 1.2816 + 1.0, "{d} sigmas");
        let p = naming_probability(d, d, z1, z2);
        assert!((p - 0.9).abs() < 1e-9, "{p}");
    }
}
