//! The real-time ring: the unchanged sans-IO master and slaves of `ringsync-proto` driven
//! by the monotonic clock and real sockets, the slaves' axes simulated in real time.
//!
//! A run has four steps, each in its own module: open the transport
//! ([`TransportKind::open`]); measure the ring ([`calibrate`](crate::calibrate)); set the
//! master's schedule from the measurements ([`schedule`]); run the nodes on
//! the real-time loop ([`ring`](crate::ring)), a warm-up first, with faults injected from
//! threads of their own ([`inject`]). The timing is accounted by
//! [`timing`](crate::timing) on the [`clock`](crate::clock) that `ringsync latency` uses.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use ringsync_model::result::RunResult;
use ringsync_model::stream::{CaptureSink, TraceSink};
use ringsync_model::{Observer, Scenario};
use ringsync_proto::node::Reject;
use ringsync_proto::{Duration, PlanKind};

use crate::calibrate::{Calibration, calibrate};
use crate::inject::{self, Flap, Forgery, Injected, InjectorPlan};
use crate::netns::NetnsError;
use crate::realtime::{Applied, Realtime};
use crate::ring::{Finished, Mode, Ring, drain};
use crate::schedule::{self, Schedule};
use crate::sys;
use crate::timing::Timing;
use crate::transport::{OpenRing, Port, TransportKind};

/// Start-up phases a run measures at most when the ring they measure does not fit the cycle.
pub const START_UP_TRIES: u32 = 3;

/// Assumptions of a real-time run that the paper does not state (beyond the simulator's).
pub const ASSUMPTIONS: &[&str] = &[
    "one process and one event-loop thread serve every node's sockets; every hop is a real send and receive through the kernel",
    "slaves forward frames at once, in software",
    "path delays are measured by the nodes at start-up in place of the wire figures of the plan (delay probes round the ring: the master's round trip and each slave's residence, every link taken to have the same delay), and each slave takes its own; the P2P slices are planned from the same probes' round trips",
    "slave encoders latch at their synchronised sampling instants exactly (as hardware latches); commands take effect when the loop reads them, and the master's law times its feed-forward for the arrivals the warm-up measured",
    "slaves latch their encoders a lead before each cycle start (--sample-lead, 100 µs unless the scenario or the option sets one) where the paper latches at the cycle start: software-stamped clocks are off by tens of µs and a host stall can hold the loop past the latch, and a latch that falls after the lumped frame has passed sends last cycle's sample again; the simulator's prediction uses the same lead",
    "the axes are simulated in the runtime's process, advanced exactly between events with the command held",
    "a cycle overruns when the master loses a lumped frame or a command of it (not back, not acknowledged in its cycle)",
];

/// The runtime's default sampling lead: software-stamped clocks are off by up to a few
/// tens of µs (measured: docs/runtime.md) and a host stall can hold the loop past the
/// latch, and the latch must come before the lumped frame reaches the slave, 5-30 µs after
/// the cycle start.
pub const SAMPLE_LEAD: Duration = Duration::from_us(100);

/// A slave taken out of the ring mid-run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kill {
    /// Slave (1-based).
    pub slave: usize,
    /// When, from the run's start.
    pub at: Duration,
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RtOptions {
    /// UDP or veth.
    pub transport: TransportKind,
    /// Override of the scenario's duration.
    pub duration: Option<Duration>,
    /// Override of the scenario's cycle time.
    pub cycle: Option<Duration>,
    /// Override of the scenario's W (`faults.watchdog_cycles`): cycles without a command
    /// before a slave's safe state, without a response or feedback before the group stop.
    pub watchdog_cycles: Option<u32>,
    /// Real-time settings of the loop thread.
    pub realtime: Realtime,
    /// How long the master waits for a response beyond the measured slice.
    pub response_timeout: Duration,
    /// Calibration rounds per figure.
    pub calibration_rounds: usize,
    /// Keep the trace rows.
    pub trace: bool,
    /// Keep every frame sent (for `--pcap`).
    pub capture: bool,
    /// Take a slave out mid-run.
    pub kill: Option<Kill>,
    /// Garbage and bad-CRC frames injected onto the ring [frames/s] (0: none).
    pub garbage_rate: f64,
    /// Forged frames with a valid CRC injected onto the ring.
    pub forge: Vec<Forgery>,
    /// A link taken down for a while.
    pub flap: Option<Flap>,
    /// Sampling lead (slaves latch this long before each cycle start). `None`: the
    /// scenario's `clock.sample_lead`, or [`SAMPLE_LEAD`] when that is 0.
    pub sample_lead: Option<Duration>,
    /// How the slaves stamp the lumped frames they receive (their clocks' measurements).
    pub stamps: Stamps,
    /// Print start-up messages and a progress line a second to standard error.
    pub verbose: bool,
}

