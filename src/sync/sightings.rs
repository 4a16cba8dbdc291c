//! The paper's method: a target cluster chosen per predicted crossing, the clock fitted and
//! the choice re-made until stable; the sightings and their usability.

use super::detect::Cluster;
use super::geometry::Crossing;
use super::options::{SyncOptions, SyncTarget};
use super::paper::{self, Obs};
use super::result::{Sighting, SightingStatus};
use crate::{Error, Result};

pub(super) type Predict<'a> = dyn Fn(&Crossing, f64, f64) -> f64 + 'a;

/// Chooses a cluster per crossing (nearest the predicted profile), fits, and re-associates
/// with the fitted clock until the choice is stable.
pub(super) fn associate(
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    o: &SyncOptions,
    t_ref: f64,
    predict: &Predict,
) -> Result<(paper::LineFit, Vec<Option<usize>>, Vec<usize>)> {
    let mut clock = (o.t0_approx_s, o.period_approx_s);
    let mut chosen: Vec<Option<usize>> = Vec::new();
    for _ in 0..10 {
        let next: Vec<Option<usize>> = crossings
            .iter()
            .zip(cands)
            .map(|(c, cs)| {
                let n = predict(c, clock.0, clock.1);
                (0..cs.len()).min_by(|&a, &b| {
                    (cs[a].mean_profile - n)
                        .abs()
                        .total_cmp(&(cs[b].mean_profile - n).abs())
                })
            })
            .collect();
        let obs = observations(crossings, cands, &next, o, t_ref);
        let active: Vec<usize> = (0..obs.len()).filter(|&i| next[i].is_some()).collect();
        if active.len() < 2 {
            return Err(not_enough(active.len(), crossings.len(), o));
        }
        let (fit, outliers) =
            paper::robust_fit(&obs, &active, o.outlier_sigma).ok_or_else(|| Error::Numerical {
                what: "sync".into(),
                problem: "all sightings lie at one place: the mirror period T is not \
                          constrained; survey sync points seen at times far apart"
                    .into(),
            })?;
        let stable = next == chosen;
        chosen = next;
        clock = (t_ref + fit.x[0], fit.x[1]);
        if stable {
            return Ok((fit, chosen, outliers));
        }
    }
    Err(Error::Numerical {
        what: "sync detection".into(),
        problem: "the choice of target clusters does not settle; check the targets".into(),
    })
}

fn not_enough(found: usize, predicted: usize, o: &SyncOptions) -> Error {
    Error::Numerical {
        what: "sync".into(),
        problem: format!(
            "{found} sighting(s) detected for {predicted} predicted pass(es) over the sync \
             points: need at least 2 usable sync points seen at times far apart. Check that \
             the approximate t0 ({:.3} s) and period ({} s) are within window_s = {} s of \
             the truth, that the targets are within max_range_m = {} m of the route and \
             brighter than min_intensity = {}",
            o.t0_approx_s, o.period_approx_s, o.window_s, o.max_range_m, o.min_intensity
        ),
    }
}

fn observations(
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    chosen: &[Option<usize>],
    o: &SyncOptions,
    t_ref: f64,
) -> Vec<Obs> {
    crossings
        .iter()
        .zip(cands)
        .zip(chosen)
        .map(|((c, cs), ch)| {
            let (nu, _) = ch.map_or((0.0, 0), |k| {
                let cl = &cs[k];
                (cl.profile as f64 + o.mirror.fraction(cl.beta_rad), 0)
            });
            Obs {
                nu,
                y_s: c.t_s - t_ref,
                sigma_s: observation_sigma(c, o.period_approx_s),
            }
        })
        .collect()
}

/// Sighting sigma (s): profile quantisation `T / sqrt(12)` and `sigma_d / |d'|`.
fn observation_sigma(c: &Crossing, period: f64) -> f64 {
    (period * period / 12.0 + (c.sigma_d_m / c.rate_mps).powi(2)).sqrt()
}

#[allow(clippy::too_many_arguments)]
pub(super) fn sightings(
    targets: &[SyncTarget],
    crossings: &[Crossing],
    cands: &[Vec<Cluster>],
    chosen: &[Option<usize>],
    outliers: &[usize],
    fit: &paper::LineFit,
    o: &SyncOptions,
    t_ref: f64,
) -> Vec<Sighting> {
    let obs = observations(crossings, cands, chosen, o, t_ref);
    let mut passes = vec![0u32; targets.len()];
    crossings
        .iter()
        .enumerate()
        .map(|(i, c)| {
            passes[c.point] += 1;
            let cl = chosen[i].map(|k| &cands[i][k]);
            let status = match (cl, outliers.contains(&i)) {
                (None, _) => SightingStatus::NotFound,
                (Some(_), true) => SightingStatus::Outlier,
                (Some(_), false) => SightingStatus::Accepted,
            };
            let z = cl.map(|_| fit.z(&obs[i]));
            Sighting {
                target: targets[c.point].id.clone(),
                pass: passes[c.point],
                crossing_time_s: c.t_s,
                range_m: c.range_m,
                predicted_profile: (c.t_s - o.t0_approx_s) / o.period_approx_s
                    - o.mirror.fraction(c.beta_rad),
                candidates: cands[i].len(),
                profile: cl.map(|k| k.profile),
                beta_deg: cl.map(|k| k.beta_rad.to_degrees()),
                profile_position: cl.map(|_| obs[i].nu),
                returns_count: cl.map_or(0, |k| k.returns.len()),
                residual_s: z.map(|z| z * obs[i].sigma_s),
                normalised_residual: z,
                sigma_s: obs[i].sigma_s,
                status,
                returns: cl.map_or(Vec::new(), |k| k.returns.clone()),
                refined_returns: Vec::new(),
            }
        })
        .collect()
}

/// Fewer than 2 sync points, or all sightings at one place: a clear error.
pub(super) fn check_usable(s: &[Sighting], o: &SyncOptions) -> Result<()> {
    let ok: Vec<&Sighting> = s
        .iter()
        .filter(|s| s.status == SightingStatus::Accepted)
        .collect();
    let mut ids: Vec<&str> = ok.iter().map(|s| s.target.as_str()).collect();
    ids.sort();
    ids.dedup();
    if ids.len() < 2 {
        return Err(Error::Numerical {
            what: "sync".into(),
            problem: format!(
                "only {} usable sync point(s) ({}) among {} predicted passes: need at least 2 \
                 sync points, each detected as a bright cluster, to estimate t0 and T",
                ids.len(),
                ids.join(", "),
                s.len()
            ),
        });
    }
    let (lo, hi) = ok
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
            (a.min(s.crossing_time_s), b.max(s.crossing_time_s))
        });
    if hi - lo < o.min_span_s {
        return Err(Error::Numerical {
            what: "sync".into(),
            problem: format!(
                "all sightings lie within {:.1} s of each other (one place): the mirror period \
                 T is not constrained; sync points must be seen at least min_span_s = {} s \
                 apart (e.g. at the start and the end of the route)",
                hi - lo,
                o.min_span_s
            ),
        });
    }
    Ok(())
}
