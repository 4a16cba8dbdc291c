//! Rotating-table scenario for the latency calibration (paper 000, sections 3-4).
//!
//! A level table turns about `table_axis_n` (NED, origin at its centre of rotation) in a
//! triangle wave between `-sweep` and `+sweep`: for each speed, `passes_per_direction` passes at
//! `+omega` alternating with as many at `-omega`. The IMU sits on the table with mount attitude
//! `imu_mount_deg` at table angle 0, so `R_b^n(t) = Rot(a_n, theta(t)) * R_mount`. A profile
//! scanner (boresight, lever arm from the rotation centre) with hardware time tags scans a
//! sphere placed in its scan plane at `sphere_beta_deg`, `sphere_distance_m` from the optical
//! centre at table angle 0; an optional stand (vertical cylinder under the sphere) gives returns
//! off the sphere. Ranges get Gaussian noise. The IMU stream is stamped `latency_ms` after the
//! physical attitude (conventions §2). Defaults are the paper's geometry: 20 cm sphere at 1.5 m,
//! 2-18 deg/s, 15 passes per direction, a point density of ~2000 sphere returns per pass at
//! 6 deg/s (paper: ~30 000 points over 15 scans) and 5 mm noise per return (the HDS6200's
//! position accuracy quoted in the paper; its 2 mm range noise alone gives centre sigmas 2.5x
//! below the paper's Table 2, while 5 mm gives ~80 % of Table 2's centre STD and 0.087 ms
//! latency sigma at 18 deg/s against the paper's 0.09 ms).

use super::latency::{beam_s, AttitudeSample, LatencyData, LatencySetup, TablePass, TimedReturn};
use super::sphere::{ray_sphere_range, SphereRadius};
use crate::geo::rotations::{r_b_to_n, r_zyx, roll_pitch_heading, wrap_two_pi};
use crate::io::atomic::{write_atomic, write_json};
use crate::io::config_file;
use crate::io::publish::publish_folder;
use crate::{Error, Result};
use nalgebra::{Matrix3, Unit, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// Rotating-table scenario (TOML keys as fields; every key optional, defaults = paper).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableScenario {
    /// Random seed.
    pub seed: u64,
    /// Injected latency `tau` (ms, convention sign).
    pub latency_ms: f64,
    /// Table speeds |omega| (deg/s).
    pub speeds_deg_s: Vec<f64>,
    /// Passes per direction and speed.
    pub passes_per_direction: usize,
    /// Sphere radius (m).
    pub sphere_radius_m: f64,
    /// Optical centre to sphere centre at table angle 0 (m).
    pub sphere_distance_m: f64,
    /// Mirror angle of the sphere centre at table angle 0 (deg).
    pub sphere_beta_deg: f64,
    /// Range noise, 1 sigma (m).
    pub sigma_range_m: f64,
    /// Profile rate (Hz).
    pub profile_rate_hz: f64,
    /// Mirror angle step between returns (deg).
    pub beta_step_deg: f64,
    /// IMU output rate (Hz).
    pub imu_rate_hz: f64,
    /// Half sweep of the triangle wave (deg).
    pub sweep_half_angle_deg: f64,
    /// Table axis in NED.
    pub table_axis_n: [f64; 3],
    /// IMU roll, pitch, heading on the table at table angle 0 (deg).
    pub imu_mount_deg: [f64; 3],
    /// Boresight `[bx, by, bz]` (deg).
    pub boresight_deg: [f64; 3],
    /// Optical centre relative to the rotation centre, body frame (m).
    pub lever_arm_b_m: [f64; 3],
    /// Radius of the stand under the sphere (m); 0 = no stand.
    pub stand_radius_m: f64,
    /// Length of the stand below the sphere (m).
    pub stand_length_m: f64,
    /// GPS time of the start (s of week).
    pub start_time_s: f64,
}

impl Default for TableScenario {
    fn default() -> Self {
        Self {
            seed: 1,
            latency_ms: 4.21,
            speeds_deg_s: vec![2.0, 4.0, 6.0, 10.0, 14.0, 18.0],
            passes_per_direction: 15,
            sphere_radius_m: 0.1,
            sphere_distance_m: 1.5,
            sphere_beta_deg: -90.0,
            sigma_range_m: 0.005,
            profile_rate_hz: 50.0,
            beta_step_deg: 0.2,
            imu_rate_hz: 100.0,
            sweep_half_angle_deg: 10.0,
            table_axis_n: [0.0, 0.0, 1.0],
            imu_mount_deg: [0.0, 0.0, 0.0],
            boresight_deg: [0.0, 0.0, 0.0],
            lever_arm_b_m: [0.0, 0.0, 0.0],
            stand_radius_m: 0.0,
            stand_length_m: 0.3,
            start_time_s: 100_000.0,
        }
    }
}

