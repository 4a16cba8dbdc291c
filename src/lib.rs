//! kinescan: post-processing for mobile (vehicle-borne) laser scanning.
//!
//! Data flows one way through the modules: `geo` (ellipsoid, rotations, projections) ->
//! `io` (file formats) -> `trajectory` -> `timing` -> `georef` -> `uncertainty` ->
//! `pipeline` (stages) -> `app` (commands that combine stages: demo, diagnose, sensitivity);
//! `sim` and `calib` sit beside the pipeline and use the lower layers. docs/architecture.md
//! maps the modules.
//! Conventions (frames, signs, time model, files, effect catalogue) are docs/conventions.md;
//! "conventions §N" in the code cites its section N.
//!
//! # Library use
//!
//! The `kinescan` binary is a thin layer over this library; a program can do what it does.
//! Load a pipeline file (the same TOML and `--set` overrides as `kinescan run`), run it, read
//! the report:
//!
//! ```no_run
//! use kinescan::pipeline::{self, RunOptions};
//!
//! let set = ["output.scale_m=0.001".to_string()];
//! let loaded = pipeline::load("survey/pipeline.toml".as_ref(), &set)?;
//! let opts = RunOptions { progress: false, ..RunOptions::default() };
//! let report = pipeline::run(&loaded, &opts)?; // also written as JSON beside the LAS
//! println!("{} of {} returns written", report.totals.written, report.totals.read);
//! # Ok::<(), kinescan::Error>(())
//! ```
//!
//! The public surface (everything else is `pub(crate)`; docs/architecture.md lists it too):
//! - **pipeline**: [`pipeline::load`], [`pipeline::run`], [`pipeline::check_inputs`],
//!   [`pipeline::RunOptions`], the options ([`pipeline::config`]), the report
//!   ([`pipeline::report::RunReport`], serialisable), the per-return
//!   [`pipeline::georeference::ReturnGeoreferencer`].
//! - **file formats** ([`io`]): trajectories [`io::sbet`], [`io::smrmsg`]; scanner profiles
//!   [`io::profiles`] (binary), [`io::profiles_csv`]; [`io::points`], [`io::patches`]; the
//!   [`io::las`] writer and [`io::laz`]; [`io::info::describe`]; config files
//!   [`io::config_file`]; atomic outputs [`io::atomic`].
//! - **geodesy** ([`geo`]): [`geo::ellipsoid`], [`geo::rotations`],
//!   [`geo::projection::MapFrame`] (UTM, ECEF, ENU, EPSG), [`geo::local`], [`geo::geoid`].
//! - **the models**: [`trajectory`], [`timing`], [`georef`] (the equation), [`uncertainty`].
//! - **commands**: [`sim::simulate`], [`sync::estimate`], [`calib`] (latency, boresight),
//!   [`app`] (demo, diagnose, sensitivity).
//! - **errors**: [`Error`] (every message names the file and record, or the config key) and
//!   [`Result`].
#![forbid(unsafe_op_in_unsafe_fn)]
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

pub mod app;
pub mod calib;
mod error;
pub mod geo;
pub mod georef;
pub mod ins;
pub mod interrupt;
pub mod io;
pub mod pipeline;
pub mod plot;
pub mod progress;
pub mod sim;
pub mod sync;
#[doc(hidden)]
pub mod testing;
pub mod timing;
pub mod trajectory;
pub mod uncertainty;

pub use error::{Error, Result};
