//! The master node of the proposed plan (docs/system.md, "The cycle plan"). Per cycle k, from its own
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
//! extrapolates them over a longer D. One that comes back after the law ran (late) brings
//! samples the next law run takes as new.
//!
//! # Frame acceptance
//! Nothing from the wire is trusted ([`super::reject`]). A returning lumped frame is taken
//! only if it is one the master sent in this cycle (its cycle, sequence number, send stamp
//! and slot layout echo what went out) and has not come back before; each feedback slot in
//! it only if its sampling instant is not in the future by the master's clock
//! (`timestamp_tolerance`) and is newer than the last sample taken from that slave. A
//! response is taken only if it answers the slice that is open (its source, cycle, echo
//! and retry count). Refused frames change nothing and are counted per reason.
//!
//! # Supervision and the group stop
//! An axis whose accepted samples stop advancing for W cycles (the feedback watchdog:
//! counted in the master's own cycles, whatever timestamps a frame claims), that does not
//! answer for W cycles, that reports a fault, or whose error exceeds the following-error
//! limit stops the whole group. Like a drive's quick stop, every axis's desired motion
//! becomes a ramp to standstill from where the axis is (its measured position and
//! velocity), and commands carry the STOP flag. An axis that cannot follow its ramp within
//! the following-error limit, or has no feedback, gets torque off (the `TORQUE_OFF` flag);
//! every other axis gets torque off once its ramp has ended and it has held still for
//! `stop_hold`, and in any case `stop_timeout` after the stop began.

use crate::node::link::LinkEstimate;
use std::collections::VecDeque;

use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Flags, Frame, FrameKind, LumpedOnlySlot, LumpedPayload,
    LumpedRepr, Pdu, ResponseRepr, SlotCodec, Status,
};

use super::motion::{CycleRecord, MonitorNews, Motion, MotionInput, MotionOutput, Setpoint};
use super::reject::{Reject, Rejections};
use super::{Outbox, Port, Transmit, TransmitPdu, WireFrame};
use crate::plan::{BrokenRing, CyclePlan, FrameRef, Node, PlanKind, RingModel};
use crate::time::{Duration, Instant, round_i64};

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
    /// Encoder resolution of each axis [rad per count] (the lumped-only frame carries the
    /// desired motion in counts).
    pub resolution: Vec<f64>,
    /// W: consecutive cycles without a response from an axis, or without a fresh
    /// feedback sample, before the group stops.
    pub watchdog_cycles: u32,
    /// The communication plan. With the lumped-only plan the master only sends the lumped
    /// frame; the slaves run the law.
    pub plan: PlanKind,
    /// How far in the future (by the master's clock) a feedback sample's sampling instant
    /// may lie and still be taken (the slaves' clock error).
    pub timestamp_tolerance: Duration,
    /// The ring's timing model, from which the master works out the cycle on a broken
    /// ring (ring redundancy, docs/planner.md "A broken link"); `None`: the master uses
    /// port A alone and a broken ring is a broken ring (the lumped-only plan).
    pub ring: Option<RingModel>,
    /// The P2P schedule was measured on real links ([`MasterConfig::with_measured`]): on a
    /// broken ring the master stretches the measured slice, P2P start and command arrivals
    /// (from the P2P start) by the longer path's hops over the whole ring's, at least to the
    /// model's (the model's wire figures are not the real links').
    pub measured: bool,
    /// The relays are transparent, on links of this delay L (a ring of node processes with
    /// kernel stamps): every slave adds to a sync lumped frame's stamp the time it held the
    /// frame, and the slaves' path delays are their links alone. A lumped frame may then
    /// come back with its stamp later than sent, by up to a cycle; on a broken ring the
    /// copy on port B is stamped ahead by the links alone, L·(n + 1 − 2j)
    /// ([`BrokenRing::stamp_shift`] counts the residences too). The master also measures
    /// the links from the round trips of its frames and sends its estimate with every
    /// command ([`crate::node::link`]). `None`: stamps come back as sent, and commands
    /// carry no link.
    pub transparent_link: Option<Duration>,
}

/// The ring as the master sees it (ring redundancy, docs/planner.md "A broken link").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum RingState {
    /// Frames leave on port A and come back on port B.
    #[default]
    Whole,
    /// Link `link` (1..=n+1; link j joins node j−1 to node j, 0 and n+1 being the master)
    /// is broken: the master sends on both ports and reaches slaves 1..link−1 from A and
    /// link..n from B.
    Broken {
        /// The broken link.
        link: u32,
    },
}

impl RingState {
    /// One line: "whole" or "link j broken".
    pub fn describe(&self) -> String {
        match self {
            RingState::Whole => "whole".into(),
            RingState::Broken { link } => format!("link {link} broken"),
        }
    }
}

/// A ring's P2P schedule as measured on real links (see [`MasterConfig::with_measured`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeasuredSchedule {
    /// Start of the P2P phase from the cycle start.
    pub p2p_start: Duration,
    /// Length of one time slice: the slowest slave's command-to-response time.
    pub slice: Duration,
    /// How long the master waits for a response beyond the slice.
    pub guard: Duration,
    /// Per slave: the command's transit, from the master's send to its last bit at the
    /// slave.
    pub command_transit: Vec<Duration>,
    /// Per slave: its typical slice, from the command's send to the response back at the
    /// master (the next slice's command follows it after the turnaround).
    pub typical_slice: Vec<Duration>,
}

impl MasterConfig {
    /// The schedule of the lumped-only plan on the ring of `plan` (a single lumped frame).
    pub fn lumped_only(plan: &CyclePlan, resolution: Vec<f64>) -> Self {
        let mut c = MasterConfig::from_plan(plan, Duration::ZERO, resolution);
        let lo = &plan.lumped_only.lumped;
        c.plan = PlanKind::LumpedOnly;
        c.lumped_slots = lo.frame_slots.clone();
        c.lumped_offsets = (0..lo.frame_slots.len())
            .map(|j| lo.frame_offset(j, plan.link.gap()))
            .collect();
        c.command_arrival = plan.d_c.iter().map(|d| *d + lo.frame_time[0]).collect();
        c.ring = None;
        c
    }

    /// The schedule of `plan`, with `jitter` allowed per hop when waiting for a response.
    pub fn from_plan(plan: &CyclePlan, jitter: Duration, resolution: Vec<f64>) -> Self {
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
            watchdog_cycles: 5,
            plan: PlanKind::P2pLumped,
            timestamp_tolerance: Duration::from_us(50),
            ring: Some(RingModel::of(plan)),
            measured: false,
            transparent_link: None,
        }
    }

    /// This schedule with its P2P phase as measured on real links (the runtime's
    /// calibration) in place of the plan's wire figures: the P2P start, the slice and the
    /// guard as given, and each command's arrival where the measured ring puts it: slice
    /// i's command leaves after the earlier slices' typical round trips (each followed by
    /// the turnaround) and takes its slave's measured transit.
    pub fn with_measured(mut self, m: &MeasuredSchedule) -> Self {
        self.measured = true;
        self.p2p_start = m.p2p_start;
        self.slice = m.slice;
        self.guard = m.guard;
        let mut at = m.p2p_start;
        for (i, arrival) in self.command_arrival.iter_mut().enumerate() {
            *arrival = at + m.command_transit.get(i).copied().unwrap_or(Duration::ZERO);
            at += m.typical_slice.get(i).copied().unwrap_or(m.slice) + self.turnaround;
        }
        self
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.command_arrival.len()
    }
}

