//! The deterministic co-simulator: the ring's [`Devices`] (the sans-IO master and slaves of
//! `ringsync-proto`, their oscillators, the axes, the recorder) driven by an event
//! queue (`kernel`) ordered by (time, sequence), on modelled links (`link`).
//!
//! - **Links**: per hop L + uniform jitter, loss and corruption per trip round the ring,
//!   cut-through forwarding, closed-form paths (see `link`).
//! - **Oscillators**: slave i's local clock reads offset_i + t·(1 + drift_i), truncated to the
//!   timestamp resolution; the master's clock is the reference (true time).
//! - **Plants**: each axis advances exactly (piecewise for Coulomb friction) from one event to
//!   the next with its command held.
//!
//! Same scenario and seed → the same events in the same order → identical outputs.
//! Assumptions beyond the paper are listed in [`ASSUMPTIONS`].

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use ringsync_proto::Instant;
use ringsync_proto::PlanKind;
use ringsync_proto::node::{FrameOutcome, Port, WireFrame};
use ringsync_proto::plan::{FrameRef, Node};
use ringsync_wire::{Route, SlotCodec};

use ringsync_model::devices::Devices;
use ringsync_model::observer::Observer;
use ringsync_model::result::{PassageLog, RunResult};
use ringsync_model::scenario::{PathDelays, Scenario, ScenarioError};
use ringsync_model::spec::Spec;

use crate::kernel::{Next, Queue};
use crate::link::{Delivery, Link, cycle_route};

/// Assumptions of the simulation that the paper does not state (the model's, shared with
/// the runtime's results).
pub use ringsync_model::result::ASSUMPTIONS;

/// Options of a run besides the scenario.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Record every frame passage of cycles `[from, to)` (for tests and the timing figure).
    pub log_cycles: Option<(i64, i64)>,
    /// Record the per-cycle trace.
    pub trace: bool,
    /// Record every frame a node sends (for `--pcap`).
    pub capture: bool,
    /// Carry every frame between the nodes as bytes, as the runtime does, rather than
    /// decoded (no bytes, no CRC, where nothing reads them). The results are the same
    /// (a test compares the two); bytes cost more.
    pub bytes: bool,
    /// The caller's stop flag (Ctrl-C): when it rises, the run ends at the next cycle start
    /// and [`simulate`] returns [`RunError::Interrupted`] (no partial result).
    pub stop: Option<Stop>,
}

/// A flag that asks a run (or a sweep) to stop, looked at once per cycle (and before each
/// case of a sweep).
#[derive(Debug, Clone)]
pub enum Stop {
    /// A flag the caller shares with whatever raises it.
    Shared(Arc<AtomicBool>),
    /// A flag that lives for the whole process (a signal handler's).
    Static(&'static AtomicBool),
}

impl Stop {
    /// A new shared flag, down.
    pub fn new() -> Self {
        Stop::Shared(Arc::new(AtomicBool::new(false)))
    }

    /// Whether the flag has risen.
    pub fn raised(&self) -> bool {
        match self {
            Stop::Shared(f) => f.load(Ordering::Relaxed),
            Stop::Static(f) => f.load(Ordering::Relaxed),
        }
    }

    /// Raises the flag.
    pub fn raise(&self) {
        match self {
            Stop::Shared(f) => f.store(true, Ordering::Relaxed),
            Stop::Static(f) => f.store(true, Ordering::Relaxed),
        }
    }
}

impl Default for Stop {
    fn default() -> Self {
        Stop::new()
    }
}

/// What can stop a run from starting.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A plan the simulator does not run yet.
    #[error("{0}")]
    Unsupported(String),
    /// The nodes' start-up phase failed (`clock.path_delays = "measured"`).
    #[error("the start-up phase failed: {0}")]
    StartUp(#[from] ringsync_proto::node::CalibrationError),
    /// The caller's [`Stop`] flag rose before the run's end.
    #[error("interrupted at cycle {cycle} of {cycles}")]
    Interrupted {
        /// The cycle whose start saw the flag.
        cycle: i64,
        /// Cycles in the whole run.
        cycles: i64,
    },
}

#[derive(Debug)]
enum Ev {
    /// A frame's last bit reaches `node` (0 = master, on `port`).
    Arrive {
        node: usize,
        port: Port,
        rx_start: i64,
        frame: Boxed,
    },
    /// Slave i's response leaves (first bit).
    SlaveSend { slave: usize, frame: Boxed },
    /// Cycle start: read the true plant states.
    Probe { k: i64 },
    /// The link of the master's port `port` goes down or comes up (a broken link).
    PortLink { port: Port, up: bool },
}

/// A frame in flight, boxed: its event in the queue, and the node that handles it, move a
/// pointer rather than the frame, and a node forwards it where it lies. The boxes are kept
/// for the next frames sent ([`Net::boxed`], [`Net::unbox`]).
type Boxed = Box<WireFrame>;

/// The wire side of the simulation: the queue, the links, the boxes of frames in flight and
/// the buffers a lost frame hands back to its sender. The devices' `send` closure borrows
/// this alone.
struct Net {
    q: Queue<Ev>,
    link: Link,
    /// Empty boxes for the next frames sent.
    boxes: Vec<Boxed>,
    /// Lost frames, to hand back to (node, frame) once the devices are free.
    spare: Vec<(usize, WireFrame)>,
    /// The node index of the master's port B (n + 1).
    port_b: usize,
}

impl Net {
    /// A frame node `from` sends with first bit at `at`: the master's go on the link now (it
    /// sends at the instant it handles its timeout); a slave's response leaves at its own
    /// time, an event.
    fn send(&mut self, from: usize, at: i64, frame: WireFrame) {
        let frame = self.boxed(frame);
        if from == 0 || from == self.port_b {
            self.transmit(from, at, frame);
        } else {
            self.q.push(
                at,
                Ev::SlaveSend {
                    slave: from - 1,
                    frame,
                },
            );
        }
    }

