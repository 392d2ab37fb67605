//! The real-time runtime through the front door: run a scenario's motion in real time over
//! UDP on loopback or a veth ring, the simulator's prediction beside it, its results
//! written; and the host probe behind `ringsync latency`.
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! let s = ringsync::load("paper-2015")?.scenario;
//! let opts = ringsync::RtOptions { transport: ringsync::TransportKind::Udp, ..Default::default() };
//! let stop = AtomicBool::new(false); // raise it (e.g. from a signal handler) to end early
//! let r = ringsync::run_rt(&s, &opts, &stop, Vec::new())?;
//! println!("{}", ringsync::rt::rt_text(&r, None));
//! # Ok::<(), ringsync::Error>(())
//! ```

use std::path::Path;
use std::sync::atomic::AtomicBool;

use ringsync_model::Scenario;
use ringsync_model::observer::Observer;
use ringsync_report::sim::{summary_json, write_trace_csv};
use ringsync_rt::host::{HostError, HostLatency, HostOptions};
use ringsync_rt::run::ASSUMPTIONS;
use ringsync_rt::stats::Percentiles;
use ringsync_rt::{RtOptions, RtResult};
pub use ringsync_sim::SimPrediction;
use serde_json::{Value, json};

use crate::error::{Error, Result};
use crate::output::OutDir;

/// Runs `s` in real time; `stop` ends the run early when raised (its partial results come
/// back with `interrupted` set); `observers` are told every cycle and event from the
/// real-time loop (each call must be short: copy into a buffer, never block).
pub fn run_rt(
    s: &Scenario,
    opts: &RtOptions,
    stop: &AtomicBool,
    observers: Vec<Box<dyn Observer>>,
) -> Result<RtResult> {
    Ok(ringsync_rt::run_observed(s, opts, stop, observers)?)
}

/// Runs the scenario `loaded` as one process per node (`ringsync node …`, started from this
/// executable): docs/runtime.md, "One process per node". With `pcap` (inside `dir` or
/// beside it, committed with it), the frames every node sent, merged in time order once the
/// nodes are done, go there as pcapng (the result's capture is then empty, as a streamed
/// run's). `observers` watch it as it goes, from what the nodes tell
/// ([`ringsync_rt::launch::live_merge`]).
pub fn run_rt_processes(
    dir: &mut OutDir,
    loaded: &crate::Loaded,
    opts: &RtOptions,
    stop: &AtomicBool,
    pcap: Option<&Path>,
    observers: Vec<Box<dyn Observer>>,
) -> Result<RtResult> {
    use std::io::Write as _;
    let program = std::env::current_exe()
        .map_err(|e| Error::io("finding the ringsync executable to start the nodes", e))?;
    let run = move |capture| {
        ringsync_rt::launch::run_processes(
            &loaded.text,
            &loaded.origin,
            opts,
            &program,
            stop,
            capture,
            observers,
        )
    };
    let Some(p) = pcap.filter(|_| opts.capture) else {
        return Ok(run(None)?);
    };
    let shown = format!("cannot write {}", p.display());
    let staged = dir.stream_file(p)?;
    let file = std::fs::File::create(&staged).map_err(|e| Error::io(&shown, e))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 16, file);
    let axes = loaded.scenario.axes_count();
    let named = |e: std::io::Error| std::io::Error::new(e.kind(), format!("{shown}: {e}"));
    let info = ringsync_report::pcap::CaptureInfo::real_time(
        &loaded.scenario,
        loaded.hash,
        opts.transport.name(),
    );
    w.write_all(&ringsync_report::pcap::pcapng_header(axes, &info))
        .map_err(|e| Error::io(&shown, e))?;
    let mut buf = Vec::with_capacity(256);
    let mut each = |f: &ringsync_model::result::Captured| {
        buf.clear();
        ringsync_report::pcap::push_pcapng_frame(&mut buf, f, axes);
        w.write_all(&buf).map_err(named)
    };
    let beside = staged.parent().unwrap_or(Path::new("."));
    let r = run(Some(ringsync_rt::launch::Capture {
        beside,
        sink: &mut each,
    }))?;
    w.flush().map_err(|e| Error::io(&shown, e))?;
    Ok(r)
}

