//! Scan-plane geometry along the trajectory (paper 004, section 3.2): the orthogonal distance
//! `d_p(t) = m(t) . (c - o(t))` of a sync point `c` (ECEF, m) to the scan plane through the
//! scanner's optical centre `o(t)` with normal `m(t) = R_b^e(t + tau) R_s^b x_s` (the mirror
//! axis, s-frame x), its zero crossings (when the scanner sweeps the point), and the
//! georeferenced return as a function of the clock parameters.

use crate::geo::ellipsoid::r_n_to_e;
use crate::georef::{georeference, point_s, r_b_to_e, Sensor};
use crate::trajectory::{NavSigma, Pose, PoseCursor, Trajectory};
use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};

/// Pose at `t` with attitude latency `tau_s`, or an error naming what was being done.
pub(crate) fn pose_at(traj: &Trajectory, tau_s: f64, t: f64, what: &str) -> Result<Pose> {
    PoseCursor::new(traj, tau_s, 0.0).at(t).map_err(|g| {
        Error::Invalid(format!(
            "sync: {what} at GPS time {t:.3} s: no navigation state ({g:?})"
        ))
    })
}

/// Scanner optical centre `o` (ECEF, m) and scan-plane normal `m` (ECEF unit vector).
pub(crate) fn scan_plane(pose: &Pose, sensor: &Sensor) -> (Vector3<f64>, Vector3<f64>) {
    let r = r_b_to_e(pose);
    let o = pose.nav.r_e_m + r * sensor.lever_arm_b_m;
    (o, r * sensor.r_s_to_b.column(0))
}

/// Signed orthogonal distance (m) of `c_e` to the scan plane of `pose`.
pub(crate) fn plane_distance(pose: &Pose, sensor: &Sensor, c_e: &Vector3<f64>) -> f64 {
    let (o, m) = scan_plane(pose, sensor);
    m.dot(&(c_e - o))
}

/// Mirror angle beta (rad) and scanner-frame range (m) at which `c_e` is seen from `pose`.
pub(crate) fn beta_and_range(pose: &Pose, sensor: &Sensor, c_e: &Vector3<f64>) -> (f64, f64) {
    let r = r_b_to_e(pose);
    let x_b = r.transpose() * (c_e - pose.nav.r_e_m) - sensor.lever_arm_b_m;
    let x_s = sensor.r_s_to_b.transpose() * x_b;
    ((-x_s.y).atan2(x_s.z), x_s.norm())
}

/// Navigation sigmas at `t`, zero without an SMRMSG file.
pub(crate) fn nav_sigma(traj: &Trajectory, t: f64) -> NavSigma {
    traj.sigma_cursor()
        .and_then(|mut c| c.at(t).ok())
        .unwrap_or(NavSigma {
            pos_ned_m: Vector3::zeros(),
            att_rph_rad: Vector3::zeros(),
        })
}

/// Position covariance in ECEF (m^2) from NED sigmas at `pose`.
pub(crate) fn position_cov_e(pose: &Pose, s: &NavSigma) -> Matrix3<f64> {
    let r = r_n_to_e(pose.nav.lat_rad, pose.nav.lon_rad);
    r * Matrix3::from_diagonal(&s.pos_ned_m.component_mul(&s.pos_ned_m)) * r.transpose()
}

/// Attitude covariance (rad^2) of a small body-frame rotation error, roll/pitch/heading taken
/// as rotations about body x, y, z (exact for level attitude, which is all the sigmas need).
pub(crate) fn attitude_cov_b(s: &NavSigma) -> Matrix3<f64> {
    Matrix3::from_diagonal(&s.att_rph_rad.component_mul(&s.att_rph_rad))
}

/// A time at which the scan plane sweeps a sync point within range.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Crossing {
    /// Index of the sync point.
    pub point: usize,
    /// GPS time of the crossing (s).
    pub t_s: f64,
    /// Mirror angle towards the point (rad).
    pub beta_rad: f64,
    /// Range to the point (m).
    pub range_m: f64,
    /// d(d_p)/dt at the crossing (m/s).
    pub rate_mps: f64,
    /// 1-sigma of d_p from navigation and survey errors (m).
    pub sigma_d_m: f64,
}

