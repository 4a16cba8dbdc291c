//! The navigation trajectory: position, attitude and their sigmas at any time.
//!
//! Interpolation (the one definition shared by the pipeline and the simulator):
//! ECEF position, latitude, longitude, height, NED velocity and body rates are linear in time
//! between neighbouring records; attitude `R_b^n` is spherical-linear (quaternion slerp on the
//! shorter arc, so heading wraps through 359 -> 1 deg correctly, never Euler interpolation).
//! SMRMSG sigmas are linear in time. Latency (conventions §2): [`PoseCursor`] evaluates position at `t`
//! and attitude at `t + tau`.

use crate::geo::ellipsoid::{geodetic_to_ecef, Geodetic};
use crate::geo::rotations::{q_b_to_n, wrap_pi};
use crate::io::sbet::{SbetFile, SbetRecord};
use crate::io::smrmsg::{SmrmsgFile, SmrmsgRecord, RAD_PER_ARCMIN};
use crate::Result;
use nalgebra::{Quaternion, UnitQuaternion, Vector3, Vector4};
use std::path::Path;

/// Navigation state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavSample {
    /// GPS time (s).
    pub t_s: f64,
    /// IMU origin in ECEF `e` (m).
    pub r_e_m: Vector3<f64>,
    /// Geodetic latitude (rad).
    pub lat_rad: f64,
    /// Longitude (rad), (-pi, pi].
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub h_m: f64,
    /// Attitude `R_b^n` as a unit quaternion (body to NED).
    pub q_b_to_n: UnitQuaternion<f64>,
    /// Velocity in NED (m/s).
    pub v_n_mps: Vector3<f64>,
    /// Body angular rate (rad/s), body axes.
    pub omega_b_radps: Vector3<f64>,
}

impl NavSample {
    /// State from an SBET record: true heading = platform heading - wander angle; velocity
    /// rotated from the wander-azimuth frame to NED.
    pub fn from_sbet(r: &SbetRecord) -> Self {
        let g = Geodetic {
            lat_rad: r.lat_rad,
            lon_rad: r.lon_rad,
            h_m: r.alt_m,
        };
        let (sw, cw) = r.wander_rad.sin_cos();
        // Wander x axis lies at azimuth -wander: v_w = R(wander) v_ne.
        let v_n = Vector3::new(
            cw * r.vel_x_mps + sw * r.vel_y_mps,
            -sw * r.vel_x_mps + cw * r.vel_y_mps,
            r.vel_z_mps,
        );
        NavSample {
            t_s: r.time_s,
            r_e_m: geodetic_to_ecef(g),
            lat_rad: r.lat_rad,
            lon_rad: wrap_pi(r.lon_rad),
            h_m: r.alt_m,
            q_b_to_n: q_b_to_n(r.roll_rad, r.pitch_rad, r.true_heading_rad()),
            v_n_mps: v_n,
            omega_b_radps: Vector3::new(r.rate_x_radps, r.rate_y_radps, r.rate_z_radps),
        }
    }
}

/// Spherical linear interpolation from `a` (w = 0) to `b` (w = 1) along the shorter arc.
#[inline]
pub fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, w: f64) -> UnitQuaternion<f64> {
    Slerp::new(a, b).at(w)
}

/// [`slerp`] between one pair of attitudes, with the pair's constants (shortest-path sign,
/// angle, `1 / sin(angle)`) computed once for many weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slerp {
    qa: Vector4<f64>,
    qb: Vector4<f64>,
    theta: f64,
    inv_sin_theta: f64,
}

