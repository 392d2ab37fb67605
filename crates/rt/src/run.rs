//! The real-time ring: the unchanged sans-IO master and slaves of `ringsync-proto` driven
//! by the monotonic clock and real sockets, the slaves' axes simulated in real time.
//!
//! Process layout: one process, one event loop thread serving every node's sockets. Each
//! hop is a real send and a real receive through the kernel (a UDP datagram on loopback, or
//! an Ethernet frame over a veth pair between two namespaces), but no hop needs a thread to
//! be woken on another CPU: on a 2-CPU virtual machine a cross-CPU wake-up costs about
//! 40-50 µs, and a cycle has 5 + 4·5 hops with 4 slaves (DEPENDENCIES.md).
//!
//! Per iteration the loop reads every frame waiting on any node's socket (a slave forwards
//! at once, in software, where the paper's FPGA forwards after a fixed residence), then runs
//! the earliest due timer: a cycle-start probe of the true axis states, the master's
//! timeout, a slave's encoder latch, a slave's pending response. Between timers it sleeps
//! (clock_nanosleep to an absolute deadline, or ppoll on the sockets while the master awaits
//! frames) until `spin` before the next deadline, then spins.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::thread::JoinHandle;

use ringsync_model::Scenario;
use ringsync_model::nodes::{Oscillator, RingConfig, ServoAxis, locate_break_of};
use ringsync_model::record::{AxisProbe, Recorder};
use ringsync_model::result::{Captured, LinkCounters, RunResult};
use ringsync_proto::node::{
    ClockFilter, FrameOutcome, MasterCounters, MasterEvent, Reject, SlaveEvent,
};
use ringsync_proto::{Duration, Instant, PlanKind};
use ringsync_wire::{FrameKind, Status};

use crate::calibrate::{Calibration, calibrate};
use crate::inject::{self, Flap, Forgery, Injected, InjectorPlan};
use crate::netns::{NetnsError, VethRing};
use crate::realtime::{Applied, Realtime};
use crate::stats::Percentiles;
use crate::sys;
use crate::transport::{MAX_PDU, Port, TransportKind, VethPort, udp_ring};

/// Assumptions of a real-time run that the paper does not state (beyond the simulator's).
pub const ASSUMPTIONS: &[&str] = &[
    "one process and one event-loop thread serve every node's sockets; every hop is a real send and receive through the kernel",
    "frames are timestamped in software when the loop reads them (no hardware timestamps); slaves forward at once, in software",
    "path delays and time slices are measured at start-up (median of the calibration rounds) in place of the wire figures of the plan",
    "slave encoders latch at their synchronised sampling instants exactly (as hardware latches); commands take effect when the loop reads them",
    "slaves latch their encoders a lead before each cycle start (--sample-lead, 100 µs unless the scenario or the option sets one) where the paper latches at the cycle start: software-synchronised clocks are off by tens of µs, and a latch that falls after the lumped frame has passed sends last cycle's sample again; the simulator's prediction uses the same lead",
    "the axes are simulated in the runtime's process, advanced exactly between events with the command held",
    "a cycle overruns when the master loses a lumped frame or a command of it (not back, not acknowledged in its cycle)",
];

/// The runtime's default sampling lead: the slaves' software-synchronised clocks are off
/// by up to a few tens of µs (measured: docs/runtime.md), and the latch must come before
/// the lumped frame reaches the slave, 5-30 µs after the cycle start.
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
    /// Print start-up messages and a progress line a second to standard error.
    pub verbose: bool,
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
            verbose: false,
        }
    }
}

/// The ring's timing over the run.
#[derive(Debug, Clone, Default)]
pub struct Timing {
    /// Cycles the master started (fewer than planned when the run was interrupted).
    pub cycles: i64,
    /// Cycles planned: the duration over the cycle time.
    pub cycles_planned: i64,
    /// Cycles that did not finish in time (lumped frame or a command lost).
    pub overruns: u64,
    /// Cycles whose lumped frame was lost or late.
    pub lumped_lost: u64,
    /// Commands not acknowledged within their cycle.
    pub commands_lost: u64,
    /// Lateness of the cycle start (the lumped frame's send) behind k·T_cyc.
    pub lateness: Percentiles,
    /// P2P phase: from the law's run to the last response of the cycle.
    pub p2p: Percentiles,
    /// Timer deadlines run later than 1 ms.
    pub late_timers: u64,
    /// Sends that failed (a node gone, a link down).
    pub send_errors: u64,
    /// Receives that failed (a link went down); the port is read again [`RX_RETRY`] later.
    pub receive_errors: u64,
    /// Frames the runtime dropped on the link of a `--flap` over UDP while it was down
    /// (UDP has no link to take down: the loop drops what the link would carry).
    pub flap_dropped: u64,
    /// How long the flapped link was really down [ns] (the `ip` calls take milliseconds).
    pub flap_down_ns: Option<i64>,
    /// Cycle starts whose true axis states were read after the axis had moved on.
    pub probes_late: u64,
    /// Encoder latches taken after their axis had moved past their instant (0 by design:
    /// latches are taken before any frame moves the axis on).
    pub latches_late: u64,
    /// The longest stall of each cycle [ns]: the longest gap between two of the loop's
    /// clock readings beyond what it asked of a sleep, or the cycle's late start. The loop
    /// reads the clock at every frame and timer, so a gap of [`STALL`] or more is the host
    /// holding it off its CPU.
    pub stalls: Percentiles,
    /// Cycles with a stall of [`STALL`] or more.
    pub cycles_stalled: u64,
    /// Overruns in cycles with a stall of [`STALL`] or more.
    pub overruns_stalled: u64,
    /// The longest run of consecutive overruns [cycles]: the longest the axes went without
    /// fresh feedback or a command (the master stops the group at W).
    pub longest_outage: u64,
}

