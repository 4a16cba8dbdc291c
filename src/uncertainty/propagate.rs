//! First-order propagation: `Sigma = J Q J^T` per return (the paper's equation 7 with `Q`, not
//! `Q^-1`), along the map axes, with per-group variance shares.

use super::model::{Group, Input, Jacobian, LocalLevel, PointGeometry, N_GROUPS, N_INPUTS};
use crate::trajectory::NavSigma;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Configured 1-sigma uncertainties of the inputs that do not come from the SMRMSG file
/// (SPEC 5), in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UncertaintyInputs {
    /// Lever arm x, y, z (m).
    pub sigma_lever_arm_b_m: Vector3<f64>,
    /// Boresight angles bx, by, bz (rad).
    pub sigma_boresight_rad: Vector3<f64>,
    /// Out-of-plane angle alpha (rad).
    pub sigma_alpha_rad: f64,
    /// Mirror angle encoder beta (rad).
    pub sigma_beta_rad: f64,
    /// Range noise (m).
    pub sigma_range_m: f64,
    /// Range zero error K (m).
    pub sigma_range_zero_m: f64,
    /// Covariance of the clock parameters (t0, T) (s^2).
    pub clock_covariance_s2: Matrix2<f64>,
    /// Attitude latency tau (s).
    pub sigma_attitude_latency_s: f64,
}

impl UncertaintyInputs {
    /// The 1-sigma of every model input for one return (model order, units of [`Input`]):
    /// INS sigmas from `nav` (SMRMSG at the return's time), the clock's time sigma
    /// `sqrt(g^T C g)` from the partials `g = (dt/dt0, dt/dT)` of the return's time.
    pub fn sigmas(&self, nav: &NavSigma, dt_dclock: [f64; 2]) -> [f64; N_INPUTS] {
        let g = Vector2::from(dt_dclock);
        let var_t = (g.transpose() * self.clock_covariance_s2 * g)[0].max(0.0);
        let mut s = [0.0; N_INPUTS];
        s[0..3].copy_from_slice(nav.pos_ned_m.as_slice());
        s[3..6].copy_from_slice(nav.att_rph_rad.as_slice());
        s[6..9].copy_from_slice(self.sigma_lever_arm_b_m.as_slice());
        s[9..12].copy_from_slice(self.sigma_boresight_rad.as_slice());
        s[Input::Alpha as usize] = self.sigma_alpha_rad;
        s[Input::Beta as usize] = self.sigma_beta_rad;
        s[Input::Range as usize] = self.sigma_range_m;
        s[Input::RangeZero as usize] = self.sigma_range_zero_m;
        s[Input::ClockTime as usize] = var_t.sqrt();
        s[Input::Latency as usize] = self.sigma_attitude_latency_s;
        s
    }
}

/// Propagated covariance of one point along the map axes, with each group's contribution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointCovariance {
    /// 3x3 covariance along the map X, Y, Z axes (m^2).
    pub cov_m2: Matrix3<f64>,
    /// Each group's variance `trace(J_g Q_g J_g^T)` (m^2), [`Group`] order; they sum to
    /// `trace(cov_m2)` (the inputs are independent).
    pub group_variance_m2: [f64; N_GROUPS],
}

/// IHO S-44 / cBLUE 95% horizontal factor: `THU95 = 1.7308 sqrt(sx^2 + sy^2)`, exact for a
/// circular horizontal error (2.4477 sigma per axis).
pub const THU95_FACTOR: f64 = 1.7308;
/// 95% vertical factor (normal, two-sided): `TVU95 = 1.96 sz`.
pub const TVU95_FACTOR: f64 = 1.96;

impl PointCovariance {
    /// 1-sigma along the map X, Y, Z axes (m).
    pub fn sigma_xyz_m(&self) -> Vector3<f64> {
        self.cov_m2.diagonal().map(|v| v.max(0.0).sqrt())
    }

    /// 95% horizontal uncertainty (m), IHO S-44 / cBLUE `total_thu` convention.
    pub fn thu95_m(&self) -> f64 {
        THU95_FACTOR * (self.cov_m2[(0, 0)] + self.cov_m2[(1, 1)]).max(0.0).sqrt()
    }

    /// 95% vertical uncertainty (m), cBLUE `total_tvu` convention.
    pub fn tvu95_m(&self) -> f64 {
        TVU95_FACTOR * self.cov_m2[(2, 2)].max(0.0).sqrt()
    }

    /// Each group's share of the total 3D variance (fractions summing to 1; zeros when the
    /// total is 0).
    pub fn shares(&self) -> [f64; N_GROUPS] {
        let total: f64 = self.group_variance_m2.iter().sum();
        if total > 0.0 {
            self.group_variance_m2.map(|v| v / total)
        } else {
            [0.0; N_GROUPS]
        }
    }
}

/// `Sigma = J diag(sigma^2) J^T` for a Jacobian `j` whose rows are the output axes.
pub fn covariance_of(j: &Jacobian, sigmas: &[f64; N_INPUTS]) -> PointCovariance {
    // Scaled columns c_k = sigma_k J_k: Sigma = sum c_k c_k^T, group variance = sum |c_k|^2.
    let mut upper = [0.0; 6];
    let mut groups = [0.0; N_GROUPS];
    for (g, group) in Group::ALL.iter().enumerate() {
        for k in group.inputs() {
            let s = sigmas[k];
            let (x, y, z) = (j[(0, k)] * s, j[(1, k)] * s, j[(2, k)] * s);
            upper[0] += x * x;
            upper[1] += x * y;
            upper[2] += x * z;
            upper[3] += y * y;
            upper[4] += y * z;
            upper[5] += z * z;
            groups[g] += x * x + y * y + z * z;
        }
    }
    let [xx, xy, xz, yy, yz, zz] = upper;
    PointCovariance {
        cov_m2: Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz),
        group_variance_m2: groups,
    }
}

/// Propagated covariance of one return along the map axes.
///
/// `geom`: the return's nominal state; `local`: the local-level frame at its IMU
/// ([`LocalLevel::at`], or from a [`super::model::FrameCache`]); `inputs`: configured sigmas;
/// `nav`: SMRMSG sigmas at the return's time; `dt_dclock`: partials of the return's time with respect to (t0, T)
/// ([`crate::timing::ScannerClock::partials`], or `(0, f(beta))` for PPS profile tags, `(0, 0)`
/// for per-return tags); `r_e_to_map`: `d x_map / d x_e` at the point
/// ([`super::model::r_e_to_map_axes`] or a [`super::model::FrameCache`]).
pub fn propagate(
    geom: &PointGeometry,
    local: &LocalLevel,
    inputs: &UncertaintyInputs,
    nav: &NavSigma,
    dt_dclock: [f64; 2],
    r_e_to_map: &Matrix3<f64>,
) -> PointCovariance {
    let j = geom.jacobian_in_axes(r_e_to_map, &local.dtheta_per_m, &geom.terms(local.r_n_to_e));
    covariance_of(&j, &inputs.sigmas(nav, dt_dclock))
}
