//! The error model of one return: the conventions §4 equation as a function of the conventions §5 input errors,
//! evaluated exactly (for Monte Carlo and Sobol) and linearised with an analytic Jacobian.
//!
//! The 18 error inputs, in this order ([`Input`]): INS position north, east, down (m, in `n`
//! at the IMU); INS roll, pitch, heading (rad, added to the Euler angles of `R_b^n`); lever arm
//! x, y, z (m, `b`); boresight bx, by, bz (rad, added to the angles of `R_s^b`); scanner alpha,
//! beta (rad), range noise (m), zero error K (m); clock time error `dt` (s, moves the whole
//! return in time: position along the velocity, attitude along the body rate) and attitude
//! latency error `dtau` (s, moves only the attitude).
//!
//! Exact model for an error vector `e`:
//! `d_n = e_pos + v_n dt`; `r_e' = r_e + R_n^e d_n`; `(lat', lon')` = geodetic of `r_e'`;
//! `R_b^n' = R(roll + e_r, pitch + e_p, heading + e_h) exp([w_b]x (dt + dtau))`;
//! `R_s^b' = R(bx + e_bx, by + e_by, bz + e_bz)` (`R(x, y, z) = Rz(z) Ry(y) Rx(x)`, angles of
//! the nominal matrices; singular at pitch or by = +-90 deg);
//! `x_e = r_e' + R_n^e(lat', lon') R_b^n' (l + e_l + R_s^b' (rho + e_rho + K + e_K)
//! u_s(alpha + e_alpha, beta + e_beta))`.
//! The body rate `w_b` is taken as the rate of `b` relative to `n` (the SBET rate includes the
//! Earth rate, 7.3e-5 rad/s: below 4 um/ms at 50 m, neglected).

use crate::geo::ellipsoid::{
    ecef_to_geodetic, prime_vertical_radius_m, r_enu_to_e, r_n_to_e, WGS84_A, WGS84_E2,
};
use crate::geo::projection::MapFrame;
use crate::geo::rotations::{r_zyx, skew, zyx_angles};
use crate::georef::{beam_s, ReturnTerms, Sensor};
use crate::trajectory::{NavPosition, Pose};
use nalgebra::{Matrix3, Rotation3, SMatrix, Vector3};

/// Number of error inputs.
pub const N_INPUTS: usize = 18;

/// Jacobian of a point's coordinates (3 axes) with respect to the [`N_INPUTS`] error inputs.
pub type Jacobian = SMatrix<f64, 3, N_INPUTS>;

/// The error inputs, in model order (`Input::X as usize` is the column of the Jacobian).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Input {
    /// INS position north (m).
    InsNorth,
    /// INS position east (m).
    InsEast,
    /// INS position down (m).
    InsDown,
    /// INS roll (rad).
    InsRoll,
    /// INS pitch (rad).
    InsPitch,
    /// INS heading (rad).
    InsHeading,
    /// Lever arm x (m).
    LeverX,
    /// Lever arm y (m).
    LeverY,
    /// Lever arm z (m).
    LeverZ,
    /// Boresight angle bx (rad).
    BoresightX,
    /// Boresight angle by (rad).
    BoresightY,
    /// Boresight angle bz (rad).
    BoresightZ,
    /// Out-of-plane angle alpha (rad).
    Alpha,
    /// Mirror angle beta (rad).
    Beta,
    /// Range noise (m).
    Range,
    /// Range zero error K (m).
    RangeZero,
    /// Clock time error dt (s), from the (t0, T) covariance.
    ClockTime,
    /// Attitude latency error dtau (s).
    Latency,
}

impl Input {
    /// All inputs in model order.
    pub const ALL: [Input; N_INPUTS] = [
        Input::InsNorth,
        Input::InsEast,
        Input::InsDown,
        Input::InsRoll,
        Input::InsPitch,
        Input::InsHeading,
        Input::LeverX,
        Input::LeverY,
        Input::LeverZ,
        Input::BoresightX,
        Input::BoresightY,
        Input::BoresightZ,
        Input::Alpha,
        Input::Beta,
        Input::Range,
        Input::RangeZero,
        Input::ClockTime,
        Input::Latency,
    ];