impl Slerp {
    /// From `a` (weight 0) to `b` (weight 1).
    pub fn new(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> Self {
        let (qa, mut qb) = (a.quaternion().coords, b.quaternion().coords);
        let mut dot = qa.dot(&qb);
        if dot < 0.0 {
            qb = -qb;
            dot = -dot;
        }
        let theta = dot.min(1.0).acos();
        Slerp {
            qa,
            qb,
            theta,
            inv_sin_theta: 1.0 / theta.sin(),
        }
    }

    /// The attitude at weight `w`.
    #[inline]
    pub fn at(&self, w: f64) -> UnitQuaternion<f64> {
        let coords = if self.theta < 1e-6 {
            // Linear blend: error O(theta^3) < 1e-18 rad here.
            self.qa * (1.0 - w) + self.qb * w
        } else {
            let (t, k) = (self.theta, self.inv_sin_theta);
            self.qa * (((1.0 - w) * t).sin() * k) + self.qb * ((w * t).sin() * k)
        };
        UnitQuaternion::from_quaternion(Quaternion::from(coords))
    }
}

/// Interpolates between `a` and `b` at `t` (normally `a.t_s <= t <= b.t_s`; a small
/// extrapolation is linear too).
#[inline]
pub fn interpolate(a: &NavSample, b: &NavSample, t: f64) -> NavSample {
    interpolate_with(a, b, &Slerp::new(&a.q_b_to_n, &b.q_b_to_n), t)
}

/// [`interpolate`] with the attitude pair's [`Slerp`] given.
#[inline]
fn interpolate_with(a: &NavSample, b: &NavSample, attitude: &Slerp, t: f64) -> NavSample {
    let w = (t - a.t_s) / (b.t_s - a.t_s);
    let lerp = |x: f64, y: f64| x + w * (y - x);
    NavSample {
        t_s: t,
        r_e_m: a.r_e_m + (b.r_e_m - a.r_e_m) * w,
        lat_rad: lerp(a.lat_rad, b.lat_rad),
        lon_rad: wrap_pi(a.lon_rad + w * wrap_pi(b.lon_rad - a.lon_rad)),
        h_m: lerp(a.h_m, b.h_m),
        q_b_to_n: attitude.at(w),
        v_n_mps: a.v_n_mps + (b.v_n_mps - a.v_n_mps) * w,
        omega_b_radps: a.omega_b_radps + (b.omega_b_radps - a.omega_b_radps) * w,
    }
}

/// Why a time cannot be given a navigation state: per-return rejection reasons.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NavGap {
    /// Before the first or after the last trajectory record.
    OutsideTrajectory,
    /// Between two records further apart than the configured maximum gap.
    TrajectoryGap,
    /// Outside the SMRMSG span (sigmas requested but not available).
    OutsideAccuracy,
}

/// Navigation sigmas (1 sigma) at one instant (conventions §5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavSigma {
    /// North, east, down position sigma (m).
    pub pos_ned_m: Vector3<f64>,
    /// Roll, pitch, heading sigma (rad).
    pub att_rph_rad: Vector3<f64>,
}

/// Trajectory options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryOptions {
    /// Longest interval between records that may be interpolated across (s).
    pub max_gap_s: f64,
    /// Added to the SBET true heading (rad): `R_b^n = Rz(heading + offset) Ry(pitch) Rx(roll)`
    /// (docs/conventions.md §3).
    pub heading_offset_rad: f64,
}

impl Default for TrajectoryOptions {
    /// `max_gap_s` 0.1 s (the `trajectory.max_gap_s` default of pipeline files).
    fn default() -> Self {
        TrajectoryOptions {
            max_gap_s: 0.1,
            heading_offset_rad: 0.0,
        }
    }
}

/// A memory-mapped SBET (and optional SMRMSG) trajectory. Records are decoded on demand by
/// cursors, so memory does not grow with the length of the day.
#[derive(Debug)]
pub struct Trajectory {
    sbet: SbetFile,
    smrmsg: Option<SmrmsgFile>,
    opts: TrajectoryOptions,
    /// [`Trajectory::motion_checks`], made on first use.
    motion: std::sync::OnceLock<MotionChecks>,
}

impl Trajectory {
    /// Opens and validates the SBET and, if given, the SMRMSG file.
    pub fn open(sbet: &Path, smrmsg: Option<&Path>, opts: TrajectoryOptions) -> Result<Self> {
        let sbet = SbetFile::open(sbet)?;
        let smrmsg = smrmsg.map(SmrmsgFile::open).transpose()?;
        Ok(Trajectory {
            sbet,
            smrmsg,
            opts,
            motion: std::sync::OnceLock::new(),
        })
    }

    /// The SBET file.
    pub fn sbet(&self) -> &SbetFile {
        &self.sbet
    }

    /// The SMRMSG file, if any.
    pub fn smrmsg(&self) -> Option<&SmrmsgFile> {
        self.smrmsg.as_ref()
    }

    /// Lets the kernel drop the mapped pages of the SBET and SMRMSG files (re-read from the
    /// page cache when touched again): a pass that jumps about the day calls it between
    /// batches, so the pages it read stay resident no longer than a batch (a 2000 s SBET is
    /// 54 MB).
    pub fn release(&self) {
        self.sbet.release_all();
        if let Some(m) = &self.smrmsg {
            m.release_all();
        }
    }

