//! The loosely coupled error-state Kalman filter (paper 004 §2.2: misorientation, velocity and
//! position errors, gyro drifts and accelerometer biases, updated by GNSS positions), with the
//! scale factors of both triads: 21 states.
//!
//! Error state `dx = estimate - truth`: position (m, north, east, down), velocity (m/s, NED),
//! attitude `phi` (rad, NED: `R_est = (I - [phi x]) R_true`), gyro bias (rad/s), accelerometer
//! bias (m/s^2), gyro and accelerometer scale factors. Sensor model per axis
//! `measured = (1 + s) true + b + noise`. Continuous dynamics (docs/trajectory.md):
//! `d(dr) = -w_en x dr + dv`,
//! `d(dv) = [f_n x] phi - (2 w_ie + w_en) x dv - R db_a - R diag(f_b) ds_a + (2 g / R) dr_D e_D`,
//! `d(phi) = -w_in x phi + R db_g + R diag(w_b) ds_g`, biases random walks, scale factors
//! constants. Discretised per IMU step to first order (`Phi = I + F dt`, `Qd = Qc dt`; the
//! step is 2-10 ms against error dynamics of seconds to minutes). GNSS update in Joseph form,
//! symmetrised, after a chi-square innovation test; corrections fed back into the navigation
//! state and the sensor estimates (closed loop), so the error state is zero after each update.

use super::earth::{metres_per_rad, normal_gravity_mps2, omega_en_n, omega_ie_n};
use super::imu_model::ImuGrade;
use super::mechanisation::{step, NavState};
use crate::geo::rotations::skew;
use crate::io::gnss::GnssRecord;
use crate::io::imu::ImuRecord;
use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};
use std::ops::AddAssign;

/// Number of error states.
pub const N: usize = 21;
/// Index of the position error (3).
pub const POS: usize = 0;
/// Index of the velocity error (3).
pub const VEL: usize = 3;
/// Index of the attitude error (3).
pub const ATT: usize = 6;
/// Index of the gyro bias error (3).
pub const BG: usize = 9;
/// Index of the accelerometer bias error (3).
pub const BA: usize = 12;
/// Index of the gyro scale factor error (3).
pub const SG: usize = 15;
/// Index of the accelerometer scale factor error (3).
pub const SA: usize = 18;

/// Square matrix of the error state.
pub type Mat = SMatrix<f64, N, N>;
/// Error-state vector.
pub type Vec21 = SVector<f64, N>;

/// The filter's estimates of the IMU's errors.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorEstimate {
    /// Gyro bias (rad/s).
    pub b_g: Vector3<f64>,
    /// Accelerometer bias (m/s^2).
    pub b_a: Vector3<f64>,
    /// Gyro scale factor error.
    pub s_g: Vector3<f64>,
    /// Accelerometer scale factor error.
    pub s_a: Vector3<f64>,
}

impl SensorEstimate {
    /// Corrected angular rate and specific force of a record.
    #[inline]
    pub fn correct(&self, r: &ImuRecord) -> (Vector3<f64>, Vector3<f64>) {
        let w = (Vector3::from(r.w_b) - self.b_g).component_div(&self.s_g.add_scalar(1.0));
        let f = (Vector3::from(r.f_b) - self.b_a).component_div(&self.s_a.add_scalar(1.0));
        (w, f)
    }
}

/// Process noise of the filter's sensor model (continuous, per axis).
#[derive(Debug, Clone, Copy)]
pub struct ProcessNoise {
    /// Angle random walk PSD (rad^2/s).
    pub arw2: f64,
    /// Velocity random walk PSD ((m/s)^2/s).
    pub vrw2: f64,
    /// Gyro bias random-walk PSD ((rad/s)^2/s): `2 sigma^2 / tau` of the bias instability.
    pub bg2: f64,
    /// Accelerometer bias random-walk PSD ((m/s^2)^2/s).
    pub ba2: f64,
}

