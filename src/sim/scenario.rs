//! Scenario files: the TOML description of a simulated survey, read strictly (unknown keys and
//! impossible values are refused with the dotted key named). Keys ending `_deg` are degrees
//! and are converted once here; everything else is SI. Every key, unit and default is listed
//! in docs/simulator.md.

use super::checker::Checker;
use super::effects::Effects;
use crate::io::config_file;
use crate::Result;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A whole scenario, as read from its TOML file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Scenario name (recorded in the truth file).
    pub name: String,
    /// Master seed of every random stream.
    pub seed: u64,
    /// Length of the trajectory (s).
    pub duration_s: f64,
    /// GPS seconds of the week at the start of the trajectory (s).
    #[serde(default = "default_start_time")]
    pub start_time_s: f64,
    /// GPS week number, when the survey is to be tied to an absolute date.
    #[serde(default)]
    pub gps_week: Option<u32>,
    /// Origin of the local East-North-Up scene frame.
    pub origin: OriginCfg,
    /// Scene generator parameters.
    pub scene: SceneCfg,
    /// Route and speed profile.
    pub route: RouteCfg,
    /// Vehicle body dynamics and true-trajectory sampling.
    #[serde(default)]
    pub vehicle: VehicleCfg,
    /// Profile scanner.
    pub scanner: ScannerCfg,
    /// Random errors of the navigation solution.
    #[serde(default)]
    pub nav_errors: NavErrorCfg,
    /// Injected systematic effects (all off by default).
    #[serde(default)]
    pub effects: Effects,
    /// Optional outputs.
    #[serde(default)]
    pub output: OutputCfg,
}

fn default_start_time() -> f64 {
    345_600.0
}

/// Geodetic origin of the scene frame (WGS84, ellipsoidal height).
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OriginCfg {
    /// Latitude (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Ellipsoidal height of the scene's ground at the origin (m).
    pub h_m: f64,
}

/// Which scene generator to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// A grid of building blocks separated by streets.
    Streets,
    /// One large open paved area ringed by buildings, with lamp posts and parked cars.
    ParkingLot,
}

/// Procedural scene parameters (scene frame: local ENU about the origin, metres).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneCfg {
    /// Generator.
    pub kind: SceneKind,
    /// Number of blocks along East / North (streets) or 1 x 1 (parking lot area).
    pub blocks: [u32; 2],
    /// Block size along East and North (m); for a parking lot, the open area's size.
    pub block_size_m: [f64; 2],
    /// Street width, kerb to kerb (m).
    pub street_width_m: f64,
    /// Sidewalk width (m).
    pub sidewalk_width_m: f64,
    /// Kerb height above the road (m).
    pub curb_height_m: f64,
    /// Ground slope dz/dEast and dz/dNorth (dimensionless).
    pub ground_slope: [f64; 2],
    /// Building height range (m).
    pub building_height_m: [f64; 2],
    /// Building frontage length range (m).
    pub building_length_m: [f64; 2],
    /// Largest yaw of a facade away from its street (deg).
    pub facade_max_skew_deg: f64,
    /// Pole (lamp post) spacing along sidewalks (m); 0 = none.
    pub pole_spacing_m: f64,
    /// Pole radius and height (m).
    pub pole_radius_m: f64,
    /// Pole height (m).
    pub pole_height_m: f64,
    /// Spherical targets per street side per block; 0 = none.
    pub spheres_per_side: u32,
    /// Spherical target radius (m).
    pub sphere_radius_m: f64,
    /// Flat retro-reflective sync targets per street side per block; 0 = none.
    pub sync_targets_per_side: u32,
    /// Trees per street side per block (porous sphere crowns on trunks); 0 = none.
    pub trees_per_side: u32,
    /// Probability that a ray passes through a tree crown.
    pub tree_porosity: f64,
    /// Parked cars per row (parking lot only).
    pub cars_per_row: u32,
    /// Spatial index cell size (m).
    pub grid_cell_m: f64,
    /// Diffuse reflectance of ground, facades, poles, spheres, trees (0..1).
    pub reflectance: [f64; 5],
    /// Reflectance of retro-reflective sync targets (>> 1 saturates the intensity).
    pub sync_reflectance: f64,
    /// Yaw of every sync target's face about the vertical, away from facing its street (deg).
    pub sync_target_yaw_deg: f64,
    /// When > 0, an unlisted retro-reflective plate (a sign, not a sync target) stands this
    /// far along the street beyond the first sync target (m).
    pub decoy_offset_m: f64,
}

