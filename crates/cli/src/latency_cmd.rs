//! `ringsync latency`: what this host gives a real-time loop, without the ring.

use clap::Args;
use ringsync::Duration;
use ringsync::layers::runtime::host::HostOptions;

use crate::rt_cmd::{RealtimeArgs, duration};
use crate::{CliError, Outcome, out};

/// Options of `ringsync latency`.
#[derive(Args, Debug)]
pub struct LatencyArgs {
    /// How long to probe (e.g. 60s).
    #[arg(long, value_parser = duration, default_value = "10s")]
    duration: Duration,
    /// Cycle time.
    #[arg(long, value_parser = duration, default_value = "1ms")]
    cycle: Duration,
    /// How long after each deadline the loop stays busy reading the clock (where a ring
    /// carries its frames).
    #[arg(long, value_parser = duration, default_value = "300us")]
    busy: Duration,
    #[command(flatten)]
    realtime: RealtimeArgs,
    /// Print the figures as one JSON object instead of the text, as `plan --json` and
    /// `check --json` do (redirect it to keep it: `> latency.json`).
    #[arg(long)]
    json: bool,
}

pub(crate) fn latency(args: &LatencyArgs) -> Result<Outcome, CliError> {
    let opts = HostOptions {
        cycle: args.cycle,
        duration: args.duration,
        busy: args.busy,
        realtime: args.realtime.settings(),
        verbose: true,
    };
    // (The probe checks the cycle, --spin and --busy against each other itself.)
    args.realtime.check_cpu()?;
    let stop = ringsync::layers::runtime::stop_flag();
    let r = ringsync::rt::latency(&opts, stop)?;
    if args.json {
        let json = serde_json::to_string_pretty(&ringsync::rt::latency_json(&r, &opts))
            .map_err(|e| CliError::Failure(format!("cannot format JSON: {e}")))?;
        return out(&format!("{json}\n"));
    }
    out(&ringsync::rt::latency_text(&r, &opts))
}
