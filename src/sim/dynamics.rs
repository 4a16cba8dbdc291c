//! Vehicle body dynamics: the true trajectory, sampled at the nav rate as SBET records (wander
//! angle 0, so platform heading = true heading and x/y velocity = north/east).
//!
//! Position: the route point, on the sloped ground, IMU `imu_height_m` above it, plus vertical
//! road vibration. Attitude in the scene frame: heading along the path (its direction
//! averaged over 1 m of arc, so the yaw rate ramps into a corner), pitch from the slope
//! along the heading plus `k_pitch * a_lon` (nose up accelerating), roll from the cross slope
//! plus `k_roll * a_lat` (rolling out of the turn), both through a second-order lag (two
//! first-order lags of half the body time constant), plus
//! road vibration (three sinusoids per channel, amplitude proportional to speed; roll and
//! pitch one sinusoid at `vibration_hz` when set). The scene
//! attitude is rotated to the local NED frame of the vehicle's own position. Between samples
//! the truth is, by definition, `trajectory::interpolate` of these samples.

use super::route::Route;
use super::scenario::{Scenario, VehicleCfg};
use crate::geo::ellipsoid::{ecef_to_geodetic, r_enu_to_e, r_n_to_e};
use crate::geo::rotations::{r_b_to_n, wrap_two_pi, zyx_angles};
use crate::io::sbet::SbetRecord;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// Standard gravity used for the (approximate) specific-force fields (m/s^2).
const G_MPS2: f64 = 9.806_65;

/// The scene frame's tie to ECEF.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    /// Origin in ECEF (m).
    pub origin_e: Vector3<f64>,
    /// Rotation ENU (at the origin) to ECEF.
    pub r_enu_to_e: Matrix3<f64>,
    /// Rotation NED (at the origin) to ECEF.
    pub r_ned_to_e: Matrix3<f64>,
}

impl Frame {
    /// Frame about geodetic origin (rad, rad, m).
    pub fn new(lat_rad: f64, lon_rad: f64, h_m: f64) -> Frame {
        let g = crate::geo::ellipsoid::Geodetic {
            lat_rad,
            lon_rad,
            h_m,
        };
        Frame {
            origin_e: crate::geo::ellipsoid::geodetic_to_ecef(g),
            r_enu_to_e: r_enu_to_e(lat_rad, lon_rad),
            r_ned_to_e: r_n_to_e(lat_rad, lon_rad),
        }
    }
    /// Scene ENU point to ECEF.
    #[inline]
    pub fn to_ecef(self, p: &Vector3<f64>) -> Vector3<f64> {
        self.origin_e + self.r_enu_to_e * p
    }
}

/// Sequential generator of true nav samples `k = 0, 1, ...` at `t_k = start + k / rate`.
#[derive(Debug, Clone)]
pub struct TruthGen {
    route: Route,
    cfg: VehicleCfg,
    slope: [f64; 2],
    frame: Frame,
    start_s: f64,
    rate_hz: f64,
    v_top: f64,
    /// Frequency (Hz) and phase (rad) of 3 sinusoids for roll, pitch, vertical.
    vib: [[(f64, f64); 3]; 3],
    k: u64,
    /// Roll and pitch body terms after the first and the second lag stage.
    lag: [[f64; 2]; 2],
    prev: Option<(f64, f64, f64)>,
}

impl TruthGen {
    /// Generator for a scenario with its route and scene frame.
    pub fn new(sc: &Scenario, route: Route, frame: Frame) -> TruthGen {
        let mut rng = ChaCha8Rng::seed_from_u64(sc.seed ^ 0xD7A_0000_0000_0002);
        let bands = [(1.0, 1.8), (2.5, 4.0), (5.0, 9.0)];
        let vib = [0; 3]
            .map(|_| bands.map(|(lo, hi)| (rng.random_range(lo..hi), rng.random_range(0.0..TAU))));
        TruthGen {
            route,
            cfg: sc.vehicle.clone(),
            slope: sc.scene.ground_slope,
            frame,
            start_s: sc.start_time_s,
            rate_hz: sc.vehicle.nav_rate_hz,
            v_top: sc.route.max_speed_mps,
            vib,
            k: 0,
            lag: [[0.0; 2]; 2],
            prev: None,
        }
    }

    /// Time of sample `k` (s); the one formula every writer uses.
    #[inline]
    pub fn time_of(start_s: f64, rate_hz: f64, k: u64) -> f64 {
        start_s + k as f64 / rate_hz
    }

    /// Index of the next sample.
    pub fn next_index(&self) -> u64 {
        self.k
    }

