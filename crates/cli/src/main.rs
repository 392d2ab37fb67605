//! `ringsync`: plan, simulate and run a networked CNC ring with position synchronisation
//! (Huang et al. 2015). Thin: parse the command line, call the `ringsync` library, print.

mod latency_cmd;
mod node_cmd;
mod plan_cmd;
mod program_cmd;
mod rt_cmd;
mod scenario_cmd;
#[cfg(feature = "scope")]
mod scope_opt;
mod sim_cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Exit status for bad input: options, values, files (as clap uses for usage errors).
const EXIT_USAGE: u8 = 2;
/// Exit status for a failure while doing the work (I/O and the like).
const EXIT_FAILURE: u8 = 1;
/// Exit status for work that finished, results written, with a bad outcome.
const EXIT_FLAGGED: u8 = 3;

/// Longest line of an error message [characters]: echoed values are cut in the middle.
const ERROR_LINE_CHARS: usize = 400;

/// The exit statuses, for `ringsync --help` (README.md says the same).
const EXIT_STATUSES: &str = "\
Exit status:
  0  success
  1  a runtime or I/O error; also work interrupted by Ctrl-C: an `rt` run or a `sweep`
     writes what it finished, a `sim` or `reproduce` writes nothing
  2  bad usage or input: options, scenario files, an --out that is not a results directory
  3  the work finished and its results are written, but `sim`, `reproduce`, `sweep` (any
     case) or `rt` ended in a group stop, or `check` could not show the loop stable
     (spectral radius >= 1, or a loop it does not model: verdict `not shown`)

--out DIR is replaced as a whole when a run succeeds (or ends in status 3): the results are
written beside it first, so DIR holds one run's complete results or the previous ones.";

/// How a command that did its work ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// All well: exit status 0.
    Done,
    /// Finished and results written, but the run ended in a group stop or the check could
    /// not show the loop stable: exit status 3.
    Flagged,
}

impl Outcome {
    /// `Flagged` when `bad`, else `Done`.
    pub(crate) fn flagged_if(bad: bool) -> Self {
        if bad { Outcome::Flagged } else { Outcome::Done }
    }
}

/// What went wrong, and so which exit status.
#[derive(Debug)]
enum CliError {
    /// The user's input is wrong: one line, exit status 2.
    Usage(String),
    /// The work failed: exit status 1.
    Failure(String),
}

impl From<ringsync::Error> for CliError {
    fn from(e: ringsync::Error) -> Self {
        if e.is_usage() {
            CliError::Usage(e.to_string())
        } else {
            CliError::Failure(e.to_string())
        }
    }
}

#[derive(Parser)]
#[command(
    name = "ringsync",
    version = concat!(env!("CARGO_PKG_VERSION"), " (", env!("RINGSYNC_GIT_HASH"), ")"),
    about = "Plan, simulate and run a networked CNC ring with position synchronisation (Huang et al. 2015)",
    long_about = None,
    propagate_version = true,
    after_help = EXIT_STATUSES
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
    /// Plan a scenario's part program without simulating it: duration, each axis's peak
    /// velocity, acceleration and jerk at the cycle against its limits, what bounds the feed.
    Program(program_cmd::ProgramArgs),
    /// Simulate a scenario: summary.json and trace.csv.
    Sim(sim_cmd::SimArgs),
    /// Reproduce the paper's Table 1 on the reference scenario (PD, sync, ring-coupled).
    Reproduce(sim_cmd::ReproduceArgs),
    /// Run a scenario in real time over UDP on loopback or a veth ring of network namespaces.
    Rt(Box<rt_cmd::RtArgs>),
    /// Run one node of a ring as this process (what `rt --processes` starts, one per node;
    /// docs/runtime.md, "One process per node").
    #[command(subcommand)]
    Node(node_cmd::NodeCmd),
    /// What this host gives a real-time loop, without the ring (cyclictest-like): cycle-start
    /// lateness and stalls, with the same loop and settings as `rt`.
    Latency(latency_cmd::LatencyArgs),
    /// Identify a run's axes (H = J/K_a, C = b/K_a, F = T_c/K_a by least squares) and write
    /// its scenario with them as feed-forward.
    Identify(sim_cmd::IdentifyArgs),
    /// Sweep scenario keys (their product, several seeds each), or one scenario over many
    /// seeds, in parallel: CSV and a figure.
    Sweep(sim_cmd::SweepArgs),
    /// Print a shell completion script for bash, zsh, fish, elvish or powershell (e.g.
    /// `ringsync completions bash > ~/.local/share/bash-completion/completions/ringsync`).
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Write the man pages (ringsync.1 and one per command, ringsync-sim.1, …) into a
    /// directory, generated from these same definitions (`man -l DIR/ringsync.1`).
    Man {
        /// Directory to write them into (created if missing).
        #[arg(long, value_name = "DIR", default_value = "man")]
        out: std::path::PathBuf,
    },
}