/// Table angle history: constant-rate segments `(t_start, t_end, theta_start, rate)`.
struct TableMotion {
    segments: Vec<(f64, f64, f64, f64)>,
}

impl TableMotion {
    fn theta(&self, t: f64) -> f64 {
        let k = self.segments.partition_point(|s| s.0 <= t).max(1) - 1;
        let (t0, t1, th0, rate) = self.segments[k];
        th0 + rate * (t.clamp(t0, t1) - t0)
    }
}

/// The truth of a scenario in SI and the setup a calibration should use.
struct Geometry {
    axis: Unit<Vector3<f64>>,
    r_mount: Matrix3<f64>,
    r_s_to_b: Matrix3<f64>,
    lever_b: Vector3<f64>,
    centre_n: Vector3<f64>,
}

impl TableScenario {
    fn check(&self) -> Result<()> {
        let bad = |k: &str, p: &str| Err(Error::config("table scenario", k, p));
        if self.speeds_deg_s.iter().any(|s| !super::positive(s.abs()))
            || self.speeds_deg_s.is_empty()
        {
            return bad("speeds_deg_s", "need >= 1 speed, none zero");
        }
        if self.passes_per_direction == 0 {
            return bad("passes_per_direction", "must be >= 1");
        }
        for (k, v) in [
            ("sphere_radius_m", self.sphere_radius_m),
            ("sphere_distance_m", self.sphere_distance_m),
            ("profile_rate_hz", self.profile_rate_hz),
            ("beta_step_deg", self.beta_step_deg),
            ("imu_rate_hz", self.imu_rate_hz),
            ("sweep_half_angle_deg", self.sweep_half_angle_deg),
        ] {
            if !super::positive(v) {
                return bad(k, "must be > 0");
            }
        }
        if !super::positive(Vector3::from(self.table_axis_n).norm()) {
            return bad("table_axis_n", "must be non-zero");
        }
        Ok(())
    }

    fn geometry(&self) -> Geometry {
        let [mr, mp, mh] = self.imu_mount_deg.map(f64::to_radians);
        let [bx, by, bz] = self.boresight_deg.map(f64::to_radians);
        let r_mount = r_b_to_n(mr, mp, mh);
        let r_s_to_b = r_zyx(bx, by, bz);
        let lever_b = Vector3::from(self.lever_arm_b_m);
        let u = beam_s(0.0, self.sphere_beta_deg.to_radians());
        let centre_n = r_mount * (lever_b + r_s_to_b * u * self.sphere_distance_m);
        let axis = Unit::new_normalize(Vector3::from(self.table_axis_n));
        Geometry {
            axis,
            r_mount,
            r_s_to_b,
            lever_b,
            centre_n,
        }
    }

    fn motion(&self) -> (TableMotion, Vec<TablePass>) {
        let sweep = 2.0 * self.sweep_half_angle_deg.to_radians();
        let (mut t, mut theta) = (self.start_time_s, -sweep / 2.0);
        let (mut segments, mut passes) = (Vec::new(), Vec::new());
        for &speed in &self.speeds_deg_s {
            let w = speed.abs().to_radians();
            for k in 0..2 * self.passes_per_direction {
                let rate = if k % 2 == 0 { w } else { -w };
                let dt = sweep / w;
                segments.push((t, t + dt, theta, rate));
                passes.push(TablePass {
                    t_start_s: t,
                    t_end_s: t + dt,
                    rate_rad_s: rate,
                });
                t += dt;
                theta += rate * dt;
            }
        }
        (TableMotion { segments }, passes)
    }

    /// The setup a calibration of this scenario uses: true mounting, known radius, nothing
    /// applied, gate 5 cm about the true centre.
    pub fn calibration_setup(&self) -> LatencySetup {
        let g = self.geometry();
        LatencySetup {
            r_s_to_b: g.r_s_to_b,
            lever_arm_b_m: g.lever_b,
            range_zero_error_m: 0.0,
            table_axis_n: g.axis.into_inner(),
            sphere_radius: SphereRadius::Known(self.sphere_radius_m),
            applied_latency_s: 0.0,
            sphere_gate_n_m: Some((g.centre_n, 0.05)),
        }
    }
}

