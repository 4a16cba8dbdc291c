//! Initial alignment: the filter's first state and covariance from the data.
//!
//! Position from the first GNSS fix (minus the lever arm). "auto": when the IMU is static
//! over the first `static_s` (no rotation, specific force of constant magnitude), roll and
//! pitch from the mean specific force (`roll = atan2(-f_y, -f_z)`,
//! `pitch = atan2(f_x, hypot(f_y, f_z))`) and zero velocity; otherwise roll = pitch = 0 +- 5
//! deg and the velocity from the first fixes. Heading from the GNSS course (displacement over
//! about 1 s) at the first speed above `course_min_speed_mps`: the heading of a van at rest
//! is the heading it drives off with. "given": the configured angles and sigmas.

use super::config::AlignmentCfg;
use super::filter::{initial_covariance, Filter, ProcessNoise, SensorEstimate};
use super::imu_model::ImuGrade;
use super::mechanisation::NavState;
use super::smoother::{ImuSource, Start};
use crate::geo::rotations::q_b_to_n;
use crate::io::gnss::GnssRecord;
use crate::{Error, Result};
use nalgebra::Vector3;
use serde::Serialize;

/// What the alignment found.
#[derive(Debug, Clone, Serialize)]
pub struct AlignmentReport {
    /// "auto" or "given".
    pub mode: String,
    /// Whether a static start was detected ("auto").
    pub static_start: bool,
    /// Initial roll, pitch, heading (deg).
    pub attitude_deg: [f64; 3],
    /// Their 1-sigma (deg).
    pub attitude_sigma_deg: [f64; 3],
    /// Time of the GNSS course that gave the heading (s), "auto".
    pub course_time_s: Option<f64>,
    /// Start time of the solution (s).
    pub start_time_s: f64,
}

fn fail(problem: String) -> Error {
    Error::Numerical {
        what: "initial alignment".into(),
        problem,
    }
}

/// Fix `i` as a geodetic point with zero velocity and attitude (for NED differences).
fn point(g: &GnssRecord) -> NavState {
    NavState {
        time_s: g.time_s,
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
        v_n: Vector3::zeros(),
        q_b_n: Default::default(),
    }
}

/// Largest distance (m) of a fix from the line through its neighbours for it to count as
/// consistent: an outlier (multipath) is metres off, a curve's sagitta over 1 s is decimetres.
const CONSISTENT_M: f64 = 0.5;

/// Whether fix `i` agrees with the straight-line extrapolation of fixes i+1 and i+2.
fn consistent(gnss: &[GnssRecord], i: usize) -> bool {
    let (Some(b), Some(c)) = (gnss.get(i + 1), gnss.get(i + 2)) else {
        return false;
    };
    let a = &gnss[i];
    let pb = point(b);
    let d_bc = pb.ned_to(c.lat_rad, c.lon_rad, c.h_m);
    let d_ba = pb.ned_to(a.lat_rad, a.lon_rad, a.h_m);
    let k = (a.time_s - b.time_s) / (c.time_s - b.time_s);
    (d_ba - d_bc * k).norm() <= CONSISTENT_M
}

/// The GNSS course: (time, heading (rad), NED velocity) of the first pair of fixes about 1 s
/// apart moving faster than `min_speed`, whose fix half way between agrees with them (an
/// outlier at either end or in the middle is skipped).
fn course(gnss: &[GnssRecord], from: usize, min_speed: f64) -> Option<(f64, f64, Vector3<f64>)> {
    let mut b = from;
    for a in from..gnss.len() {
        while b < gnss.len() && gnss[b].time_s < gnss[a].time_s + 0.95 {
            b += 1;
        }
        if b >= gnss.len() {
            return None;
        }
        let dt = gnss[b].time_s - gnss[a].time_s;
        if dt > 1.5 || b < a + 2 {
            continue;
        }
        let pa = point(&gnss[a]);
        let d = pa.ned_to(gnss[b].lat_rad, gnss[b].lon_rad, gnss[b].h_m);
        let tm = 0.5 * (gnss[a].time_s + gnss[b].time_s);
        let m = (a + 1..b)
            .min_by(|&i, &j| {
                (gnss[i].time_s - tm)
                    .abs()
                    .total_cmp(&(gnss[j].time_s - tm).abs())
            })
            .unwrap_or(a + 1);
        let w = (gnss[m].time_s - gnss[a].time_s) / dt;
        let dm = pa.ned_to(gnss[m].lat_rad, gnss[m].lon_rad, gnss[m].h_m);
        if (dm - d * w).norm() > CONSISTENT_M {
            continue;
        }
        let v = d / dt;
        if v.x.hypot(v.y) >= min_speed {
            return Some((tm, v.y.atan2(v.x), v));
        }
    }
    None
}

