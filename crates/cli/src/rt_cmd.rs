//! `ringsync rt`: the scenario's motion in real time over UDP or a veth ring.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::{Args, ValueEnum};
use ringsync_model::scenario::Scenario;
use ringsync_proto::Duration;
use ringsync_report::sim::{summary_json, trace_csv};
use ringsync_rt::run::ASSUMPTIONS;
use ringsync_rt::stats::Percentiles;
use ringsync_rt::{
    Flap, Forgery, Kill, Pin, Realtime, RtError, RtOptions, RtResult, TransportKind,
};
use ringsync_sim::SimPrediction;
use serde_json::{Value, json};

use crate::scenario_cmd::usage;
use crate::sim_cmd::out_dir;
use crate::{CliError, Outcome, out};

/// Which transport carries the frames.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Transport {
    /// UDP datagrams on 127.0.0.1, one socket per node (no privileges needed).
    Udp,
    /// Raw Ethernet frames on a ring of veth pairs, one network namespace per node (root).
    Veth,
}

pub(crate) fn duration(s: &str) -> Result<Duration, String> {
    let d: Duration = s.parse().map_err(|e| format!("{e}"))?;
    if d.as_ns() < 0 {
        return Err(format!("{s} is negative"));
    }
    Ok(d)
}

/// Options of `ringsync rt`.
#[derive(Args, Debug)]
pub struct RtArgs {
    /// Scenario file or built-in name (see `ringsync scenario list`).
    scenario: String,
    /// How the frames travel.
    #[arg(long, value_enum)]
    transport: Transport,
    /// Directory for summary.json and trace.csv; checked before the run, replaced as a whole
    /// when it ends (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Run this long instead of the scenario's duration (e.g. 60s).
    #[arg(long, value_parser = duration)]
    duration: Option<Duration>,
    /// Cycle time instead of the scenario's (e.g. 500us), to find the fastest one this
    /// machine holds.
    #[arg(long, value_parser = duration)]
    cycle: Option<Duration>,
    /// W instead of the scenario's faults.watchdog_cycles: cycles without a command before
    /// a slave goes to 0 V, without a response or feedback before the master stops the
    /// group. On a virtual machine the host can freeze the loop for several ms (see
    /// `ringsync latency`); W must be longer, or such a freeze ends the run in a group stop.
    #[arg(long, value_name = "W")]
    watchdog_cycles: Option<u32>,
    /// Also write every frame the nodes send, with its send time, as pcapng.
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
    #[command(flatten)]
    realtime: RealtimeArgs,
    /// How long the master waits for a response beyond the measured time slice.
    #[arg(long, value_parser = duration, default_value = "200us")]
    response_timeout: Duration,
    /// Take this slave (1-based) out of the ring mid-run: its sockets close and, on veth,
    /// its links go down.
    #[arg(long, requires = "kill_at")]
    kill_slave: Option<usize>,
    /// When to take the slave out, from the start (e.g. 1s).
    #[arg(long, value_parser = duration, requires = "kill_slave")]
    kill_at: Option<Duration>,
    /// Inject garbage and bad-CRC frames onto the ring at this rate [frames/s].
    #[arg(long, default_value_t = 0.0)]
    inject_garbage: f64,
    /// Inject forged frames with a valid CRC (repeatable): wrong-cycle-commands (commands
    /// 2-1000 cycles off at ±10 V, 1000/s), future-lumped (lumped frames stamped 1 s ahead,
    /// 100/s), sync-burst (30 lumped frames with a wrong cycle and a far timestamp, 1/s).
    #[arg(long, value_name = "KIND")]
    forge: Vec<Forgery>,
    /// Take a link down for a while: A-B, the link from node A to the next node B (m is the
    /// master), e.g. 2-3, m-1, 4-m. veth: both ends go down with `ip`; UDP: the runtime
    /// drops what the link would carry.
    #[arg(long, value_name = "A-B", requires_all = ["flap_at", "flap_for"])]
    flap_link: Option<String>,
    /// When the link goes down, from the start (e.g. 1s).
    #[arg(long, value_parser = duration, requires = "flap_link")]
    flap_at: Option<Duration>,
    /// How long the link stays down (e.g. 8ms).
    #[arg(long, value_parser = duration, requires = "flap_link")]
    flap_for: Option<Duration>,
    /// Slaves latch their encoders this long before each cycle start (default: the
    /// scenario's clock.sample_lead, or 100us when that is 0). Software clocks are off by
    /// tens of µs; a latch after the lumped frame has passed sends last cycle's sample.
    #[arg(long, value_parser = duration)]
    sample_lead: Option<Duration>,
    /// Skip the simulator's prediction for the same scenario.
    #[arg(long)]
    no_sim_prediction: bool,
}

