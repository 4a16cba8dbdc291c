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

use super::model::{Group, Input, PointGeometry, N_INPUTS};
use super::propagate::UncertaintyInputs;
use super::sobol::{FactorIndices, SaltelliDesign, SobolIndices, N_OUT};
use crate::geo::ellipsoid::{ecef_to_geodetic, geodetic_to_ecef, r_enu_to_e, r_n_to_e, Geodetic};
use crate::geo::rotations::r_zyx;
use crate::io::atomic::{write_atomic, write_json};
use crate::io::profiles::ProfileFile;
use crate::pipeline::config::UncertaintyConfig;
use crate::plot::{Plot, PALETTE};
use crate::sim::scanner::ScannerModel;
use crate::sim::{files, simulate, Scenario, SimOptions};
use crate::trajectory::{NavSigma, PoseCursor, Trajectory, TrajectoryOptions};
use crate::{Error, Result};
use nalgebra::{Matrix2, Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Outputs analysed: displacement along local East, North, Up at the point, and "total" (the
/// 3D variance: indices weighted by each component's variance).
pub const OUTPUTS: [&str; N_OUT + 1] = ["east", "north", "up", "total"];

/// Which sigma set: paper 003 Table 1 "expected" or "ideal", or `[custom]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SigmaSet {
    /// Table 1 expected: lever 0.02 m, boresight 0.02 deg, alpha/beta 0.0055 deg, range
    /// 0.008 m, K 0.01 m.
    Expected,
    /// Table 1 ideal: lever 0.004 m, boresight 0.001 deg, alpha/beta 0.0055 deg, range 0.003 m,
    /// K 0.005 m.
    Ideal,
    /// The `[custom]` table.
    Custom,
}

/// A sensitivity study file (TOML, unknown keys refused).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensitivityConfig {
    /// Sigma set.
    pub sigma_set: SigmaSet,
    /// Sigmas for `sigma_set = "custom"` (same keys as the pipeline's `[uncertainty]`).
    #[serde(default)]
    pub custom: Option<UncertaintyConfig>,
    /// Saltelli base rows per point (model runs: `samples * (18 + 6 + 2)`).
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Bootstrap resamples for the 95% intervals.
    #[serde(default = "default_bootstrap")]
    pub bootstrap: usize,
    /// Random seed.
    #[serde(default)]
    pub seed: u64,
    /// INS sigmas ("estimated from INS" in Table 1). Required for flat ground; with
    /// `[scenario]`, absent means the simulated SMRMSG at each return's time.
    #[serde(default)]
    pub ins: Option<InsSigmaConfig>,
    /// Timing sigmas (not in Table 1; used by every set).
    #[serde(default)]
    pub timing: TimingSigmaConfig,
    /// Platform state (flat ground).
    #[serde(default)]
    pub platform: Option<PlatformConfig>,
    /// Scanner mounting (flat ground).
    #[serde(default)]
    pub sensor: Option<StudySensorConfig>,
    /// Points studied (flat ground).
    #[serde(default)]
    pub points: Option<PointsConfig>,
    /// Or: the returns of a simulated survey (instead of `[platform]`, `[sensor]`, `[points]`).
    #[serde(default)]
    pub scenario: Option<ScenarioPointsConfig>,
}

/// `[scenario]`: study returns of a survey simulated from a scenario file (docs/simulator.md),
/// with their real ranges, beam directions and attitudes; the sensor is the scenario's
/// configured one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioPointsConfig {
    /// Scenario file, relative to the study file (made absolute when loaded).
    pub file: PathBuf,
    /// Simulated duration (s), replacing the scenario's `duration_s`.
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// First and last range (m): split into `count` equal bins, one return per bin (the one
    /// closest to the bin centre; bins without a return are left out).
    pub range_m: [f64; 2],
    /// Number of range bins.
    pub count: usize,
}

/// `[ins]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsSigmaConfig {
    /// North, east, down position (m).
    pub sigma_position_ned_m: [f64; 3],
    /// Roll, pitch, heading (deg).
    pub sigma_attitude_rph_deg: [f64; 3],
}