/// `ringsync completions SHELL`: the script on standard output.
fn completions(shell: clap_complete::Shell) -> Result<Outcome, CliError> {
    use clap::CommandFactory as _;
    let mut buf = Vec::new();
    clap_complete::generate(shell, &mut Cli::command(), "ringsync", &mut buf);
    out(&String::from_utf8_lossy(&buf))
}

/// `ringsync man --out DIR`: ringsync.1 and a page per command (and per subcommand of
/// `scenario` and `node`), each written atomically.
fn man_pages(dir: &std::path::Path) -> Result<Outcome, CliError> {
    use clap::CommandFactory as _;
    let failed = |e: std::io::Error| {
        CliError::Failure(format!(
            "cannot write the man pages into {}: {e}",
            dir.display()
        ))
    };
    std::fs::create_dir_all(dir).map_err(failed)?;
    let mut written = Vec::new();
    fn walk(
        cmd: clap::Command,
        name: String,
        dir: &std::path::Path,
        written: &mut Vec<String>,
    ) -> Result<(), CliError> {
        let cmd = cmd
            .display_name(name.clone())
            .bin_name(name.replace('-', " "));
        let mut buf = Vec::new();
        clap_mangen::Man::new(cmd.clone())
            .render(&mut buf)
            .map_err(|e| CliError::Failure(format!("cannot render the man page of {name}: {e}")))?;
        let file = format!("{name}.1");
        ringsync::output::write_file(&dir.join(&file), &buf)?;
        written.push(file);
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            walk(
                sub.clone(),
                format!("{name}-{}", sub.get_name()),
                dir,
                written,
            )?;
        }
        Ok(())
    }
    let mut root = Cli::command();
    root.build();
    walk(root, "ringsync".into(), dir, &mut written)?;
    out(&format!(
        "wrote {} man pages into {}: {}\n",
        written.len(),
        dir.display(),
        written.join(", ")
    ))
}

/// Writes `text` to standard output. A closed pipe (`ringsync plan | head`) ends the output
/// quietly instead of failing.
pub(crate) fn out(text: &str) -> Result<Outcome, CliError> {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Ok(()) => Ok(Outcome::Done),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(Outcome::Done),
        Err(e) => Err(CliError::Failure(format!(
            "cannot write to standard output: {e}"
        ))),
    }
}

/// `text` with every line cut to a readable length.
fn readable(text: &str) -> String {
    text.lines()
        .map(|l| ringsync::layers::model::scenario::clip_middle(l, ERROR_LINE_CHARS))
        .collect::<Vec<_>>()
        .join("\n")
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
                    // clap's whole message: the problem, what it suggests or accepts, the
                    // usage line and the pointer to --help.
                    eprintln!("{}", readable(e.render().to_string().trim_end()));
                    return ExitCode::from(EXIT_USAGE);
                }
            }
        }
    };
    let result = match cli.command {
        Command::Plan(args) => plan_cmd::run(&args),
        Command::Scenario(cmd) => scenario_cmd::run(&cmd),
        Command::Check(args) => scenario_cmd::check(&args),
        Command::Program(args) => program_cmd::run(&args),
        Command::Sim(args) => sim_cmd::sim(&args),
        Command::Reproduce(args) => sim_cmd::reproduce(&args),
        Command::Sweep(args) => sim_cmd::sweep(&args),
        Command::Identify(args) => sim_cmd::identify(&args),
        Command::Rt(args) => rt_cmd::rt(&args),
        Command::Node(cmd) => node_cmd::node(&cmd),
        Command::Latency(args) => latency_cmd::latency(&args),
        Command::Completions { shell } => completions(shell),
        Command::Man { out } => man_pages(&out),
    };
    match result {
        Ok(Outcome::Done) => ExitCode::SUCCESS,
        Ok(Outcome::Flagged) => ExitCode::from(EXIT_FLAGGED),
        Err(CliError::Usage(msg)) => {
            eprintln!("ringsync: error: {}", readable(&msg));
            ExitCode::from(EXIT_USAGE)
        }
        Err(CliError::Failure(e)) => {
            eprintln!("ringsync: error: {}", readable(&e));
            ExitCode::from(EXIT_FAILURE)
        }
    }
}
