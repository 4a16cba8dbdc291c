//! Sigma statistics of the day's points for the morning report: median and 95th percentile of
//! `sigma_z` and `thu95` per pass and per tile, from histograms filled as the points are
//! written (per pass by the units, per tile by the merge: no file is read again for them).
//!
//! The bins are those of the f32 values' own bits (exponent and the top 7 mantissa bits: 128
//! bins an octave, each at most 0.78% wide), so filling one is a shift, not a logarithm; a
//! quantile is given as its bin's middle, within 0.4% of the exact one.

use crate::pipeline::schema::OutputSchema;
use serde::{Deserialize, Serialize};

/// Bins an octave: the f32 mantissa's top 7 bits.
const MANTISSA_BITS: u32 = 7;
/// The f32 bits below the bin index.
const SHIFT: u32 = 23 - MANTISSA_BITS;
/// Biased f32 exponent of the lowest bin's lower edge: 2^-17 m (7.6 micrometres); values below
/// (and zero, negative or NaN ones) count in the lowest bin.
const LOW_EXPONENT: u32 = 127 - 17;
/// Octaves covered: 2^-17 m to 2^7 m (128 m); values above count in the highest bin.
const OCTAVES: u32 = 24;
/// Bins.
const BINS: usize = (OCTAVES << MANTISSA_BITS) as usize;
/// Bytes of point format 6 before the extra bytes.
const CORE_BYTES: usize = 30;

/// Counts of values (m) in the bins of their f32 bits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<(usize, u64)>", into = "Vec<(usize, u64)>")]
struct Histogram {
    counts: Vec<u64>,
    n: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram {
            counts: vec![0; BINS],
            n: 0,
        }
    }
}

/// The bin of `v`.
fn bin_of(v: f32) -> usize {
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    let index = (v.to_bits() >> SHIFT).saturating_sub(LOW_EXPONENT << MANTISSA_BITS);
    (index as usize).min(BINS - 1)
}

impl Histogram {
    fn add(&mut self, v: f32) {
        self.counts[bin_of(v)] += 1;
        self.n += 1;
    }

    fn merge(&mut self, other: &Histogram) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
        self.n += other.n;
    }

    /// The `q` quantile (0..1) as its bin's middle; None when empty.
    fn quantile(&self, q: f64) -> Option<f64> {
        let rank = (q * self.n as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        let bin = self.counts.iter().position(|&c| {
            seen += c;
            seen >= rank
        })?;
        let lower = (bin as u32 + (LOW_EXPONENT << MANTISSA_BITS)) << SHIFT;
        // The middle of a bin: its lower edge with the next mantissa bit set.
        Some(f64::from(f32::from_bits(lower | 1 << (SHIFT - 1))))
    }
}

/// Sparse form (bin, count) of the non-empty bins: the journal's.
impl From<Histogram> for Vec<(usize, u64)> {
    fn from(h: Histogram) -> Self {
        let bins = h.counts.into_iter().enumerate();
        bins.filter(|&(_, c)| c > 0).collect()
    }
}

impl TryFrom<Vec<(usize, u64)>> for Histogram {
    type Error = String;

    fn try_from(bins: Vec<(usize, u64)>) -> Result<Self, String> {
        let mut h = Histogram::default();
        for (bin, count) in bins {
            let slot = h
                .counts
                .get_mut(bin)
                .ok_or_else(|| format!("histogram bin {bin} beyond the {BINS} bins"))?;
            *slot += count;
            h.n += count;
        }
        Ok(h)
    }
}

/// Where `sigma_z` and `thu95` (f32) lie in a record of the day's schema.
#[derive(Debug, Clone, Copy)]
pub struct SigmaOffsets {
    sigma_z: usize,
    thu95: Option<usize>,
    /// Metres per file unit of the sigmas (1 but for a foot CRS): the statistics are in m.
    metres_per_unit: f32,
}

impl SigmaOffsets {
    /// None without `[uncertainty]` (the points carry no sigma).
    pub fn of(schema: &OutputSchema) -> Option<Self> {
        let u = schema.uncertainty?;
        let at = |slot: usize| CORE_BYTES + schema.extra_byte_offset(slot);
        Some(SigmaOffsets {
            sigma_z: at(u.sigma_x + 2),
            thu95: u.thu95.map(at),
            metres_per_unit: (1.0 / schema.units_per_m) as f32,
        })
    }
}

/// The sigma histograms of one scope (a work unit, a pass or a tile).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SigmaHistograms {
    sigma_z: Histogram,
    thu95: Histogram,
}