/// How the slaves stamp the lumped frames they receive, from which their clocks follow the
/// master's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stamps {
    /// Emulated PHY stamps, the scenario's hardware timestamps: the instant the loop sent
    /// the frame from the master plus the slave's path delay (the shortest the warm-up
    /// measured), as a hardware stamp reads on links of constant delay. The loop's
    /// forwarding jitter (µs, the host's) then moves the frames but not the clocks.
    #[default]
    Phy,
    /// Software stamps: the instant the loop read the frame. The clocks then follow the
    /// master to within the loop's forwarding jitter (µs to tens of µs here).
    Software,
    /// Kernel receive stamps (a ring of node processes, the default there): the instant
    /// the frame reached the node's socket (`SO_TIMESTAMPNS`), before the node's process
    /// woke to read it; and every relay transparent (it adds the time it held a sync
    /// lumped frame to its stamp). The clocks then see the links' jitter, not the nodes'
    /// wake-ups and forwarding.
    Kernel,
}

impl Stamps {
    /// Both kinds.
    pub const ALL: [Stamps; 3] = [Stamps::Phy, Stamps::Software, Stamps::Kernel];

    /// The name used on the command line and in summary.json.
    pub fn name(self) -> &'static str {
        match self {
            Stamps::Phy => "phy",
            Stamps::Software => "software",
            Stamps::Kernel => "kernel",
        }
    }

    /// These stamps as a ring of node processes takes them: no process sees another's
    /// sends, so emulated PHY stamps (the in-process default) become kernel stamps, the
    /// processes' default.
    pub fn in_processes(self) -> Stamps {
        match self {
            Stamps::Phy | Stamps::Kernel => Stamps::Kernel,
            Stamps::Software => Stamps::Software,
        }
    }

    /// What a run with these stamps assumes (summary.json's `runtime_assumptions`).
    pub fn assumption(self) -> &'static str {
        match self {
            Stamps::Phy => {
                "slaves stamp the lumped frames they receive as a PHY would on links of constant delay (--stamps phy): the instant the loop sent the frame from the master plus the slave's path delay, the shortest the warm-up measured; frames the loop did not send get the instant the loop read them"
            }
            Stamps::Software => {
                "slaves stamp the lumped frames they receive in software, at the instant the loop reads them (--stamps software): the clocks see the loop's forwarding jitter"
            }
            Stamps::Kernel => {
                "every node stamps the frames it receives with the kernel's receive time (--stamps kernel, SO_TIMESTAMPNS): the instant the frame reached its socket, before the node's process woke to read it; and every relay is transparent (as a PTP transparent clock): it adds to a sync lumped frame's stamp how long it held the frame, from that receive stamp to just before its send, and the slaves' path delays are their links alone (every link taken equal); the clocks see the links' jitter (a send call's), not the nodes' wake-ups and forwarding"
            }
        }
    }
}

impl std::str::FromStr for Stamps {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Stamps::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown stamps '{s}': use phy, software or kernel"))
    }
}

impl Default for RtOptions {
    fn default() -> Self {
        RtOptions {
            transport: TransportKind::Udp,
            duration: None,
            cycle: None,
            watchdog_cycles: None,
            realtime: Realtime::default(),
            response_timeout: Duration::from_us(200),
            calibration_rounds: 200,
            trace: true,
            capture: false,
            kill: None,
            garbage_rate: 0.0,
            forge: Vec::new(),
            flap: None,
            sample_lead: None,
            stamps: Stamps::Phy,
            verbose: false,
        }
    }
}

