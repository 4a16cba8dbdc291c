//! Pipeline files (TOML): every stage's options, declared in one place.
//!
//! A pipeline file has one table per stage, in the order the data flows: `[inputs]` (read),
//! `[trajectory]`, `[sensor]`, `[time]` (scanner clock), `[latency]`, `[uncertainty]`
//! (optional per-point sigmas), `[output]` (georeference and write). Unknown keys are refused,
//! naming the key and the file (`io::config_file`). Paths are `ConfigPath`s: relative ones are
//! resolved against the pipeline file's folder when it is loaded.
//! Angles are given in degrees (keys ending `_deg`) and converted once, here.
//! docs/pipeline.md documents every option.

use crate::geo::ellipsoid::Geodetic;
use crate::geo::epsg::EpsgCrs;
use crate::io::config_file::{self, ConfigPath};
use crate::timing::MirrorDirection;
pub use crate::timing::TimeModel;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole pipeline definition.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineConfig {
    /// Input files.
    pub inputs: InputsConfig,
    /// Trajectory handling.
    #[serde(default)]
    pub trajectory: TrajectoryConfig,
    /// Scanner mounting and intrinsics.
    pub sensor: SensorConfig,
    /// Scanner time model.
    pub time: TimeConfig,
    /// IMU-to-scanner latencies.
    #[serde(default)]
    pub latency: LatencyConfig,
    /// Output LAS and report.
    pub output: OutputConfig,
    /// Per-point uncertainty (optional; needs `inputs.smrmsg`).
    #[serde(default)]
    pub uncertainty: Option<UncertaintyConfig>,
    /// Object-space time synchronisation (optional; runs before georeferencing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sync: Option<SyncConfig>,
    /// `kinescan diagnose` options (optional; command-line options win).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnose: Option<DiagnoseConfig>,
}

/// `[diagnose]`: what `kinescan diagnose` reads and how it turns returns on reference patches
/// into observations (docs/diagnosis.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiagnoseConfig {
    /// Reference planar patches (patch CSV).
    #[serde(default)]
    pub patches: Option<ConfigPath>,
    /// Output folder of the diagnosis.
    #[serde(default)]
    pub out: Option<ConfigPath>,
    /// A return further than this from its patch plane is not an observation (m).
    #[serde(default = "default_plane_tolerance_m")]
    pub plane_tolerance_m: f64,
    /// Returns closer than this to a patch edge are left out (m).
    #[serde(default = "default_edge_margin_m")]
    pub edge_margin_m: f64,
    /// A gap longer than this between two returns on one patch starts a new visit (s).
    #[serde(default = "default_visit_gap_s")]
    pub visit_gap_s: f64,
    /// A visit longer than this is split (s): one visit shares one navigation error.
    #[serde(default = "default_max_visit_s")]
    pub max_visit_s: f64,
    /// Correlation time of the INS position errors (s): their drift within a visit is added
    /// to each return's independent variance.
    #[serde(default = "default_nav_position_tau_s")]
    pub nav_position_tau_s: f64,
    /// Correlation time of the INS attitude errors (s).
    #[serde(default = "default_nav_attitude_tau_s")]
    pub nav_attitude_tau_s: f64,
    /// Visits with fewer returns are left out.
    #[serde(default = "default_min_per_visit")]
    pub min_per_visit: usize,
    /// At most this many returns of a visit are kept, evenly spaced in time.
    #[serde(default = "default_max_per_visit")]
    pub max_per_visit: usize,
    /// Seed of the split of the references into fit and held-out halves.
    #[serde(default = "default_diagnose_seed")]
    pub seed: u64,
    /// Family-wise significance level of the effect tests (Holm).
    #[serde(default = "default_diagnose_alpha")]
    pub alpha: f64,
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

fn default_plane_tolerance_m() -> f64 {
    0.15
}
fn default_edge_margin_m() -> f64 {
    0.1
}
fn default_visit_gap_s() -> f64 {
    1.0
}
fn default_max_visit_s() -> f64 {
    5.0
}
fn default_nav_position_tau_s() -> f64 {
    60.0
}
fn default_nav_attitude_tau_s() -> f64 {
    30.0
}
fn default_min_per_visit() -> usize {
    20
}
fn default_max_per_visit() -> usize {
    400
}
fn default_diagnose_seed() -> u64 {
    1
}
fn default_diagnose_alpha() -> f64 {
    0.01
}