/// Busy-wait before a deadline that is not the master's [ns] (see [`Realtime::spin`] for
/// the master's): a spin before every latch and probe kept the loop on its CPU most of
/// each cycle, and a loop that never sleeps starves the CPU's other tasks until the kernel
/// takes the CPU away from it for tens of ms (measured: docs/runtime.md).
const SPIN_OTHER: i64 = 20_000;

/// A stall this long or longer is the host holding the loop off its CPU (a pass of the
/// loop takes a few µs; measured in docs/runtime.md).
pub const STALL: i64 = 50_000;

/// After a receive error (a link went down) a port is read again this much later [ns]: a
/// link flap costs the cycles it lasts, not the run.
pub const RX_RETRY: i64 = 1_000_000;

/// How far from a node's clock a received timestamp may be in the runtime, ahead or behind
/// (software timestamps: the slaves' clocks are good to tens of µs, measured in
/// docs/runtime.md; a frame read later than this after a host stall is refused as stale).
pub const RT_TIMESTAMP_TOLERANCE: Duration = Duration::from_us(200);

/// What a real-time run produced.
#[derive(Debug, Clone)]
pub struct RtResult {
    /// The scenario as run (with the overrides).
    pub scenario: Scenario,
    /// The same result a simulation gives: metrics, counters, trace, faults.
    pub run: RunResult,
    /// Timing statistics.
    pub timing: Timing,
    /// The start-up measurements and the schedule derived from them.
    pub calibration: Calibration,
    /// P2P start, slice and response deadline used by the master [ns].
    pub schedule: (i64, i64, i64),
    /// Real-time settings applied, and warnings for those that were not.
    pub realtime: Vec<String>,
    /// Frames injected onto the ring, per kind.
    pub injected: Injection,
    /// Per node (index 0 the master, i slave i): frames read from its port, and when it
    /// last read one [s]: the nodes' "last seen" counters.
    pub nodes_rx: Vec<(u64, Option<f64>)>,
    /// The largest |command| the master sent to each axis, and the largest a slave applied
    /// [V]: a slave applies only what the master sent.
    pub command_max: (Vec<f64>, Vec<f64>),
    /// The run was interrupted (Ctrl-C) before its end.
    pub interrupted: bool,
    /// The slave taken out, and when [s].
    pub killed: Option<(usize, f64)>,
    /// Cycles the master started from the slave's removal to the group stop.
    pub detection_cycles: Option<i64>,
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
}

fn io_err(context: &str) -> impl FnOnce(io::Error) -> RtError + '_ {
    move |source| RtError::Io {
        context: context.to_string(),
        source,
    }
}