/// Runs node `index` (0 the master, i slave i) of the ring the plan at `plan` describes,
/// until the run's end or `stop`.
pub fn run_node(
    plan: &Path,
    index: usize,
    stop: &AtomicBool,
) -> Result<ringsync_rt::node::NodeRecord> {
    let plan = ringsync_rt::node::NodePlan::read(plan)?;
    Ok(ringsync_rt::node::run_node(&plan, index, stop)?)
}

/// Writes what a node saw (JSON), whole or not at all, as every single file ringsync
/// writes ([`crate::output::write_file`]: a symbolic link is followed, a device or FIFO is
/// written to, never replaced).
pub fn write_node_record(rec: &ringsync_rt::node::NodeRecord, path: &Path) -> Result<()> {
    let json = serde_json::to_vec(rec)
        .map_err(|e| Error::Failed(format!("cannot write the node's record: {e}")))?;
    crate::output::write_file(path, json)
}

/// The plan of a ring of node processes started by hand (docs/runtime.md, "Real
/// interfaces"): the scenario `loaded` run with `opts`, node i on `links[i]` (0 the
/// master), the run's time 0 `start_in` from now on this host's `CLOCK_MONOTONIC`. Fails
/// when `start_in` leaves the master's start-up phase too little time (it begins
/// [`ringsync_rt::launch::start_up_ns`] before time 0, and every node must be running by
/// then).
pub fn node_plan(
    loaded: &crate::Loaded,
    opts: &RtOptions,
    links: Vec<ringsync_rt::node::NodeLink>,
    start_in: crate::Duration,
) -> Result<ringsync_rt::node::NodePlan> {
    let s = ringsync_rt::run::as_run(&loaded.scenario, opts);
    if !s.faults.break_link.is_empty() {
        return Err(Error::Input(
            "faults.break_link: a ring on the host's own interfaces knows a broken link from the cards' carrier, and nothing here takes a link down on a schedule: pull the cable (or set faults.break_link = [] and run the schedule with `ringsync rt --processes --transport veth`)".into(),
        ));
    }
    let start_up = ringsync_rt::launch::start_up_ns(opts, s.ring.cycle.0.as_ns());
    // A second to start the processes, at least.
    let least = start_up + 1_000_000_000;
    if start_in.as_ns() < least {
        return Err(Error::Input(format!(
            "--start-in {:.1} s leaves no time to start the nodes: the master's start-up phase begins {:.1} s before the run, give at least {:.1} s",
            start_in.as_ns() as f64 * 1e-9,
            start_up as f64 * 1e-9,
            least as f64 * 1e-9
        )));
    }
    let epoch = ringsync_rt::launch::monotonic_now_ns()
        .checked_add(start_in.as_ns())
        .ok_or_else(|| Error::Input(format!("--start-in {start_in:?} is out of range")))?;
    let mut plan =
        ringsync_rt::launch::node_plan(&loaded.text, &loaded.origin, opts, links, epoch)?;
    // A ring on the host's interfaces knows a broken link from the cards' carrier.
    plan.sense_carrier = true;
    Ok(plan)
}

/// Writes a node plan as JSON to `path`, whole or not at all, as every single file
/// ringsync writes ([`crate::output::write_file`]: a symbolic link is followed, a device or
/// FIFO is written to, never replaced).
pub fn write_node_plan(plan: &ringsync_rt::node::NodePlan, path: &Path) -> Result<()> {
    let json = serde_json::to_vec_pretty(plan)
        .map_err(|e| Error::Failed(format!("cannot write the node plan: {e}")))?;
    crate::output::write_file(path, json)
}

/// One run's result from the records its node processes wrote (`ringsync node gather`):
/// the ring of the plan at `plan`, a record per node (any order). Also the scenario as
/// loaded from the plan.
pub fn gather_nodes(
    plan: &Path,
    records: &[std::path::PathBuf],
) -> Result<(RtResult, crate::Loaded)> {
    let plan = ringsync_rt::node::NodePlan::read(plan)?;
    let records = records
        .iter()
        .map(|p| ringsync_rt::node::read_record(p))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let r = ringsync_rt::launch::gather(&plan, &records, false, true)?;
    Ok((r, crate::parse(&plan.scenario, &plan.origin)?))
}

