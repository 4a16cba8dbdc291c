//! One point of an existing cloud back to its measurement: the pose at its time (latencies
//! applied), the scanner-frame vector by inverting the georeferencing equation (conventions §4)
//!
//! `x_s = R_b^s (R_e^b (x_e - r_e) - l_b)`,
//!
//! the beam parameters and fit check of the scanner kind (`scanner`), and the inputs of `run`'s
//! propagation ([`ReturnInputs`]) for it: the same terms, the same frames, the same sigmas.

use super::scanner::{Misfit, ScannerGeometry};
use crate::geo::ellipsoid::r_n_to_e_of_trig;
use crate::geo::local::{LocalUnprojection, UNPROJECT_RADIUS_M};
use crate::geo::projection::MapFrame;
use crate::geo::rotations::SinCosNear;
use crate::georef::{ReturnTerms, Sensor};
use crate::io::las::GpsTimeConvention;
use crate::pipeline::config::TimeConfig;
use crate::timing::{Mirror, TimeModel};
use crate::trajectory::{NavGap, PoseCursor, SigmaCursor, Trajectory};
use crate::uncertainty::model::FrameCache;
use crate::uncertainty::propagate::ReturnInputs;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Why a point gets no sigma.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PointReject {
    /// Non-finite time or coordinates.
    NonFinite,
    /// Time before the first or after the last trajectory record.
    OutsideTrajectory,
    /// Time inside a trajectory gap longer than `trajectory.max_gap_s`.
    TrajectoryGap,
    /// Time outside the SMRMSG span.
    OutsideAccuracy,
    /// The recovered range `rho = |x_s| / (1 + S 1e-6) - K` is negative or zero.
    NegativeRange,
    /// The recovered range is outside `[sensor.min_range_m, sensor.max_range_m]`.
    RangeOutOfLimits,
    /// Further than `tpu.cone_tolerance_m` from the scanner's beam cone or plane.
    OffCone,
    /// Mirror angle beyond `tpu.max_scan_angle_deg` (oscillating mirror).
    ScanAngleOutOfLimits,
}

impl PointReject {
    /// Every reason, in report order.
    pub const ALL: [PointReject; 8] = [
        PointReject::NonFinite,
        PointReject::OutsideTrajectory,
        PointReject::TrajectoryGap,
        PointReject::OutsideAccuracy,
        PointReject::NegativeRange,
        PointReject::RangeOutOfLimits,
        PointReject::OffCone,
        PointReject::ScanAngleOutOfLimits,
    ];

    /// A sentence for errors and the report.
    pub fn describe(self) -> &'static str {
        match self {
            PointReject::NonFinite => "non-finite GPS time or coordinates",
            PointReject::OutsideTrajectory => "point time outside the SBET span",
            PointReject::TrajectoryGap => {
                "point time inside a trajectory gap longer than trajectory.max_gap_s"
            }
            PointReject::OutsideAccuracy => "point time outside the SMRMSG span",
            PointReject::NegativeRange => {
                "recovered range negative: the point is behind the scanner for this sensor \
                 (lever arm, boresight or range offset wrong, or the point is not from this \
                 trajectory)"
            }
            PointReject::RangeOutOfLimits => {
                "recovered range outside sensor.min_range_m..max_range_m"
            }
            PointReject::OffCone => {
                "further than tpu.cone_tolerance_m from the scanner's beam cone (sensor.alpha0_deg): \
                 wrong boresight, latency or trajectory, or another scanner"
            }
            PointReject::ScanAngleOutOfLimits => "mirror angle beyond tpu.max_scan_angle_deg",
        }
    }
}

impl From<NavGap> for PointReject {
    fn from(g: NavGap) -> Self {
        match g {
            NavGap::OutsideTrajectory => PointReject::OutsideTrajectory,
            NavGap::TrajectoryGap => PointReject::TrajectoryGap,
            NavGap::OutsideAccuracy => PointReject::OutsideAccuracy,
        }
    }
}

impl From<Misfit> for PointReject {
    fn from(m: Misfit) -> Self {
        match m {
            Misfit::OffCone => PointReject::OffCone,
            Misfit::ScanAngleOutOfLimits => PointReject::ScanAngleOutOfLimits,
        }
    }
}

