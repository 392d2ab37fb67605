//! What a run produced, whoever drove it (the simulator or the real-time runtime): the
//! metrics, the counters of every node, the trace, the faults.

use ringsync_control::Summary;
use ringsync_proto::Instant;
use ringsync_proto::node::{MasterCounters, SlaveCounters, StopReason};
use ringsync_proto::plan::{FrameRef, Node};

use crate::nodes::RingBreak;
use crate::record::FaultEvent;

/// Assumptions behind a run's figures that the paper does not state (the model of the ring
/// both drivers run; the runtime names its own beside them).
pub const ASSUMPTIONS: &[&str] = &[
    "the master's clock is the reference; slave oscillators are offset and drift uniformly within the scenario's bounds",
    "slaves sample their encoders at synchronised time k·T_cyc − clock.sample_lead (0 unless the scenario sets it); velocity is the encoder difference over the velocity window",
    "the master runs the law at the start of the P2P phase; time slices are fixed from the event-level cycle plan (plus jitter allowance)",
    "a command takes effect at its last bit at the slave; frames on a link never contend (the schedule keeps them apart)",
    "Track-RMSE and Sync-RMSE use the true axis positions at each cycle start (k·T_cyc), one sample per cycle",
    "Coulomb friction uses the exact sign with stiction unless the scenario asks for the smooth tanh model",
    "lumped-only plan: each slave evaluates the shared trajectory itself to form e_j = x^d_j(s_j) − x_j; the frame's desired fields carry the master's values for monitoring",
];

/// One frame passage at a node, recorded for tests and traces (true time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PassageLog {
    /// Cycle index k of the frame.
    pub cycle: i64,
    /// Which frame.
    pub frame: FrameRef,
    /// Where.
    pub node: Node,
    /// First bit in [ns].
    pub rx_start: Instant,
    /// Last bit in [ns].
    pub rx_end: Instant,
}

/// A frame as its sender put it on the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Captured {
    /// First bit out [ns, true time].
    pub t: i64,
    /// Sender: 0 = master, i = slave i.
    pub node: usize,
    /// The PDU.
    pub bytes: Vec<u8>,
}

/// One row of the trace: one cycle, one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Cycle start [s].
    pub t: f64,
    /// Axis, 1-based.
    pub axis: usize,
    /// Desired position at the cycle start [rad].
    pub x_d: f64,
    /// True position at the cycle start [rad].
    pub x: f64,
    /// e = x_d − x [rad].
    pub e: f64,
    /// ε [rad].
    pub eps: f64,
    /// Command computed in this cycle [V].
    pub u: f64,
    /// Sampling instant of the sample the command used [s].
    pub sample_time: f64,
    /// When this cycle's command took effect at the slave [s] (NaN if it never arrived).
    pub apply_time: f64,
    /// Slave clock minus true time at the cycle start [ns].
    pub clock_error_ns: f64,
}

/// Link-level counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkCounters {
    /// Frames lost on a hop.
    pub lost: u64,
    /// Frames corrupted on a hop.
    pub corrupted: u64,
    /// Events processed.
    pub events: u64,
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// Scenario name.
    pub scenario: String,
    /// Cycles run.
    pub cycles: i64,
    /// Metrics (eq. 26-27) and per-axis figures.
    pub summary: Summary,
    /// Master counters.
    pub master: MasterCounters,
    /// Per-slave counters.
    pub slaves: Vec<SlaveCounters>,
    /// Link counters.
    pub links: LinkCounters,
    /// Largest |clock error| over the second half of the run, per slave [ns].
    pub clock_error_max_ns: Vec<f64>,
    /// RMS clock error over the second half of the run, per slave [ns].
    pub clock_error_rms_ns: Vec<f64>,
    /// Watchdog expiries: (slave, true time [s]).
    pub watchdog: Vec<(usize, f64)>,
    /// The group stop, if any: (time [s], reason).
    pub group_stop: Option<(f64, StopReason)>,
    /// Every step of the fault reactions, in time order per source.
    pub faults: Vec<FaultEvent>,
    /// Where the ring broke, located from the nodes' own counters when the group stopped.
    pub ring_break: Option<RingBreak>,
    /// Trace rows (with [`RunOptions::trace`]).
    pub trace: Vec<TraceRow>,
    /// Frame passages (with [`RunOptions::log_cycles`]).
    pub passages: Vec<PassageLog>,
    /// Frames sent (with [`RunOptions::capture`]).
    pub captured: Vec<Captured>,
}