/// Every zero crossing of `d_p` for every point in `[t_a, t_b]` with the point closer than
/// `max_range_m`, found on a `step_s` grid and refined by bisection to 1e-7 s.
#[allow(clippy::too_many_arguments)]
pub(crate) fn crossings(
    traj: &Trajectory,
    sensor: &Sensor,
    tau_s: f64,
    points: &[(Vector3<f64>, f64)],
    t_a: f64,
    t_b: f64,
    step_s: f64,
    max_range_m: f64,
) -> Result<Vec<Crossing>> {
    let mut cursor = PoseCursor::new(traj, tau_s, 0.0);
    let mut prev: Vec<Option<f64>> = vec![None; points.len()];
    let mut out = Vec::new();
    let steps = ((t_b - t_a) / step_s).floor() as usize;
    for k in 0..=steps {
        let t = t_a + k as f64 * step_s;
        let Ok(pose) = cursor.at(t) else {
            prev.iter_mut().for_each(|p| *p = None);
            continue;
        };
        for (i, (c, sigma_c)) in points.iter().enumerate() {
            let (o, _) = scan_plane(&pose, sensor);
            let d = plane_distance(&pose, sensor, c);
            let near = (c - o).norm() < max_range_m;
            if let (Some(dp), true) = (prev[i], near) {
                if dp.signum() != d.signum() {
                    out.push(refine(traj, sensor, tau_s, i, c, *sigma_c, t - step_s, t)?);
                }
            }
            prev[i] = near.then_some(d);
        }
    }
    out.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    Ok(out)
}

#[allow(clippy::too_many_arguments)]
fn refine(
    traj: &Trajectory,
    sensor: &Sensor,
    tau_s: f64,
    point: usize,
    c: &Vector3<f64>,
    sigma_c: f64,
    mut lo: f64,
    mut hi: f64,
) -> Result<Crossing> {
    let d = |t: f64| -> Result<f64> {
        Ok(plane_distance(
            &pose_at(traj, tau_s, t, "plane crossing")?,
            sensor,
            c,
        ))
    };
    let d_lo = d(lo)?;
    while hi - lo > 1e-7 {
        let mid = 0.5 * (lo + hi);
        if d(mid)?.signum() == d_lo.signum() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let t = 0.5 * (lo + hi);
    let h = 1e-3;
    let rate = (d(t + h)? - d(t - h)?) / (2.0 * h);
    let pose = pose_at(traj, tau_s, t, "plane crossing")?;
    let (beta_rad, range_m) = beta_and_range(&pose, sensor, c);
    let s = nav_sigma(traj, t);
    let (o, m) = scan_plane(&pose, sensor);
    // d = m.(c - o): position error moves o, attitude error turns m and the lever arm.
    let r = r_b_to_e(&pose);
    let (m_b, w_b) = (
        sensor.r_s_to_b.column(0).into_owned(),
        r.transpose() * (c - o),
    );
    let g = m_b.cross(&w_b) - sensor.lever_arm_b_m.cross(&m_b);
    let var = (m.transpose() * position_cov_e(&pose, &s) * m)[0]
        + sigma_c * sigma_c
        + (g.transpose() * attitude_cov_b(&s) * g)[0];
    Ok(Crossing {
        point,
        t_s: t,
        beta_rad,
        range_m,
        rate_mps: rate,
        sigma_d_m: var.sqrt(),
    })
}

/// A return on a sync target, as recorded.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TargetReturn {
    /// Profile number.
    pub profile: u32,
    /// Mirror angle (rad).
    pub beta_rad: f64,
    /// Out-of-plane angle (rad).
    pub alpha_rad: f64,
    /// Measured range (m).
    pub range_m: f64,
    /// Intensity.
    pub intensity: u16,
}

/// Georeferenced return (ECEF, m) at return time `t` with attitude latency `tau_s`.
pub(crate) fn return_point(
    traj: &Trajectory,
    sensor: &Sensor,
    r: &TargetReturn,
    t: f64,
    tau_s: f64,
) -> Result<(Vector3<f64>, Pose)> {
    let pose = pose_at(traj, tau_s, t, "target return")?;
    let x = georeference(
        &pose,
        sensor,
        &point_s(sensor, r.range_m, r.alpha_rad, r.beta_rad),
    );
    Ok((x, pose))
}