impl ProcessNoise {
    /// The noise of a grade.
    pub fn of(g: &ImuGrade) -> Self {
        ProcessNoise {
            arw2: g.gyro.random_walk.powi(2),
            vrw2: g.accel.random_walk.powi(2),
            bg2: 2.0 * g.gyro.instability.powi(2) / g.gyro.instability_tau_s,
            ba2: 2.0 * g.accel.instability.powi(2) / g.accel.instability_tau_s,
        }
    }
}

/// Initial error-state covariance for a grade and initial navigation sigmas.
pub fn initial_covariance(
    g: &ImuGrade,
    pos_sigma_m: [f64; 3],
    vel_sigma_mps: f64,
    att_sigma_rad: [f64; 3],
) -> Mat {
    let mut p = Mat::zeros();
    for (i, (sp, sa)) in pos_sigma_m.iter().zip(att_sigma_rad).enumerate() {
        p[(POS + i, POS + i)] = sp.powi(2);
        p[(VEL + i, VEL + i)] = vel_sigma_mps.powi(2);
        p[(ATT + i, ATT + i)] = sa.powi(2);
        p[(BG + i, BG + i)] = g.gyro.bias.powi(2) + g.gyro.instability.powi(2);
        p[(BA + i, BA + i)] = g.accel.bias.powi(2) + g.accel.instability.powi(2);
        p[(SG + i, SG + i)] = g.gyro.scale_factor.powi(2);
        p[(SA + i, SA + i)] = g.accel.scale_factor.powi(2);
    }
    p
}

/// What a GNSS update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UpdateOutcome {
    /// Accepted; the correction applied (truth - estimate, error-state coordinates).
    Accepted(Vec21),
    /// Rejected by the innovation test with this normalised innovation squared.
    Rejected(f64),
}

/// Filter state: navigation solution, sensor estimates, covariance.
#[derive(Debug, Clone)]
pub struct Filter {
    /// Navigation state.
    pub nav: NavState,
    /// Sensor error estimates.
    pub sens: SensorEstimate,
    /// Error-state covariance.
    pub p: Mat,
    /// Process noise.
    pub noise: ProcessNoise,
    /// GNSS antenna lever arm, body frame (m).
    pub lever_b: Vector3<f64>,
    /// Innovation test threshold on the normalised innovation squared (3 dof).
    pub gate: f64,
}

/// The rows of a transition that differ from the identity: `Phi = I + [G; 0]`, `G = F_top dt`
/// (9 x 21: position, velocity and attitude rows). The bias rows are random walks and the
/// scale-factor rows constants, so their transition rows are the identity's; the filter and
/// smoother work with `G` alone (docs/trajectory.md, "Cost").
pub type TransitionRows = SMatrix<f64, 9, N>;

/// The top 9 rows of a 21 x 21 matrix.
pub type Rows9 = SMatrix<f64, 9, N>;

/// Transition rows `G` and discrete process noise diagonal of one step from `nav` with the
/// corrected rate `w` and specific force `f` (body) over `dt`.
pub fn transition(
    nav: &NavState,
    w: &Vector3<f64>,
    f: &Vector3<f64>,
    dt: f64,
    q: &ProcessNoise,
) -> (TransitionRows, Vec21) {
    let r = *nav.q_b_n.to_rotation_matrix().matrix();
    let w_ie = omega_ie_n(nav.lat_rad);
    let w_en = omega_en_n(nav.lat_rad, nav.h_m, &nav.v_n);
    let f_n = r * f;
    let mut g = TransitionRows::zeros();
    let mut put = |row: usize, col: usize, m: &Matrix3<f64>| {
        g.fixed_view_mut::<3, 3>(row, col).copy_from(&(m * dt));
    };
    put(POS, POS, &-skew(&w_en));
    put(POS, VEL, &Matrix3::identity());
    put(VEL, ATT, &skew(&f_n));
    put(VEL, VEL, &-skew(&(2.0 * w_ie + w_en)));
    put(VEL, BA, &-r);
    put(VEL, SA, &-(r * Matrix3::from_diagonal(f)));
    put(ATT, ATT, &-skew(&(w_ie + w_en)));
    put(ATT, BG, &r);
    put(ATT, SG, &(r * Matrix3::from_diagonal(w)));
    let (m_lat, m_lon) = metres_per_rad(nav.lat_rad, 0.0);
    let radius = (m_lat * m_lon / nav.lat_rad.cos()).sqrt() + nav.h_m;
    g[(VEL + 2, POS + 2)] += 2.0 * normal_gravity_mps2(nav.lat_rad, nav.h_m) / radius * dt;
    let mut qd = Vec21::zeros();
    for i in 0..3 {
        qd[VEL + i] = q.vrw2 * dt;
        qd[ATT + i] = q.arw2 * dt;
        qd[BG + i] = q.bg2 * dt;
        qd[BA + i] = q.ba2 * dt;
    }
    (g, qd)
}