    /// [`Trajectory::release`] of the records from `t0_s` to `t1_s` only (s, GPS; widened by
    /// `margin_s` for the latencies): for a visit, whose neighbours in the batch other threads
    /// may be reading.
    pub fn release_times(&self, t0_s: f64, t1_s: f64, margin_s: f64) {
        self.sbet.release_times(t0_s - margin_s, t1_s + margin_s);
        if let Some(m) = &self.smrmsg {
            m.release_times(t0_s - margin_s, t1_s + margin_s);
        }
    }

    /// First and last SBET times (s).
    pub fn span_s(&self) -> (f64, f64) {
        (self.sbet.time_s(0), self.sbet.time_s(self.sbet.len() - 1))
    }

    /// Navigation state of SBET record `i` with the heading offset applied. The offset turns
    /// `R_b^n` about the n-frame z axis (`Rz(h + dh) = Rz(dh) Rz(h)`), so it commutes with the
    /// slerp between records.
    fn sample(&self, i: usize) -> NavSample {
        let mut s = NavSample::from_sbet(&self.sbet.record(i));
        if self.opts.heading_offset_rad != 0.0 {
            let dh =
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.opts.heading_offset_rad);
            s.q_b_to_n = dh * s.q_b_to_n;
        }
        s
    }

    /// The SBET interval GPS time `t` (s) falls in: the index `i` of its first record
    /// (`t(i) <= t <= t(i + 1)`) and the interpolation weight of record `i + 1`; `None`
    /// outside the trajectory.
    pub fn interval_at(&self, t: f64) -> Option<(usize, f64)> {
        let s = &self.sbet;
        let i = locate(s.len(), |k| s.time_s(k), usize::MAX, t)?;
        let (a, b) = (s.time_s(i), s.time_s(i + 1));
        Some((i, ((t - a) / (b - a)).clamp(0.0, 1.0)))
    }

    /// A cursor for time-ordered queries (cheap; one per thread or chunk).
    pub fn cursor(&self) -> NavCursor<'_> {
        NavCursor {
            traj: self,
            idx: usize::MAX,
            a: None,
            b: None,
            attitude: None,
        }
    }

    /// A cursor over SMRMSG sigmas, or `None` without an SMRMSG file.
    pub fn sigma_cursor(&self) -> Option<SigmaCursor<'_>> {
        self.smrmsg.as_ref().map(|f| SigmaCursor {
            file: f,
            idx: usize::MAX,
            interval: (0.0, [0.0; 6], [0.0; 6]),
        })
    }
}

/// Index `i` with `t(i) <= t < t(i+1)` (or the last interval for t == last), found from a
/// previous index first (time-ordered queries) and by bisection otherwise.
fn locate(len: usize, time: impl Fn(usize) -> f64, hint: usize, t: f64) -> Option<usize> {
    if len < 2 || t < time(0) || t > time(len - 1) {
        return None;
    }
    for i in [hint, hint.wrapping_add(1)] {
        if i < len - 1 && time(i) <= t && t <= time(i + 1) {
            return Some(i);
        }
    }
    let (mut lo, mut hi) = (0, len - 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if time(mid) <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// Interpolating cursor over the SBET; caches the current interval's decoded records and
/// their [`Slerp`].
pub struct NavCursor<'a> {
    traj: &'a Trajectory,
    idx: usize,
    a: Option<NavSample>,
    b: Option<NavSample>,
    attitude: Option<Slerp>,
}

impl NavCursor<'_> {
    /// Navigation state at GPS time `t` (s).
    pub fn at(&mut self, t: f64) -> Result<NavSample, NavGap> {
        let sbet = &self.traj.sbet;
        let i =
            locate(sbet.len(), |k| sbet.time_s(k), self.idx, t).ok_or(NavGap::OutsideTrajectory)?;
        if i != self.idx {
            // Moving one interval forward reuses the decoded end record.
            let a = match (self.b, i == self.idx.wrapping_add(1)) {
                (Some(b), true) => b,
                _ => self.traj.sample(i),
            };
            let b = self.traj.sample(i + 1);
            self.attitude = Some(Slerp::new(&a.q_b_to_n, &b.q_b_to_n));
            (self.a, self.b) = (Some(a), Some(b));
            self.idx = i;
        }
        let (a, b, attitude) = (
            self.a.as_ref().expect("set above"),
            self.b.as_ref().expect("set above"),
            self.attitude.as_ref().expect("set above"),
        );
        if b.t_s - a.t_s > self.traj.opts.max_gap_s {
            return Err(NavGap::TrajectoryGap);
        }
        Ok(interpolate_with(a, b, attitude, t))
    }
}

