//! `ringsync latency`: what this host gives a real-time loop, without the ring.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use ringsync_proto::Duration;
use ringsync_rt::host::{HostError, HostOptions, probe};
use serde_json::json;

use crate::rt_cmd::{RealtimeArgs, duration, pct};
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
    /// Also write the figures as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

pub(crate) fn latency(args: &LatencyArgs) -> Result<Outcome, CliError> {
    let opts = HostOptions {
        cycle: args.cycle,
        duration: args.duration,
        busy: args.busy,
        realtime: args.realtime.settings(),
        verbose: true,
    };
    let stop = ringsync_rt::stop_flag();
    let r = probe(&opts, stop).map_err(|e| match e {
        HostError::OutOfRange { name, value, range } => {
            CliError::Usage(format!("--{name} {value} is out of range ({range})"))
        }
    })?;
    let us = |ns: i64| ns as f64 * 1e-3;
    let share = |c: u64| 100.0 * c as f64 / r.cycles.max(1) as f64;
    if let Some(path) = &args.json {
        let v = json!({
            "cycles": r.cycles,
            "cycle_us": us(args.cycle.as_ns()),
            "busy_us": us(args.busy.as_ns()),
            "lateness_us": pct(&r.lateness),
            "stalls_us": pct(&r.stalls),
            "stall_threshold_us": us(ringsync_rt::timing::STALL),
            "cycles_stalled": r.cycles_stalled,
            "cycles_stalled_at_least_us": r.over.iter().map(|(th, c)| json!({"us": us(*th), "cycles": c})).collect::<Vec<_>>(),
            "longest_stalled_run": r.longest_stalled_run,
            "realtime": r.realtime,
            "interrupted": r.interrupted,
        });
        let text = serde_json::to_string_pretty(&v).context("cannot format JSON")?;
        crate::output::write_file(path, format!("{text}\n"))?;
    }
    let mut text = format!(
        "host latency over {} cycles of {:.0} µs{}\n  cycle-start lateness p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  stalls per cycle p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  cycles with a stall of at least:",
        r.cycles,
        us(args.cycle.as_ns()),
        if r.interrupted { " (interrupted)" } else { "" },
        us(r.lateness.p50),
        us(r.lateness.p99),
        us(r.lateness.p999),
        us(r.lateness.max),
        us(r.stalls.p50),
        us(r.stalls.p99),
        us(r.stalls.p999),
        us(r.stalls.max),
    );
    for (th, c) in &r.over {
        text += &format!(" {:.0} µs {} ({:.3} %);", us(*th), c, share(*c));
    }
    text.pop();
    text += &format!(
        "\n  longest run of cycles stalled {:.0} µs or more: {}\n",
        us(ringsync_rt::timing::STALL),
        r.longest_stalled_run
    );
    if let Some(p) = &args.json {
        text += &format!("  wrote {}\n", p.display());
    }
    out(&text)
}