/// `[sync]`: estimate t0 and T (and optionally the attitude latency) from surveyed sync
/// targets before georeferencing; the estimates replace `time.t0_s` / `time.period_s`
/// (docs/sync.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SyncConfig {
    /// Sync points (control-point CSV: target centres).
    pub points: ConfigPath,
    /// Target faces (patches CSV, ids as in `points`): needed by `method = "refined"`.
    #[serde(default)]
    pub targets: Option<ConfigPath>,
    /// Approximate t0 (s); default `time.t0_s`.
    #[serde(default)]
    pub t0_approx_s: Option<f64>,
    /// Approximate period (s); default `time.period_s`.
    #[serde(default)]
    pub period_approx_s: Option<f64>,
    /// Detection searches this far (s) either side of the predicted sighting.
    #[serde(default = "default_sync_window_s")]
    pub window_s: f64,
    /// `paper` (one observation per sighting) or `refined` (every target return).
    #[serde(default = "default_sync_method")]
    pub method: crate::sync::Method,
    /// Estimate the attitude latency jointly (refined only; reported only if constrained).
    #[serde(default)]
    pub estimate_latency: bool,
    /// Returns at or above this intensity may belong to a target.
    #[serde(default = "default_sync_min_intensity")]
    pub min_intensity: u16,
    /// Targets further than this from the scanner are not looked for (m).
    #[serde(default = "default_sync_max_range_m")]
    pub max_range_m: f64,
    /// Range noise of the scanner, 1 sigma (m).
    #[serde(default = "default_sync_sigma_range_m")]
    pub sigma_range_m: f64,
    /// Mirror and cone angle noise, 1 sigma (deg).
    #[serde(default = "default_sync_sigma_angle_deg")]
    pub sigma_angle_deg: f64,
    /// Sightings must span at least this long (s).
    #[serde(default = "default_sync_min_span_s")]
    pub min_span_s: f64,
    /// Write the diagnostic PNGs beside the report.
    #[serde(default = "yes")]
    pub plots: bool,
}

fn default_sync_window_s() -> f64 {
    1.0
}
fn default_sync_method() -> crate::sync::Method {
    crate::sync::Method::Paper
}
fn default_sync_min_intensity() -> u16 {
    60000
}
fn default_sync_max_range_m() -> f64 {
    30.0
}
fn default_sync_sigma_range_m() -> f64 {
    0.005
}
fn default_sync_sigma_angle_deg() -> f64 {
    0.002
}
fn default_sync_min_span_s() -> f64 {
    30.0
}

/// `[inputs]`: what is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputsConfig {
    /// Applanix SBET trajectory.
    pub sbet: ConfigPath,
    /// Applanix SMRMSG accuracy file (needed for uncertainty).
    #[serde(default)]
    pub smrmsg: Option<ConfigPath>,
    /// Scanner profile files, one per pass (binary `.ksprof` or CSV `.csv`). Pass `k` (from 0)
    /// gets point source id `first_point_source_id + k`.
    pub profiles: Vec<ConfigPath>,
    /// Point source id of the first profile file.
    #[serde(default = "one_u16")]
    pub first_point_source_id: u16,
    /// GPS week of the trajectory's seconds-of-week times. When given, LAS GPS time is
    /// adjusted standard GPS time; when absent, GPS week seconds (conventions §2).
    #[serde(default)]
    pub gps_week: Option<u32>,
}

/// `[trajectory]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Longest interval between trajectory records that may be interpolated across (s).
    #[serde(default = "default_max_gap_s")]
    pub max_gap_s: f64,
    /// Added to the SBET true heading (deg, clockwise from north; docs/conventions.md §3).
    #[serde(default)]
    pub heading_offset_deg: f64,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        TrajectoryConfig {
            max_gap_s: default_max_gap_s(),
            heading_offset_deg: 0.0,
        }
    }
}