/// How a point's time depends on the scanner clock (t0, T), for the clock covariance: from
/// `[time]` as `run` computes it; without `[time]` the clock covariance is zero (checked).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClockPartials {
    /// No `[time]`: `(0, 0)`.
    None,
    /// Software clock: `(1, (t - t0) / T)`.
    Software {
        /// t0 (s).
        t0_s: f64,
        /// T (s).
        period_s: f64,
    },
    /// Profile time tags: `(0, f(beta))`.
    ProfileTags {
        /// Mirror geometry for `f`.
        mirror: Mirror,
    },
    /// Return time tags: `(0, 0)`.
    ReturnTags,
}

impl ClockPartials {
    /// From an optional `[time]` table (the encoder offset moves the mirror's start as in
    /// `run`).
    pub fn of(time: Option<&TimeConfig>, encoder_offset_deg: f64) -> Self {
        let Some(t) = time else {
            return ClockPartials::None;
        };
        match t.model {
            TimeModel::Software => ClockPartials::Software {
                t0_s: t.t0_s.unwrap_or(0.0),
                period_s: t.period_s,
            },
            TimeModel::HardwareProfile => ClockPartials::ProfileTags {
                mirror: t.mirror(encoder_offset_deg),
            },
            TimeModel::HardwareReturn => ClockPartials::ReturnTags,
        }
    }

    #[inline]
    fn at(&self, t_s: f64, recorded_beta_rad: f64) -> [f64; 2] {
        match *self {
            ClockPartials::None | ClockPartials::ReturnTags => [0.0, 0.0],
            ClockPartials::Software { t0_s, period_s } => [1.0, (t_s - t0_s) / period_s],
            ClockPartials::ProfileTags { mirror } => [0.0, mirror.fraction(recorded_beta_rad)],
        }
    }
}

/// What is recovered of one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recovered {
    /// Recorded range `rho` (m).
    pub range_m: f64,
    /// Recorded mirror angle (rad).
    pub beta_rad: f64,
    /// Recovered out-of-plane angle (rad).
    pub alpha_rad: f64,
    /// Distance from the beam cone (m).
    pub off_cone_m: f64,
    /// Seconds-of-week time (s).
    pub t_s: f64,
}

/// Recovers the points of one cloud (module docs). Shared by the threads.
pub struct Recoverer<'a> {
    /// Trajectory.
    pub traj: &'a Trajectory,
    /// Sensor mounting and intrinsics.
    pub sensor: Sensor,
    /// The scanner kind.
    pub scanner: &'a dyn ScannerGeometry,
    /// The cloud's map frame.
    pub frame: MapFrame,
    /// Stored time to seconds of week.
    pub time: GpsTimeConvention,
    /// Clock partials.
    pub clock: ClockPartials,
    /// Attitude latency (s).
    pub attitude_latency_s: f64,
    /// Position latency (s).
    pub position_latency_s: f64,
    /// Range limits (m).
    pub range_limits_m: (f64, f64),
}

/// Per-thread state of a [`Recoverer`].
pub struct RecoverCursors<'a> {
    poses: PoseCursor<'a>,
    sigmas: SigmaCursor<'a>,
    frames: FrameCache,
    unproject: Option<LocalUnprojection>,
    /// `(sin, cos)` of the IMU's latitude and longitude, which move little between points.
    lat: SinCosNear,
    lon: SinCosNear,
    /// `(sin, cos)` of the scanner kind's alpha0.
    sin_cos_alpha0: (f64, f64),
    /// The kind's beam frame: `Q^T` (None: the scanner frame) and `R_s^b Q`.
    to_beam: Option<Matrix3<f64>>,
    r_beam_to_b: Matrix3<f64>,
}

/// Map distance (m) a point may be from the unprojection's centre before it is re-expanded.
const RECENTRE_M: f64 = UNPROJECT_RADIUS_M * 0.66;

