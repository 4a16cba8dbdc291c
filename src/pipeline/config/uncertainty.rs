//! `[uncertainty]`: the 1-sigma inputs of the per-point uncertainty (docs/uncertainty.md).

use super::refusal::{elements, refuse, require_non_negative, Refusal};
use serde::{Deserialize, Serialize};

/// `[uncertainty]`: 1-sigma of the inputs not in the SMRMSG file (conventions §5). Every sigma must be
/// given (0 is allowed and means "exact"), so no error source is dropped silently.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyConfig {
    /// Lever arm x, y, z (m).
    pub sigma_lever_arm_b_m: [f64; 3],
    /// Boresight angles bx, by, bz (deg).
    pub sigma_boresight_deg: [f64; 3],
    /// Out-of-plane angle alpha (deg).
    pub sigma_alpha_deg: f64,
    /// Mirror angle encoder beta (deg).
    pub sigma_beta_deg: f64,
    /// Range noise (m).
    pub sigma_range_m: f64,
    /// Range zero error K (m).
    pub sigma_range_zero_m: f64,
    /// Covariance of the clock parameters (t0, T) (s^2), `[[var_t0, cov], [cov, var_T]]`.
    pub clock_covariance_s2: [[f64; 2]; 2],
    /// Attitude latency tau (s).
    pub sigma_attitude_latency_s: f64,
    /// Also write `thu95` and `tvu95` (95% horizontal and vertical, m). Default false: they
    /// follow from `sigma_x/y/z`, and cost 8 bytes a point.
    #[serde(default)]
    pub write_95: bool,
    /// Also write the per-group variance shares `share_<group>` (fractions, one scaled byte
    /// each). Default false: 6 bytes a point.
    #[serde(default)]
    pub write_shares: bool,
}

impl UncertaintyConfig {
    /// The sigmas in SI units (degrees converted to radians).
    pub fn inputs(&self) -> crate::uncertainty::UncertaintyInputs {
        let c = self.clock_covariance_s2;
        crate::uncertainty::UncertaintyInputs {
            sigma_lever_arm_b_m: self.sigma_lever_arm_b_m.into(),
            sigma_boresight_rad: self.sigma_boresight_deg.map(f64::to_radians).into(),
            sigma_alpha_rad: self.sigma_alpha_deg.to_radians(),
            sigma_beta_rad: self.sigma_beta_deg.to_radians(),
            sigma_range_m: self.sigma_range_m,
            sigma_range_zero_m: self.sigma_range_zero_m,
            clock_covariance_s2: nalgebra::Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]),
            sigma_attitude_latency_s: self.sigma_attitude_latency_s,
        }
    }

    /// Checks sigmas are finite and >= 0 and the clock covariance symmetric positive
    /// semi-definite; keys are named under `table` (`uncertainty` in a pipeline file).
    pub fn check(&self, table: &str) -> Result<(), Refusal> {
        let scalars = [
            ("sigma_alpha_deg", self.sigma_alpha_deg),
            ("sigma_beta_deg", self.sigma_beta_deg),
            ("sigma_range_m", self.sigma_range_m),
            ("sigma_range_zero_m", self.sigma_range_zero_m),
            ("sigma_attitude_latency_s", self.sigma_attitude_latency_s),
        ];
        let (lever, boresight) = (
            format!("{table}.sigma_lever_arm_b_m"),
            format!("{table}.sigma_boresight_deg"),
        );
        require_non_negative(
            elements(&lever, &self.sigma_lever_arm_b_m)
                .chain(elements(&boresight, &self.sigma_boresight_deg))
                .chain(scalars.map(|(k, v)| (format!("{table}.{k}"), v))),
        )?;
        let c = self.clock_covariance_s2;
        let psd = c.iter().flatten().all(|v| v.is_finite())
            && c[0][1] == c[1][0]
            && c[0][0] >= 0.0
            && c[1][1] >= 0.0
            && c[0][0] * c[1][1] >= c[0][1] * c[0][1];
        if !psd {
            let msg = format!("must be symmetric positive semi-definite, got {c:?}");
            return Err(refuse(format!("{table}.clock_covariance_s2"), msg));
        }
        Ok(())
    }
}
