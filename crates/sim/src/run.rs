//! The deterministic co-simulator: the sans-IO master and slaves of `ringsync-proto` driven
//! by an event queue ordered by (time, sequence), on modelled links and oscillators, with
//! the servo plants integrated exactly between events.
//!
//! - **Links**: every hop adds PHY tx + cable + PHY rx (the cycle plan's L), plus a uniform
//!   random jitter in [0, jitter]. `loss` and `corruption` are probabilities per full trip
//!   round the ring (n + 1 hops): each hop loses a frame with 1 − (1 − loss)^(1/(n+1)), or
//!   flips one of its bits (its CRC then fails where it is checked) likewise. Forwarding
//!   slaves are cut-through: first bit out T_t after first bit in.
//! - **Closed-form paths**: a frame that slaves only forward (a command on its way to its
//!   target, a response on its way to the master) costs no event per hop; its arrival at the
//!   node that consumes it is computed at once, loss, corruption and jitter draws included.
//!   The lumped frame is processed at every slave (each writes its slot).
//! - **Oscillators**: slave i's local clock reads offset_i + t·(1 + drift_i), truncated to the
//!   timestamp resolution; the master's clock is the reference (true time).
//! - **Plants**: each axis advances exactly (piecewise for Coulomb friction) from one event to
//!   the next with its command held.
//!
//! Same scenario and seed → the same events in the same order → identical outputs.
//! Assumptions beyond the paper are listed in [`ASSUMPTIONS`].

use ringsync_proto::node::{FrameOutcome, Master, Slave};
use ringsync_proto::plan::{FrameRef, Node};
use ringsync_proto::{Instant, PlanKind};
use ringsync_wire::{Frame, FrameKind, SlotCodec};

use ringsync_model::nodes::{Oscillator, RingConfig, ServoAxis, locate_break_of};
use ringsync_model::record::{AxisProbe, Recorder};
use ringsync_model::result::{Captured, LinkCounters, PassageLog, RunResult};
use ringsync_model::rng::Rng;
use ringsync_model::scenario::{Scenario, ScenarioError};

/// Assumptions of the simulation that the paper does not state (the model's, shared with
/// the runtime's results).
pub use ringsync_model::result::ASSUMPTIONS;

/// Options of a run besides the scenario.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Record every frame passage of cycles `[from, to)` (for tests and the timing figure).
    pub log_cycles: Option<(i64, i64)>,
    /// Record the per-cycle trace rows.
    pub trace: bool,
    /// Record every frame a node sends (for `--pcap`).
    pub capture: bool,
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
}

#[derive(Debug)]
enum Ev {
    /// The master's next timeout; `generation` invalidates stale timers.
    Master { generation: u64 },
    /// Slave i's encoder latch; `generation` invalidates stale timers.
    Sample { slave: usize, generation: u64 },
    /// A frame's last bit reaches `node` (0 = master).
    Arrive {
        node: usize,
        rx_start: i64,
        bytes: Vec<u8>,
        corrupted: bool,
    },
    /// Slave i's response leaves (first bit).
    SlaveSend { slave: usize, bytes: Vec<u8> },
    /// Cycle start: read the true plant states.
    Probe { k: i64 },
}

struct Queued {
    t: i64,
    seq: u64,
    ev: Ev,
}

/// A slave's pending encoder latch, kept apart from the other events: there is one per
/// slave, so on a long ring they would make every insertion into the sorted event vector
/// walk and shift O(n) entries. Ordered by (time, sequence) like every event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Latch {
    t: i64,
    seq: u64,
    slave: usize,
    generation: u64,
}

impl PartialEq for Queued {
    fn eq(&self, o: &Self) -> bool {
        (self.t, self.seq) == (o.t, o.seq)
    }
}
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Queued {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.t, self.seq).cmp(&(o.t, o.seq))
    }
}

