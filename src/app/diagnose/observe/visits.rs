//! Visits: the returns found on one reference in one pass, split where they pause, made while
//! the first pass streams the returns (docs/diagnosis.md, "Thinning"). A visit is closed as
//! soon as a later return on its reference shows that it ended, and thinned then, so the first
//! pass holds the open visits and the kept returns, never every return on a reference; the
//! observation budget bounds the kept returns whatever the survey's length.

use crate::pipeline::config::DiagnoseConfig;
use std::collections::BTreeMap;

/// One return on a reference (a patch or a control point's target), from the first pass:
/// its record in the pass's file, its time (s) and its signed distance from the patch's plane
/// (m, along the normal; 0 on a target).
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    pub index: usize,
    pub t_s: f64,
    pub d_m: f32,
}

/// A visit before its observations are computed: reference (patch or control point), pass
/// and the kept returns, in time order.
pub(super) struct PendingVisit {
    pub patch: usize,
    pub pass: usize,
    pub hits: Vec<Hit>,
}

/// The visits made, and the account of the returns left out.
pub(super) struct Closed {
    /// By (reference, pass), in time order within one.
    pub visits: Vec<PendingVisit>,
    /// Returns in visits with fewer than `min_returns`.
    pub short: u64,
    /// Returns thinned out of kept visits, and those of visits left out for the budget.
    pub thinned: u64,
    /// Returns of centred visits further than `band_m` from their visit's median.
    pub off_band: u64,
    /// Per centred reference, the median distance from its plane (m) of each of its visits.
    pub medians: BTreeMap<usize, Vec<f64>>,
}

/// How returns on one reference in one pass make visits.
pub(super) struct VisitRule {
    /// A pause longer than this (s) ends a visit.
    gap_s: f64,
    /// A visit longer than this (s) is split.
    max_s: f64,
    min_returns: usize,
    max_returns: usize,
    /// At most this many returns are kept over all visits.
    budget: usize,
}

impl VisitRule {
    pub fn patches(opts: &DiagnoseConfig) -> Self {
        VisitRule {
            gap_s: opts.visit_gap_s,
            max_s: opts.max_visit_s,
            min_returns: opts.min_per_visit,
            max_returns: opts.max_per_visit,
            budget: opts.max_observations,
        }
    }

    /// A target visit keeps all its returns: their centroid is the observation.
    pub fn targets(opts: &DiagnoseConfig) -> Self {
        VisitRule {
            min_returns: opts.target_min_returns,
            max_returns: usize::MAX,
            budget: usize::MAX,
            ..VisitRule::patches(opts)
        }
    }
}

/// Visits being made from the hits of every reference and pass, each (reference, pass)'s
/// hits given in record order.
pub(super) struct Visits {
    rule: VisitRule,
    /// The visit still open on each (reference, pass), and its earliest and latest time (s).
    open: BTreeMap<(usize, usize), (Vec<Hit>, f64, f64)>,
    /// Closed visits, each with its number among its (reference, pass)'s visits.
    closed: Vec<(u64, PendingVisit)>,
    /// Visits closed so far on each (reference, pass).
    closings: BTreeMap<(usize, usize), u64>,
    /// Returns a visit keeps now: `max_returns`, halved while the kept returns exceed twice
    /// the budget.
    cap: usize,
    /// Of the visits of each (reference, pass), those numbered a multiple of this are kept
    /// (doubled once the cap is down to `min_returns` and the kept returns still exceed twice
    /// the budget): each reference keeps visits spread over the whole survey.
    stride: u64,
    kept: usize,
    short: u64,
    thinned: u64,
    /// References whose visits keep only their returns within `band_m` of the visit's median
    /// distance from the plane ([`Visits::centre_on_median`]); empty: none.
    centred: Vec<bool>,
    band_m: f64,
    off_band: u64,
    medians: BTreeMap<usize, Vec<f64>>,
}

