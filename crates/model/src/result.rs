//! What a run produced, whoever drove it (the simulator or the real-time runtime): the
//! metrics, the counters of every node, the trace, the faults.

use ringsync_control::Summary;
use ringsync_proto::Instant;
use ringsync_proto::node::{MasterCounters, RingState, SlaveCounters, StopReason};
use ringsync_proto::plan::{FrameRef, Node};

use crate::locate::RingBreak;
use crate::record::FaultEvent;

/// Assumptions behind a run's figures that the paper does not state (the model of the ring
/// both drivers run; the runtime names its own beside them).
pub const ASSUMPTIONS: &[&str] = &[
    "the master's clock is the reference; slave oscillators are offset and drift uniformly within the scenario's bounds",
    "slaves sample their encoders at synchronised time k·T_cyc − clock.sample_lead (0 unless the scenario sets it); velocity is the encoder difference over the velocity window",
    "a command takes effect at its last bit at the slave; frames on a link never contend (the schedule keeps them apart)",
    "Track-RMSE and Sync-RMSE use the true axis positions at each cycle start (k·T_cyc), one sample per cycle",
    "Coulomb friction uses the exact sign with stiction unless the scenario asks for the smooth tanh model",
];

/// The assumption of a run on the proposed plan (`ring.plan = "p2p-lumped"`), named after
/// [`ASSUMPTIONS`] in its outputs.
pub const P2P_ASSUMPTION: &str = "p2p-lumped plan: the master runs the law at the start of the P2P phase; time slices are fixed from the event-level cycle plan (plus jitter allowance)";

/// The assumption of a run on the lumped-only plan (`ring.plan = "lumped-only"`), named
/// after [`ASSUMPTIONS`] in its outputs.
pub const LUMPED_ONLY_ASSUMPTION: &str = "lumped-only plan: each slave evaluates the shared trajectory itself to form e_j = x^d_j(s_j) − x_j; the frame's desired fields carry the master's values for monitoring";

/// Assumptions of the coupled two-link arm (`[plant] kind = "two-link-arm"`), named after
/// [`ASSUMPTIONS`] in the outputs of a run of it (docs/simulator.md, "The plant").
pub const ARM_ASSUMPTIONS: &[&str] = &[
    "plant.kind = \"two-link-arm\": the two axes are the joints of a planar arm, M(q)q̈ + C(q,q̇)q̇ + F·q̇ = τ with p1, p2, p3 and F from [plant]; it moves in a horizontal plane (no gravity), with rigid links and viscous joint friction only (no Coulomb friction: the [[axis]] tables' mechanical keys are not used)",
    "each joint's drive is an ideal torque source, τ_i = K_a,i·sat(u_i) with K_a,i from plant.torque_constant and ±u_max of the joint's [[axis]] table (no current-loop lag); both joints advance together by RK4 (steps of at most 0.1 ms) with both commands held between events",
];

/// The assumption behind path delays the nodes measured (`clock.path_delays =
/// "measured"`), added to [`ASSUMPTIONS`] in the outputs of such a run.
pub const MEASURED_DELAY_ASSUMPTION: &str = "clock.path_delays = \"measured\": the slaves' path delays come from the nodes' start-up phase, which takes every link of the ring to have the same delay (a one-directional ring gives the master the sum of its links and the slaves their residences, not each link alone)";

/// Assumptions of a part program's run (`trajectory.kind = "program"`), named after
/// [`ASSUMPTIONS`] in its outputs (docs/programs.md).
pub const PROGRAM_ASSUMPTIONS: &[&str] = &[
    "part program: the machine's axes are rigid (a drive's position through its lead is the tool's; a gantry axis's tool position is the mean of its drives) and the program starts at the origin with every axis at 0",
    "part program: the contour error is the distance from the tool to the programmed lines and arcs within 2·|q − p_ref| + path_tolerance + 1 mm of programmed length of the reference's move, at each cycle start; rapids (G0) and cycles after a group stop are left out of its metrics",
];

