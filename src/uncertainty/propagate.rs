//! First-order propagation: `Sigma = J Q J^T` per return (the paper's equation 7 with `Q`, not
//! `Q^-1`), along the map axes, with per-group variance shares.

use super::model::{zyx_axes, Input, Jacobian, LocalLevel, PointGeometry, N_GROUPS, N_INPUTS};
use crate::georef::ReturnTerms;
use crate::trajectory::NavSigma;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

/// Configured 1-sigma uncertainties of the inputs that do not come from the SMRMSG file
/// (conventions §5), in SI units.
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
    #[inline]
    pub fn sigmas(&self, nav: &NavSigma, dt_dclock: [f64; 2]) -> [f64; N_INPUTS] {
        let var_t = self.clock_time_variance_s2(dt_dclock);
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

    /// Variance (s^2) of a return's time from the clock: `g^T C g` with the partials
    /// `g = (dt/dt0, dt/dT)`.
    #[inline]
    pub fn clock_time_variance_s2(&self, dt_dclock: [f64; 2]) -> f64 {
        let g = Vector2::from(dt_dclock);
        (g.transpose() * self.clock_covariance_s2 * g)[0].max(0.0)
    }
}

/// Propagated covariance of one point along the map axes, with each group's contribution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointCovariance {
    /// 3x3 covariance along the map X, Y, Z axes (m^2).
    pub cov_m2: Matrix3<f64>,
    /// Each group's variance `trace(J_g Q_g J_g^T)` (m^2), [`crate::uncertainty::Group`] order; they sum to
    /// `trace(cov_m2)` (the inputs are independent).
    pub group_variance_m2: [f64; N_GROUPS],
}

/// IHO S-44 / cBLUE 95% horizontal factor: `THU95 = 1.7308 sqrt(sx^2 + sy^2)`, exact for a
/// circular horizontal error (2.4477 sigma per axis).
pub const THU95_FACTOR: f64 = 1.7308;
/// 95% vertical factor (normal, two-sided): `TVU95 = 1.96 sz`.
pub const TVU95_FACTOR: f64 = 1.96;

impl PointCovariance {
    /// The variances along the three axes, with the group variances.
    pub fn axes(&self) -> AxisVariances {
        AxisVariances {
            var_m2: self.cov_m2.diagonal(),
            group_variance_m2: self.group_variance_m2,
        }
    }
}

/// Variances of one point along the map X, Y, Z axes (what the LAS fields need), with each
/// group's variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisVariances {
    /// Variance along X, Y, Z (m^2): the diagonal of [`PointCovariance::cov_m2`].
    pub var_m2: Vector3<f64>,
    /// As [`PointCovariance::group_variance_m2`] (zeros when not computed).
    pub group_variance_m2: [f64; N_GROUPS],
}

impl AxisVariances {
    /// 1-sigma along the map X, Y, Z axes (m).
    pub fn sigma_xyz_m(&self) -> Vector3<f64> {
        self.var_m2.map(|v| v.max(0.0).sqrt())
    }

    /// 95% horizontal uncertainty (m), IHO S-44 / cBLUE `total_thu` convention.
    pub fn thu95_m(&self) -> f64 {
        THU95_FACTOR * (self.var_m2.x + self.var_m2.y).max(0.0).sqrt()
    }

    /// 95% vertical uncertainty (m), cBLUE `total_tvu` convention.
    pub fn tvu95_m(&self) -> f64 {
        TVU95_FACTOR * self.var_m2.z.max(0.0).sqrt()
    }

    /// Each group's share of the total 3D variance (fractions summing to 1; zeros when the
    /// total is 0).
    pub fn shares(&self) -> [f64; N_GROUPS] {
        let total: f64 = self.group_variance_m2.iter().sum();
        if total > 0.0 {
            let per_total = 1.0 / total;
            self.group_variance_m2.map(|v| v * per_total)
        } else {
            [0.0; N_GROUPS]
        }
    }
}