/// What a real-time run produced.
#[derive(Debug, Clone)]
pub struct RtResult {
    /// The scenario as run (with the overrides).
    pub scenario: Scenario,
    /// The nodes' configuration as they ran: the scenario's, with the schedule, path
    /// delays and command timing of the measured ring
    /// ([`schedule::measured_ring`] makes a simulator's ring of it).
    pub spec: ringsync_model::Spec,
    /// The transport the frames travelled on.
    pub transport: TransportKind,
    /// How the slaves stamped the lumped frames.
    pub stamps: Stamps,
    /// The same result a simulation gives: metrics, counters, trace, faults.
    pub run: RunResult,
    /// Timing statistics.
    pub timing: Timing,
    /// The start-up measurements and the schedule derived from them.
    pub calibration: Calibration,
    /// The master's schedule on the measured ring.
    pub schedule: Schedule,
    /// Real-time settings applied, and warnings for those that were not.
    pub realtime: Vec<String>,
    /// Frames injected onto the ring, per kind.
    pub injected: Injection,
    /// Per node (index 0 the master, i slave i): frames read from its port, and when it
    /// last read one \[s\]: the nodes' "last seen" counters.
    pub nodes_rx: Vec<(u64, Option<f64>)>,
    /// The run was interrupted (Ctrl-C) before its end.
    pub interrupted: bool,
    /// The slave taken out, and when \[s\].
    pub killed: Option<(usize, f64)>,
    /// Cycles the master started from the slave's removal to the group stop.
    pub detection_cycles: Option<i64>,
    /// What went to streaming sinks ([`Sinks`]) instead of this result.
    pub streamed: Streamed,
    /// Behind transparent relays (a ring of node processes with kernel stamps): the links
    /// as the run's own frames measured them, and the path delays the slaves followed.
    pub links_in_run: Option<LinksInRun>,
}

/// Behind transparent relays: the master's running estimate of one link (the median of
/// every 64 round trips of its sync lumped frames over the n + 1 links), sent with its
/// commands, and what the slaves made of it (`ringsync_proto::node::link`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinksInRun {
    /// The master's last estimate of one link \[ns\]; `None` if it made none.
    pub link_ns: Option<i64>,
    /// Estimates the master made.
    pub estimates: u64,
    /// Each slave's path delay when the run ended \[ns\] (`None`: no record).
    pub path_delay_end_ns: Vec<Option<i64>>,
    /// Links in commands the slaves refused, all slaves together.
    pub refused: u64,
}

/// What a run streamed to its [`Sinks`] instead of keeping it in its result.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Streamed {
    /// The trace rows went to a sink (the result's trace is empty).
    pub trace: bool,
    /// The captured frames went to a sink (the result's are empty).
    pub capture: bool,
    /// Trace rows the sink could not take.
    pub trace_rows_dropped: u64,
    /// Captured frames the sink could not take.
    pub frames_dropped: u64,
    /// Messages of a ring of node processes' live view that the nodes' queues dropped
    /// (`--scope`: a node's writer fell behind).
    pub live_dropped: u64,
}

/// Frames injected onto the ring.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Injection {
    /// Garbage and bad-CRC frames.
    pub garbage: u64,
    /// Forged frames with a valid CRC, per kind.
    pub forged: Vec<(Forgery, u64)>,
    /// Frames the nodes refused as malformed (the garbage among them).
    pub counted_malformed: u64,
    /// Malformed frames still waiting on the nodes' ports when the run ended, read after
    /// the injector stopped and handed to no node.
    pub malformed_unread: u64,
    /// Well-formed frames still waiting on the nodes' ports when the run ended (forged
    /// ones among them), likewise.
    pub valid_unread: u64,
}

/// Frames the nodes of `run` refused as malformed (injected garbage among them).
pub(crate) fn malformed_counted(run: &ringsync_model::result::RunResult) -> u64 {
    run.master.rejected.get(Reject::Malformed)
        + run
            .slaves
            .iter()
            .map(|c| c.rejected.get(Reject::Malformed))
            .sum::<u64>()
}

/// What can stop a real-time run from starting.
#[derive(Debug, thiserror::Error)]
pub enum RtError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ringsync_model::ScenarioError),
    /// The namespaces or links could not be created.
    #[error(transparent)]
    Netns(#[from] NetnsError),
    /// A socket failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The error.
        source: io::Error,
    },
    /// The measured ring does not fit the cycle, or an option is out of range.
    #[error("{0}")]
    Config(String),
    /// A node process failed, or its start-up phase did (one process per node).
    #[error("{0}")]
    Node(String),
}

pub(crate) fn io_err(context: &str) -> impl FnOnce(io::Error) -> RtError + '_ {
    move |source| RtError::Io {
        context: context.to_string(),
        source,
    }
}