struct Sim<'a> {
    s: &'a Scenario,
    /// Pending events, sorted by (time, sequence) descending: the next one is last. The
    /// queue stays short (a few events per node), so an insertion's move is cheap.
    q: Vec<Queued>,
    /// Pending encoder latches, soonest first.
    latches: std::collections::BinaryHeap<std::cmp::Reverse<Latch>>,
    seq: u64,
    master: Master,
    slaves: Vec<Slave>,
    osc: Vec<Oscillator>,
    axes: Vec<ServoAxis>,
    gens: Vec<u64>,
    /// True time of each slave's valid pending latch event (None once it has run).
    sample_at: Vec<Option<i64>>,
    master_gen: u64,
    link_rng: Vec<Rng>,
    n: usize,
    hop: i64,
    residence: i64,
    jitter: i64,
    frame_ns: [i64; 4],
    /// Most slots per lumped frame (frame j carries slots from j·this).
    slots_per_frame: usize,
    /// Per-hop loss and corruption probabilities.
    hop_loss: f64,
    hop_corruption: f64,
    /// Loss and corruption probabilities over h hops (index h, 0 ..= n + 1).
    over_hops: Vec<(f64, f64)>,
    end: i64,
    counters: LinkCounters,
    opts: RunOptions,
    passages: Vec<PassageLog>,
    rec: Recorder,
    captured: Vec<Captured>,
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
    s.validate()?;
    let cap = ringsync_wire::lumped::slot_capacity(ringsync_wire::LumpedOnlySlot::LEN);
    if s.ring.plan == PlanKind::LumpedOnly && s.axes_count() > cap {
        return Err(RunError::Unsupported(format!(
            "the simulator runs the lumped-only plan with one frame, so at most {cap} slaves; the scenario has {}",
            s.axes_count()
        )));
    }
    let mut sim = Sim::new(s, opts)?;
    sim.run(progress);
    Ok(sim.finish())
}

impl<'a> Sim<'a> {
    fn new(s: &'a Scenario, opts: RunOptions) -> Result<Self, RunError> {
        let n = s.axes_count();
        let rc = RingConfig::new(s)?;
        let (master, slaves) = rc.build(s)?;
        let plan = rc.plan;
        let osc = Oscillator::for_scenario(s);
        let axes = ServoAxis::for_scenario(s)?;
        let frame_ns = [
            plan.lumped.frame_time[0].as_ns(),
            plan.t_cmf.as_ns(),
            plan.t_rmf.as_ns(),
            plan.lumped_only.lumped.frame_time[0].as_ns(),
        ];
        let cycles = s.duration.0.as_ns() / s.ring.cycle.0.as_ns();
        let opts_trace = opts.trace;
        let mut sim = Sim {
            s,
            q: Vec::with_capacity(64),
            latches: std::collections::BinaryHeap::with_capacity(2 * n + 2),
            seq: 0,
            master,
            slaves,
            osc,
            axes,
            gens: vec![0; n],
            sample_at: vec![None; n],
            master_gen: 0,
            link_rng: (0..=n).map(|h| Rng::stream(s.seed, h as u64)).collect(),
            n,
            hop: plan.hop.as_ns(),
            residence: s.ring.residence.0.as_ns(),
            jitter: s.ring.jitter.0.as_ns(),
            frame_ns,
            slots_per_frame: plan.lumped.slots_per_frame,
            hop_loss: 1.0 - (1.0 - s.faults.loss).powf(1.0 / (n + 1) as f64),
            hop_corruption: 1.0 - (1.0 - s.faults.corruption).powf(1.0 / (n + 1) as f64),
            over_hops: Vec::new(),
            end: cycles * s.ring.cycle.0.as_ns(),
            counters: LinkCounters::default(),
            opts,
            passages: Vec::new(),
            rec: Recorder::new(n, cycles, s.ring.cycle.secs(), opts_trace),
            captured: Vec::new(),
        };
        let over = |p: f64, h: usize| 1.0 - (1.0 - p).powi(h as i32);
        sim.over_hops = (0..=n + 1)
            .map(|h| (over(sim.hop_loss, h), over(sim.hop_corruption, h)))
            .collect();
        sim.schedule_master();
        for i in 0..n {
            sim.schedule_sample(i);
        }
        // Probes are scheduled one at a time, so the queue stays a few entries deep.
        sim.push(0, Ev::Probe { k: 0 });
        Ok(sim)
    }