/// The simulator's prediction for `s`: means over `seeds` seeds from its own (one run's
/// Sync-RMSE moves by about ±10 % with the seed; a real-time run is one more draw).
///
/// ```
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(200);
/// let p = ringsync::predict(&s, 3)?;
/// assert_eq!(p.seeds, 3);
/// assert!(p.sync_rmse_range.0 <= p.sync_rmse && p.sync_rmse <= p.sync_rmse_range.1);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn predict(s: &Scenario, seeds: u64) -> Result<SimPrediction> {
    Ok(ringsync_sim::predict(s, seeds)?)
}

/// The simulator's predictions beside a real-time run: for the scenario as run, on the
/// links and schedule its plan describes, and for the ring as the run measured it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RtPrediction {
    /// The scenario as run (after the overrides) on its plan's links and schedule.
    pub planned: SimPrediction,
    /// The ring the nodes ran: their schedule, every link the measured L and every slave
    /// the median measured residence, each slave's clock that ring's own path
    /// ([`ringsync_rt::schedule::measured_ring`]), the law told the command arrivals of
    /// this simulated ring ([`ringsync_sim::predict::with_settled_arrivals`]); `None` when
    /// the simulator could not run it.
    pub measured: Option<SimPrediction>,
    /// The same ring with each simulated clock off by the mean error the run's clock had
    /// over its second half ([`with_clock_bias`]): how much of a difference between the
    /// run and `measured` the clocks' biases account for. `None` when the simulator could
    /// not run it, or no clock was off by a nanosecond.
    pub clock_biased: Option<SimPrediction>,
    /// The link L the measured ring's hops took \[ns\].
    pub link_ns: i64,
    /// The residence its slaves took \[ns\].
    pub residence_ns: i64,
}

/// Both of the simulator's predictions for the run `r` ([`RtPrediction`]), each the mean
/// over `seeds` seeds.
pub fn predict_rt(r: &RtResult, seeds: u64) -> Result<RtPrediction> {
    let planned = predict(&r.scenario, seeds)?;
    let ring = ringsync_rt::schedule::measured_ring(&r.spec, &r.calibration);
    // The law times its feed-forward for the arrivals this simulated ring gives, as the
    // runtime's law does for its own (its warm-up).
    let settled_prediction = |ring: &ringsync_model::Spec| {
        ringsync_sim::predict::with_settled_arrivals(ring)
            .and_then(|ring| ringsync_sim::predict::predict_spec(&ring, seeds))
            .ok()
    };
    let measured = settled_prediction(&ring);
    let bias = &r.run.clock_error_mean_ns;
    let clock_biased = if bias.iter().any(|b| b.abs() >= 1.0) {
        settled_prediction(&with_clock_bias(&ring, bias))
    } else {
        None
    };
    Ok(RtPrediction {
        planned,
        measured,
        clock_biased,
        link_ns: ring.plan.hop.as_ns(),
        residence_ns: ring.scenario.ring.residence.0.as_ns(),
    })
}

/// What the prediction with the run's clock biases ([`with_clock_bias`]) assumes beyond the
/// ring as measured.
pub const CLOCK_BIAS_ASSUMPTION: &str = "the ring as measured, each slave's clock off by the mean error the run's clock had over its second half (its path delay taken that much too long); the clocks' wander about that mean is not modelled";

/// `spec` with slave i's clock off by `bias_ns[i]` \[ns\] (synchronised minus true time, as
/// [`RunResult::clock_error_mean_ns`](ringsync_model::result::RunResult) has it): its path
/// delay taken that much too long, so that every sync sets its clock that far ahead.
pub fn with_clock_bias(spec: &ringsync_model::Spec, bias_ns: &[f64]) -> ringsync_model::Spec {
    let mut spec = spec.clone();
    for (c, b) in spec.slaves.iter_mut().zip(bias_ns) {
        if b.is_finite() {
            c.path_delay += ringsync_proto::Duration::from_ns(b.round() as i64);
        }
    }
    spec
}

/// Runs `s` in real time as [`run_rt`] does, writing `trace.csv` into `dir` and the frames
/// sent as pcapng to `pcap` (when given) while it runs ([`crate::stream`]): the run's memory
/// does not grow with its duration. The result's trace and captured frames are empty
/// ([`RtResult::streamed`] says what went to the files, and what they could not take);
/// [`write_rt`] then writes the rest.
#[allow(clippy::too_many_arguments)]
pub fn run_rt_streamed(
    dir: &mut OutDir,
    s: &Scenario,
    hash: u64,
    opts: &RtOptions,
    stop: &AtomicBool,
    observers: Vec<Box<dyn Observer>>,
    pcap: Option<&Path>,
) -> Result<RtResult> {
    let pcap = pcap.filter(|_| opts.capture);
    let info = ringsync_report::pcap::CaptureInfo::real_time(s, hash, opts.transport.name());
    let (streams, sinks) = crate::stream::open(dir, s.axes_count(), opts.trace, pcap, &info)?;
    let run = ringsync_rt::run_streamed(s, opts, stop, observers, sinks);
    // The run is over and its sinks are gone: the writers end.
    let written = streams.finish();
    let r = run?;
    written?;
    Ok(r)
}