impl TrajectoryConfig {
    /// The trajectory options (angles converted to radians).
    pub fn options(&self) -> crate::trajectory::TrajectoryOptions {
        crate::trajectory::TrajectoryOptions {
            max_gap_s: self.max_gap_s,
            heading_offset_rad: self.heading_offset_deg.to_radians(),
        }
    }
}

/// `[sensor]`: lever arm, boresight, scanner intrinsics and range limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Scanner optical centre relative to the IMU origin in the body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (bx, by, bz) (deg): `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    #[serde(default)]
    pub boresight_deg: [f64; 3],
    /// Out-of-plane beam angle alpha0 (deg), used when a profile file has no alpha column.
    #[serde(default)]
    pub alpha0_deg: f64,
    /// Range zero error K (m), added to every range.
    #[serde(default)]
    pub range_zero_m: f64,
    /// Range scale error S (ppm): `x_s = (1 + S 1e-6) (rho + K) u_s` (docs/conventions.md §3).
    #[serde(default)]
    pub range_scale_ppm: f64,
    /// Encoder offset dbeta (deg), added to the recorded mirror angle everywhere it is used:
    /// the beam direction and the time model's `f(beta)` (docs/conventions.md §2-3).
    #[serde(default)]
    pub encoder_offset_deg: f64,
    /// Returns closer than this are rejected (m).
    #[serde(default = "default_min_range_m")]
    pub min_range_m: f64,
    /// Returns further than this are rejected (m).
    #[serde(default = "default_max_range_m")]
    pub max_range_m: f64,
}

impl SensorConfig {
    /// The georeferencing sensor (angles converted to radians).
    pub fn sensor(&self) -> crate::georef::Sensor {
        crate::georef::Sensor::new(
            nalgebra::Vector3::from(self.lever_arm_b_m),
            nalgebra::Vector3::from(self.boresight_deg.map(f64::to_radians)),
            self.alpha0_deg.to_radians(),
            self.range_zero_m,
        )
        .with_range_scale_ppm(self.range_scale_ppm)
        .with_encoder_offset_rad(self.encoder_offset_deg.to_radians())
    }
}

/// `[time]`: the scanner clock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeConfig {
    /// Which time model.
    #[serde(default = "default_time_model")]
    pub model: TimeModel,
    /// GPS time of the start of profile 0 (s); required by the software model.
    #[serde(default)]
    pub t0_s: Option<f64>,
    /// Mirror period T (s).
    pub period_s: f64,
    /// Mirror angle at which the profile counter increments (deg).
    #[serde(default)]
    pub beta_start_deg: f64,
    /// Sense of mirror rotation.
    #[serde(default = "default_direction")]
    pub direction: MirrorDirection,
}

impl TimeConfig {
    /// The mirror geometry (radians) for RECORDED mirror angles, with the encoder offset
    /// dbeta (deg, `sensor.encoder_offset_deg`) applied: `f(beta + dbeta)` is the fraction of
    /// the recorded `beta` with the profile start moved to `beta_start - dbeta`.
    pub fn mirror(&self, encoder_offset_deg: f64) -> crate::timing::Mirror {
        crate::timing::Mirror {
            beta_start_rad: (self.beta_start_deg - encoder_offset_deg).to_radians(),
            direction: self.direction,
        }
    }
}

/// `[latency]` (conventions §2 signs).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LatencyConfig {
    /// Attitude latency tau (s): attitude is evaluated at `t + tau`.
    #[serde(default)]
    pub attitude_s: f64,
    /// Position latency (s): position is evaluated at `t + position_s`.
    #[serde(default)]
    pub position_s: f64,
}

/// Output mapping frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind", deny_unknown_fields)]
pub enum FrameConfig {
    /// UTM with ellipsoidal height; zone from the trajectory's first record unless given.
    Utm {
        /// Zone 1-60 (automatic when absent).
        #[serde(default)]
        zone: Option<u8>,
        /// Northern hemisphere (automatic when absent).
        #[serde(default)]
        north: Option<bool>,
    },
    /// Earth-centred, Earth-fixed WGS84.
    Ecef,
    /// Local East-North-Up about an origin (degrees, metres).
    Enu {
        /// Origin latitude (deg).
        lat_deg: f64,
        /// Origin longitude (deg).
        lon_deg: f64,
        /// Origin ellipsoidal height (m).
        h_m: f64,
    },
    /// A projected CRS by EPSG code (WGS84 or a datum with a stated Helmert to it), with
    /// WGS84 ellipsoidal height; see `geo::epsg`.
    Epsg {
        /// EPSG code, e.g. 2154 (RGF93 v1 / Lambert-93).
        code: u32,
    },
}

