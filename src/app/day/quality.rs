//! Sigma statistics of the day's points for the morning report: median and 95th percentile of
//! `sigma_z` and `thu95` per pass and per tile, from log-spaced histograms filled while the
//! units are merged (the files are not read again).

use crate::pipeline::schema::OutputSchema;
use serde::Serialize;

/// Histogram bins per decade: a quantile is known to 1/100 of a decade (2.3%).
const BINS_PER_DECADE: f64 = 100.0;
/// log10 of the lowest bin's lower edge (m); values below count in the lowest bin.
const LOG10_LOW: f64 = -5.0;
/// Bins: 1e-5 m to 1e2 m; values above count in the highest bin.
const BINS: usize = 700;
/// Bytes of point format 6 before the extra bytes.
const CORE_BYTES: usize = 30;

/// Counts of values (m) in log-spaced bins.
#[derive(Debug, Clone)]
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

impl Histogram {
    fn add(&mut self, v: f64) {
        let bin = ((v.log10() - LOG10_LOW) * BINS_PER_DECADE).floor();
        // NaN and values below the range go to the lowest bin, above it to the highest.
        let bin = if bin.is_nan() {
            0.0
        } else {
            bin.clamp(0.0, (BINS - 1) as f64)
        };
        self.counts[bin as usize] += 1;
        self.n += 1;
    }

    /// The `q` quantile (0..1) as its bin's geometric centre; None when empty.
    fn quantile(&self, q: f64) -> Option<f64> {
        let rank = (q * self.n as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        let bin = self.counts.iter().position(|&c| {
            seen += c;
            seen >= rank
        })?;
        Some(10f64.powf(LOG10_LOW + (bin as f64 + 0.5) / BINS_PER_DECADE))
    }
}

/// Where `sigma_z` and `thu95` (f32) lie in a record of the day's schema.
#[derive(Debug, Clone, Copy)]
pub struct SigmaOffsets {
    sigma_z: usize,
    thu95: Option<usize>,
}

impl SigmaOffsets {
    /// None without `[uncertainty]` (the points carry no sigma).
    pub fn of(schema: &OutputSchema) -> Option<Self> {
        let u = schema.uncertainty?;
        let at = |slot: usize| CORE_BYTES + schema.extra_byte_offset(slot);
        Some(SigmaOffsets {
            sigma_z: at(u.sigma_x + 2),
            thu95: u.thu95.map(at),
        })
    }
}

/// The sigma histograms of one scope (a pass or a tile).
#[derive(Debug, Clone, Default)]
pub struct SigmaHistograms {
    sigma_z: Histogram,
    thu95: Histogram,
}

impl SigmaHistograms {
    /// Adds every record of `records` (records of `record_len` bytes).
    pub fn add_records(&mut self, records: &[u8], record_len: usize, at: SigmaOffsets) {
        let f32_at = |r: &[u8], i: usize| f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
        for r in records.chunks_exact(record_len) {
            self.sigma_z.add(f64::from(f32_at(r, at.sigma_z)));
            if let Some(t) = at.thu95 {
                self.thu95.add(f64::from(f32_at(r, t)));
            }
        }
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

/// Median and 95th percentile of `sigma_z` and `thu95` (m) of a pass or a tile, each to 2.3%
/// (the histogram's bin width); None where the points carry no such dimension.
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
    fn quantiles_within_a_bin_of_the_exact_ones() {
        let mut h = Histogram::default();
        let values: Vec<f64> = (1..=1000).map(|i| i as f64 * 1e-4).collect();
        values.iter().for_each(|&v| h.add(v));
        // Exact: the 500th and 950th values; a bin is 10^(1/100) - 1 = 2.33% wide.
        for (q, exact) in [(0.5, 0.05), (0.95, 0.095)] {
            let got = h.quantile(q).unwrap();
            assert!((got / exact - 1.0).abs() < 0.024, "q {q}: {got} vs {exact}");
        }
        assert_eq!(Histogram::default().quantile(0.5), None);
    }
}