/// Writes a real-time run into `dir`: `summary.json` (the simulator's fields, the timing,
/// the calibration, the prediction when given), `trace.csv`, and the frames sent as pcapng
/// to `pcap` when given; a trace or capture that went to its file as the run went
/// ([`run_rt_streamed`]) is not written again. `hash` is the scenario text's hash.
pub fn write_rt(
    dir: &mut OutDir,
    r: &RtResult,
    hash: u64,
    prediction: Option<RtPrediction>,
    pcap: Option<&Path>,
) -> Result<()> {
    let summary = rt_summary(r, hash, r.transport.name(), prediction);
    dir.write(
        "summary.json",
        format!("{}\n", serde_json::to_string_pretty(&summary)?),
    )?;
    if !r.streamed.trace {
        dir.write_with("trace.csv", |w| write_trace_csv(&r.run, w))?;
    }
    // A part program's path table, when the run kept it (not when the trace was streamed).
    if let Some(p) = &r.run.path
        && !p.trace.is_empty()
    {
        dir.write_with("path.csv", |w| ringsync_report::path::write_path_csv(p, w))?;
    }
    if let Some(p) = pcap
        && !r.streamed.capture
    {
        dir.write_file(
            p,
            ringsync_report::pcap::pcapng(
                &r.run.captured,
                r.scenario.axes_count(),
                &ringsync_report::pcap::CaptureInfo::real_time(
                    &r.scenario,
                    hash,
                    r.transport.name(),
                ),
            ),
        )?;
    }
    Ok(())
}