    /// Name used in tables (snake case).
    pub fn name(self) -> &'static str {
        const NAMES: [&str; N_INPUTS] = [
            "ins_north",
            "ins_east",
            "ins_down",
            "ins_roll",
            "ins_pitch",
            "ins_heading",
            "lever_x",
            "lever_y",
            "lever_z",
            "boresight_x",
            "boresight_y",
            "boresight_z",
            "alpha",
            "beta",
            "range",
            "range_zero",
            "clock_time",
            "latency",
        ];
        NAMES[self as usize]
    }

    /// The group the input belongs to.
    pub fn group(self) -> Group {
        Group::ALL[match self as usize {
            0..=2 => 0,
            3..=5 => 1,
            6..=8 => 2,
            9..=11 => 3,
            12..=15 => 4,
            _ => 5,
        }]
    }
}

/// Number of input groups.
pub const N_GROUPS: usize = 6;

/// Input groups of conventions §5 (the paper's groups 1-5 plus timing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Group {
    /// INS position (north, east, down).
    InsPosition,
    /// INS attitude (roll, pitch, heading).
    InsAttitude,
    /// Lever arm.
    LeverArm,
    /// Boresight.
    Boresight,
    /// Scanner alpha, beta, range noise, zero error.
    Scanner,
    /// Clock (t0, T) and latency.
    Timing,
}

impl Group {
    /// All groups in order (`Group::X as usize` indexes per-group arrays).
    pub const ALL: [Group; N_GROUPS] = [
        Group::InsPosition,
        Group::InsAttitude,
        Group::LeverArm,
        Group::Boresight,
        Group::Scanner,
        Group::Timing,
    ];

    /// Name used in tables and LAS extra dimensions (snake case).
    pub fn name(self) -> &'static str {
        const NAMES: [&str; N_GROUPS] = [
            "ins_position",
            "ins_attitude",
            "lever_arm",
            "boresight",
            "scanner",
            "timing",
        ];
        NAMES[self as usize]
    }

    /// Model-order indices of the group's inputs.
    pub fn inputs(self) -> std::ops::Range<usize> {
        const RANGES: [(usize, usize); N_GROUPS] =
            [(0, 3), (3, 6), (6, 9), (9, 12), (12, 16), (16, 18)];
        let (a, b) = RANGES[self as usize];
        a..b
    }
}

/// The nominal state of one return: everything the equation needs, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointGeometry {
    /// IMU origin, ECEF (m).
    pub r_e_m: Vector3<f64>,
    /// IMU geodetic latitude (rad).
    pub lat_rad: f64,
    /// IMU longitude (rad).
    pub lon_rad: f64,
    /// IMU ellipsoidal height (m).
    pub h_m: f64,
    /// Attitude `R_b^n` at `t + tau` (`Rz(heading) Ry(pitch) Rx(roll)`).
    pub r_b_to_n: Matrix3<f64>,
    /// Velocity in NED (m/s).
    pub v_n_mps: Vector3<f64>,
    /// Body angular rate at `t + tau` (rad/s, body axes).
    pub omega_b_radps: Vector3<f64>,
    /// Lever arm `l_b` (m).
    pub lever_arm_b_m: Vector3<f64>,
    /// Boresight `R_s^b = Rz(bz) Ry(by) Rx(bx)`.
    pub r_s_to_b: Matrix3<f64>,
    /// Out-of-plane angle alpha (rad).
    pub alpha_rad: f64,
    /// Mirror angle beta (rad).
    pub beta_rad: f64,
    /// Measured range rho (m).
    pub range_m: f64,
    /// Range zero error K (m).
    pub range_zero_m: f64,
}

impl PointGeometry {
    /// The geometry of a return georeferenced with `pose` and `sensor` (conventions §4).
    pub fn from_pose(
        pose: &Pose,
        sensor: &Sensor,
        alpha_rad: f64,
        beta_rad: f64,
        range_m: f64,
    ) -> Self {
        PointGeometry {
            r_e_m: pose.nav.r_e_m,
            lat_rad: pose.nav.lat_rad,
            lon_rad: pose.nav.lon_rad,
            h_m: pose.nav.h_m,
            r_b_to_n: *pose.q_b_to_n.to_rotation_matrix().matrix(),
            v_n_mps: pose.nav.v_n_mps,
            omega_b_radps: pose.omega_b_radps,
            lever_arm_b_m: sensor.lever_arm_b_m,
            r_s_to_b: sensor.r_s_to_b,
            alpha_rad,
            beta_rad,
            range_m,
            range_zero_m: sensor.range_zero_m,
        }
    }