impl FrameConfig {
    /// Origin of a local frame as geodetic radians.
    pub fn enu_origin(&self) -> Option<Geodetic> {
        match *self {
            FrameConfig::Enu {
                lat_deg,
                lon_deg,
                h_m,
            } => Some(Geodetic {
                lat_rad: lat_deg.to_radians(),
                lon_rad: lon_deg.to_radians(),
                h_m,
            }),
            _ => None,
        }
    }
}

/// How the output is split into files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SplitMode {
    /// One LAS file: `path`.
    None,
    /// One file per profile file: `<stem>_<profile file stem>.las`.
    PerInput,
    /// At most `max_points_per_file` points each: `<stem>_0001.las`, `<stem>_0002.las`, ...
    MaxPoints,
}

/// What happens to a return that cannot be georeferenced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Strictness {
    /// Count it as rejected with its reason and go on.
    Count,
    /// Stop with an error naming the file and record.
    Fail,
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Output LAS path (the base name when split).
    pub las: ConfigPath,
    /// Run report path (JSON); default: `<las stem>.report.json` beside the LAS.
    #[serde(default)]
    pub report: Option<ConfigPath>,
    /// Mapping frame.
    #[serde(default = "default_frame")]
    pub frame: FrameConfig,
    /// Coordinate scale (m per integer step); the quantisation error is half of it.
    #[serde(default = "default_scale_m")]
    pub scale_m: f64,
    /// LAS coordinate offset X, Y, Z in the map frame (m); default: the map coordinates of the
    /// first trajectory record rounded to 1 km. Points must lie within `2^31 * scale_m` of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_m: Option<[f64; 3]>,
    /// Accept a run that writes no point (default: such a run fails and keeps the old output).
    #[serde(default)]
    pub allow_empty: bool,
    /// File splitting.
    #[serde(default = "default_split")]
    pub split: SplitMode,
    /// Maximum points per file with `split = "max_points"`.
    #[serde(default)]
    pub max_points_per_file: Option<u64>,
    /// Per-return problems: counted (`count`) or fatal (`fail`).
    #[serde(default = "default_strictness")]
    pub strictness: Strictness,
    /// Write the measured range (m) as an extra dimension `range`.
    #[serde(default = "yes")]
    pub range_dimension: bool,
    /// Write each point's 0-based record index in its profile file as the extra dimension
    /// `return_index` (float64, exact to 2^53), to trace a point back to its raw return.
    #[serde(default)]
    pub return_index_dimension: bool,
}

/// `[uncertainty]`: 1-sigma of the inputs not in the SMRMSG file (conventions §5). Every sigma must be
/// given (0 is allowed and means "exact"), so no error source is dropped silently.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyConfig {
    /// Lever arm x, y, z (m).
    pub sigma_lever_arm_b_m: [f64; 3],
    /// Boresight angles bx, by, bz (deg).
    pub sigma_boresight_deg: [f64; 3],
    /// Out-of-plane angle alpha (deg).
    pub sigma_alpha_deg: f64,
    /// Mirror angle encoder beta (deg).
    pub sigma_beta_deg: f64,
    /// Range noise (m).
    pub sigma_range_m: f64,
    /// Range zero error K (m).
    pub sigma_range_zero_m: f64,
    /// Covariance of the clock parameters (t0, T) (s^2), `[[var_t0, cov], [cov, var_T]]`.
    pub clock_covariance_s2: [[f64; 2]; 2],
    /// Attitude latency tau (s).
    pub sigma_attitude_latency_s: f64,
    /// Also write `thu95` and `tvu95` (95% horizontal and vertical, m). Default false: they
    /// follow from `sigma_x/y/z`, and cost 8 bytes a point.
    #[serde(default)]
    pub write_95: bool,
    /// Also write the per-group variance shares `share_<group>` (fractions, one scaled byte
    /// each). Default false: 6 bytes a point.
    #[serde(default)]
    pub write_shares: bool,
}