/// The filter's start from the data.
pub fn align(
    imu: &(impl ImuSource + ?Sized),
    gnss: &[GnssRecord],
    cfg: &AlignmentCfg,
    grade: &ImuGrade,
    lever_b: Vector3<f64>,
    gate: f64,
) -> Result<(Start, AlignmentReport)> {
    let n = imu.count();
    if n < 2 {
        return Err(fail("fewer than 2 IMU records".into()));
    }
    let t_imu0 = imu.get(0).time_s;
    let t_imu1 = imu.get(n - 1).time_s;
    // The first fix within the IMU span that agrees with the next two (not an outlier).
    let mut g0 = gnss.partition_point(|g| g.time_s < t_imu0);
    while g0 < gnss.len() && !consistent(gnss, g0) {
        g0 += 1;
    }
    let Some(fix0) = gnss.get(g0).filter(|g| g.time_s <= t_imu1) else {
        return Err(fail("no GNSS fix within the IMU records' time span".into()));
    };
    // The IMU record nearest the first fix.
    let mut index = 0;
    while index + 1 < n && imu.get(index + 1).time_s <= fix0.time_s {
        index += 1;
    }
    let t0 = imu.get(index).time_s;
    let deg = f64::to_radians;
    let (roll, pitch, heading, sig, v_n, static_start, course_time) = match cfg.mode.as_str() {
        "given" => {
            let a = cfg.attitude_deg.unwrap_or([0.0; 3]);
            let v = course(gnss, g0, 0.0)
                .map(|c| c.2)
                .unwrap_or_else(Vector3::zeros);
            (
                deg(a[0]),
                deg(a[1]),
                deg(a[2]),
                cfg.attitude_sigma_deg.map(deg),
                v,
                false,
                None,
            )
        }
        _ => {
            // Static while no rotation above 0.5 deg/s and the specific force stays within
            // 0.1 m/s^2 of the first record's magnitude, for at least 1 s. The records after
            // the start (the one at the start covers the interval before it).
            let mut sum_f = Vector3::zeros();
            let first = (index + 1).min(n - 1);
            let f_first = Vector3::from(imu.get(first).f_b).norm();
            let mut k = first;
            while k < n && imu.get(k).time_s <= t0 + cfg.static_s {
                let r = imu.get(k);
                let f = Vector3::from(r.f_b);
                if Vector3::from(r.w_b).norm() > 0.5f64.to_radians()
                    || (f.norm() - f_first).abs() > 0.1
                {
                    break;
                }
                sum_f += f;
                k += 1;
            }
            let count = k - first;
            let is_static = count >= 2 && imu.get(k - 1).time_s - t0 >= 1.0;
            let Some((tc, _, vc)) = course(gnss, g0, cfg.course_min_speed_mps) else {
                return Err(fail(format!(
                    "the GNSS positions never move faster than {} m/s \
                     (alignment.course_min_speed_mps): no course for the heading; give it \
                     with alignment.mode = \"given\"",
                    cfg.course_min_speed_mps
                )));
            };
            let h_sig = deg(cfg.course_heading_sigma_deg);
            let (roll, pitch, a_sig, v0) = if is_static {
                let f = sum_f / count as f64;
                let g = 9.8;
                let a_sig =
                    ((grade.accel.bias.powi(2) + grade.accel.instability.powi(2)).sqrt() * 2.0 / g)
                        .max(deg(0.005));
                (
                    (-f.y).atan2(-f.z),
                    f.x.atan2(f.y.hypot(f.z)),
                    a_sig,
                    Vector3::zeros(),
                )
            } else {
                let v0 = course(gnss, g0, 0.0).map_or_else(Vector3::zeros, |c| c.2);
                (0.0, 0.0, deg(5.0), v0)
            };
            // The course is the antenna's: take out the lever arm's rotation velocity
            // R (w x l), then go back from the course's time to the start with the yaw rate
            // (the van may drive off in a curve).
            let (mut yaw, mut w_tc) = (0.0, Vector3::zeros());
            let mut k = index + 1;
            let (sr, cr) = roll.sin_cos();
            while k < n && imu.get(k).time_s <= tc {
                let r = imu.get(k);
                let dt = r.time_s - imu.get(k - 1).time_s;
                yaw += (r.w_b[1] * sr + r.w_b[2] * cr) / pitch.cos() * dt;
                w_tc = Vector3::from(r.w_b);
                k += 1;
            }
            let h_tc = vc.y.atan2(vc.x);
            let lever_v = q_b_to_n(roll, pitch, h_tc) * w_tc.cross(&lever_b);
            let v_imu = vc - lever_v;
            let heading = v_imu.y.atan2(v_imu.x) - yaw;
            (
                roll,
                pitch,
                heading,
                [a_sig, a_sig, h_sig],
                v0,
                is_static,
                Some(tc),
            )
        }
    };
    let q = q_b_to_n(roll, pitch, heading);
    let mut nav = NavState {
        time_s: t0,
        lat_rad: fix0.lat_rad,
        lon_rad: fix0.lon_rad,
        h_m: fix0.h_m,
        v_n,
        q_b_n: q,
    };
    nav.shift_ned(&-(q * lever_b + v_n * (t0 - fix0.time_s)));
    let lever_sig = lever_b.norm() * sig.iter().fold(0.0f64, |a, b| a.max(*b));
    let pos_sig = fix0
        .sigma_ned_m
        .map(|s| (s * s + lever_sig * lever_sig).sqrt() * 1.5);
    let vel_sig = if static_start { 0.02 } else { 0.2 };
    let p = initial_covariance(grade, pos_sig, vel_sig, sig);
    let filter = Filter {
        nav,
        sens: SensorEstimate::default(),
        p,
        noise: ProcessNoise::of(grade),
        lever_b,
        gate,
    };
    let report = AlignmentReport {
        mode: cfg.mode.clone(),
        static_start,
        attitude_deg: [roll, pitch, crate::geo::rotations::wrap_two_pi(heading)]
            .map(f64::to_degrees),
        attitude_sigma_deg: sig.map(f64::to_degrees),
        course_time_s: course_time,
        start_time_s: t0,
    };
    Ok((Start { filter, index }, report))
}