    /// Next true sample.
    pub fn next_sample(&mut self) -> SbetRecord {
        let t = Self::time_of(self.start_s, self.rate_hz, self.k);
        let dt = 1.0 / self.rate_hz;
        let tr = t - self.start_s;
        let m = self.route.motion(tr);
        let p = self.route.at(m.s_m);
        let [gx, gy] = self.slope;
        let (de, dn) = (p.dir[0], p.dir[1]);
        // The body's heading (and the lateral acceleration of its turn) follows the smoothed
        // path direction: the yaw rate is continuous.
        let (steer_rad, steer_curvature) = self.route.steered(m.s_m);
        let (hn, he) = steer_rad.sin_cos();
        let a_lat = m.v_mps * m.v_mps * steer_curvature;
        // Two first-order lags of half the body time constant each (each exact for an input
        // held over the step):
        // the body's roll and pitch rates stay continuous when an acceleration steps.
        let w = if self.cfg.body_time_constant_s > 0.0 {
            1.0 - (-2.0 * dt / self.cfg.body_time_constant_s).exp()
        } else {
            1.0
        };
        let target = [
            self.cfg.roll_per_lateral_acc_deg.to_radians() * a_lat,
            self.cfg.pitch_per_longitudinal_acc_deg.to_radians() * m.a_mps2,
        ];
        let k0 = self.k == 0;
        let [first, second] = &mut self.lag;
        for ((l1, l2), target) in first.iter_mut().zip(second.iter_mut()).zip(target) {
            (*l1, *l2) = if k0 {
                (target, target)
            } else {
                let l1_next = *l1 + w * (target - *l1);
                (l1_next, *l2 + w * (l1_next - *l2))
            };
        }
        let amp = (m.v_mps / self.v_top).min(1.0);
        let vib = |ch: usize| -> f64 {
            if let (Some(f), true) = (self.cfg.vibration_hz, ch < 2) {
                // One sinusoid at the set frequency, the first band's seeded phase.
                return (TAU * f * tr + self.vib[ch][0].1).sin() * amp;
            }
            self.vib[ch]
                .iter()
                .map(|(f, ph)| (TAU * f * tr + ph).sin())
                .sum::<f64>()
                / 3.0
                * amp
        };
        let roll = -(gx * he - gy * hn).atan()
            + self.lag[1][0]
            + self.cfg.vibration_deg[0].to_radians() * vib(0);
        let pitch = (gx * he + gy * hn).atan()
            + self.lag[1][1]
            + self.cfg.vibration_deg[1].to_radians() * vib(1);
        let heading = he.atan2(hn);
        let z = gx * p.xy[0]
            + gy * p.xy[1]
            + self.cfg.imu_height_m
            + self.cfg.vibration_vertical_m * vib(2);
        let x_e = self.frame.to_ecef(&Vector3::new(p.xy[0], p.xy[1], z));
        let geo = ecef_to_geodetic(&x_e);
        // Scene-frame attitude to the local NED frame at the vehicle.
        let r_b_e = self.frame.r_ned_to_e * r_b_to_n(roll, pitch, heading);
        let r_b_n = r_n_to_e(geo.lat_rad, geo.lon_rad).transpose() * r_b_e;
        let (roll_n, pitch_n, heading_n) = zyx_angles(&r_b_n);
        let heading_n = wrap_two_pi(heading_n);
        let v_up = m.v_mps * (gx * de + gy * dn);
        let v_enu = Vector3::new(m.v_mps * de, m.v_mps * dn, v_up);
        let v_ned =
            r_n_to_e(geo.lat_rad, geo.lon_rad).transpose() * (self.frame.r_enu_to_e * v_enu);
        let rates = self.body_rates(roll_n, pitch_n, heading_n, dt);
        self.prev = Some((roll_n, pitch_n, heading_n));
        self.k += 1;
        SbetRecord {
            time_s: t,
            lat_rad: geo.lat_rad,
            lon_rad: geo.lon_rad,
            alt_m: geo.h_m,
            vel_x_mps: v_ned.x,
            vel_y_mps: v_ned.y,
            vel_z_mps: v_ned.z,
            roll_rad: roll_n,
            pitch_rad: pitch_n,
            platform_heading_rad: heading_n,
            wander_rad: 0.0,
            acc_x_mps2: m.a_mps2,
            acc_y_mps2: -a_lat,
            acc_z_mps2: -G_MPS2,
            rate_x_radps: rates.x,
            rate_y_radps: rates.y,
            rate_z_radps: rates.z,
        }
    }

    /// Body angular rate from Euler-angle differences to the previous sample (rad/s).
    fn body_rates(&self, roll: f64, pitch: f64, heading: f64, dt: f64) -> Vector3<f64> {
        let Some((r0, p0, h0)) = self.prev else {
            return Vector3::zeros();
        };
        let d = |a: f64, b: f64| crate::geo::rotations::wrap_pi(a - b) / dt;
        let (rd, pd, hd) = (d(roll, r0), d(pitch, p0), d(heading, h0));
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        Vector3::new(
            rd - sp * hd,
            cr * pd + sr * cp * hd,
            -sr * pd + cr * cp * hd,
        )
    }
}
