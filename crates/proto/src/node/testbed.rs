//! A ring driven by hand: a [`Master`] and n [`Slave`]s on ideal links, a simple axis per
//! slave, and a clock the caller owns. For the nodes' own tests, the state-machine fuzz
//! targets and examples: what the nodes decide, without the simulator's link model.
//!
//! Every hop takes the same fixed delay; a slave forwards at once; slave i's clock reads
//! true time plus its own fixed offset (no drift). Each axis is a double integrator,
//! ẍ = gain·u, stepped exactly between events. A [`Tap`] sees every frame as it is about
//! to reach a node and decides its fate (deliver, drop, duplicate, delay); [`Testbed::inject`]
//! puts any bytes on the wire in front of any node. [`seal`] rewrites a frame's CRC after an
//! edit, so a test can forge a frame the wire layer accepts.
//!
//! ```
//! use ringsync_proto::node::testbed::{Testbed, TestbedConfig};
//! let mut ring = Testbed::new(TestbedConfig::default());
//! ring.run_until(200_000_000); // 200 cycles of 1 ms
//! assert_eq!(ring.master.counters().rejected.total(), 0);
//! assert!(!ring.master.is_stopping());
//! ```

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use ringsync_wire::{Frame, Status};

use super::motion::{Motion, MotionInput, MotionOutput, Setpoint};
use super::{
    FrameOutcome, Master, MasterConfig, MasterEvent, SafeState, Slave, SlaveConfig, SlaveEvent,
    StopReason,
};
use crate::plan::{CyclePlan, RingParams};
use crate::time::{Duration, Instant};

/// How to build a [`Testbed`].
#[derive(Debug, Clone, PartialEq)]
pub struct TestbedConfig {
    /// Number of slaves n.
    pub slaves: u32,
    /// Delay of every hop, first bit out to the whole frame in \[ns\].
    pub hop_ns: i64,
    /// Slave i's clock reads true time plus `clock_offsets_ns[i - 1]` \[ns\] (0 if missing).
    pub clock_offsets_ns: Vec<i64>,
    /// Each axis: ẍ = gain·u [rad/s² per V] (the reference axes' K_a/J ≈ 64).
    pub axis_gain: f64,
    /// W, for the master and the slaves.
    pub watchdog_cycles: u32,
    /// The slaves' reaction to losing the master.
    pub safe_state: SafeState,
    /// Following-error limit \[rad\].
    pub following_error_limit: f64,
    /// Peak speed of the cosine every axis follows [rad/s] (period 2 s).
    pub peak_speed: f64,
}

impl Default for TestbedConfig {
    /// 4 slaves, 1 µs hops, clocks 3-12 µs off, PD on the reference gains, a cosine of
    /// 15.12 rad/s peak speed, W = 5, brake, limit 1 rad.
    fn default() -> Self {
        TestbedConfig {
            slaves: 4,
            hop_ns: 1_000,
            clock_offsets_ns: vec![3_000, -7_000, 12_000, -4_000],
            axis_gain: 64.0,
            watchdog_cycles: 5,
            safe_state: SafeState::Brake,
            following_error_limit: 1.0,
            peak_speed: 15.12,
        }
    }
}

/// One axis of the testbed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    /// Position \[rad\].
    pub x: f64,
    /// Velocity [rad/s].
    pub v: f64,
    /// Command held \[V\].
    pub u: f64,
    /// Torque off (the command no longer acts).
    pub off: bool,
    /// True time of the state \[ns\].
    pub t: i64,
}

/// Encoder resolution of the testbed's axes [rad per count]: 2^20 counts per revolution.
pub const RESOLUTION: f64 = std::f64::consts::TAU / 1_048_576.0;