/// `[timing]`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingSigmaConfig {
    /// Clock time error of a return (s): `sqrt(g^T C g)` of the (t0, T) covariance.
    #[serde(default)]
    pub sigma_clock_time_s: f64,
    /// Attitude latency (s).
    #[serde(default)]
    pub sigma_attitude_latency_s: f64,
}

/// `[platform]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlatformConfig {
    /// IMU latitude (deg).
    pub lat_deg: f64,
    /// IMU longitude (deg).
    pub lon_deg: f64,
    /// IMU ellipsoidal height (m).
    pub h_m: f64,
    /// Roll, pitch, heading (deg).
    #[serde(default)]
    pub rph_deg: [f64; 3],
    /// Speed along the heading (m/s).
    #[serde(default)]
    pub speed_mps: f64,
    /// Body angular rate (deg/s, body axes).
    #[serde(default)]
    pub body_rate_deg_s: [f64; 3],
}

/// `[sensor]` of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySensorConfig {
    /// Lever arm (m, body frame).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (deg).
    #[serde(default)]
    pub boresight_deg: [f64; 3],
    /// Out-of-plane angle alpha0 (deg).
    #[serde(default)]
    pub alpha0_deg: f64,
}

/// `[points]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointsConfig {
    /// Height of the scanner's optical centre above the ground (m).
    pub scanner_height_m: f64,
    /// First and last range (m), both >= the scanner height.
    pub range_m: [f64; 2],
    /// Number of ranges, evenly spaced.
    pub count: usize,
}

fn default_samples() -> usize {
    4096
}
fn default_bootstrap() -> usize {
    100
}

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

impl SigmaSet {
    /// Table 1 of paper 003 (no timing terms; they come from `[timing]`).
    fn inputs(self, custom: Option<&UncertaintyConfig>) -> Option<UncertaintyInputs> {
        let table = |lever: f64, bore_deg: f64, range: f64, k: f64| UncertaintyInputs {
            sigma_lever_arm_b_m: Vector3::repeat(lever),
            sigma_boresight_rad: Vector3::repeat(bore_deg.to_radians()),
            sigma_alpha_rad: 0.0055f64.to_radians(),
            sigma_beta_rad: 0.0055f64.to_radians(),
            sigma_range_m: range,
            sigma_range_zero_m: k,
            clock_covariance_s2: Matrix2::zeros(),
            sigma_attitude_latency_s: 0.0,
        };
        match self {
            SigmaSet::Expected => Some(table(0.02, 0.02, 0.008, 0.01)),
            SigmaSet::Ideal => Some(table(0.004, 0.001, 0.003, 0.005)),
            SigmaSet::Custom => custom.map(UncertaintyConfig::inputs),
        }
    }
}

/// Reads a study file (TOML).
pub fn load_sensitivity(path: &Path) -> Result<SensitivityConfig> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let de = toml::Deserializer::parse(&text)
        .map_err(|e| Error::config(&name, "(syntax)", e.to_string()))?;
    let c: SensitivityConfig = serde_path_to_error::deserialize(de)
        .map_err(|e| Error::config(&name, e.path().to_string(), e.inner().message()))?;
    let mut c = c;
    validate(&c).map_err(|(key, problem)| Error::config(&name, key, problem))?;
    if let Some(sc) = c.scenario.as_mut() {
        let dir = path.parent().unwrap_or(Path::new("."));
        sc.file = dir.join(&sc.file);
    }
    Ok(c)
}

fn validate(c: &SensitivityConfig) -> std::result::Result<(), (&'static str, String)> {
    if c.sigma_set == SigmaSet::Custom {
        c.custom
            .as_ref()
            .ok_or((
                "custom",
                "sigma_set = \"custom\" needs a [custom] table".into(),
            ))?
            .check()?;
    }
    if !(64..=1 << 22).contains(&c.samples) || c.bootstrap == 1 {
        return Err((
            "samples",
            "samples must be in 64..=4194304 and bootstrap 0 or >= 2".into(),
        ));
    }
    let ins = c.ins.iter().flat_map(|i| {
        i.sigma_position_ned_m
            .iter()
            .chain(&i.sigma_attitude_rph_deg)
    });
    let t = &c.timing;
    let timing = [t.sigma_clock_time_s, t.sigma_attitude_latency_s];
    if !ins.chain(&timing).all(|s| s.is_finite() && *s >= 0.0) {
        return Err((
            "ins",
            "INS and timing sigmas must be finite and >= 0".into(),
        ));
    }
    match (&c.scenario, &c.platform, &c.sensor, &c.points) {
        (Some(sc), None, None, None) => validate_scenario(sc),
        (None, Some(_), Some(_), Some(p)) => {
            if c.ins.is_none() {
                return Err(("ins", "flat ground needs [ins]".into()));
            }
            validate_points(p)
        }
        _ => Err((
            "scenario",
            "give either [scenario] or all of [platform], [sensor], [points]".into(),
        )),
    }
}