impl Visits {
    pub fn new(rule: VisitRule) -> Self {
        Visits {
            cap: rule.max_returns,
            rule,
            open: BTreeMap::new(),
            closed: Vec::new(),
            closings: BTreeMap::new(),
            stride: 1,
            kept: 0,
            short: 0,
            thinned: 0,
            centred: Vec::new(),
            band_m: 0.0,
            off_band: 0,
            medians: BTreeMap::new(),
        }
    }

    /// Keeps of each visit on a reference `centred` names only the returns within `band_m`
    /// (m) of the visit's median distance from the plane: a patch whose returns lie off its
    /// plane as a whole (docs/diagnosis.md, "Patches off their plane").
    pub fn centre_on_median(&mut self, centred: Vec<bool>, band_m: f64) {
        (self.centred, self.band_m) = (centred, band_m);
    }

    /// Adds `hit` on reference and pass `key`, closing the visit open there when the hit
    /// comes more than `gap_s` after its latest return or `max_s` after its earliest.
    pub fn push(&mut self, key: (usize, usize), hit: Hit) {
        let (run, earliest, latest) = self
            .open
            .entry(key)
            .or_insert_with(|| (Vec::new(), hit.t_s, hit.t_s));
        let ended = hit.t_s - *latest > self.rule.gap_s || hit.t_s - *earliest > self.rule.max_s;
        let ended = if ended {
            (*earliest, *latest) = (hit.t_s, hit.t_s);
            Some(std::mem::take(run))
        } else {
            (*earliest, *latest) = (earliest.min(hit.t_s), latest.max(hit.t_s));
            None
        };
        run.push(hit);
        if let Some(run) = ended {
            self.close(key, run);
        }
    }

    /// Closes every open visit and gives all visits, by (reference, pass) and in time order
    /// within one, with at most the budget of returns.
    pub fn finish(mut self) -> Closed {
        for (key, (run, _, _)) in std::mem::take(&mut self.open) {
            self.close(key, run);
        }
        let mut closed: Vec<PendingVisit> = std::mem::take(&mut self.closed)
            .into_iter()
            .map(|(_, v)| v)
            .collect();
        // Stable: the visits of one (reference, pass) closed in time order.
        closed.sort_by_key(|v| (v.patch, v.pass));
        let visits = self.within_budget(closed);
        Closed {
            visits,
            short: self.short,
            thinned: self.thinned,
            off_band: self.off_band,
            medians: self.medians,
        }
    }

    fn close(&mut self, (patch, pass): (usize, usize), mut run: Vec<Hit>) {
        run.sort_by(|a, b| a.t_s.total_cmp(&b.t_s).then(a.index.cmp(&b.index)));
        if self.centred.get(patch).copied().unwrap_or(false) {
            run = self.about_median(patch, run);
        }
        if run.len() < self.rule.min_returns {
            self.short += run.len() as u64;
            return;
        }
        let count = self.closings.entry((patch, pass)).or_default();
        let number = *count;
        *count += 1;
        if !number.is_multiple_of(self.stride) {
            self.thinned += run.len() as u64;
            return;
        }
        let hits = self.thin(&run, self.cap);
        self.kept += hits.len();
        self.closed
            .push((number, PendingVisit { patch, pass, hits }));
        if self.kept > self.rule.budget.saturating_mul(2) {
            self.halve();
        }
    }

    /// Halves the returns kept per visit, or once that is down to `min_returns`, the visits.
    fn halve(&mut self) {
        if self.cap / 2 >= self.rule.min_returns {
            self.cap /= 2;
            let cap = self.cap;
            let mut closed = std::mem::take(&mut self.closed);
            for (_, v) in &mut closed {
                v.hits = self.thin(&v.hits, cap);
            }
            self.closed = closed;
        } else {
            self.stride *= 2;
            let stride = self.stride;
            let mut dropped = 0;
            self.closed.retain(|(number, v)| {
                let keep = number.is_multiple_of(stride);
                dropped += if keep { 0 } else { v.hits.len() as u64 };
                keep
            });
            self.thinned += dropped;
        }
        self.kept = self.closed.iter().map(|(_, v)| v.hits.len()).sum();
    }