    /// `frame` in a box (a kept one when there is one).
    fn boxed(&mut self, frame: WireFrame) -> Boxed {
        match self.boxes.pop() {
            Some(mut b) => {
                *b = frame;
                b
            }
            None => Box::new(frame),
        }
    }

    /// The frame out of its box, the box kept.
    fn unbox(&mut self, mut b: Boxed) -> WireFrame {
        let frame = std::mem::replace(&mut *b, WireFrame::Bytes(Vec::new()));
        self.boxes.push(b);
        frame
    }

    /// Sends `frame` from node `from`, first bit at `at`.
    fn transmit(&mut self, from: usize, at: i64, frame: Boxed) {
        // On a plain ring the frame stays in its box, into its arrival.
        if let Some(path) = self.link.plain_path(from, at, &frame) {
            match path {
                Some((node, rx_start, arrive)) => self.q.push(
                    arrive,
                    Ev::Arrive {
                        node,
                        port: Port::B,
                        rx_start,
                        frame,
                    },
                ),
                None => drop(self.unbox(frame)),
            }
            return;
        }
        let frame = self.unbox(frame);
        match self.link.send(from, at, frame) {
            Delivery::Arrive {
                node,
                port,
                rx_start,
                at,
                frame,
            } => {
                let frame = self.boxed(frame);
                self.q.push(
                    at,
                    Ev::Arrive {
                        node,
                        port,
                        rx_start,
                        frame,
                    },
                )
            }
            Delivery::Lost(frame) => self.spare.push((from % self.port_b, frame)),
            Delivery::Gone => {}
        }
    }
}

struct Sim {
    dev: Devices,
    net: Net,
    /// True time of each slave's pending latch (None once it has run).
    sample_at: Vec<Option<i64>>,
    /// Each slave's latch deadline in its local time when it was last scheduled: what its
    /// `poll_timeout` reads until a latch or a frame changes it.
    deadline: Vec<Instant>,
    t_cyc: i64,
    end: i64,
    /// Most slots per lumped frame (frame j carries slots from j·this).
    slots_per_frame: usize,
    log_cycles: Option<(i64, i64)>,
    passages: Vec<PassageLog>,
    stop: Option<Stop>,
    /// The cycle at whose start the stop flag was seen.
    interrupted: Option<i64>,
}

/// Runs a scenario.
pub fn run(s: &Scenario, opts: RunOptions) -> Result<RunResult, RunError> {
    run_with_progress(s, opts, &mut |_, _| {})
}

/// Runs a scenario, calling `progress(cycles done, cycles in all)` every 100 cycles.
pub fn run_with_progress(
    s: &Scenario,
    opts: RunOptions,
    progress: &mut dyn FnMut(i64, i64),
) -> Result<RunResult, RunError> {
    let spec = s.build()?;
    simulate(&spec, opts, Vec::new(), progress)
}

/// Runs a built ring, `observers` watching the run as it goes (each is told what the
/// recorder is told), `progress(cycles done, cycles in all)` called every 100 cycles.
pub fn simulate(
    spec: &Spec,
    opts: RunOptions,
    observers: Vec<Box<dyn Observer>>,
    progress: &mut dyn FnMut(i64, i64),
) -> Result<RunResult, RunError> {
    let s = &spec.scenario;
    let cap = ringsync_wire::lumped::slot_capacity(ringsync_wire::LumpedOnlySlot::LEN);
    if s.ring.plan == PlanKind::LumpedOnly && spec.axes() > cap {
        return Err(RunError::Unsupported(format!(
            "the simulator runs the lumped-only plan with one frame, so at most {cap} slaves; the scenario has {}",
            spec.axes()
        )));
    }
    // The start-up phase, when the nodes measure their path delays: before the run, each
    // slave then runs with the delay it took.
    let start_up = match s.clock.path_delays {
        PathDelays::Plan => None,
        PathDelays::Measured => Some(crate::calibrate::calibrate(
            spec,
            crate::calibrate::DEFAULT_PROBES,
        )?),
    };
    let measured_spec;
    let spec = match &start_up {
        None => spec,
        Some(c) => {
            let mut m = spec.clone();
            for (cfg, d) in m.slaves.iter_mut().zip(&c.taken) {
                if let Some(d) = d {
                    cfg.path_delay = *d;
                }
            }
            measured_spec = m;
            &measured_spec
        }
    };
    let mut sim = Sim::new(spec, opts)?;
    for o in observers {
        sim.dev.observe(o);
    }
    sim.run(progress);
    if let Some(cycle) = sim.interrupted {
        return Err(RunError::Interrupted {
            cycle,
            cycles: sim.end / sim.t_cyc,
        });
    }
    let mut r = sim.finish(&s.name);
    r.start_up = start_up;
    Ok(r)
}

impl Sim {
    fn new(spec: &Spec, opts: RunOptions) -> Result<Self, RunError> {
        let s = &spec.scenario;
        let n = spec.axes();
        let t_cyc = s.ring.cycle.0.as_ns();
        let cycles = s.duration.0.as_ns() / t_cyc;
        let end = cycles * t_cyc;
        let mut dev = Devices::new(spec, cycles, opts.trace)?;
        dev.carry_decoded(!opts.bytes);
        let mut sim = Sim {
            dev,
            net: Net {
                q: Queue::new(n),
                link: Link::new(spec, end, opts.capture),
                boxes: Vec::new(),
                spare: Vec::new(),
                port_b: n + 1,
            },
            sample_at: vec![None; n],
            deadline: vec![Instant::from_ns(0); n],
            t_cyc,
            end,
            slots_per_frame: spec.plan.lumped.slots_per_frame,
            log_cycles: opts.log_cycles,
            passages: Vec::new(),
            stop: opts.stop,
            interrupted: None,
        };
        sim.schedule_master();
        for i in 0..n {
            sim.schedule_latch(i);
        }
        // Probes are scheduled one at a time, so the queue stays a few entries deep.
        sim.net.q.push(0, Ev::Probe { k: 0 });
        for (t, port, up) in sim.net.link.port_changes() {
            sim.net.q.push(t, Ev::PortLink { port, up });
        }
        Ok(sim)
    }

