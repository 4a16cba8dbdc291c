//! Tripod boresight calibration (paper 002, sections 4.2 and 5).
//!
//! Model. At site `k` the IMU attitude is `R_k = R_b^n` and the scanner sees the static tripod's
//! unit leg directions `u_ki` (frame `s`, `calib::tripod`). The legs are fixed in NED, so
//! `R_k R_s^b u_ki = w_i` for all sites (paper: "foot vectors invariant"; unit vectors, because
//! the cut moves along the legs from site to site). The boresight is parametrised as
//! `R_s^b = Rz(dz) Ry(dy) Rx(dx) * R_nom`: a misalignment `d = (dx, dy, dz)` (rad) about the body
//! axes (boresight roll, pitch, heading) on top of the nominal mounting `R_nom` (convention angles
//! from the config). With `R_nom = I`, `d` are the conventions' `(bx, by, bz)` directly. The estimate is
//! reported both as `d` and as convention angles of `R_s^b`, so a pipeline file takes it directly.
//!
//! Estimation: weighted Gauss-Newton on `d` and the tripod's orientation in NED from residuals
//! `R_k R_s^b(d) u_ki - w_i` (9 per site). The cosine law makes the three `u_ki` of a site a
//! rigid triad with the tripod's inter-leg angles, so noise only rotates the triad: a site
//! carries 3 independent observations (the paper's "nine equations" for three sites), and the
//! legs in NED are a rigid triad `w_i = Rot(phi) w_i0` with 3 unknowns `phi` (multiplicative
//! update; `w_i0` from site 1 with the nominal boresight). The weight of a site is the
//! pseudo-inverse of its residual covariance (rank 3): the leg-direction covariance propagated
//! from the ellipse-centre sigmas (central differences through resection and apex) plus the IMU
//! attitude sigmas (paper footnote 1). Start: closed-form hand-eye solution from the relative
//! rotations between sites (see `hand_eye_start`). The covariance of `d` is the inverse
//! normal matrix (a-priori, not rescaled); the variance factor is reported.
//!
//! Observability: with `>= 3` sites whose relative rotations are not all about one axis
//! ("collinear" sites) all three angles are determined; identical or collinear sites are
//! refused.
//!
//! Modules: `estimate` (the estimator), `config` (the TOML file), `inputs` (the CSV files),
//! `run` (the command).

mod config;
mod estimate;
mod inputs;
mod run;

pub use super::tripod::BoresightSetup;
pub use config::{BoresightConfig, BoresightFiles, BoresightScannerConfig, TripodConfig};
pub use estimate::{estimate_boresight, BoresightReport, SiteResult, TripodSite, MAX_ITERATIONS};
pub use inputs::{read_scan_sites, read_sites};
pub use run::run_boresight_calibration;
