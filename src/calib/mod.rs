//! Calibration tools: sphere fitting, rotating-table latency calibration
//! (paper 000) and tripod boresight calibration (paper 002), with their simulator scenarios.
//!
//! Conventions are the conventions': latency `tau` with the attitude evaluated at `t + tau`; boresight
//! `R_s^b = Rz(bz) Ry(by) Rx(bx)`; beam `u_s(alpha, beta)`. The user guide, file formats and the
//! mapping of the papers' conventions are in `docs/calibration.md`.
//!
//! Files: configs through `io::config_file`, scanner returns through the conventions §6 reader
//! (`io::profiles_csv`), the lab's tables through `io::csv_text::CsvTable`, outputs through
//! `io::atomic`. The tables:
//! - table passes: `pass,t_start_s,t_end_s,table_rate_deg_s` (signed rate about the table axis).
//! - IMU attitude stream: `time_s,roll_deg,pitch_deg,heading_deg` (convention attitude angles).
//! - tripod ellipse centres: `site,leg,y_s_m,z_s_m,sigma_m` (scan-plane coordinates, s frame).
//! - tripod sites: `site,roll_deg,pitch_deg,heading_deg,sigma_roll_deg,sigma_pitch_deg,
//!   sigma_heading_deg` (IMU attitude averaged over the static scan).

pub mod boresight;
pub mod ellipse;
pub mod latency;
pub mod sim_table;
pub mod sim_tripod;
pub mod sphere;
pub(crate) mod tripod;

/// `v > 0` and not NaN: the validity test for sizes, sigmas and rates read from configs.
pub(crate) fn positive(v: f64) -> bool {
    v > 0.0
}

pub use boresight::{run_boresight_calibration, BoresightReport};
pub use latency::{run_latency_calibration, LatencyReport};
