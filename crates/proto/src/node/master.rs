//! The master node of the proposed plan (SYSTEM.md section 2). Per cycle k, from its own
//! clock (the reference time):
//!
//! 1. at k·T_cyc it sends the sync lumped frame(s), stamped with the send time, slots empty;
//! 2. it takes the feedback of every slave from the returning frame(s);
//! 3. at the start of the P2P phase it runs the control law for all axes (the estimator gets
//!    D_jk from the sampling instants and the known command arrival times) and
//! 4. serves the slaves in order, one fixed time slice each: command out, response back. A
//!    slice without its response is retried in the ⌊n/4⌋ + 1 reserve slices.
//!
//! A lost lumped frame leaves the old samples in place (`fresh = false`), so the estimator
//! extrapolates them over a longer D. When any axis reports a fault or exceeds the
//! following-error limit, the master stops the whole group: every axis's desired motion
//! becomes a ramp to standstill, and commands carry the STOP flag.

use std::collections::VecDeque;

use ringsync_control::{
    AxisTrajectory, ControlInput, ControlLaw, ControlOutput, Controller, Feedback, State,
    Trajectory, VelocitySource,
};
use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Flags, Frame, FrameKind, LumpedOnlySlot, LumpedPayload,
    LumpedRepr, Pdu, SlotCodec, Status,
};

use super::Transmit;
use crate::plan::{CyclePlan, FrameRef, Node, PlanKind};
use crate::time::{Duration, Instant};

/// Everything the master knows about the ring and the motion.
#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// Cycle time T_cyc.
    pub cycle: Duration,
    /// Slots in each lumped frame of the train.
    pub lumped_slots: Vec<usize>,
    /// Send offset of each lumped frame from the cycle start.
    pub lumped_offsets: Vec<Duration>,
    /// Start of the P2P phase from the cycle start.
    pub p2p_start: Duration,
    /// Length of one time slice on the event-level ring path.
    pub slice: Duration,
    /// How long the master waits for a response beyond the slice before it gives up
    /// (jitter allowance plus timestamp and clock tolerance).
    pub guard: Duration,
    /// Wait after a response before the next command (keeps the inter-frame gap).
    pub turnaround: Duration,
    /// Number of reserve slices, ⌊n/4⌋ + 1.
    pub reserve_slices: u32,
    /// Arrival of axis i's command (last bit at its slave) from the cycle start, first try;
    /// with the lumped-only plan, the lumped frame's last bit at slave i.
    pub command_arrival: Vec<Duration>,
    /// Encoder resolution of each axis [rad per count].
    pub resolution: Vec<f64>,
    /// Following-error limit [rad].
    pub following_error_limit: f64,
    /// Deceleration of the group-stop ramp [rad/s²].
    pub stop_deceleration: f64,
    /// W: consecutive cycles without a response from an axis before the group stops.
    pub watchdog_cycles: u32,
    /// The communication plan. With the lumped-only plan the master only sends the lumped
    /// frame; the slaves run the law.
    pub plan: PlanKind,
}

impl MasterConfig {
    /// The schedule of the lumped-only plan on the ring of `plan` (a single lumped frame).
    pub fn lumped_only(plan: &CyclePlan, resolution: Vec<f64>, following_error_limit: f64) -> Self {
        let mut c =
            MasterConfig::from_plan(plan, Duration::ZERO, resolution, following_error_limit);
        let lo = &plan.lumped_only.lumped;
        c.plan = PlanKind::LumpedOnly;
        c.lumped_slots = lo.frame_slots.clone();
        c.lumped_offsets = (0..lo.frame_slots.len())
            .map(|j| lo.frame_offset(j, plan.link.gap()))
            .collect();
        c.command_arrival = plan.d_c.iter().map(|d| *d + lo.frame_time[0]).collect();
        c
    }