    /// ECEF point (m) for the error vector `e` (model order; units of [`Input`]): the exact
    /// nonlinear equation of the module documentation. `e = 0` gives the conventions §4 point.
    pub fn point_e(&self, e: &[f64; N_INPUTS]) -> Vector3<f64> {
        let dt = e[Input::ClockTime as usize];
        let d_n = Vector3::new(e[0], e[1], e[2]) + self.v_n_mps * dt;
        let r_e = self.r_e_m + r_n_to_e(self.lat_rad, self.lon_rad) * d_n;
        let g = ecef_to_geodetic(&r_e);
        let turn = Rotation3::new(self.omega_b_radps * (dt + e[Input::Latency as usize]));
        let r_b_n = perturb_zyx(&self.r_b_to_n, e[3], e[4], e[5]) * turn.matrix();
        let lever = self.lever_arm_b_m + Vector3::new(e[6], e[7], e[8]);
        let r_s_b = perturb_zyx(&self.r_s_to_b, e[9], e[10], e[11]);
        let rho = self.range_m + e[14] + self.range_zero_m + e[15];
        let x_s = beam_s(self.alpha_rad + e[12], self.beta_rad + e[13]) * rho;
        r_e + r_n_to_e(g.lat_rad, g.lon_rad) * r_b_n * (lever + r_s_b * x_s)
    }

    /// Analytic Jacobian `d x_e / d e` at `e = 0` (ECEF axes; columns in model order).
    pub fn jacobian_e(&self) -> Jacobian {
        self.jacobian_e_in(&LocalLevel::at(self.lat_rad, self.lon_rad, self.h_m))
    }

    /// [`Self::jacobian_e`] with the local-level quantities given (exact when `local` is
    /// [`LocalLevel::at`] the IMU; see [`FrameCache`] for a nearby one).
    pub fn jacobian_e_in(&self, local: &LocalLevel) -> Jacobian {
        let terms = self.terms(local.r_n_to_e);
        self.jacobian_in_axes(&Matrix3::identity(), &local.dtheta_per_m, &terms)
    }

    /// The georeferencing terms of this return with `R_n^e` given.
    pub fn terms(&self, r_n_to_e: Matrix3<f64>) -> ReturnTerms {
        ReturnTerms::new(
            r_n_to_e,
            self.r_b_to_n,
            &self.lever_arm_b_m,
            &self.r_s_to_b,
            self.alpha_rad,
            self.beta_rad,
            self.range_m + self.range_zero_m,
        )
    }