/// Simulates a rotating-table run: scanner returns (with time tags), the table log and the IMU
/// attitude stream, seeded (same scenario, same output).
pub fn simulate_table(sc: &TableScenario) -> Result<LatencyData> {
    sc.check()?;
    let g = sc.geometry();
    let (motion, passes) = sc.motion();
    let r_b_n = |t: f64| {
        *UnitQuaternion::from_axis_angle(&g.axis, motion.theta(t))
            .to_rotation_matrix()
            .matrix()
            * g.r_mount
    };
    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed);
    let noise = Normal::new(0.0, sc.sigma_range_m)
        .map_err(|e| Error::config("table scenario", "sigma_range_m", e.to_string()))?;
    let period = 1.0 / sc.profile_rate_hz;
    let t_end = passes.last().map_or(sc.start_time_s, |p| p.t_end_s);
    let n_profiles = ((t_end - sc.start_time_s) / period).floor() as u64;
    let d_beta = sc.beta_step_deg.to_radians();
    let reach = sc.sphere_radius_m
        + if sc.stand_radius_m > 0.0 {
            sc.stand_length_m
        } else {
            0.0
        };
    let mut returns = Vec::new();
    for n in 0..n_profiles {
        let t_n = sc.start_time_s + n as f64 * period;
        let r = r_b_n(t_n);
        let c_s = g.r_s_to_b.transpose() * (r.transpose() * g.centre_n - g.lever_b);
        if c_s.x.abs() > reach + 0.02 {
            continue;
        }
        let beta_c = (-c_s.y).atan2(c_s.z);
        let half = (reach / c_s.norm()).min(1.0).asin() + 0.01;
        let (k0, k1) = (
            ((beta_c - half) / d_beta).floor() as i64,
            ((beta_c + half) / d_beta).ceil() as i64,
        );
        for k in k0..=k1 {
            let beta = k as f64 * d_beta;
            let t = t_n + period * wrap_two_pi(beta) / std::f64::consts::TAU;
            let r = r_b_n(t);
            let origin = r * g.lever_b;
            let dir = r * g.r_s_to_b * beam_s(0.0, beta);
            let Some(range) = first_hit(sc, &g, &origin, &dir) else {
                continue;
            };
            returns.push(TimedReturn {
                profile: n,
                time_s: t,
                alpha_rad: 0.0,
                beta_rad: beta,
                range_m: range + noise.sample(&mut rng),
            });
        }
    }
    let tau = sc.latency_ms * 1e-3;
    let dt_imu = 1.0 / sc.imu_rate_hz;
    let n_imu = ((t_end - sc.start_time_s + 2.0) / dt_imu).ceil() as usize;
    let attitude = (0..n_imu)
        .map(|j| {
            let stamp = sc.start_time_s - 1.0 + j as f64 * dt_imu;
            let q = UnitQuaternion::from_matrix(&r_b_n(stamp - tau));
            let (roll_rad, pitch_rad, heading_rad) = roll_pitch_heading(&q);
            AttitudeSample {
                time_s: stamp,
                roll_rad,
                pitch_rad,
                heading_rad,
            }
        })
        .collect();
    Ok(LatencyData {
        returns,
        passes,
        attitude,
    })
}

