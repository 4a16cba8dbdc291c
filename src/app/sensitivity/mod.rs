//! The sensitivity study behind `kinescan sensitivity`: Sobol indices (per input and per group)
//! and the analytic linear shares of every point of a parking-lot-like geometry, written as
//! CSV and JSON tables.
//!
//! Geometry: a platform at a stated position and attitude, moving at `speed_mps` along its
//! heading and turning with `body_rate_deg_s`; a profile scanner whose returns come from flat
//! ground `scanner_height_m` below the optical centre at ranges `range_m[0]..range_m[1]`:
//! `beta = acos(height / rho)` (exact for a level platform and identity boresight; otherwise it
//! is just the set of (rho, beta) studied). Outputs are the point's displacement along local
//! East, North, Up at the point, and their variance-weighted combination ("total").
//!
//! An application command: it combines the uncertainty model with the simulator (for
//! `[scenario]` studies). Submodules: `config` (the study file), `points` (the points
//! studied and their sigmas), `tables` (CSV tables and plots).

pub(crate) mod config;
pub(crate) mod points;
mod tables;

pub use config::*;
pub use points::*;

use crate::io::atomic::{write_atomic, write_json};
use crate::io::publish::publish_folder;
use crate::uncertainty::model::{Group, Input, Jacobian, PointGeometry, N_INPUTS};
use crate::uncertainty::sobol::{FactorIndices, SaltelliDesign, SobolIndices, N_OUT};
use crate::Result;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Outputs analysed: displacement along local East, North, Up at the point, and "total" (the
/// 3D variance: indices weighted by each component's variance).
pub const OUTPUTS: [&str; N_OUT + 1] = ["east", "north", "up", "total"];

/// One factor's result at one point.
#[derive(Debug, Clone, Serialize)]
pub struct FactorRow {
    /// Input or group name.
    pub factor: String,
    /// "input" or "group".
    pub kind: &'static str,
    /// Sobol indices per output ([`OUTPUTS`]: E, N, U, total = variance-weighted E, N, U).
    pub sobol: [FactorIndices; N_OUT + 1],
    /// Analytic linear share of each output's variance.
    pub linear_share: [f64; N_OUT + 1],
}

/// Results at one point.
#[derive(Debug, Clone, Serialize)]
pub struct PointResult {
    /// Range (m).
    pub range_m: f64,
    /// Mirror angle (deg).
    pub beta_deg: f64,
    /// Elevation of the beam above the local horizontal at the scanner (deg; negative: down).
    pub beam_elevation_deg: f64,
    /// The 1-sigma of every input at this point (model order, SI units).
    pub sigmas: [f64; N_INPUTS],
    /// Linear 1-sigma along E, N, U and in 3D (m).
    pub sigma_enu_m: [f64; 4],
    /// Monte Carlo 1-sigma along E, N, U (m) from the Sobol base samples.
    pub sigma_enu_mc_m: [f64; 3],
    /// Per factor (18 inputs then 6 groups).
    pub factors: Vec<FactorRow>,
}

/// Mean over the points of one factor's indices on one output.
#[derive(Debug, Clone, Serialize)]
pub struct FactorSummary {
    /// Input or group name.
    pub factor: String,
    /// Output ([`OUTPUTS`]).
    pub output: &'static str,
    /// Mean first-order index.
    pub mean_first: f64,
    /// Mean total-effect index.
    pub mean_total: f64,
    /// Mean linear share.
    pub mean_linear_share: f64,
    /// Largest first-order index over the points, and its range (m).
    pub max_first: (f64, f64),
}

/// What `run_sensitivity` computed and wrote.
#[derive(Debug, Clone, Serialize)]
pub struct SensitivityReport {
    /// The study file as read.
    pub config: SensitivityConfig,
    /// The 1-sigma of every input at the first point (model order; SI units, see
    /// docs/uncertainty.md); with SMRMSG sigmas the INS ones vary per point
    /// ([`PointResult::sigmas`]).
    pub sigmas: Vec<(String, f64)>,
    /// Per point.
    pub points: Vec<PointResult>,
    /// Per factor, over the points.
    pub summary: Vec<FactorSummary>,
    /// Files written.
    pub outputs: Vec<PathBuf>,
}

/// Runs the study in `config_path` and writes into `out_dir`: `sensitivity_points.csv` (every
/// point, factor and output), `share_vs_range.csv` (plot data: first-order, total and linear
/// share of each factor against range), `sensitivity.json` (the [`SensitivityReport`]).
pub fn run_sensitivity(config_path: &Path, out_dir: &Path) -> Result<SensitivityReport> {
    let config = load_sensitivity(config_path)?;
    let mut inputs = vec![("config file".to_string(), config_path.to_path_buf())];
    if let Some(sc) = &config.scenario {
        inputs.push(("scenario.file".into(), sc.file.to_path_buf()));
    }
    let names = output_names();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    crate::io::paths::check_collisions(&inputs, &crate::io::paths::in_out_dir(out_dir, &names))?;
    run_sensitivity_config(config, out_dir)
}

/// [`run_sensitivity`] for a study already loaded with [`load_sensitivity`] (and possibly
/// changed, e.g. made smaller).
pub fn run_sensitivity_config(
    config: SensitivityConfig,
    out_dir: &Path,
) -> Result<SensitivityReport> {
    let mut report = study(config)?;
    let names = output_names();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    publish_folder(out_dir, "sensitivity", JSON, &names, |dir| {
        let final_path = |p: &Path| out_dir.join(p.file_name().unwrap_or_default());
        let points_csv = dir.join(POINTS_CSV);
        write_atomic(&points_csv, tables::points_table(&report).as_bytes())?;
        let plot_csv = dir.join(SHARE_CSV);
        write_atomic(&plot_csv, tables::share_vs_range_table(&report).as_bytes())?;
        let plots = tables::plot_share_against_range(&report, dir)?;
        report.outputs = [points_csv, plot_csv]
            .iter()
            .chain(&plots)
            .map(|p| final_path(p))
            .chain([out_dir.join(JSON)])
            .collect();
        write_json(&dir.join(JSON), &report)
    })?;
    Ok(report)
}

const POINTS_CSV: &str = "sensitivity_points.csv";
const SHARE_CSV: &str = "share_vs_range.csv";
/// The report, published after the other files.
const JSON: &str = "sensitivity.json";

/// Every file a study may write into its output folder.
fn output_names() -> Vec<String> {
    let mut names = vec![POINTS_CSV.to_string(), SHARE_CSV.into(), JSON.into()];
    for o in OUTPUTS {
        names.push(format!("share_vs_range_{o}.png"));
        names.push(format!("share_vs_range_inputs_{o}.png"));
    }
    names
}

/// The factors studied: each input alone, then each group.
pub fn study_factors() -> (Vec<String>, Vec<Vec<usize>>) {
    let mut names: Vec<String> = Input::ALL.iter().map(|i| i.name().to_string()).collect();
    let mut sets: Vec<Vec<usize>> = (0..N_INPUTS).map(|i| vec![i]).collect();
    for g in Group::ALL {
        names.push(g.name().to_string());
        sets.push(g.inputs().collect());
    }
    (names, sets)
}

fn study(config: SensitivityConfig) -> Result<SensitivityReport> {
    let (names, sets) = study_factors();
    let mut points = Vec::new();
    for (k, (geom, nav)) in study_geometries(&config)?.iter().enumerate() {
        let sigmas = study_sigmas(&config, nav.as_ref())?;
        let seed = config.seed.wrapping_add(k as u64);
        let design = SaltelliDesign::new(&sigmas, sets.clone(), config.samples, seed);
        let sobol = design
            .evaluate(enu_error_model(geom))
            .analyze(config.bootstrap, seed);
        let j = r_e_to_enu_at_point(geom) * geom.jacobian_e();
        points.push(point_result(geom, &j, &sigmas, &names, &sets, &sobol));
    }
    let summary = summarise(&names, &points);
    let first = points.first().map_or([0.0; N_INPUTS], |p| p.sigmas);
    let sigmas = Input::ALL
        .iter()
        .map(|i| (i.name().to_string(), first[*i as usize]))
        .collect();
    Ok(SensitivityReport {
        config,
        sigmas,
        points,
        summary,
        outputs: Vec::new(),
    })
}

fn point_result(
    geom: &PointGeometry,
    j: &Jacobian,
    sigmas: &[f64; N_INPUTS],
    names: &[String],
    sets: &[Vec<usize>],
    sobol: &SobolIndices,
) -> PointResult {
    // contrib[k][i]: variance of output k (E, N, U, then their sum) from input i.
    let mut contrib = [[0.0; N_INPUTS]; N_OUT + 1];
    for i in 0..N_INPUTS {
        for k in 0..N_OUT {
            contrib[k][i] = (j[(k, i)] * sigmas[i]).powi(2);
            contrib[N_OUT][i] += contrib[k][i];
        }
    }
    let var: [f64; N_OUT + 1] = contrib.map(|c| c.iter().sum::<f64>());
    let factors = names
        .iter()
        .zip(sets)
        .enumerate()
        .map(|(f, (name, set))| FactorRow {
            factor: name.clone(),
            kind: if f < N_INPUTS { "input" } else { "group" },
            sobol: std::array::from_fn(|k| {
                if k < N_OUT {
                    sobol.per_output[k][f]
                } else {
                    sobol.combined[f]
                }
            }),
            linear_share: std::array::from_fn(|k| {
                set.iter().map(|&i| contrib[k][i]).sum::<f64>() / var[k].max(f64::MIN_POSITIVE)
            }),
        })
        .collect();
    PointResult {
        range_m: geom.range_m,
        beta_deg: geom.beta_rad.to_degrees(),
        beam_elevation_deg: beam_elevation_rad(geom).to_degrees(),
        sigmas: *sigmas,
        sigma_enu_m: std::array::from_fn(|k| var[k].sqrt()),
        sigma_enu_mc_m: sobol.variance.map(f64::sqrt),
        factors,
    }
}

fn summarise(names: &[String], points: &[PointResult]) -> Vec<FactorSummary> {
    let n = points.len().max(1) as f64;
    let mut out = Vec::new();
    for (f, name) in names.iter().enumerate() {
        for (k, output) in OUTPUTS.iter().enumerate() {
            let rows = points.iter().map(|p| (&p.factors[f], p.range_m));
            let max_first = rows.clone().map(|(r, rho)| (r.sobol[k].first, rho)).fold(
                (f64::NEG_INFINITY, 0.0),
                |a, b| if b.0 > a.0 { b } else { a },
            );
            out.push(FactorSummary {
                factor: name.clone(),
                output,
                mean_first: rows.clone().map(|(r, _)| r.sobol[k].first).sum::<f64>() / n,
                mean_total: rows.clone().map(|(r, _)| r.sobol[k].total).sum::<f64>() / n,
                mean_linear_share: rows.map(|(r, _)| r.linear_share[k]).sum::<f64>() / n,
                max_first,
            });
        }
    }
    out
}
