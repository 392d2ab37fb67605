//! The real-time loop: one thread serves every node's port and runs the ring's
//! [`Devices`] (the same master, slaves, oscillators, axes and recorder the simulator
//! drives) from the monotonic [`Clock`].
//!
//! Per pass the loop (1) runs the timers that are due other than the master's: a cycle-start
//! probe of the true axis states, a slave's encoder latch, a slave's pending response; (2)
//! reads every frame waiting on any node's port (a slave forwards at once, in software,
//! where the paper's FPGA forwards after a fixed residence); (3) runs the master's timeout
//! if due. Between timers it sleeps (to an absolute deadline, or in `ppoll` on the ports
//! while the master awaits frames) until `spin` before the next deadline, then spins.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::thread::JoinHandle;

use ringsync_model::Spec;
use ringsync_model::devices::Devices;
use ringsync_model::observer::Observer;
use ringsync_model::result::{Captured, LinkCounters, RunResult};
use ringsync_model::scenario::LinkBreak;
use ringsync_model::stream::CaptureSink;
use ringsync_proto::Duration;
use ringsync_proto::node::{ClockFilter, FrameOutcome, Port as MasterPort, WireFrame};
use ringsync_wire::Frame;
use ringsync_wire::Pdu;

use crate::breaks::Breaks;
use crate::clock::Clock;
use crate::netns::VethRing;
use crate::run::{Kill, RtError, RtOptions, Sinks, Stamps, io_err, rejected_line};
use crate::sys;
use crate::timing::{Timing, TimingLog};
use crate::transport::{MAX_PDU, Port};

/// Busy-wait before a deadline that is not the master's [ns] (see
/// [`Realtime::spin`](crate::Realtime::spin) for the master's): a spin before every latch and
/// probe kept the loop on its CPU most of each cycle, and a loop that never sleeps starves
/// the CPU's other tasks until the kernel takes the CPU away from it for tens of ms
/// (measured: docs/runtime.md).
const SPIN_OTHER: i64 = 20_000;

/// After a receive error (a link went down) a port is read again this much later \[ns\]: a
/// link flap costs the cycles it lasts, not the run.
pub const RX_RETRY: i64 = 1_000_000;

/// The slave clock servo of the runtime (both stamps): it rides out bursts of late or lost
/// frames, which software stamps see as outliers (see the runtime's assumptions).
pub(crate) const RT_CLOCK_FILTER: ClockFilter = ClockFilter {
    offset_gain: 0.25,
    rate_gain: 0.25,
    outlier_limit: Some(Duration::from_us(50)),
    max_skips: 20,
    rate_interval: Duration::from_ms(100),
    max_rate_error: ringsync_proto::node::clock::MAX_RATE_ERROR,
};

/// What a loop is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mode {
    /// The warm-up: the real nodes on the real loop, measuring when each axis's commands
    /// take effect; nothing recorded.
    WarmUp,
    /// The run: recorded, with the trace and the frames sent when asked.
    Run {
        /// Keep the trace.
        trace: bool,
        /// Keep every frame sent.
        capture: bool,
        /// How the slaves stamp the lumped frames they receive.
        stamps: Stamps,
    },
}

/// What a finished loop hands back.
pub(crate) struct Finished {
    /// The recorder's result.
    pub run: RunResult,
    /// The ring's timing.
    pub timing: Timing,
    /// Per node: frames read, and when it last read one [s].
    pub nodes_rx: Vec<(u64, Option<f64>)>,
    /// Cycles from the removal of a slave to the group stop.
    pub detection_cycles: Option<i64>,
    /// Trace rows and captured frames the sinks dropped.
    pub dropped: (u64, u64),
}

/// Frames the nodes send, waiting for the loop: the devices' `send` closure borrows this
/// alone.
#[derive(Default)]
struct Outbox {
    /// The node index of the master's port B (n + 1).
    port_b: usize,
    /// The master's, to go out now.
    now: Vec<Vec<u8>>,
    /// The master's on its port B (a broken ring), to go out now.
    now_b: Vec<Vec<u8>>,
    /// Slave transmissions waiting for their time: (true ns, slave 0-based, bytes).
    pending: Vec<(i64, usize, Vec<u8>)>,
}

