//! The staged batch processor.
//!
//! Lifecycle of a run: **load** the pipeline file (all options declared in [`config`], unknown
//! keys refused, `--set` overrides applied) -> **prepare** (open and validate the trajectory,
//! map or import the profile files) -> **georeference** (chunks of returns in parallel: time
//! model, trajectory interpolation with latency, SPEC 4 equation, map projection) -> **write**
//! (LAS 1.4 streamed in input order, atomically) -> **report** (JSON run report).

pub mod config;
pub mod executor;
pub mod files;
pub mod publish;
pub mod report;
pub mod sink;