/// Percentiles in µs as JSON: p50, p99, p99.9, max and the count.
pub fn pct(p: &Percentiles) -> Value {
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

/// summary.json of a real-time run, as [`write_rt`] writes it: the simulator's fields plus
/// the timing (µs), the calibration and, when given, the predictions. `hash` is the
/// scenario text's hash, `transport` its name.
pub fn rt_summary(
    r: &RtResult,
    hash: u64,
    transport: &str,
    prediction: Option<RtPrediction>,
) -> Value {
    let mut v = summary_json(&r.scenario, hash, &r.run);
    let t = &r.timing;
    let c = &r.calibration;
    let mc = &r.run.master;
    let extra = json!({
        "transport": transport,
        "stamps": r.stamps.name(),
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
        "broken_dropped": t.broken_dropped,
        "receive_errors": t.receive_errors,
        "residual_clock_error_ns": {
            "max": r.run.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
            "rms": r.run.clock_error_rms_ns.clone(),
            "mean": r.run.clock_error_mean_ns.clone(),
        },
        "sim_prediction": prediction.map(|p| {
            let mut v = prediction_json(&p.planned);
            v["note"] = json!("means over the seeds: one run's Sync-RMSE moves by about ±10 % with the seed");
            v["measured_ring"] = p.measured.map_or(Value::Null, |m| {
                let mut v = prediction_json(&m);
                v["link_us"] = json!(p.link_ns as f64 * 1e-3);
                v["residence_us"] = json!(p.residence_ns as f64 * 1e-3);
                v["assumption"] = json!(ringsync_rt::schedule::MEASURED_RING_ASSUMPTION);
                v["with_the_runs_clock_bias"] = p.clock_biased.map_or(Value::Null, |b| {
                    let mut v = prediction_json(&b);
                    v["assumption"] = json!(CLOCK_BIAS_ASSUMPTION);
                    v["clock_bias_us"] = json!(
                        r.run
                            .clock_error_mean_ns
                            .iter()
                            .map(|b| b * 1e-3)
                            .collect::<Vec<_>>()
                    );
                    v
                });
                v
            });
            v
        }),
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
            "malformed_unread_at_end": r.injected.malformed_unread,
            "valid_unread_at_end": r.injected.valid_unread,
            "forged": r.injected.forged.iter().map(|(f, n)| json!({"kind": f.name(), "frames": n})).collect::<Vec<_>>(),
        },
        "links_in_run": r.links_in_run.as_ref().map(|l| json!({
            "link_us": l.link_ns.map(|v| v as f64 * 1e-3),
            "start_up_link_us": r.calibration.start_up.measured.link.as_ns() as f64 * 1e-3,
            "estimates": l.estimates,
            "path_delay_end_us": l.path_delay_end_ns.iter().map(|p| p.map(|v| v as f64 * 1e-3)).collect::<Vec<_>>(),
            "links_refused": l.refused,
        })),
        "relays": {
            "transparent": r.stamps == ringsync_rt::Stamps::Kernel,
            "lumped_frames_corrected": t.relay_corrected,
            "frames_passed_untouched": t.relay_uncorrected,
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
        "streamed": {
            "trace": r.streamed.trace,
            "capture": r.streamed.capture,
            "trace_rows_dropped": r.streamed.trace_rows_dropped,
            "frames_dropped": r.streamed.frames_dropped,
            "live_dropped": r.streamed.live_dropped,
        },
        "runtime_assumptions": ASSUMPTIONS.iter().copied().chain([r.stamps.assumption()]).collect::<Vec<_>>(),
    });
    if let (Value::Object(m), Value::Object(e)) = (&mut v, extra) {
        m.extend(e);
    }
    v
}

/// The run in a paragraph: cycles, overruns and the host's stalls, lateness, the P2P phase,
/// the metrics beside the prediction, clock error, injections, rejections, the group stop.
pub fn rt_text(r: &RtResult, prediction: Option<RtPrediction>) -> String {
    let transport = r.transport;
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
        let line = |what: &str, p: &SimPrediction| {
            format!(
                "\n  simulator{what}, mean of {} seeds: Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad ({:.7} to {:.7})",
                p.seeds, p.track_rmse, p.sync_rmse, p.sync_rmse_range.0, p.sync_rmse_range.1
            )
        };
        text += &line("", &p.planned);
        if let Some(m) = &p.measured {
            text += &line(
                &format!(
                    " on the ring as measured (links {:.1} µs, residence {:.1} µs)",
                    p.link_ns as f64 * 1e-3,
                    p.residence_ns as f64 * 1e-3
                ),
                m,
            );
        }
        if let Some(b) = &p.clock_biased {
            let us: Vec<String> = r
                .run
                .clock_error_mean_ns
                .iter()
                .map(|b| format!("{:+.2}", b * 1e-3))
                .collect();
            text += &line(
                &format!(
                    " on that ring with the run's clock biases ({} µs)",
                    us.join(", ")
                ),
                b,
            );
        }
    }
    text += &format!(
        "\n  residual clock error ≤ {:.0} ns ({} stamps{})",
        r.run.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        r.stamps.name(),
        if t.relay_corrected + t.relay_uncorrected > 0 {
            format!(
                ", transparent relays: {} lumped frames corrected, {} frames passed untouched",
                t.relay_corrected, t.relay_uncorrected
            )
        } else {
            String::new()
        }
    );
    if let Some(p) = &r.run.path {
        for l in ringsync_report::path::path_lines(p) {
            text += &format!("\n  {l}");
        }
    }
    if let Some(l) = &r.links_in_run {
        let us = |ns: Option<i64>| ns.map_or("-".into(), |v| format!("{:.3}", v as f64 * 1e-3));
        text += &format!(
            "\n  links as the run's frames measured them: {} µs a link (start-up {} µs; {} estimates); the slaves' path delays at the end {} µs; {} links refused",
            us(l.link_ns),
            us(Some(r.calibration.start_up.measured.link.as_ns())),
            l.estimates,
            l.path_delay_end_ns
                .iter()
                .map(|p| us(*p))
                .collect::<Vec<_>>()
                .join(", "),
            l.refused
        );
    }
    if r.injected.garbage > 0 {
        text += &format!(
            "\n  injected {} garbage frames; the nodes refused {} malformed frames, {} more were unread at the end",
            r.injected.garbage, r.injected.counted_malformed, r.injected.malformed_unread
        );
    }
    for (f, frames) in &r.injected.forged {
        text += &format!("\n  injected {frames} forged frames ({})", f.name());
    }
    text += &format!(
        "\n  rejected by the nodes: {}",
        ringsync_rt::run::rejected_summary(&r.run)
    );
    let st = &r.streamed;
    if st.trace_rows_dropped + st.frames_dropped > 0 {
        text += &format!(
            "\n  WARNING: the files written during the run could not keep up: {} trace rows and {} captured frames are missing from them",
            st.trace_rows_dropped, st.frames_dropped
        );
    }
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
    text.push('\n');
    if let Some(l) = ringsync_report::sim::start_up_line(&r.run) {
        text += &format!("  start-up: {l}\n");
    }
    text += &crate::simulate::monitor_text(&r.scenario, &r.run);
    text += &crate::simulate::ring_text(&r.run);
    text += &crate::simulate::saturation_text(&r.run);
    text
}