/// Nearest hit (m) on the sphere or the stand (vertical cylinder in NED below the sphere).
fn first_hit(sc: &TableScenario, g: &Geometry, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
    let sphere = ray_sphere_range(o, d, &g.centre_n, sc.sphere_radius_m);
    if sc.stand_radius_m <= 0.0 {
        return sphere;
    }
    let stand = ray_stand_range(
        o,
        d,
        &g.centre_n,
        sc.stand_radius_m,
        sc.sphere_radius_m + sc.stand_length_m,
    );
    match (sphere, stand) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Ray against the vertical cylinder of radius `rad` through `top` (NED), from `top.z` down to
/// `top.z + len`.
fn ray_stand_range(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    top: &Vector3<f64>,
    rad: f64,
    len: f64,
) -> Option<f64> {
    let (ox, oy, dx, dy) = (o.x - top.x, o.y - top.y, d.x, d.y);
    let a = dx * dx + dy * dy;
    let b = ox * dx + oy * dy;
    let disc = b * b - a * (ox * ox + oy * oy - rad * rad);
    if a < 1e-15 || disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    let z = o.z + t * d.z - top.z;
    (t > 0.0 && (0.0..=len).contains(&z)).then_some(t)
}

/// Files a table simulation writes into its output folder.
pub const OUTPUT_FILES: [&str; 5] = [
    "sphere_returns.csv",
    "table_passes.csv",
    "imu_attitude.csv",
    "calib_latency.toml",
    "truth.json",
];

/// Writes the scenario's files as a lab would record them (`sphere_returns.csv`,
/// `table_passes.csv`, `imu_attitude.csv`), the calibration config `calib_latency.toml` that
/// reads them, and `truth.json`, atomically into `out_dir`.
pub fn write_table_run(sc: &TableScenario, data: &LatencyData, out_dir: &Path) -> Result<()> {
    let mut s = String::from("profile,beta_rad,range_m,intensity,time_s\n");
    for r in &data.returns {
        let _ = writeln!(
            s,
            "{},{:.10},{:.6},100,{:.9}",
            r.profile, r.beta_rad, r.range_m, r.time_s
        );
    }
    write_atomic(&out_dir.join("sphere_returns.csv"), s.as_bytes())?;
    let mut s = String::from("pass,t_start_s,t_end_s,table_rate_deg_s\n");
    for (i, p) in data.passes.iter().enumerate() {
        let _ = writeln!(
            s,
            "{i},{:.9},{:.9},{:.9}",
            p.t_start_s,
            p.t_end_s,
            p.rate_rad_s.to_degrees()
        );
    }
    write_atomic(&out_dir.join("table_passes.csv"), s.as_bytes())?;
    let mut s = String::from("time_s,roll_deg,pitch_deg,heading_deg\n");
    for a in &data.attitude {
        let [r, p, h] = [a.roll_rad, a.pitch_rad, a.heading_rad].map(f64::to_degrees);
        let _ = writeln!(s, "{:.9},{r:.12},{p:.12},{h:.12}", a.time_s);
    }
    write_atomic(&out_dir.join("imu_attitude.csv"), s.as_bytes())?;
    let c = sc.geometry().centre_n;
    let cfg = format!(
        "# Written by the rotating-table simulator (seed {}).\n[files]\nreturns = \"sphere_returns.csv\"\n\
         passes = \"table_passes.csv\"\nattitude = \"imu_attitude.csv\"\n\n[table]\naxis_n = {:?}\n\n\
         [sphere]\nradius_m = {:?}\napprox_centre_n_m = [{:?}, {:?}, {:?}]\ngate_m = 0.05\n\n\
         [scanner]\nboresight_deg = {:?}\nlever_arm_b_m = {:?}\napplied_latency_ms = 0.0\n",
        sc.seed, sc.table_axis_n, sc.sphere_radius_m, c.x, c.y, c.z, sc.boresight_deg, sc.lever_arm_b_m
    );
    write_atomic(&out_dir.join("calib_latency.toml"), cfg.as_bytes())?;
    write_json(
        &out_dir.join("truth.json"),
        &serde_json::json!({
            "latency_s": sc.latency_ms * 1e-3,
            "sphere_centre_n_m": [c.x, c.y, c.z],
            "scenario": sc,
        }),
    )
}

/// What [`run_table_simulation`] wrote (serialisable, for the CLI's summary).
#[derive(Debug, Clone, Serialize)]
pub struct TableSimulationReport {
    /// Scanner returns written to `sphere_returns.csv`.
    pub n_returns: usize,
    /// Table passes written to `table_passes.csv`.
    pub n_passes: usize,
    /// IMU attitude records written to `imu_attitude.csv`.
    pub n_attitude: usize,
    /// Injected (true) latency `tau` (s), convention sign: attitude stamps lag the physical attitude.
    pub true_latency_s: f64,
    /// Files written into the output directory.
    pub files: Vec<String>,
}

/// `kinescan simulate` for the rotating table (paper 000): reads a [`TableScenario`] TOML at
/// `config_path` (unknown keys refused) and writes, atomically into `out_dir`, the recorded
/// files `sphere_returns.csv` (conventions §6 profile CSV with `time_s`), `table_passes.csv`,
/// `imu_attitude.csv` (convention angles, deg), the calibration config `calib_latency.toml` that
/// reads them and `truth.json` (see [`write_table_run`]).
pub fn run_table_simulation(config_path: &Path, out_dir: &Path) -> Result<TableSimulationReport> {
    let sc: TableScenario = config_file::load(config_path, &[])?.value;
    crate::io::paths::check_collisions(
        &[("config file".into(), config_path.to_path_buf())],
        &crate::io::paths::in_out_dir(out_dir, &OUTPUT_FILES),
    )?;
    let data = simulate_table(&sc)?;
    publish_folder(out_dir, "table", "truth.json", &OUTPUT_FILES, |dir| {
        write_table_run(&sc, &data, dir)
    })?;
    Ok(TableSimulationReport {
        n_returns: data.returns.len(),
        n_passes: data.passes.len(),
        n_attitude: data.attitude.len(),
        true_latency_s: sc.latency_ms * 1e-3,
        files: [
            "sphere_returns.csv",
            "table_passes.csv",
            "imu_attitude.csv",
            "calib_latency.toml",
            "truth.json",
        ]
        .map(String::from)
        .to_vec(),
    })
}
