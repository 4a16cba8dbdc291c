//! The application layer: commands that combine stages and libraries. Nothing below imports
//! from here; the command-line interface (`src/cli`) calls these.
//!
//! - [`day`]: a survey day processed overnight in resumable work units (`kinescan day`).
//! - [`demo`]: simulate a city block, run the pipeline on it, compare with the truth.
//! - [`diagnose`]: the sim-to-real gap diagnosis (`kinescan diagnose`, docs/diagnosis.md).
//! - [`sensitivity`]: the `kinescan sensitivity` study (the uncertainty model on flat-ground
//!   points or on a simulated survey's returns).
//! - [`tpu`]: per-point uncertainty for a cloud georeferenced elsewhere (`kinescan tpu`,
//!   docs/tpu.md).
//! - [`verify`]: whether a folder's output sets are whole (`kinescan info FOLDER`).
//!
//! A new command that chains stages (e.g. a batch of days) goes here, as its own module,
//! calling the pipeline's stages ([`crate::pipeline`]) and libraries.

pub mod day;
pub mod demo;
pub mod diagnose;
pub mod sensitivity;
pub mod tpu;
pub mod verify;