fn validate_points(p: &PointsConfig) -> std::result::Result<(), (&'static str, String)> {
    let ok = p.scanner_height_m > 0.0
        && p.range_m[0] >= p.scanner_height_m
        && p.range_m[1] >= p.range_m[0]
        && p.range_m[1].is_finite()
        && p.count >= 1;
    if !ok {
        return Err((
            "points",
            "need 0 < scanner_height_m <= range_m[0] <= range_m[1] and count >= 1".into(),
        ));
    }
    Ok(())
}

fn validate_scenario(s: &ScenarioPointsConfig) -> std::result::Result<(), (&'static str, String)> {
    let ok = s.range_m[0] >= 0.0
        && s.range_m[1] > s.range_m[0]
        && s.range_m[1].is_finite()
        && s.count >= 1
        && s.duration_s.is_none_or(|d| d > 0.0 && d.is_finite());
    if !ok {
        return Err((
            "scenario",
            "need 0 <= range_m[0] < range_m[1], count >= 1 and duration_s > 0".into(),
        ));
    }
    Ok(())
}

/// Runs the study in `config_path` and writes into `out_dir`: `sensitivity_points.csv` (every
/// point, factor and output), `share_vs_range.csv` (plot data: first-order, total and linear
/// share of each factor against range), `sensitivity.json` (the [`SensitivityReport`]).
pub fn run_sensitivity(config_path: &Path, out_dir: &Path) -> Result<SensitivityReport> {
    let config = load_sensitivity(config_path)?;
    let mut inputs = vec![("config file".to_string(), config_path.to_path_buf())];
    if let Some(sc) = &config.scenario {
        inputs.push(("scenario.file".into(), sc.file.clone()));
    }
    let mut names = vec![
        "sensitivity_points.csv".to_string(),
        "share_vs_range.csv".into(),
        "sensitivity.json".into(),
    ];
    for o in OUTPUTS {
        names.push(format!("share_vs_range_{o}.png"));
        names.push(format!("share_vs_range_inputs_{o}.png"));
    }
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
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    let mut report = study(config)?;
    let points_csv = out_dir.join("sensitivity_points.csv");
    write_atomic(&points_csv, points_table(&report).as_bytes())?;
    let plot_csv = out_dir.join("share_vs_range.csv");
    write_atomic(&plot_csv, share_vs_range_table(&report).as_bytes())?;
    report.outputs = vec![points_csv, plot_csv];
    let plots = plot_share_against_range(&report, out_dir)?;
    report.outputs.extend(plots);
    let json = out_dir.join("sensitivity.json");
    report.outputs.push(json.clone());
    write_json(&json, &report)?;
    Ok(report)
}

/// Inputs drawn in the per-input plots: those whose linear share of the output reaches this.
const PLOT_INPUT_MIN_SHARE: f64 = 0.1;

