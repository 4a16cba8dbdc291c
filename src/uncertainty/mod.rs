//! Per-point propagated uncertainty and variance-based sensitivity (conventions §5).
//!
//! - [`model`]: the georeferencing equation as a function of the 18 error inputs, exact and
//!   linearised (analytic Jacobian).
//! - [`mod@propagate`]: `Sigma = J Q J^T` per return along the map axes, 95% figures and per-group
//!   variance shares; [`batch`]: the same for many returns at once, vectorised.
//! - [`sobol`]: Saltelli sampling, Saltelli-2010 first-order and Jansen total-effect
//!   estimators with bootstrap intervals, on the exact model.
//!
//! The `kinescan sensitivity` study built on them is an application command (`app::sensitivity`).
//!
//! docs/uncertainty.md documents the model, the inputs and the output fields.

pub mod batch;
pub mod model;
pub mod propagate;
pub mod sobol;

pub use model::{Group, Input, PointGeometry, N_GROUPS, N_INPUTS};
pub use propagate::{propagate, PointCovariance, UncertaintyInputs};