impl Default for SceneCfg {
    fn default() -> Self {
        SceneCfg {
            kind: SceneKind::Streets,
            blocks: [2, 2],
            block_size_m: [100.0, 80.0],
            street_width_m: 12.0,
            sidewalk_width_m: 3.0,
            curb_height_m: 0.15,
            ground_slope: [0.0, 0.0],
            building_height_m: [8.0, 25.0],
            building_length_m: [12.0, 30.0],
            facade_max_skew_deg: 8.0,
            pole_spacing_m: 25.0,
            pole_radius_m: 0.1,
            pole_height_m: 6.0,
            spheres_per_side: 1,
            sphere_radius_m: 0.25,
            sync_targets_per_side: 1,
            trees_per_side: 0,
            tree_porosity: 0.4,
            cars_per_row: 10,
            grid_cell_m: 8.0,
            reflectance: [0.2, 0.5, 0.4, 0.8, 0.3],
            sync_reflectance: 50.0,
            sync_target_yaw_deg: 0.0,
            decoy_offset_m: 0.0,
        }
    }
}

/// A stop on the route.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct StopCfg {
    /// Distance along one lap where the vehicle stands (m).
    pub at_m: f64,
    /// How long it stands (s).
    pub dwell_s: f64,
}

/// Route: a closed loop through waypoints (scene frame), driven lap after lap.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RouteCfg {
    /// Waypoints East, North (m); the loop closes back to the first. Corners are rounded.
    pub waypoints_m: Vec<[f64; 2]>,
    /// Corner radius (m).
    pub corner_radius_m: f64,
    /// Top speed on straights (m/s), at most 20.
    pub max_speed_mps: f64,
    /// Largest lateral acceleration in corners (m/s^2).
    pub max_lateral_acc_mps2: f64,
    /// Largest longitudinal acceleration (m/s^2).
    pub max_acc_mps2: f64,
    /// Largest braking deceleration (m/s^2).
    pub max_decel_mps2: f64,
    /// Stops within each lap (besides the start/end of every lap).
    pub stops: Vec<StopCfg>,
    /// Standing time at the start of every lap (s).
    pub lap_start_dwell_s: f64,
}

impl Default for RouteCfg {
    fn default() -> Self {
        RouteCfg {
            waypoints_m: Vec::new(),
            corner_radius_m: 8.0,
            max_speed_mps: 12.0,
            max_lateral_acc_mps2: 2.5,
            max_acc_mps2: 1.5,
            max_decel_mps2: 2.5,
            stops: Vec::new(),
            lap_start_dwell_s: 2.0,
        }
    }
}

/// Vehicle body dynamics.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct VehicleCfg {
    /// IMU origin height above the road (m).
    pub imu_height_m: f64,
    /// Lateral offset of the driving line from the street centre line, to the right (m).
    pub lane_offset_m: f64,
    /// Body roll per lateral acceleration (deg per m/s^2), rolling out of the turn.
    pub roll_per_lateral_acc_deg: f64,
    /// Body pitch per longitudinal acceleration (deg per m/s^2), nose down when braking.
    pub pitch_per_longitudinal_acc_deg: f64,
    /// Time constant of the body's roll/pitch response (s).
    pub body_time_constant_s: f64,
    /// Road vibration amplitude at top speed: roll, pitch (deg).
    pub vibration_deg: [f64; 2],
    /// Road vibration vertical amplitude at top speed (m).
    pub vibration_vertical_m: f64,
    /// True trajectory (and SBET) sampling rate (Hz), >= 200.
    pub nav_rate_hz: f64,
}