/// The real-time options shared by `ringsync rt` and `ringsync latency`.
#[derive(Args, Debug)]
pub struct RealtimeArgs {
    /// Busy-wait this long before each deadline.
    #[arg(long, value_parser = duration, default_value = "150us")]
    spin: Duration,
    /// SCHED_FIFO priority of the loop (1-99); 0 keeps the normal scheduler.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(0..=99))]
    priority: i32,
    /// CPU to pin the loop to (default: the last one no other ringsync run has claimed;
    /// one another run holds is not shared: the loop then runs unpinned, with a warning).
    #[arg(long)]
    cpu: Option<usize>,
    /// Do not pin the loop to a CPU.
    #[arg(long, conflicts_with = "cpu")]
    no_pin: bool,
    /// Do not lock memory (mlockall).
    #[arg(long)]
    no_mlock: bool,
}

impl RealtimeArgs {
    /// The settings these options ask for.
    pub fn settings(&self) -> Realtime {
        Realtime {
            spin: self.spin,
            priority: self.priority,
            cpu: match (self.no_pin, self.cpu) {
                (true, _) => Pin::Off,
                (false, Some(c)) => Pin::Cpu(c),
                (false, None) => Pin::Auto,
            },
            lock_memory: !self.no_mlock,
        }
    }
}

fn rt_error(e: RtError) -> CliError {
    match e {
        RtError::Scenario(e) => usage(e),
        RtError::Config(m) => CliError::Usage(m),
        other => CliError::Failure(anyhow::Error::new(other)),
    }
}

pub(crate) fn pct(p: &Percentiles) -> Value {
    json!({
        "p50": p.p50 as f64 * 1e-3, "p99": p.p99 as f64 * 1e-3,
        "p999": p.p999 as f64 * 1e-3, "max": p.max as f64 * 1e-3, "count": p.count,
    })
}

/// The nodes' own "last seen" counters: frames each read, when it last read one, and the
/// last cycle whose lumped frame it took.
fn nodes_json(r: &RtResult) -> Value {
    r.nodes_rx
        .iter()
        .enumerate()
        .map(|(i, (frames, last))| {
            json!({
                "node": if i == 0 { "master".to_string() } else { format!("slave {i}") },
                "frames_read": frames,
                "last_frame_s": last,
            })
        })
        .collect()
}

