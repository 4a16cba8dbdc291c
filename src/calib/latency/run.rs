//! `kinescan calibrate latency`: config and files in, `latency.json`, the per-speed table and
//! its plot out.

use super::config::LatencyConfig;
use super::estimate::{estimate_latency, LatencyData, LatencyReport};
use super::inputs::{read_attitude, read_passes, read_returns};
use crate::io::atomic::{write_atomic, write_json};
use crate::io::config_file;
use crate::io::paths::{check_collisions, in_out_dir};
use crate::io::publish::publish_folder;
use crate::plot::Plot;
use crate::Result;
use std::path::Path;

/// Files a latency calibration writes into its output folder.
pub const OUTPUT_FILES: [&str; 3] = [
    "latency.json",
    "latency_by_speed.csv",
    "latency_by_speed.png",
];

/// `kinescan calibrate latency`: reads the TOML config at `config_path` (a [`LatencyConfig`];
/// unknown keys refused, errors name the key and the file) and the files it names (paths
/// relative to the config: conventions §6 returns with `time_s`, the table's pass log, the IMU attitude
/// stream in convention angles), estimates the total latency `tau` (s; convention sign: the attitude of
/// `t + tau` belongs to a return at `t`) and writes `latency.json` (the [`LatencyReport`]),
/// `latency_by_speed.csv` (the Table-2-like table) and `latency_by_speed.png` ([`latency_plot`])
/// atomically into `out_dir`.
pub fn run_latency_calibration(config_path: &Path, out_dir: &Path) -> Result<LatencyReport> {
    let cfg: LatencyConfig = config_file::load(config_path, &[])?.value;
    let setup = cfg.setup(&config_path.display().to_string())?;
    let returns = cfg.files.returns.to_path_buf();
    let passes = cfg.files.passes.to_path_buf();
    let attitude = cfg.files.attitude.to_path_buf();
    check_collisions(
        &[
            ("config file".into(), config_path.to_path_buf()),
            ("files.returns".into(), returns.clone()),
            ("files.passes".into(), passes.clone()),
            ("files.attitude".into(), attitude.clone()),
        ],
        &in_out_dir(out_dir, &OUTPUT_FILES),
    )?;
    let data = LatencyData {
        returns: read_returns(&returns, cfg.scanner.alpha0_deg.to_radians())?,
        passes: read_passes(&passes)?,
        attitude: read_attitude(&attitude)?,
    };
    let report = estimate_latency(&data, &setup)?;
    publish_folder(out_dir, "latency", OUTPUT_FILES[0], &OUTPUT_FILES, |dir| {
        let [json, csv, png] = OUTPUT_FILES.map(|n| dir.join(n));
        write_atomic(&csv, speed_table_csv(&report).as_bytes())?;
        latency_plot(&report).save_png(png)?;
        write_json(&json, &report)
    })?;
    Ok(report)
}

/// Latency (ms) against table speed |omega| (deg/s): the per-speed estimates and their +-1 sigma
/// limits as points, and the combined estimate as a line (written as `latency_by_speed.png`).
pub fn latency_plot(report: &LatencyReport) -> Plot {
    let at = |k: f64| {
        report.speeds.iter().map(move |r| {
            let ms = (r.latency_s + k * r.sigma_latency_s) * 1e3;
            (r.rate_deg_s.abs(), ms)
        })
    };
    let estimates: Vec<(f64, f64)> = at(0.0).collect();
    let limits: Vec<(f64, f64)> = at(-1.0).chain(at(1.0)).collect();
    let lo = estimates.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let hi = estimates
        .iter()
        .map(|p| p.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let combined_ms = report.latency_s * 1e3;
    Plot::new(
        "IMU-scanner latency by table speed",
        "table speed (deg/s)",
        "latency (ms)",
    )
    .scatter("per-speed estimate", &estimates)
    .scatter("estimate +- 1 sigma", &limits)
    .line(
        &format!(
            "combined {combined_ms:.3} +- {:.3} ms",
            report.sigma_latency_s * 1e3
        ),
        &[(lo, combined_ms), (hi, combined_ms)],
    )
}

/// The per-speed table (paper Table 2 layout, one row per speed, plus the combined row).
pub fn speed_table_csv(report: &LatencyReport) -> String {
    let mut s = String::from(
        "rate_deg_s,latency_ms,sigma_latency_ms,sigma_centre_plus_mm,sigma_centre_minus_mm,\
         shift_mm,n_used_plus,n_used_minus,n_rejected_plus,n_rejected_minus\n",
    );
    for r in &report.speeds {
        s += &format!(
            "{},{:.4},{:.4},{:.5},{:.5},{:.4},{},{},{},{}\n",
            r.rate_deg_s,
            r.latency_s * 1e3,
            r.sigma_latency_s * 1e3,
            r.sigma_centre_plus_m * 1e3,
            r.sigma_centre_minus_m * 1e3,
            r.shift_m * 1e3,
            r.n_used_plus,
            r.n_used_minus,
            r.n_rejected_plus,
            r.n_rejected_minus
        );
    }
    s += &format!(
        "combined,{:.4},{:.4},,,,,,,\n",
        report.latency_s * 1e3,
        report.sigma_latency_s * 1e3
    );
    s
}