/// The full transition `I + [G; 0]` (for tests and checks; the filter never forms it).
pub fn dense_transition(g: &TransitionRows) -> Mat {
    let mut phi = Mat::identity();
    phi.fixed_rows_mut::<9>(0).add_assign(g);
    phi
}

/// `Phi P Phi^T + diag(qd)`, symmetrised, with `Phi = I + [G; 0]`: `T = G P` (9 x 21), then
/// `X = Phi P` is `P` with `T` added to its top rows, and `X Phi^T` adds `X G^T` to its first
/// 9 columns, whose bottom 12 rows are `T`'s last 12 columns transposed (P symmetric). 5,670
/// multiply-adds instead of the dense product's 18,522.
#[inline]
pub fn propagate_covariance(p: &Mat, g: &TransitionRows, qd: &Vec21) -> Mat {
    let t = g * p;
    let mut out = *p;
    out.fixed_rows_mut::<9>(0).add_assign(&t);
    let top = out.fixed_rows::<9>(0) * g.transpose();
    out.fixed_view_mut::<9, 9>(0, 0).add_assign(&top);
    out.fixed_view_mut::<12, 9>(9, 0)
        .add_assign(&t.fixed_view::<9, 12>(0, 9).transpose());
    for i in 0..N {
        out[(i, i)] += qd[i];
    }
    symmetrise(&mut out);
    out
}

/// Top rows of `Phi M` for `M = [M_top; 0 I]` (a product of transitions, whose bottom rows
/// stay the identity's): `M_top + G_a M_top + [0 | G_b]`, `G_a` the first 9 columns of `G`.
#[inline]
pub fn chain_transition(m_top: &mut Rows9, g: &TransitionRows) {
    let ga = g.fixed_view::<9, 9>(0, 0) * *m_top;
    m_top.add_assign(&ga);
    m_top
        .fixed_view_mut::<9, 12>(0, 9)
        .add_assign(&g.fixed_view::<9, 12>(0, 9));
}

/// The full matrix `[M_top; 0 I]`.
pub fn dense_chain(m_top: &Rows9) -> Mat {
    let mut m = Mat::identity();
    m.fixed_rows_mut::<9>(0).copy_from(m_top);
    m
}

