//! What the trajectory says about each pass, for the morning report: GNSS outages read from
//! the SMRMSG (spans where the horizontal position RMS stands well above the day's usual) and
//! gaps in the SBET's records.
//!
//! An outage is a run of SMRMSG records whose horizontal position RMS `hypot(north, east)`
//! exceeds [`OUTAGE_FACTOR`] times the median over the whole file and at least
//! [`OUTAGE_MIN_M`]: an inertial solution without GNSS drifts, and its RMS grows from the
//! first second (5x within seconds in the simulator, decimetres to metres in practice), while
//! the day's median is the GNSS-aided level. A gap is a step between SBET records longer than
//! [`GAP_FACTOR`] times the file's median step.
//!
//! A trajectory made by `kinescan trajectory` has a smoothed SMRMSG whose RMS in an outage
//! may stay below [`OUTAGE_MIN_M`] (2.9 cm through 30 s in the simulator: the smoother bridges
//! the gap from both ends); its run report beside the SBET ([`crate::ins::report_path`])
//! lists the GNSS gaps themselves, and those the SMRMSG does not show are added
//! ([`add_reported_gaps`]).

use crate::io::smrmsg::SmrmsgFile;
use crate::trajectory::Trajectory;
use crate::{Error, Result};
use serde::Serialize;
use std::path::Path;

/// Horizontal RMS above this multiple of the file's median marks an outage.
pub const OUTAGE_FACTOR: f64 = 3.0;
/// ... and above this (m): a day at millimetre level does not call 3 mm an outage.
pub const OUTAGE_MIN_M: f64 = 0.05;
/// A step between SBET records longer than this multiple of the median step is a gap.
pub const GAP_FACTOR: f64 = 5.0;

/// One GNSS outage seen in the SMRMSG.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outage {
    /// First and last SMRMSG record time above the threshold (GPS s).
    pub span_s: [f64; 2],
    /// Largest horizontal position RMS within (m).
    pub peak_horizontal_rms_m: f64,
}

impl Outage {
    /// Duration (s), from the first to the last record above the threshold.
    pub fn seconds(&self) -> f64 {
        self.span_s[1] - self.span_s[0]
    }
}

/// The trajectory's state over one pass.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TrajectoryHealth {
    /// Median horizontal position RMS over the pass (m); None without SMRMSG.
    pub horizontal_rms_median_m: Option<f64>,
    /// GNSS outages within the pass.
    pub outages: Vec<Outage>,
    /// SBET gaps within the pass: [last record before, first record after] (GPS s).
    pub gaps_s: Vec<[f64; 2]>,
    /// GNSS gaps within the pass from the `kinescan trajectory` report beside the SBET that
    /// no outage of the SMRMSG overlaps.
    pub reported_gnss_gaps: Vec<ReportedGap>,
}

/// A GNSS gap listed by `kinescan trajectory`'s report (`gnss_gaps`, docs/trajectory.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReportedGap {
    /// Last fix before the gap and first fix after it (GPS s).
    pub span_s: [f64; 2],
    /// Largest smoothed horizontal position sigma inside (m).
    pub max_horizontal_sigma_m: f64,
}

impl ReportedGap {
    /// Duration without a fix (s).
    pub fn seconds(&self) -> f64 {
        self.span_s[1] - self.span_s[0]
    }
}

/// The GNSS gaps of the `kinescan trajectory` report beside `sbet` (its default name,
/// [`crate::ins::report_path`]); none when there is no such file or it is another kind of
/// report (no `gnss_gaps` and `filter`). A file that is not JSON is refused with its name.
pub fn reported_gaps(sbet: &Path) -> Result<Vec<ReportedGap>> {
    let path = crate::ins::report_path(sbet);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(&path, e)),
    };
    let v: serde_json::Value = serde_json::from_slice(&bytes).map_err(|e| {
        Error::bad_file(
            &path,
            format!("the trajectory report beside the SBET is not JSON ({e})"),
        )
    })?;
    let (Some(gaps), true) = (v["gnss_gaps"].as_array(), v["filter"].is_object()) else {
        return Ok(Vec::new());
    };
    let bad = |k: usize, what: &str| {
        Error::bad_record(
            &path,
            format!("gnss_gaps[{k}]"),
            format!("{what} missing or not a number"),
        )
    };
    gaps.iter()
        .enumerate()
        .map(|(k, g)| {
            let num = |key: &str| g[key].as_f64().ok_or_else(|| bad(k, key));
            Ok(ReportedGap {
                span_s: [num("from_s")?, num("to_s")?],
                max_horizontal_sigma_m: num("max_horizontal_sigma_m")?,
            })
        })
        .collect()
}

