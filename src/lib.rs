//! kinescan: post-processing for mobile (vehicle-borne) laser scanning.
//!
//! Data flows one way through the modules: `geo` (ellipsoid, rotations, projections) ->
//! `io` (file formats) -> `trajectory` -> `timing` -> `georef` -> `uncertainty` ->
//! `pipeline` (stages) -> `app` (commands that combine stages: demo, diagnose, sensitivity);
//! `sim` and `calib` sit beside the pipeline and use the lower layers. docs/architecture.md
//! maps the modules.
//! Conventions (frames, signs, time model, files, effect catalogue) are docs/conventions.md;
//! "conventions §N" in the code cites its section N.
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