/// A minimal motion for the protocol's tests: PD on a cosine per axis (peak speed
/// `peak_speed`, period 2 s; K_P 3.182 V/rad, K_D 1.591 V·s/rad on the reported velocity,
/// ±10 V). It stops on whatever the protocol raises, on a slave's fault, on a following
/// error and on a blind axis; once stopped it holds every axis where the stop found it,
/// and commands 0 V to a blind axis. It gives no per-axis orders: the full group stop (ramps,
/// brake and torque-off orders) is `ringsync-model`'s `ControlMotion`.
#[derive(Debug, Clone)]
pub struct PdMotion {
    axes: usize,
    amplitude: f64,
    omega: f64,
    limit: f64,
    resolution: f64,
    hold: Option<Vec<f64>>,
}

impl PdMotion {
    /// The motion of `n` axes.
    pub fn new(n: usize, peak_speed: f64, following_error_limit: f64, resolution: f64) -> Self {
        let period = 2.0;
        let omega = std::f64::consts::TAU / period;
        PdMotion {
            axes: n,
            amplitude: peak_speed / omega,
            omega,
            limit: following_error_limit,
            resolution,
            hold: None,
        }
    }
}

impl Motion for PdMotion {
    fn axes(&self) -> usize {
        self.axes
    }

    fn compute(&mut self, input: &MotionInput<'_>, out: &mut MotionOutput) {
        out.stop = None;
        out.orders.clear();
        let n = input.samples.len();
        let t_start = input.cycle_start.as_ns() as f64 * 1e-9;
        let mut stop = input.pending;
        let mut feedback = vec![(0.0, 0.0, t_start); n];
        for (i, fb) in feedback.iter_mut().enumerate() {
            if let Some(s) = input.samples[i] {
                let (x, v) = (
                    f64::from(s.position) * self.resolution,
                    f64::from(s.velocity) * self.resolution,
                );
                let ts = s.sample_time_ns as f64 * 1e-9;
                *fb = (x, v, ts);
                if s.status.contains(Status::FAULT) {
                    stop = stop.or(Some(StopReason::AxisFault { axis: i }));
                }
                let error = self.desired(i, ts).x - x;
                if error.abs() > self.limit {
                    stop = stop.or(Some(StopReason::FollowingError { axis: i, error }));
                }
            }
            if input.blind[i] && self.hold.is_none() {
                stop = stop.or(Some(StopReason::NoFeedback { axis: i }));
            }
        }
        if let (Some(reason), None) = (stop, &self.hold) {
            self.hold = Some(feedback.iter().map(|f| f.0).collect());
            out.stop = Some(reason);
        }
        let r = &mut out.record;
        r.k = input.k;
        for (i, &(x, v, ts)) in feedback.iter().enumerate() {
            let d = self.desired(i, ts);
            let u = if input.blind[i] || !input.commanded {
                0.0
            } else {
                3.182 * (d.x - x) + 1.591 * (d.v - v)
            };
            let clipped = u.clamp(-10.0, 10.0);
            out.u[i] = clipped;
            out.saturated[i] = clipped != u;
            r.sample_time[i] = ts;
            r.position[i] = x;
            r.fresh[i] = input.fresh[i];
            r.u[i] = clipped;
            r.saturated[i] = clipped != u;
            r.apply_time[i] = t_start + input.command_arrival[i].as_ns() as f64 * 1e-9;
        }
    }

    fn is_stopping(&self) -> bool {
        self.hold.is_some()
    }

    fn desired(&self, axis: usize, t: f64) -> Setpoint {
        match &self.hold {
            Some(x) => Setpoint {
                x: x.get(axis).copied().unwrap_or(0.0),
                v: 0.0,
            },
            None => Setpoint {
                x: self.amplitude * (1.0 - (self.omega * t).cos()),
                v: self.amplitude * self.omega * (self.omega * t).sin(),
            },
        }
    }
}

/// A frame about to reach node `to` (0 = the master, i = slave i) at true time `at` \[ns\].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hop {
    /// Sender (0 = master).
    pub from: usize,
    /// Receiver (0 = master).
    pub to: usize,
    /// Arrival [ns, true time].
    pub at: i64,
}