impl UncertaintyConfig {
    /// The sigmas in SI units (degrees converted to radians).
    pub fn inputs(&self) -> crate::uncertainty::UncertaintyInputs {
        let c = self.clock_covariance_s2;
        crate::uncertainty::UncertaintyInputs {
            sigma_lever_arm_b_m: self.sigma_lever_arm_b_m.into(),
            sigma_boresight_rad: self.sigma_boresight_deg.map(f64::to_radians).into(),
            sigma_alpha_rad: self.sigma_alpha_deg.to_radians(),
            sigma_beta_rad: self.sigma_beta_deg.to_radians(),
            sigma_range_m: self.sigma_range_m,
            sigma_range_zero_m: self.sigma_range_zero_m,
            clock_covariance_s2: nalgebra::Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]),
            sigma_attitude_latency_s: self.sigma_attitude_latency_s,
        }
    }

    /// Checks sigmas are finite and >= 0 and the clock covariance symmetric positive
    /// semi-definite; `Err(key, problem)`.
    pub fn check(&self) -> std::result::Result<(), (&'static str, String)> {
        let scalars = [
            self.sigma_alpha_deg,
            self.sigma_beta_deg,
            self.sigma_range_m,
            self.sigma_range_zero_m,
            self.sigma_attitude_latency_s,
        ];
        let mut sigmas = self
            .sigma_lever_arm_b_m
            .iter()
            .chain(&self.sigma_boresight_deg)
            .chain(&scalars);
        if !sigmas.all(|s| s.is_finite() && *s >= 0.0) {
            return Err(("uncertainty", "every sigma must be finite and >= 0".into()));
        }
        let c = self.clock_covariance_s2;
        let psd = c.iter().flatten().all(|v| v.is_finite())
            && c[0][1] == c[1][0]
            && c[0][0] >= 0.0
            && c[1][1] >= 0.0
            && c[0][0] * c[1][1] >= c[0][1] * c[0][1];
        if !psd {
            let msg = format!("must be symmetric positive semi-definite, got {c:?}");
            return Err(("uncertainty.clock_covariance_s2", msg));
        }
        Ok(())
    }
}

fn one_u16() -> u16 {
    1
}
fn yes() -> bool {
    true
}
fn default_max_gap_s() -> f64 {
    crate::trajectory::TrajectoryOptions::default().max_gap_s
}
fn default_min_range_m() -> f64 {
    0.5
}
fn default_max_range_m() -> f64 {
    1000.0
}
fn default_time_model() -> TimeModel {
    TimeModel::Software
}
fn default_direction() -> MirrorDirection {
    MirrorDirection::Increasing
}
fn default_frame() -> FrameConfig {
    FrameConfig::Utm {
        zone: None,
        north: None,
    }
}
fn default_scale_m() -> f64 {
    1e-4
}
fn default_split() -> SplitMode {
    SplitMode::None
}
fn default_strictness() -> Strictness {
    Strictness::Count
}

/// A pipeline file loaded with its overrides applied and paths resolved.
#[derive(Debug, Clone)]
pub struct LoadedPipeline {
    /// Pipeline file.
    pub path: PathBuf,
    /// The configuration, every path absolute (resolved against the pipeline file's folder).
    pub config: PipelineConfig,
    /// `--set` overrides applied, as given.
    pub overrides: Vec<String>,
}

/// Reads `path`, applies `KEY=VALUE` overrides (`io::config_file`), validates and resolves
/// relative paths against the file's folder.
pub fn load(path: &Path, overrides: &[String]) -> Result<LoadedPipeline> {
    let parsed = config_file::load::<PipelineConfig>(path, overrides)?;
    validate(&parsed.value, &parsed.source)?;
    Ok(LoadedPipeline {
        path: path.to_path_buf(),
        config: parsed.value,
        overrides: overrides.to_vec(),
    })
}