/// The assumptions behind a run of scenario `s`: [`ASSUMPTIONS`], [`ARM_ASSUMPTIONS`] when
/// its plant is the two-link arm, and [`MEASURED_DELAY_ASSUMPTION`] when its path delays are
/// measured.
pub fn assumptions(s: &crate::Scenario) -> Vec<&'static str> {
    let mut v = ASSUMPTIONS.to_vec();
    v.push(match s.ring.plan {
        ringsync_proto::PlanKind::LumpedOnly => LUMPED_ONLY_ASSUMPTION,
        _ => P2P_ASSUMPTION,
    });
    if s.plant.arm().is_some() {
        v.extend_from_slice(ARM_ASSUMPTIONS);
    }
    if s.clock.path_delays == crate::scenario::PathDelays::Measured {
        v.push(MEASURED_DELAY_ASSUMPTION);
    }
    if matches!(
        s.trajectory,
        crate::scenario::TrajectorySpec::Program { .. }
    ) {
        v.extend_from_slice(PROGRAM_ASSUMPTIONS);
    }
    v
}

/// What the nodes' start-up phase measured (`clock.path_delays = "measured"`), beside the
/// planner's figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StartUp {
    /// The master's figures.
    pub measured: ringsync_proto::node::DelayMeasurement,
    /// The path delay each slave took (`None`: it never got one).
    pub taken: Vec<Option<ringsync_proto::Duration>>,
    /// The planner's event-level path delays D_i (master send to first bit in), for
    /// comparison (the runtime's links are not the plan's: there they differ).
    pub planned: Vec<ringsync_proto::Duration>,
    /// Timestamp resolution of the slaves' clocks.
    pub resolution: ringsync_proto::Duration,
    /// Frames the slaves refused during the phase.
    pub slaves_rejected: u64,
    /// How long the phase took on the master's clock.
    pub took: ringsync_proto::Duration,
}

/// One frame passage at a node, recorded for tests and traces (true time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PassageLog {
    /// Cycle index k of the frame.
    pub cycle: i64,
    /// Which frame.
    pub frame: FrameRef,
    /// Where.
    pub node: Node,
    /// First bit in \[ns\].
    pub rx_start: Instant,
    /// Last bit in \[ns\].
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
    /// Cycle start \[s\].
    pub t: f64,
    /// Axis, 1-based.
    pub axis: usize,
    /// Desired position at the cycle start \[rad\].
    pub x_d: f64,
    /// True position at the cycle start \[rad\].
    pub x: f64,
    /// e = x_d − x \[rad\].
    pub e: f64,
    /// ε \[rad\].
    pub eps: f64,
    /// Command computed in this cycle \[V\].
    pub u: f64,
    /// Sampling instant of the sample the command used \[s\].
    pub sample_time: f64,
    /// When this cycle's command took effect at the slave \[s\] (NaN if it never arrived).
    pub apply_time: f64,
    /// Slave clock minus true time at the cycle start \[ns\].
    pub clock_error_ns: f64,
}

/// A run's trace, stored by column: one group of rows per cycle the master computed, one
/// row per axis in each group. [`Trace::rows`] reads it row by row (as `trace.csv` does);
/// the columns are what arrays for numpy or a columnar file want.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trace {
    /// Number of axes n (rows per group).
    pub axes: usize,
    /// Cycle start of each group \[s\].
    pub t: Vec<f64>,
    /// Desired position at the cycle start \[rad\], group-major (n per group).
    pub x_d: Vec<f64>,
    /// True position at the cycle start \[rad\].
    pub x: Vec<f64>,
    /// ε \[rad\].
    pub eps: Vec<f64>,
    /// Command computed in the cycle \[V\].
    pub u: Vec<f64>,
    /// Sampling instant of the sample the command used \[s\].
    pub sample_time: Vec<f64>,
    /// When the cycle's command took effect at the slave \[s\] (NaN if it never arrived).
    pub apply_time: Vec<f64>,
    /// Slave clock minus true time at the cycle start \[ns\].
    pub clock_error_ns: Vec<f64>,
}

impl Trace {
    /// An empty trace of `axes` axes with room for `groups` cycles (reserved up front, so
    /// that recording never reallocates mid-run: in the real-time runtime a growing trace
    /// stalled the loop by up to 0.4 ms at each doubling).
    pub fn with_capacity(axes: usize, groups: usize) -> Self {
        let cells = axes.saturating_mul(groups);
        Trace {
            axes,
            t: Vec::with_capacity(groups),
            x_d: Vec::with_capacity(cells),
            x: Vec::with_capacity(cells),
            eps: Vec::with_capacity(cells),
            u: Vec::with_capacity(cells),
            sample_time: Vec::with_capacity(cells),
            apply_time: Vec::with_capacity(cells),
            clock_error_ns: Vec::with_capacity(cells),
        }
    }