/// Runs `scenario` in real time. `stop` ends the run early when raised (Ctrl-C).
pub fn run(scenario: &Scenario, opts: &RtOptions, stop: &AtomicBool) -> Result<RtResult, RtError> {
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
    s.validate()?;
    let n = s.axes_count();
    if let Some(k) = opts.kill
        && (k.slave == 0 || k.slave > n)
    {
        return Err(RtError::Config(format!(
            "--kill-slave {} is not a slave of this ring (1..={n})",
            k.slave
        )));
    }
    if s.ring.plan == PlanKind::LumpedOnly
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
    // Transport.
    let veth = match opts.transport {
        TransportKind::Veth => {
            say(&format!(
                "creating {} network namespaces and veth links",
                n + 1
            ));
            Some(Arc::new(VethRing::create(n + 1)?))
        }
        TransportKind::Udp => None,
    };
    let mut ports: Vec<Box<dyn Port>> = match &veth {
        Some(ring) => (0..=n)
            .map(|i| VethPort::open(ring, i).map(|p| Box::new(p) as Box<dyn Port>))
            .collect::<io::Result<_>>()
            .map_err(io_err("opening raw sockets in the namespaces"))?,
        None => udp_ring(n + 1)
            .map_err(io_err("opening UDP sockets on 127.0.0.1"))?
            .into_iter()
            .map(|p| Box::new(p) as Box<dyn Port>)
            .collect(),
    };
    // Real time, before calibrating so that the measurements see the same scheduling.
    // The CPU claim (`_cpu`) holds the loop's CPU against other runs until the run ends.
    let Applied {
        lines: mut realtime,
        cpu: _cpu,
    } = opts.realtime.apply();
    realtime.push(format!(
        "encoders latch {:.0} µs before each cycle start",
        s.clock.sample_lead.0.as_ns() as f64 * 1e-3
    ));
    for r in &realtime {
        say(r);
    }
    let cal = calibrate(&mut ports, opts.calibration_rounds.max(1))
        .map_err(io_err("calibrating the ring"))?;
    say(&format!(
        "ring calibrated over {} rounds ({} measured again after a host stall): lumped round trip p50 {:.1} µs, p99 {:.1} µs; slice to slave {n} p99 {:.1} µs",
        cal.rounds,
        cal.repeated,
        cal.round_trip.p50 as f64 * 1e-3,
        cal.round_trip.p99 as f64 * 1e-3,
        cal.slice[n - 1].p99 as f64 * 1e-3
    ));
    // The schedule from the measurements.
    let mut rc = RingConfig::new(&s)?;
    let t_cyc = s.ring.cycle.0.as_ns();
    let t_ti = s.ring.response_delay.0.as_ns();
    let slice = cal.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti;
    let p2p_start = (2 * cal.round_trip.p99 + 20_000).max(rc.master.p2p_start.as_ns());
    let timeout = opts.response_timeout.as_ns();
    let turnaround = rc.master.turnaround.as_ns();
    if rc.master.plan == PlanKind::P2pLumped {
        // Each slice ends when its response is back; only a slice whose response is lost
        // runs to its deadline (slice + timeout), and the master opens no slice that would
        // end after the cycle.
        let need = p2p_start + n as i64 * slice + timeout;
        if need > t_cyc {
            return Err(RtError::Config(format!(
                "the measured ring needs {:.1} µs per cycle (P2P start {:.1} µs + {n} slices of {:.1} µs + a response timeout of {:.1} µs); the cycle is {:.1} µs: use a longer --cycle or a shorter --response-timeout",
                need as f64 * 1e-3,
                p2p_start as f64 * 1e-3,
                slice as f64 * 1e-3,
                timeout as f64 * 1e-3,
                t_cyc as f64 * 1e-3
            )));
        }
        rc.master.p2p_start = Duration::from_ns(p2p_start);
        rc.master.slice = Duration::from_ns(slice);
        rc.master.guard = Duration::from_ns(timeout);
        let mut at = p2p_start;
        for i in 0..n {
            rc.master.command_arrival[i] = Duration::from_ns(at + cal.command[i]);
            at += cal.slice[i].p50 + t_ti + turnaround;
        }
    } else {
        for i in 0..n {
            rc.master.command_arrival[i] =
                Duration::from_ns(cal.path[i] + rc.plan.lumped_only.lumped.frame_time[0].as_ns());
        }
    }
    // The clock window: software timestamps, and what free-running clocks drift apart
    // when the scenario turns clock sync off (as the simulator allows for it).
    let tolerance = RT_TIMESTAMP_TOLERANCE.max(ringsync_model::nodes::timestamp_tolerance(&s));
    for i in 0..n {
        rc.slaves[i].path_delay = Duration::from_ns(cal.path[i]);
        rc.slaves[i].clock_window = tolerance;
        if rc.master.plan == PlanKind::P2pLumped {
            rc.slaves[i].p2p_start = rc.master.p2p_start;
        }
    }
    rc.master.timestamp_tolerance = tolerance;
    // Warm-up: the real nodes on the real loop for a few hundred cycles, to measure each
    // slave's path delay as the running loop sees it (the calibration's frames skip the
    // nodes' processing and the loop's timers).
    let warm = (300_000_000 / t_cyc).max(100);
    let ports = ports.into_iter().map(Some).collect();
    let mut ring = Ring::new(&s, &rc, ports, warm, false, false, true)?;
    ring.run_loop(&s, opts, stop, None, &None, &mut None)?;
    if let Some(d) = &ring.delays {
        for (i, v) in d.iter().enumerate() {
            if !v.is_empty() {
                rc.slaves[i].path_delay = Duration::from_ns(Percentiles::of(v).p50);
            }
        }
    }
    let mut ports = std::mem::take(&mut ring.ports);
    drop(ring);
    // Frames of the warm-up still in the kernel's queues arrive within microseconds: let
    // them, then read them all away, so that the run's fresh nodes never see one.
    sys::sleep_until(sys::now_ns() + 2_000_000);
    drain(&mut ports);
    say(&format!(
        "warm-up of {warm} cycles: path delays {} µs",
        rc.slaves
            .iter()
            .map(|c| format!("{:.1}", c.path_delay.as_ns() as f64 * 1e-3))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let cycles = s.duration.0.as_ns() / t_cyc;
    let mut ring = Ring::new(&s, &rc, ports, cycles, opts.trace, opts.capture, false)?;
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
            },
            injected.clone(),
            stop_inject.clone(),
        ))
    } else {
        None
    };
    if let Some(f) = opts.flap {
        say(&format!(
            "link {} goes down at {:.3} s for {:.1} ms{}",
            f.name(n),
            f.at.as_ns() as f64 * 1e-9,
            f.down_for.as_ns() as f64 * 1e-6,
            if veth.is_some() {
                ""
            } else {
                " (UDP: the runtime drops what it would carry)"
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
    let (interrupted, killed) = ring.run_loop(&s, opts, stop, opts.kill, &veth, &mut killer)?;
    stop_inject.store(true, Ordering::SeqCst);
    if let Some(h) = injector {
        let _ = h.join();
    }
    if let Some(h) = flapper {
        ring.timing.flap_down_ns = h.join().ok().flatten();
    }
    if let Some(h) = killer {
        let _ = h.join();
    }
    // Close every socket before the namespaces go (a socket keeps its namespace alive).
    let Ring {
        master,
        slaves,
        rec,
        ports,
        timing,
        lateness,
        p2p,
        stalls,
        last_rx,
        rx_frames,
        sent_max,
        applied_max,
        cycles_started,
        captured,
        kill_cycle,
        stop_cycle,
        ..
    } = ring;
    drop(ports);
    drop(veth);
    let mut timing = timing;
    timing.lateness = Percentiles::of(&lateness);
    timing.p2p = Percentiles::of(&p2p);
    timing.stalls = Percentiles::of(&stalls);
    let mc: MasterCounters = master.counters();
    timing.lumped_lost = mc.lumped_lost;
    timing.commands_lost = mc.commands_lost;
    let sc: Vec<_> = slaves.iter().map(|s| s.counters()).collect();
    let counted = mc.rejected.get(Reject::Malformed)
        + sc.iter()
            .map(|c| c.rejected.get(Reject::Malformed))
            .sum::<u64>();
    timing.cycles = cycles_started;
    let mut run = rec.finish(
        &s.name,
        mc,
        sc,
        LinkCounters::default(),
        Vec::new(),
        captured,
    );
    run.cycles = cycles_started;
    Ok(RtResult {
        scenario: s,
        run,
        timing,
        calibration: cal,
        schedule: (p2p_start, slice, timeout),
        realtime,
        injected: Injection {
            garbage: injected.garbage.load(Ordering::SeqCst),
            forged: opts
                .forge
                .iter()
                .map(|f| (*f, injected.forged(*f)))
                .collect(),
            counted_malformed: counted,
        },
        nodes_rx: rx_frames.into_iter().zip(last_rx).collect(),
        command_max: (sent_max, applied_max),
        interrupted,
        killed,
        detection_cycles: kill_cycle.zip(stop_cycle).map(|(k, s)| s - k),
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

/// The running ring.
struct Ring {
    master: ringsync_proto::node::Master,
    slaves: Vec<ringsync_proto::node::Slave>,
    osc: Vec<Oscillator>,
    axes: Vec<ServoAxis>,
    alive: Vec<bool>,
    /// Per port: read again from this time on after a receive error [ns, true time].
    rx_paused: Vec<Option<i64>>,
    /// The set of ports to wait on changed.
    fds_dirty: bool,
    ports: Vec<Option<Box<dyn Port>>>,
    rec: Recorder,
    /// Slave transmissions waiting for their time: (true ns, slave 0-based, bytes).
    pending: Vec<(i64, usize, Vec<u8>)>,
    sample_due: Vec<i64>,
    /// Last frame read per node [s], and frames read per node.
    last_rx: Vec<Option<f64>>,
    rx_frames: Vec<u64>,
    /// Largest |command| the master sent, and a slave applied, per axis [V].
    sent_max: Vec<f64>,
    applied_max: Vec<f64>,
    /// A link flap over UDP: frames sent on it in [from, to) [ns] are dropped.
    flap: Option<(usize, i64, i64)>,
    /// CLOCK_MONOTONIC at true time 0, for the injector's threads [ns].
    t0_shared: Arc<AtomicI64>,
    captured: Vec<Captured>,
    capture: bool,
    /// CLOCK_MONOTONIC at true time 0 [ns].
    t0: i64,
    /// End of the run [ns, true time].
    end: i64,
    timing: Timing,
    lateness: Vec<i64>,
    p2p: Vec<i64>,
    stalls: Vec<i64>,
    /// The loop's last clock reading and the longest stall since the cycle began [ns].
    last_read: i64,
    stall: i64,
    computed_at: Option<i64>,
    last_master_rx: i64,
    /// With `Some`, the delay from the master's send to each slave's read of every lumped
    /// frame [ns] (the warm-up's measurement).
    delays: Option<Vec<Vec<i64>>>,
    /// Cycles started so far; at the removal of a slave; at the group stop.
    cycles_started: i64,
    kill_cycle: Option<i64>,
    stop_cycle: Option<i64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Due {
    Probe,
    Sample(usize),
    Pending(usize),
}

/// Reads and discards whatever is waiting on the ports.
fn drain(ports: &mut [Option<Box<dyn Port>>]) {
    let mut buf = vec![0u8; MAX_PDU];
    for p in ports.iter_mut().flatten() {
        while let Ok(Some(_)) = p.recv(&mut buf) {}
    }
}

/// The slave clock servo for software timestamps: see [`ASSUMPTIONS`].
const RT_CLOCK_FILTER: ClockFilter = ClockFilter {
    offset_gain: 0.25,
    rate_gain: 0.25,
    outlier_limit: Some(Duration::from_us(50)),
    max_skips: 20,
    rate_interval: Duration::from_ms(100),
    max_rate_error: ringsync_proto::node::clock::MAX_RATE_ERROR,
};

impl Ring {
    fn new(
        s: &Scenario,
        rc: &RingConfig,
        ports: Vec<Option<Box<dyn Port>>>,
        cycles: i64,
        trace: bool,
        capture: bool,
        measure: bool,
    ) -> Result<Ring, RtError> {
        let n = s.axes_count();
        let (master, mut slaves) = rc.build(s)?;
        for sl in &mut slaves {
            sl.clock_mut().set_filter(RT_CLOCK_FILTER);
        }
        Ok(Ring {
            master,
            slaves,
            osc: Oscillator::for_scenario(s),
            axes: ServoAxis::for_scenario(s)?,
            alive: vec![true; n + 1],
            rx_paused: vec![None; n + 1],
            fds_dirty: false,
            ports,
            rec: Recorder::new(n, cycles, s.ring.cycle.secs(), trace),
            pending: Vec::new(),
            sample_due: vec![0; n],
            last_rx: vec![None; n + 1],
            rx_frames: vec![0; n + 1],
            sent_max: vec![0.0; n],
            applied_max: vec![0.0; n],
            flap: None,
            t0_shared: Arc::new(AtomicI64::new(0)),
            // Every send: the lumped frame's n + 1 hops and each slice's n + 1 (command and
            // response), so that capturing never reallocates mid-run.
            captured: Vec::with_capacity(if capture {
                usize::try_from(cycles.max(0)).unwrap_or(0) * (n + 1) * (n + 2)
            } else {
                0
            }),
            capture,
            t0: 0,
            end: cycles * s.ring.cycle.0.as_ns(),
            timing: Timing {
                cycles_planned: cycles,
                ..Timing::default()
            },
            lateness: Vec::with_capacity(cycles.max(0) as usize),
            p2p: Vec::with_capacity(cycles.max(0) as usize),
            stalls: Vec::with_capacity(cycles.max(0) as usize),
            last_read: 0,
            stall: 0,
            computed_at: None,
            last_master_rx: 0,
            delays: measure.then(|| vec![Vec::new(); n]),
            cycles_started: 0,
            kill_cycle: None,
            stop_cycle: None,
        })
    }

    /// The loop's clock [ns from the run's start]. Each reading also measures the stall
    /// since the last one: the loop reads the clock at least once per frame and timer, so a
    /// gap between two readings longer than a send, a receive and their processing (a few
    /// µs) is time the loop was held off its CPU.
    fn now(&mut self) -> i64 {
        let t = sys::now_ns() - self.t0;
        self.stall = self.stall.max(t - self.last_read);
        self.last_read = t;
        t
    }

    /// Back from a sleep or a wait planned to end at `planned` [ns]: only a late return
    /// counts as a stall.
    fn woke(&mut self, planned: i64) -> i64 {
        let t = sys::now_ns() - self.t0;
        self.stall = self.stall.max(t - planned);
        self.last_read = t;
        t
    }

    fn send(&mut self, node: usize, t: i64, bytes: &[u8]) {
        if self.capture {
            self.captured.push(Captured {
                t,
                node,
                bytes: bytes.to_vec(),
            });
        }
        if let Some((link, from, to)) = self.flap
            && link == node
            && (from..to).contains(&t)
        {
            self.timing.flap_dropped += 1;
            return;
        }
        if let Some(p) = self.ports[node].as_mut()
            && self.alive[node]
            && p.send(bytes).is_err()
        {
            self.timing.send_errors += 1;
        }
    }

    fn drain_master(&mut self, now: i64) {
        while let Some(tx) = self.master.poll_transmit() {
            self.send(0, now, &tx.bytes);
            self.master.recycle(tx.bytes);
        }
        while let Some(ev) = self.master.poll_event() {
            match ev {
                MasterEvent::Computed { .. } => {
                    self.computed_at = Some(now);
                    for (m, u) in self.sent_max.iter_mut().zip(&self.master.record().u) {
                        *m = m.max(u.abs());
                    }
                }
                MasterEvent::GroupStop { .. } => {
                    self.stop_cycle.get_or_insert(self.cycles_started);
                    // Where the ring broke, from what each node last took.
                    self.rec
                        .ring_break(locate_break_of(&self.master, &self.slaves));
                }
                MasterEvent::Order { .. } => {}
            }
            self.rec.master_event(ev, self.master.record());
        }
    }

    fn drain_slave(&mut self, i: usize, now: i64) {
        while let Some(ev) = self.slaves[i].poll_event() {
            if let SlaveEvent::Apply { u } = ev {
                self.applied_max[i] = self.applied_max[i].max(u.abs());
            }
            let safe = self.slaves[i].config().safe_state;
            self.axes[i].take(ev, i, now, safe, &mut self.rec);
        }
        while let Some(tx) = self.slaves[i].poll_transmit() {
            let at = self.osc[i].true_at(tx.at);
            self.pending.push((at, i, tx.bytes));
        }
        self.sample_due[i] = self.osc[i].true_at(self.slaves[i].poll_timeout());
    }

    fn on_frame(&mut self, node: usize, now: i64, bytes: &mut [u8]) {
        self.last_rx[node] = Some(now as f64 * 1e-9);
        self.rx_frames[node] += 1;

        if node == 0 {
            self.last_master_rx = now;
            self.master.handle_frame(Instant::from_ns(now), bytes);
            self.drain_master(now);
            return;
        }
        let i = node - 1;
        if let Some(d) = self.delays.as_mut()
            && bytes.len() >= 20
            && (bytes[1] == FrameKind::Lumped as u8 || bytes[1] == FrameKind::LumpedOnly as u8)
        {
            // The master's send time is the payload's first field.
            let sent = u64::from_le_bytes(bytes[12..20].try_into().unwrap_or([0; 8])) as i64;
            d[i].push(now - sent);
        }
        self.latch_due(i, now);
        let local = self.osc[i].local(now);
        if self.slaves[i].handle_frame(local, local, bytes) == FrameOutcome::Forward {
            self.send(node, now, bytes);
        }
        self.drain_slave(i, now);
    }

    /// Takes slave i's encoder latches due by `t`, each at its own instant with the axis
    /// state of that instant, however late the loop gets to them (as a hardware latch). Runs
    /// before anything that advances the axis past them: a frame read at `t` whose command
    /// moved the axis on first would make the latch read a later position (at a 500 µs cycle
    /// the velocity window's opening latch fell inside axis 4's time slice, and its velocity
    /// read up to 25 % high).
    fn latch_due(&mut self, i: usize, t: i64) {
        while self.alive[i + 1] && self.sample_due[i] <= t {
            let at = self.sample_due[i];
            // (The first cycle's latches fall before the run's start, when the axis is at
            // rest where it starts.)
            if self.axes[i].t > at.max(0) {
                self.timing.latches_late += 1;
            }
            self.axes[i].advance(at);
            let counts = self.axes[i].counts();
            let local = self.osc[i].local(at);
            self.slaves[i].handle_sample(local, counts);
            self.sample_due[i] = self.osc[i].true_at(self.slaves[i].poll_timeout());
        }
    }

    /// The earliest timer other than the master's and its true time [ns].
    fn next_local(&self, probe_at: i64) -> (i64, Due) {
        let mut best = (probe_at, Due::Probe);
        for (i, &t) in self.sample_due.iter().enumerate() {
            if self.alive[i + 1] && t < best.0 {
                best = (t, Due::Sample(i));
            }
        }
        for (j, p) in self.pending.iter().enumerate() {
            if p.0 < best.0 {
                best = (p.0, Due::Pending(j));
            }
        }
        best
    }

    /// Runs a timer other than the master's.
    fn run_local(&mut self, due: Due, due_at: i64, now: i64, probe_k: &mut i64) {
        match due {
            Due::Probe => {
                self.probe(*probe_k, due_at);
                *probe_k += 1;
            }
            Due::Sample(i) => {
                self.latch_due(i, due_at);
                self.drain_slave(i, now);
            }
            Due::Pending(j) => {
                let (_, i, bytes) = self.pending.swap_remove(j);
                if self.alive[i + 1] {
                    self.send(i + 1, now, &bytes);
                }
                self.slaves[i].recycle(bytes);
            }
        }
    }

    /// Reads every frame waiting on any node's port; a frame forwarded in this pass is read
    /// at the next node in the same pass. Whether any was read.
    fn receive_all(&mut self, buf: &mut [u8]) -> bool {
        let mut got = false;
        for node in 0..self.ports.len() {
            if let Some(until) = self.rx_paused[node] {
                if self.last_read < until {
                    continue;
                }
                self.rx_paused[node] = None;
                self.fds_dirty = true;
            }
            while let Some(p) = self.ports[node].as_mut() {
                let len = match p.recv(buf) {
                    Ok(Some(len)) => len,
                    Ok(None) => break,
                    Err(_) => {
                        // A link gone down: the socket reports an error (and would keep the
                        // poll awake). Read it again a little later: a flap shorter than W
                        // cycles costs those cycles, not the run.
                        self.timing.receive_errors += 1;
                        self.rx_paused[node] = Some(self.last_read + RX_RETRY);
                        self.fds_dirty = true;
                        break;
                    }
                };
                got = true;
                let now = self.now();
                self.on_frame(node, now, &mut buf[..len]);
            }
        }
        got
    }

    fn take_out(&mut self, k: Kill, veth: &Option<Arc<VethRing>>) -> JoinHandle<()> {
        self.alive[k.slave] = false;
        // Closing a raw socket waits for an RCU grace period in the kernel (milliseconds):
        // the helper thread closes it, not the loop.
        let port = self.ports[k.slave].take();
        let v = veth.clone();
        std::thread::spawn(move || {
            sys::set_normal();
            drop(port);
            if let Some(v) = v {
                let _ = v.take_down(k.slave);
            }
        })
    }

    /// Runs the ring until its end or `stop`: (interrupted, the slave taken out and when).
    fn run_loop(
        &mut self,
        s: &Scenario,
        opts: &RtOptions,
        stop: &AtomicBool,
        kill: Option<Kill>,
        veth: &Option<Arc<VethRing>>,
        killer: &mut Option<JoinHandle<()>>,
    ) -> Result<(bool, Option<(usize, f64)>), RtError> {
        let n = self.slaves.len();
        let t_cyc = s.ring.cycle.0.as_ns();
        let spin = opts.realtime.spin.as_ns();
        let end = self.end;
        let mut buf = vec![0u8; MAX_PDU];
        let fds_of =
            |ports: &[Option<Box<dyn Port>>], paused: &[Option<i64>]| -> Vec<libc::pollfd> {
                ports
                    .iter()
                    .zip(paused)
                    .filter(|(_, p)| p.is_none())
                    .filter_map(|(p, _)| p.as_ref().map(|p| sys::pollfd(p.rx_fd())))
                    .collect()
            };
        let mut fds = fds_of(&self.ports, &self.rx_paused);
        for i in 0..n {
            self.sample_due[i] = self.osc[i].true_at(self.slaves[i].poll_timeout());
        }
        let (mut probe_k, mut cycle_k, mut last_losses) = (0i64, 0i64, 0u64);
        let mut outage = 0u64;
        let mut kill = kill;
        let mut killed = None;
        let mut next_progress = 1_000_000_000;
        // Start 2 ms from now, so that the first cycle starts on time.
        self.t0 = sys::now_ns() + 2_000_000;
        self.t0_shared.store(self.t0, Ordering::SeqCst);
        self.flap = opts
            .flap
            .filter(|_| veth.is_none())
            .map(|f| (f.from, f.at.as_ns(), f.at.as_ns() + f.down_for.as_ns()));
        self.last_read = -2_000_000;
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok((true, killed));
            }
            let mut now = self.now();
            if now >= end {
                return Ok((false, killed));
            }
            if let Some(k) = kill
                && now >= k.at.as_ns()
            {
                kill = None;
                *killer = Some(self.take_out(k, veth));
                fds = fds_of(&self.ports, &self.rx_paused);
                killed = Some((k.slave, now as f64 * 1e-9));
                self.kill_cycle = Some(cycle_k);
                if opts.verbose {
                    eprintln!(
                        "ringsync rt: slave {} taken out at {:.3} s",
                        k.slave,
                        now as f64 * 1e-9
                    );
                }
            }
            // 1. Latches, probes and responses that are due: they happen at their instants
            //    in the devices, before any frame the loop has yet to read.
            loop {
                let (at, due) = self.next_local(probe_k * t_cyc);
                if at > now || at >= end {
                    break;
                }
                if now - at > 1_000_000 {
                    self.timing.late_timers += 1;
                }
                self.run_local(due, at, now, &mut probe_k);
                now = self.now();
            }
            // 2. Every frame waiting anywhere.
            let got = self.receive_all(&mut buf);
            if std::mem::take(&mut self.fds_dirty) {
                fds = fds_of(&self.ports, &self.rx_paused);
            }
            // 3. The master, once per pass, so that a late master never runs its next step
            //    before the frames of its last one have gone round.
            let m = self.master.poll_timeout().as_ns();
            now = self.now();
            if m <= now && m < end {
                if now - m > 1_000_000 {
                    self.timing.late_timers += 1;
                }
                if m == cycle_k * t_cyc {
                    // A cycle starts: its lateness; the last cycle's losses and P2P phase.
                    self.lateness.push(now - m);
                    let c = self.master.counters();
                    let losses = c.lumped_lost + c.commands_lost;
                    // A stall up to this cycle's start counts for the cycle that ends.
                    let stall = std::mem::take(&mut self.stall);
                    if cycle_k > 0 {
                        self.stalls.push(stall);
                        if stall >= STALL {
                            self.timing.cycles_stalled += 1;
                        }
                    }
                    if losses > last_losses {
                        self.timing.overruns += 1;
                        if stall >= STALL {
                            self.timing.overruns_stalled += 1;
                        }
                        outage += 1;
                        self.timing.longest_outage = self.timing.longest_outage.max(outage);
                    } else {
                        outage = 0;
                    }
                    // A late start is a stall of the cycle it delays: its lumped frame
                    // leaves late against a P2P start that does not move.
                    self.stall = now - m;
                    last_losses = losses;
                    if let Some(t) = self.computed_at.take()
                        && self.last_master_rx > t
                    {
                        self.p2p.push(self.last_master_rx - t);
                    }
                    cycle_k += 1;
                    self.cycles_started = cycle_k;
                }
                self.master.handle_timeout(Instant::from_ns(now));
                self.drain_master(now);
                continue;
            }
            if got {
                continue;
            }
            if opts.verbose && now >= next_progress {
                next_progress += 1_000_000_000;
                let p = Percentiles::of(&self.lateness);
                eprintln!(
                    "ringsync rt: {:5.1} s  {cycle_k} cycles  overruns {}  cycle-start lateness p50 {:.1} µs, p99 {:.1} µs  rejected {}",
                    now as f64 * 1e-9,
                    self.timing.overruns,
                    p.p50 as f64 * 1e-3,
                    p.p99 as f64 * 1e-3,
                    rejected_line(&self.master, &self.slaves)
                );
            }
            // Wait for the next deadline, or for a frame while the master awaits one. Only
            // the master's deadlines (the cycle start, the P2P start) are worth `spin` of
            // busy-waiting; a latch is taken at its instant whenever the loop gets to it,
            // and a slave's response goes out when its command has been read.
            let mut wake = self.next_local(probe_k * t_cyc).0.min(m).min(end);
            if let Some(k) = kill {
                wake = wake.min(k.at.as_ns());
            }
            let lead = if wake >= m || wake == probe_k * t_cyc {
                spin
            } else {
                spin.min(SPIN_OTHER)
            };
            let rest = wake - now;
            if rest > lead {
                if self.master.awaiting_frames() || !self.pending.is_empty() {
                    sys::wait_readable(&mut fds, rest - lead)
                        .map_err(io_err("waiting for frames"))?;
                } else {
                    sys::sleep_until(self.t0 + wake - lead);
                }
                self.woke(wake - lead);
            }
        }
    }

    fn probe(&mut self, k: i64, t: i64) {
        let ts = t as f64 * 1e-9;
        let (axes, master, slaves, osc) = (&mut self.axes, &self.master, &self.slaves, &self.osc);
        let mut late = 0;
        self.rec.probe(k, |i| {
            if axes[i].t > t {
                late += 1;
            }
            axes[i].advance(t);
            let sync = slaves[i].clock().to_sync(osc[i].local(t));
            AxisProbe {
                x: axes[i].x,
                x_d: master.desired(i, ts).x,
                clock_error_ns: (sync.as_ns() - t) as f64,
                u: axes[i].u,
                saturated: slaves[i].status().contains(Status::SATURATED),
            }
        });
        if late > 0 {
            self.timing.probes_late += 1;
        }
    }
}