/// What becomes of a frame at a [`Tap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    /// It arrives (possibly edited by the tap).
    Deliver,
    /// It is lost.
    Drop,
    /// It arrives twice, the copy `after` ns later.
    Duplicate {
        /// Delay of the copy \[ns\].
        after: i64,
    },
    /// It arrives `by` ns late.
    Delay {
        /// The extra delay \[ns\].
        by: i64,
    },
}

/// Sees every frame before it reaches a node; may edit it (then [`seal`] it) and decides
/// its fate.
pub type Tap = Box<dyn FnMut(&Hop, &mut Vec<u8>) -> Fate>;

/// Rewrites the CRC of the PDU in `bytes` after an edit (no-op if the header is unreadable).
pub fn seal(bytes: &mut [u8]) {
    if let Ok(mut f) = Frame::new_checked(bytes) {
        f.fill_crc();
    }
}

/// A frame on the wire: it reaches `to` at `at`.
#[derive(Debug)]
struct InFlight {
    from: usize,
    to: usize,
    bytes: Vec<u8>,
    tapped: bool,
}

/// The ring.
pub struct Testbed {
    /// The master.
    pub master: Master,
    /// Slave i at index i − 1.
    pub slaves: Vec<Slave>,
    /// Axis i at index i − 1.
    pub axes: Vec<Axis>,
    /// What the master reported, with the true time \[ns\].
    pub master_events: Vec<(i64, MasterEvent)>,
    /// What each slave reported, with the true time \[ns\] and the slave (1-based).
    pub slave_events: Vec<(i64, usize, SlaveEvent)>,
    /// Every command a slave applied: (true time \[ns\], slave 1-based, command \[V\]).
    pub applied: Vec<(i64, usize, f64)>,
    /// Sees every frame (None: all delivered).
    pub tap: Option<Tap>,
    /// Nodes that neither forward nor answer nor sample (a dead node); index 0 is the master.
    pub dead: Vec<bool>,
    /// Each axis: ẍ = gain·u [rad/s² per V] (a test may change one mid-run: a seized axis).
    pub gains: Vec<f64>,
    now: i64,
    hop: i64,
    offsets: Vec<i64>,
    resolution: f64,
    queue: BinaryHeap<Reverse<(i64, u64)>>,
    flights: std::collections::HashMap<u64, InFlight>,
    seq: u64,
}

impl Testbed {
    /// A ring at rest at time 0 whose master runs the minimal [`PdMotion`].
    ///
    /// # Panics
    /// If the ring cannot be planned (no slaves, or more than a 1 ms cycle holds).
    pub fn new(c: TestbedConfig) -> Self {
        let motion = PdMotion::new(
            c.slaves as usize,
            c.peak_speed,
            c.following_error_limit,
            RESOLUTION,
        );
        Testbed::with_motion(c, Box::new(motion))
    }