/// `Sigma = J diag(sigma^2) J^T` for a Jacobian `j` whose rows are the output axes.
pub fn covariance_of(j: &Jacobian, sigmas: &[f64; N_INPUTS]) -> PointCovariance {
    // Scaled columns c_k = sigma_k J_k: Sigma = sum c_k c_k^T, group variance = sum |c_k|^2.
    let mut cov = Sym::default();
    let mut group_variance_m2 = [0.0; N_GROUPS];
    for (k, input) in Input::ALL.iter().enumerate() {
        let c = j.column(k) * sigmas[k];
        cov.add(&c);
        group_variance_m2[input.group() as usize] += c.norm_squared();
    }
    PointCovariance {
        cov_m2: cov.matrix(),
        group_variance_m2,
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

/// The per-return propagation of a run, for throughput: the axis variances (and optionally
/// group variances) of the same `Sigma = J Q J^T` as [`PointGeometry::jacobian_in_axes`] +
/// [`covariance_of`] (equal to round-off, tested), at half (sigmas) to two thirds (with group
/// variances) of the cost (`benches/uncertainty.rs`).
///
/// Every Jacobian column except the position ones is `R_b^out` times a body-frame vector, so
/// the body-frame covariance of those inputs is summed first and rotated once:
/// `Sigma = J_pos Q_pos J_pos^T + R_b^out Sigma_b R_b^out^T + sigma_dt^2 c c^T`, where the clock
/// column `c = J_pos v_n + R_b^out (omega_b x a_b)` mixes both. Body vectors: attitude
/// `A_k x a_b` (`A` = [`zyx_axes`] of `R_b^n`), lever arm `e_k`, boresight `(R_s^b A_s,k) x
/// x_b` with `x_b = R_s^b x_s = a_b - l` (from `R [x]x = [R x]x R`; `R_s^b A_s` is a per-run
/// constant), scanner `R_s^b dx_s`, latency `omega_b x a_b`. Range noise and zero error share a
/// column, so their variances add. Only the diagonal of `Sigma` is formed. A group's variance
/// is `trace(R Sigma_g R^T) = <R^T R, Sigma_g>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Propagator {
    inputs: UncertaintyInputs,
    with_groups: bool,
    /// `sqrt(sigma_range^2 + sigma_K^2)` (m).
    sigma_range_total_m: f64,
    lever_arm_b_m: Vector3<f64>,
    r_s_to_b: Matrix3<f64>,
    /// Body-frame axes of the boresight angles (`dR_s^b/dk = [w_k]x R_s^b`), as columns.
    boresight_axes_b: Matrix3<f64>,
    /// Body-frame covariance of the lever arm, `diag(sigma_l^2)` (m^2).
    lever: Sym,
}

/// What [`Propagator::variances_of`] reads of one return (see [`Propagator::variances`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnInputs {
    /// `d x_out / d x_e` times `R_n^e` at the IMU.
    pub r_n_to_out: Matrix3<f64>,
    /// Entries (0, 1), (1, 0), (2, 1) of [`LocalLevel::dtheta_per_m`] (the others are 0).
    pub dtheta_per_m: [f64; 3],
    /// `R_b^n` of the georeferencing terms.
    pub r_b_to_n: Matrix3<f64>,
    /// `a_b = l_b + R_s^b x_s` (m).
    pub a_b_m: Vector3<f64>,
    /// `(sin, cos)` of alpha.
    pub sin_cos_alpha: (f64, f64),
    /// `(sin, cos)` of the corrected mirror angle.
    pub sin_cos_beta: (f64, f64),
    /// Corrected range (m).
    pub range_total_m: f64,
    /// Body rate at `t + tau` (rad/s).
    pub omega_b_radps: Vector3<f64>,
    /// NED velocity (m/s).
    pub v_n_mps: Vector3<f64>,
    /// SMRMSG sigmas.
    pub nav: NavSigma,
    /// Partials of the return's time with respect to (t0, T).
    pub dt_dclock: [f64; 2],
}

impl ReturnInputs {
    /// Number of values in [`Self::values`].
    pub const LEN: usize = 43;