/// `(P + P^T) / 2` in place.
#[inline]
pub fn symmetrise(p: &mut Mat) {
    for i in 0..N {
        for j in 0..i {
            let m = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
}

/// Applies a correction `c` (truth - estimate) to a navigation state and sensor estimate.
pub fn apply_correction(nav: &mut NavState, sens: &mut SensorEstimate, c: &Vec21) {
    nav.shift_ned(&c.fixed_rows::<3>(POS).into_owned());
    nav.v_n += c.fixed_rows::<3>(VEL);
    // R_true = (I + [phi x]) R_est with phi = -c_att.
    nav.q_b_n = UnitQuaternion::from_scaled_axis(-c.fixed_rows::<3>(ATT).into_owned()) * nav.q_b_n;
    sens.b_g += c.fixed_rows::<3>(BG);
    sens.b_a += c.fixed_rows::<3>(BA);
    sens.s_g += c.fixed_rows::<3>(SG);
    sens.s_a += c.fixed_rows::<3>(SA);
}

impl Filter {
    /// One IMU record: mechanisation and covariance propagation; returns the transition's
    /// rows (`Phi = I + [G; 0]`).
    pub fn propagate(&mut self, rec: &ImuRecord) -> TransitionRows {
        let dt = rec.time_s - self.nav.time_s;
        let (w, f) = self.sens.correct(rec);
        let (g, qd) = transition(&self.nav, &w, &f, dt, &self.noise);
        self.nav = step(&self.nav, &(w * dt), &(f * dt), dt);
        self.nav.time_s = rec.time_s;
        self.p = propagate_covariance(&self.p, &g, &qd);
        g
    }

    /// GNSS position update; the fix may be up to half an IMU step off the state's time (the
    /// prediction is moved along the velocity).
    pub fn update(&mut self, fix: &GnssRecord) -> UpdateOutcome {
        let r = self.nav.q_b_n.to_rotation_matrix();
        let lever_n = r * self.lever_b;
        let mut ant = self.nav;
        ant.shift_ned(&(lever_n + self.nav.v_n * (fix.time_s - self.nav.time_s)));
        // y = antenna estimate - fix (NED m) = dr + [(R l) x] phi + noise.
        let y = -ant.ned_to(fix.lat_rad, fix.lon_rad, fix.h_m);
        let mut h = SMatrix::<f64, 3, N>::zeros();
        h.fixed_view_mut::<3, 3>(0, POS)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, ATT).copy_from(&skew(&lever_n));
        let rm = Matrix3::from_diagonal(&Vector3::from(fix.sigma_ned_m).map(|s| s * s));
        let pht = self.p * h.transpose();
        let s = h * pht + rm;
        let Some(s_inv) = s.try_inverse() else {
            return UpdateOutcome::Rejected(f64::INFINITY);
        };
        let d2 = (y.transpose() * s_inv * y)[(0, 0)];
        if d2.is_nan() || d2 > self.gate {
            return UpdateOutcome::Rejected(d2);
        }
        let k = pht * s_inv;
        let dx = k * y;
        let ikh = Mat::identity() - k * h;
        let mut p = ikh * self.p * ikh.transpose() + k * rm * k.transpose();
        symmetrise(&mut p);
        self.p = p;
        let c = -dx;
        apply_correction(&mut self.nav, &mut self.sens, &c);
        UpdateOutcome::Accepted(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ins::imu_model;
    use crate::testing::max_abs;

    /// The structured products equal the dense ones (to rounding: 1e-12 relative).
    #[test]
    fn structured_products_equal_the_dense_ones() {
        let grade = imu_model::grade("tactical").unwrap();
        let nav = NavState {
            time_s: 0.0,
            lat_rad: 0.84,
            lon_rad: 0.2,
            h_m: 520.0,
            v_n: Vector3::new(8.0, -3.0, 0.2),
            q_b_n: UnitQuaternion::from_euler_angles(0.05, -0.03, 2.1),
        };
        let (g, qd) = transition(
            &nav,
            &Vector3::new(0.01, -0.2, 0.4),
            &Vector3::new(1.5, 0.3, -9.7),
            0.005,
            &ProcessNoise::of(&grade),
        );
        let a = Mat::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.1 - 0.4);
        let p = a * a.transpose() + initial_covariance(&grade, [0.1; 3], 0.05, [1e-3; 3]);
        let phi = dense_transition(&g);
        let mut dense = phi * p * phi.transpose();
        for i in 0..N {
            dense[(i, i)] += qd[i];
        }
        let fast = propagate_covariance(&p, &g, &qd);
        let diff = max_abs((fast - dense).iter().copied());
        assert!(diff <= 1e-12 * max_abs(dense.iter().copied()), "{diff}");
        // A chain of three transitions.
        let mut m_top = Rows9::zeros();
        m_top.fixed_view_mut::<9, 9>(0, 0).fill_with_identity();
        let mut m = Mat::identity();
        for k in 0..3 {
            let gk = g * (1.0 + k as f64);
            chain_transition(&mut m_top, &gk);
            m = dense_transition(&gk) * m;
        }
        let diff = max_abs((dense_chain(&m_top) - m).iter().copied());
        assert!(diff <= 1e-14 * max_abs(m.iter().copied()), "{diff}");
    }
}