    /// Schedules the master's next timeout in place of its pending one. A replaced timeout
    /// counts as an event (it counted as one when it stayed in the queue, stale, until its
    /// time, which was before the end).
    fn schedule_master(&mut self) {
        let t = self.dev.master_deadline();
        if self.net.q.set_timer((t < self.end).then_some(t)).is_some() {
            self.net.link.counters.events += 1;
        }
    }

    /// Schedules slave i's next latch. A clock sync moves the latch's local deadline by
    /// nanoseconds at most, and often not at all in true time: then the pending latch
    /// stands. A replaced latch before the end counts as an event, as the master's timeout
    /// does.
    fn schedule_latch(&mut self, i: usize) {
        let (l, t) = self.dev.latch_deadline(i);
        self.schedule_latch_at(i, l, t);
    }

    /// [`Sim::schedule_latch`] with slave i's deadline `l` (local) and `t` (true) known.
    fn schedule_latch_at(&mut self, i: usize, l: Instant, t: i64) {
        self.deadline[i] = l;
        if self.sample_at[i] == Some(t) {
            return;
        }
        self.sample_at[i] = Some(t);
        if self.net.q.set_latch(t, i).is_some_and(|old| old < self.end) {
            self.net.link.counters.events += 1;
        }
    }

    /// Hands the buffers of lost frames back to their senders.
    fn recycle(&mut self) {
        if self.net.spare.is_empty() {
            return;
        }
        for (node, frame) in self.net.spare.drain(..) {
            self.dev.recycle_frame(node, frame);
        }
    }

    fn log(&mut self, node: usize, frame: &WireFrame, rx_start: i64, rx_end: i64) {
        let Some((from, to)) = self.log_cycles else {
            return;
        };
        let Some((cycle, route)) = cycle_route(frame) else {
            return;
        };
        let cycle = i64::from(cycle);
        if cycle < from || cycle >= to {
            return;
        }
        let frame = match route {
            Some(Route::Lumped { first_slot, .. }) => {
                FrameRef::Lumped((usize::from(first_slot) / self.slots_per_frame) as u32)
            }
            Some(Route::Command { target }) => FrameRef::Command(u32::from(target)),
            Some(Route::Response { source }) => FrameRef::Response(u32::from(source)),
            _ => return,
        };
        self.passages.push(PassageLog {
            cycle,
            frame,
            node: if node == 0 {
                Node::Master
            } else {
                Node::Slave(node as u32)
            },
            rx_start: Instant::from_ns(rx_start),
            rx_end: Instant::from_ns(rx_end),
        });
    }

