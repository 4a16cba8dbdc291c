//! Hardware (PPS) profile time tags (conventions §2: `time_s` holds each profile's start `t_n`): the
//! clock line `t_n = t0 + T n` fitted to every profile, and the comparison with the software
//! synchronisation (paper 004, figure 6: hardware minus software profile times).

use crate::io::profiles::ProfileFile;
use nalgebra::{Matrix2, Vector2};
use serde::Serialize;

/// Hardware clock fit and its comparison with the object-space result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HardwareComparison {
    /// Profiles with a finite tag used.
    pub profiles: u64,
    /// t0 of the line through the tags (s).
    pub t0_s: f64,
    /// Period of the line through the tags (s).
    pub period_s: f64,
    /// RMS of the tags about the line (s): PPS jitter plus clock non-linearity.
    pub rms_residual_s: f64,
    /// Largest |tag - software time| over the profiles (s).
    pub max_abs_difference_s: f64,
    /// Largest |tag - software time| / software sigma at that profile.
    pub max_normalised_difference: f64,
    /// (profile, tag - software time (s), software sigma there (s)) on a thinned grid, for
    /// the figure.
    pub differences: Vec<(u32, f64, f64)>,
}

/// Per-profile tags `(n, t_n)`: the first return's `time_s` of every profile.
pub(crate) fn profile_tags(file: &ProfileFile) -> Vec<(u32, f64)> {
    let mut out: Vec<(u32, f64)> = Vec::new();
    for i in 0..file.len() {
        let r = file.get(i);
        if out.last().is_none_or(|l| l.0 != r.profile) && r.time_s.is_finite() {
            out.push((r.profile, r.time_s));
        }
    }
    out
}

/// Fits the tags and compares them with the software clock `(t0_sw, T_sw)` of covariance
/// `cov_sw`; `None` with fewer than 2 tags.
pub(crate) fn compare(
    tags: &[(u32, f64)],
    t0_sw: f64,
    period_sw: f64,
    cov_sw: &Matrix2<f64>,
) -> Option<HardwareComparison> {
    if tags.len() < 2 {
        return None;
    }
    let t_ref = tags[0].1;
    let k = tags.len() as f64;
    let n_mean = tags.iter().map(|t| t.0 as f64).sum::<f64>() / k;
    let y_mean = tags.iter().map(|t| t.1 - t_ref).sum::<f64>() / k;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for &(n, t) in tags {
        let dx = n as f64 - n_mean;
        sxx += dx * dx;
        sxy += dx * (t - t_ref - y_mean);
    }
    if sxx <= 0.0 {
        return None;
    }
    let period = sxy / sxx;
    let a = y_mean - period * n_mean;
    let rms = (tags
        .iter()
        .map(|&(n, t)| (t - t_ref - a - period * n as f64).powi(2))
        .sum::<f64>()
        / k)
        .sqrt();
    let stride = (tags.len() / 500).max(1);
    let (mut max_abs, mut max_norm) = (0.0f64, 0.0f64);
    let mut differences = Vec::new();
    for (i, &(n, t)) in tags.iter().enumerate() {
        let d = (t - t0_sw) - period_sw * n as f64;
        let g = Vector2::new(1.0, n as f64);
        let sigma = (g.transpose() * cov_sw * g)[0].sqrt();
        max_abs = max_abs.max(d.abs());
        max_norm = max_norm.max(d.abs() / sigma);
        if i % stride == 0 {
            differences.push((n, d, sigma));
        }
    }
    Some(HardwareComparison {
        profiles: tags.len() as u64,
        t0_s: t_ref + a,
        period_s: period,
        rms_residual_s: rms,
        max_abs_difference_s: max_abs,
        max_normalised_difference: max_norm,
        differences,
    })
}
