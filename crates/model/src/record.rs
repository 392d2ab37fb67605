//! What a run records, cycle by cycle, whoever drives the nodes (the simulator or the
//! real-time runtime): the true axis states at each cycle start, the metrics (eq. 26-27),
//! the clock errors, the trace rows, the faults. Both drivers feed one [`Recorder`], so
//! their `summary.json` and `trace.csv` are the same files.

use ringsync_control::{Coupling, Metrics};
use ringsync_proto::Duration;
use ringsync_proto::node::{
    CycleRecord, MasterCounters, MasterEvent, OffReason, SafeState, SlaveCounters, StopOrder,
    StopReason, TorqueOffCause,
};

use crate::result::{Captured, LinkCounters, PassageLog, RunResult, TraceRow};

/// One axis at a cycle start, as the driver observes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisProbe {
    /// True position [rad].
    pub x: f64,
    /// Desired position [rad].
    pub x_d: f64,
    /// Slave's synchronised clock minus true time [ns].
    pub clock_error_ns: f64,
    /// Command held by the drive [V].
    pub u: f64,
    /// Whether the slave reports its command saturated.
    pub saturated: bool,
}

/// One step of a fault reaction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultStep {
    /// The master stopped the group (the axis is the one that caused it).
    GroupStop(StopReason),
    /// During the stop, the master gave the axis an order (brake, or torque off).
    Ordered(StopOrder, OffReason),
    /// The slave's watchdog expired (it lost the master) and it applied its safe state.
    Watchdog(SafeState),
    /// The drive began to brake on its own (ordered by the master, or its safe state).
    Braking {
        /// Whether the master ordered it.
        ordered: bool,
    },
    /// The axis's drive cut its torque.
    TorqueOff(TorqueOffCause),
    /// The slave's clock re-locked to a new master time line, stepping by this much.
    Relocked(Duration),
}

impl FaultStep {
    /// Short name used in summary.json.
    pub fn name(&self) -> &'static str {
        match self {
            FaultStep::GroupStop(_) => "group_stop",
            FaultStep::Ordered(StopOrder::Brake, _) => "brake_ordered",
            FaultStep::Ordered(StopOrder::TorqueOff, _) => "torque_off_ordered",
            FaultStep::Watchdog(_) => "watchdog",
            FaultStep::Braking { .. } => "braking",
            FaultStep::TorqueOff(_) => "torque_off",
            FaultStep::Relocked(_) => "clock_relock",
        }
    }
    /// One line on what happened and why (axes 1-based).
    pub fn detail(&self) -> String {
        match self {
            FaultStep::GroupStop(r) => match r {
                StopReason::FollowingError { error, .. } => {
                    format!("following error {error:.4} rad beyond the limit")
                }
                StopReason::CommandMismatch { sent, applied, .. } => {
                    format!("the slave applied {applied} V where the master sent {sent} V")
                }
                other => other.name().to_string(),
            },
            FaultStep::Ordered(_, w) => match w {
                OffReason::FollowingError { error } => {
                    format!("could not follow the stop ramp: {error:.4} rad off it")
                }
                other => other.name().to_string(),
            },
            FaultStep::Watchdog(s) => format!("master lost; safe state {}", s.name()),
            FaultStep::Braking { ordered: true } => "ordered by the master".into(),
            FaultStep::Braking { ordered: false } => "the slave's safe state".into(),
            FaultStep::TorqueOff(c) => c.name().to_string(),
            FaultStep::Relocked(step) => format!("stepped by {step}"),
        }
    }
}

/// A fault-reaction step at a time, on an axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultEvent {
    /// When [s, true time].
    pub t: f64,
    /// The axis (1-based: axis i is slave i).
    pub axis: usize,
    /// What happened.
    pub step: FaultStep,
}

/// The per-cycle recorder.
#[derive(Debug)]
pub struct Recorder {
    n: usize,
    cycles: i64,
    t_cyc: f64,
    trace_on: bool,
    probe: Vec<AxisProbe>,
    e: Vec<f64>,
    u: Vec<f64>,
    sat: Vec<bool>,
    eps: Vec<f64>,
    apply_time: Vec<f64>,
    coupling: Option<Coupling>,
    metrics: Metrics,
    trace: Vec<TraceRow>,
    pending: Vec<TraceRow>,
    clock_max: Vec<f64>,
    clock_sq: Vec<f64>,
    clock_count: u64,
    watchdog: Vec<(usize, f64)>,
    group_stop: Option<(f64, StopReason)>,
    faults: Vec<FaultEvent>,
    ring_break: Option<crate::nodes::RingBreak>,
}