/// The PNG plots of share against range, like paper 003's scatter plots, two per output
/// ([`OUTPUTS`]): `share_vs_range_<output>.png` with the six groups and
/// `share_vs_range_inputs_<output>.png` with the inputs whose linear share reaches 10% at
/// some point (at most 8, largest first). Each factor is drawn in one colour: its first-order
/// Sobol index at every point as markers, its analytic linear share as a line through the
/// points in range order.
fn plot_share_against_range(r: &SensitivityReport, out_dir: &Path) -> Result<Vec<PathBuf>> {
    let mut order: Vec<&PointResult> = r.points.iter().collect();
    order.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    let mut written = Vec::new();
    for (k, output) in OUTPUTS.iter().enumerate() {
        let series = |f: usize| -> [Vec<(f64, f64)>; 2] {
            let pts = |v: &dyn Fn(&FactorRow) -> f64| {
                order
                    .iter()
                    .map(|p| (p.range_m, v(&p.factors[f])))
                    .collect()
            };
            [
                pts(&|row| row.sobol[k].first),
                pts(&|row| row.linear_share[k]),
            ]
        };
        let groups: Vec<usize> = (N_INPUTS..N_INPUTS + Group::ALL.len()).collect();
        let mut inputs: Vec<(usize, f64)> = (0..N_INPUTS)
            .map(|i| {
                (
                    i,
                    order
                        .iter()
                        .map(|p| p.factors[i].linear_share[k])
                        .fold(0.0, f64::max),
                )
            })
            .filter(|&(_, m)| m >= PLOT_INPUT_MIN_SHARE)
            .collect();
        inputs.sort_by(|a, b| b.1.total_cmp(&a.1));
        let inputs: Vec<usize> = inputs.iter().take(PALETTE.len()).map(|&(i, _)| i).collect();
        for (what, factors, file) in [
            ("groups", groups, format!("share_vs_range_{output}.png")),
            (
                "inputs",
                inputs,
                format!("share_vs_range_inputs_{output}.png"),
            ),
        ] {
            if factors.is_empty() || order.is_empty() {
                continue;
            }
            let title =
                format!("Share of the {output} variance by {what} (S1 markers, linear lines)");
            let mut plot = Plot::new(&title, "range (m)", "share of variance")
                .size(1000, 700)
                .y_range(0.0, 1.0);
            for (c, &f) in factors.iter().enumerate() {
                let [first, linear] = series(f);
                let name = &order[0].factors[f].factor;
                plot = plot
                    .scatter(&format!("{name} S1"), &first)
                    .color(PALETTE[c % PALETTE.len()])
                    .line(&format!("{name} linear"), &linear)
                    .color(PALETTE[c % PALETTE.len()]);
            }
            let path = out_dir.join(file);
            plot.save_png(&path)?;
            written.push(path);
        }
    }
    Ok(written)
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

/// The geometry of a flat-ground study point at range `rho` (m): `beta = acos(height / rho)`.
pub fn flat_ground_point(
    p: &PlatformConfig,
    sensor: &StudySensorConfig,
    scanner_height_m: f64,
    rho: f64,
) -> PointGeometry {
    let g = Geodetic {
        lat_rad: p.lat_deg.to_radians(),
        lon_rad: p.lon_deg.to_radians(),
        h_m: p.h_m,
    };
    let [r, pitch, h] = p.rph_deg.map(f64::to_radians);
    let [bx, by, bz] = sensor.boresight_deg.map(f64::to_radians);
    let (sh, ch) = h.sin_cos();
    PointGeometry {
        r_e_m: geodetic_to_ecef(g),
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        r_b_to_n: r_zyx(r, pitch, h),
        v_n_mps: Vector3::new(ch, sh, 0.0) * p.speed_mps,
        omega_b_radps: Vector3::from(p.body_rate_deg_s.map(f64::to_radians)),
        lever_arm_b_m: sensor.lever_arm_b_m.into(),
        r_s_to_b: r_zyx(bx, by, bz),
        alpha_rad: sensor.alpha0_deg.to_radians(),
        beta_rad: (scanner_height_m / rho).min(1.0).acos(),
        range_m: rho,
        range_zero_m: 0.0,
    }
}

/// The returns of a simulated survey studied for `[scenario]`: the scenario is simulated into
/// a temporary directory, the returns are binned by range, and each chosen return gets the
/// pipeline's geometry: its time from the configured clock (SPEC 2), the pose of the
/// navigation solution (`trajectory.sbet`) at that time, the configured sensor, and the
/// SMRMSG sigmas at that time.
pub fn scenario_points(s: &ScenarioPointsConfig) -> Result<Vec<(PointGeometry, NavSigma)>> {
    let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("(temporary directory)"), e))?;
    let opts = SimOptions {
        duration_s: s.duration_s,
        ..SimOptions::default()
    };
    simulate(&s.file, dir.path(), &opts)?;
    let model = ScannerModel::new(&Scenario::load(&s.file)?);
    let traj = Trajectory::open(
        &dir.path().join(files::SBET),
        Some(&dir.path().join(files::SMRMSG)),
        TrajectoryOptions::default(),
    )?;
    let profiles = ProfileFile::open(&dir.path().join(files::PROFILES))?;
    let chosen = pick_by_range(&profiles, s.range_m, s.count);
    let mut poses = PoseCursor::new(&traj, 0.0, 0.0);
    let mut nav_sigmas = traj
        .sigma_cursor()
        .ok_or_else(|| Error::Invalid("the simulated survey has no SMRMSG".into()))?;
    let gap = |t: f64| Error::Invalid(format!("simulated return at {t} s has no pose or sigma"));
    let mut out = Vec::with_capacity(chosen.len());
    for i in chosen {
        let r = profiles.get(i);
        let t = if profiles.columns().time {
            model.clock.time_from_profile_tag(r.time_s, r.beta_rad)
        } else {
            model.clock.time_of(r.profile, r.beta_rad)
        };
        let pose = poses.at(t).map_err(|_| gap(t))?;
        let nav = nav_sigmas.at(t).map_err(|_| gap(t))?;
        let alpha = model.configured.alpha0_rad;
        let geom = PointGeometry::from_pose(&pose, &model.configured, alpha, r.beta_rad, r.range_m);
        out.push((geom, nav));
    }
    if out.is_empty() {
        return Err(Error::Invalid(format!(
            "{}: no simulated return between {} and {} m",
            s.file.display(),
            s.range_m[0],
            s.range_m[1]
        )));
    }
    Ok(out)
}

