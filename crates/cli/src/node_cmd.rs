//! `ringsync node master|slave`: one node of a ring as this process.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::{CliError, Outcome};

/// Which node.
#[derive(Subcommand, Debug)]
pub enum NodeCmd {
    /// The master: its start-up phase (delay probes, each slave's path delay), then its
    /// cycles.
    Master(NodeArgs),
    /// Slave I: its start-up phase (it answers the probes and takes its path delay), then
    /// its axis.
    Slave {
        /// The slave's index on the ring, 1..=n.
        #[arg(long, value_name = "I")]
        index: usize,
        #[command(flatten)]
        args: NodeArgs,
    },
}

/// What every node process is given.
#[derive(Args, Debug)]
pub struct NodeArgs {
    /// The ring's plan (JSON: the scenario, every node's link, the shared epoch;
    /// docs/runtime.md).
    #[arg(long, value_name = "FILE")]
    plan: PathBuf,
    /// Where to write what the node saw (JSON), when it ends.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

/// Runs the node until the run's end (or SIGINT, SIGTERM, SIGHUP: it then writes what it
/// saw so far and exits with status 1).
pub fn node(cmd: &NodeCmd) -> Result<Outcome, CliError> {
    let (index, args) = match cmd {
        NodeCmd::Master(a) => (0, a),
        NodeCmd::Slave { index, args } => {
            if *index == 0 {
                return Err(CliError::Usage(
                    "--index counts slaves from 1 (the master is `ringsync node master`)".into(),
                ));
            }
            (*index, args)
        }
    };
    let stop = ringsync::layers::runtime::stop_flag();
    let rec = ringsync::rt::run_node(&args.plan, index, stop)?;
    ringsync::rt::write_node_record(&rec, &args.out)?;
    if rec.interrupted {
        return Err(CliError::Failure(
            "interrupted; what the node saw is written".into(),
        ));
    }
    Ok(Outcome::Done)
}