    /// The visits with at most `budget` returns: every visit thinned to the largest common cap
    /// that fits, or when `min_returns` each does not fit, the visits themselves evenly.
    fn within_budget(&mut self, mut visits: Vec<PendingVisit>) -> Vec<PendingVisit> {
        let (budget, min) = (self.rule.budget, self.rule.min_returns);
        let total = |cap: usize, vs: &[PendingVisit]| -> usize {
            vs.iter().map(|v| v.hits.len().min(cap)).sum()
        };
        if total(usize::MAX, &visits) <= budget {
            return visits;
        }
        if total(min, &visits) > budget {
            let n = (budget / min).max(1);
            let len = visits.len();
            let mut k = 0;
            let mut dropped = 0;
            let mut next = 0;
            visits.retain(|v| {
                let keep = k == next * len / n && next < n;
                next += usize::from(keep);
                k += 1;
                dropped += if keep { 0 } else { v.hits.len() as u64 };
                keep
            });
            self.thinned += dropped;
        }
        // The largest cap in [min, longest] whose total fits (the total grows with the cap).
        let (mut lo, mut hi) = (
            min,
            visits.iter().map(|v| v.hits.len()).max().unwrap_or(min),
        );
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            if total(mid, &visits) <= budget {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        for v in &mut visits {
            v.hits = self.thin(&v.hits, lo);
        }
        visits
    }

    /// The returns of `run` within `band_m` of its median distance from the plane (the lower
    /// median); counts the others and notes the median.
    fn about_median(&mut self, patch: usize, run: Vec<Hit>) -> Vec<Hit> {
        let mut d: Vec<f32> = run.iter().map(|h| h.d_m).collect();
        d.sort_by(f32::total_cmp);
        let median = f64::from(d[(d.len() - 1) / 2]);
        self.medians.entry(patch).or_default().push(median);
        let band_m = self.band_m;
        let near = |h: &Hit| (f64::from(h.d_m) - median).abs() <= band_m;
        let kept: Vec<Hit> = run.iter().copied().filter(near).collect();
        self.off_band += (run.len() - kept.len()) as u64;
        kept
    }

    /// At most `max` of `run`, evenly spaced by position (the first kept); counts the others.
    fn thin(&mut self, run: &[Hit], max: usize) -> Vec<Hit> {
        if run.len() <= max {
            return run.to_vec();
        }
        self.thinned += (run.len() - max) as u64;
        (0..max).map(|k| run[k * run.len() / max]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(budget: usize) -> VisitRule {
        VisitRule {
            gap_s: 1.0,
            max_s: 5.0,
            min_returns: 4,
            max_returns: 16,
            budget,
        }
    }

    /// `visits` passes over one patch, 2 s apart, `per` returns 10 ms apart each, as hits in
    /// record order; with a second patch seen at the same times.
    fn stream(visits: &mut Visits, passes: usize, per: usize) -> u64 {
        let mut index = 0;
        for k in 0..passes {
            for j in 0..per {
                for patch in [0, 1] {
                    let t_s = 2.0 * k as f64 + 0.01 * j as f64;
                    visits.push(
                        (patch, 0),
                        Hit {
                            index,
                            t_s,
                            d_m: 0.0,
                        },
                    );
                    index += 1;
                }
            }
        }
        index as u64
    }

    /// Pauses split visits, long visits are split at `max_s` and thinned, short ones left out,
    /// and every hit is a kept, thinned or short return.
    #[test]
    fn splits_thins_and_accounts_for_every_hit() {
        let mut v = Visits::new(rule(usize::MAX));
        let mut n = stream(&mut v, 3, 10);
        // A long visit on patch 2 (7 s of hits every 0.1 s: split at 5 s) and a short one.
        for j in 0..70 {
            v.push(
                (2, 1),
                Hit {
                    index: 1000 + j,
                    t_s: 100.0 + 0.1 * j as f64,
                    d_m: 0.0,
                },
            );
        }
        v.push(
            (2, 1),
            Hit {
                index: 2000,
                t_s: 200.0,
                d_m: 0.0,
            },
        );
        n += 71;
        let Closed {
            visits,
            short,
            thinned,
            ..
        } = v.finish();
        let kept: usize = visits.iter().map(|v| v.hits.len()).sum();
        assert_eq!(kept as u64 + short + thinned, n);
        assert_eq!(short, 1);
        let keys: Vec<_> = visits
            .iter()
            .map(|v| (v.patch, v.pass, v.hits.len()))
            .collect();
        assert_eq!(
            keys,
            [
                (0, 0, 10),
                (0, 0, 10),
                (0, 0, 10),
                (1, 0, 10),
                (1, 0, 10),
                (1, 0, 10),
                (2, 1, 16),
                (2, 1, 16)
            ]
        );
        let long = &visits[6].hits;
        assert!(long.windows(2).all(|w| w[0].t_s < w[1].t_s));
        assert_eq!(long[0].t_s, 100.0);
    }

    /// A centred visit keeps the returns about its median (here 0.21 m off the plane, as a
    /// lever arm's error moves a ground patch) and counts the clutter 0.8 m off; a visit on
    /// another reference is untouched.
    #[test]
    fn centred_visits_keep_their_bulk_about_its_median() {
        let mut v = Visits::new(rule(usize::MAX));
        v.centre_on_median(vec![true, false], 0.15);
        for (patch, j) in (0..2).flat_map(|p| (0..12).map(move |j| (p, j))) {
            let d_m = if j % 4 == 3 {
                0.8
            } else {
                0.21 + 0.001 * j as f32
            };
            let t_s = 0.01 * j as f64;
            let index = 100 * patch + j;
            v.push((patch, 0), Hit { index, t_s, d_m });
        }
        let c = v.finish();
        let lengths: Vec<usize> = c.visits.iter().map(|v| v.hits.len()).collect();
        assert_eq!((c.short, c.thinned, c.off_band), (0, 0, 3));
        assert_eq!(lengths, [9, 12]);
        assert!(c.visits[0].hits.iter().all(|h| h.d_m < 0.3));
        let medians = &c.medians[&0];
        assert_eq!(medians.len(), 1);
        assert!((medians[0] - 0.216).abs() < 1e-6, "{medians:?}");
        assert!(!c.medians.contains_key(&1));
    }

    /// Under a budget the kept returns never exceed it, at any length, and what is kept stays
    /// spread over the whole survey; every hit is accounted for.
    #[test]
    fn the_budget_bounds_the_kept_returns_whatever_the_length() {
        for (passes, budget) in [(10, 200), (100, 200), (1000, 200), (1000, 40), (1000, 4)] {
            let mut v = Visits::new(rule(budget));
            let n = stream(&mut v, passes, 12);
            let Closed {
                visits,
                short,
                thinned,
                ..
            } = v.finish();
            let kept: usize = visits.iter().map(|v| v.hits.len()).sum();
            assert!(
                kept <= budget,
                "{passes} passes, budget {budget}: {kept} kept"
            );
            assert!(visits.iter().all(|v| v.hits.len() >= 4));
            assert_eq!(kept as u64 + short + thinned, n);
            assert_eq!(short, 0);
            // Both patches, the first and the last third of the survey.
            for patch in [0, 1] {
                let times: Vec<f64> = visits
                    .iter()
                    .filter(|v| v.patch == patch)
                    .map(|v| v.hits[0].t_s)
                    .collect();
                let end = 2.0 * passes as f64;
                if budget >= 8 * 4 {
                    assert!(times.iter().any(|&t| t < end / 3.0), "{passes} {budget}");
                    assert!(
                        times.iter().any(|&t| t > 2.0 * end / 3.0),
                        "{passes} {budget}"
                    );
                }
            }
        }
    }
}
