//! Shared helpers of the simulator tests: a small base scenario and the pipeline's inverse
//! (georeferencing with the configured parameters read back from truth.json).
#![allow(dead_code)]

use kinescan::georef::{beam_e, georeference, point_s, r_b_to_e, Sensor};
use kinescan::io::profiles::ProfileFile;
use kinescan::sim::{read_truth_points, simulate_scenario, Scenario, SimOptions};
use kinescan::timing::{Mirror, MirrorDirection, ScannerClock};
use kinescan::trajectory::{PoseCursor, Trajectory, TrajectoryOptions};
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

/// A 14 s drive from standing along the first street of the city block and round its first
/// corner; no random or systematic error.
pub const BASE: &str = r#"
name = "test"
seed = 5
duration_s = 14.0
[origin]
lat_deg = 48.1372
lon_deg = 11.5756
h_m = 520.0
[scene]
ground_slope = [0.01, -0.005]
trees_per_side = 1
[route]
waypoints_m = [[0.0, 0.0], [112.0, 0.0], [112.0, 92.0], [0.0, 92.0]]
corner_radius_m = 7.0
max_speed_mps = 11.0
max_acc_mps2 = 2.5
lap_start_dwell_s = 0.0
[scanner]
period_s = 0.02
points_per_profile = 300
lever_arm_b_m = [-0.6, 0.1, -0.5]
boresight_deg = [0.4, -0.3, 0.7]
alpha0_deg = 0.5
range_zero_m = 0.02
"#;

/// The base scenario.
pub fn base() -> Scenario {
    Scenario::parse(BASE, "test").unwrap()
}

/// Simulates `sc` into `dir` with `threads` workers.
pub fn run(sc: &Scenario, dir: &Path, threads: usize) {
    let opts = SimOptions {
        threads: Some(threads),
        ..Default::default()
    };
    simulate_scenario(sc, dir, &opts).unwrap();
}

/// Configured sensor and clock from truth.json (what a user gives the pipeline).
pub fn configured(dir: &Path) -> (Sensor, ScannerClock) {
    let text = std::fs::read_to_string(dir.join("truth.json")).unwrap();
    let j: serde_json::Value = serde_json::from_str(&text).unwrap();
    let v3 = |v: &serde_json::Value| {
        Vector3::new(
            v[0].as_f64().unwrap(),
            v[1].as_f64().unwrap(),
            v[2].as_f64().unwrap(),
        )
    };
    let s = &j["configured_sensor"];
    let sensor = Sensor::new(
        v3(&s["lever_arm_b_m"]),
        v3(&s["boresight_rad"]),
        s["alpha0_rad"].as_f64().unwrap(),
        s["range_zero_m"].as_f64().unwrap(),
    );
    let sc = &j["scanner"];
    let direction = if sc["direction"].as_f64().unwrap() > 0.0 {
        MirrorDirection::Increasing
    } else {
        MirrorDirection::Decreasing
    };
    let clock = ScannerClock {
        t0_s: sc["t0_s"].as_f64().unwrap(),
        period_s: sc["nominal_period_s"].as_f64().unwrap(),
        mirror: Mirror {
            beta_start_rad: sc["beta_start_rad"].as_f64().unwrap(),
            direction,
        },
    };
    (sensor, clock)
}

/// One georeferenced return next to its truth.
pub struct Pair {
    /// Profile counter.
    pub profile: u32,
    /// Recorded mirror angle (rad).
    pub beta_rad: f64,
    /// Scanner time from the configured clock (s).
    pub t_s: f64,
    /// Pipeline's point (ECEF, m).
    pub x_e: Vector3<f64>,
    /// True point (ECEF, m).
    pub truth_e: Vector3<f64>,
    /// Pipeline's beam origin (ECEF, m) and unit direction.
    pub beam_e: (Vector3<f64>, Vector3<f64>),
    /// Pipeline's IMU position (ECEF, m) and body-to-ECEF rotation.
    pub imu_e: Vector3<f64>,
    /// Pipeline's `R_b^e`.
    pub r_b_e: Matrix3<f64>,
}

