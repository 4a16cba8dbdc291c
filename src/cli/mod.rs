//! Command-line parsing and dispatch. `anyhow` lives here only; the library returns
//! `kinescan::Error`.

mod calib_cmds;
mod diagnose_cmd;
mod pipeline_cmds;
mod sensitivity_cmd;
mod sim_cmds;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// kinescan: georeferenced, uncertainty-tagged LAS from mobile laser scanning.
#[derive(Parser)]
#[command(name = "kinescan", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// No progress bars or summaries (errors still go to stderr).
    #[arg(long, short, global = true)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    Run(pipeline_cmds::RunArgs),
    Validate(pipeline_cmds::ValidateArgs),
    Import(pipeline_cmds::ImportArgs),
    Info(pipeline_cmds::InfoArgs),
    Calibrate(calib_cmds::CalibrateArgs),
    Simulate(sim_cmds::SimulateArgs),
    Demo(sim_cmds::DemoArgs),
    Sensitivity(sensitivity_cmd::SensitivityArgs),
    Diagnose(diagnose_cmd::DiagnoseArgs),
}

/// The error and its causes joined by `: `, leaving out a cause whose text is already in the
/// message (the library's errors carry their OS error's text: printed once, not twice).
fn message(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    msg
}

/// `--threads N`: a whole number >= 1.
pub(crate) fn threads(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1 (omit it to use every core)".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("`{s}` is not a whole number: {e}")),
    }
}

/// Parses the command line, runs the command, maps errors to a message and exit code 1.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Run(a) => pipeline_cmds::run(a, cli.quiet),
        Command::Validate(a) => pipeline_cmds::validate(a),
        Command::Import(a) => pipeline_cmds::import(a, cli.quiet),
        Command::Info(a) => pipeline_cmds::info(a),
        Command::Calibrate(a) => calib_cmds::calibrate(a, cli.quiet),
        Command::Simulate(a) => sim_cmds::simulate(a, cli.quiet),
        Command::Demo(a) => sim_cmds::demo(a, cli.quiet),
        Command::Sensitivity(a) => sensitivity_cmd::sensitivity(a, cli.quiet),
        Command::Diagnose(a) => diagnose_cmd::diagnose(a, cli.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            ExitCode::FAILURE
        }
    }
}