/// Runs `scenario` in real time. `stop` ends the run early when raised (Ctrl-C).
pub fn run(scenario: &Scenario, opts: &RtOptions, stop: &AtomicBool) -> Result<RtResult, RtError> {
    run_observed(scenario, opts, stop, Vec::new())
}

/// The scenario as the runtime runs it: with the options' overrides, and a sampling lead.
pub fn as_run(scenario: &Scenario, opts: &RtOptions) -> Scenario {
    let mut s = scenario.clone();
    if let Some(c) = opts.cycle {
        s.ring.cycle.0 = c;
    }
    if let Some(d) = opts.duration {
        s.duration.0 = d;
    }
    if let Some(w) = opts.watchdog_cycles {
        s.faults.watchdog_cycles = w;
    }
    s.clock.sample_lead.0 = match opts.sample_lead {
        Some(l) => l,
        None if s.clock.sample_lead.0 == Duration::ZERO => SAMPLE_LEAD,
        None => s.clock.sample_lead.0,
    };
    s
}

/// Where a run streams its trace rows and the frames it captures instead of keeping them in
/// its result (each used only when the run keeps the trace, or captures): then a run takes
/// the same memory whatever its duration.
#[derive(Debug, Default)]
pub struct Sinks {
    /// The trace rows, each cycle's once complete.
    pub trace: Option<Box<dyn TraceSink>>,
    /// The frames sent, as they are sent.
    pub capture: Option<Box<dyn CaptureSink>>,
}

/// [`run`], with `observers` told every cycle, law run, applied command and fault step as
/// the run goes. They are called from the real-time loop: each call must be short (copy
/// into a preallocated buffer or a channel; never block or print).
pub fn run_observed(
    scenario: &Scenario,
    opts: &RtOptions,
    stop: &AtomicBool,
    observers: Vec<Box<dyn Observer>>,
) -> Result<RtResult, RtError> {
    run_streamed(scenario, opts, stop, observers, Sinks::default())
}