    /// A ring at rest at time 0 whose master runs `motion` (with `c.slaves` axes; the
    /// encoders have 2^20 counts per revolution: [`RESOLUTION`]).
    ///
    /// # Panics
    /// If the ring cannot be planned (no slaves, or more than a 1 ms cycle holds).
    pub fn with_motion(c: TestbedConfig, motion: Box<dyn Motion>) -> Self {
        let n = c.slaves as usize;
        let plan = CyclePlan::new(&RingParams {
            slaves: c.slaves,
            ..RingParams::default()
        })
        .unwrap_or_else(|e| panic!("testbed ring of {n} slaves: {e}"));
        let resolution = RESOLUTION;
        let mut cfg = MasterConfig::from_plan(&plan, Duration::ZERO, vec![resolution; n]);
        cfg.watchdog_cycles = c.watchdog_cycles;
        let master = Master::new(cfg, motion);
        let t_cyc = plan.params.t_cyc;
        let p2p_start = master.config().p2p_start;
        let slaves = (1..=n)
            .map(|i| {
                Slave::new(SlaveConfig {
                    p2p_start,
                    watchdog_cycles: c.watchdog_cycles,
                    resolution,
                    safe_state: c.safe_state,
                    ..SlaveConfig::new(i as u16, t_cyc, Duration::from_ns(c.hop_ns * i as i64))
                })
            })
            .collect();
        let zero = Axis {
            x: 0.0,
            v: 0.0,
            u: 0.0,
            off: false,
            t: 0,
        };
        Testbed {
            master,
            slaves,
            axes: vec![zero; n],
            master_events: Vec::new(),
            slave_events: Vec::new(),
            applied: Vec::new(),
            tap: None,
            dead: vec![false; n + 1],
            gains: vec![c.axis_gain; n],
            now: 0,
            hop: c.hop_ns,
            offsets: (0..n)
                .map(|i| c.clock_offsets_ns.get(i).copied().unwrap_or(0))
                .collect(),
            resolution,
            queue: BinaryHeap::new(),
            flights: std::collections::HashMap::new(),
            seq: 0,
        }
    }

    /// True time now \[ns\].
    pub fn now(&self) -> i64 {
        self.now
    }

    /// Slave i's (1-based) local clock at true time `t` \[ns\].
    pub fn local(&self, i: usize, t: i64) -> Instant {
        Instant::from_ns(t + self.offsets[i - 1])
    }

    /// The desired position of axis i (1-based) at true time `t` \[ns\], as the master has it.
    pub fn desired(&self, i: usize, t: i64) -> f64 {
        self.master.desired(i - 1, t as f64 * 1e-9).x
    }

    /// Puts `bytes` on the wire so that they reach node `to` (0 = master) at true time `at`
    /// (not before now). The tap does not see them.
    pub fn inject(&mut self, to: usize, at: i64, bytes: Vec<u8>) {
        self.push(
            at.max(self.now),
            InFlight {
                from: usize::MAX,
                to,
                bytes,
                tapped: true,
            },
        );
    }

    fn push(&mut self, at: i64, f: InFlight) {
        self.seq += 1;
        self.queue.push(Reverse((at, self.seq)));
        self.flights.insert(self.seq, f);
    }

    /// Sends `bytes` from node `from` at true time `t`: it reaches the next node a hop later.
    fn send(&mut self, from: usize, t: i64, bytes: Vec<u8>) {
        let to = (from + 1) % (self.slaves.len() + 1);
        self.push(
            t + self.hop,
            InFlight {
                from,
                to,
                bytes,
                tapped: false,
            },
        );
    }

    fn advance_axis(&mut self, i: usize, t: i64) {
        let gain = self.gains[i];
        let a = &mut self.axes[i];
        if t > a.t {
            let dt = (t - a.t) as f64 * 1e-9;
            let acc = if a.off { 0.0 } else { gain * a.u };
            a.x += a.v * dt + 0.5 * acc * dt * dt;
            a.v += acc * dt;
            a.t = t;
        }
    }

    /// The next event's true time and kind: 0 a slave latch (slave index), 1 a frame, 2 the
    /// master. Latches come first at equal times (as in hardware), the master last.
    fn next(&self) -> Option<(i64, u8, usize)> {
        let mut best: Option<(i64, u8, usize)> = None;
        let mut consider = |c: (i64, u8, usize)| {
            if best.is_none_or(|b| (c.0, c.1) < (b.0, b.1)) {
                best = Some(c);
            }
        };
        for (i, s) in self.slaves.iter().enumerate() {
            if !self.dead[i + 1] {
                consider((s.poll_timeout().as_ns() - self.offsets[i], 0, i));
            }
        }
        if let Some(Reverse((t, _))) = self.queue.peek() {
            consider((*t, 1, 0));
        }
        if !self.dead[0] {
            consider((self.master.poll_timeout().as_ns(), 2, 0));
        }
        best
    }