/// Interpolating cursor over SMRMSG sigmas; caches the current interval as a start value and
/// a rate (sigmas are linear in time between records).
pub struct SigmaCursor<'a> {
    file: &'a SmrmsgFile,
    idx: usize,
    /// Start time (s), sigmas at it and their rates per second: north, east, down (m), roll,
    /// pitch, heading (rad).
    interval: (f64, [f64; 6], [f64; 6]),
}

impl SigmaCursor<'_> {
    /// Sigmas at GPS time `t` (s), linear between records.
    pub fn at(&mut self, t: f64) -> Result<NavSigma, NavGap> {
        let f = self.file;
        let i = locate(f.len(), |k| f.time_s(k), self.idx, t).ok_or(NavGap::OutsideAccuracy)?;
        if i != self.idx {
            let (a, b) = (f.record(i), f.record(i + 1));
            let v = |r: &SmrmsgRecord| {
                let rad = RAD_PER_ARCMIN;
                [
                    r.north_m,
                    r.east_m,
                    r.down_m,
                    r.roll_arcmin * rad,
                    r.pitch_arcmin * rad,
                    r.heading_arcmin * rad,
                ]
            };
            let (va, vb) = (v(&a), v(&b));
            let dt = b.time_s - a.time_s;
            self.interval = (a.time_s, va, std::array::from_fn(|k| (vb[k] - va[k]) / dt));
            self.idx = i;
        }
        let (t_a, a, rate) = &self.interval;
        let dt = t - t_a;
        let l = |k: usize| a[k] + rate[k] * dt;
        Ok(NavSigma {
            pos_ned_m: Vector3::new(l(0), l(1), l(2)),
            att_rph_rad: Vector3::new(l(3), l(4), l(5)),
        })
    }
}

/// The navigation state without attitude, at `t + position latency`: position, geodetic
/// coordinates and velocity. (A [`Pose`]'s attitude is evaluated at `t + tau`, so this part
/// carries none, and the attitude at the wrong time cannot be picked up by mistake.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavPosition {
    /// GPS time (s) at which it is evaluated.
    pub t_s: f64,
    /// IMU origin in ECEF `e` (m).
    pub r_e_m: Vector3<f64>,
    /// Geodetic latitude (rad).
    pub lat_rad: f64,
    /// Longitude (rad), (-pi, pi].
    pub lon_rad: f64,
    /// Ellipsoidal height (m).
    pub h_m: f64,
    /// Velocity in NED (m/s).
    pub v_n_mps: Vector3<f64>,
}

impl NavSample {
    /// The state without its attitude.
    #[inline]
    pub fn position(&self) -> NavPosition {
        NavPosition {
            t_s: self.t_s,
            r_e_m: self.r_e_m,
            lat_rad: self.lat_rad,
            lon_rad: self.lon_rad,
            h_m: self.h_m,
            v_n_mps: self.v_n_mps,
        }
    }
}

/// Pose for georeferencing one return: position at `t` (+ position latency), attitude at
/// `t + tau` (conventions §2). It carries one attitude, the one the equation uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position, geodetic coordinates and velocity at `t + position latency`.
    pub nav: NavPosition,
    /// Attitude `R_b^n` at `t + tau`.
    pub q_b_to_n: UnitQuaternion<f64>,
    /// Body angular rate at `t + tau` (rad/s).
    pub omega_b_radps: Vector3<f64>,
}

impl Pose {
    /// The pose of one navigation state (no latency).
    #[inline]
    pub fn of(nav: &NavSample) -> Self {
        Pose::split(nav, nav)
    }

    /// Position from `position`, attitude and body rate from `attitude`.
    #[inline]
    pub fn split(position: &NavSample, attitude: &NavSample) -> Self {
        Pose {
            nav: position.position(),
            q_b_to_n: attitude.q_b_to_n,
            omega_b_radps: attitude.omega_b_radps,
        }
    }
}

/// Two cursors (position and attitude) applying the latencies.
pub struct PoseCursor<'a> {
    pos: NavCursor<'a>,
    att: NavCursor<'a>,
    attitude_latency_s: f64,
    position_latency_s: f64,
}

impl<'a> PoseCursor<'a> {
    /// Cursor with attitude latency `tau` and position latency (s), conventions §2 signs.
    pub fn new(traj: &'a Trajectory, attitude_latency_s: f64, position_latency_s: f64) -> Self {
        PoseCursor {
            pos: traj.cursor(),
            att: traj.cursor(),
            attitude_latency_s,
            position_latency_s,
        }
    }

