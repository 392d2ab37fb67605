//! `ringsync`: plan, simulate and run a networked CNC ring with position synchronisation
//! (Huang et al. 2015). Thin: parse, call the library crates, print.

mod latency_cmd;
mod plan_cmd;
mod rt_cmd;
mod scenario_cmd;
mod sim_cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Exit status for bad input: options, values, files (as clap uses for usage errors).
const EXIT_USAGE: u8 = 2;
/// Exit status for a failure while doing the work (I/O and the like).
const EXIT_FAILURE: u8 = 1;

/// What went wrong, and so which exit status.
#[derive(Debug)]
enum CliError {
    /// The user's input is wrong: one line, exit status 2.
    Usage(String),
    /// The work failed: exit status 1.
    Failure(anyhow::Error),
}

impl From<anyhow::Error> for CliError {
    fn from(e: anyhow::Error) -> Self {
        CliError::Failure(e)
    }
}

#[derive(Parser)]
#[command(
    name = "ringsync",
    version,
    about = "Plan, simulate and run a networked CNC ring with position synchronisation (Huang et al. 2015)",
    long_about = None,
    propagate_version = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Cycle-time planner (eq. 1-2): how fast a ring of n axes can cycle and where the time goes.
    Plan(plan_cmd::PlanArgs),
    /// Built-in scenarios: list them, print one as editable TOML, validate a file.
    #[command(subcommand)]
    Scenario(scenario_cmd::ScenarioCmd),
    /// Stability analysis of a scenario: discrete-time spectral radius and the paper's conditions.
    Check(scenario_cmd::CheckArgs),
    /// Simulate a scenario: summary.json and trace.csv.
    Sim(sim_cmd::SimArgs),
    /// Reproduce the paper's Table 1 on the reference scenario (PD, sync, ring-coupled).
    Reproduce(sim_cmd::ReproduceArgs),
    /// Run a scenario in real time over UDP on loopback or a veth ring of network namespaces.
    Rt(rt_cmd::RtArgs),
    /// What this host gives a real-time loop, without the ring (cyclictest-like): cycle-start
    /// lateness and stalls, with the same loop and settings as `rt`.
    Latency(latency_cmd::LatencyArgs),
    /// Sweep scenario keys (their product, several seeds each) in parallel: CSV and a figure.
    Sweep(sim_cmd::SweepArgs),
}

/// Writes `text` to standard output. A closed pipe (`ringsync plan | head`) ends the output
/// quietly instead of failing.
pub(crate) fn out(text: &str) -> Result<(), CliError> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(CliError::Failure(
            anyhow::Error::new(e).context("cannot write to standard output"),
        )),
    }
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            match e.kind() {
                ErrorKind::DisplayHelp
                | ErrorKind::DisplayVersion
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => e.exit(),
                _ => {
                    // clap's message is several lines; its first line names the option and
                    // the problem. Keep that one and point to --help.
                    let text = e.to_string();
                    let first = text.lines().next().unwrap_or("invalid arguments");
                    let first = first.strip_prefix("error: ").unwrap_or(first);
                    eprintln!("ringsync: error: {first} (see ringsync --help)");
                    return ExitCode::from(EXIT_USAGE);
                }
            }
        }
    };
    let result = match cli.command {
        Command::Plan(args) => plan_cmd::run(&args),
        Command::Scenario(cmd) => scenario_cmd::run(&cmd),
        Command::Check(args) => scenario_cmd::check(&args),
        Command::Sim(args) => sim_cmd::sim(&args),
        Command::Reproduce(args) => sim_cmd::reproduce(&args),
        Command::Sweep(args) => sim_cmd::sweep(&args),
        Command::Rt(args) => rt_cmd::rt(&args),
        Command::Latency(args) => latency_cmd::latency(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::Usage(msg)) => {
            eprintln!("ringsync: error: {msg}");
            ExitCode::from(EXIT_USAGE)
        }
        Err(CliError::Failure(e)) => {
            eprintln!("ringsync: error: {e:#}");
            ExitCode::from(EXIT_FAILURE)
        }
    }
}