impl Default for VehicleCfg {
    fn default() -> Self {
        VehicleCfg {
            imu_height_m: 2.0,
            lane_offset_m: 2.0,
            roll_per_lateral_acc_deg: 0.5,
            pitch_per_longitudinal_acc_deg: 0.4,
            body_time_constant_s: 0.3,
            vibration_deg: [0.02, 0.02],
            vibration_vertical_m: 0.003,
            nav_rate_hz: 200.0,
        }
    }
}

/// Profile scanner: mounting, mirror, clock and measurement noise.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScannerCfg {
    /// Mirror period T (s), 1/250 .. 1/33.
    pub period_s: f64,
    /// Returns per profile (mirror turn).
    pub points_per_profile: u32,
    /// Mirror angle where the profile counter increments (deg).
    pub beta_start_deg: f64,
    /// +1 when beta increases with time, -1 otherwise.
    pub direction: i32,
    /// Out-of-plane (cone) angle alpha0 (deg).
    pub alpha0_deg: f64,
    /// Longest range measured (m).
    pub max_range_m: f64,
    /// Shortest range measured (m).
    pub min_range_m: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Mirror (beta) and cone (alpha) angle noise, 1 sigma (deg).
    pub sigma_angle_deg: f64,
    /// Probability that a return is lost at random.
    pub dropout_probability: f64,
    /// Range at which intensity stops growing as range shrinks (m).
    pub intensity_ref_range_m: f64,
    /// Lever arm, scanner optical centre relative to the IMU, body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Boresight angles (bx, by, bz) of `R_s^b = Rz(bz) Ry(by) Rx(bx)` (deg).
    pub boresight_deg: [f64; 3],
    /// Range zero error K of the scanner (m), known to the pipeline.
    pub range_zero_m: f64,
    /// Start of profile 0 relative to the start of the trajectory (s).
    pub t0_offset_s: f64,
    /// Stop scanning this long before the trajectory ends (s).
    pub end_margin_s: f64,
    /// Write each profile's PPS-derived GPS start time in the returns' time column.
    pub pps_time_tags: bool,
}

impl Default for ScannerCfg {
    fn default() -> Self {
        ScannerCfg {
            period_s: 0.01,
            points_per_profile: 1000,
            beta_start_deg: 0.0,
            direction: 1,
            alpha0_deg: 0.0,
            max_range_m: 80.0,
            min_range_m: 0.5,
            sigma_range_m: 0.0,
            sigma_angle_deg: 0.0,
            dropout_probability: 0.0,
            intensity_ref_range_m: 10.0,
            lever_arm_b_m: [-0.5, 0.0, -0.4],
            boresight_deg: [0.0, 0.0, 0.0],
            range_zero_m: 0.0,
            t0_offset_s: 1.0,
            end_margin_s: 1.0,
            pps_time_tags: false,
        }
    }
}

/// Random navigation errors: first-order Gauss-Markov processes per axis.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct NavErrorCfg {
    /// Position error sigma north, east, down (m).
    pub position_sigma_m: [f64; 3],
    /// Position error correlation time (s).
    pub position_tau_s: f64,
    /// Attitude error sigma roll, pitch, heading (deg).
    pub attitude_sigma_deg: [f64; 3],
    /// Attitude error correlation time (s).
    pub attitude_tau_s: f64,
    /// GNSS outages [start, end] relative to the start of the trajectory (s).
    pub outages_s: Vec<[f64; 2]>,
    /// Factor on every sigma inside outages.
    pub outage_sigma_factor: f64,
    /// Velocity RMS written to SMRMSG (m/s); velocities carry no injected error.
    pub velocity_sigma_mps: f64,
    /// SMRMSG record rate (Hz); must divide the nav rate.
    pub smrmsg_rate_hz: f64,
}

