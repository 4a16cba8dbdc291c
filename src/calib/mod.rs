//! Calibration tools: sphere fitting, rotating-table latency calibration
//! (paper 000) and tripod boresight calibration (paper 002), with their simulator scenarios.
//!
//! Conventions are the conventions': latency `tau` with the attitude evaluated at `t + tau`; boresight
//! `R_s^b = Rz(bz) Ry(by) Rx(bx)`; beam `u_s(alpha, beta)`. The user guide, file formats and the
//! mapping of the papers' conventions are in `docs/calibration.md`.

pub mod boresight;
pub mod ellipse;
pub mod files;
pub mod latency;
pub mod sim_table;
pub mod sim_tripod;
pub mod sphere;
pub mod tripod;

/// `v > 0` and not NaN: the validity test for sizes, sigmas and rates read from configs.
pub(crate) fn positive(v: f64) -> bool {
    v > 0.0
}

pub use boresight::{run_boresight_calibration, BoresightReport};
pub use latency::{run_latency_calibration, LatencyReport};
