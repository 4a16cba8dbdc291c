//! Axis ranges, round tick values with their labels, and histogram binning.

use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;

/// Equal-width bins over the finite values' range (+-0.5 around a single value): bin edges
/// and counts.
pub(super) fn bin(values: &[f64], bins: usize) -> (Vec<f64>, Vec<u64>) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if finite.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5, hi + 0.5)
    };
    let width = (hi - lo) / bins as f64;
    let edges = (0..=bins).map(|i| lo + width * i as f64).collect();
    let mut counts = vec![0u64; bins];
    for v in finite {
        counts[(((v - lo) / width) as usize).min(bins - 1)] += 1;
    }
    (edges, counts)
}

/// The axis range: fixed, or the data extent padded 5% each side (lower end kept at 0 for
/// non-negative y so histogram bars start on the axis). Errors name what is wrong.
pub(super) fn axis_range(
    fixed: Option<(f64, f64)>,
    extent: Option<(f64, f64)>,
    is_y: bool,
) -> Result<(f64, f64), String> {
    if let Some((lo, hi)) = fixed {
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(format!("axis range {lo}..{hi} is empty"));
        }
        return Ok((lo, hi));
    }
    let (lo, hi) = extent.ok_or("no finite data to plot")?;
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        (lo - 0.5 * lo.abs().max(1.0), hi + 0.5 * hi.abs().max(1.0))
    };
    let pad = 0.05 * (hi - lo);
    let lo_padded = if is_y && lo == 0.0 { 0.0 } else { lo - pad };
    Ok((lo_padded, hi + pad))
}

/// The tick values plotters draws along an axis (multiples of a 1-2-5 step, at most
/// `max_ticks`), labelled with the decimals the step needs (scientific notation for very large
/// values or very small steps).
pub(super) struct Ticks {
    values: Vec<f64>,
    step: f64,
    decimals: usize,
    scientific: bool,
}

impl Ticks {
    pub(super) fn new((lo, hi): (f64, f64), max_ticks: usize) -> Self {
        let values = RangedCoordf64::from(lo..hi).key_points(max_ticks);
        let step = match values.as_slice() {
            [a, b, ..] => b - a,
            _ => hi - lo,
        };
        Ticks {
            decimals: (-(step.log10() + 1e-9).floor()).clamp(0.0, 12.0) as usize,
            scientific: lo.abs().max(hi.abs()) >= 1e7 || step < 1e-5,
            values,
            step,
        }
    }

    /// The label of tick value `v`; a rounding residue of zero is labelled as zero.
    pub(super) fn label(&self, v: f64) -> String {
        let v = if v.abs() < 1e-9 * self.step { 0.0 } else { v };
        if self.scientific {
            format!("{v:.3e}")
        } else {
            format!("{v:.*}", self.decimals)
        }
    }

    pub(super) fn labels(&self) -> Vec<String> {
        self.values.iter().map(|&v| self.label(v)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        let t = Ticks::new((0.0, 10.0), 8);
        assert_eq!(t.values, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(t.labels()[1], "2");
        let t = Ticks::new((-0.013, 0.021), 8);
        assert!(t.values.iter().all(|v| (-0.013..=0.021).contains(v)));
        assert_eq!(t.labels()[2], "0.000"); // a rounding residue of 1.7e-18
        assert_eq!(t.label(-1e-18), "0.000", "no negative zero");
    }

    #[test]
    fn histogram_counts_every_finite_value_once() {
        let (edges, counts) = bin(&[0.0, 0.5, 1.0, 2.0, f64::NAN, 4.0], 4);
        assert_eq!(edges, [0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(counts, [2, 1, 1, 1]); // 4.0 falls in the last (closed) bin
    }
}