    /// The schedule of `plan`, with `jitter` allowed per hop when waiting for a response.
    pub fn from_plan(
        plan: &CyclePlan,
        jitter: Duration,
        resolution: Vec<f64>,
        following_error_limit: f64,
    ) -> Self {
        let n = plan.slaves() as i64;
        let tl = plan.timeline();
        let gap = plan.link.gap();
        // Axis i's command arrival: its first passage at slave i (one pass over the
        // timeline's O(n²) passages; a search per slave made the set-up O(n³)).
        let mut command_arrival = vec![None; plan.slaves() as usize];
        for p in &tl.passages {
            if let (FrameRef::Command(i), Node::Slave(j)) = (p.frame, p.node)
                && i == j
                && let Some(slot) = (i as usize)
                    .checked_sub(1)
                    .and_then(|k| command_arrival.get_mut(k))
                && slot.is_none()
            {
                *slot = Some(p.rx.map_or(Duration::ZERO, |rx| rx.end.since_origin()));
            }
        }
        let command_arrival = command_arrival
            .into_iter()
            .map(|a| a.unwrap_or(Duration::ZERO))
            .collect();
        MasterConfig {
            cycle: plan.params.t_cyc,
            lumped_slots: plan.lumped.frame_slots.clone(),
            lumped_offsets: (0..plan.lumped.frame_slots.len())
                .map(|j| plan.lumped.frame_offset(j, gap))
                .collect(),
            p2p_start: plan.event.p2p_start,
            slice: plan.event.slot[0],
            guard: jitter * (n + 1) + Duration::from_ns(200),
            turnaround: plan.event.turnaround,
            reserve_slices: plan.reserve_slices,
            command_arrival,
            resolution,
            following_error_limit,
            stop_deceleration: 200.0,
            watchdog_cycles: 5,
            plan: PlanKind::P2pLumped,
        }
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.command_arrival.len()
    }
}

/// Why the group stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StopReason {
    /// Axis `axis` (0-based) exceeded the following-error limit with error `error` [rad].
    FollowingError {
        /// Axis index.
        axis: usize,
        /// The error [rad].
        error: f64,
    },
    /// Axis `axis` reported a fault (e.g. its watchdog expired).
    AxisFault {
        /// Axis index.
        axis: usize,
    },
    /// Axis `axis` did not answer for W consecutive cycles.
    NoResponse {
        /// Axis index.
        axis: usize,
    },
    /// Axis `axis`'s newest feedback sample is more than W cycles old: the master can no
    /// longer control it (its command is 0 V from then on).
    NoFeedback {
        /// Axis index.
        axis: usize,
    },
}

/// Events for the driver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MasterEvent {
    /// The control law ran for cycle `k`; [`Master::record`] has the figures.
    Computed {
        /// Cycle index.
        k: i64,
    },
    /// The group stop began at `at` [master ns].
    GroupStop {
        /// When.
        at: Instant,
        /// Why.
        reason: StopReason,
    },
}

/// Counters that explain every lost cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MasterCounters {
    /// Frames sent (lumped and commands, retries included).
    pub frames_sent: u64,
    /// Lumped frames that did not return by the P2P start.
    pub lumped_lost: u64,
    /// Feedback samples missing from returned lumped frames (slot not written).
    pub samples_missing: u64,
    /// Feedback samples that were not newer than the last one taken from the same slave
    /// (the slave latched after the lumped frame passed it, so the frame carried the
    /// previous sample again); they are not taken again.
    pub samples_stale: u64,
    /// Slices that ended without their response.
    pub slices_failed: u64,
    /// Retries sent in reserve slices.
    pub retries: u64,
    /// Retries that got their response.
    pub retries_ok: u64,
    /// Commands never acknowledged in their cycle.
    pub commands_lost: u64,
    /// Frames dropped for a bad CRC or format.
    pub bad_frames: u64,
}

/// What the master computed in one cycle (for traces).
#[derive(Debug, Clone, PartialEq)]
pub struct CycleRecord {
    /// Cycle index k.
    pub k: i64,
    /// Sampling instant of each axis's latest sample [s, synchronised clock].
    pub sample_time: Vec<f64>,
    /// Measured position of each axis [rad].
    pub position: Vec<f64>,
    /// Whether the sample is from this cycle.
    pub fresh: Vec<bool>,
    /// Command sent to each axis [V].
    pub u: Vec<f64>,
    /// Whether it was clipped.
    pub saturated: Vec<bool>,
    /// Planned arrival of each command [s].
    pub apply_time: Vec<f64>,
}

