//! Detection of sync targets in the raw profiles: the high-intensity returns within a window
//! of profiles about where the approximate clock puts each plane crossing, grouped into
//! clusters (returns linked when at most `MAX_PROFILE_GAP` profiles and `cluster_gap_m`
//! apart across the profile), each cluster a candidate sighting.

use super::geometry::{Crossing, TargetReturn};
use crate::geo::rotations::wrap_pi;
use crate::io::profiles::ProfileFile;

/// Profiles a cluster may skip (a lost or missed profile) and stay one cluster.
const MAX_PROFILE_GAP: u32 = 2;

/// A group of high-intensity returns: one candidate sighting of a sync target.
#[derive(Debug, Clone)]
pub(crate) struct Cluster {
    /// The returns, in file order.
    pub returns: Vec<TargetReturn>,
    /// Sighting profile: the cluster's mean profile number, rounded (paper's `n_i`).
    pub profile: u32,
    /// Mean mirror angle of the cluster's returns (rad).
    pub beta_rad: f64,
    /// Mean profile number (unrounded).
    pub mean_profile: f64,
}

/// First record index whose profile is >= `profile` (records are ordered by profile).
pub(crate) fn lower_bound(file: &ProfileFile, profile: u32) -> usize {
    let (mut lo, mut hi) = (0usize, file.len());
    while lo < hi {
        let mid = (lo + hi) / 2;
        if file.get(mid).profile < profile {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Detection settings.
pub(crate) struct DetectParams {
    pub min_intensity: u16,
    pub window_profiles: f64,
    pub beta_gate_rad: f64,
    pub cluster_gap_m: f64,
    pub alpha0_rad: f64,
    pub use_alpha_column: bool,
}

/// Candidate clusters for one crossing predicted at (fractional) profile `n_pred`.
pub(crate) fn candidates(
    file: &ProfileFile,
    c: &Crossing,
    n_pred: f64,
    p: &DetectParams,
) -> Vec<Cluster> {
    let first = (n_pred - p.window_profiles).floor().max(0.0) as u32;
    let last = (n_pred + p.window_profiles).ceil().max(0.0) as u32;
    let mut hits: Vec<TargetReturn> = Vec::new();
    for i in lower_bound(file, first)..lower_bound(file, last.saturating_add(1)) {
        let r = file.get(i);
        let ok = r.intensity >= p.min_intensity
            && r.range_m > 0.0
            && r.range_m.is_finite()
            && r.beta_rad.is_finite()
            && wrap_pi(r.beta_rad - c.beta_rad).abs() <= p.beta_gate_rad;
        if ok {
            let alpha = if p.use_alpha_column {
                r.alpha_rad
            } else {
                p.alpha0_rad
            };
            hits.push(TargetReturn {
                profile: r.profile,
                beta_rad: r.beta_rad,
                alpha_rad: alpha,
                range_m: r.range_m,
                intensity: r.intensity,
            });
        }
    }
    cluster(&hits, p.cluster_gap_m)
}

/// Single-linkage clusters of `hits`.
fn cluster(hits: &[TargetReturn], gap_m: f64) -> Vec<Cluster> {
    let n = hits.len();
    let mut label: Vec<usize> = (0..n).collect();
    fn root(l: &mut [usize], mut i: usize) -> usize {
        while l[i] != i {
            l[i] = l[l[i]];
            i = l[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (&hits[i], &hits[j]);
            if b.profile > a.profile + MAX_PROFILE_GAP {
                break;
            }
            let across = wrap_pi(a.beta_rad - b.beta_rad).abs() * a.range_m.min(b.range_m);
            if across <= gap_m && (a.range_m - b.range_m).abs() <= gap_m {
                let (ra, rb) = (root(&mut label, i), root(&mut label, j));
                label[ra] = rb;
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<TargetReturn>> = Default::default();
    for (i, h) in hits.iter().enumerate() {
        let r = root(&mut label, i);
        groups.entry(r).or_default().push(*h);
    }
    groups
        .into_values()
        .map(|returns| {
            let k = returns.len() as f64;
            let mean_profile = returns.iter().map(|r| r.profile as f64).sum::<f64>() / k;
            let b0 = returns[0].beta_rad;
            let beta = b0
                + returns
                    .iter()
                    .map(|r| wrap_pi(r.beta_rad - b0))
                    .sum::<f64>()
                    / k;
            Cluster {
                profile: mean_profile.round() as u32,
                beta_rad: beta,
                mean_profile,
                returns,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ret(profile: u32, beta_deg: f64) -> TargetReturn {
        TargetReturn {
            profile,
            beta_rad: beta_deg.to_radians(),
            alpha_rad: 0.0,
            range_m: 5.0,
            intensity: 65535,
        }
    }

    #[test]
    fn clusters_split_by_profile_gap_and_across_the_profile() {
        // A target over profiles 10-12, a sign at profiles 20-21, a far return at 11.
        let hits = [
            ret(10, 70.0),
            ret(10, 71.0),
            ret(11, 70.5),
            ret(11, 90.0),
            ret(12, 70.0),
            ret(20, 70.0),
            ret(21, 70.5),
        ];
        let mut c = cluster(&hits, 0.3);
        c.sort_by(|a, b| a.mean_profile.total_cmp(&b.mean_profile));
        let sizes: Vec<usize> = c.iter().map(|c| c.returns.len()).collect();
        assert_eq!(sizes, vec![4, 1, 2]);
        assert_eq!(c[0].profile, 11);
        assert!((c[0].beta_rad.to_degrees() - 70.375).abs() < 1e-9);
        assert_eq!(c[2].profile, 21);
    }
}