    /// Pose for a return measured at GPS time `t` (s).
    #[inline]
    pub fn at(&mut self, t: f64) -> Result<Pose, NavGap> {
        let nav = self.pos.at(t + self.position_latency_s)?;
        if self.attitude_latency_s == self.position_latency_s {
            return Ok(Pose::of(&nav));
        }
        let att = self.att.at(t + self.attitude_latency_s)?;
        Ok(Pose::split(&nav, &att))
    }
}

/// Where the body rates, or the velocities, of a [`Pose`] come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionSource {
    /// The SBET's own rate (velocity) fields.
    SbetFields,
    /// Central differences of the trajectory's attitude ([`derived_rates`]) or position
    /// ([`derived_velocity`]): the SBET fields are empty or disagree with it.
    Trajectory,
}

/// The fields unless their difference from what the trajectory implies is above a quarter of
/// that (and `floor`).
fn motion_source(difference_rms: f64, derived_rms: f64, floor: f64) -> MotionSource {
    if difference_rms > (0.25 * derived_rms).max(floor) {
        MotionSource::Trajectory
    } else {
        MotionSource::SbetFields
    }
}

/// The SBET's body-rate fields against the rates its attitude implies, on up to `samples`
/// record pairs spread over the file: the rms of the fields, of the derived rates, and of
/// their difference (rad/s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RateCheck {
    /// Rms of the SBET rate fields (rad/s).
    pub fields_rms_radps: f64,
    /// Rms of the rates from consecutive attitudes (rad/s).
    pub derived_rms_radps: f64,
    /// Rms of fields minus derived (rad/s).
    pub difference_rms_radps: f64,
    /// Which the diagnosis uses: the fields unless they are empty or off by more than a
    /// quarter of the derived rms (and 0.1 deg/s).
    pub source: MotionSource,
}

/// The SBET's velocity fields against the velocity of its own positions over
/// [`VELOCITY_HALF_BASELINE_S`] either side, on up to 2000 record pairs spread over the file:
/// the rms of the fields, of the derived velocity, and of their difference (m/s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct VelocityCheck {
    /// Rms of the SBET velocity fields (m/s).
    pub fields_rms_mps: f64,
    /// Rms of the velocity of the positions (m/s).
    pub derived_rms_mps: f64,
    /// Rms of fields minus derived (m/s).
    pub difference_rms_mps: f64,
    /// Which the diagnosis uses: the fields unless they are empty or off by more than a
    /// quarter of the derived rms (and 0.1 m/s).
    pub source: MotionSource,
}

/// Where the body rates and the velocities that the timing signatures need come from, each
/// checked on its own: an SBET can leave its rate fields empty and fill its velocities.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MotionChecks {
    /// The SBET's body-rate fields against the rates of its own attitude.
    pub rates: RateCheck,
    /// The SBET's velocity fields against the velocity of its own positions.
    pub velocities: VelocityCheck,
}

/// Half the baseline (s) of the velocity derived from the trajectory's positions
/// ([`derived_velocity`], [`Trajectory::velocity_check`]): long enough that the
/// record-to-record steps of the navigation position error (an error drawn per record has no
/// derivative; over one 5 ms record they are noise of about 0.06 m/s in the simulator, which
/// in the position latency's signature biased its estimate about 30% low) shrink 20-fold
/// against one record's, short enough that the chord of a turn is its tangent (0.4% at
/// 1.5 rad/s).
pub const VELOCITY_HALF_BASELINE_S: f64 = 0.1;

impl Trajectory {
    /// Rms of the fields, of what the trajectory implies and of their difference, over up to
    /// 2000 record pairs `k` records apart spread over the file; `pair` gives a pair's field
    /// value and derived value.
    fn compare_fields(
        &self,
        k: usize,
        pair: impl Fn(&NavSample, &NavSample, f64) -> (Vector3<f64>, Vector3<f64>),
    ) -> [f64; 3] {
        let sbet = self.sbet();
        let n = sbet.len();
        let step = (n / 2000).max(1);
        let (mut f2, mut d2, mut e2, mut count) = (0.0, 0.0, 0.0, 0.0f64);
        let mut i = 0;
        while i + k < n {
            let a = NavSample::from_sbet(&sbet.record(i));
            let b = NavSample::from_sbet(&sbet.record(i + k));
            let dt = b.t_s - a.t_s;
            if dt > 0.0 {
                let (fields, derived) = pair(&a, &b, dt);
                f2 += fields.norm_squared();
                d2 += derived.norm_squared();
                e2 += (fields - derived).norm_squared();
                count += 1.0;
            }
            i += step;
        }
        // The samples spread over the whole file, and each fault maps its neighbours: without
        // this the check leaves all of the SBET resident.
        self.release();
        [f2, d2, e2].map(|x| (x / count.max(1.0)).sqrt())
    }