    fn push(&mut self, t: i64, ev: Ev) {
        self.seq += 1;
        // The new entry has the largest sequence number, so it goes after every entry later
        // than `t`. New events are mostly near-future: scan from the near end.
        let mut at = self.q.len();
        while at > 0 && self.q[at - 1].t <= t {
            at -= 1;
        }
        self.q.insert(
            at,
            Queued {
                t,
                seq: self.seq,
                ev,
            },
        );
    }

    fn schedule_master(&mut self) {
        self.master_gen += 1;
        let t = self.master.poll_timeout().as_ns();
        if t < self.end {
            let generation = self.master_gen;
            self.push(t, Ev::Master { generation });
        }
    }

    /// Schedules slave i's next latch. A clock sync moves the latch's local deadline by
    /// nanoseconds at most, and often not at all in true time: then the pending event
    /// stands (a new one would leave the old, invalidated, in the queue until its time).
    fn schedule_sample(&mut self, i: usize) {
        let t = self.osc[i].true_at(self.slaves[i].poll_timeout());
        if self.sample_at[i] == Some(t) {
            return;
        }
        self.sample_at[i] = Some(t);
        self.gens[i] += 1;
        self.seq += 1;
        self.latches.push(std::cmp::Reverse(Latch {
            t,
            seq: self.seq,
            slave: i,
            generation: self.gens[i],
        }));
    }

    /// The next event in (time, sequence) order, from the event vector or the latches.
    fn pop(&mut self) -> Option<(i64, Ev)> {
        let latch_first = match (self.latches.peek(), self.q.last()) {
            (Some(std::cmp::Reverse(l)), Some(e)) => (l.t, l.seq) < (e.t, e.seq),
            (Some(_), None) => true,
            (None, _) => false,
        };
        if latch_first {
            let std::cmp::Reverse(l) = self.latches.pop()?;
            Some((
                l.t,
                Ev::Sample {
                    slave: l.slave,
                    generation: l.generation,
                },
            ))
        } else {
            self.q.pop().map(|e| (e.t, e.ev))
        }
    }

    /// Wire time of a frame of kind `kind` (its kind byte) [ns].
    fn frame_ns(&self, kind: u8) -> i64 {
        match kind {
            1 => self.frame_ns[0],
            2 => self.frame_ns[1],
            4 => self.frame_ns[3],
            _ => self.frame_ns[2],
        }
    }

