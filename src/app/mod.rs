//! Application commands built on the pipeline: each reads pipeline files and writes reports.

pub mod diagnose;