impl Outbox {
    /// A node's frame (the runtime's devices send bytes: [`WireFrame::into_bytes`] only
    /// moves them).
    fn send(&mut self, from: usize, at: i64, frame: WireFrame) {
        let bytes = frame.into_bytes();
        if from == 0 {
            self.now.push(bytes);
        } else if from == self.port_b {
            self.now_b.push(bytes);
        } else {
            self.pending.push((at, from - 1, bytes));
        }
    }
}

/// The running ring.
pub(crate) struct Ring {
    dev: Devices,
    /// Each slave's next latch [true ns], kept as the devices tell it after each call.
    latch_due: Vec<i64>,
    /// The emulated PHY stamps ([`Stamps::Phy`]); `None`: the loop's reading times.
    phy: Option<PhyStamps>,
    /// The next cycle probe's cycle.
    probe_k: i64,
    out: Outbox,
    /// Per node (0 = master): still in the ring.
    alive: Vec<bool>,
    /// Per port: read again from this time on after a receive error [ns, true time]; and
    /// the same for frames coming backward (a broken ring).
    rx_paused: Vec<Option<i64>>,
    back_paused: Vec<Option<i64>>,
    /// The set of ports to wait on changed.
    fds_dirty: bool,
    /// The nodes' ports (index 0 the master); a port taken out is `None`.
    pub ports: Vec<Option<Box<dyn Port>>>,
    /// Last frame read per node [s], and frames read per node.
    last_rx: Vec<Option<f64>>,
    rx_frames: Vec<u64>,
    /// A link flap over UDP: frames sent on it in [from, to) [ns] are dropped.
    flap: Option<(usize, i64, i64)>,
    /// Broken links (`faults.break_link`): the nodes beside one sense it, as a PHY does,
    /// and turn frames back; and the master's port links' changes still to tell it of
    /// (true ns, port, up).
    breaks: Breaks,
    port_events: std::collections::VecDeque<(i64, MasterPort, bool)>,
    /// CLOCK_MONOTONIC at true time 0, for the injectors' threads [ns].
    pub t0_shared: Arc<AtomicI64>,
    captured: Option<Vec<Captured>>,
    /// Where captured frames go instead of `captured` ([`Ring::stream`]).
    capture_sink: Option<Box<dyn CaptureSink>>,
    clock: Clock,
    /// End of the run [ns, true time].
    end: i64,
    t_cyc: i64,
    log: TimingLog,
    /// Warm-up: when each axis's commands took effect, from their cycle's start [ns].
    arrivals: Option<Vec<Vec<i64>>>,
    /// Cycles started at the removal of a slave, and at the group stop.
    kill_cycle: Option<i64>,
    stop_cycle: Option<i64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Due {
    Probe,
    Latch(usize),
    Pending(usize),
}

/// Reads and discards whatever is waiting on the ports; returns how many of those frames a
/// node would have refused as malformed (not ringsync's at the link layer, or failing the
/// PDU's header, payload or CRC checks), and how many were well-formed.
pub(crate) fn drain(ports: &mut [Option<Box<dyn Port>>]) -> (u64, u64) {
    ports
        .iter_mut()
        .flatten()
        .map(|p| drain_port(p.as_mut()))
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// [`drain`] for one port.
pub(crate) fn drain_port(p: &mut dyn Port) -> (u64, u64) {
    let mut buf = vec![0u8; MAX_PDU];
    let (mut malformed, mut valid) = (0, 0);
    // Both directions: frames a broken ring turned back wait on the other socket.
    for back in [false, true] {
        while let Ok(Some(len)) = if back {
            p.recv_back(&mut buf)
        } else {
            p.recv(&mut buf)
        } {
            if buf
                .get(..len)
                .is_none_or(|b| len == 0 || Pdu::parse(b).is_err())
            {
                malformed += 1;
            } else {
                valid += 1;
            }
        }
    }
    (malformed, valid)
}

/// The cycle counter of a command frame, if `bytes` is one.
fn command_cycle(bytes: &[u8]) -> Option<u32> {
    let f = Frame::new_checked(bytes).ok()?;
    (f.kind().ok()? == ringsync_wire::FrameKind::Command).then(|| f.common().cycle)
}

/// The master's timestamp of a lumped frame (of either plan), if `bytes` is one.
fn lumped_stamp(bytes: &[u8]) -> Option<u64> {
    let f = Frame::new_checked(bytes).ok()?;
    f.lumped().ok().map(|p| p.master_time_ns())
}

/// Emulated PHY receive stamps ([`Stamps::Phy`]): the loop knows when the master sent each
/// lumped frame; a slave's stamp is that instant plus its path delay, as a hardware stamp
/// reads on links of constant delay, whatever the loop's forwarding took. Looked up by the
/// master's timestamp in the frame among the last [`PhyStamps::KEPT`] lumped frames the loop
/// sent: a frame from elsewhere (injected, forged) gets the loop's reading time, and one
/// that replays a recent stamp gets that send's instant (a true measurement; the slave's
/// cycle and sequence checks refuse the replay).
pub(crate) struct PhyStamps {
    /// Each slave's path delay [ns].
    path: Vec<i64>,
    /// The master's latest lumped sends: (its timestamp in the frame, when the loop sent
    /// it [true ns]), a ring of [`PhyStamps::KEPT`].
    sent: Vec<(u64, i64)>,
    next: usize,
}

impl PhyStamps {
    /// Lumped sends remembered: several cycles of the largest ring's frames per cycle.
    const KEPT: usize = 64;

    fn new(path: Vec<i64>) -> PhyStamps {
        PhyStamps {
            path,
            sent: Vec::with_capacity(Self::KEPT),
            next: 0,
        }
    }

    /// The master sent a lumped frame stamped `stamp` at `at`.
    fn sent(&mut self, stamp: u64, at: i64) {
        if self.sent.len() < Self::KEPT {
            self.sent.push((stamp, at));
        } else {
            self.sent[self.next] = (stamp, at);
        }
        self.next = (self.next + 1) % Self::KEPT;
    }

    /// Slave `i`'s stamp of the lumped frame stamped `stamp`: `None` when the loop did not
    /// send it (lately). It may lie a little after the loop's reading of the frame, when the
    /// loop forwarded faster than in any cycle of the warm-up: a stamp held back to the
    /// reading would bias the slave's clock by the difference.
    fn received(&self, i: usize, stamp: u64) -> Option<i64> {
        let &(_, at) = self.sent.iter().find(|(s, _)| *s == stamp)?;
        Some(at.saturating_add(*self.path.get(i)?))
    }
}

impl Ring {
    /// The ring `spec` describes on `ports` for `cycles` cycles, `observers` watching.
    pub fn new(
        spec: &Spec,
        ports: Vec<Option<Box<dyn Port>>>,
        cycles: i64,
        mode: Mode,
        observers: Vec<Box<dyn Observer>>,
        sinks: Sinks,
    ) -> Result<Ring, RtError> {
        let n = spec.axes();
        let (trace, capture) = match mode {
            Mode::WarmUp => (false, false),
            Mode::Run { trace, capture, .. } => (trace, capture),
        };
        let phy = matches!(
            mode,
            Mode::Run {
                stamps: Stamps::Phy,
                ..
            }
        )
        .then(|| PhyStamps::new(spec.slaves.iter().map(|c| c.path_delay.as_ns()).collect()));
        // A trace or capture that goes to a sink is never reserved for the whole run
        // (under `mlockall` a reservation is resident at once, and would grow with the
        // run's duration).
        let trace_sink = sinks.trace.filter(|_| trace);
        let capture_sink = sinks.capture.filter(|_| capture);
        let mut dev = Devices::new(spec, cycles, trace && trace_sink.is_none())?;
        if let Some(t) = trace_sink {
            dev.stream_trace(t);
        }
        for sl in &mut dev.slaves {
            sl.clock_mut().set_filter(RT_CLOCK_FILTER);
        }
        for o in observers {
            dev.observe(o);
        }
        let latch_due = (0..n).map(|i| dev.latch_at(i)).collect();
        Ok(Ring {
            dev,
            latch_due,
            out: Outbox {
                port_b: n + 1,
                ..Outbox::default()
            },
            alive: vec![true; n + 1],
            rx_paused: vec![None; n + 1],
            back_paused: vec![None; n + 1],
            fds_dirty: false,
            ports,
            last_rx: vec![None; n + 1],
            rx_frames: vec![0; n + 1],
            flap: None,
            breaks: match mode {
                Mode::WarmUp => Breaks::default(),
                Mode::Run { .. } => Breaks::new(spec.scenario.faults.break_link.clone(), n),
            },
            port_events: match mode {
                Mode::WarmUp => Default::default(),
                Mode::Run { .. } => {
                    LinkBreak::port_changes(&spec.scenario.faults.break_link, n).into()
                }
            },
            t0_shared: Arc::new(AtomicI64::new(0)),
            // Every send: the lumped frame's n + 1 hops and each slice's n + 1 (command and
            // response), so that capturing never reallocates mid-run.
            captured: (capture && capture_sink.is_none()).then(|| {
                Vec::with_capacity(usize::try_from(cycles.max(0)).unwrap_or(0) * (n + 1) * (n + 2))
            }),
            capture_sink,
            clock: Clock::start_in(0),
            t_cyc: spec.scenario.ring.cycle.0.as_ns(),
            end: cycles * spec.scenario.ring.cycle.0.as_ns(),
            log: TimingLog::new(cycles),
            arrivals: (mode == Mode::WarmUp).then(|| vec![Vec::new(); n]),
            phy,
            probe_k: 0,
            kill_cycle: None,
            stop_cycle: None,
        })
    }

    /// When each axis's commands took effect in the warm-up, from the cycle start (median
    /// per axis) [ns].
    pub fn measured_command_arrivals(&self) -> Vec<Option<i64>> {
        self.arrivals
            .iter()
            .flatten()
            .map(|v| (!v.is_empty()).then(|| crate::stats::Percentiles::of(v).p50))
            .collect()
    }

    /// Whether the trace and the capture go to sinks (trace, capture).
    pub fn streaming(&self) -> (bool, bool) {
        (
            self.dev.recorder().streams_trace(),
            self.capture_sink.is_some(),
        )
    }

    /// Whether link `link` (1..=n+1, from node link − 1 to node link; n + 1 is the master's
    /// port B) is broken at `t` [ns].
    fn link_down(&self, link: usize, t: i64) -> bool {
        self.breaks.down(link, t)
    }

    /// Node `node` sends a frame on round the ring, as its PHYs let it: forward, or back the
    /// way it came when its link ahead is broken (a slave turns it; the master's port A
    /// has nowhere to send it).
    fn forward(&mut self, node: usize, t: i64, bytes: &[u8]) {
        if self.breaks.is_empty() || !self.link_down(node + 1, t) {
            self.send(node, t, bytes, false);
        } else if node != 0 && !self.cut_off(node, t) {
            self.send(node, t, bytes, true);
        } else {
            self.log.timing.broken_dropped += 1;
        }
    }

    /// Whether slave `node` is cut off from both of the master's ports at `t`
    /// ([`Breaks::cut_off`]).
    fn cut_off(&self, node: usize, t: i64) -> bool {
        self.breaks.cut_off(node, t)
    }

    fn send(&mut self, node: usize, t: i64, bytes: &[u8], back: bool) {
        let frame = || Captured {
            t,
            node,
            bytes: bytes.to_vec(),
        };
        if let Some(c) = &mut self.captured {
            c.push(frame());
        } else if let Some(c) = &mut self.capture_sink {
            c.frame(frame());
        }
        if let Some((link, from, to)) = self.flap
            && link == node
            && (from..to).contains(&t)
        {
            self.log.timing.flap_dropped += 1;
            return;
        }
        if let Some(p) = self.ports[node].as_mut()
            && self.alive[node]
            && if back {
                p.send_back(bytes)
            } else {
                p.send(bytes)
            }
            .is_err()
        {
            self.log.timing.send_errors += 1;
        }
    }

    /// Sends what the master queued at `now` and hands the buffers back.
    fn flush_master(&mut self, now: i64) {
        let mut out = std::mem::take(&mut self.out.now);
        for bytes in out.drain(..) {
            if let Some(p) = self.phy.as_mut()
                && let Some(stamp) = lumped_stamp(&bytes)
            {
                p.sent(stamp, now);
            }
            self.forward(0, now, &bytes);
            self.dev.recycle(0, bytes);
        }
        self.out.now = out;
        // Port B of a broken ring: the copy's stamp is its send time + Δ, the extra path to
        // the slaves it reaches (docs/planner.md, "A broken link"); their emulated PHY
        // stamps take it from there.
        let mut out_b = std::mem::take(&mut self.out.now_b);
        let shift = self
            .dev
            .master
            .broken_ring()
            .map_or(0, |b| b.stamp_shift.as_ns());
        let port_b = self.out.port_b;
        for bytes in out_b.drain(..) {
            if let Some(p) = self.phy.as_mut()
                && let Some(stamp) = lumped_stamp(&bytes)
            {
                p.sent(stamp, now + shift);
            }
            if self.link_down(port_b, now) {
                self.log.timing.broken_dropped += 1;
            } else {
                self.send(0, now, &bytes, true);
            }
            self.dev.recycle(0, bytes);
        }
        self.out.now_b = out_b;
    }

    /// A frame that came to node `node` backward round the ring: the master takes it on
    /// its port A; a slave relays it on, or turns it and takes it when the link behind it
    /// is broken.
    fn on_back(&mut self, node: usize, now: i64, bytes: &mut [u8]) {
        if node == 0 {
            self.last_rx[0] = Some(now as f64 * 1e-9);
            self.rx_frames[0] += 1;
            self.log.master_rx(now);
            let Ring { dev, out, .. } = self;
            let news = dev.master_frame_port(MasterPort::A, now, bytes, &mut |f, at, b| {
                out.send(f, at, b)
            });
            self.master_news(news, now);
        } else if self.link_down(node, now) {
            if self.cut_off(node, now) {
                self.log.timing.broken_dropped += 1;
            } else {
                self.on_frame(node, now, bytes);
            }
        } else {
            // A relay: the node read it (its counters, as the locator reads them).
            self.last_rx[node] = Some(now as f64 * 1e-9);
            self.rx_frames[node] += 1;
            self.send(node, now, bytes, true);
        }
    }

    /// Tells the master of its ports' links that went down or came up by `now`.
    fn port_news(&mut self, now: i64) {
        while let Some(&(t, port, up)) = self.port_events.front() {
            if t > now {
                return;
            }
            self.port_events.pop_front();
            self.dev.master_link(now, port, up);
        }
    }

    fn on_frame(&mut self, node: usize, now: i64, bytes: &mut [u8]) {
        self.last_rx[node] = Some(now as f64 * 1e-9);
        self.rx_frames[node] += 1;
        let Ring { dev, out, .. } = self;
        if node == 0 {
            self.log.master_rx(now);
            let news = dev.master_frame(now, bytes, &mut |f, at, b| out.send(f, at, b));
            self.master_news(news, now);
            return;
        }
        let i = node - 1;
        // Everything due before the frame first: a command it carries advances the axis to
        // `now`, and a cycle probe or latch due earlier would then read a later state (a
        // host stall between the loop's timers and its reads made a probe read axis 4
        // 0.8 ms on and put 11.7 mrad into the run's errors).
        self.locals_until(now);
        let rx = self
            .phy
            .as_ref()
            .and_then(|p| p.received(i, lumped_stamp(bytes)?))
            .unwrap_or(now);
        let applied = self.dev.slaves[i].counters().commands;
        // The stamp starts the frame (the clock's measurement); what the frame makes the
        // slave do happens when the loop hands it over.
        let Ring { dev, out, .. } = self;
        let outcome = dev.slave_frame(i, rx, now, bytes, &mut |f, at, b| out.send(f, at, b));
        // A command taken in its own cycle: when it took effect, from that cycle's start.
        let t_cyc = self.t_cyc.max(1);
        if let Some(a) = self.arrivals.as_mut()
            && self.dev.slaves[i].counters().commands > applied
            && command_cycle(bytes) == Some(now.div_euclid(t_cyc) as u32)
        {
            a[i].push(now.rem_euclid(t_cyc));
        }
        if outcome == FrameOutcome::Forward {
            self.forward(node, now, bytes);
        }
        self.latch_due[i] = self.dev.latch_at(i);
    }

    fn master_news(&mut self, news: ringsync_model::devices::MasterNews, now: i64) {
        if news.computed {
            self.log.computed(now);
        }
        if news.stopped {
            self.stop_cycle.get_or_insert(self.log.timing.cycles);
        }
        self.flush_master(now);
    }

    /// Takes slave i's encoder latches due by `t`, each at its own instant with the axis
    /// state of that instant, however late the loop gets to them (as a hardware latch). Runs
    /// before anything that advances the axis past them: a frame read at `t` whose command
    /// moved the axis on first would make the latch read a later position (at a 500 µs cycle
    /// the velocity window's opening latch fell inside axis 4's time slice, and its velocity
    /// read up to 25 % high).
    fn latch_due(&mut self, i: usize, t: i64) {
        while self.alive[i + 1] && self.latch_due[i] <= t {
            let at = self.latch_due[i];
            let Ring { dev, out, .. } = self;
            if dev.latch(i, at, &mut |f, at, b| out.send(f, at, b)) {
                self.log.timing.latches_late += 1;
            }
            self.latch_due[i] = self.dev.latch_at(i);
        }
    }

    /// The earliest timer other than the master's and its true time [ns].
    fn next_local(&self, probe_at: i64) -> (i64, Due) {
        let mut best = (probe_at, Due::Probe);
        for (i, &t) in self.latch_due.iter().enumerate() {
            if self.alive[i + 1] && t < best.0 {
                best = (t, Due::Latch(i));
            }
        }
        for (j, p) in self.out.pending.iter().enumerate() {
            if p.0 < best.0 {
                best = (p.0, Due::Pending(j));
            }
        }
        best
    }

    /// Runs every timer other than the master's that is due by `now`, in time order:
    /// latches, cycle probes, responses.
    fn locals_until(&mut self, now: i64) {
        loop {
            let (at, due) = self.next_local(self.probe_k * self.t_cyc);
            if at > now || at >= self.end {
                return;
            }
            if now - at > 1_000_000 {
                self.log.timing.late_timers += 1;
            }
            self.run_local(due, at, now);
        }
    }

    /// Runs a timer other than the master's.
    fn run_local(&mut self, due: Due, due_at: i64, now: i64) {
        match due {
            Due::Probe => {
                if self.dev.probe(self.probe_k, due_at) > 0 {
                    self.log.timing.probes_late += 1;
                }
                self.probe_k += 1;
            }
            Due::Latch(i) => self.latch_due(i, due_at),
            Due::Pending(j) => {
                let (_, i, bytes) = self.out.pending.swap_remove(j);
                if self.alive[i + 1] {
                    self.forward(i + 1, now, &bytes);
                }
                self.dev.recycle(i + 1, bytes);
            }
        }
    }

    /// Reads every frame waiting on any node's port; a frame forwarded in this pass is read
    /// at the next node in the same pass. Whether any was read.
    fn receive_all(&mut self, buf: &mut [u8]) -> bool {
        let mut got = false;
        for node in 0..self.ports.len() {
            got |= self.receive(node, false, buf);
            if !self.breaks.is_empty() {
                got |= self.receive(node, true, buf);
            }
        }
        got
    }

    /// Reads every frame waiting at node `node` from one direction (`back`: frames coming
    /// backward round the ring). Whether any was read.
    fn receive(&mut self, node: usize, back: bool, buf: &mut [u8]) -> bool {
        let paused = if back {
            &mut self.back_paused[node]
        } else {
            &mut self.rx_paused[node]
        };
        if let Some(until) = *paused {
            if self.clock.last() < until {
                return false;
            }
            *paused = None;
            self.fds_dirty = true;
        }
        let mut got = false;
        while let Some(p) = self.ports[node].as_mut() {
            let read = if back { p.recv_back(buf) } else { p.recv(buf) };
            let len = match read {
                Ok(Some(len)) => len,
                Ok(None) => break,
                Err(_) => {
                    // A link gone down: the socket reports an error (and would keep the
                    // poll awake). Read it again a little later: a flap shorter than W
                    // cycles costs those cycles, not the run.
                    self.log.timing.receive_errors += 1;
                    let until = Some(self.clock.last() + RX_RETRY);
                    if back {
                        self.back_paused[node] = until;
                    } else {
                        self.rx_paused[node] = until;
                    }
                    self.fds_dirty = true;
                    break;
                }
            };
            got = true;
            let now = self.clock.now();
            if back {
                self.on_back(node, now, &mut buf[..len]);
            } else {
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
    pub fn run_loop(
        &mut self,
        opts: &RtOptions,
        stop: &AtomicBool,
        kill: Option<Kill>,
        veth: &Option<Arc<VethRing>>,
        killer: &mut Option<JoinHandle<()>>,
    ) -> Result<(bool, Option<(usize, f64)>), RtError> {
        let t_cyc = self.t_cyc;
        let spin = opts.realtime.spin.as_ns();
        let end = self.end;
        let mut buf = vec![0u8; MAX_PDU];
        let both = !self.breaks.is_empty();
        let fds_of = |ports: &[Option<Box<dyn Port>>],
                      paused: &[Option<i64>],
                      back_paused: &[Option<i64>]|
         -> Vec<libc::pollfd> {
            ports
                .iter()
                .zip(paused.iter().zip(back_paused))
                .filter_map(|(p, (fwd, back))| {
                    let p = p.as_ref()?;
                    let fwd = fwd.is_none().then(|| p.rx_fd());
                    let back = p.back_fd().filter(|_| both && back.is_none());
                    Some(fwd.into_iter().chain(back))
                })
                .flatten()
                .map(sys::pollfd)
                .collect()
        };
        let mut fds = fds_of(&self.ports, &self.rx_paused, &self.back_paused);
        let mut cycle_k = 0i64;
        self.probe_k = 0;
        let mut kill = kill;
        let mut killed = None;
        let mut next_progress = 1_000_000_000;
        // Start 2 ms from now, so that the first cycle starts on time.
        self.clock = Clock::start_in(2_000_000);
        self.t0_shared.store(self.clock.t0(), Ordering::SeqCst);
        self.flap = opts
            .flap
            .filter(|_| veth.is_none())
            .map(|f| (f.from, f.at.as_ns(), f.at.as_ns() + f.down_for.as_ns()));
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok((true, killed));
            }
            let mut now = self.clock.now();
            if now >= end {
                return Ok((false, killed));
            }
            if let Some(k) = kill
                && now >= k.at.as_ns()
            {
                kill = None;
                *killer = Some(self.take_out(k, veth));
                fds = fds_of(&self.ports, &self.rx_paused, &self.back_paused);
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
            //    in the devices, before any frame the loop has yet to read; and what the
            //    master's PHYs say of its links.
            self.locals_until(now);
            self.port_news(now);
            // 2. Every frame waiting anywhere.
            let got = self.receive_all(&mut buf);
            if std::mem::take(&mut self.fds_dirty) {
                fds = fds_of(&self.ports, &self.rx_paused, &self.back_paused);
            }
            // 3. The master, once per pass, so that a late master never runs its next step
            //    before the frames of its last one have gone round.
            let m = self.dev.master_deadline();
            now = self.clock.now();
            if m <= now && m < end {
                if now - m > 1_000_000 {
                    self.log.timing.late_timers += 1;
                }
                if m == cycle_k * t_cyc {
                    // A cycle starts: the account of the last one closes.
                    let c = self.dev.master.counters();
                    let stall = self.clock.take_stall();
                    let late = self.log.cycle_start(
                        cycle_k,
                        now,
                        m,
                        c.lumped_lost + c.commands_lost,
                        stall,
                    );
                    self.clock.note_stall(late);
                    self.dev
                        .timing(cycle_k, now - m, stall >= crate::timing::STALL);
                    cycle_k += 1;
                }
                let Ring { dev, out, .. } = self;
                let news = dev.master_timeout(now, &mut |f, at, b| out.send(f, at, b));
                self.master_news(news, now);
                continue;
            }
            if got {
                continue;
            }
            if opts.verbose && now >= next_progress {
                next_progress += 1_000_000_000;
                let p = self.log.lateness();
                eprintln!(
                    "ringsync rt: {:5.1} s  {cycle_k} cycles  overruns {}  cycle-start lateness p50 {:.1} µs, p99 {:.1} µs  rejected {}",
                    now as f64 * 1e-9,
                    self.log.timing.overruns,
                    p.p50 as f64 * 1e-3,
                    p.p99 as f64 * 1e-3,
                    rejected_line(&self.dev.master, &self.dev.slaves)
                );
            }
            // Wait for the next deadline, or for a frame while the master awaits one. Only
            // the master's deadlines (the cycle start, the P2P start) are worth `spin` of
            // busy-waiting; a latch is taken at its instant whenever the loop gets to it,
            // and a slave's response goes out when its command has been read.
            let mut wake = self.next_local(self.probe_k * t_cyc).0.min(m).min(end);
            if let Some(k) = kill {
                wake = wake.min(k.at.as_ns());
            }
            let lead = if wake >= m || wake == self.probe_k * t_cyc {
                spin
            } else {
                spin.min(SPIN_OTHER)
            };
            if wake - now > lead {
                if self.dev.master.awaiting_frames() || !self.out.pending.is_empty() {
                    self.clock
                        .wait_readable_until(&mut fds, wake - lead)
                        .map_err(io_err("waiting for frames"))?;
                } else {
                    self.clock.sleep_until(wake - lead);
                }
            }
        }
    }

    /// The run's result and timing; the ports stay with the caller (to close before the
    /// namespaces go).
    pub fn finish(self, scenario: &str) -> (Finished, Vec<Option<Box<dyn Port>>>) {
        let Ring {
            dev,
            ports,
            log,
            last_rx,
            rx_frames,
            captured,
            capture_sink,
            kill_cycle,
            stop_cycle,
            ..
        } = self;
        let dropped = (
            dev.recorder().trace_rows_dropped(),
            capture_sink.as_ref().map_or(0, |c| c.dropped()),
        );
        let timing = log.finish(&dev.master.counters());
        let mut run = dev.finish(
            scenario,
            LinkCounters::default(),
            Vec::new(),
            captured.unwrap_or_default(),
        );
        run.cycles = timing.cycles;
        (
            Finished {
                run,
                timing,
                nodes_rx: rx_frames.into_iter().zip(last_rx).collect(),
                detection_cycles: kill_cycle.zip(stop_cycle).map(|(k, s)| s - k),
                dropped,
            },
            ports,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_loop_refuses_kernel_stamps_before_it_builds_anything() {
        let opts = crate::run::RtOptions {
            stamps: Stamps::Kernel,
            ..crate::run::RtOptions::default()
        };
        let stop = std::sync::atomic::AtomicBool::new(false);
        let e = crate::run::run(&ringsync_model::scenario::Scenario::default(), &opts, &stop)
            .expect_err("refused");
        assert!(e.to_string().contains("--processes"), "{e}");
    }

    #[test]
    fn phy_stamps_come_from_the_masters_sends_never_from_a_frames_content() {
        let mut p = PhyStamps::new(vec![2_000, 4_000]);
        p.sent(1_000_000, 1_000_300);
        // The send instant plus the slave's path delay, whatever the stamp in the frame.
        assert_eq!(p.received(0, 1_000_000), Some(1_002_300));
        assert_eq!(p.received(1, 1_000_000), Some(1_004_300));
        // A frame the loop never sent (a forged one from the future) gets no PHY stamp.
        assert_eq!(p.received(0, 2_000_000_000), None);
        // Only the latest sends are kept.
        for k in 1..=PhyStamps::KEPT as u64 {
            p.sent(1_000_000 + k, 1_000_300 + k as i64);
        }
        assert_eq!(p.received(0, 1_000_000), None);
        assert_eq!(p.received(0, 1_000_001), Some(1_002_301));
        // A slave beyond the ring gets none either.
        assert_eq!(p.received(2, 1_000_001), None);
    }
}