/// Why the group stopped.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum StopReason {
    /// Axis `axis` (0-based) exceeded the following-error limit with error `error` \[rad\].
    FollowingError {
        /// Axis index.
        axis: usize,
        /// The error \[rad\].
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
    /// Axis `axis` brought no fresh feedback sample for W cycles: the master can no
    /// longer control it (its command is 0 V from then on).
    NoFeedback {
        /// Axis index.
        axis: usize,
    },
    /// Axis `axis`'s slave applied a command other than the one the master sent it (its
    /// response's applied command disagrees): something else commands the axis.
    CommandMismatch {
        /// Axis index.
        axis: usize,
        /// What the master sent \[V\].
        sent: f32,
        /// What the slave says it applied \[V\].
        applied: f32,
    },
    /// Axis `axis`'s sync error ε stayed beyond the sync monitor's trip limit for its
    /// filter time, and the monitor's reaction is the group stop.
    SyncTrip {
        /// Axis index.
        axis: usize,
        /// ε when it tripped \[rad\].
        error: f64,
    },
    /// Axis `axis`'s following error stayed beyond the following-error monitor's trip
    /// limit for its filter time, and the monitor's reaction is the group stop (the
    /// instantaneous hard limit is [`StopReason::FollowingError`]).
    FollowingTrip {
        /// Axis index.
        axis: usize,
        /// The error when it tripped \[rad\].
        error: f64,
    },
    /// A second break cut axes `axis..=last` (0-based) off both of the master's ports.
    RingSplit {
        /// The first isolated axis.
        axis: usize,
        /// The last isolated axis.
        last: usize,
    },
}

impl StopReason {
    /// The axis that caused the stop (0-based).
    pub fn axis(&self) -> usize {
        match *self {
            StopReason::FollowingError { axis, .. }
            | StopReason::AxisFault { axis }
            | StopReason::NoResponse { axis }
            | StopReason::NoFeedback { axis }
            | StopReason::CommandMismatch { axis, .. }
            | StopReason::SyncTrip { axis, .. }
            | StopReason::FollowingTrip { axis, .. }
            | StopReason::RingSplit { axis, .. } => axis,
        }
    }
    /// A short name for outputs.
    pub fn name(&self) -> &'static str {
        match self {
            StopReason::FollowingError { .. } => "following error",
            StopReason::AxisFault { .. } => "axis fault",
            StopReason::NoResponse { .. } => "no response",
            StopReason::NoFeedback { .. } => "no feedback",
            StopReason::CommandMismatch { .. } => "command mismatch",
            StopReason::SyncTrip { .. } => "sync error trip",
            StopReason::FollowingTrip { .. } => "following error trip",
            StopReason::RingSplit { .. } => "ring split",
        }
    }
}

/// What the master orders an axis's drive to do during a group stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum StopOrder {
    /// Brake on its own (the `BRAKE` flag): damp its measured velocity to standstill, then
    /// cut torque. For an axis the master can still reach but no longer sees.
    Brake,
    /// Cut torque (the `TORQUE_OFF` flag).
    TorqueOff,
}

impl StopOrder {
    /// A short name for outputs.
    pub fn name(self) -> &'static str {
        match self {
            StopOrder::Brake => "brake",
            StopOrder::TorqueOff => "torque off",
        }
    }
}

/// Why the master gave an axis a [`StopOrder`] during a group stop.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum OffReason {
    /// The axis could not follow its stop ramp: its error against the ramp \[rad\] exceeded
    /// the following-error limit.
    FollowingError {
        /// The error against the ramp \[rad\].
        error: f64,
    },
    /// The axis has no feedback (none fresh for W cycles): the master cannot control it,
    /// so it orders the drive to brake on its own.
    NoFeedback,
    /// Its ramp has ended and it has held still for the hold time.
    StopComplete,
    /// The stop has lasted its longest allowed time.
    StopTimeout,
    /// The lumped-only plan: the master does not command the axes, so every drive brakes
    /// on its own.
    LumpedOnly,
}

impl OffReason {
    /// A short name for outputs.
    pub fn name(&self) -> &'static str {
        match self {
            OffReason::FollowingError { .. } => "could not follow the stop ramp",
            OffReason::NoFeedback => "no feedback",
            OffReason::StopComplete => "stop complete",
            OffReason::StopTimeout => "stop timed out",
            OffReason::LumpedOnly => "lumped-only plan: the drives brake on their own",
        }
    }
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
    /// During the group stop, the master gave axis `axis` an order at `at`.
    Order {
        /// When [master ns].
        at: Instant,
        /// The axis (0-based).
        axis: usize,
        /// Brake or torque off.
        order: StopOrder,
        /// Why.
        why: OffReason,
    },
    /// A monitor of the motion (sync error, following error) raised or cleared a warning
    /// or tripped, at `at`.
    Monitor {
        /// When [master ns].
        at: Instant,
        /// What.
        news: MonitorNews,
    },
    /// The master found the ring changed at `at` (a link broke, healed, or the break
    /// moved) and from this cycle's P2P phase on sends as the new ring needs.
    Ring {
        /// When [master ns].
        at: Instant,
        /// The master's cycle.
        k: i64,
        /// The ring before.
        from: RingState,
        /// The ring now.
        to: RingState,
    },
}

/// Counters that explain every lost cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
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
    /// Frames (and feedback slots) refused, per reason.
    pub rejected: Rejections,
    /// Responses whose applied command was not the one the master sent.
    pub command_mismatches: u64,
    /// Times the master found a link broken (a whole ring broken, or a break moved).
    pub ring_breaks: u64,
    /// Times the master found a broken ring whole again.
    pub ring_heals: u64,
}

/// 0 for port A, 1 for port B.
fn port_ix(p: Port) -> usize {
    match p {
        Port::A => 0,
        Port::B => 1,
    }
}

/// A lumped frame back at the master: frame `j` of the cycle, the port its copy left on
/// and the port it came back to.
#[derive(Debug, Clone, Copy)]
struct Back {
    j: usize,
    sent: Port,
    port: Port,
}

/// A lumped frame as it went out, to recognise it when it comes back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct SentLumped {
    seq: u16,
    stamp: u64,
    sent: bool,
    /// Whether it came back to port A, to port B (a copy reflected to one port must not
    /// keep the genuine one from being taken at the other).
    back: [bool; 2],
}