    /// Compares the SBET rate fields with the rates of its own attitude (consecutive records).
    pub fn rate_check(&self) -> RateCheck {
        let [fields, derived, diff] = self.compare_fields(1, |a, b, dt| {
            let derived = (a.q_b_to_n.inverse() * b.q_b_to_n).scaled_axis() / dt;
            ((a.omega_b_radps + b.omega_b_radps) / 2.0, derived)
        });
        RateCheck {
            fields_rms_radps: fields,
            derived_rms_radps: derived,
            difference_rms_radps: diff,
            source: motion_source(diff, derived, 0.1f64.to_radians()),
        }
    }

    /// Compares the SBET velocity fields with the velocity of its own positions (records
    /// `2 VELOCITY_HALF_BASELINE_S` apart, at least consecutive ones).
    pub fn velocity_check(&self) -> VelocityCheck {
        let k = (2.0 * VELOCITY_HALF_BASELINE_S / self.record_spacing_s()).round() as usize;
        let [fields, derived, diff] = self.compare_fields(k.max(1), |a, b, dt| {
            let r_n_to_e = crate::geo::ellipsoid::r_n_to_e(a.lat_rad, a.lon_rad);
            let derived = r_n_to_e.transpose() * (b.r_e_m - a.r_e_m) / dt;
            ((a.v_n_mps + b.v_n_mps) / 2.0, derived)
        });
        VelocityCheck {
            fields_rms_mps: fields,
            derived_rms_mps: derived,
            difference_rms_mps: diff,
            source: motion_source(diff, derived, 0.1),
        }
    }

    /// Both checks: where the diagnosis takes the body rates and the velocities from (made
    /// once per trajectory: every profile file and every re-observation asks).
    pub fn motion_checks(&self) -> MotionChecks {
        *self.motion.get_or_init(|| MotionChecks {
            rates: self.rate_check(),
            velocities: self.velocity_check(),
        })
    }

    /// Mean spacing of the SBET's records (s).
    pub fn record_spacing_s(&self) -> f64 {
        let (t0, t1) = self.span_s();
        (t1 - t0) / self.sbet().len().max(2) as f64
    }
}

/// Body angular rate (rad/s, at `t + tau`) from the trajectory's own attitude, by central
/// differences over `h_s` either side: for an SBET whose rate fields are empty or disagree
/// with it.
pub fn derived_rates(cursor: &mut PoseCursor, t: f64, h_s: f64) -> Result<Vector3<f64>, NavGap> {
    let (a, b) = (cursor.at(t - h_s)?, cursor.at(t + h_s)?);
    Ok((a.q_b_to_n.inverse() * b.q_b_to_n).scaled_axis() / (2.0 * h_s))
}