#[derive(Debug, Clone, Copy)]
struct StopRamp {
    t0: f64,
    x0: f64,
    v0: f64,
    decel: f64,
}

impl StopRamp {
    fn at(&self, t: f64) -> State {
        let tau = (t - self.t0).max(0.0);
        let t_stop = self.v0.abs() / self.decel;
        let s = self.v0.signum();
        if tau >= t_stop {
            State {
                x: self.x0 + self.v0 * t_stop - 0.5 * s * self.decel * t_stop * t_stop,
                v: 0.0,
                a: 0.0,
            }
        } else {
            State {
                x: self.x0 + self.v0 * tau - 0.5 * s * self.decel * tau * tau,
                v: self.v0 - s * self.decel * tau,
                a: -s * self.decel,
            }
        }
    }
}

/// The master.
pub struct Master {
    cfg: MasterConfig,
    controller: Controller<Box<dyn ControlLaw>>,
    trajectories: Vec<AxisTrajectory>,
    stop: Option<Vec<StopRamp>>,
    /// A stop detected outside the law's run, taken at the next one.
    pending_stop: Option<StopReason>,
    /// Current cycle index; lumped frames sent so far in it; whether the law has run.
    k: i64,
    next_lumped: usize,
    computed: bool,
    /// Next slice to open (0..n+R), when to open it, and the open slice's deadline.
    next_slot: usize,
    open_at: Option<Instant>,
    deadline: Option<Instant>,
    /// Latest sample per axis and whether it arrived this cycle.
    latest: Vec<Option<FeedbackSlot>>,
    /// Last returned lumped-only slots (the lumped-only plan).
    lo_slots: Vec<LumpedOnlySlot>,
    /// Empty slots for the next lumped frame, kept to avoid an allocation per cycle.
    empty_slots: Vec<FeedbackSlot>,
    fresh: Vec<bool>,
    lumped_back: usize,
    /// Slice bookkeeping: target (0-based) of the open slice, its retry count.
    open: Option<(usize, u8)>,
    acked: Vec<bool>,
    missed: Vec<u32>,
    /// Axes whose feedback is more than W cycles old: commanded 0 V.
    blind: Vec<bool>,
    retry_queue: VecDeque<usize>,
    fb: Feedback,
    input: ControlInput,
    output: ControlOutput,
    record: CycleRecord,
    seq: u16,
    out: VecDeque<Transmit>,
    events: VecDeque<MasterEvent>,
    counters: MasterCounters,
    spares: super::Spares,
}