impl Recorder {
    /// A recorder for `n` axes over `cycles` cycles of `t_cyc` [s]; `trace` keeps the rows.
    /// The rows of the whole run are reserved here, so that recording never reallocates
    /// mid-run (in the real-time runtime a growing trace stalled the loop by up to 0.4 ms
    /// at each doubling).
    pub fn new(n: usize, cycles: i64, t_cyc: f64, trace: bool) -> Self {
        let zero = AxisProbe {
            x: 0.0,
            x_d: 0.0,
            clock_error_ns: 0.0,
            u: 0.0,
            saturated: false,
        };
        Recorder {
            n,
            cycles,
            t_cyc,
            trace_on: trace,
            probe: vec![zero; n],
            e: vec![0.0; n],
            u: vec![0.0; n],
            sat: vec![false; n],
            eps: vec![0.0; n],
            apply_time: vec![f64::NAN; n],
            coupling: Coupling::new(n, 0.0).ok(),
            metrics: Metrics::new(n),
            trace: Vec::with_capacity(if trace {
                n.saturating_mul(usize::try_from(cycles.max(0)).unwrap_or(0) + 1)
            } else {
                0
            }),
            pending: Vec::with_capacity(n),
            clock_max: vec![0.0; n],
            clock_sq: vec![0.0; n],
            clock_count: 0,
            watchdog: Vec::new(),
            group_stop: None,
            faults: Vec::new(),
            ring_break: None,
        }
    }

    /// Moves the waiting rows to the trace with the apply times seen since.
    fn flush_trace(&mut self) {
        for mut row in self.pending.drain(..) {
            row.apply_time = self.apply_time[row.axis - 1];
            self.trace.push(row);
        }
    }

    /// Cycle k starts: `axis(i)` gives axis i's state (0-based). Clock errors count over the
    /// second half of the run.
    pub fn probe(&mut self, k: i64, mut axis: impl FnMut(usize) -> AxisProbe) {
        self.flush_trace();
        for i in 0..self.n {
            let p = axis(i);
            self.probe[i] = p;
            self.e[i] = p.x_d - p.x;
            self.u[i] = p.u;
            self.sat[i] = p.saturated;
        }
        let _ = self.metrics.push(&self.e, &self.u, &self.sat);
        if 2 * k >= self.cycles {
            self.clock_count += 1;
            for i in 0..self.n {
                let c = self.probe[i].clock_error_ns;
                self.clock_max[i] = self.clock_max[i].max(c.abs());
                self.clock_sq[i] += c * c;
            }
        }
        if let Some(c) = &self.coupling {
            let _ = c.sync_errors(&self.e, &mut self.eps);
        }
    }

    /// The master computed cycle k's commands (`r` is its record).
    pub fn computed(&mut self, k: i64, r: &CycleRecord) {
        if !self.trace_on {
            return;
        }
        let t = k as f64 * self.t_cyc;
        self.apply_time.fill(f64::NAN);
        for i in 0..self.n {
            let p = self.probe[i];
            self.pending.push(TraceRow {
                t,
                axis: i + 1,
                x_d: p.x_d,
                x: p.x,
                e: p.x_d - p.x,
                eps: self.eps[i],
                u: r.u[i],
                sample_time: r.sample_time[i],
                apply_time: f64::NAN,
                clock_error_ns: p.clock_error_ns,
            });
        }
    }

    /// Axis i (0-based) took a command at true time `t` [s].
    pub fn applied(&mut self, i: usize, t: f64) {
        self.apply_time[i] = t;
    }

    /// Slave `slave` (1-based) went to its safe state at true time `t` [s].
    pub fn watchdog(&mut self, slave: usize, t: f64) {
        self.watchdog.push((slave, t));
    }

    /// The master stopped the group at `t` [s] (the first stop counts).
    pub fn group_stop(&mut self, t: f64, reason: StopReason) {
        if self.group_stop.is_none() {
            self.group_stop = Some((t, reason));
        }
    }

    /// A fault-reaction step on axis `axis` (1-based) at true time `t` [s].
    pub fn fault(&mut self, t: f64, axis: usize, step: FaultStep) {
        self.faults.push(FaultEvent { t, axis, step });
    }

    /// What the master reported, from the driver's loop: the law's figures go to the
    /// trace, the stop and its torque-off orders to the fault log.
    pub fn master_event(&mut self, ev: MasterEvent, record: &CycleRecord) {
        match ev {
            MasterEvent::Computed { k } => self.computed(k, record),
            MasterEvent::GroupStop { at, reason } => {
                let t = at.as_ns() as f64 * 1e-9;
                self.group_stop(t, reason);
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
        }
    }

    /// Where the ring broke, located when the group stopped (the first located counts).
    pub fn ring_break(&mut self, b: crate::nodes::RingBreak) {
        self.ring_break.get_or_insert(b);
    }

    /// The first group stop, if any.
    pub fn group_stop_seen(&self) -> Option<(f64, StopReason)> {
        self.group_stop
    }

    /// The run's result.
    pub fn finish(
        mut self,
        scenario: &str,
        master: MasterCounters,
        slaves: Vec<SlaveCounters>,
        links: LinkCounters,
        passages: Vec<PassageLog>,
        captured: Vec<Captured>,
    ) -> RunResult {
        self.flush_trace();
        let n = self.clock_count.max(1) as f64;
        RunResult {
            scenario: scenario.to_string(),
            cycles: self.cycles,
            summary: self.metrics.summary(),
            master,
            slaves,
            links,
            clock_error_max_ns: self.clock_max,
            clock_error_rms_ns: self.clock_sq.iter().map(|s| (s / n).sqrt()).collect(),
            watchdog: self.watchdog,
            group_stop: self.group_stop,
            faults: self.faults,
            ring_break: self.ring_break,
            trace: self.trace,
            passages,
            captured,
        }
    }
}