impl Default for NavErrorCfg {
    fn default() -> Self {
        NavErrorCfg {
            position_sigma_m: [0.0; 3],
            position_tau_s: 60.0,
            attitude_sigma_deg: [0.0; 3],
            attitude_tau_s: 30.0,
            outages_s: Vec::new(),
            outage_sigma_factor: 5.0,
            velocity_sigma_mps: 0.01,
            smrmsg_rate_hz: 10.0,
        }
    }
}

/// Optional outputs.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputCfg {
    /// Also write profiles as CSV (conventions §6); large.
    pub profiles_csv: bool,
    /// Write the per-return truth sidecar (24 bytes per return).
    pub truth_points: bool,
    /// Write the true trajectory as `truth.sbet`.
    pub truth_sbet: bool,
    /// A facade or ground patch is listed once it has this many returns.
    pub patch_min_returns: u32,
}

impl Default for OutputCfg {
    fn default() -> Self {
        OutputCfg {
            profiles_csv: false,
            truth_points: true,
            truth_sbet: true,
            patch_min_returns: 200,
        }
    }
}

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario> {
        let parsed = config_file::load::<Scenario>(path, &[])?;
        parsed.value.validate(&parsed.source)?;
        Ok(parsed.value)
    }

    /// Parses and validates scenario text; `source` names it in errors.
    pub fn parse(text: &str, source: &str) -> Result<Scenario> {
        let sc: Scenario = config_file::parse(text, source, Path::new("."), &[])?.value;
        sc.validate(source)?;
        Ok(sc)
    }

    /// Checks every value's range; `src` names the scenario in errors.
    pub(crate) fn validate(&self, src: &str) -> Result<()> {
        let mut c = Checker::new(src);
        c.pos("duration_s", self.duration_s);
        c.range("start_time_s", self.start_time_s, 0.0, 604_800.0);
        c.range("origin.lat_deg", self.origin.lat_deg, -89.0, 89.0);
        c.range("origin.lon_deg", self.origin.lon_deg, -180.0, 180.0);
        c.range("origin.h_m", self.origin.h_m, -1000.0, 9000.0);
        self.scene.check(&mut c);
        self.route.check(&mut c);
        self.vehicle.check(&mut c);
        self.scanner.check(&mut c);
        self.nav_errors.check(&mut c, self.vehicle.nav_rate_hz);
        self.effects.check(&mut c);
        if let Some(q) = self.effects.clock_drift_quadratic_per_s {
            c.test(
                "effects.clock_drift_quadratic_per_s",
                (2.0 * q * self.duration_s).abs() < 0.1,
                || {
                    format!(
                        "{q} 1/s over duration_s {} s would make the scanner clock run backwards",
                        self.duration_s
                    )
                },
            );
        }
        let s = &self.scanner;
        let scan_s = self.duration_s - s.t0_offset_s - s.end_margin_s;
        c.test("duration_s", scan_s > s.period_s, || {
            "too short: no complete profile between scanner.t0_offset_s and scanner.end_margin_s"
                .into()
        });
        c.done()
    }
}

