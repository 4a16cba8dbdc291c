//! Shared helpers of the sync tests: simulate the paper-geometry scenario for a seed, and
//! build the sync targets (surveyed centres and face normals) and the truth.
#![allow(dead_code)]

use crate::sim_support;

use kinescan::geo::ellipsoid::r_enu_to_e;
use kinescan::georef::Sensor;
use kinescan::io::points::read_control_points;
use kinescan::io::profiles::ProfileFile;
use kinescan::sim::{simulate_scenario, Scenario, SimOptions};
use kinescan::sync::{SyncOptions, SyncTarget};
use kinescan::timing::ScannerClock;
use kinescan::trajectory::{Trajectory, TrajectoryOptions};
use std::path::Path;

/// The paper-geometry scenario file.
pub const PAPER: &str = "pipelines/scenario_sync_paper.toml";

/// The scenario at `path` with `seed`, without the (large) truth sidecars. The laps repeat
/// exactly, so the phase of the profiles at each pass is randomised per seed (t0 within a
/// period, the clock drift within +-50 ppm of the file's): otherwise every seed would see
/// the same profile-quantisation errors.
pub fn scenario(path: &str, seed: u64) -> Scenario {
    let mut sc = Scenario::load(Path::new(path)).unwrap();
    sc.seed = seed;
    let u = |k: f64| (seed as f64 * k).fract();
    sc.scanner.t0_offset_s += u(0.618_033_988_7) * sc.scanner.period_s;
    let drift = sc.effects.clock_drift_ppm.unwrap_or(0.0);
    sc.effects.clock_drift_ppm = Some(drift + 100.0 * (u(0.754_877_666_2) - 0.5));
    sc.output.truth_points = false;
    sc.output.truth_sbet = false;
    sc
}

/// Everything a sync run needs, and the truth.
pub struct Survey {
    pub traj: Trajectory,
    pub file: ProfileFile,
    pub targets: Vec<SyncTarget>,
    pub sensor: Sensor,
    pub clock: ScannerClock,
    pub true_t0_s: f64,
    pub true_period_s: f64,
    pub sigma_range_m: f64,
}

/// Simulates `sc` into `dir` and opens it; targets carry the face normals of the scene's
/// sync plates (what a surveyor would measure).
pub fn survey(sc: &Scenario, dir: &Path) -> Survey {
    simulate_scenario(sc, dir, &SimOptions::default()).unwrap();
    let traj = Trajectory::open(
        &dir.join("trajectory.sbet"),
        Some(&dir.join("trajectory.smrmsg")),
        TrajectoryOptions::default(),
    )
    .unwrap();
    let file = ProfileFile::open(&dir.join("profiles.bin")).unwrap();
    let cps = read_control_points(&dir.join("control_points.csv")).unwrap();
    let mut targets = SyncTarget::from_surveys(&cps, &[]);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let o = &sc.origin;
    let r_enu_to_e = r_enu_to_e(o.lat_deg.to_radians(), o.lon_deg.to_radians());
    let faces = j["sync_targets"].as_array().unwrap();
    assert!(!faces.is_empty(), "the scenario has sync targets");
    for face in faces {
        let id = face["id"].as_str().unwrap();
        let t = targets.iter_mut().find(|t| t.id == id).unwrap();
        let v = |key: &str, k: usize| face[key][k].as_f64().unwrap();
        let n = nalgebra::Vector3::new(v("normal_enu", 0), v("normal_enu", 1), v("normal_enu", 2));
        t.normal_e = Some(r_enu_to_e * n);
        t.half_size_m = Some([v("half_size_m", 0), v("half_size_m", 1)]);
    }
    let (sensor, clock) = sim_support::configured(dir);
    Survey {
        traj,
        file,
        targets,
        sensor,
        clock,
        true_t0_s: j["scanner"]["t0_s"].as_f64().unwrap(),
        true_period_s: j["scanner"]["true_period_s"].as_f64().unwrap(),
        sigma_range_m: sc.scanner.sigma_range_m,
    }
}

/// Options as a user would give them: t0 known to `t0_error_s`, the nominal period.
pub fn options(s: &Survey, t0_error_s: f64) -> SyncOptions {
    let mut o = SyncOptions::new(s.true_t0_s + t0_error_s, s.clock.period_s, s.clock.mirror);
    o.sigma_range_m = s.sigma_range_m;
    o.max_range_m = 15.0;
    o
}