/// Indices (in file order) of the returns closest to the centres of `count` equal range bins
/// over `range_m`, one per non-empty bin.
fn pick_by_range(profiles: &ProfileFile, range_m: [f64; 2], count: usize) -> Vec<usize> {
    let width = (range_m[1] - range_m[0]) / count as f64;
    let mut best: Vec<Option<(f64, usize)>> = vec![None; count];
    for i in 0..profiles.len() {
        let rho = profiles.get(i).range_m;
        let bin = ((rho - range_m[0]) / width).floor();
        if !(rho > 0.0 && bin >= 0.0 && bin < count as f64) {
            continue;
        }
        let b = bin as usize;
        let off = (rho - range_m[0] - (b as f64 + 0.5) * width).abs();
        if best[b].is_none_or(|(o, _)| off < o) {
            best[b] = Some((off, i));
        }
    }
    let mut idx: Vec<usize> = best.into_iter().flatten().map(|(_, i)| i).collect();
    idx.sort_unstable();
    idx
}

/// The 1-sigma of every input for the study (model order): the sigma set, the INS sigmas of
/// `[ins]` if given, else `nav` (SMRMSG at the return), and `[timing]`.
pub fn study_sigmas(c: &SensitivityConfig, nav: Option<&NavSigma>) -> Result<[f64; N_INPUTS]> {
    let inputs = c
        .sigma_set
        .inputs(c.custom.as_ref())
        .ok_or_else(|| Error::Invalid("sigma_set = \"custom\" needs [custom]".into()))?;
    let nav = match (&c.ins, nav) {
        (Some(ins), _) => NavSigma {
            pos_ned_m: ins.sigma_position_ned_m.into(),
            att_rph_rad: ins.sigma_attitude_rph_deg.map(f64::to_radians).into(),
        },
        (None, Some(nav)) => *nav,
        (None, None) => return Err(Error::Invalid("no INS sigmas: [ins] is missing".into())),
    };
    let mut s = inputs.sigmas(&nav, [0.0, 0.0]);
    if c.sigma_set != SigmaSet::Custom {
        s[Input::Latency as usize] = c.timing.sigma_attitude_latency_s;
    }
    s[Input::ClockTime as usize] = s[Input::ClockTime as usize].hypot(c.timing.sigma_clock_time_s);
    Ok(s)
}

