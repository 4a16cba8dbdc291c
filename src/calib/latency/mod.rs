//! Latency calibration on a rotating table (paper 000, sections 2.2-4; paper 002, section 2).
//!
//! The scanner and IMU turn together on a table at known angular rates `+omega` and `-omega`
//! (rad/s, from the table's own log, about the unit axis `a_n` fixed in the NED frame `n`, whose
//! origin is the table's centre of rotation). Each return (time `t`) is placed in `n` with the
//! IMU attitude evaluated at `t + tau_applied` (conventions §2):
//! `x_n = R_b^n(t + tau_applied) * (l_b + R_s^b * (rho + K) * u_s(alpha, beta))`.
//! A residual latency `dtau = tau - tau_applied` rotates every return by `-omega * dtau` about
//! `a_n`, so the fitted sphere centre of each direction is shifted:
//! `c_pm = x - dtau * (omega_pm a_n) x x` (paper eq. 3 with the paper's `dt` = convention `tau`).
//! With `d = c_minus - c_plus` and `g = (omega_plus - omega_minus) a_n x xbar` the least-squares
//! solution of eq. 3 in 3D (any axis) is `dtau = g.d / |g|^2`, variance
//! `g^T (Cov_plus + Cov_minus) g / |g|^4`. Paper eq. 4 takes norms (`|d| / |g|`), which loses the
//! sign and is biased upwards by noise; the projection keeps the sign and is unbiased, and equals
//! eq. 4 when `d` is parallel to `g`. Speeds are combined by inverse-variance weights.
//!
//! Modules: `estimate` (the estimator), `config` (the TOML file), `inputs` (the CSV files),
//! `run` (the command, its table and plot).

mod config;
mod estimate;
mod inputs;
mod run;

pub use config::{LatencyConfig, LatencyFiles, ScannerConfig, SphereConfig, TableConfig};
pub use estimate::{
    beam_s, estimate_latency, residual_latency, AttitudeSample, LatencyData, LatencyReport,
    LatencySetup, SpeedResult, TablePass, TimedReturn,
};
pub use inputs::{read_attitude, read_passes, read_returns};
pub use run::{latency_plot, run_latency_calibration, speed_table_csv, OUTPUT_FILES};