/// Adds to each pass (`spans` as for [`per_pass`]) the reported gaps that overlap it and that
/// none of its SMRMSG outages overlaps.
pub fn add_reported_gaps(
    health: &mut [TrajectoryHealth],
    spans: &[Option<[f64; 2]>],
    gaps: &[ReportedGap],
) {
    let overlaps = |a: [f64; 2], b: [f64; 2]| a[0] <= b[1] && b[0] <= a[1];
    for (h, s) in health.iter_mut().zip(spans) {
        let Some(span) = *s else { continue };
        for g in gaps.iter().filter(|g| overlaps(g.span_s, span)) {
            if !h.outages.iter().any(|o| overlaps(o.span_s, g.span_s)) {
                h.reported_gnss_gaps.push(g.clone());
            }
        }
    }
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

fn horizontal(f: &SmrmsgFile, i: usize) -> f64 {
    let r = f.record(i);
    r.north_m.hypot(r.east_m)
}

/// The trajectory's outages, gaps and RMS level over each of `spans` ([first, last] GPS s of
/// a pass's returns). The day's levels (median RMS, median SBET step) are computed once, over
/// the whole files.
pub fn per_pass(traj: &Trajectory, spans: &[Option<[f64; 2]>]) -> Vec<TrajectoryHealth> {
    let mut out = vec![TrajectoryHealth::default(); spans.len()];
    let inside = |t: f64| {
        spans
            .iter()
            .position(|s| s.is_some_and(|[t0, t1]| (t0..=t1).contains(&t)))
    };
    if let Some(f) = traj.smrmsg() {
        let rms: Vec<f64> = (0..f.len()).map(|i| horizontal(f, i)).collect();
        let threshold = (OUTAGE_FACTOR * median(rms.clone()).unwrap_or(0.0)).max(OUTAGE_MIN_M);
        let mut levels: Vec<Vec<f64>> = vec![Vec::new(); spans.len()];
        let mut current: Option<(usize, Outage)> = None;
        for (i, &v) in rms.iter().enumerate() {
            let t = f.time_s(i);
            let pass = inside(t);
            if let Some(k) = pass {
                levels[k].push(v);
            }
            let continues = current.as_ref().is_some_and(|(k, _)| Some(*k) == pass);
            if !(continues && v > threshold) {
                if let Some((k, o)) = current.take() {
                    out[k].outages.push(o);
                }
            }
            if let (Some(k), true) = (pass, v > threshold) {
                let (_, o) = current.get_or_insert((
                    k,
                    Outage {
                        span_s: [t, t],
                        peak_horizontal_rms_m: v,
                    },
                ));
                o.span_s[1] = t;
                o.peak_horizontal_rms_m = o.peak_horizontal_rms_m.max(v);
            }
        }
        if let Some((k, o)) = current {
            out[k].outages.push(o);
        }
        for (h, l) in out.iter_mut().zip(levels) {
            h.horizontal_rms_median_m = median(l);
        }
    }
    let sbet = traj.sbet();
    let steps: Vec<f64> = (1..sbet.len())
        .map(|i| sbet.time_s(i) - sbet.time_s(i - 1))
        .collect();
    if let Some(step) = median(steps) {
        for i in 1..sbet.len() {
            let (a, b) = (sbet.time_s(i - 1), sbet.time_s(i));
            if b - a > GAP_FACTOR * step {
                for (h, s) in out.iter_mut().zip(spans) {
                    if s.is_some_and(|[t0, t1]| b >= t0 && a <= t1) {
                        h.gaps_s.push([a, b]);
                    }
                }
            }
        }
    }
    out
}