    /// Analytic Jacobian along the output axes `out` (`d x_out / d x_e`, e.g.
    /// [`r_e_to_map_axes`]; rows are the output axes), from the georeferencing terms `t` of
    /// this return (its rotations, lever arm, angles and range; velocity, body rate and
    /// boresight come from `self`) and the local-level turn `dtheta_per_m`
    /// ([`LocalLevel::dtheta_per_m`]). Every column is `R_n^e` or `R_b^e` times a vector, so
    /// the output rotation is folded into those two matrices instead of applied to the 18
    /// columns.
    pub fn jacobian_in_axes(
        &self,
        out: &Matrix3<f64>,
        dtheta_per_m: &Matrix3<f64>,
        t: &ReturnTerms,
    ) -> Jacobian {
        let r_n_out = out * t.r_n_to_e;
        let r_b_out = r_n_out * t.r_b_to_n;
        let r_s_b = self.r_s_to_b;
        let a_b = t.a_b_m;
        let a_n = t.r_b_to_n * a_b;
        let mut j = Jacobian::zeros();

        // Position: R_n^e, plus the turn of n when lat/lon follow the displaced IMU.
        let j_pos = r_n_out * (Matrix3::identity() - skew(&a_n) * dtheta_per_m);
        j.fixed_columns_mut::<3>(0).copy_from(&j_pos);

        // Attitude: dR/dk = R [u_k]x with u_r = x, u_p = Rx(r)^T y, u_h = R^T z.
        let minus_rbo_ab = -r_b_out * skew(&a_b);
        j.fixed_columns_mut::<3>(3)
            .copy_from(&(minus_rbo_ab * zyx_axes(&t.r_b_to_n)));

        j.fixed_columns_mut::<3>(6).copy_from(&r_b_out);

        // Boresight: same structure on R_s^b acting on x_s.
        let r_s_out = r_b_out * r_s_b;
        j.fixed_columns_mut::<3>(9)
            .copy_from(&(-r_s_out * skew(&t.x_s_m) * zyx_axes(&r_s_b)));

        // Scanner: x_s = (rho + K) u_s(alpha, beta).
        let ((sa, ca), (sb, cb)) = (t.sin_cos_alpha, t.sin_cos_beta);
        let rho = t.range_total_m;
        let dxs_dalpha = Vector3::new(ca, sa * sb, -sa * cb) * rho;
        let dxs_dbeta = Vector3::new(0.0, -ca * cb, -ca * sb) * rho;
        j.set_column(12, &(r_s_out * dxs_dalpha));
        j.set_column(13, &(r_s_out * dxs_dbeta));
        let d_rho = r_s_out * t.u_s();
        j.set_column(14, &d_rho);
        j.set_column(15, &d_rho);

        // Timing: the attitude turns with the body rate; the clock also moves the IMU.
        let d_att = minus_rbo_ab * self.omega_b_radps;
        j.set_column(16, &(j_pos * self.v_n_mps + d_att));
        j.set_column(17, &d_att);
        j
    }
}

/// The local-level frame at the IMU: `R_n^e` and the turn of `n` per metre of NED
/// displacement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalLevel {
    /// `R_n^e` at the IMU.
    pub r_n_to_e: Matrix3<f64>,
    /// `dtheta / d d_n` (rad/m): `R_n^e(lat + dlat, lon + dlon) = R_n^e (I + [dtheta]x)` with
    /// `dtheta = (dlon cos lat, -dlat, -dlon sin lat)`, `dlat = d_N / (M + h)`,
    /// `dlon = d_E / ((N + h) cos lat)`.
    pub dtheta_per_m: Matrix3<f64>,
}

impl LocalLevel {
    /// At geodetic latitude, longitude (rad) and height (m).
    pub fn at(lat_rad: f64, lon_rad: f64, h_m: f64) -> Self {
        let r_n_to_e = r_n_to_e(lat_rad, lon_rad);
        // Meridian radius from the prime-vertical one: M = (1 - e^2) N^3 / a^2.
        let n_m = prime_vertical_radius_m(lat_rad);
        let n_h = n_m + h_m;
        let m_h = (1.0 - WGS84_E2) * n_m.powi(3) / (WGS84_A * WGS84_A) + h_m;
        let minus_tan_lat = r_n_to_e[(2, 2)] / r_n_to_e[(2, 0)];
        let dtheta_per_m = Matrix3::new(
            0.0,
            1.0 / n_h,
            0.0,
            -1.0 / m_h,
            0.0,
            0.0,
            0.0,
            minus_tan_lat / n_h,
            0.0,
        );
        LocalLevel {
            r_n_to_e,
            dtheta_per_m,
        }
    }
}

/// `R = Rz(z) Ry(y) Rx(x)` with `(dx, dy, dz)` added to its ZYX angles.
fn perturb_zyx(r: &Matrix3<f64>, dx: f64, dy: f64, dz: f64) -> Matrix3<f64> {
    let (x, y, z) = zyx_angles(r);
    r_zyx(x + dx, y + dy, z + dz)
}