impl<'a> Recoverer<'a> {
    /// Fresh cursors; `None` without an SMRMSG file (checked when the pipeline is loaded).
    pub fn cursors(&self) -> Option<RecoverCursors<'a>> {
        Some(RecoverCursors {
            poses: PoseCursor::new(self.traj, self.attitude_latency_s, self.position_latency_s),
            sigmas: self.traj.sigma_cursor()?,
            frames: FrameCache::new(self.frame),
            unproject: None,
            lat: SinCosNear::default(),
            lon: SinCosNear::default(),
            sin_cos_alpha0: self.scanner.alpha0_rad().sin_cos(),
            to_beam: self.scanner.beam_axes().map(|q| q.transpose()),
            r_beam_to_b: self.sensor.r_s_to_b
                * self.scanner.beam_axes().unwrap_or_else(Matrix3::identity),
        })
    }

    /// ECEF of a map point (the local inverse, re-expanded as the points move).
    #[inline]
    pub fn to_ecef(&self, x_map: &Vector3<f64>, c: &mut RecoverCursors) -> Vector3<f64> {
        if matches!(self.frame, MapFrame::Ecef) {
            return *x_map;
        }
        let stale = c
            .unproject
            .as_ref()
            .is_none_or(|u| (u.centre_map() - x_map).norm_squared() > RECENTRE_M * RECENTRE_M);
        if stale {
            c.unproject = Some(LocalUnprojection::new(self.frame, *x_map));
        }
        c.unproject.as_ref().expect("set above").map_to_ecef(x_map)
    }

    /// The propagation inputs of the point at map coordinates `x_map` (m) with stored GPS time
    /// `stored_time`, and what was recovered; or why it gets no sigma.
    #[inline]
    pub fn recover(
        &self,
        x_map: &Vector3<f64>,
        stored_time: f64,
        c: &mut RecoverCursors,
    ) -> Result<(ReturnInputs, Recovered), PointReject> {
        let t_s = stored_time - self.time.shift_s();
        if !(t_s.is_finite() && x_map.iter().all(|v| v.is_finite())) {
            return Err(PointReject::NonFinite);
        }
        let pose = c.poses.at(t_s)?;
        let nav_sigma = c.sigmas.at(t_s)?;
        let x_e = self.to_ecef(x_map, c);
        let r_n_to_e = r_n_to_e_of_trig(c.lat.at(pose.nav.lat_rad), c.lon.at(pose.nav.lon_rad));
        let r_b_to_n = *pose.q_b_to_n.to_rotation_matrix().matrix();
        let a_b = (r_n_to_e * r_b_to_n).transpose() * (x_e - pose.nav.r_e_m);
        let mut x_s = self.sensor.r_s_to_b.transpose() * (a_b - self.sensor.lever_arm_b_m);
        if let Some(q_t) = &c.to_beam {
            x_s = q_t * x_s;
        }
        let beam = self.scanner.fit(&x_s)?;
        let s = &self.sensor;
        let range_m = beam.range_total_m / (1.0 + s.range_scale_ppm * 1e-6) - s.range_zero_m;
        if range_m.is_nan() || range_m <= 0.0 {
            return Err(PointReject::NegativeRange);
        }
        let (min, max) = self.range_limits_m;
        if !(min..=max).contains(&range_m) {
            return Err(PointReject::RangeOutOfLimits);
        }
        let beta_recorded = beam.beta_rad - s.encoder_offset_rad;
        // (sin, cos) of beta = atan2(-y, z) straight from x_s (no trigonometry).
        let yz = (x_s.y * x_s.y + x_s.z * x_s.z).sqrt();
        let sin_cos_beta = if yz > 0.0 {
            (-x_s.y / yz, x_s.z / yz)
        } else {
            beam.beta_rad.sin_cos()
        };
        let terms = ReturnTerms::of_trig(
            r_n_to_e,
            r_b_to_n,
            &s.lever_arm_b_m,
            &c.r_beam_to_b,
            (c.sin_cos_alpha0, sin_cos_beta),
            beam.range_total_m,
        );
        let (r_n_to_map, dtheta) = c.frames.frames(&x_e, &pose.nav);
        let inputs = ReturnInputs::new(
            r_n_to_map,
            dtheta,
            &terms,
            &pose.omega_b_radps,
            &pose.nav.v_n_mps,
            &nav_sigma,
            self.clock.at(t_s, beta_recorded),
        );
        Ok((
            inputs,
            Recovered {
                range_m,
                beta_rad: beta_recorded,
                alpha_rad: beam.alpha_rad,
                off_cone_m: beam.off_cone_m,
                t_s,
            },
        ))
    }
}