    /// e = x_d − x of row `r` \[rad\], computed from the two columns (the same double the
    /// recorder computed; not stored: a 600 s run of 4 axes keeps 19 MB less).
    pub fn e(&self, r: usize) -> f64 {
        self.x_d[r] - self.x[r]
    }

    /// The e column \[rad\] of rows `rows`, into `out` (cleared first).
    pub fn e_into(&self, rows: std::ops::Range<usize>, out: &mut Vec<f64>) {
        out.clear();
        out.extend(
            self.x_d[rows.clone()]
                .iter()
                .zip(&self.x[rows])
                .map(|(d, x)| d - x),
        );
    }

    /// Removes every row (the room stays).
    pub fn clear(&mut self) {
        for c in [
            &mut self.t,
            &mut self.x_d,
            &mut self.x,
            &mut self.eps,
            &mut self.u,
            &mut self.sample_time,
            &mut self.apply_time,
            &mut self.clock_error_ns,
        ] {
            c.clear();
        }
    }

    /// Number of rows (groups × axes).
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there is no row.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Row `r` (group r / n, axis r mod n + 1).
    pub fn row(&self, r: usize) -> TraceRow {
        let n = self.axes.max(1);
        TraceRow {
            t: self.t[r / n],
            axis: r % n + 1,
            x_d: self.x_d[r],
            x: self.x[r],
            e: self.e(r),
            eps: self.eps[r],
            u: self.u[r],
            sample_time: self.sample_time[r],
            apply_time: self.apply_time[r],
            clock_error_ns: self.clock_error_ns[r],
        }
    }

    /// Every row in order: cycle by cycle, axis by axis.
    pub fn rows(&self) -> impl Iterator<Item = TraceRow> + '_ {
        (0..self.len()).map(|r| self.row(r))
    }
}

/// Link-level counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct LinkCounters {
    /// Frames lost on a hop.
    pub lost: u64,
    /// Frames corrupted on a hop.
    pub corrupted: u64,
    /// Events processed.
    pub events: u64,
}

/// A change of the ring the master found (ring redundancy, docs/planner.md "A broken
/// link").
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RingChange {
    /// When the master found it (its P2P start) \[s\].
    pub t: f64,
    /// The master's cycle then.
    pub k: i64,
    /// The ring before.
    pub from: RingState,
    /// The ring after.
    pub to: RingState,
    /// Law runs from this one on that lacked a fresh sample of some axis, up to the first
    /// that had every axis's (the cycles the change cost).
    pub cycles_lost: u64,
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
    /// Largest |clock error| over the second half of the run, per slave \[ns\].
    pub clock_error_max_ns: Vec<f64>,
    /// RMS clock error over the second half of the run, per slave \[ns\].
    pub clock_error_rms_ns: Vec<f64>,
    /// Mean clock error (synchronised minus true time) over the second half of the run,
    /// per slave \[ns\]: a clock's bias.
    pub clock_error_mean_ns: Vec<f64>,
    /// Watchdog expiries: (slave, true time \[s\]).
    pub watchdog: Vec<(usize, f64)>,
    /// The group stop, if any: (time \[s\], reason).
    pub group_stop: Option<(f64, StopReason)>,
    /// Every step of the fault reactions, in time order per source.
    pub faults: Vec<FaultEvent>,
    /// Where the ring broke, located from the nodes' own counters when the group stopped.
    pub ring_break: Option<RingBreak>,
    /// Every change of the ring the master found (a link broke, healed, or the break
    /// moved), in time order.
    pub ring_changes: Vec<RingChange>,
    /// Every warning and trip the sync-error and following-error monitors raised or
    /// cleared, in time order.
    pub monitor: Vec<crate::monitor::MonitorEvent>,
    /// The largest |command| the master sent to each axis, and the largest each drive
    /// applied \[V\]: a drive applies only what the master sent.
    pub command_max: (Vec<f64>, Vec<f64>),
    /// The trace (when the driver was asked to keep it).
    pub trace: Trace,
    /// Frame passages (when the simulator was asked to log them).
    pub passages: Vec<PassageLog>,
    /// Frames sent (when the driver was asked to capture them).
    pub captured: Vec<Captured>,
    /// The nodes' start-up phase, when the path delays were measured.
    pub start_up: Option<StartUp>,
    /// A part program's run: the path table, contour error and circular tests
    /// (docs/programs.md).
    pub path: Option<crate::contour::PathResult>,
}