impl SceneCfg {
    fn check(&self, c: &mut Checker) {
        c.test(
            "scene.blocks",
            self.blocks.iter().all(|&b| (1..=50).contains(&b)),
            || format!("each count must be 1..=50, got {:?}", self.blocks),
        );
        for (i, v) in self.block_size_m.iter().enumerate() {
            c.range(&format!("scene.block_size_m[{i}]"), *v, 20.0, 2000.0);
        }
        c.range("scene.street_width_m", self.street_width_m, 5.0, 100.0);
        c.range("scene.sidewalk_width_m", self.sidewalk_width_m, 0.5, 20.0);
        c.range("scene.curb_height_m", self.curb_height_m, 0.0, 0.5);
        c.finite("scene.ground_slope", &self.ground_slope);
        c.test(
            "scene.ground_slope",
            self.ground_slope.iter().all(|g| g.abs() <= 0.15),
            || {
                format!(
                    "each slope must be within +-0.15, got {:?}",
                    self.ground_slope
                )
            },
        );
        c.interval("scene.building_height_m", self.building_height_m);
        c.interval("scene.building_length_m", self.building_length_m);
        c.range(
            "scene.facade_max_skew_deg",
            self.facade_max_skew_deg,
            0.0,
            30.0,
        );
        c.nonneg("scene.pole_spacing_m", self.pole_spacing_m);
        c.range("scene.pole_radius_m", self.pole_radius_m, 0.01, 2.0);
        c.range("scene.pole_height_m", self.pole_height_m, 0.5, 50.0);
        c.range("scene.sphere_radius_m", self.sphere_radius_m, 0.02, 2.0);
        c.range("scene.tree_porosity", self.tree_porosity, 0.0, 1.0);
        c.range("scene.grid_cell_m", self.grid_cell_m, 1.0, 100.0);
        for (i, r) in self.reflectance.iter().enumerate() {
            c.range(&format!("scene.reflectance[{i}]"), *r, 0.0, 1.0);
        }
        c.range("scene.sync_reflectance", self.sync_reflectance, 0.0, 1000.0);
        c.range(
            "scene.sync_target_yaw_deg",
            self.sync_target_yaw_deg,
            -80.0,
            80.0,
        );
        c.range("scene.decoy_offset_m", self.decoy_offset_m, 0.0, 1000.0);
    }
}

impl RouteCfg {
    fn check(&self, c: &mut Checker) {
        c.test("route.waypoints_m", self.waypoints_m.len() >= 3, || {
            format!("needs at least 3 waypoints, got {}", self.waypoints_m.len())
        });
        let flat: Vec<f64> = self.waypoints_m.iter().flatten().copied().collect();
        c.finite("route.waypoints_m", &flat);
        c.range("route.corner_radius_m", self.corner_radius_m, 2.0, 500.0);
        c.range("route.max_speed_mps", self.max_speed_mps, 0.5, 20.0);
        c.range(
            "route.max_lateral_acc_mps2",
            self.max_lateral_acc_mps2,
            0.1,
            8.0,
        );
        c.range("route.max_acc_mps2", self.max_acc_mps2, 0.1, 8.0);
        c.range("route.max_decel_mps2", self.max_decel_mps2, 0.1, 10.0);
        c.range(
            "route.lap_start_dwell_s",
            self.lap_start_dwell_s,
            0.0,
            3600.0,
        );
        for (i, s) in self.stops.iter().enumerate() {
            c.nonneg(&format!("route.stops[{i}].at_m"), s.at_m);
            c.range(&format!("route.stops[{i}].dwell_s"), s.dwell_s, 0.0, 3600.0);
        }
    }
}

impl VehicleCfg {
    fn check(&self, c: &mut Checker) {
        c.range("vehicle.imu_height_m", self.imu_height_m, 0.3, 10.0);
        c.range("vehicle.lane_offset_m", self.lane_offset_m, -20.0, 20.0);
        c.range(
            "vehicle.roll_per_lateral_acc_deg",
            self.roll_per_lateral_acc_deg,
            0.0,
            5.0,
        );
        let p = self.pitch_per_longitudinal_acc_deg;
        c.range("vehicle.pitch_per_longitudinal_acc_deg", p, 0.0, 5.0);
        c.range(
            "vehicle.body_time_constant_s",
            self.body_time_constant_s,
            0.0,
            10.0,
        );
        for (i, v) in self.vibration_deg.iter().enumerate() {
            c.range(&format!("vehicle.vibration_deg[{i}]"), *v, 0.0, 2.0);
        }
        c.range(
            "vehicle.vibration_vertical_m",
            self.vibration_vertical_m,
            0.0,
            0.1,
        );
        c.range("vehicle.nav_rate_hz", self.nav_rate_hz, 200.0, 2000.0);
    }
}