/// The study's points: flat ground, or the chosen returns of `[scenario]` with their SMRMSG
/// sigmas.
fn study_geometries(c: &SensitivityConfig) -> Result<Vec<(PointGeometry, Option<NavSigma>)>> {
    if let Some(sc) = &c.scenario {
        let pts = scenario_points(sc)?;
        return Ok(pts.into_iter().map(|(g, n)| (g, Some(n))).collect());
    }
    let (Some(platform), Some(sensor), Some(p)) = (&c.platform, &c.sensor, &c.points) else {
        return Err(Error::Invalid("no points: [points] is missing".into()));
    };
    let rho = |k: usize| {
        let w = if p.count > 1 {
            k as f64 / (p.count - 1) as f64
        } else {
            0.0
        };
        p.range_m[0] + w * (p.range_m[1] - p.range_m[0])
    };
    Ok((0..p.count)
        .map(|k| {
            let g = flat_ground_point(platform, sensor, p.scanner_height_m, rho(k));
            (g, None)
        })
        .collect())
}

/// `R_e^enu` at the nominal point of `geom`.
pub fn r_e_to_enu_at_point(geom: &PointGeometry) -> Matrix3<f64> {
    let g = ecef_to_geodetic(&geom.point_e(&[0.0; N_INPUTS]));
    r_enu_to_e(g.lat_rad, g.lon_rad).transpose()
}

/// The exact model as a Sobol model: input errors to the E, N, U displacement (m).
pub fn enu_error_model(geom: &PointGeometry) -> impl Fn(&[f64]) -> [f64; N_OUT] + Sync + '_ {
    let nominal = geom.point_e(&[0.0; N_INPUTS]);
    let rot = r_e_to_enu_at_point(geom);
    move |e: &[f64]| {
        let e: [f64; N_INPUTS] = e.try_into().expect("model input length");
        let d = rot * (geom.point_e(&e) - nominal);
        [d.x, d.y, d.z]
    }
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

/// Elevation of the beam of `geom` above the local horizontal at the scanner (rad).
fn beam_elevation_rad(geom: &PointGeometry) -> f64 {
    let x = geom.point_e(&[0.0; N_INPUTS]);
    let r_b_e = r_n_to_e(geom.lat_rad, geom.lon_rad) * geom.r_b_to_n;
    let scanner = geom.r_e_m + r_b_e * geom.lever_arm_b_m;
    let d = r_e_to_enu_at_point(geom) * (x - scanner);
    d.z.atan2(d.xy().norm())
}

fn point_result(
    geom: &PointGeometry,
    j: &super::model::Jacobian,
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

fn points_table(r: &SensitivityReport) -> String {
    let mut s = String::from(
        "range_m,beta_deg,factor,kind,output,first,first_conf,total,total_conf,linear_share\n",
    );
    for p in &r.points {
        for f in &p.factors {
            for (k, output) in OUTPUTS.iter().enumerate() {
                let i = &f.sobol[k];
                let _ = writeln!(
                    s,
                    "{:.3},{:.4},{},{},{output},{:.6},{:.6},{:.6},{:.6},{:.6}",
                    p.range_m,
                    p.beta_deg,
                    f.factor,
                    f.kind,
                    i.first,
                    i.first_conf,
                    i.total,
                    i.total_conf,
                    f.linear_share[k]
                );
            }
        }
    }
    s
}

/// Plot data: one row per range; for each factor and output, the first-order and total Sobol
/// indices and the linear share (`<factor>_<output>_first`, `_total`, `_linear`).
fn share_vs_range_table(r: &SensitivityReport) -> String {
    let Some(first) = r.points.first() else {
        return String::new();
    };
    let mut s = String::from("range_m,sigma_e_m,sigma_n_m,sigma_u_m");
    for f in &first.factors {
        for o in OUTPUTS {
            let _ = write!(s, ",{0}_{o}_first,{0}_{o}_total,{0}_{o}_linear", f.factor);
        }
    }
    s.push('\n');
    for p in &r.points {
        let [e, n, u, _] = p.sigma_enu_m;
        let _ = write!(s, "{:.3},{e:.6},{n:.6},{u:.6}", p.range_m);
        for f in &p.factors {
            for k in 0..OUTPUTS.len() {
                let i = &f.sobol[k];
                let _ = write!(s, ",{:.6},{:.6},{:.6}", i.first, i.total, f.linear_share[k]);
            }
        }
        s.push('\n');
    }
    s
}