/// The body-frame axes `u_k` with `dR/dk = R [u_k]x` for the ZYX angles of `R = Rz Ry Rx`, as
/// columns: `x`, `Rx(x)^T y = (0, cos x, -sin x)`, `R^T z` (the third row of `R`). Needs no
/// angle: `(sin x, cos x)` is the normalised `(R_zy, R_zz)` (cos y > 0 away from y = +-90 deg).
pub fn zyx_axes(r: &Matrix3<f64>) -> Matrix3<f64> {
    let (s, c) = (r[(2, 1)], r[(2, 2)]);
    let norm = (s * s + c * c).sqrt();
    Matrix3::new(
        1.0,
        0.0,
        r[(2, 0)],
        0.0,
        c / norm,
        r[(2, 1)],
        0.0,
        -s / norm,
        r[(2, 2)],
    )
}

/// `d x_map / d x_e` at the ECEF point `x_e`: ECEF displacements to displacements along the map
/// axes of `frame` (UTM easting, northing, height; ECEF; local E, N, U).
pub fn r_e_to_map_axes(frame: &MapFrame, x_e: &Vector3<f64>) -> Matrix3<f64> {
    let g = ecef_to_geodetic(x_e);
    frame.r_enu_to_map_axes(x_e) * r_enu_to_e(g.lat_rad, g.lon_rad).transpose()
}

/// Per-thread cache of the frame quantities of a return that vary slowly in space:
/// [`r_e_to_map_axes`] at the point, [`LocalLevel`] at the IMU and their product with `R_n^e`,
/// re-evaluated only when the point or the IMU has moved more than
/// [`FrameCache::REUSE_RADIUS_M`] (consecutive returns are centimetres to decimetres apart, the
/// IMU moves millimetres between them).
///
/// These matrices turn by about `(1 + tan(lat)) / 6.4e6` rad per metre (local vertical plus
/// grid convergence: 3.3e-7 rad/m at 48 deg, 1.9e-6 rad/m at 85 deg); the UTM scale changes by
/// < 1e-8 per metre. Within 25 m each cached matrix is off by < 8.5e-6 rad (48 deg; 5e-5 at
/// 85 deg), their product by twice that, so a sigma changes by < 1.7e-5 (1e-4 at 85 deg) times
/// the ratio of the other axes' sigma to its own: far below the accuracy of any input sigma.
#[derive(Debug, Clone)]
pub struct FrameCache {
    frame: MapFrame,
    map_at_e: Vector3<f64>,
    r_e_to_map: Matrix3<f64>,
    local_at_e: Vector3<f64>,
    local: LocalLevel,
    r_n_to_map: Matrix3<f64>,
}

impl FrameCache {
    /// Reuse radius (m).
    pub const REUSE_RADIUS_M: f64 = 25.0;

    /// An empty cache for the map frame `frame`.
    pub fn new(frame: MapFrame) -> Self {
        FrameCache {
            frame,
            map_at_e: Vector3::repeat(f64::INFINITY),
            r_e_to_map: Matrix3::identity(),
            local_at_e: Vector3::repeat(f64::INFINITY),
            local: LocalLevel::at(0.0, 0.0, 0.0),
            r_n_to_map: Matrix3::identity(),
        }
    }

    fn stale(at: &Vector3<f64>, x_e: &Vector3<f64>) -> bool {
        (x_e - at).norm_squared() > Self::REUSE_RADIUS_M * Self::REUSE_RADIUS_M
    }

    /// For a point at ECEF `x_e` seen from the IMU state `imu`: `d x_map / d x_n`
    /// ([`r_e_to_map_axes`] at the point times `R_n^e` at the IMU) and
    /// [`LocalLevel::dtheta_per_m`] at the IMU.
    #[inline]
    pub fn frames(
        &mut self,
        x_e: &Vector3<f64>,
        imu: &NavPosition,
    ) -> (&Matrix3<f64>, &Matrix3<f64>) {
        let mut moved = false;
        if Self::stale(&self.map_at_e, x_e) {
            self.r_e_to_map = r_e_to_map_axes(&self.frame, x_e);
            self.map_at_e = *x_e;
            moved = true;
        }
        if Self::stale(&self.local_at_e, &imu.r_e_m) {
            self.local = LocalLevel::at(imu.lat_rad, imu.lon_rad, imu.h_m);
            self.local_at_e = imu.r_e_m;
            moved = true;
        }
        if moved {
            self.r_n_to_map = self.r_e_to_map * self.local.r_n_to_e;
        }
        (&self.r_n_to_map, &self.local.dtheta_per_m)
    }
}