    fn run(&mut self, progress: &mut dyn FnMut(i64, i64)) {
        let cycles = self.end / self.t_cyc;
        while let Some(next) = self.net.q.pop() {
            let (t, ev) = match next {
                Next::Latch(l) => {
                    if l.t >= self.end {
                        continue;
                    }
                    self.net.link.counters.events += 1;
                    self.sample_at[l.slave] = None;
                    let net = &mut self.net;
                    self.dev
                        .latch(l.slave, l.t, &mut |from, at, f| net.send(from, at, f));
                    self.recycle();
                    self.schedule_latch(l.slave);
                    continue;
                }
                Next::Timer(t) => {
                    if t >= self.end {
                        continue;
                    }
                    self.net.link.counters.events += 1;
                    let net = &mut self.net;
                    self.dev
                        .master_timeout(t, &mut |from, at, b| net.send(from, at, b));
                    self.recycle();
                    self.schedule_master();
                    continue;
                }
                Next::Event(t, ev) => (t, ev),
            };
            if t >= self.end && !matches!(ev, Ev::Probe { .. }) {
                // Let the last cycle's probe pass; nothing after the end counts.
                continue;
            }
            self.net.link.counters.events += 1;
            match ev {
                Ev::Arrive {
                    node,
                    port,
                    rx_start,
                    frame,
                } => {
                    self.log(node, &frame, rx_start, t);
                    if node != 0 && self.net.link.is_silent(node, t) {
                        continue;
                    }
                    if node == 0 {
                        let net = &mut self.net;
                        let send = &mut |from, at, f| net.send(from, at, f);
                        match (&*frame, port) {
                            (WireFrame::Bytes(b), Port::B) => self.dev.master_frame(t, b, send),
                            (WireFrame::Pdu(p), Port::B) => self.dev.master_pdu(t, p, send),
                            (f, Port::A) => self.dev.master_frame_on(Port::A, t, f, send),
                        };
                        let frame = self.net.unbox(frame);
                        self.dev.recycle_frame(0, frame);
                        self.recycle();
                        self.schedule_master();
                    } else {
                        self.on_slave_frame(node - 1, rx_start, t, frame);
                    }
                }
                Ev::PortLink { port, up } => {
                    self.dev.master_link(t, port, up);
                }
                Ev::SlaveSend { slave, frame } => {
                    self.net.transmit(slave + 1, t, frame);
                    self.recycle();
                }
                Ev::Probe { k } => {
                    if self.stop.as_ref().is_some_and(Stop::raised) {
                        self.interrupted = Some(k);
                        return;
                    }
                    if k % 100 == 0 {
                        progress(k, cycles);
                    }
                    let next = t + self.t_cyc;
                    if next < self.end {
                        self.net.q.push(next, Ev::Probe { k: k + 1 });
                    }
                    self.dev.probe(k, t);
                }
            }
        }
    }

    fn on_slave_frame(&mut self, i: usize, rx_start: i64, rx_end: i64, mut frame: Boxed) {
        let before = self.deadline[i];
        debug_assert_eq!(before, self.dev.slaves[i].poll_timeout());
        let net = &mut self.net;
        let send = &mut |from, at, f| net.send(from, at, f);
        let outcome = match &mut *frame {
            WireFrame::Bytes(b) => self.dev.slave_frame(i, rx_start, rx_end, b, send),
            WireFrame::Pdu(p) => self.dev.slave_pdu(i, rx_start, rx_end, p, send),
        };
        match outcome {
            FrameOutcome::Forward => {
                let at = rx_start + self.net.link.residence();
                self.net.transmit(i + 1, at, frame);
            }
            FrameOutcome::Consumed | FrameOutcome::Dropped => {
                let frame = self.net.unbox(frame);
                self.dev.recycle_frame(i + 1, frame)
            }
        }
        self.recycle();
        let l = self.dev.slaves[i].poll_timeout();
        if l != before {
            let t = self.dev.osc[i].true_at(l);
            self.schedule_latch_at(i, l, t);
        }
    }

    fn finish(self, scenario: &str) -> RunResult {
        let Net { link, .. } = self.net;
        let mut captured = link.captured.unwrap_or_default();
        // Relays are recorded when their frame is sent: put every hop in time order (stable,
        // so frames sent at one instant keep their order).
        captured.sort_by_key(|c| c.t);
        self.dev
            .finish(scenario, link.counters, self.passages, captured)
    }
}

#[cfg(test)]
mod arm_tests;
#[cfg(test)]
mod redundancy_tests;
#[cfg(test)]
mod tests;