/// The master of the ring: it sends the lumped frame at each cycle start (clock sync and
/// feedback, docs/system.md eq. 1-2), runs the [`Motion`] at the P2P start, then opens one
/// time slice per axis for its command and takes each response (retrying into reserved
/// slices), and stops the group when feedback or responses fail for W cycles.
///
/// It is sans-IO, like quinn-proto's `Connection`: it never reads a clock or touches a
/// socket. Its time is the master's clock, which is the ring's true time.
///
/// # Driving it
///
/// A driver owns time and the wire, and calls, in this order:
///
/// 1. [`poll_timeout`](Master::poll_timeout): when the master next needs
///    [`handle_timeout`](Master::handle_timeout) (the cycle start, the P2P start, a slice's
///    opening or deadline);
/// 2. at that time [`handle_timeout`](Master::handle_timeout); whenever a frame comes back,
///    [`handle_frame`](Master::handle_frame) with the time its last bit arrived. Time never
///    goes backwards from one call to the next;
/// 3. after either, [`poll_transmit`](Master::poll_transmit) until `None` (frames to send,
///    each with its send instant), then [`poll_event`](Master::poll_event) until `None` (the
///    law ran, the group stopped, an order was given);
/// 4. optionally [`recycle`](Master::recycle) the buffers of frames sent or received, so a
///    steady ring allocates nothing per frame.
///
/// # Getters
///
/// [`config`](Master::config), [`counters`](Master::counters) (every lost cycle explained,
/// every refused frame counted), [`record`](Master::record) (the last law run),
/// [`cycle`](Master::cycle), [`is_stopping`](Master::is_stopping),
/// [`order`](Master::order), [`desired`](Master::desired),
/// [`awaiting_frames`](Master::awaiting_frames),
/// [`last_lumped_cycle`](Master::last_lumped_cycle), [`motion`](Master::motion).
///
/// # Example
///
/// [`testbed`](super::testbed) drives a master and its slaves on ideal links;
/// `examples/04_nodes_by_hand.rs` does it in a page, with the calls above spelled out.
pub struct Master {
    cfg: MasterConfig,
    /// The motion application (law, trajectories, supervision, the stop ramp).
    motion: Box<dyn Motion>,
    /// Its output of the last run.
    mout: MotionOutput,
    /// The lumped-only plan: each axis's latest written feedback, and the cycle's record
    /// (what the slaves did).
    lo_latest: Vec<Option<FeedbackSlot>>,
    lo_record: CycleRecord,
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
    /// Latest sample per axis.
    latest: Vec<Option<FeedbackSlot>>,
    /// Last returned lumped-only slots (the lumped-only plan).
    lo_slots: Vec<LumpedOnlySlot>,
    /// Empty slots for the next lumped frame, kept to avoid an allocation per cycle.
    empty_slots: Vec<FeedbackSlot>,
    /// Per axis, whether `latest` holds a sample no law run has taken yet (P2P plans; the
    /// lumped-only plan: whether one came back this cycle).
    fresh: Vec<bool>,
    lumped_back: usize,
    /// Slice bookkeeping: target (0-based) of the open slice, its retry count.
    open: Option<(usize, u8)>,
    acked: Vec<bool>,
    missed: Vec<u32>,
    /// Axes without a fresh sample for W cycles or more: commanded 0 V.
    blind: Vec<bool>,
    /// Consecutive law runs without a new sample, per axis (the feedback watchdog), and
    /// whether a new sample was taken since the last law run (a sample that came back late
    /// still counts: the frame was late, the axis not blind).
    since_fresh: Vec<u32>,
    fed: Vec<bool>,
    /// The order given to each axis during a group stop (latched; a brake may still become
    /// torque off).
    orders: Vec<Option<StopOrder>>,
    /// The command sent to each axis in this cycle [V], to check the responses' echo.
    sent_u: Vec<f32>,
    /// Per lumped frame of this cycle: the sequence number and stamp it went out with,
    /// and whether it has come back.
    sent_lumped: Vec<SentLumped>,
    /// The cycle of the last lumped frame taken.
    last_back: Option<i64>,
    /// The cycles whose first lumped frame went out in the last cycle time, with their send
    /// instants, and the newest one sent before that at the front: what frames have had the
    /// time to go round (see [`Master::settled_cycle`]).
    recent_sends: VecDeque<(i64, Instant)>,
    retry_queue: VecDeque<usize>,
    /// The ring as the master sees it, and its timing when broken.
    ring: RingState,
    broken: Option<BrokenRing>,
    /// The master's ports whose link is down, as its PHYs say: [A, B].
    port_down: [bool; 2],
    /// This cycle's lumped frames to send: (offset from the cycle start, port, frame).
    sends: Vec<(Duration, Port, usize)>,
    /// The copies of this cycle's lumped frames sent on port B (a broken ring).
    sent_lumped_b: Vec<SentLumped>,
    /// What came back this cycle: the furthest slave that wrote its slot in a copy that
    /// came back to port A, the nearest in one that came back to port B (n + 1 when none
    /// wrote), and whether a copy went all the way round.
    back_a: Option<usize>,
    back_b: Option<usize>,
    round_trip: bool,
    /// Consecutive law runs whose two copies did not meet (slaves cut off from both ports),
    /// and the slaves (0-based, inclusive) they last left between them.
    split_runs: u32,
    split: Option<(usize, usize)>,
    seq: u16,
    out: Outbox,
    events: VecDeque<MasterEvent>,
    counters: MasterCounters,
    /// Behind transparent relays: one link's delay as the run's round trips measure it,
    /// sent with every command.
    link: Option<LinkEstimate>,
}

impl Master {
    /// A master running `motion` on the ring of `cfg` (`motion` has `cfg.axes()` axes).
    pub fn new(cfg: MasterConfig, motion: Box<dyn Motion>) -> Self {
        let n = cfg.axes();
        Master {
            motion,
            mout: MotionOutput::new(n),
            lo_latest: vec![None; n],
            lo_record: CycleRecord::new(n),
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
            since_fresh: vec![0; n],
            fed: vec![false; n],
            orders: vec![None; n],
            sent_u: vec![0.0; n],
            sent_lumped: vec![SentLumped::default(); cfg.lumped_offsets.len()],
            last_back: None,
            recent_sends: VecDeque::new(),
            retry_queue: VecDeque::new(),
            ring: RingState::Whole,
            broken: None,
            port_down: [false; 2],
            sends: cfg
                .lumped_offsets
                .iter()
                .enumerate()
                .map(|(j, &o)| (o, Port::A, j))
                .collect(),
            sent_lumped_b: vec![SentLumped::default(); cfg.lumped_offsets.len()],
            back_a: None,
            back_b: None,
            round_trip: false,
            split_runs: 0,
            split: None,
            seq: 0,
            out: Outbox::default(),
            events: VecDeque::new(),
            counters: MasterCounters::default(),
            link: cfg
                .transparent_link
                .map(|_| LinkEstimate::new(n, cfg.cycle)),
            cfg,
        }
    }

    /// Behind transparent relays: the run's estimate of one link's delay (the median of
    /// the last [`link::WINDOW`](crate::node::link::WINDOW) round trips over the n + 1
    /// links), once there is one, and how many estimates were made.
    pub fn link_estimate(&self) -> Option<(Duration, u64)> {
        self.link
            .as_ref()
            .and_then(|l| l.current().map(|d| (d, l.estimates())))
    }