/// summary.json of a real-time run: the simulator's fields plus the timing.
fn rt_summary(
    r: &RtResult,
    hash: u64,
    transport: &str,
    prediction: Option<SimPrediction>,
) -> Value {
    let mut v = summary_json(&r.scenario, hash, &r.run);
    let t = &r.timing;
    let c = &r.calibration;
    let mc = &r.run.master;
    let extra = json!({
        "transport": transport,
        "cycles_planned": t.cycles_planned,
        "overruns": t.overruns,
        "stalls_us": pct(&t.stalls),
        "stall_threshold_us": ringsync_rt::timing::STALL as f64 * 1e-3,
        "cycles_stalled": t.cycles_stalled,
        "overruns_stalled": t.overruns_stalled,
        "longest_outage_cycles": t.longest_outage,
        "lateness_us": pct(&t.lateness),
        "p2p_phase_us": pct(&t.p2p),
        "late_or_lost_responses": mc.slices_failed,
        "retries": mc.retries,
        "retries_ok": mc.retries_ok,
        "commands_lost": t.commands_lost,
        "lumped_lost": t.lumped_lost,
        "late_timers": t.late_timers,
        "probes_late": t.probes_late,
        "latches_late": t.latches_late,
        "send_errors": t.send_errors,
        "receive_errors": t.receive_errors,
        "residual_clock_error_ns": {
            "max": r.run.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
            "rms": r.run.clock_error_rms_ns.clone(),
        },
        "sim_prediction": prediction.map(|p| json!({
            "track_rmse": p.track_rmse, "sync_rmse": p.sync_rmse,
            "sync_rmse_min": p.sync_rmse_range.0, "sync_rmse_max": p.sync_rmse_range.1,
            "seeds": p.seeds,
            "note": "means over the seeds: one run's Sync-RMSE moves by about ±10 % with the seed",
        })),
        "calibration": {
            "rounds": c.rounds,
            "rounds_repeated_after_host_stalls": c.repeated,
            "path_delay_us": c.path.iter().map(|d| *d as f64 * 1e-3).collect::<Vec<_>>(),
            "round_trip_us": pct(&c.round_trip),
            "slice_us": c.slice.iter().map(pct).collect::<Vec<_>>(),
            "p2p_start_us": r.schedule.p2p_start as f64 * 1e-3,
            "slice_used_us": r.schedule.slice as f64 * 1e-3,
            "response_timeout_us": r.schedule.response_timeout as f64 * 1e-3,
        },
        "realtime": r.realtime,
        "killed": r.killed.map(|(s, t)| json!({"slave": s, "at_s": t, "detected_after_cycles": r.detection_cycles})),
        "nodes": nodes_json(r),
        "injected": {
            "garbage": r.injected.garbage,
            "garbage_counted_malformed": r.injected.counted_malformed,
            "forged": r.injected.forged.iter().map(|(f, n)| json!({"kind": f.name(), "frames": n})).collect::<Vec<_>>(),
        },
        "flap": {
            "dropped_by_runtime_udp": t.flap_dropped,
            "link_down_ms": t.flap_down_ns.map(|d| d as f64 * 1e-6),
        },
        "commands": {
            "max_sent_v": r.run.command_max.0,
            "max_applied_v": r.run.command_max.1,
        },
        "interrupted": r.interrupted,
        "runtime_assumptions": ASSUMPTIONS,
    });
    if let (Value::Object(m), Value::Object(e)) = (&mut v, extra) {
        m.extend(e);
    }
    v
}