impl SigmaHistograms {
    /// Adds every record of `records` (records of `record_len` bytes).
    pub fn add_records(&mut self, records: &[u8], record_len: usize, at: SigmaOffsets) {
        let f32_at = |r: &[u8], i: usize| {
            f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]) * at.metres_per_unit
        };
        for r in records.chunks_exact(record_len) {
            self.sigma_z.add(f32_at(r, at.sigma_z));
            if let Some(t) = at.thu95 {
                self.thu95.add(f32_at(r, t));
            }
        }
    }

    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: &SigmaHistograms) {
        self.sigma_z.merge(&other.sigma_z);
        self.thu95.merge(&other.thu95);
    }

    /// The statistics of `scope` (e.g. `pass p01`, `tile_691650_5334700`).
    pub fn stats(&self, scope: &str) -> SigmaStats {
        SigmaStats {
            scope: scope.to_string(),
            points: self.sigma_z.n,
            sigma_z_median_m: self.sigma_z.quantile(0.5),
            sigma_z_p95_m: self.sigma_z.quantile(0.95),
            thu95_median_m: self.thu95.quantile(0.5),
            thu95_p95_m: self.thu95.quantile(0.95),
        }
    }
}

/// Median and 95th percentile of `sigma_z` and `thu95` (m) of a pass or a tile, each within
/// 0.4% (half the histogram's widest bin); None where the points carry no such dimension.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SigmaStats {
    /// `pass <name>` or the tile's file stem.
    pub scope: String,
    /// Points counted.
    pub points: u64,
    /// Median of `sigma_z` (m).
    pub sigma_z_median_m: Option<f64>,
    /// 95th percentile of `sigma_z` (m).
    pub sigma_z_p95_m: Option<f64>,
    /// Median of `thu95` (m).
    pub thu95_median_m: Option<f64>,
    /// 95th percentile of `thu95` (m).
    pub thu95_p95_m: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_within_half_a_bin_of_the_exact_ones() {
        let mut h = Histogram::default();
        let values: Vec<f32> = (1..=1000).map(|i| i as f32 * 1e-4).collect();
        values.iter().for_each(|&v| h.add(v));
        // Exact: the 500th and 950th values; a bin is at most 1/128 of its octave's start wide.
        for (q, exact) in [(0.5, 0.05), (0.95, 0.095)] {
            let got = h.quantile(q).unwrap();
            assert!((got / exact - 1.0).abs() < 0.004, "q {q}: {got} vs {exact}");
        }
        assert_eq!(Histogram::default().quantile(0.5), None);
    }

    #[test]
    fn bins_are_ordered_and_out_of_range_values_go_to_the_ends() {
        assert_eq!(bin_of(0.0), 0);
        assert_eq!(bin_of(-1.0), 0);
        assert_eq!(bin_of(f32::NAN), 0);
        assert_eq!(bin_of(1e-9), 0);
        assert_eq!(bin_of(1e3), BINS - 1);
        assert_eq!(bin_of(f32::INFINITY), BINS - 1);
        // 2^-17 m starts the lowest bin, 1 m starts octave 17.
        assert_eq!(bin_of(2f32.powi(-17)), 0);
        assert_eq!(bin_of(1.0), 17 << MANTISSA_BITS);
        let values: Vec<f32> = (0..2000).map(|i| 1e-5 * 1.01f32.powi(i)).collect();
        let bins: Vec<usize> = values.iter().map(|&v| bin_of(v)).collect();
        assert!(bins.windows(2).all(|w| w[0] <= w[1]));
        // Each value lies in its bin: within half a bin of the bin's middle.
        for &v in &values[..1400] {
            let mut h = Histogram::default();
            h.add(v);
            let middle = h.quantile(0.5).unwrap();
            assert!(
                (middle / f64::from(v) - 1.0).abs() < 0.0079,
                "{v}: {middle}"
            );
        }
    }

    #[test]
    fn the_sparse_form_round_trips_and_merges_add() {
        let mut a = Histogram::default();
        [0.01f32, 0.01, 0.5, 3.0].iter().for_each(|&v| a.add(v));
        let json = serde_json::to_string(&a).unwrap();
        let back: Histogram = serde_json::from_str(&json).unwrap();
        assert_eq!(back, a);
        let mut sum = back.clone();
        sum.merge(&a);
        assert_eq!(sum.n, 8);
        assert_eq!(sum.quantile(0.5), a.quantile(0.5));
        let bad = format!("[[{BINS}, 1]]");
        assert!(serde_json::from_str::<Histogram>(&bad).is_err());
    }
}
