//! The one driver kit: a ring's master, slaves, the slaves' oscillators, the axes and the
//! recorder, as every driver of a ring drives them. The simulator (an event queue on modelled
//! links) and the runtime (a real-time loop on real sockets) own time and the wire; this owns
//! everything else, so that the glue around the nodes is written once.
//!
//! Times in the calls are true (master) time in ns; a slave's local time is its
//! oscillator's reading of it. Frames a node sends go out through the driver's `send`
//! closure, `send(from, at, frame)`: from node `from` (0 = the master, i = slave i; n + 1 =
//! the master's port B, on a broken ring), first bit at true time `at`. The master's frames leave when it handles its timeout (or a frame);
//! a slave's responses at their own time, after its response delay. The frames are bytes
//! ([`WireFrame::Bytes`]) unless the driver asked for decoded ones
//! ([`Devices::carry_decoded`]: the simulator, which then computes no CRC).
//!
//! ```
//! use ringsync_model::Scenario;
//! use ringsync_model::devices::Devices;
//! let spec = Scenario::default().build().unwrap();
//! let mut d = Devices::new(&spec, 10, false).unwrap();
//! // The master's first deadline: the cycle start, where it sends the lumped frame.
//! assert_eq!(d.master_deadline(), 0);
//! let mut sent = Vec::new();
//! d.master_timeout(0, &mut |from, at, frame| sent.push((from, at, frame.into_bytes().len())));
//! assert_eq!(sent, vec![(0, 0, 108)]);
//! ```

use ringsync_proto::Instant;
use ringsync_proto::node::{
    FrameOutcome, Master, MasterEvent, Port, SafeState, Slave, SlaveEvent, WireFrame,
};
use ringsync_wire::{Pdu, Status};

use crate::axes::Axes;
use crate::locate::locate_break_of;
use crate::monitor::MonitorEvent;
use crate::observer::Observer;
use crate::oscillator::Oscillator;
use crate::record::{AxisProbe, FaultEvent, FaultStep, Recorder};
use crate::result::{Captured, LinkCounters, PassageLog, RingChange, RunResult};
use crate::scenario::ScenarioError;
use crate::spec::Spec;

/// What happened at the master in one call, for a driver's own bookkeeping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MasterNews {
    /// The law ran (a cycle's commands are computed).
    pub computed: bool,
    /// The group stop began.
    pub stopped: bool,
}

/// A ring's devices (see the module docs).
pub struct Devices {
    /// The master.
    pub master: Master,
    /// Slave i at index i − 1.
    pub slaves: Vec<Slave>,
    /// Slave i's oscillator at index i − 1.
    pub osc: Vec<Oscillator>,
    /// The axes, advanced by true time.
    pub axes: Box<dyn Axes>,
    rec: Recorder,
    observers: Vec<Box<dyn Observer>>,
    safe: Vec<SafeState>,
    probe: Vec<AxisProbe>,
    /// The nodes' frames go out decoded ([`Devices::carry_decoded`]).
    decoded: bool,
}

impl std::fmt::Debug for Devices {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Devices")
            .field("slaves", &self.slaves.len())
            .field("observers", &self.observers.len())
            .finish_non_exhaustive()
    }
}

impl Devices {
    /// The devices of `spec`'s ring at rest at true time 0, recording `cycles` cycles (and
    /// keeping the trace with `trace`).
    pub fn new(spec: &Spec, cycles: i64, trace: bool) -> Result<Self, ScenarioError> {
        let s = &spec.scenario;
        let (master, slaves) = spec.nodes()?;
        let axes = spec.plant()?;
        let n = slaves.len();
        let zero = AxisProbe::AT_REST;
        let mut rec = Recorder::new(n, cycles, s.ring.cycle.secs(), trace);
        if let (Some(map), Some(path)) = (s.machine_map()?, s.planned_path()?) {
            rec = rec.with_contour(map, path);
        }
        Ok(Devices {
            master,
            safe: slaves.iter().map(|s| s.config().safe_state).collect(),
            slaves,
            osc: Oscillator::for_scenario(s),
            axes,
            rec,
            observers: Vec::new(),
            probe: vec![zero; n],
            decoded: false,
        })
    }

