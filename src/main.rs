//! The `kinescan` command line: a thin layer over the library.
#![allow(clippy::disallowed_methods)] // clippy.toml's NaN rule is for tests/suite

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    cli::run()
}