    /// The inputs of the arguments of [`Propagator::variances`].
    #[inline]
    pub fn new(
        r_n_to_out: &Matrix3<f64>,
        dtheta_per_m: &Matrix3<f64>,
        t: &ReturnTerms,
        omega_b_radps: &Vector3<f64>,
        v_n_mps: &Vector3<f64>,
        nav: &NavSigma,
        dt_dclock: [f64; 2],
    ) -> Self {
        debug_assert!(
            [(0, 0), (0, 2), (1, 1), (1, 2), (2, 0), (2, 2)]
                .iter()
                .all(|&ij| dtheta_per_m[ij] == 0.0),
            "dtheta_per_m is not a LocalLevel's"
        );
        ReturnInputs {
            r_n_to_out: *r_n_to_out,
            dtheta_per_m: [
                dtheta_per_m[(0, 1)],
                dtheta_per_m[(1, 0)],
                dtheta_per_m[(2, 1)],
            ],
            r_b_to_n: t.r_b_to_n,
            a_b_m: t.a_b_m,
            sin_cos_alpha: t.sin_cos_alpha,
            sin_cos_beta: t.sin_cos_beta,
            range_total_m: t.range_total_m,
            omega_b_radps: *omega_b_radps,
            v_n_mps: *v_n_mps,
            nav: *nav,
            dt_dclock,
        }
    }

    /// The inputs as one array (the columns of a batch of returns, `uncertainty::batch`).
    #[inline(always)]
    pub fn values(&self) -> [f64; Self::LEN] {
        let mut v = [0.0; Self::LEN];
        v[0..9].copy_from_slice(self.r_n_to_out.as_slice());
        v[9..12].copy_from_slice(&self.dtheta_per_m);
        v[12..21].copy_from_slice(self.r_b_to_n.as_slice());
        v[21..24].copy_from_slice(self.a_b_m.as_slice());
        (v[24], v[25], v[26], v[27]) = (
            self.sin_cos_alpha.0,
            self.sin_cos_alpha.1,
            self.sin_cos_beta.0,
            self.sin_cos_beta.1,
        );
        v[28] = self.range_total_m;
        v[29..32].copy_from_slice(self.omega_b_radps.as_slice());
        v[32..35].copy_from_slice(self.v_n_mps.as_slice());
        v[35..38].copy_from_slice(self.nav.pos_ned_m.as_slice());
        v[38..41].copy_from_slice(self.nav.att_rph_rad.as_slice());
        v[41..43].copy_from_slice(&self.dt_dclock);
        v
    }

    /// The inverse of [`Self::values`].
    #[inline(always)]
    pub fn from_values(v: &[f64; Self::LEN]) -> Self {
        let v3 = |k: usize| Vector3::new(v[k], v[k + 1], v[k + 2]);
        ReturnInputs {
            r_n_to_out: Matrix3::from_column_slice(&v[0..9]),
            dtheta_per_m: [v[9], v[10], v[11]],
            r_b_to_n: Matrix3::from_column_slice(&v[12..21]),
            a_b_m: v3(21),
            sin_cos_alpha: (v[24], v[25]),
            sin_cos_beta: (v[26], v[27]),
            range_total_m: v[28],
            omega_b_radps: v3(29),
            v_n_mps: v3(32),
            nav: NavSigma {
                pos_ned_m: v3(35),
                att_rph_rad: v3(38),
            },
            dt_dclock: [v[41], v[42]],
        }
    }
}

impl Propagator {
    /// For a sensor with lever arm `l_b` (m) and boresight `R_s^b`; `with_groups`: also
    /// compute the group variances (for shares).
    pub fn new(
        inputs: UncertaintyInputs,
        with_groups: bool,
        lever_arm_b_m: Vector3<f64>,
        r_s_to_b: Matrix3<f64>,
    ) -> Self {
        let s_lever = &inputs.sigma_lever_arm_b_m;
        Propagator {
            inputs,
            with_groups,
            sigma_range_total_m: inputs.sigma_range_m.hypot(inputs.sigma_range_zero_m),
            lever_arm_b_m,
            r_s_to_b,
            boresight_axes_b: r_s_to_b * zyx_axes(&r_s_to_b),
            lever: Sym::diagonal(&s_lever.component_mul(s_lever)),
        }
    }

    /// The same propagator for a scanner whose beams are `u_s(alpha, beta)` in a frame `s'`
    /// of its own, `x_s = Q x_s'` (a rotating (Palmer) mirror: `app::tpu::scanner`): the
    /// scanner partials are taken in `s'` (`R_s^b Q`; the returns' terms then carry `x_s'`
    /// and `R_s^b Q`), the boresight sigmas stay about the axes of the configured `R_s^b`.
    pub fn with_beam_axes(mut self, q: &Matrix3<f64>) -> Self {
        self.r_s_to_b *= q;
        self
    }