    /// Streams the trace rows to `sink` as the run goes, instead of keeping them
    /// ([`crate::record::Recorder::stream_trace`]).
    pub fn stream_trace(&mut self, sink: Box<dyn crate::stream::TraceSink>) {
        self.rec.stream_trace(sink);
    }

    /// Whether the nodes' frames go to `send` decoded ([`WireFrame::Pdu`]: no bytes, no
    /// CRC) rather than as bytes. Default: bytes. A driver that carries decoded frames
    /// hands received ones to [`Devices::master_pdu`] and [`Devices::slave_pdu`].
    pub fn carry_decoded(&mut self, on: bool) {
        self.decoded = on;
    }

    /// Adds an observer: it is told what the recorder is told, as the run goes.
    pub fn observe(&mut self, o: Box<dyn Observer>) {
        self.observers.push(o);
    }

    /// Number of slaves n.
    pub fn len(&self) -> usize {
        self.slaves.len()
    }

    /// Whether the ring has no slave.
    pub fn is_empty(&self) -> bool {
        self.slaves.is_empty()
    }

    /// The recorder (its group stop so far, for instance).
    pub fn recorder(&self) -> &Recorder {
        &self.rec
    }

    fn each(&mut self, mut f: impl FnMut(&mut dyn Observer)) {
        f(&mut self.rec);
        for o in &mut self.observers {
            f(o.as_mut());
        }
    }

    fn fault(&mut self, t: f64, axis: usize, step: FaultStep) {
        let ev = FaultEvent { t, axis, step };
        self.each(|o| o.fault(&ev));
    }

    /// When the master next needs [`Devices::master_timeout`] [true ns].
    pub fn master_deadline(&self) -> i64 {
        self.master.poll_timeout().as_ns()
    }