/// [`run_observed`], streaming the trace and the capture to `sinks` (the result's trace
/// and captured frames are then empty; [`Streamed::trace_rows_dropped`] and [`Streamed::frames_dropped`] count what the sinks could
/// not take).
pub fn run_streamed(
    scenario: &Scenario,
    opts: &RtOptions,
    stop: &AtomicBool,
    observers: Vec<Box<dyn Observer>>,
    sinks: Sinks,
) -> Result<RtResult, RtError> {
    if opts.stamps == Stamps::Kernel {
        return Err(RtError::Config(
            "stamps 'kernel' are for a ring of node processes (--processes): one loop reading every node's socket would stamp its own sends; use phy or software".into(),
        ));
    }
    let mut spec = as_run(scenario, opts).build()?;
    let n = spec.axes();
    if let Some(k) = opts.kill
        && (k.slave == 0 || k.slave > n)
    {
        return Err(RtError::Config(format!(
            "--kill-slave {} is not a slave of this ring (1..={n})",
            k.slave
        )));
    }
    if spec.scenario.ring.plan == PlanKind::LumpedOnly
        && n > ringsync_wire::lumped::slot_capacity(
            <ringsync_wire::LumpedOnlySlot as ringsync_wire::SlotCodec>::LEN,
        )
    {
        return Err(RtError::Config(
            "the lumped-only plan runs with one frame here".into(),
        ));
    }
    let say = |m: &str| {
        if opts.verbose {
            eprintln!("ringsync rt: {m}");
        }
    };
    if opts.transport == TransportKind::Veth {
        say(&format!(
            "creating {} network namespaces and veth links",
            n + 1
        ));
    }
    let OpenRing { mut ports, veth } = opts.transport.open(n + 1)?;
    // Real time, before calibrating so that the measurements see the same scheduling.
    // The CPU claim (`_cpu`) holds the loop's CPU against other runs until the run ends.
    let Applied {
        lines: mut realtime,
        cpu: _cpu,
    } = opts.realtime.apply();
    realtime.push(format!(
        "encoders latch {:.0} µs before each cycle start",
        spec.scenario.clock.sample_lead.0.as_ns() as f64 * 1e-3
    ));
    for r in &realtime {
        say(r);
    }
    // The start-up phase, measured again (at most twice) when the ring it measured does
    // not fit the cycle: a host that held the loop off its CPU in short bursts during the
    // probes (each too short to count as a stall) makes the round trips' p99 a host figure.
    let mut tries = 1;
    let (cal, sched) = loop {
        let cal = calibrate(&mut ports, &spec, opts.calibration_rounds.max(1))
            .map_err(io_err("the nodes' start-up phase"))?;
        let mut measured = spec.clone();
        match schedule::apply(&mut measured, &cal, opts.response_timeout) {
            Ok(sched) => {
                spec = measured;
                break (cal, sched);
            }
            Err(e) if tries < START_UP_TRIES => {
                say(&format!(
                    "start-up phase {tries} of {START_UP_TRIES}: {e}; measuring again"
                ));
                tries += 1;
                let mut ports_opt: Vec<Option<Box<dyn Port>>> =
                    std::mem::take(&mut ports).into_iter().map(Some).collect();
                let _ = drain(&mut ports_opt);
                ports = ports_opt.into_iter().flatten().collect();
            }
            Err(e) => return Err(e),
        }
    };
    say(&format!(
        "start-up phase: {} probes ({} not counted after a host stall): round trip p50 {:.1} µs, p99 {:.1} µs; one link {:.1} µs; path delays taken by the slaves {} µs",
        cal.rounds,
        cal.repeated,
        cal.round_trip.p50 as f64 * 1e-3,
        cal.round_trip.p99 as f64 * 1e-3,
        cal.start_up.measured.link.as_ns() as f64 * 1e-3,
        cal.path
            .iter()
            .map(|d| format!("{:.1}", *d as f64 * 1e-3))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    // Warm-up: the real nodes on the real loop for a few hundred cycles, to measure when
    // each axis's commands take effect (the slaves keep the path delays they took).
    let t_cyc = spec.scenario.ring.cycle.0.as_ns();
    let warm = (300_000_000 / t_cyc).max(100);
    let ports = ports.into_iter().map(Some).collect();
    let mut ring = Ring::new(
        &spec,
        ports,
        warm,
        Mode::WarmUp,
        Vec::new(),
        Sinks::default(),
    )?;
    ring.run_loop(opts, stop, None, &None, &mut None)?;
    // The law times its feed-forward for each command's arrival: the arrivals the running
    // loop gave, not the calibration's estimate (a few µs apart per axis, and at an error of
    // one encoder count that decides the synchronisation error).
    if spec.master.plan == PlanKind::P2pLumped {
        for (a, d) in spec
            .master
            .command_arrival
            .iter_mut()
            .zip(ring.measured_command_arrivals())
        {
            if let Some(d) = d {
                *a = Duration::from_ns(d);
            }
        }
    }
    let (_, mut ports) = ring.finish(&spec.scenario.name);
    // Frames of the warm-up still in the kernel's queues arrive within microseconds: let
    // them, then read them all away, so that the run's fresh nodes never see one.
    sys::sleep_until(sys::now_ns() + 2_000_000);
    let _ = drain(&mut ports);
    say(&format!("warm-up of {warm} cycles"));
    let s = &spec.scenario;
    let cycles = s.duration.0.as_ns() / t_cyc;
    let mode = Mode::Run {
        trace: opts.trace,
        capture: opts.capture,
        stamps: opts.stamps,
    };
    let mut ring = Ring::new(&spec, ports, cycles, mode, observers, sinks)?;
    let (trace_streamed, capture_streamed) = ring.streaming();
    // Fault injection: its own threads and sockets, like a faulty device on the ring.
    let injected = Arc::new(Injected::default());
    let stop_inject = Arc::new(AtomicBool::new(false));
    let injector = if opts.garbage_rate > 0.0 || !opts.forge.is_empty() {
        let udp: Vec<std::net::SocketAddr> = ring
            .ports
            .iter()
            .flatten()
            .filter_map(|p| p.udp_addr())
            .collect();
        let senders =
            inject::senders(&veth, &udp).map_err(io_err("opening the injector's sockets"))?;
        Some(inject::spawn(
            senders,
            InjectorPlan {
                garbage_rate: opts.garbage_rate,
                forgeries: opts.forge.clone(),
                slaves: n,
                t_cyc,
                seed: s.seed,
                t0: ring.t0_shared.clone(),
                run_for: None,
            },
            injected.clone(),
            stop_inject.clone(),
        ))
    } else {
        None
    };
    if let Some(f) = opts.flap {
        say(&inject::flap_line(&f, n, veth.is_some()));
    }
    let breakers: Vec<_> = match &veth {
        Some(v) => s
            .faults
            .break_link
            .iter()
            .map(|b| {
                inject::spawn_break(v.clone(), *b, ring.t0_shared.clone(), stop_inject.clone())
            })
            .collect(),
        None => Vec::new(),
    };
    for b in &s.faults.break_link {
        say(&format!(
            "{}{}",
            inject::break_line(b),
            if veth.is_some() {
                ""
            } else {
                " (UDP: the nodes beside it stop sending on it)"
            }
        ));
    }
    let flapper = match (opts.flap, &veth) {
        (Some(f), Some(v)) => Some(inject::spawn_flap(
            v.clone(),
            f,
            ring.t0_shared.clone(),
            stop_inject.clone(),
        )),
        _ => None,
    };
    say(&format!(
        "running {} for {:.1} s: {cycles} cycles of {:.1} µs, {n} slaves over {}",
        s.name,
        s.duration.0.as_ns() as f64 * 1e-9,
        t_cyc as f64 * 1e-3,
        opts.transport.name()
    ));
    let mut killer: Option<JoinHandle<()>> = None;
    let (interrupted, killed) = ring.run_loop(opts, stop, opts.kill, &veth, &mut killer)?;
    stop_inject.store(true, Ordering::SeqCst);
    if let Some(h) = injector {
        let _ = h.join();
    }
    let flap_down_ns = crate::inject::flap_down_ns(flapper);
    for h in breakers {
        if let Ok(Err(why)) = h.join() {
            eprintln!("ringsync rt: warning: a link break did not happen: {why}");
        }
    }
    if let Some(h) = killer {
        let _ = h.join();
    }
    let (
        Finished {
            mut run,
            mut timing,
            nodes_rx,
            detection_cycles,
            dropped,
        },
        mut ports,
    ) = ring.finish(&s.name);
    // What the injector sent that the nodes never read (a host stall at the end holds the
    // loop while the injector catches up): the injector has stopped; what it sent last
    // arrives within microseconds (as after the warm-up), so this is all of it.
    sys::sleep_until(sys::now_ns() + 2_000_000);
    let (malformed_unread, valid_unread) = drain(&mut ports);
    // Close every socket before the namespaces go (a socket keeps its namespace alive).
    drop(ports);
    drop(veth);
    timing.flap_down_ns = flap_down_ns;
    run.start_up = Some(cal.start_up.clone());
    let counted = malformed_counted(&run);
    Ok(RtResult {
        links_in_run: None,
        scenario: spec.scenario.clone(),
        spec,
        transport: opts.transport,
        stamps: opts.stamps,
        run,
        timing,
        calibration: cal,
        schedule: sched,
        realtime,
        injected: Injection {
            garbage: injected.garbage.load(Ordering::SeqCst),
            forged: opts
                .forge
                .iter()
                .map(|f| (*f, injected.forged(*f)))
                .collect(),
            counted_malformed: counted,
            malformed_unread,
            valid_unread,
        },
        nodes_rx,
        interrupted,
        killed,
        detection_cycles,
        streamed: Streamed {
            trace: trace_streamed,
            capture: capture_streamed,
            trace_rows_dropped: dropped.0,
            frames_dropped: dropped.1,
            live_dropped: 0,
        },
    })
}

/// The frames every node refused so far: the total and its non-zero reasons, e.g.
/// `3012 (wrong_cycle 3000, future_timestamp 12)`.
pub fn rejected_line(
    master: &ringsync_proto::node::Master,
    slaves: &[ringsync_proto::node::Slave],
) -> String {
    let all = slaves.iter().fold(master.counters().rejected, |a, s| {
        a.plus(&s.counters().rejected)
    });
    rejections_text(&all)
}

/// [`rejected_line`] from a finished run's counters.
pub fn rejected_summary(r: &RunResult) -> String {
    let all = r
        .slaves
        .iter()
        .fold(r.master.rejected, |a, c| a.plus(&c.rejected));
    rejections_text(&all)
}

fn rejections_text(all: &ringsync_proto::node::Rejections) -> String {
    let reasons: Vec<String> = all
        .iter()
        .filter(|(_, n)| *n > 0)
        .map(|(r, n)| format!("{} {n}", r.name()))
        .collect();
    if reasons.is_empty() {
        "0".into()
    } else {
        format!("{} ({})", all.total(), reasons.join(", "))
    }
}