    /// Whether [`Self::variances_of`] computes the group variances.
    pub fn with_groups(&self) -> bool {
        self.with_groups
    }

    /// Variances along the output axes of one return.
    ///
    /// `r_n_to_out`: `d x_out / d x_e` times `R_n^e` at the IMU (e.g. from a
    /// [`super::model::FrameCache`]); `dtheta_per_m`: [`LocalLevel::dtheta_per_m`] (only its
    /// entries (0, 1), (1, 0), (2, 1) are read: the others are 0); `t`: the return's
    /// georeferencing terms (lever arm and boresight as given to [`Self::new`]);
    /// `omega_b_radps`: body rate at `t + tau` (rad/s); `v_n_mps`: NED velocity (m/s); `nav`:
    /// SMRMSG sigmas; `dt_dclock`: as for [`propagate`].
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn variances(
        &self,
        r_n_to_out: &Matrix3<f64>,
        dtheta_per_m: &Matrix3<f64>,
        t: &ReturnTerms,
        omega_b_radps: &Vector3<f64>,
        v_n_mps: &Vector3<f64>,
        nav: &NavSigma,
        dt_dclock: [f64; 2],
    ) -> AxisVariances {
        let x_b = t.a_b_m - self.lever_arm_b_m;
        debug_assert!(
            (x_b - self.r_s_to_b * t.x_s_m).norm() <= 1e-9 * (1.0 + x_b.norm()),
            "terms made with another lever arm or boresight"
        );
        let x = ReturnInputs::new(
            r_n_to_out,
            dtheta_per_m,
            t,
            omega_b_radps,
            v_n_mps,
            nav,
            dt_dclock,
        );
        if self.with_groups {
            self.variances_of::<true>(&x)
        } else {
            self.variances_of::<false>(&x)
        }
    }

    /// [`Self::variances`] of [`ReturnInputs`]; `GROUPS` is [`Self::with_groups`] (a constant,
    /// so that a batch of returns is one branch-free loop, `uncertainty::batch`).
    #[inline(always)]
    pub fn variances_of<const GROUPS: bool>(&self, x: &ReturnInputs) -> AxisVariances {
        let i = &self.inputs;
        let (s_pos, s_att) = (&x.nav.pos_ned_m, &x.nav.att_rph_rad);
        let r_b_n = &x.r_b_to_n;
        let a_b = x.a_b_m;
        let x_b = a_b - self.lever_arm_b_m;
        let (mut att, mut bore, mut scanner) = (Sym::default(), Sym::default(), Sym::default());
        // Attitude axes (zyx_axes): x, (0, c, -s) with (s, c) the normalised (R_zy, R_zz), R^T z.
        let (r20, r21, r22) = (r_b_n[(2, 0)], r_b_n[(2, 1)], r_b_n[(2, 2)]);
        let inv = 1.0 / (r21 * r21 + r22 * r22).sqrt();
        let axes = [
            Vector3::x(),
            Vector3::new(0.0, r22 * inv, -r21 * inv),
            Vector3::new(r20, r21, r22),
        ];
        for k in 0..3 {
            att.add(&(axes[k].cross(&a_b) * s_att[k]));
            let s_bore = i.sigma_boresight_rad[k];
            bore.add(&(self.boresight_axes_b.column(k).cross(&x_b) * s_bore));
        }
        let ((sa, ca), (sb, cb)) = (x.sin_cos_alpha, x.sin_cos_beta);
        let rho = x.range_total_m;
        let scanner_s = [
            Vector3::new(ca, sa * sb, -sa * cb) * (rho * i.sigma_alpha_rad),
            Vector3::new(0.0, -ca * cb, -ca * sb) * (rho * i.sigma_beta_rad),
            Vector3::new(sa, -ca * sb, ca * cb) * self.sigma_range_total_m,
        ];
        for d in &scanner_s {
            scanner.add(&(self.r_s_to_b * d));
        }
        let turn_b = x.omega_b_radps.cross(&a_b);
        let mut latency = Sym::default();
        latency.add(&(turn_b * i.sigma_attitude_latency_s));
        let lever = &self.lever;
        let body = att.plus(&bore).plus(lever).plus(&scanner).plus(&latency);
        let r_n_to_out = &x.r_n_to_out;
        let r_b_out = r_n_to_out * r_b_n;

        // Position columns r_n_to_out (I - [a_n]x dtheta); [a_n]x dtheta has a zero third column.
        let a_n = r_b_n * a_b;
        let [p, q, w] = x.dtheta_per_m;
        let j_pos = [
            r_n_to_out * Vector3::new(1.0 + q * a_n.z, 0.0, -q * a_n.x),
            r_n_to_out * Vector3::new(-w * a_n.y, 1.0 - p * a_n.z + w * a_n.x, p * a_n.y),
            r_n_to_out.column(2).into_owned(),
        ];
        let pos = j_pos
            .iter()
            .zip(s_pos.iter())
            .map(|(j, sk)| (j * *sk).component_mul(&(j * *sk)))
            .fold(Vector3::zeros(), |acc, v| acc + v);
        let v_n_mps = &x.v_n_mps;
        let clock =
            j_pos[0] * v_n_mps.x + j_pos[1] * v_n_mps.y + j_pos[2] * v_n_mps.z + r_b_out * turn_b;
        let clock = clock.component_mul(&clock) * i.clock_time_variance_s2(x.dt_dclock);
        let var_m2 = body.diagonal_rotated(&r_b_out) + pos + clock;

        let group_variance_m2 = if GROUPS {
            let gram = Sym::gram(&r_b_out);
            [
                pos.sum(),
                gram.dot(&att),
                gram.dot(lever),
                gram.dot(&bore),
                gram.dot(&scanner),
                clock.sum() + gram.dot(&latency),
            ]
        } else {
            [0.0; N_GROUPS]
        };
        AxisVariances {
            var_m2,
            group_variance_m2,
        }
    }
}