/// Georeferences every valid return of `dir` as the pipeline does (configured parameters,
/// latency 0) and pairs it with its truth. Also checks missing returns are marked in both.
pub fn georef_pairs(dir: &Path) -> Vec<Pair> {
    georef_pairs_with_latency(dir, 0.0)
}

/// [`georef_pairs`] with the pipeline's attitude latency `tau_s` (s, conventions §2).
pub fn georef_pairs_with_latency(dir: &Path, tau_s: f64) -> Vec<Pair> {
    let (sensor, clock) = configured(dir);
    let traj = Trajectory::open(
        &dir.join("trajectory.sbet"),
        None,
        TrajectoryOptions::default(),
    )
    .unwrap();
    let mut cursor = PoseCursor::new(&traj, tau_s, 0.0);
    let prof = ProfileFile::open(&dir.join("profiles.bin")).unwrap();
    let truth = read_truth_points(&dir.join("truth_points.bin")).unwrap();
    assert_eq!(prof.len(), truth.len());
    let mut out = Vec::new();
    for (i, tr) in truth.iter().enumerate() {
        let r = prof.get(i);
        assert_eq!(
            r.range_m == 0.0,
            tr[0].is_nan(),
            "return {i}: missing marks disagree"
        );
        if r.range_m == 0.0 {
            continue;
        }
        let t = if prof.columns().time {
            clock.time_from_profile_tag(r.time_s, r.beta_rad)
        } else {
            clock.time_of(r.profile, r.beta_rad)
        };
        let pose = cursor.at(t).unwrap();
        let x = georeference(
            &pose,
            &sensor,
            &point_s(&sensor, r.range_m, sensor.alpha0_rad, r.beta_rad),
        );
        out.push(Pair {
            beam_e: beam_e(&pose, &sensor, sensor.alpha0_rad, r.beta_rad),
            imu_e: pose.nav.r_e_m,
            r_b_e: r_b_to_e(&pose),
            profile: r.profile,
            beta_rad: r.beta_rad,
            t_s: t,
            x_e: x,
            truth_e: Vector3::new(tr[0], tr[1], tr[2]),
        });
    }
    out
}

/// SMRMSG column of error axis `i` (north, east, down, roll, pitch, heading).
pub fn smrmsg_col(i: usize) -> usize {
    if i < 3 {
        i + 1
    } else {
        i + 4
    }
}

/// The navigation errors the simulation in `dir` injected, per SBET record: `trajectory.sbet`
/// minus `truth.sbet` as north, east, down (m) and roll, pitch, heading (rad).
pub fn nav_errors(dir: &Path) -> Vec<[f64; 6]> {
    use kinescan::geo::ellipsoid::{meridian_radius_m, prime_vertical_radius_m};
    use kinescan::geo::rotations::wrap_pi;
    use kinescan::io::sbet::SbetFile;
    let nav = SbetFile::open(&dir.join("trajectory.sbet")).unwrap();
    let truth = SbetFile::open(&dir.join("truth.sbet")).unwrap();
    assert_eq!(nav.len(), truth.len());
    (0..nav.len())
        .map(|k| {
            let (a, b) = (nav.record(k), truth.record(k));
            let h = b.alt_m;
            [
                (a.lat_rad - b.lat_rad) * (meridian_radius_m(b.lat_rad) + h),
                (a.lon_rad - b.lon_rad)
                    * (prime_vertical_radius_m(a.lat_rad) + h)
                    * a.lat_rad.cos(),
                -(a.alt_m - b.alt_m),
                a.roll_rad - b.roll_rad,
                a.pitch_rad - b.pitch_rad,
                wrap_pi(a.platform_heading_rad - b.platform_heading_rad),
            ]
        })
        .collect()
}
