//! The motion application: what the master runs at each P2P start, behind a small trait, so
//! that the protocol ([`Master`](super::Master)) knows nothing of trajectories, control laws,
//! units or stop ramps. `ringsync-model` implements it with the control library's laws
//! (`ControlMotion`); [`testbed`](super::testbed) has a minimal one for the protocol's tests.
//!
//! The master calls [`Motion::compute`] once per cycle with the feedback it took (raw wire
//! values: encoder counts, counts/s, ns) and what its own supervision found (which axes are
//! blind, a stop the protocol raised). The motion returns a command per axis, the stop it
//! decided (if any), the orders it gives during a stop, and the cycle's record. In the
//! lumped-only plan the master does not command the axes; it calls [`Motion::compute`] with
//! `commanded = false` for supervision only.

use ringsync_wire::FeedbackSlot;

use super::master::{OffReason, StopOrder, StopReason};
use crate::time::{Duration, Instant};

/// A desired state: position \[rad\] and velocity [rad/s].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Setpoint {
    /// Position \[rad\].
    pub x: f64,
    /// Velocity [rad/s].
    pub v: f64,
}

/// What the master computed in one cycle (for traces).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CycleRecord {
    /// Cycle index k.
    pub k: i64,
    /// Sampling instant of each axis's latest sample [s, synchronised clock].
    pub sample_time: Vec<f64>,
    /// Measured position of each axis \[rad\].
    pub position: Vec<f64>,
    /// Whether the sample is from this cycle.
    pub fresh: Vec<bool>,
    /// Command sent to each axis \[V\].
    pub u: Vec<f64>,
    /// Whether it was clipped.
    pub saturated: Vec<bool>,
    /// Planned arrival of each command \[s\].
    pub apply_time: Vec<f64>,
}

impl CycleRecord {
    /// A zero record for `n` axes.
    pub fn new(n: usize) -> Self {
        CycleRecord {
            k: 0,
            sample_time: vec![0.0; n],
            position: vec![0.0; n],
            fresh: vec![false; n],
            u: vec![0.0; n],
            saturated: vec![false; n],
            apply_time: vec![0.0; n],
        }
    }
}

/// What the master hands the motion at the P2P start of cycle k.
#[derive(Debug, Clone, Copy)]
pub struct MotionInput<'a> {
    /// Cycle index k.
    pub k: i64,
    /// When the law runs [master ns].
    pub now: Instant,
    /// The cycle's start k·T_cyc [master ns].
    pub cycle_start: Instant,
    /// Latest accepted sample of each axis (raw wire values), if any yet.
    pub samples: &'a [Option<FeedbackSlot>],
    /// Whether the sample is new to the law: no law run has taken it yet (in the lumped-only
    /// plan: it came back this cycle).
    pub fresh: &'a [bool],
    /// Axes without a new sample for W cycles (the master's feedback watchdog).
    pub blind: &'a [bool],
    /// When each axis's command takes effect, from the cycle start.
    pub command_arrival: &'a [Duration],
    /// A stop the protocol raised since the last run (no response, command mismatch).
    pub pending: Option<StopReason>,
    /// Whether the master commands the axes (false in the lumped-only plan: supervision
    /// only, no commands, no per-axis orders).
    pub commanded: bool,
}

/// Which monitor of the motion, and which of its two limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum MonitorKind {
    /// The sync error ε's warning limit.
    SyncWarning,
    /// The sync error ε's trip limit.
    SyncTrip,
    /// The following error's warning limit.
    FollowingWarning,
    /// The following error's trip limit.
    FollowingTrip,
}

impl MonitorKind {
    /// The monitor's name in outputs: `sync` or `following`.
    pub fn monitor(self) -> &'static str {
        match self {
            MonitorKind::SyncWarning | MonitorKind::SyncTrip => "sync",
            MonitorKind::FollowingWarning | MonitorKind::FollowingTrip => "following",
        }
    }
    /// The limit's name in outputs: `warning` or `trip`.
    pub fn level(self) -> &'static str {
        match self {
            MonitorKind::SyncWarning | MonitorKind::FollowingWarning => "warning",
            MonitorKind::SyncTrip | MonitorKind::FollowingTrip => "trip",
        }
    }
}

/// A monitor's news about one axis in one law run: a limit exceeded for its filter time
/// (raised), or a warning whose value came back within its limit (cleared; a trip latches).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorNews {
    /// The axis (0-based).
    pub axis: usize,
    /// Which monitor and limit.
    pub kind: MonitorKind,
    /// Raised (true) or cleared (false).
    pub raised: bool,
    /// The monitored value then (ε or the following error) \[rad\].
    pub value: f64,
}

/// What the motion returns for one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionOutput {
    /// Command per axis \[V\] (0 for an axis the motion cannot control).
    pub u: Vec<f64>,
    /// Whether the command was clipped to the drive's range.
    pub saturated: Vec<bool>,
    /// The stop that began in this run, if any.
    pub stop: Option<StopReason>,
    /// Orders given in this run during a stop: (axis, order, why).
    pub orders: Vec<(usize, StopOrder, OffReason)>,
    /// What the motion's monitors raised or cleared in this run.
    pub monitor: Vec<MonitorNews>,
    /// The cycle's figures.
    pub record: CycleRecord,
}

impl MotionOutput {
    /// An empty output for `n` axes.
    pub fn new(n: usize) -> Self {
        MotionOutput {
            u: vec![0.0; n],
            saturated: vec![false; n],
            stop: None,
            orders: Vec::new(),
            monitor: Vec::new(),
            record: CycleRecord::new(n),
        }
    }
}

/// The motion application a master runs (see the module docs).
pub trait Motion: Send {
    /// Number of axes.
    fn axes(&self) -> usize;
    /// Runs the cycle: supervision (a stop decided here, or one the protocol raised, begins
    /// the group stop), the law, the record. `out.stop` and `out.orders` report only what
    /// began or was ordered in this run.
    fn compute(&mut self, input: &MotionInput<'_>, out: &mut MotionOutput);
    /// Whether the group is stopping.
    fn is_stopping(&self) -> bool;
    /// The desired state of axis `axis` at `t` \[s\] (the stop ramp once stopping).
    fn desired(&self, axis: usize, t: f64) -> Setpoint;
}

/// A boxed motion is a motion.
impl<M: Motion + ?Sized> Motion for Box<M> {
    fn axes(&self) -> usize {
        (**self).axes()
    }
    fn compute(&mut self, input: &MotionInput<'_>, out: &mut MotionOutput) {
        (**self).compute(input, out)
    }
    fn is_stopping(&self) -> bool {
        (**self).is_stopping()
    }
    fn desired(&self, axis: usize, t: f64) -> Setpoint {
        (**self).desired(axis, t)
    }
}
