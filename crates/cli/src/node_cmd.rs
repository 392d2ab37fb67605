//! `ringsync node master|slave`: one node of a ring as this process; `ringsync node plan`
//! and `ringsync node gather`: the plan of a ring started by hand, and its results.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use ringsync::layers::runtime::node::NodeLink;
use ringsync::{Duration, RtOptions};

use crate::rt_cmd::duration;
use crate::sim_cmd::{key_value, out_dir};
use crate::{CliError, Outcome, out};

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
    /// Writes the plan of a ring whose node processes you start yourself, on the host's
    /// own interfaces (docs/runtime.md, "Real interfaces"): the scenario, each node's two
    /// interfaces, and the run's start on this host's clock.
    Plan(PlanArgs),
    /// Gathers what the nodes of a ring saw (their --out records) into one run's results,
    /// summary.json and trace.csv, as `ringsync rt --processes` does.
    Gather(GatherArgs),
}

/// `ringsync node plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Scenario file or built-in name.
    scenario: String,
    /// Each node's interfaces, the master's first, then slave 1's …: `RX:TX` (frames
    /// arrive on RX from the previous node and leave on TX to the next), or `NETNS/RX:TX`
    /// inside a network namespace; comma-separated, n + 1 of them.
    #[arg(long, value_name = "LIST")]
    links: String,
    /// When the run starts, from now (the master's start-up phase begins before it; every
    /// node must be started by then).
    #[arg(long, value_parser = duration, default_value = "10s")]
    start_in: Duration,
    /// Where to write the plan (JSON).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Run this long instead of the scenario's duration.
    #[arg(long, value_parser = duration)]
    duration: Option<Duration>,
    /// Cycle time instead of the scenario's.
    #[arg(long, value_parser = duration)]
    cycle: Option<Duration>,
    /// W instead of the scenario's faults.watchdog_cycles.
    #[arg(long, value_name = "W")]
    watchdog_cycles: Option<u32>,
    /// How the nodes stamp the frames they receive: kernel (the instant it reached the
    /// node's socket: on a real network card, when its driver took it in; every relay then
    /// adds the time it held a sync lumped frame to its stamp) or software (the instant a
    /// node's loop reads the frame).
    #[arg(long, value_name = "KIND", default_value = "kernel")]
    stamps: ringsync::Stamps,
    /// Set a scenario key (repeatable), as `ringsync sim --set`.
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = key_value)]
    set: Vec<(String, String)>,
}

/// `ringsync node gather`.
#[derive(Args, Debug)]
pub struct GatherArgs {
    /// The ring's plan.
    #[arg(long, value_name = "FILE")]
    plan: PathBuf,
    /// Directory for summary.json, trace.csv and scenario.toml (replaced as a whole).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Skip the simulator's predictions for the same ring.
    #[arg(long)]
    no_sim_prediction: bool,
    /// The nodes' records (each node's --out), one per node, any order.
    #[arg(required = true, value_name = "RECORD")]
    records: Vec<PathBuf>,
}

/// The links of `--links LIST`: `[NETNS/]RX:TX`, comma-separated.
fn links(list: &str) -> Result<Vec<NodeLink>, CliError> {
    list.split(',')
        .enumerate()
        .map(|(i, item)| {
            let bad = |why: &str| {
                CliError::Usage(format!(
                    "--links: item {} ({item:?}) {why}: expected RX:TX or NETNS/RX:TX",
                    i + 1
                ))
            };
            let (netns, ifs) = match item.trim().split_once('/') {
                Some((ns, ifs)) => (Some(ns.to_string()), ifs),
                None => (None, item.trim()),
            };
            let (rx, tx) = ifs.split_once(':').ok_or_else(|| bad("has no ':'"))?;
            if rx.is_empty() || tx.is_empty() || netns.as_deref() == Some("") {
                return Err(bad("has an empty name"));
            }
            Ok(NodeLink::Raw {
                netns,
                rx_if: rx.to_string(),
                tx_if: tx.to_string(),
            })
        })
        .collect()
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
        NodeCmd::Plan(p) => return plan(p),
        NodeCmd::Gather(g) => return gather(g),
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
    // An --out that cannot be written fails now, not after the run.
    ringsync::output::writable(&args.out)?;
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

/// `ringsync node plan`: checks the ring and writes its plan.
fn plan(args: &PlanArgs) -> Result<Outcome, CliError> {
    let loaded = ringsync::with_values(&ringsync::load(&args.scenario)?, &args.set)?;
    let links = links(&args.links)?;
    let n = loaded.scenario.axes_count();
    if links.len() != n + 1 {
        return Err(CliError::Usage(format!(
            "--links has {} items; the ring of {} has {} nodes (the master and {n} slaves)",
            links.len(),
            loaded.origin,
            n + 1
        )));
    }
    if args.stamps == ringsync::Stamps::Phy {
        return Err(CliError::Usage(
            "--stamps phy needs the one loop that sees the master's sends: a ring of node processes stamps software or kernel".into(),
        ));
    }
    let opts = RtOptions {
        duration: args.duration,
        cycle: args.cycle,
        watchdog_cycles: args.watchdog_cycles,
        stamps: args.stamps,
        ..RtOptions::default()
    };
    let plan = ringsync::rt::node_plan(&loaded, &opts, links, args.start_in)?;
    ringsync::rt::write_node_plan(&plan, &args.out)?;
    out(&format!(
        "wrote {}: {} nodes; the run starts in {:.1} s (the master's start-up phase {:.1} s before): start the slaves, then the master\n",
        args.out.display(),
        n + 1,
        args.start_in.as_ns() as f64 * 1e-9,
        plan.start_up_ns as f64 * 1e-9
    ))?;
    Ok(Outcome::Done)
}

/// `ringsync node gather`: one run's results from the nodes' records.
fn gather(args: &GatherArgs) -> Result<Outcome, CliError> {
    let (r, loaded) = ringsync::rt::gather_nodes(&args.plan, &args.records)?;
    let dir = out_dir(&args.out, &loaded)?;
    crate::rt_cmd::write_run(dir, &r, &loaded, !args.no_sim_prediction, None, &args.out)?;
    if r.interrupted {
        return Err(CliError::Failure(
            "a node was interrupted; its partial results are written".into(),
        ));
    }
    Ok(Outcome::flagged_if(r.run.group_stop.is_some()))
}