fn validate(c: &PipelineConfig, source: &str) -> Result<()> {
    let bad = |key: &str, problem: String| Err(Error::config(source, key, problem));
    if c.inputs.profiles.is_empty() {
        return bad(
            "inputs.profiles",
            "at least one profile file is required".into(),
        );
    }
    let finite_pos = |v: f64| v.is_finite() && v > 0.0;
    if !finite_pos(c.trajectory.max_gap_s) {
        return bad(
            "trajectory.max_gap_s",
            format!("must be > 0, got {}", c.trajectory.max_gap_s),
        );
    }
    let s = &c.sensor;
    let all_finite = s
        .lever_arm_b_m
        .iter()
        .chain(&s.boresight_deg)
        .all(|v| v.is_finite());
    if !all_finite || !s.alpha0_deg.is_finite() || !s.range_zero_m.is_finite() {
        return bad(
            "sensor",
            "lever arm, boresight, alpha0 and range zero must be finite".into(),
        );
    }
    if !(s.min_range_m >= 0.0 && s.max_range_m > s.min_range_m && s.max_range_m.is_finite()) {
        return bad(
            "sensor.max_range_m",
            format!(
                "need 0 <= min_range_m < max_range_m, got {} and {}",
                s.min_range_m, s.max_range_m
            ),
        );
    }
    let t = &c.time;
    if !(MIN_PERIOD_S..=1.0).contains(&t.period_s) {
        return bad(
            "time.period_s",
            format!("must be in [{MIN_PERIOD_S}, 1] s, got {:?}", t.period_s),
        );
    }
    if let Some(t0) = t.t0_s.filter(|v| !v.is_finite()) {
        return bad("time.t0_s", format!("must be a finite number, got {t0}"));
    }
    if let Some(sy) = &c.sync {
        validate_sync(sy, t, source)?;
    }
    if let Some(d) = &c.diagnose {
        validate_diagnose(d, source)?;
    }
    if t.model == TimeModel::Software && !t.t0_s.is_some_and(f64::is_finite) && c.sync.is_none() {
        return bad(
            "time.t0_s",
            "the software time model needs t0_s (or a sync stage)".into(),
        );
    }
    let s = &c.sensor;
    for (key, v) in [
        ("sensor.range_scale_ppm", s.range_scale_ppm),
        ("sensor.encoder_offset_deg", s.encoder_offset_deg),
        (
            "trajectory.heading_offset_deg",
            c.trajectory.heading_offset_deg,
        ),
    ] {
        if !v.is_finite() {
            return bad(key, format!("must be a finite number, got {v}"));
        }
    }
    let l = &c.latency;
    if !(l.attitude_s.abs() < 1.0 && l.position_s.abs() < 1.0) {
        return bad(
            "latency",
            "latencies must be finite and below 1 s in magnitude".into(),
        );
    }
    let o = &c.output;
    if !(o.scale_m > 0.0 && o.scale_m <= 1e-3) {
        return bad(
            "output.scale_m",
            format!(
                "must be in (0, 0.001] m (quantisation <= 0.5 mm), got {}",
                o.scale_m
            ),
        );
    }
    if o.offset_m.is_some_and(|v| !v.iter().all(|x| x.is_finite())) {
        return bad(
            "output.offset_m",
            format!("must be three finite numbers, got {:?}", o.offset_m),
        );
    }
    if o.split == SplitMode::MaxPoints && o.max_points_per_file.is_none_or(|n| n == 0) {
        return bad(
            "output.max_points_per_file",
            "split = \"max_points\" needs max_points_per_file > 0".into(),
        );
    }
    if let Some(u) = &c.uncertainty {
        u.check().or_else(|(key, problem)| bad(key, problem))?;
        if c.inputs.smrmsg.is_none() {
            return bad(
                "inputs.smrmsg",
                "[uncertainty] needs the SMRMSG file (INS position and attitude sigmas)".into(),
            );
        }
    }
    validate_frame(&o.frame, source)
}

/// Shortest mirror period accepted (s): a 10 kHz mirror, far beyond any profile scanner;
/// anything shorter is a typing error (and would make profile times meaningless).
pub const MIN_PERIOD_S: f64 = 1e-4;

