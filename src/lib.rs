//! kinescan: post-processing for mobile (vehicle-borne) laser scanning.
//!
//! Data flows one way through the modules: `geo` (ellipsoid, rotations, projections) ->
//! `io` (file formats) -> `trajectory` -> `timing` -> `georef` -> `uncertainty` ->
//! `pipeline`; `sim` and `calib` sit beside the pipeline and use the lower layers.
//! Conventions (frames, signs, time model) follow `../shared/SPEC.md`, restated in `docs/`.
#![forbid(unsafe_op_in_unsafe_fn)]

pub mod app;
pub mod calib;
pub mod error;
pub mod geo;
pub mod georef;
pub mod interrupt;
pub mod io;
pub mod pipeline;
pub mod plot;
pub mod progress;
pub mod sim;
pub mod sync;
pub mod timing;
pub mod trajectory;
pub mod uncertainty;

pub use error::{Error, Result};