/// A symmetric 3x3 matrix by its upper triangle `(xx, xy, xz, yy, yz, zz)`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Sym([f64; 6]);

impl Sym {
    #[inline(always)]
    fn diagonal(d: &Vector3<f64>) -> Sym {
        Sym([d.x, 0.0, 0.0, d.y, 0.0, d.z])
    }

    /// Adds `c c^T`.
    #[inline(always)]
    fn add(&mut self, c: &Vector3<f64>) {
        let (x, y, z) = (c.x, c.y, c.z);
        let m = &mut self.0;
        m[0] += x * x;
        m[1] += x * y;
        m[2] += x * z;
        m[3] += y * y;
        m[4] += y * z;
        m[5] += z * z;
    }

    #[inline(always)]
    fn plus(&self, o: &Sym) -> Sym {
        Sym(std::array::from_fn(|k| self.0[k] + o.0[k]))
    }

    #[inline(always)]
    fn matrix(&self) -> Matrix3<f64> {
        let [xx, xy, xz, yy, yz, zz] = self.0;
        Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
    }

    /// `R^T R`.
    #[inline(always)]
    fn gram(r: &Matrix3<f64>) -> Sym {
        let (c0, c1, c2) = (r.column(0), r.column(1), r.column(2));
        Sym([
            c0.dot(&c0),
            c0.dot(&c1),
            c0.dot(&c2),
            c1.dot(&c1),
            c1.dot(&c2),
            c2.dot(&c2),
        ])
    }

    /// `sum_ij A_ij B_ij`.
    #[inline(always)]
    fn dot(&self, o: &Sym) -> f64 {
        let (a, b) = (&self.0, &o.0);
        a[0] * b[0] + a[3] * b[3] + a[5] * b[5] + 2.0 * (a[1] * b[1] + a[2] * b[2] + a[4] * b[4])
    }

    /// The diagonal of `R S R^T`.
    #[inline(always)]
    fn diagonal_rotated(&self, r: &Matrix3<f64>) -> Vector3<f64> {
        let [xx, xy, xz, yy, yz, zz] = self.0;
        let d = |i: usize| {
            let (a, b, c) = (r[(i, 0)], r[(i, 1)], r[(i, 2)]);
            a * (a * xx + b * xy + c * xz)
                + b * (a * xy + b * yy + c * yz)
                + c * (a * xz + b * yz + c * zz)
        };
        Vector3::new(d(0), d(1), d(2))
    }
}