fn validate_frame(frame: &FrameConfig, source: &str) -> Result<()> {
    let bad = |key: &str, problem: String| Err(Error::config(source, key, problem));
    match *frame {
        FrameConfig::Utm { zone: Some(z), .. } if !(1..=60).contains(&z) => bad(
            "output.frame.zone",
            format!("UTM zone must be 1..60, got {z}"),
        ),
        FrameConfig::Enu {
            lat_deg,
            lon_deg,
            h_m,
        } => {
            if !(-90.0..=90.0).contains(&lat_deg) {
                return bad(
                    "output.frame.lat_deg",
                    format!("must be in [-90, 90] deg, got {lat_deg}"),
                );
            }
            if !(-180.0..=180.0).contains(&lon_deg) {
                return bad(
                    "output.frame.lon_deg",
                    format!("must be in [-180, 180] deg, got {lon_deg}"),
                );
            }
            if !h_m.is_finite() {
                return bad("output.frame.h_m", format!("must be finite, got {h_m}"));
            }
            Ok(())
        }
        FrameConfig::Epsg { code } => match EpsgCrs::get(code) {
            Ok(_) => Ok(()),
            Err(why) => bad("output.frame.code", why),
        },
        _ => Ok(()),
    }
}

fn validate_sync(sy: &SyncConfig, t: &TimeConfig, source: &str) -> Result<()> {
    let bad = |key: &str, problem: String| Err(Error::config(source, key, problem));
    if t.model != TimeModel::Software {
        return bad(
            "sync",
            "object-space sync estimates the software clock: needs time.model = \"software\""
                .into(),
        );
    }
    if !sy.t0_approx_s.or(t.t0_s).is_some_and(f64::is_finite) {
        return bad(
            "sync.t0_approx_s",
            "an approximate t0 is needed (sync.t0_approx_s or time.t0_s)".into(),
        );
    }
    let pos = |v: f64| v.is_finite() && v > 0.0;
    let checks = [
        ("sync.window_s", sy.window_s),
        ("sync.max_range_m", sy.max_range_m),
        ("sync.sigma_range_m", sy.sigma_range_m),
        ("sync.sigma_angle_deg", sy.sigma_angle_deg),
        ("sync.min_span_s", sy.min_span_s),
        (
            "sync.period_approx_s",
            sy.period_approx_s.unwrap_or(t.period_s),
        ),
    ];
    for (key, v) in checks {
        if !pos(v) {
            return bad(key, format!("must be a finite number > 0, got {v}"));
        }
    }
    if sy.estimate_latency && sy.method == crate::sync::Method::Paper {
        return bad(
            "sync.estimate_latency",
            "the latency is estimated by method = \"refined\" only".into(),
        );
    }
    Ok(())
}

fn validate_diagnose(d: &DiagnoseConfig, source: &str) -> Result<()> {
    let bad = |key: &str, problem: String| Err(Error::config(source, key, problem));
    let positive = [
        ("diagnose.plane_tolerance_m", d.plane_tolerance_m),
        ("diagnose.visit_gap_s", d.visit_gap_s),
        ("diagnose.max_visit_s", d.max_visit_s),
        ("diagnose.nav_position_tau_s", d.nav_position_tau_s),
        ("diagnose.nav_attitude_tau_s", d.nav_attitude_tau_s),
    ];
    for (key, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return bad(key, format!("must be a finite number > 0, got {v}"));
        }
    }
    if !(d.edge_margin_m.is_finite() && d.edge_margin_m >= 0.0) {
        let v = d.edge_margin_m;
        return bad("diagnose.edge_margin_m", format!("must be >= 0, got {v}"));
    }
    if d.min_per_visit < 2 || d.max_per_visit < d.min_per_visit {
        let problem = format!(
            "need 2 <= min_per_visit <= max_per_visit, got {} and {}",
            d.min_per_visit, d.max_per_visit
        );
        return bad("diagnose.max_per_visit", problem);
    }
    if !(d.alpha > 0.0 && d.alpha < 0.5) {
        let v = d.alpha;
        return bad("diagnose.alpha", format!("must be in (0, 0.5), got {v}"));
    }
    Ok(())
}