/// Probes what this host gives a real-time loop, without the ring (`ringsync latency`).
pub fn latency(opts: &HostOptions, stop: &AtomicBool) -> Result<HostLatency> {
    ringsync_rt::host::probe(opts, stop).map_err(|e| match e {
        HostError::OutOfRange { name, value, range } => {
            Error::Input(format!("--{name} {value} is out of range ({range})"))
        }
    })
}

/// The host probe's figures as JSON.
pub fn latency_json(r: &HostLatency, opts: &HostOptions) -> Value {
    let us = |ns: i64| ns as f64 * 1e-3;
    ringsync_report::provenance::stamp(latency_fields(r, opts, &us), 1)
}

fn latency_fields(r: &HostLatency, opts: &HostOptions, us: &dyn Fn(i64) -> f64) -> Value {
    json!({
        "cycles": r.cycles,
        "cycle_us": us(opts.cycle.as_ns()),
        "busy_us": us(opts.busy.as_ns()),
        "lateness_us": pct(&r.lateness),
        "stalls_us": pct(&r.stalls),
        "stall_threshold_us": us(ringsync_rt::timing::STALL),
        "cycles_stalled": r.cycles_stalled,
        "cycles_stalled_at_least_us": r.over.iter().map(|(th, c)| json!({"us": us(*th), "cycles": c})).collect::<Vec<_>>(),
        "longest_stalled_run": r.longest_stalled_run,
        "realtime": r.realtime,
        "interrupted": r.interrupted,
    })
}

/// The host probe's figures in a few lines.
pub fn latency_text(r: &HostLatency, opts: &HostOptions) -> String {
    let us = |ns: i64| ns as f64 * 1e-3;
    let share = |c: u64| 100.0 * c as f64 / r.cycles.max(1) as f64;
    let mut text = format!(
        "host latency over {} cycles of {:.0} µs{}\n  cycle-start lateness p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  stalls per cycle p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs\n  cycles with a stall of at least:",
        r.cycles,
        us(opts.cycle.as_ns()),
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
    text
}

/// One prediction's figures for summary.json.
fn prediction_json(p: &SimPrediction) -> Value {
    json!({
        "track_rmse": p.track_rmse, "sync_rmse": p.sync_rmse,
        "sync_rmse_min": p.sync_rmse_range.0, "sync_rmse_max": p.sync_rmse_range.1,
        "seeds": p.seeds,
    })
}

#[cfg(test)]
mod tests {
    /// A clock bias is a path delay taken too long by as much: the simulated clocks then
    /// run off by the bias given, with its sign, to within their timestamp resolution.
    #[test]
    fn clock_bias_sets_each_clock_off_by_it() {
        let s = ringsync_model::Scenario::from_toml("duration = \"300ms\"\n", "test")
            .expect("scenario");
        let spec = s.build().expect("spec");
        let bias = [-500.0, 0.0, 800.0, 2_000.0];
        let run = |spec: &ringsync_model::Spec| {
            let opts = ringsync_sim::RunOptions::default();
            ringsync_sim::run::simulate(spec, opts, Vec::new(), &mut |_, _| {}).expect("run")
        };
        let r = run(&super::with_clock_bias(&spec, &bias));
        for (i, (m, b)) in r.clock_error_mean_ns.iter().zip(bias).enumerate() {
            assert!(
                (m - b).abs() < 10.0,
                "slave {}: mean {m} ns for a bias of {b}",
                i + 1
            );
        }
        let plain = run(&spec);
        assert!(plain.clock_error_mean_ns.iter().all(|m| m.abs() < 10.0));
    }
}