impl Master {
    /// A master for `law` with one trajectory per axis.
    pub fn new(
        cfg: MasterConfig,
        law: Box<dyn ControlLaw>,
        velocity: VelocitySource,
        trajectories: Vec<AxisTrajectory>,
    ) -> Self {
        let n = cfg.axes();
        let t_cyc = cfg.cycle.as_ns() as f64 * 1e-9;
        Master {
            controller: Controller::new(law, velocity),
            trajectories,
            stop: None,
            pending_stop: None,
            k: 0,
            next_lumped: 0,
            computed: false,
            next_slot: 0,
            open_at: None,
            deadline: None,
            latest: vec![None; n],
            lo_slots: vec![LumpedOnlySlot::default(); n],
            empty_slots: Vec::new(),
            fresh: vec![false; n],
            lumped_back: 0,
            open: None,
            acked: vec![false; n],
            missed: vec![0; n],
            blind: vec![false; n],
            retry_queue: VecDeque::new(),
            fb: Feedback::new(n),
            input: ControlInput::new(n, t_cyc),
            output: ControlOutput::new(n),
            record: CycleRecord {
                k: 0,
                sample_time: vec![0.0; n],
                position: vec![0.0; n],
                fresh: vec![false; n],
                u: vec![0.0; n],
                saturated: vec![false; n],
                apply_time: vec![0.0; n],
            },
            seq: 0,
            out: VecDeque::new(),
            events: VecDeque::new(),
            counters: MasterCounters::default(),
            spares: super::Spares::default(),
            cfg,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &MasterConfig {
        &self.cfg
    }
    /// Counters.
    pub fn counters(&self) -> MasterCounters {
        self.counters
    }
    /// The last cycle's figures.
    pub fn record(&self) -> &CycleRecord {
        &self.record
    }
    /// Whether the group is stopping.
    pub fn is_stopping(&self) -> bool {
        self.stop.is_some()
    }

    /// Whether the master is waiting for frames: a lumped frame of this cycle not back yet,
    /// or a time slice open. A driver may sleep less precisely when it is not.
    pub fn awaiting_frames(&self) -> bool {
        self.lumped_back < self.next_lumped || self.deadline.is_some()
    }

    /// The desired state of axis `i` at `t` [s] (the stop ramp once stopping).
    pub fn desired(&self, i: usize, t: f64) -> State {
        match &self.stop {
            Some(r) => r[i].at(t),
            None => self.trajectories[i].at(t),
        }
    }

    fn cycle_start(&self) -> Instant {
        Instant::from_ns(self.k * self.cfg.cycle.as_ns())
    }

    fn slots_total(&self) -> usize {
        self.cfg.axes() + self.cfg.reserve_slices as usize
    }

    /// When the master next needs [`Master::handle_timeout`] [master ns].
    pub fn poll_timeout(&self) -> Instant {
        let c = self.cycle_start();
        if self.next_lumped < self.cfg.lumped_offsets.len() {
            return c + self.cfg.lumped_offsets[self.next_lumped];
        }
        if self.cfg.plan == PlanKind::LumpedOnly {
            return c + self.cfg.cycle;
        }
        if !self.computed {
            return c + self.cfg.p2p_start;
        }
        match (self.open_at, self.deadline) {
            (Some(o), Some(d)) => o.min(d),
            (Some(o), None) => o,
            (None, Some(d)) => d,
            // P2P phase over: the next cycle starts.
            (None, None) => c + self.cfg.cycle,
        }
    }

    /// Runs what is due at `now` (the time [`Master::poll_timeout`] gave).
    pub fn handle_timeout(&mut self, now: Instant) {
        let c = self.cycle_start();
        if self.next_lumped < self.cfg.lumped_offsets.len() {
            if self.cfg.plan == PlanKind::LumpedOnly {
                self.send_lumped_only(now);
            } else {
                self.send_lumped(now);
            }
            self.next_lumped += 1;
            return;
        }
        if self.cfg.plan == PlanKind::LumpedOnly {
            if now >= c + self.cfg.cycle {
                if self.lumped_back < self.cfg.lumped_offsets.len() {
                    self.counters.lumped_lost +=
                        (self.cfg.lumped_offsets.len() - self.lumped_back) as u64;
                }
                self.k += 1;
                self.next_lumped = 0;
                self.lumped_back = 0;
                self.fresh.fill(false);
            }
            return;
        }
        if !self.computed {
            self.compute(now);
            self.computed = true;
            self.open_at = Some(now);
        }
        if self.deadline.is_some_and(|d| now >= d) {
            self.close_slice();
            self.open_at = Some(now);
        }
        if self.open_at.is_some_and(|o| now >= o) {
            self.open_at = None;
            self.open_next(now);
        }
        if self.open_at.is_none() && self.deadline.is_none() && now >= c + self.cfg.cycle {
            self.end_cycle();
        }
    }

    /// Opens the next slice that has work, if any fits before the next cycle.
    fn open_next(&mut self, now: Instant) {
        let next_cycle = self.cycle_start() + self.cfg.cycle;
        while self.next_slot < self.slots_total() {
            let s = self.next_slot;
            self.next_slot += 1;
            if now + self.cfg.slice + self.cfg.guard > next_cycle {
                break;
            }
            if self.open_slice(s, now) {
                self.deadline = Some(now + self.cfg.slice + self.cfg.guard);
                return;
            }
        }
        self.deadline = None;
    }

    fn end_cycle(&mut self) {
        // Commands never acknowledged in their cycle are lost.
        self.counters.commands_lost += self.acked.iter().filter(|a| !**a).count() as u64;
        for (m, a) in self.missed.iter_mut().zip(&self.acked) {
            *m = if *a { 0 } else { *m + 1 };
        }
        if let Some(axis) = self
            .missed
            .iter()
            .position(|m| *m >= self.cfg.watchdog_cycles)
        {
            self.pending_stop
                .get_or_insert(StopReason::NoResponse { axis });
        }
        self.retry_queue.clear();
        self.k += 1;
        self.next_lumped = 0;
        self.computed = false;
        self.next_slot = 0;
        self.open_at = None;
        self.deadline = None;
        self.lumped_back = 0;
        self.fresh.fill(false);
        self.acked.fill(false);
    }

    fn send_lumped(&mut self, now: Instant) {
        let j = self.next_lumped;
        let first: usize = self.cfg.lumped_slots[..j].iter().sum();
        // Empty slots, reused from cycle to cycle.
        let mut slots = std::mem::take(&mut self.empty_slots);
        slots.clear();
        slots.resize(self.cfg.lumped_slots[j], FeedbackSlot::default());
        self.empty_slots = self.queue_lumped(now, first, slots);
    }

    /// Sends a lumped frame of either layout, stamped with `now`, and gives the slots back.
    fn queue_lumped<S: SlotCodec>(&mut self, now: Instant, first: usize, slots: Vec<S>) -> Vec<S> {
        self.seq = self.seq.wrapping_add(1);
        let repr = LumpedRepr {
            common: Common {
                cycle: self.k as u32,
                seq: self.seq,
                ..Common::default()
            },
            master_time_ns: now.as_ns().max(0) as u64,
            first_slot: first as u16,
            slots,
        };
        let mut buf = self.spares.take(repr.buffer_len());
        if repr.emit(&mut buf).is_ok() {
            self.out.push_back(Transmit {
                at: now,
                bytes: buf,
            });
            self.counters.frames_sent += 1;
        }
        repr.slots
    }

    /// The lumped-only plan's frame: last cycle's returned slots (not written this cycle),
    /// with the desired state at this cycle's sampling instant for monitoring.
    fn send_lumped_only(&mut self, now: Instant) {
        let j = self.next_lumped;
        let first: usize = self.cfg.lumped_slots[..j].iter().sum();
        let t = self.cycle_start().as_ns() as f64 * 1e-9;
        let slots: Vec<LumpedOnlySlot> = (first..first + self.cfg.lumped_slots[j])
            .map(|i| {
                let d = self.desired(i, t);
                let res = self.cfg.resolution[i];
                let mut s = self.lo_slots[i];
                s.feedback.written = false;
                s.desired_position = (d.x / res)
                    .round()
                    .clamp(f64::from(i32::MIN), f64::from(i32::MAX))
                    as i32;
                s.desired_velocity = (d.v / res)
                    .round()
                    .clamp(f64::from(i32::MIN), f64::from(i32::MAX))
                    as i32;
                s
            })
            .collect();
        self.queue_lumped(now, first, slots);
    }

    fn compute(&mut self, now: Instant) {
        let n = self.cfg.axes();
        if self.lumped_back < self.cfg.lumped_offsets.len() {
            self.counters.lumped_lost += (self.cfg.lumped_offsets.len() - self.lumped_back) as u64;
        }
        let t_start = self.cycle_start().as_ns() as f64 * 1e-9;
        let mut stop_reason = self.pending_stop.take();
        for i in 0..n {
            let res = self.cfg.resolution[i];
            match self.latest[i] {
                Some(s) => {
                    let ts = s.sample_time_ns as f64 * 1e-9;
                    self.fb.position[i] = f64::from(s.position) * res;
                    self.fb.velocity[i] = f64::from(s.velocity) * res;
                    self.fb.sample_time[i] = ts;
                    self.fb.desired[i] = self.desired(i, ts);
                    self.fb.fresh[i] = self.fresh[i];
                    if s.status.contains(Status::FAULT) && stop_reason.is_none() {
                        stop_reason = Some(StopReason::AxisFault { axis: i });
                    }
                }
                None => {
                    self.fb.position[i] = 0.0;
                    self.fb.velocity[i] = 0.0;
                    self.fb.sample_time[i] = t_start;
                    self.fb.desired[i] = self.desired(i, t_start);
                    self.fb.fresh[i] = false;
                }
            }
            let e = self.fb.desired[i].x - self.fb.position[i];
            if self.latest[i].is_some()
                && e.abs() > self.cfg.following_error_limit
                && stop_reason.is_none()
            {
                stop_reason = Some(StopReason::FollowingError { axis: i, error: e });
            }
            // Feedback watchdog: a law run on a sample W cycles old drives the axis blind
            // (with the ring broken behind it, the error it sees never closes and the
            // command winds up to saturation).
            let w = i64::from(self.cfg.watchdog_cycles);
            self.blind[i] = match self.latest[i] {
                Some(_) => {
                    t_start - self.fb.sample_time[i]
                        > w as f64 * self.cfg.cycle.as_ns() as f64 * 1e-9
                }
                None => self.k >= w,
            };
            if self.blind[i] && stop_reason.is_none() && self.stop.is_none() {
                stop_reason = Some(StopReason::NoFeedback { axis: i });
            }
        }
        if let (Some(reason), None) = (stop_reason, &self.stop) {
            let t = now.as_ns() as f64 * 1e-9;
            let decel = self.cfg.stop_deceleration;
            self.stop = Some(
                (0..n)
                    .map(|i| {
                        let d = self.trajectories[i].at(t);
                        StopRamp {
                            t0: t,
                            x0: d.x,
                            v0: d.v,
                            decel,
                        }
                    })
                    .collect(),
            );
            self.events
                .push_back(MasterEvent::GroupStop { at: now, reason });
            for i in 0..n {
                self.fb.desired[i] = self.desired(i, self.fb.sample_time[i]);
            }
        }
        for i in 0..n {
            let a = t_start + self.cfg.command_arrival[i].as_ns() as f64 * 1e-9;
            self.input.apply_time[i] = a;
            self.input.desired[i] = self.desired(i, a);
        }
        if self
            .controller
            .update(&self.fb, &self.input, &mut self.output)
            .is_err()
        {
            // Lengths are fixed at construction; an error here is a bug. Command 0 V.
            self.output.u.fill(0.0);
        }
        for (i, blind) in self.blind.iter().enumerate() {
            if *blind {
                self.output.u[i] = 0.0;
                self.output.saturated[i] = false;
            }
        }
        let r = &mut self.record;
        r.k = self.k;
        r.sample_time.copy_from_slice(&self.fb.sample_time);
        r.position.copy_from_slice(&self.fb.position);
        r.fresh.copy_from_slice(&self.fb.fresh);
        r.u.copy_from_slice(&self.output.u);
        r.saturated.copy_from_slice(&self.output.saturated);
        r.apply_time.copy_from_slice(&self.input.apply_time);
        self.events.push_back(MasterEvent::Computed { k: self.k });
    }

    /// Sends slice `s`'s command; false when a reserve slice has nothing to retry.
    fn open_slice(&mut self, s: usize, now: Instant) -> bool {
        let n = self.cfg.axes();
        let (target, retry) = if s < n {
            (s, 0u8)
        } else {
            match self.retry_queue.pop_front() {
                Some(t) => {
                    self.counters.retries += 1;
                    (t, 1u8)
                }
                None => {
                    self.open = None;
                    return false;
                }
            }
        };
        self.open = Some((target, retry));
        self.seq = self.seq.wrapping_add(1);
        let flags = if self.stop.is_some() {
            Flags::STOP
        } else {
            Flags::empty()
        };
        let cmd = CommandRepr {
            common: Common {
                flags,
                retry,
                cycle: self.k as u32,
                seq: self.seq,
            },
            target: (target + 1) as u16,
            command_v: self.output.u[target] as f32,
            sample_time_ns: (self.fb.sample_time[target] * 1e9).round().max(0.0) as u64,
        };
        let mut buf = self.spares.take(cmd.buffer_len());
        if cmd.emit(&mut buf).is_ok() {
            self.out.push_back(Transmit {
                at: now,
                bytes: buf,
            });
            self.counters.frames_sent += 1;
        }
        true
    }

    fn close_slice(&mut self) {
        if let Some((target, retry)) = self.open.take() {
            if self.acked[target] {
                if retry > 0 {
                    self.counters.retries_ok += 1;
                }
            } else {
                self.counters.slices_failed += 1;
                if retry == 0 {
                    self.retry_queue.push_back(target);
                }
            }
        }
    }

    /// A frame received completely at `now` [master ns].
    pub fn handle_frame(&mut self, now: Instant, bytes: &[u8]) {
        // The proposed plan's lumped frame comes back every cycle: read its slots in place
        // (no allocation); everything else through the owned representations.
        if let Ok(f) = Frame::new_checked(bytes)
            && f.kind_byte() == FrameKind::Lumped as u8
        {
            match f.check() {
                Ok(_) => self.take_lumped(&f),
                Err(_) => self.counters.bad_frames += 1,
            }
            return;
        }
        match Pdu::parse(bytes) {
            Ok(Pdu::Lumped(_)) => {}
            Ok(Pdu::Response(r)) => {
                let i = usize::from(r.source).wrapping_sub(1);
                if i64::from(r.echo_cycle) == self.k & 0xFFFF_FFFF && i < self.acked.len() {
                    if let Some((target, _)) = self.open
                        && target == i
                        && self.deadline.is_some()
                    {
                        // The slice ends when the master has the response (eq. 2).
                        self.acked[i] = true;
                        self.close_slice();
                        self.deadline = None;
                        self.open_at = Some(now + self.cfg.turnaround);
                    }
                    if r.status.contains(Status::FAULT)
                        && let Some(s) = self.latest[i].as_mut()
                    {
                        s.status = s.status.with(Status::FAULT);
                    }
                }
            }
            Ok(Pdu::LumpedOnly(l)) => {
                if i64::from(l.common.cycle) != self.k & 0xFFFF_FFFF {
                    return;
                }
                self.lumped_back += 1;
                let r = &mut self.record;
                r.k = self.k;
                for (k, slot) in l.slots.iter().enumerate() {
                    let i = usize::from(l.first_slot) + k;
                    if i >= self.lo_slots.len() {
                        continue;
                    }
                    self.lo_slots[i] = *slot;
                    let f = slot.feedback;
                    if !f.written {
                        self.counters.samples_missing += 1;
                    }
                    r.fresh[i] = f.written;
                    r.position[i] = f64::from(f.position) * self.cfg.resolution[i];
                    r.sample_time[i] = f.sample_time_ns as f64 * 1e-9;
                    r.u[i] = f64::from(slot.command_v);
                    r.saturated[i] = f.status.contains(Status::SATURATED);
                    r.apply_time[i] = r.sample_time[i];
                }
                if self.lumped_back == self.cfg.lumped_offsets.len() {
                    self.events.push_back(MasterEvent::Computed { k: self.k });
                }
            }
            Ok(Pdu::Command(_)) => {}
            Err(_) => self.counters.bad_frames += 1,
        }
    }

    /// A returned lumped frame (CRC checked): the feedback of every slave that wrote its slot.
    fn take_lumped(&mut self, f: &Frame<&[u8]>) {
        if i64::from(f.cycle()) != self.k & 0xFFFF_FFFF {
            return; // a late frame of an older cycle
        }
        let Ok(p) = LumpedPayload::new_checked(f.payload(), FrameKind::Lumped) else {
            self.counters.bad_frames += 1;
            return;
        };
        self.lumped_back += 1;
        let first = usize::from(p.first_slot());
        for k in 0..usize::from(p.slot_count()) {
            let i = first + k;
            if i >= self.latest.len() {
                break;
            }
            match p.slot_bytes(k).map(FeedbackSlot::parse) {
                Some(Ok(slot)) if slot.written => {
                    if self.latest[i].is_some_and(|l| slot.sample_time_ns <= l.sample_time_ns) {
                        self.counters.samples_stale += 1;
                    } else {
                        self.latest[i] = Some(slot);
                        self.fresh[i] = true;
                    }
                }
                Some(Ok(_)) => self.counters.samples_missing += 1,
                _ => self.counters.bad_frames += 1,
            }
        }
    }

    /// Hands back the buffer of a frame the driver is done with (sent, or received and
    /// handled), for the master's next sends. Optional: without it the master allocates.
    pub fn recycle(&mut self, buf: Vec<u8>) {
        self.spares.give(buf);
    }

    /// The next frame to send.
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        self.out.pop_front()
    }

    /// The next event.
    pub fn poll_event(&mut self) -> Option<MasterEvent> {
        self.events.pop_front()
    }
}