    /// Runs every event due up to true time `t` \[ns\].
    pub fn run_until(&mut self, t: i64) {
        while let Some((at, kind, i)) = self.next() {
            if at > t {
                break;
            }
            self.now = self.now.max(at);
            match kind {
                0 => {
                    self.advance_axis(i, at);
                    let counts = (self.axes[i].x / self.resolution).round() as i64;
                    let local = self.local(i + 1, at);
                    self.slaves[i].handle_sample(local, counts);
                    self.drain_slave(i);
                }
                1 => self.deliver(),
                _ => {
                    self.master.handle_timeout(Instant::from_ns(at));
                    self.drain_master();
                }
            }
        }
        self.now = self.now.max(t);
        for i in 0..self.axes.len() {
            self.advance_axis(i, t);
        }
    }

    fn deliver(&mut self) {
        let Some(Reverse((at, id))) = self.queue.pop() else {
            return;
        };
        let Some(mut f) = self.flights.remove(&id) else {
            return;
        };
        if !f.tapped
            && let Some(tap) = self.tap.as_mut()
        {
            let hop = Hop {
                from: f.from,
                to: f.to,
                at,
            };
            match tap(&hop, &mut f.bytes) {
                Fate::Deliver => {}
                Fate::Drop => return,
                Fate::Duplicate { after } => {
                    let copy = InFlight {
                        from: f.from,
                        to: f.to,
                        bytes: f.bytes.clone(),
                        tapped: true,
                    };
                    self.push(at + after.max(0), copy);
                }
                Fate::Delay { by } => {
                    f.tapped = true;
                    self.push(at + by.max(0), f);
                    return;
                }
            }
        }
        if self.dead[f.to] {
            return;
        }
        if f.to == 0 {
            self.master.handle_frame(Instant::from_ns(at), &f.bytes);
            self.drain_master();
            return;
        }
        let i = f.to - 1;
        self.advance_axis(i, at);
        let local = self.local(f.to, at);
        let outcome = self.slaves[i].handle_frame(local, local, &mut f.bytes);
        if outcome == FrameOutcome::Forward {
            self.send(f.to, at, f.bytes);
        }
        self.drain_slave(i);
    }

    fn drain_master(&mut self) {
        while let Some(tx) = self.master.poll_transmit() {
            self.send(0, tx.at.as_ns(), tx.bytes);
        }
        while let Some(ev) = self.master.poll_event() {
            self.master_events.push((self.now, ev));
        }
    }

    fn drain_slave(&mut self, i: usize) {
        while let Some(ev) = self.slaves[i].poll_event() {
            let a = &mut self.axes[i];
            match ev {
                SlaveEvent::Apply { u } => {
                    a.u = u;
                    self.applied.push((self.now, i + 1, u));
                }
                SlaveEvent::Brake { u } => a.u = u,
                SlaveEvent::TorqueOff { .. } | SlaveEvent::WatchdogExpired => a.u = 0.0,
                SlaveEvent::Relocked { .. }
                | SlaveEvent::Braking { .. }
                | SlaveEvent::Calibrated { .. } => {}
            }
            if let SlaveEvent::TorqueOff { .. } = ev {
                a.off = true;
            }
            self.slave_events.push((self.now, i + 1, ev));
        }
        while let Some(tx) = self.slaves[i].poll_transmit() {
            let t = tx.at.as_ns() - self.offsets[i];
            self.send(i + 1, t, tx.bytes);
        }
    }

    /// The largest |x^d − x| over the axes now \[rad\].
    pub fn worst_error(&self) -> f64 {
        let t = self.now as f64 * 1e-9;
        (0..self.axes.len())
            .map(|i| (self.master.desired(i, t).x - self.axes[i].x).abs())
            .fold(0.0, f64::max)
    }
}
