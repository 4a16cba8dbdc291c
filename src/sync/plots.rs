//! Diagnostic PNGs of a synchronisation (paper 004, figures 4 and 6): sighting times against
//! profile number with the fitted clock, the residuals of both estimators, and hardware minus
//! software profile times when PPS tags exist.

use super::{SightingStatus, SyncResult};
use crate::plot::Plot;
use crate::Result;
use std::path::{Path, PathBuf};

/// Writes `<stem>_times.png`, `<stem>_residuals.png` and, with hardware tags,
/// `<stem>_hardware.png` into `dir`; returns the paths.
pub fn write_plots(r: &SyncResult, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
    let t0 = r.clock.t0_s;
    let acc = |s: &&super::Sighting| s.status == SightingStatus::Accepted;
    let pts = |keep: &dyn Fn(&&super::Sighting) -> bool| -> Vec<(f64, f64)> {
        r.sightings
            .iter()
            .filter(|s| keep(s))
            .filter_map(|s| Some((s.profile_position?, s.crossing_time_s - t0)))
            .collect()
    };
    let accepted = pts(&acc);
    let outliers = pts(&|s| s.status == SightingStatus::Outlier);
    let n_max = accepted.iter().map(|p| p.0).fold(1.0, f64::max);
    let line = [(0.0, 0.0), (n_max, r.clock.period_s * n_max)];
    let mut out = Vec::new();
    let times = dir.join(format!("{stem}_times.png"));
    Plot::new(
        "Sync: plane-crossing time against sighting profile (paper fig. 4)",
        "n + f(beta)",
        "t - t0 (s)",
    )
    .scatter("accepted sightings", &accepted)
    .scatter("outliers", &outliers)
    .line("t0 + T (n + f(beta))", &line)
    .save_png(&times)?;
    out.push(times);
    let res = |c: &super::ClockEstimate| -> Vec<(f64, f64)> {
        r.sightings
            .iter()
            .filter(acc)
            .filter_map(|s| {
                let nu = s.profile_position?;
                Some((nu, 1e3 * (s.crossing_time_s - c.t0_s - c.period_s * nu)))
            })
            .collect()
    };
    let residuals = dir.join(format!("{stem}_residuals.png"));
    let mut p = Plot::new(
        "Sync: crossing time minus t0 + T (n + f(beta)), per estimator",
        "profile number n",
        "residual (ms)",
    )
    .scatter("paper fit", &res(&r.paper));
    if let Some(f) = &r.refined {
        p = p.scatter("refined fit", &res(&f.clock));
    }
    p.save_png(&residuals)?;
    out.push(residuals);
    if let Some(h) = &r.hardware {
        let path = dir.join(format!("{stem}_hardware.png"));
        let series = |k: f64| -> Vec<(f64, f64)> {
            h.differences
                .iter()
                .map(|&(n, d, s)| (n as f64, 1e3 * (d + k * s)))
                .collect()
        };
        Plot::new(
            "Hardware (PPS) minus software profile times (paper fig. 6)",
            "profile number n",
            "t_hw - t_sw (ms)",
        )
        .line("difference", &series(0.0))
        .line("+2 sigma (software)", &series(2.0))
        .line("-2 sigma (software)", &series(-2.0))
        .save_png(&path)?;
        out.push(path);
    }
    Ok(out)
}