/// NED velocity (m/s, at `t` + position latency) from the trajectory's own positions, by
/// central differences over `h_s` either side: for an SBET whose velocity fields are empty or
/// disagree with it.
pub fn derived_velocity(cursor: &mut PoseCursor, t: f64, h_s: f64) -> Result<Vector3<f64>, NavGap> {
    let (a, b) = (cursor.at(t - h_s)?, cursor.at(t + h_s)?);
    let r_n_to_e = crate::geo::ellipsoid::r_n_to_e(a.nav.lat_rad, a.nav.lon_rad);
    Ok(r_n_to_e.transpose() * (b.nav.r_e_m - a.nav.r_e_m) / (2.0 * h_s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::rotations::roll_pitch_heading;

    #[test]
    fn slerp_crosses_north_the_short_way() {
        let a = q_b_to_n(0.0, 0.0, 359f64.to_radians());
        let b = q_b_to_n(0.0, 0.0, 1f64.to_radians());
        for k in 0..=10 {
            let w = k as f64 / 10.0;
            let (_, _, h) = roll_pitch_heading(&slerp(&a, &b, w));
            let expect = (359.0 + 2.0 * w).rem_euclid(360.0);
            let err = wrap_pi(h - expect.to_radians()).abs();
            assert!(err < 1e-12, "w {w}: heading {} deg", h.to_degrees());
        }
    }

    #[test]
    fn slerp_constant_rate_about_a_fixed_axis() {
        // Interpolating a rotation about one axis must give the angle linear in w.
        let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8));
        let a = UnitQuaternion::from_axis_angle(&axis, 0.2);
        let b = UnitQuaternion::from_axis_angle(&axis, 0.9);
        let mid = slerp(&a, &b, 0.25);
        let expect = UnitQuaternion::from_axis_angle(&axis, 0.2 + 0.25 * 0.7);
        assert!(mid.angle_to(&expect) < 1e-14);
        let same = slerp(&a, &a, 0.7);
        assert!(same.angle_to(&a) < 1e-15);
    }

    /// The heading offset adds to the true heading of every interpolated attitude and leaves
    /// A turn at 0.5 rad/s with roll vibrating at 3 Hz: with the rate fields filled the SBET's
    /// own are used; written as zeros (some exports leave them empty) the rates come from the
    /// attitude, and they match the true rates to the central difference's error.
    /// `records` written to `path` as an SBET and opened as a trajectory.
    fn written(path: &Path, records: impl IntoIterator<Item = SbetRecord>) -> Trajectory {
        let mut w = crate::io::timed::TimedWriter::<SbetRecord>::create(path).unwrap();
        for rec in records {
            w.push(&rec).unwrap();
        }
        w.finish().unwrap();
        Trajectory::open(path, None, TrajectoryOptions::default()).unwrap()
    }

    #[test]
    fn empty_rate_fields_are_replaced_by_the_attitude_s_rates() {
        let dir = std::env::temp_dir().join(format!("kinescan_rates_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (rate_hz, yaw_rate, vib, f_hz) = (200.0, 0.5, 0.3f64.to_radians(), 3.0);
        let write = |name: &str, filled: bool| {
            let records = (0..2000).map(|k| {
                let t = k as f64 / rate_hz;
                let w_roll = std::f64::consts::TAU * f_hz;
                let roll = vib * (w_roll * t).sin();
                let roll_rate = vib * w_roll * (w_roll * t).cos();
                // Body rates of R = Rz(h) Rx(roll): p = roll rate, q = h' sin roll, r = h' cos roll.
                SbetRecord {
                    time_s: t,
                    lat_rad: 0.8,
                    roll_rad: roll,
                    platform_heading_rad: yaw_rate * t,
                    rate_x_radps: if filled { roll_rate } else { 0.0 },
                    rate_y_radps: if filled { yaw_rate * roll.sin() } else { 0.0 },
                    rate_z_radps: if filled { yaw_rate * roll.cos() } else { 0.0 },
                    ..Default::default()
                }
            });
            written(&dir.join(name), records)
        };
        let filled = write("filled.sbet", true).rate_check();
        assert_eq!(filled.source, MotionSource::SbetFields, "{filled:?}");
        let empty_traj = write("empty.sbet", false);
        let empty = empty_traj.rate_check();
        assert_eq!(empty.source, MotionSource::Trajectory, "{empty:?}");
        let mut cursor = PoseCursor::new(&empty_traj, 0.0, 0.0);
        let t = 3.0;
        let omega = derived_rates(&mut cursor, t, 1.0 / rate_hz).unwrap();
        let w_roll = std::f64::consts::TAU * f_hz;
        let roll = vib * (w_roll * t).sin();
        let truth = Vector3::new(
            vib * w_roll * (w_roll * t).cos(),
            yaw_rate * roll.sin(),
            yaw_rate * roll.cos(),
        );
        // Central difference over 10 ms of a 3 Hz vibration: relative error (w h)^2 / 6 = 6e-4
        // of the 0.1 rad/s vibration rate, plus the slerp's second order.
        let err = (omega - truth).norm();
        assert!(
            err < 2e-4,
            "derived {omega:?} vs true {truth:?}: {err:e} rad/s"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An SBET moving east at 10 m/s whose positions carry a white error drawn per 5 ms
    /// record (1 cm per axis), as a Gauss-Markov error drawn per record does at that step:
    /// with the velocity fields filled, the check keeps them; zeroed, it takes the velocity of
    /// the positions, whose error over the +-0.1 s baseline is sqrt(2) 1 cm / 0.2 s = 0.07 m/s
    /// per axis (against 2.8 m/s over one record).
    #[test]
    fn empty_velocity_fields_are_replaced_by_the_positions_velocity() {
        use crate::geo::ellipsoid::prime_vertical_radius_m;
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let dir = std::env::temp_dir().join(format!("kinescan_vel_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (rate_hz, speed, lat, sigma_m) = (200.0, 10.0, 0.8f64, 0.01);
        let east_radius = prime_vertical_radius_m(lat) * lat.cos();
        let write = |name: &str, filled: bool| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
            let jitter = Normal::new(0.0, sigma_m).unwrap();
            let records = (0..6000).map(|k| {
                let t = k as f64 / rate_hz;
                let (north_m, east_m) = (jitter.sample(&mut rng), jitter.sample(&mut rng));
                SbetRecord {
                    time_s: t,
                    lat_rad: lat + north_m / crate::geo::ellipsoid::meridian_radius_m(lat),
                    lon_rad: (speed * t + east_m) / east_radius,
                    vel_y_mps: if filled { speed } else { 0.0 },
                    platform_heading_rad: std::f64::consts::FRAC_PI_2,
                    ..Default::default()
                }
            });
            written(&dir.join(name), records)
        };
        let filled = write("filled.sbet", true).velocity_check();
        assert_eq!(filled.source, MotionSource::SbetFields, "{filled:?}");
        assert!(filled.difference_rms_mps < 0.15, "{filled:?}");
        let empty_traj = write("empty.sbet", false);
        let empty = empty_traj.velocity_check();
        assert_eq!(empty.source, MotionSource::Trajectory, "{empty:?}");
        let mut cursor = PoseCursor::new(&empty_traj, 0.0, 0.0);
        let errors: Vec<f64> = (0..200)
            .map(|i| {
                let t = 1.0 + 0.137 * i as f64;
                let v = derived_velocity(&mut cursor, t, VELOCITY_HALF_BASELINE_S).unwrap();
                (v - Vector3::new(0.0, speed, 0.0)).norm()
            })
            .collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        // Expected rms over the two horizontal axes: sqrt(2) * 0.0707 = 0.10 m/s.
        let expected =
            (2.0f64).sqrt() * (2.0f64).sqrt() * sigma_m / (2.0 * VELOCITY_HALF_BASELINE_S);
        assert!(
            (rms / expected - 1.0).abs() < 0.25,
            "rms {rms} m/s, expected {expected} m/s"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// roll and pitch alone.
    #[test]
    fn heading_offset_adds_to_the_true_heading() {
        let dir = std::env::temp_dir().join(format!("kinescan_heading_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.sbet");
        let recs: Vec<SbetRecord> = (0..3)
            .map(|k| SbetRecord {
                time_s: k as f64 * 0.01,
                lat_rad: 0.8,
                roll_rad: 0.02,
                pitch_rad: -0.03,
                platform_heading_rad: 1.0 + 0.1 * k as f64,
                wander_rad: 0.2,
                ..Default::default()
            })
            .collect();
        let mut w = crate::io::timed::TimedWriter::<SbetRecord>::create(&path).unwrap();
        recs.iter().for_each(|r| w.push(r).unwrap());
        w.finish().unwrap();
        let open = |dh: f64| {
            let opts = TrajectoryOptions {
                heading_offset_rad: dh,
                ..Default::default()
            };
            Trajectory::open(&path, None, opts).unwrap()
        };
        let (plain, offset) = (open(0.0), open(0.05));
        let (a, b) = (
            plain.cursor().at(0.013).unwrap(),
            offset.cursor().at(0.013).unwrap(),
        );
        let (ra, pa, ha) = roll_pitch_heading(&a.q_b_to_n);
        let (rb, pb, hb) = roll_pitch_heading(&b.q_b_to_n);
        assert!((rb - ra).abs() < 1e-14 && (pb - pa).abs() < 1e-14);
        assert!((wrap_pi(hb - ha) - 0.05).abs() < 1e-14, "{}", hb - ha);
        assert!((ha - (1.13 - 0.2)).abs() < 1e-12);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn wander_velocity_rotates_to_ned() {
        // Moving due east with wander 30 deg: heading from wander x is 90 + 30 deg.
        let w = 30f64.to_radians();
        let mut r = SbetRecord {
            lat_rad: 0.5,
            wander_rad: w,
            ..Default::default()
        };
        r.vel_x_mps = 10.0 * (90f64.to_radians() + w).cos();
        r.vel_y_mps = 10.0 * (90f64.to_radians() + w).sin();
        let s = NavSample::from_sbet(&r);
        assert!((s.v_n_mps - Vector3::new(0.0, 10.0, 0.0)).norm() < 1e-12);
    }
}