/// Runs `ringsync rt`: exit status 3 when the run ends in a group stop, 1 when it is
/// interrupted (its partial results written all the same).
pub(crate) fn rt(args: &RtArgs) -> Result<Outcome, CliError> {
    let (s, hash): (Scenario, u64) = Scenario::load_with_hash(&args.scenario).map_err(usage)?;
    if !(args.inject_garbage >= 0.0 && args.inject_garbage <= 100_000.0) {
        return Err(CliError::Usage(format!(
            "--inject-garbage {} is out of range (0 to 100000 frames/s)",
            args.inject_garbage
        )));
    }
    let n = s.axes_count();
    let flap = match (&args.flap_link, args.flap_at, args.flap_for) {
        (Some(link), Some(at), Some(down_for)) => Some(Flap {
            from: Flap::parse_link(link, n)
                .map_err(|e| CliError::Usage(format!("--flap-link {link}: {e}")))?,
            at,
            down_for,
        }),
        _ => None,
    };
    // Before the ring runs: an --out that cannot be written fails now, not after the run.
    let mut dir = out_dir(&args.out, &args.scenario)?;
    let transport = match args.transport {
        Transport::Udp => TransportKind::Udp,
        Transport::Veth => TransportKind::Veth,
    };
    let opts = RtOptions {
        transport,
        duration: args.duration,
        cycle: args.cycle,
        watchdog_cycles: args.watchdog_cycles,
        realtime: args.realtime.settings(),
        response_timeout: args.response_timeout,
        capture: args.pcap.is_some(),
        kill: args
            .kill_slave
            .zip(args.kill_at)
            .map(|(slave, at)| Kill { slave, at }),
        garbage_rate: args.inject_garbage,
        forge: args.forge.clone(),
        flap,
        sample_lead: args.sample_lead,
        verbose: true,
        ..RtOptions::default()
    };
    let stop = ringsync_rt::stop_flag();
    let r = ringsync_rt::run(&s, &opts, stop).map_err(rt_error)?;
    // The simulator's prediction for the scenario as run (after the overrides).
    let prediction = if args.no_sim_prediction {
        None
    } else {
        Some(
            ringsync_sim::predict(&r.scenario, 8)
                .map_err(|e| CliError::Failure(anyhow::Error::new(e)))?,
        )
    };
    let summary = rt_summary(&r, hash, transport.name(), prediction);
    let text = serde_json::to_string_pretty(&summary).context("cannot format JSON")?;
    dir.write("summary.json", format!("{text}\n"))?;
    dir.write("trace.csv", trace_csv(&r.run))?;
    if let Some(p) = &args.pcap {
        dir.write_file(
            p,
            ringsync_report::pcap::pcapng(&r.run.captured, r.scenario.axes_count()),
        )?;
    }
    dir.commit()?;
    let t = &r.timing;
    let m = &r.run.summary;
    let mut text = format!(
        "{} over {}: {} cycles{}, {} overruns ({:.3} %), {} of them in the {} cycles in which the host held the loop off its CPU for {:.0} µs or more; longest outage {} cycles\n  loop stalls per cycle p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  cycle-start lateness p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  P2P phase p50 {:.1} µs, p99 {:.1} µs; late or lost responses {}, retries {}, stale samples {}\n  Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad",
        r.scenario.name,
        transport.name(),
        t.cycles,
        if r.interrupted { " (interrupted)" } else { "" },
        t.overruns,
        100.0 * t.overruns as f64 / t.cycles.max(1) as f64,
        t.overruns_stalled,
        t.cycles_stalled,
        ringsync_rt::timing::STALL as f64 * 1e-3,
        t.longest_outage,
        t.stalls.p50 as f64 * 1e-3,
        t.stalls.p99 as f64 * 1e-3,
        t.stalls.p999 as f64 * 1e-3,
        t.stalls.max as f64 * 1e-3,
        t.lateness.p50 as f64 * 1e-3,
        t.lateness.p99 as f64 * 1e-3,
        t.lateness.p999 as f64 * 1e-3,
        t.lateness.max as f64 * 1e-3,
        t.p2p.p50 as f64 * 1e-3,
        t.p2p.p99 as f64 * 1e-3,
        r.run.master.slices_failed,
        r.run.master.retries,
        r.run.master.samples_stale,
        m.track_rmse,
        m.sync_rmse,
    );
    if let Some(p) = prediction {
        text += &format!(
            "\n  simulator, mean of {} seeds: Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad ({:.7} to {:.7})",
            p.seeds, p.track_rmse, p.sync_rmse, p.sync_rmse_range.0, p.sync_rmse_range.1
        );
    }
    text += &format!(
        "\n  residual clock error ≤ {:.0} ns",
        r.run.clock_error_max_ns.iter().copied().fold(0.0, f64::max)
    );
    if r.injected.garbage > 0 {
        text += &format!(
            "\n  injected {} garbage frames; the nodes refused {} malformed frames",
            r.injected.garbage, r.injected.counted_malformed
        );
    }
    for (f, frames) in &r.injected.forged {
        text += &format!("\n  injected {frames} forged frames ({})", f.name());
    }
    text += &format!(
        "\n  rejected by the nodes: {}",
        ringsync_rt::run::rejected_summary(&r.run)
    );
    if let Some((t_stop, reason)) = r.run.group_stop {
        text += &format!(
            "\n  GROUP STOP at {t_stop:.3} s{}: {} on axis {}; failed: {}",
            r.detection_cycles.map_or(String::new(), |c| format!(
                ", {c} cycles after the slave was taken out"
            )),
            reason.name(),
            reason.axis() + 1,
            r.run
                .ring_break
                .map_or("not located".to_string(), |b| b.describe())
        );
    }
    text += &format!(
        "\n  wrote {}/summary.json and trace.csv\n",
        args.out.display()
    );
    out(&text)?;
    if r.interrupted {
        return Err(CliError::Failure(anyhow::anyhow!(
            "interrupted; partial results written, namespaces and links removed"
        )));
    }
    Ok(Outcome::flagged_if(r.run.group_stop.is_some()))
}