    /// Sends `bytes` from node `from` (0 = master), first bit out at true `t_tx`, along the
    /// ring to the first node that processes it: the master for everything that comes back
    /// round, a command's target, and the slaves whose slots a lumped frame carries. Slaves in
    /// between only forward (cut-through, in hardware) and cost no event.
    fn send(&mut self, from: usize, t_tx: i64, mut bytes: Vec<u8>) {
        if self.opts.capture && t_tx < self.end {
            self.captured.push(Captured {
                t: t_tx,
                node: from,
                bytes: bytes.clone(),
            });
        }
        let Ok(f) = Frame::new_checked(&bytes[..]) else {
            return;
        };
        let (kind, p) = (f.kind_byte(), f.payload());
        let word = |at: usize| {
            p.get(at..at + 2)
                .map_or(0, |b| usize::from(u16::from_le_bytes([b[0], b[1]])))
        };
        let ring = self.n + 1;
        // The node (0 = master) that processes the frame next.
        let stop = if kind == FrameKind::Command as u8 && from == 0 {
            word(0).min(self.n)
        } else if kind == FrameKind::Lumped as u8 || kind == FrameKind::LumpedOnly as u8 {
            // Slots f..f+m belong to slaves f+1..=f+m.
            let (first, count) = (word(8), word(10));
            let next = from + 1;
            if next <= first {
                (first + 1).min(ring) % ring
            } else if next <= first + count && next <= self.n {
                next
            } else {
                0
            }
        } else {
            0
        };
        let stop = if stop == 0 && from == 0 { ring } else { stop };
        let hops = ((stop + ring - from) % ring).max(1) as i64;
        let stop = stop % ring;
        let dur = self.frame_ns(kind);
        let rng = &mut self.link_rng[from];
        let mut rx = t_tx + hops * self.hop + (hops - 1) * self.residence;
        let mut corrupted = false;
        if self.jitter > 0 {
            // Per hop: jitter, loss and corruption draws hop by hop.
            for _ in 0..hops {
                rx += (rng.unit() * (self.jitter + 1) as f64) as i64;
                if rng.chance(self.hop_loss) {
                    self.counters.lost += 1;
                    self.recycle(from, bytes);
                    return;
                }
                if rng.chance(self.hop_corruption) {
                    corrupted = true;
                }
            }
        } else {
            // No jitter: one draw each with the probability over all hops (same distribution).
            let (loss, corruption) = self.over_hops[hops as usize];
            if rng.chance(loss) {
                self.counters.lost += 1;
                self.recycle(from, bytes);
                return;
            }
            corrupted = rng.chance(corruption);
        }
        if corrupted {
            let bit = (rng.next_u64() % (bytes.len() as u64 * 8)) as usize;
            bytes[bit / 8] ^= 1 << (bit % 8);
            self.counters.corrupted += 1;
        }
        // A dead slave between sender and receiver forwards nothing.
        let silent = self.s.faults.silent_slave as usize;
        if silent != 0 && silent != stop {
            let d = (silent + ring - from) % ring;
            if d > 0 && (d as i64) < hops {
                let at = t_tx + d as i64 * self.hop + (d as i64 - 1) * self.residence;
                if self.is_silent(silent, at) {
                    return;
                }
            }
        }
        self.push(
            rx + dur,
            Ev::Arrive {
                node: stop,
                rx_start: rx,
                bytes,
                corrupted,
            },
        );
    }

    /// Hands a frame buffer back to node `node` (0 = master) for its next sends.
    fn recycle(&mut self, node: usize, bytes: Vec<u8>) {
        match node {
            0 => self.master.recycle(bytes),
            i => self.slaves[i - 1].recycle(bytes),
        }
    }

