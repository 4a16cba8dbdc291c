//! Command-line parsing and dispatch. `anyhow` lives here only; the library returns
//! `kinescan::Error`.

mod calib_cmds;
mod day_cmd;
mod diagnose_cmd;
mod pipeline_cmds;
mod sensitivity_cmd;
mod sim_cmds;
mod tpu_cmd;
mod trajectory_cmd;

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
    Day(day_cmd::DayArgs),
    Trajectory(trajectory_cmd::TrajectoryArgs),
    Tpu(tpu_cmd::TpuArgs),
}

/// Exit code of a command stopped by SIGINT or SIGTERM (128 + SIGINT, the shell's convention).
const EXIT_INTERRUPTED: u8 = 130;

/// SIGINT and SIGTERM ask the command to stop ([`kinescan::interrupt`]): it unwinds, removing
/// its temporaries, and exits with [`EXIT_INTERRUPTED`] and a one-line message. A second signal
/// exits at once (a stage that does not look at the request yet; its temporaries carry the pid
/// and are removed by the next command writing there).
fn stop_cleanly_on_signals() {
    let installed = ctrlc::set_handler(|| {
        if kinescan::interrupt::request() {
            eprintln!("error: interrupted twice: stopped at once");
            std::process::exit(i32::from(EXIT_INTERRUPTED));
        }
    });
    if let Err(e) = installed {
        eprintln!("warning: SIGINT/SIGTERM will stop kinescan without cleaning up: {e}");
    }
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

/// Removes the temporaries of dead kinescan processes (killed runs) from `dir`, a folder the
/// command writes.
pub(crate) fn remove_stale_temps(dir: &std::path::Path) -> anyhow::Result<()> {
    let dir = match dir.as_os_str().is_empty() {
        true => std::path::Path::new("."),
        false => dir,
    };
    kinescan::io::atomic::remove_stale_temps(dir)?;
    Ok(())
}

/// `--threads N`: a whole number >= 1; above [`MAX_THREADS_PER_CPU`] times the machine's
/// CPUs it is clamped there, with a warning (more threads only cost memory and switches).
pub(crate) fn threads(s: &str) -> Result<usize, String> {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1 (omit it to use every core)".into()),
        Ok(n) if n > MAX_THREADS_PER_CPU * cpus => {
            let max = MAX_THREADS_PER_CPU * cpus;
            eprintln!(
                "warning: --threads {n} is more than {MAX_THREADS_PER_CPU} times this machine's \
                 {cpus} CPUs: using {max} threads"
            );
            Ok(max)
        }
        Ok(n) => Ok(n),
        Err(e) => Err(format!("`{s}` is not a whole number: {e}")),
    }
}

/// The most threads per CPU `--threads` starts.
const MAX_THREADS_PER_CPU: usize = 4;

/// Parses the command line, runs the command, maps errors to a message and exit code 1.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    stop_cleanly_on_signals();
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
        Command::Day(a) => day_cmd::day(a, cli.quiet),
        Command::Trajectory(a) => trajectory_cmd::trajectory(a, cli.quiet),
        Command::Tpu(a) => tpu_cmd::tpu(a, cli.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            let interrupted = e
                .chain()
                .any(|c| matches!(c.downcast_ref(), Some(kinescan::Error::Interrupted)));
            if interrupted {
                ExitCode::from(EXIT_INTERRUPTED)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