    /// Runs the master's timeout at true time `now`.
    pub fn master_timeout(
        &mut self,
        now: i64,
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> MasterNews {
        self.master.handle_timeout(Instant::from_ns(now));
        self.drain_master(send)
    }

    /// A frame received completely by the master at true time `now`.
    pub fn master_frame(
        &mut self,
        now: i64,
        bytes: &[u8],
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> MasterNews {
        self.master.handle_frame(Instant::from_ns(now), bytes);
        self.drain_master(send)
    }

    /// A decoded frame received completely by the master at true time `now`.
    pub fn master_pdu(
        &mut self,
        now: i64,
        pdu: &Pdu,
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> MasterNews {
        self.master.handle_pdu(Instant::from_ns(now), pdu);
        self.drain_master(send)
    }

    /// [`Devices::master_frame`] or [`Devices::master_pdu`] for a frame that came back to
    /// the master's port `port` (a whole ring brings every frame back to port B).
    pub fn master_frame_on(
        &mut self,
        port: Port,
        now: i64,
        frame: &WireFrame,
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> MasterNews {
        let at = Instant::from_ns(now);
        match frame {
            WireFrame::Bytes(b) => self.master.handle_frame_on(port, at, b),
            WireFrame::Pdu(p) => self.master.handle_pdu_on(port, at, p),
        }
        self.drain_master(send)
    }

    /// [`Devices::master_frame`] for bytes that came back to the master's port `port`.
    pub fn master_frame_port(
        &mut self,
        port: Port,
        now: i64,
        bytes: &[u8],
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> MasterNews {
        self.master
            .handle_frame_on(port, Instant::from_ns(now), bytes);
        self.drain_master(send)
    }

    /// The link of the master's port `port` went down (`up` false) or came up at true time
    /// `now`.
    pub fn master_link(&mut self, now: i64, port: Port, up: bool) {
        self.master.handle_link(Instant::from_ns(now), port, up);
    }

    /// The node index a driver's `send` gets for the master's frames on port B: n + 1, the
    /// node after slave n (port A's are node 0).
    pub fn port_b_node(&self) -> usize {
        self.slaves.len() + 1
    }

    fn drain_master(&mut self, send: &mut dyn FnMut(usize, i64, WireFrame)) -> MasterNews {
        let mut news = MasterNews::default();
        let b = self.port_b_node();
        while let Some((at, port, frame)) = self.master.poll_frame_on(self.decoded) {
            send(if port == Port::B { b } else { 0 }, at.as_ns(), frame);
        }
        while let Some(ev) = self.master.poll_event() {
            match ev {
                MasterEvent::Computed { k } => {
                    news.computed = true;
                    let Devices {
                        master,
                        rec,
                        observers,
                        ..
                    } = self;
                    let r = master.record();
                    rec.computed(k, r);
                    for o in observers.iter_mut() {
                        o.computed(k, r);
                    }
                }
                MasterEvent::GroupStop { at, reason } => {
                    news.stopped = true;
                    // Where the ring broke, from what each node last took.
                    self.rec
                        .ring_break(locate_break_of(&self.master, &self.slaves, at));
                    let t = at.as_ns() as f64 * 1e-9;
                    self.fault(t, reason.axis() + 1, FaultStep::GroupStop(reason));
                }
                MasterEvent::Order {
                    at,
                    axis,
                    order,
                    why,
                } => self.fault(
                    at.as_ns() as f64 * 1e-9,
                    axis + 1,
                    FaultStep::Ordered(order, why),
                ),
                MasterEvent::Ring { at, k, from, to } => {
                    let change = RingChange {
                        t: at.as_ns() as f64 * 1e-9,
                        k,
                        from,
                        to,
                        cycles_lost: 0,
                    };
                    self.each(|o| o.ring(&change));
                }
                MasterEvent::Monitor { at, news } => {
                    let ev = MonitorEvent {
                        t: at.as_ns() as f64 * 1e-9,
                        axis: news.axis + 1,
                        kind: news.kind,
                        raised: news.raised,
                        value: news.value,
                    };
                    self.each(|o| o.monitor(&ev));
                }
            }
        }
        news
    }

    /// The true time of slave `i`'s (0-based) next encoder latch \[ns\].
    pub fn latch_at(&self, i: usize) -> i64 {
        self.latch_deadline(i).1
    }

    /// The local time of slave `i`'s (0-based) next encoder latch, and its true time \[ns\]
    /// ([`Devices::latch_at`]).
    pub fn latch_deadline(&self, i: usize) -> (Instant, i64) {
        let l = self.slaves[i].poll_timeout();
        (l, self.osc[i].true_at(l))
    }

    /// Takes slave `i`'s next encoder latch at its own instant `at` (the
    /// [`Devices::latch_at`] a driver scheduled), with the axis moved on to that instant;
    /// returns whether the axis had already moved past it (a driver that gets to a latch
    /// late).
    pub fn latch(
        &mut self,
        i: usize,
        at: i64,
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> bool {
        // (The first cycle's latches fall before the run's start, when the axis is at rest
        // where it starts.)
        let late = self.axes.time(i) > at.max(0);
        self.axes.advance(i, at);
        let counts = self.axes.counts(i);
        self.slaves[i].handle_sample(self.osc[i].local(at), counts);
        self.drain_slave(i, at, send);
        late
    }

    /// A frame whose first bit reached slave `i` (0-based) at true time `rx_start` and last
    /// bit at `rx_end`. A lumped frame is modified in place; on [`FrameOutcome::Forward`] the
    /// driver forwards `bytes`.
    pub fn slave_frame(
        &mut self,
        i: usize,
        rx_start: i64,
        rx_end: i64,
        bytes: &mut [u8],
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> FrameOutcome {
        let (ls, le) = (self.osc[i].local(rx_start), self.osc[i].local(rx_end));
        let outcome = self.slaves[i].handle_frame(ls, le, bytes);
        self.drain_slave(i, rx_end, send);
        outcome
    }

    /// [`Devices::slave_frame`] for a decoded frame: a lumped frame gets the slave's slot
    /// written in place.
    pub fn slave_pdu(
        &mut self,
        i: usize,
        rx_start: i64,
        rx_end: i64,
        pdu: &mut Pdu,
        send: &mut dyn FnMut(usize, i64, WireFrame),
    ) -> FrameOutcome {
        let (ls, le) = (self.osc[i].local(rx_start), self.osc[i].local(rx_end));
        let outcome = self.slaves[i].handle_pdu(ls, le, pdu);
        self.drain_slave(i, rx_end, send);
        outcome
    }

    /// Hands a frame buffer back to node `node` (0 = master) for its next sends.
    pub fn recycle(&mut self, node: usize, bytes: Vec<u8>) {
        match node {
            0 => self.master.recycle(bytes),
            i => self.slaves[i - 1].recycle(bytes),
        }
    }

    /// Hands a frame of either form back to node `node` (0 = master) for its next sends.
    pub fn recycle_frame(&mut self, node: usize, frame: WireFrame) {
        match (node, frame) {
            (_, WireFrame::Bytes(b)) => self.recycle(node, b),
            (0, WireFrame::Pdu(p)) => self.master.recycle_pdu(p),
            (_, WireFrame::Pdu(_)) => {}
        }
    }

    /// Acts on what slave `i` reported at true time `t`: a command or the drive's own brake
    /// changes the held command, torque off holds 0 V; every fault step is recorded. Its
    /// responses go to `send` at their own true time.
    fn drain_slave(&mut self, i: usize, t: i64, send: &mut dyn FnMut(usize, i64, WireFrame)) {
        while let Some(ev) = self.slaves[i].poll_event() {
            self.axes.advance(i, t);
            let ts = t as f64 * 1e-9;
            match ev {
                SlaveEvent::Apply { u } => {
                    self.axes.set_command(i, u);
                    self.each(|o| o.applied(i, ts, u));
                }
                SlaveEvent::Brake { u } => self.axes.set_command(i, u),
                SlaveEvent::WatchdogExpired => {
                    self.axes.set_command(i, 0.0);
                    self.fault(ts, i + 1, FaultStep::Watchdog(self.safe[i]));
                }
                SlaveEvent::TorqueOff { cause } => {
                    self.axes.set_command(i, 0.0);
                    self.fault(ts, i + 1, FaultStep::TorqueOff(cause));
                }
                SlaveEvent::Relocked { step } => self.fault(ts, i + 1, FaultStep::Relocked(step)),
                // The start-up phase runs before the run (`ringsync_sim::calibrate`).
                SlaveEvent::Calibrated { .. } => {}
                SlaveEvent::Braking { ordered } => {
                    self.fault(ts, i + 1, FaultStep::Braking { ordered })
                }
            }
        }
        while let Some((at, frame)) = self.slaves[i].poll_frame(self.decoded) {
            send(i + 1, self.osc[i].true_at(at), frame);
        }
    }

    /// Cycle `k` starts at true time `t` \[ns\]: every axis's true state then, to the recorder
    /// and the observers. Returns how many axes had already moved past `t` (a driver that
    /// gets to a cycle start late).
    pub fn probe(&mut self, k: i64, t: i64) -> usize {
        let ts = t as f64 * 1e-9;
        let mut late = 0;
        for i in 0..self.slaves.len() {
            if self.axes.time(i) > t {
                late += 1;
            }
            self.axes.advance(i, t);
            let sync = self.slaves[i].clock().to_sync(self.osc[i].local(t));
            self.probe[i] = AxisProbe {
                x: self.axes.position(i),
                x_d: self.master.desired(i, ts).x,
                clock_error_ns: (sync.as_ns() - t) as f64,
                u: self.axes.command(i),
                saturated: self.slaves[i].status().contains(Status::SATURATED),
            };
        }
        let Devices {
            rec,
            observers,
            probe,
            master,
            slaves,
            ..
        } = self;
        rec.cycle(k, ts, probe);
        for o in observers.iter_mut() {
            o.cycle(k, ts, probe);
            o.nodes(k, master, slaves);
        }
        late
    }

    /// A real-time driver's account of cycle `k`'s start (lateness \[ns\], whether the host
    /// stalled), to the observers (not the recorder: the driver keeps its own timing).
    pub fn timing(&mut self, k: i64, lateness_ns: i64, stalled: bool) {
        for o in &mut self.observers {
            o.timing(k, lateness_ns, stalled);
        }
    }

    /// The run's result: the recorder's, with every node's counters and the driver's own
    /// link counters, frame passages and captured frames.
    pub fn finish(
        self,
        scenario: &str,
        links: LinkCounters,
        passages: Vec<PassageLog>,
        captured: Vec<Captured>,
    ) -> RunResult {
        self.rec.finish(
            scenario,
            self.master.counters(),
            self.slaves.iter().map(|s| s.counters()).collect(),
            links,
            passages,
            captured,
        )
    }
}