impl ScannerCfg {
    fn check(&self, c: &mut Checker) {
        c.range(
            "scanner.period_s",
            self.period_s,
            1.0 / 250.0 - 1e-12,
            1.0 / 33.0 + 1e-12,
        );
        c.test(
            "scanner.points_per_profile",
            (1..=100_000).contains(&self.points_per_profile),
            || format!("must be 1..=100000, got {}", self.points_per_profile),
        );
        c.finite("scanner.beta_start_deg", &[self.beta_start_deg]);
        c.test("scanner.direction", self.direction.abs() == 1, || {
            format!("must be +1 or -1, got {}", self.direction)
        });
        c.range("scanner.alpha0_deg", self.alpha0_deg, -45.0, 45.0);
        c.range("scanner.max_range_m", self.max_range_m, 1.0, 5000.0);
        c.range(
            "scanner.min_range_m",
            self.min_range_m,
            0.0,
            self.max_range_m.max(0.0),
        );
        c.range("scanner.sigma_range_m", self.sigma_range_m, 0.0, 1.0);
        c.range("scanner.sigma_angle_deg", self.sigma_angle_deg, 0.0, 1.0);
        c.range(
            "scanner.dropout_probability",
            self.dropout_probability,
            0.0,
            1.0,
        );
        c.pos("scanner.intensity_ref_range_m", self.intensity_ref_range_m);
        c.finite("scanner.lever_arm_b_m", &self.lever_arm_b_m);
        c.test(
            "scanner.lever_arm_b_m",
            self.lever_arm_b_m.iter().all(|v| v.abs() < 10.0),
            || {
                format!(
                    "each component must be within +-10 m, got {:?}",
                    self.lever_arm_b_m
                )
            },
        );
        c.finite("scanner.boresight_deg", &self.boresight_deg);
        c.range("scanner.range_zero_m", self.range_zero_m, -10.0, 10.0);
        c.nonneg("scanner.t0_offset_s", self.t0_offset_s);
        c.nonneg("scanner.end_margin_s", self.end_margin_s);
    }
}

impl NavErrorCfg {
    fn check(&self, c: &mut Checker, nav_rate_hz: f64) {
        for (i, v) in self.position_sigma_m.iter().enumerate() {
            c.range(&format!("nav_errors.position_sigma_m[{i}]"), *v, 0.0, 100.0);
        }
        for (i, v) in self.attitude_sigma_deg.iter().enumerate() {
            c.range(
                &format!("nav_errors.attitude_sigma_deg[{i}]"),
                *v,
                0.0,
                10.0,
            );
        }
        c.pos("nav_errors.position_tau_s", self.position_tau_s);
        c.pos("nav_errors.attitude_tau_s", self.attitude_tau_s);
        for (i, o) in self.outages_s.iter().enumerate() {
            c.test(
                &format!("nav_errors.outages_s[{i}]"),
                o[0] >= 0.0 && o[1] > o[0],
                || format!("must be [start, end] with 0 <= start < end, got {o:?}"),
            );
        }
        c.range(
            "nav_errors.outage_sigma_factor",
            self.outage_sigma_factor,
            1.0,
            1000.0,
        );
        c.nonneg("nav_errors.velocity_sigma_mps", self.velocity_sigma_mps);
        let ratio = nav_rate_hz / self.smrmsg_rate_hz;
        c.test(
            "nav_errors.smrmsg_rate_hz",
            self.smrmsg_rate_hz > 0.0 && (ratio - ratio.round()).abs() < 1e-9 && ratio >= 1.0,
            || {
                format!(
                    "must divide vehicle.nav_rate_hz ({nav_rate_hz}), got {}",
                    self.smrmsg_rate_hz
                )
            },
        );
    }
}