    /// A sync lumped frame back: one that left on port A and came back to port B went
    /// round the whole ring, and behind transparent relays its round trip less its
    /// stamp's residences is the links'.
    fn note_round_trip(&mut self, sent: Port, arrived: Port, now: Instant, stamp: u64) {
        if let (Some(l), Port::A, Port::B) = (self.link.as_mut(), sent, arrived) {
            l.note(now.as_ns(), stamp);
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
        match self.cfg.plan {
            PlanKind::P2pLumped => &self.mout.record,
            PlanKind::LumpedOnly => &self.lo_record,
        }
    }
    /// Whether the group is stopping.
    pub fn is_stopping(&self) -> bool {
        self.motion.is_stopping()
    }
    /// The motion application.
    pub fn motion(&self) -> &dyn Motion {
        &*self.motion
    }
    /// The cycle in progress, k.
    pub fn cycle(&self) -> i64 {
        self.k
    }
    /// The cycle of the last lumped frame that came back and was taken: the master's
    /// "last seen" counter, from which a driver tells where a ring broke.
    pub fn last_lumped_cycle(&self) -> Option<i64> {
        self.last_back
    }

    /// The newest cycle whose first lumped frame went out at least a cycle time before `at`
    /// (`None` before any): every node had the time to take it. A master that runs late
    /// runs the cycles it missed back to back, and their frames, sent at once, have not gone
    /// round yet.
    pub fn settled_cycle(&self, at: Instant) -> Option<i64> {
        let &(first, _) = self.recent_sends.front()?;
        Some(
            self.recent_sends
                .iter()
                .rev()
                .find(|(_, sent)| *sent + self.cfg.cycle <= at)
                .map_or(first - 1, |(k, _)| *k),
        )
    }

    /// Notes that cycle k's first lumped frame goes out at `now`.
    fn note_lumped_sent(&mut self, now: Instant) {
        self.recent_sends.push_back((self.k, now));
        while self.recent_sends.len() >= 2 && self.recent_sends[1].1 + self.cfg.cycle <= now {
            self.recent_sends.pop_front();
        }
    }
    /// The order the master gave axis `i` (0-based) during a group stop, if any.
    pub fn order(&self, i: usize) -> Option<StopOrder> {
        self.orders.get(i).copied().flatten()
    }

    /// Whether the master is waiting for frames: a lumped frame of this cycle not back yet,
    /// or a time slice open. A driver may sleep less precisely when it is not.
    pub fn awaiting_frames(&self) -> bool {
        self.lumped_back < self.next_lumped || self.deadline.is_some()
    }

    /// The desired state of axis `i` at `t` \[s\] (the stop ramp once stopping).
    pub fn desired(&self, i: usize, t: f64) -> Setpoint {
        self.motion.desired(i, t)
    }

    fn cycle_start(&self) -> Instant {
        Instant::from_ns(self.k * self.cfg.cycle.as_ns())
    }

    fn slots_total(&self) -> usize {
        self.cfg.axes() + self.cfg.reserve_slices as usize
    }

    /// When the master next needs [`Master::handle_timeout`] [master ns].
    #[must_use]
    pub fn poll_timeout(&self) -> Instant {
        let c = self.cycle_start();
        if let Some(&(offset, _, _)) = self.sends.get(self.next_lumped) {
            return c + offset;
        }
        if self.cfg.plan == PlanKind::LumpedOnly {
            return c + self.cfg.cycle;
        }
        if !self.computed {
            return c + self.p2p_start();
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
        if self.next_lumped < self.sends.len() {
            if self.next_lumped == 0 {
                self.note_lumped_sent(now);
            }
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
                self.supervise_lumped_only(now);
                self.k += 1;
                self.next_lumped = 0;
                self.lumped_back = 0;
                self.fresh.fill(false);
                self.sent_lumped.fill(SentLumped::default());
                self.sent_lumped_b.fill(SentLumped::default());
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

    /// The lumped-only plan's supervision at the end of each cycle: the feedback watchdog,
    /// and the group stop (a following error seen in a returned frame, or no fresh sample
    /// for W cycles). The master cannot command the axes in this plan: from the stop on,
    /// its lumped frames carry STOP and BRAKE, and every drive brakes on its own.
    fn supervise_lumped_only(&mut self, now: Instant) {
        self.feedback_watchdog();
        let was_stopping = self.motion.is_stopping();
        let input = MotionInput {
            k: self.k,
            now,
            cycle_start: self.cycle_start(),
            samples: &self.lo_latest,
            fresh: &self.fresh,
            blind: &self.blind,
            command_arrival: &self.cfg.command_arrival,
            pending: self.pending_stop.take(),
            commanded: false,
        };
        self.motion.compute(&input, &mut self.mout);
        self.take_motion_events(now);
        if !was_stopping && self.motion.is_stopping() {
            for axis in 0..self.cfg.axes() {
                self.orders[axis] = Some(StopOrder::Brake);
                self.events.push_back(MasterEvent::Order {
                    at: now,
                    axis,
                    order: StopOrder::Brake,
                    why: OffReason::LumpedOnly,
                });
            }
        }
    }

    /// Opens the next slice that has work, if any fits before the next cycle.
    fn open_next(&mut self, now: Instant) {
        let next_cycle = self.cycle_start() + self.cfg.cycle;
        while self.next_slot < self.slots_total() {
            let s = self.next_slot;
            self.next_slot += 1;
            let slice = self.slice();
            if now + slice + self.guard() > next_cycle {
                break;
            }
            if self.open_slice(s, now) {
                self.deadline = Some(now + slice + self.guard());
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
            // An axis the ring's copies have been failing to meet around is cut off: the
            // split is the cause to name (it and the response watchdog both count about W
            // cycles from the second break, and a run the host made late delays the split's
            // count by one).
            let reason = match self.split {
                Some((first, last)) if (first..=last).contains(&axis) => {
                    StopReason::RingSplit { axis: first, last }
                }
                _ => StopReason::NoResponse { axis },
            };
            self.pending_stop.get_or_insert(reason);
        }
        self.retry_queue.clear();
        self.k += 1;
        self.next_lumped = 0;
        self.computed = false;
        self.next_slot = 0;
        self.open_at = None;
        self.deadline = None;
        self.lumped_back = 0;
        self.acked.fill(false);
        self.sent_lumped.fill(SentLumped::default());
        self.sent_lumped_b.fill(SentLumped::default());
        self.back_a = None;
        self.back_b = None;
        self.round_trip = false;
    }

    fn send_lumped(&mut self, now: Instant) {
        let Some(&(_, port, j)) = self.sends.get(self.next_lumped) else {
            return;
        };
        let first: usize = self.cfg.lumped_slots[..j].iter().sum();
        // Empty slots, reused from cycle to cycle.
        let mut slots = std::mem::take(&mut self.empty_slots);
        slots.clear();
        slots.resize(self.cfg.lumped_slots[j], FeedbackSlot::default());
        self.queue_lumped(now, port, j, first, slots);
    }

    /// Sends lumped frame `j` of either layout on `port`, stamped with `now` (on port B of a
    /// broken ring, `now` + Δ: see [`BrokenRing::stamp_shift`]).
    fn queue_lumped<S: SlotCodec>(
        &mut self,
        now: Instant,
        port: Port,
        j: usize,
        first: usize,
        slots: Vec<S>,
    ) where
        LumpedRepr<S>: Into<Pdu>,
    {
        let stamp = match (port, &self.broken) {
            (Port::B, Some(b)) => now.as_ns().saturating_add(b.stamp_shift.as_ns()),
            _ => now.as_ns(),
        };
        self.seq = self.seq.wrapping_add(1);
        // In the lumped-only plan the lumped frame is the only way to the drives: once the
        // group stops it tells them all to brake.
        let flags = if self.motion.is_stopping() && self.cfg.plan == PlanKind::LumpedOnly {
            Flags::STOP.with(Flags::BRAKE)
        } else {
            Flags::empty()
        };
        let repr = LumpedRepr {
            common: Common {
                flags,
                cycle: self.k as u32,
                seq: self.seq,
                ..Common::default()
            },
            master_time_ns: stamp.max(0) as u64,
            first_slot: first as u16,
            slots,
        };
        let sent = SentLumped {
            seq: repr.common.seq,
            stamp: repr.master_time_ns,
            sent: true,
            back: [false; 2],
        };
        if self.out.push_on(now, port, repr.into()) {
            self.counters.frames_sent += 1;
            let record = match port {
                Port::A => &mut self.sent_lumped,
                Port::B => &mut self.sent_lumped_b,
            };
            if let Some(s) = record.get_mut(j) {
                *s = sent;
            }
        }
    }

    /// The lumped-only plan's frame: last cycle's returned slots (not written this cycle),
    /// with the desired state at this cycle's sampling instant for monitoring.
    fn send_lumped_only(&mut self, now: Instant) {
        let j = self
            .next_lumped
            .min(self.cfg.lumped_slots.len().saturating_sub(1));
        let first: usize = self.cfg.lumped_slots[..j].iter().sum();
        let t = self.cycle_start().as_ns() as f64 * 1e-9;
        let slots: Vec<LumpedOnlySlot> = (first..first + self.cfg.lumped_slots[j])
            .map(|i| {
                let d = self.desired(i, t);
                let res = self.cfg.resolution[i];
                let mut s = self.lo_slots[i];
                s.feedback.written = false;
                s.desired_position =
                    round_i64(d.x / res).clamp(i32::MIN.into(), i32::MAX.into()) as i32;
                s.desired_velocity =
                    round_i64(d.v / res).clamp(i32::MIN.into(), i32::MAX.into()) as i32;
                s
            })
            .collect();
        self.queue_lumped(now, Port::A, j, first, slots);
    }

    fn compute(&mut self, now: Instant) {
        // (A copy reflected to the wrong port may come back as well as the genuine one.)
        let expected = self.expected_back();
        self.counters.lumped_lost += expected.saturating_sub(self.lumped_back) as u64;
        self.feedback_watchdog();
        self.supervise_ring(now);
        let input = MotionInput {
            k: self.k,
            now,
            cycle_start: self.cycle_start(),
            samples: &self.latest,
            fresh: &self.fresh,
            blind: &self.blind,
            command_arrival: match &self.broken {
                Some(b) => &b.command_arrival,
                None => &self.cfg.command_arrival,
            },
            pending: self.pending_stop.take(),
            commanded: true,
        };
        self.motion.compute(&input, &mut self.mout);
        // A sample is fresh until a law run has taken it: one that came back after this
        // cycle's law ran (its lumped frame late) is the next run's, not lost.
        self.fresh.fill(false);
        self.take_motion_events(now);
        self.events.push_back(MasterEvent::Computed { k: self.k });
    }

    /// The feedback watchdog, counted in the master's own cycles: an axis from which no
    /// new sample came in W law runs is blind, whatever timestamps the frames claim.
    fn feedback_watchdog(&mut self) {
        for i in 0..self.cfg.axes() {
            self.since_fresh[i] = if std::mem::take(&mut self.fed[i]) {
                0
            } else {
                self.since_fresh[i].saturating_add(1)
            };
            self.blind[i] = self.since_fresh[i] >= self.cfg.watchdog_cycles;
        }
    }

    /// The stop the motion began and the orders it gave in its last run, as events.
    fn take_motion_events(&mut self, now: Instant) {
        for news in self.mout.monitor.drain(..) {
            self.events
                .push_back(MasterEvent::Monitor { at: now, news });
        }
        if let Some(reason) = self.mout.stop.take() {
            self.events
                .push_back(MasterEvent::GroupStop { at: now, reason });
        }
        for (axis, order, why) in self.mout.orders.drain(..) {
            self.orders[axis] = Some(order);
            self.events.push_back(MasterEvent::Order {
                at: now,
                axis,
                order,
                why,
            });
        }
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
        let mut flags = if self.motion.is_stopping() {
            Flags::STOP
        } else {
            Flags::empty()
        };
        match self.orders[target] {
            Some(StopOrder::TorqueOff) => flags = flags.with(Flags::TORQUE_OFF),
            Some(StopOrder::Brake) => flags = flags.with(Flags::BRAKE),
            None => {}
        }
        self.sent_u[target] = self.mout.u[target] as f32;
        let cmd = CommandRepr {
            common: Common {
                flags,
                retry,
                cycle: self.k as u32,
                seq: self.seq,
            },
            target: (target + 1) as u16,
            command_v: self.mout.u[target] as f32,
            sample_time_ns: ns_of(self.mout.record.sample_time[target]),
            link_ns: self.link.as_ref().map_or(0, LinkEstimate::wire),
        };
        if self
            .out
            .push_on(now, self.port_of(target), Pdu::Command(cmd))
        {
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

    /// A frame received completely at `now` [master ns]. It is checked against what the
    /// master sent and its own clock before it changes anything; a refused frame is counted
    /// in [`MasterCounters::rejected`].
    pub fn handle_frame(&mut self, now: Instant, bytes: &[u8]) {
        self.handle_frame_on(Port::B, now, bytes);
    }

    /// [`Master::handle_frame`] for a frame received on `port` (a whole ring brings every
    /// frame back to port B; [`Master::handle_frame`] is this on port B).
    pub fn handle_frame_on(&mut self, port: Port, now: Instant, bytes: &[u8]) {
        if let Err(r) = self.accept_frame(port, now, bytes) {
            self.counters.rejected.count(r);
        }
    }

    /// A decoded frame received completely at `now` [master ns] (a driver that carries
    /// frames without their bytes): the checks of [`Master::handle_frame`] after the
    /// decoding, with the same effect.
    pub fn handle_pdu(&mut self, now: Instant, pdu: &Pdu) {
        self.handle_pdu_on(Port::B, now, pdu);
    }

    /// [`Master::handle_pdu`] for a frame received on `port`.
    pub fn handle_pdu_on(&mut self, port: Port, now: Instant, pdu: &Pdu) {
        let taken = match (pdu, self.cfg.plan) {
            (Pdu::Lumped(l), PlanKind::P2pLumped) => {
                let (first, slots) = (usize::from(l.first_slot), &l.slots);
                let c = &l.common;
                self.echo_of(port, c.cycle, c.seq, l.master_time_ns, first, slots.len())
                    .map(|(j, sent)| {
                        self.note_round_trip(sent, port, now, l.master_time_ns);
                        let back = Back { j, sent, port };
                        self.take_lumped_slots(now, back, first, slots.len(), |k| {
                            slots.get(k).copied()
                        })
                    })
            }
            (Pdu::Response(r), PlanKind::P2pLumped) => self.take_response(now, r),
            (Pdu::LumpedOnly(l), PlanKind::LumpedOnly) => self.take_lumped_only(now, l),
            _ => Err(Reject::UnexpectedKind),
        };
        if let Err(r) = taken {
            self.counters.rejected.count(r);
        }
    }

    fn accept_frame(&mut self, port: Port, now: Instant, bytes: &[u8]) -> Result<(), Reject> {
        let f = Frame::new_checked(bytes).map_err(|_| Reject::Malformed)?;
        let kind = f.check().map_err(|_| Reject::Malformed)?;
        match (kind, self.cfg.plan) {
            // The proposed plan's lumped frame comes back every cycle: read its slots in
            // place (no allocation).
            (FrameKind::Lumped, PlanKind::P2pLumped) => self.take_lumped(port, now, &f),
            (FrameKind::Response, PlanKind::P2pLumped) => {
                let r = ResponseRepr::parse_verified(bytes).map_err(|_| Reject::Malformed)?;
                self.take_response(now, &r)
            }
            (FrameKind::LumpedOnly, PlanKind::LumpedOnly) => {
                let l = LumpedRepr::<LumpedOnlySlot>::parse_verified(bytes)
                    .map_err(|_| Reject::Malformed)?;
                self.take_lumped_only(now, &l)
            }
            _ => Err(Reject::UnexpectedKind),
        }
    }

    /// Which lumped frame of this cycle `frame` echoes (its index, and the port its copy
    /// went out on), or why it is refused: the cycle, sequence number, stamp and first slot
    /// must be those it went out with, and it must not have come back already.
    fn echo_of(
        &self,
        arrived: Port,
        cycle: u32,
        seq: u16,
        stamp: u64,
        first: usize,
        count: usize,
    ) -> Result<(usize, Port), Reject> {
        if i64::from(cycle) != self.k & 0xFFFF_FFFF {
            return Err(Reject::WrongCycle);
        }
        let mut start = 0;
        let mut j = None;
        for (i, &m) in self.cfg.lumped_slots.iter().enumerate() {
            if start == first {
                j = Some((i, m));
                break;
            }
            start += m;
        }
        let (j, slots) = j.ok_or(Reject::Unsolicited)?;
        // Transparent relays move the stamp on by their residences, within a cycle.
        let moved = self
            .cfg
            .transparent_link
            .map_or(0, |_| self.cfg.cycle.as_ns());
        let echoes = |s: &SentLumped| {
            s.sent
                && s.seq == seq
                && stamp
                    .checked_sub(s.stamp)
                    .is_some_and(|d| d <= moved.max(0) as u64)
        };
        let (sent, port) = match (self.sent_lumped.get(j), self.sent_lumped_b.get(j)) {
            (Some(a), _) if echoes(a) => (a, Port::A),
            (_, Some(b)) if echoes(b) => (b, Port::B),
            _ => return Err(Reject::Unsolicited),
        };
        if slots != count {
            return Err(Reject::Unsolicited);
        }
        if sent.back[port_ix(arrived)] {
            return Err(Reject::Duplicate);
        }
        Ok((j, port))
    }

    /// The latest sampling instant a slot may carry when it is read at `now` [ns, the
    /// slaves' synchronised clocks, which follow the master's].
    fn newest_sample(&self, now: Instant) -> u64 {
        now.as_ns()
            .saturating_add(self.cfg.timestamp_tolerance.as_ns())
            .max(0) as u64
    }

    /// A returned lumped frame (CRC checked): the feedback of every slave that wrote its slot.
    fn take_lumped(&mut self, port: Port, now: Instant, f: &Frame<&[u8]>) -> Result<(), Reject> {
        let p = LumpedPayload::new_checked(f.payload(), FrameKind::Lumped)
            .map_err(|_| Reject::Malformed)?;
        let first = usize::from(p.first_slot());
        let count = usize::from(p.slot_count());
        let (j, sent) = self.echo_of(port, f.cycle(), f.seq(), p.master_time_ns(), first, count)?;
        // Every slot must parse before any is taken: a frame is taken whole or not at all.
        for k in 0..count {
            match p.slot_bytes(k).map(FeedbackSlot::parse) {
                Some(Ok(_)) => {}
                _ => return Err(Reject::Malformed),
            }
        }
        self.note_round_trip(sent, port, now, p.master_time_ns());
        let back = Back { j, sent, port };
        self.take_lumped_slots(now, back, first, count, |k| {
            p.slot_bytes(k).and_then(|b| FeedbackSlot::parse(b).ok())
        });
        Ok(())
    }

    /// Lumped frame `back.j` of this cycle back (checked against what was sent, every slot
    /// decoded: `slot(k)` for k < `count`, slave `first + k + 1`'s): the feedback of every
    /// slave that wrote its slot, and what the ports it left and came back on say about the
    /// ring.
    fn take_lumped_slots(
        &mut self,
        now: Instant,
        back: Back,
        first: usize,
        count: usize,
        slot: impl Fn(usize) -> Option<FeedbackSlot>,
    ) {
        let record = match back.sent {
            Port::A => &mut self.sent_lumped,
            Port::B => &mut self.sent_lumped_b,
        };
        if let Some(s) = record.get_mut(back.j) {
            s.back[port_ix(back.port)] = true;
        }
        self.lumped_back += 1;
        self.last_back = Some(self.k);
        let newest = self.newest_sample(now);
        let n = self.latest.len();
        // The slots this copy should have had written: all on a whole ring, its own side's
        // on a broken one (none for a copy that went round a ring the master thought broken).
        let side_a = self.broken.as_ref().map(|b| b.side_a as usize);
        let expected = |i: usize| match (side_a, back.sent, back.port) {
            (None, _, _) => true,
            (Some(a), Port::A, Port::A) => i < a,
            (Some(a), Port::B, Port::B) => i >= a,
            _ => false,
        };
        let (mut furthest, mut nearest) = (0, n + 1);
        for k in 0..count {
            let i = first + k;
            let Some(slot) = slot(k) else {
                continue;
            };
            if i >= n {
                break;
            }
            if slot.written {
                furthest = furthest.max(i + 1);
                nearest = nearest.min(i + 1);
            }
            if slot.written || expected(i) {
                self.take_sample(i, slot, newest);
            }
        }
        match (back.sent, back.port) {
            (Port::A, Port::A) => self.back_a = Some(self.back_a.unwrap_or(0).max(furthest)),
            (Port::B, Port::B) => self.back_b = Some(self.back_b.unwrap_or(n + 1).min(nearest)),
            _ => self.round_trip = true,
        }
    }

    /// One feedback slot of slave i + 1 in an accepted lumped frame.
    fn take_sample(&mut self, i: usize, slot: FeedbackSlot, newest: u64) {
        if !slot.written {
            self.counters.samples_missing += 1;
        } else if slot.sample_time_ns > newest {
            self.counters.rejected.count(Reject::FutureTimestamp);
        } else if self.latest[i].is_some_and(|l| slot.sample_time_ns <= l.sample_time_ns) {
            self.counters.samples_stale += 1;
        } else {
            self.latest[i] = Some(slot);
            self.fresh[i] = true;
            self.fed[i] = true;
        }
    }

    /// A response: taken only if it answers the open slice.
    fn take_response(&mut self, now: Instant, r: &ResponseRepr) -> Result<(), Reject> {
        let k = self.k & 0xFFFF_FFFF;
        if i64::from(r.echo_cycle) != k || i64::from(r.common.cycle) != k {
            return Err(Reject::WrongCycle);
        }
        let i = usize::from(r.source).wrapping_sub(1);
        if i >= self.acked.len() {
            return Err(Reject::Unsolicited);
        }
        match self.open {
            Some((target, retry))
                if target == i && self.deadline.is_some() && r.common.retry == retry =>
            {
                if self.acked[i] {
                    return Err(Reject::Duplicate);
                }
                // The slice ends when the master has the response (eq. 2).
                self.acked[i] = true;
                self.close_slice();
                self.deadline = None;
                self.open_at = Some(now + self.cfg.turnaround);
                if r.status.contains(Status::FAULT)
                    && let Some(s) = self.latest[i].as_mut()
                {
                    s.status = s.status.with(Status::FAULT);
                }
                self.check_applied(i, r);
                Ok(())
            }
            _ if self.acked[i] => Err(Reject::Duplicate),
            _ => Err(Reject::Unsolicited),
        }
    }

    /// A response says which command the slave applied: it must be the one this master
    /// sent (clipped to the drive's range if the slave says it saturated). A drive in its
    /// own safe state says FAULT (the group stops for the fault); one braking or with its
    /// torque off must have been ordered so by this master. Anything else means that
    /// something besides this master commands the axis (a forged command, or a forged
    /// order): the group stops.
    fn check_applied(&mut self, i: usize, r: &ResponseRepr) {
        if r.status.contains(Status::FAULT) {
            return;
        }
        let stopped = Status::BRAKING.with(Status::TORQUE_OFF);
        let (sent, applied) = (self.sent_u[i], r.applied_v);
        let ok = if r.status.bits() & stopped.bits() != 0 {
            self.orders[i].is_some()
        } else if r.status.contains(Status::SATURATED) {
            applied.abs() <= sent.abs() && applied * sent > 0.0
        } else {
            applied == sent
        };
        if !ok {
            self.counters.command_mismatches += 1;
            self.pending_stop
                .get_or_insert(StopReason::CommandMismatch {
                    axis: i,
                    sent,
                    applied,
                });
        }
    }

    /// The lumped-only plan's returned frame: the master monitors what the slaves did.
    fn take_lumped_only(
        &mut self,
        now: Instant,
        l: &LumpedRepr<LumpedOnlySlot>,
    ) -> Result<(), Reject> {
        let first = usize::from(l.first_slot);
        self.echo_of(
            Port::B,
            l.common.cycle,
            l.common.seq,
            l.master_time_ns,
            first,
            l.slots.len(),
        )
        .map(|(j, _)| self.sent_lumped[j].back[port_ix(Port::B)] = true)?;
        self.lumped_back += 1;
        self.last_back = Some(self.k);
        let newest = self.newest_sample(now);
        self.lo_record.k = self.k;
        for (k, slot) in l.slots.iter().enumerate() {
            let i = first + k;
            if i >= self.lo_slots.len() {
                continue;
            }
            let f = slot.feedback;
            if f.written && f.sample_time_ns > newest {
                self.counters.rejected.count(Reject::FutureTimestamp);
                continue;
            }
            self.lo_slots[i] = *slot;
            let x = f64::from(f.position) * self.cfg.resolution[i];
            let ts = f.sample_time_ns as f64 * 1e-9;
            if !f.written {
                self.counters.samples_missing += 1;
            } else {
                // The motion supervises it at the cycle's end (following error, freshness).
                self.fed[i] = true;
                self.lo_latest[i] = Some(f);
            }
            let r = &mut self.lo_record;
            r.fresh[i] = f.written;
            r.position[i] = x;
            r.sample_time[i] = ts;
            r.u[i] = f64::from(slot.command_v);
            r.saturated[i] = f.status.contains(Status::SATURATED);
            r.apply_time[i] = ts;
        }
        if self.lumped_back == self.cfg.lumped_offsets.len() {
            self.events.push_back(MasterEvent::Computed { k: self.k });
        }
        Ok(())
    }

    /// The ring as the master sees it.
    pub fn ring(&self) -> RingState {
        self.ring
    }

    /// The cycle's timing on the broken ring, when the ring is broken.
    pub fn broken_ring(&self) -> Option<&BrokenRing> {
        self.broken.as_ref()
    }

    /// The link of the master's port `port` went down (`up` false) or came up at `now`, as
    /// its PHY reports. The master acts on it at its next P2P start: with port A down,
    /// nothing it sends there comes back, so it reaches every slave from port B.
    pub fn handle_link(&mut self, now: Instant, port: Port, up: bool) {
        let _ = now;
        self.port_down[port_ix(port)] = !up;
    }

    /// Start of this cycle's P2P phase from the cycle start.
    fn p2p_start(&self) -> Duration {
        self.broken
            .as_ref()
            .map_or(self.cfg.p2p_start, |b| b.p2p_start)
    }

    /// The length of a time slice.
    fn slice(&self) -> Duration {
        self.broken.as_ref().map_or(self.cfg.slice, |b| b.slice)
    }

    /// How long the master waits beyond a slice: the configured guard (the jitter of the
    /// ring's n + 1 hops and the clocks' tolerance), stretched on a broken ring to its
    /// longer path of 2·max(a, b) hops.
    fn guard(&self) -> Duration {
        match &self.broken {
            Some(b) => self.stretch(self.cfg.guard, b),
            None => self.cfg.guard,
        }
    }

    /// `d` × (the broken ring's longer round trip in hops over the whole ring's), at least
    /// `d`.
    fn stretch(&self, d: Duration, b: &BrokenRing) -> Duration {
        let whole = self.cfg.axes() as i64 + 1;
        let broken = 2 * i64::from(b.side_a.max(b.side_b));
        Duration::from_ns(d.as_ns().saturating_mul(broken.max(whole)) / whole)
    }

    /// The port that reaches axis `target` (0-based).
    fn port_of(&self, target: usize) -> Port {
        match &self.broken {
            Some(b) if target >= b.side_a as usize => Port::B,
            _ => Port::A,
        }
    }

    /// How many lumped frames should come back this cycle: one per frame on a whole ring,
    /// one per frame and non-empty side on a broken one.
    fn expected_back(&self) -> usize {
        let m = self.cfg.lumped_offsets.len();
        match &self.broken {
            None => m,
            Some(b) => m * (usize::from(b.side_a > 0) + usize::from(b.side_b > 0)),
        }
    }

    /// The broken ring's timing on the links this master measured (see
    /// [`MasterConfig::measured`]); the model's as it is otherwise.
    fn on_real_links(&self, mut b: BrokenRing) -> BrokenRing {
        if let Some(link) = self.cfg.transparent_link {
            // The links alone; never before the copy's send (its stamp stays in its cycle,
            // which a shift beyond the model's send delay would leave: those slaves then
            // take the difference as a bias while the ring is broken).
            let n = i64::from(b.side_a + b.side_b);
            b.stamp_shift = (link * (n + 1 - 2 * i64::from(b.link))).max(-b.b_delay);
        }
        if !self.cfg.measured {
            return b;
        }
        let slice = self.stretch(self.cfg.slice, &b);
        let p2p = self.stretch(self.cfg.p2p_start, &b);
        b.slice = b.slice.max(slice);
        b.p2p_start = b.p2p_start.max(p2p);
        // The measured arrivals, moved with the P2P start and stretched with the slices.
        let (cfg_p2p, new_p2p) = (self.cfg.p2p_start, b.p2p_start);
        b.command_arrival = self
            .cfg
            .command_arrival
            .iter()
            .map(|&a| new_p2p + self.stretch(a - cfg_p2p, &b))
            .collect();
        b
    }

    /// At the P2P start: what came back tells whether the ring broke, healed or split
    /// (docs/planner.md, "A broken link"). A whole ring whose frame came back to port A
    /// turned at the last slave it reached; a broken ring whose copy went all the way round
    /// is whole again; a broken ring whose two copies have not met for W law runs has cut
    /// slaves off, and the group stops.
    fn supervise_ring(&mut self, now: Instant) {
        let Some(model) = self.cfg.ring else {
            return;
        };
        let n = self.cfg.axes();
        let next = match self.ring {
            // A copy back at port A names the break by the furthest slave that wrote its
            // slot; one with none written names nothing (nothing comes back to port A over
            // a dead link 1: the PHY tells that), nor does one in a cycle whose frame also
            // went round to port B (a reflection, not a break).
            RingState::Whole => match (self.back_a, self.port_down[0]) {
                (_, true) => Some(RingState::Broken { link: 1 }),
                (Some(a), false) if a >= 1 && !self.round_trip => Some(RingState::Broken {
                    link: (a + 1) as u32,
                }),
                _ => None,
            },
            RingState::Broken { link } => {
                let a = if self.port_down[0] {
                    Some(0)
                } else {
                    self.back_a
                };
                let b = if self.port_down[1] {
                    Some(n + 1)
                } else {
                    self.back_b
                };
                match (a, b) {
                    _ if self.round_trip && !self.port_down.iter().any(|d| *d) => {
                        Some(RingState::Whole)
                    }
                    // A slave that refused a late frame's sync leaves its slot unwritten:
                    // the copies must fail to meet for W law runs in a row, or until an
                    // axis between them has had no fresh sample for W runs (a copy the
                    // host made late leaves a run without the evidence).
                    (Some(a), Some(b)) if a + 1 < b => {
                        self.split_runs += 1;
                        self.split = Some((a, b - 2));
                        None
                    }
                    (Some(a), Some(b)) if a + 1 == b && b as u32 != link => {
                        self.split_runs = 0;
                        self.split = None;
                        Some(RingState::Broken { link: b as u32 })
                    }
                    (Some(_), Some(_)) => {
                        self.split_runs = 0;
                        self.split = None;
                        None
                    }
                    _ => None,
                }
            }
        };
        if let Some((first, last)) = self.split
            && (self.split_runs >= self.cfg.watchdog_cycles
                || self
                    .blind
                    .get(first..=last)
                    .is_some_and(|b| b.iter().any(|x| *x)))
        {
            self.pending_stop
                .get_or_insert(StopReason::RingSplit { axis: first, last });
        }
        let Some(to) = next else {
            return;
        };
        let from = self.ring;
        self.ring = to;
        self.split = None;
        self.split_runs = 0;
        match to {
            RingState::Whole => {
                self.broken = None;
                self.counters.ring_heals += 1;
            }
            RingState::Broken { link } => {
                self.broken = model.broken(link).map(|b| self.on_real_links(b));
                self.counters.ring_breaks += 1;
            }
        }
        self.sends.clear();
        for (j, &o) in self.cfg.lumped_offsets.iter().enumerate() {
            self.sends.push((o, Port::A, j));
        }
        if let Some(b) = &self.broken {
            for (j, &o) in self.cfg.lumped_offsets.iter().enumerate() {
                self.sends.push((o + b.b_delay, Port::B, j));
            }
            self.sends.sort_by_key(|s| s.0);
        }
        // This cycle's lumped frames are out: the new sends start with the next cycle.
        self.next_lumped = self.sends.len();
        self.events.push_back(MasterEvent::Ring {
            at: now,
            k: self.k,
            from,
            to,
        });
    }

    /// Hands back the buffer of a frame the driver is done with (sent, or received and
    /// handled), for the master's next sends. Optional: without it the master allocates.
    pub fn recycle(&mut self, buf: Vec<u8>) {
        self.out.recycle(buf);
    }

    /// Hands back a decoded frame the driver is done with (a lumped frame back from its
    /// round, or lost): its slots serve the next lumped frame. Optional, as
    /// [`Master::recycle`].
    pub fn recycle_pdu(&mut self, pdu: Pdu) {
        self.keep_slots(pdu);
    }

    fn keep_slots(&mut self, pdu: Pdu) {
        if let Pdu::Lumped(l) = pdu
            && l.slots.capacity() > self.empty_slots.capacity()
        {
            self.empty_slots = l.slots;
        }
    }

    /// The next frame to send, with its send instant; `None` when there is none (call after
    /// each `handle_*` until `None`).
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        let (tx, pdu) = self.out.pop_bytes()?;
        self.keep_slots(pdu);
        Some(tx)
    }

    /// The next frame to send, decoded (in place of [`Master::poll_transmit`], for a driver
    /// that carries frames without their bytes).
    #[must_use]
    pub fn poll_pdu(&mut self) -> Option<TransmitPdu> {
        self.out.pop_pdu()
    }

    /// The next frame to send with its send instant: decoded ([`Master::poll_pdu`]) when
    /// `decoded`, else as bytes ([`Master::poll_transmit`]).
    #[must_use]
    pub fn poll_frame(&mut self, decoded: bool) -> Option<(Instant, WireFrame)> {
        self.poll_frame_on(decoded).map(|(at, _, f)| (at, f))
    }

    /// [`Master::poll_frame`] with the port the frame leaves on (port A on a whole ring).
    #[must_use]
    pub fn poll_frame_on(&mut self, decoded: bool) -> Option<(Instant, Port, WireFrame)> {
        if decoded {
            self.poll_pdu()
                .map(|t| (t.at, t.port, WireFrame::Pdu(t.pdu)))
        } else {
            self.poll_transmit()
                .map(|t| (t.at, t.port, WireFrame::Bytes(t.bytes)))
        }
    }

    /// The next event for the driver; `None` when there is none (call after draining
    /// [`Master::poll_transmit`]).
    #[must_use]
    pub fn poll_event(&mut self) -> Option<MasterEvent> {
        self.events.pop_front()
    }
}

/// A time in seconds as whole nanoseconds, rounded, at least 0: `(s·10⁹).round().max(0.0) as
/// u64` without libm's `round` (`round_i64` is exact below 2⁶³ ns).
fn ns_of(s: f64) -> u64 {
    let ns = s * 1e9;
    if ns < 4e18 {
        round_i64(ns).max(0) as u64
    } else {
        ns.round() as u64
    }
}

#[cfg(test)]
mod ns_tests {
    proptest::proptest! {
        /// `ns_of` is `(s·10⁹).round().max(0.0) as u64` for any time, bit pattern or a
        /// run's seconds.
        #[test]
        fn ns_of_rounds_as_the_library_does(bits in proptest::num::u64::ANY, s in -1.0f64..1e6) {
            for s in [f64::from_bits(bits), s, s * 1e3] {
                proptest::prop_assert_eq!(super::ns_of(s), (s * 1e9).round().max(0.0) as u64);
            }
        }
    }
}