    fn log(&mut self, node: usize, bytes: &[u8], rx_start: i64, rx_end: i64) {
        let Some((from, to)) = self.opts.log_cycles else {
            return;
        };
        let Ok(f) = Frame::new_checked(bytes) else {
            return;
        };
        let cycle = i64::from(f.cycle());
        if cycle < from || cycle >= to {
            return;
        }
        let p = f.payload();
        let frame = match f.kind_byte() {
            1 if p.len() >= 10 => {
                let first = usize::from(u16::from_le_bytes([p[8], p[9]]));
                FrameRef::Lumped((first / self.slots_per_frame) as u32)
            }
            2 if p.len() >= 2 => FrameRef::Command(u32::from(u16::from_le_bytes([p[0], p[1]]))),
            3 if p.len() >= 2 => FrameRef::Response(u32::from(u16::from_le_bytes([p[0], p[1]]))),
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
        let cycles = self.end / self.s.ring.cycle.0.as_ns();
        while let Some((t, ev)) = self.pop() {
            if t >= self.end {
                // Let the last cycle's probe pass; nothing after the end counts.
                if !matches!(ev, Ev::Probe { .. }) {
                    continue;
                }
            }
            self.counters.events += 1;
            match ev {
                Ev::Master { generation } if generation == self.master_gen => self.on_master(t),
                Ev::Master { .. } => {}
                Ev::Sample { slave, generation } if generation == self.gens[slave] => {
                    self.sample_at[slave] = None;
                    self.on_sample(slave, t)
                }
                Ev::Sample { .. } => {}
                Ev::Arrive {
                    node,
                    rx_start,
                    mut bytes,
                    corrupted,
                } => {
                    let _ = corrupted;
                    self.log(node, &bytes, rx_start, t);
                    if self.is_silent(node, t) {
                        continue;
                    }
                    if node == 0 {
                        self.master.handle_frame(Instant::from_ns(t), &bytes);
                        self.master.recycle(bytes);
                        self.drain_master(t);
                        self.schedule_master();
                    } else {
                        self.on_slave_frame(node - 1, rx_start, t, &mut bytes);
                    }
                }
                Ev::SlaveSend { slave, bytes } => self.send(slave + 1, t, bytes),
                Ev::Probe { k } => {
                    if k % 100 == 0 {
                        progress(k, cycles);
                    }
                    self.on_probe(k, t);
                }
            }
        }
    }

    fn on_master(&mut self, t: i64) {
        self.master.handle_timeout(Instant::from_ns(t));
        self.drain_master(t);
        self.schedule_master();
    }

    fn drain_master(&mut self, _t: i64) {
        while let Some(tx) = self.master.poll_transmit() {
            self.send(0, tx.at.as_ns(), tx.bytes);
        }
        while let Some(ev) = self.master.poll_event() {
            if let ringsync_proto::node::MasterEvent::GroupStop { .. } = ev {
                self.rec
                    .ring_break(locate_break_of(&self.master, &self.slaves));
            }
            self.rec.master_event(ev, self.master.record());
        }
    }

    /// Whether `node` (1-based slave) has gone silent by `t`: it neither forwards nor answers.
    fn is_silent(&self, node: usize, t: i64) -> bool {
        let f = &self.s.faults;
        f.silent_slave != 0 && node == f.silent_slave as usize && t >= f.silent_from.0.as_ns()
    }

    fn on_sample(&mut self, i: usize, t: i64) {
        self.axes[i].advance(t);
        let counts = self.axes[i].counts();
        let local = self.osc[i].local(t);
        self.slaves[i].handle_sample(local, counts);
        self.drain_slave(i, t);
        self.schedule_sample(i);
    }

    fn on_slave_frame(&mut self, i: usize, rx_start: i64, rx_end: i64, bytes: &mut Vec<u8>) {
        let (ls, le) = (self.osc[i].local(rx_start), self.osc[i].local(rx_end));
        let before = self.slaves[i].poll_timeout();
        match self.slaves[i].handle_frame(ls, le, bytes) {
            FrameOutcome::Forward => {
                let b = std::mem::take(bytes);
                self.send(i + 1, rx_start + self.residence, b);
            }
            FrameOutcome::Consumed | FrameOutcome::Dropped => {
                self.slaves[i].recycle(std::mem::take(bytes));
            }
        }
        self.drain_slave(i, rx_end);
        if self.slaves[i].poll_timeout() != before {
            self.schedule_sample(i);
        }
    }

    fn drain_slave(&mut self, i: usize, t: i64) {
        while let Some(ev) = self.slaves[i].poll_event() {
            let safe = self.slaves[i].config().safe_state;
            self.axes[i].take(ev, i, t, safe, &mut self.rec);
        }
        while let Some(tx) = self.slaves[i].poll_transmit() {
            let at = self.osc[i].true_at(tx.at);
            self.push(
                at,
                Ev::SlaveSend {
                    slave: i,
                    bytes: tx.bytes,
                },
            );
        }
    }

    fn on_probe(&mut self, k: i64, t: i64) {
        let next = t + self.s.ring.cycle.0.as_ns();
        if next < self.end {
            self.push(next, Ev::Probe { k: k + 1 });
        }
        let ts = t as f64 * 1e-9;
        let (axes, master, slaves, osc) = (&mut self.axes, &self.master, &self.slaves, &self.osc);
        self.rec.probe(k, |i| {
            axes[i].advance(t);
            let sync = slaves[i].clock().to_sync(osc[i].local(t));
            AxisProbe {
                x: axes[i].x,
                x_d: master.desired(i, ts).x,
                clock_error_ns: (sync.as_ns() - t) as f64,
                u: axes[i].u,
                saturated: slaves[i]
                    .status()
                    .contains(ringsync_wire::Status::SATURATED),
            }
        });
    }

    fn finish(self) -> RunResult {
        self.rec.finish(
            &self.s.name,
            self.master.counters(),
            self.slaves.iter().map(|s| s.counters()).collect(),
            self.counters,
            self.passages,
            self.captured,
        )
    }
}

#[cfg(test)]
mod tests;
