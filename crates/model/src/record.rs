//! What a run records, cycle by cycle, whoever drives the nodes (the simulator or the
//! real-time runtime): the true axis states at each cycle start, the metrics (eq. 26-27),
//! the clock errors, the trace rows, the faults. Both drivers feed one [`Recorder`], so
//! their `summary.json` and `trace.csv` are the same files.

use ringsync_control::{Coupling, Metrics};
use ringsync_proto::Duration;
use ringsync_proto::node::{
    CycleRecord, MasterCounters, OffReason, SafeState, SlaveCounters, StopOrder, StopReason,
    TorqueOffCause,
};

use crate::locate::RingBreak;
use crate::observer::Observer;
use crate::result::{Captured, LinkCounters, PassageLog, RingChange, RunResult, Trace};
use crate::stream::TraceSink;

/// One axis at a cycle start, as the driver observes it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxisProbe {
    /// True position \[rad\].
    pub x: f64,
    /// Desired position \[rad\].
    pub x_d: f64,
    /// Slave's synchronised clock minus true time \[ns\].
    pub clock_error_ns: f64,
    /// Command held by the drive \[V\].
    pub u: f64,
    /// Whether the slave reports its command saturated.
    pub saturated: bool,
}

impl AxisProbe {
    /// An axis at rest at 0, desired 0, no clock error, 0 V.
    pub const AT_REST: AxisProbe = AxisProbe {
        x: 0.0,
        x_d: 0.0,
        clock_error_ns: 0.0,
        u: 0.0,
        saturated: false,
    };
}

/// One step of a fault reaction.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
                StopReason::SyncTrip { error, .. } => {
                    format!("sync error {error:.4} rad beyond the monitor's trip limit")
                }
                StopReason::FollowingTrip { error, .. } => {
                    format!("following error {error:.4} rad beyond the monitor's trip limit")
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
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FaultEvent {
    /// When [s, true time].
    pub t: f64,
    /// The axis (1-based: axis i is slave i).
    pub axis: usize,
    /// What happened.
    pub step: FaultStep,
}

/// The per-cycle recorder: an [`Observer`] that makes a run's [`RunResult`].
#[derive(Debug)]
pub struct Recorder {
    n: usize,
    cycles: i64,
    t_cyc: f64,
    trace_on: bool,
    probe: Vec<AxisProbe>,
    /// The cycle of `probe` and `eps`.
    probe_k: i64,
    /// The cycle before's probe and synchronisation errors, for a law run that came after
    /// the next cycle's start (a real-time master its host held up): its trace rows show
    /// its own cycle's state.
    prev: (i64, Vec<AxisProbe>, Vec<f64>),
    e: Vec<f64>,
    u: Vec<f64>,
    sat: Vec<bool>,
    eps: Vec<f64>,
    apply_time: Vec<f64>,
    coupling: Option<Coupling>,
    metrics: Metrics,
    trace: Trace,
    /// Rows of the last computed cycle wait for their apply times until the next cycle
    /// starts (or the run ends): from this row on.
    pending: Option<usize>,
    clock_max: Vec<f64>,
    clock_sq: Vec<f64>,
    clock_sum: Vec<f64>,
    clock_count: u64,
    sent_max: Vec<f64>,
    applied_max: Vec<f64>,
    watchdog: Vec<(usize, f64)>,
    group_stop: Option<(f64, StopReason)>,
    faults: Vec<FaultEvent>,
    ring_break: Option<RingBreak>,
    ring_changes: Vec<RingChange>,
    /// The ring change whose lost cycles are still being counted.
    counting: Option<usize>,
    monitor: Vec<crate::monitor::MonitorEvent>,
    /// Where complete rows go instead of the trace ([`Recorder::stream_trace`]).
    sink: Option<Box<dyn TraceSink>>,
    /// A part program's contour error and path table ([`Recorder::with_contour`]).
    contour: Option<crate::contour::ContourRecorder>,
}

impl Recorder {
    /// A recorder for `n` axes over `cycles` cycles of `t_cyc` \[s\]; `trace` keeps the
    /// trace (reserved for the whole run).
    pub fn new(n: usize, cycles: i64, t_cyc: f64, trace: bool) -> Self {
        let zero = AxisProbe::AT_REST;
        let groups = if trace {
            usize::try_from(cycles.max(0)).unwrap_or(0) + 1
        } else {
            0
        };
        Recorder {
            n,
            cycles,
            t_cyc,
            trace_on: trace,
            probe: vec![zero; n],
            probe_k: -1,
            prev: (-1, vec![zero; n], vec![0.0; n]),
            e: vec![0.0; n],
            u: vec![0.0; n],
            sat: vec![false; n],
            eps: vec![0.0; n],
            apply_time: vec![f64::NAN; n],
            coupling: Coupling::new(n, 0.0).ok(),
            metrics: Metrics::new(n),
            trace: Trace::with_capacity(n, groups),
            pending: None,
            clock_max: vec![0.0; n],
            clock_sq: vec![0.0; n],
            clock_sum: vec![0.0; n],
            clock_count: 0,
            sent_max: vec![0.0; n],
            applied_max: vec![0.0; n],
            watchdog: Vec::new(),
            group_stop: None,
            faults: Vec::new(),
            ring_break: None,
            ring_changes: Vec::new(),
            counting: None,
            monitor: Vec::new(),
            sink: None,
            contour: None,
        }
    }

    /// Records a part program's run too: the contour error every cycle, the path table
    /// (when the recorder keeps the trace) and the circular tests.
    pub fn with_contour(
        mut self,
        map: crate::scenario::MachineMap,
        path: std::sync::Arc<ringsync_path::PlannedPath>,
    ) -> Self {
        self.contour = Some(crate::contour::ContourRecorder::new(
            map,
            path,
            self.trace_on && self.sink.is_none(),
        ));
        self
    }

    /// Streams the trace to `sink` instead of keeping it (whether or not the recorder was
    /// made to keep it): each cycle's rows go there once complete, and the recorder holds
    /// one cycle's rows at most. The result's trace is then empty. (Make the recorder
    /// without the trace, so that it never reserves room for the whole run.)
    pub fn stream_trace(&mut self, sink: Box<dyn TraceSink>) {
        self.trace_on = true;
        self.trace = Trace::with_capacity(self.n, 1);
        self.sink = Some(sink);
    }

    /// Whether the trace goes to a sink.
    pub fn streams_trace(&self) -> bool {
        self.sink.is_some()
    }

    /// Rows the trace sink dropped (0 without one).
    pub fn trace_rows_dropped(&self) -> u64 {
        self.sink.as_ref().map_or(0, |s| s.dropped())
    }

    /// Gives the waiting rows the apply times seen since.
    fn flush_trace(&mut self) {
        if let Some(from) = self.pending.take() {
            for (r, a) in self.trace.apply_time[from..].iter_mut().enumerate() {
                *a = self.apply_time[r % self.n.max(1)];
            }
            if let Some(sink) = &mut self.sink {
                for row in self.trace.rows() {
                    sink.row(row);
                }
                self.trace.clear();
            }
        }
    }

    /// Where the ring broke, located when the group stopped (the first located counts).
    pub fn ring_break(&mut self, b: RingBreak) {
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
            clock_error_mean_ns: self.clock_sum.iter().map(|s| s / n).collect(),
            watchdog: self.watchdog,
            group_stop: self.group_stop,
            faults: self.faults,
            ring_break: self.ring_break,
            ring_changes: self.ring_changes,
            monitor: self.monitor,
            command_max: (self.sent_max, self.applied_max),
            trace: self.trace,
            passages,
            captured,
            start_up: None,
            path: self.contour.map(|c| c.finish()),
        }
    }
}

impl Observer for Recorder {
    /// Cycle k starts: each axis's state. Clock errors count over the second half of the
    /// run.
    fn cycle(&mut self, k: i64, t: f64, axes: &[AxisProbe]) {
        self.flush_trace();
        // Both are written whole below: the last cycle's become the previous ones.
        self.prev.0 = self.probe_k;
        std::mem::swap(&mut self.probe, &mut self.prev.1);
        std::mem::swap(&mut self.eps, &mut self.prev.2);
        self.probe_k = k;
        for (i, p) in axes.iter().enumerate().take(self.n) {
            self.probe[i] = *p;
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
                self.clock_sum[i] += c;
            }
        }
        if let Some(c) = &self.coupling {
            let _ = c.sync_errors(&self.e, &mut self.eps);
        }
        if let Some(c) = &mut self.contour {
            c.cycle(t, &self.probe, self.group_stop.is_none());
        }
    }

    /// The master found the ring changed: the law runs from then on without every axis's
    /// fresh sample count as the change's lost cycles.
    fn ring(&mut self, change: &RingChange) {
        self.counting = Some(self.ring_changes.len());
        self.ring_changes.push(RingChange {
            cycles_lost: 0,
            ..*change
        });
    }

    fn computed(&mut self, k: i64, r: &CycleRecord) {
        for (m, u) in self.sent_max.iter_mut().zip(&r.u) {
            *m = m.max(u.abs());
        }
        if let Some(c) = self.counting {
            if r.fresh.iter().all(|f| *f) {
                self.counting = None;
            } else if let Some(change) = self.ring_changes.get_mut(c) {
                change.cycles_lost += 1;
            }
        }
        if !self.trace_on {
            return;
        }
        self.apply_time.fill(f64::NAN);
        let tr = &mut self.trace;
        self.pending = Some(tr.len());
        tr.t.push(k as f64 * self.t_cyc);
        let (probe, eps) = if k != self.probe_k && k == self.prev.0 {
            (&self.prev.1, &self.prev.2)
        } else {
            (&self.probe, &self.eps)
        };
        for i in 0..self.n {
            let p = probe[i];
            tr.x_d.push(p.x_d);
            tr.x.push(p.x);
            tr.eps.push(eps[i]);
            tr.u.push(r.u[i]);
            tr.sample_time.push(r.sample_time[i]);
            tr.apply_time.push(f64::NAN);
            tr.clock_error_ns.push(p.clock_error_ns);
        }
    }

    fn applied(&mut self, axis: usize, t: f64, u: f64) {
        self.apply_time[axis] = t;
        self.applied_max[axis] = self.applied_max[axis].max(u.abs());
    }

    fn fault(&mut self, ev: &FaultEvent) {
        match ev.step {
            FaultStep::Watchdog(_) => self.watchdog.push((ev.axis, ev.t)),
            FaultStep::GroupStop(reason) if self.group_stop.is_none() => {
                self.group_stop = Some((ev.t, reason));
            }
            _ => {}
        }
        self.faults.push(*ev);
    }

    fn monitor(&mut self, ev: &crate::monitor::MonitorEvent) {
        self.monitor.push(*ev);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::result::TraceRow;
    use crate::stream::Kept;

    /// Drives a recorder through `cycles` cycles of 3 axes (probes, law runs, applied
    /// commands, one never applied), calling `each` after every cycle.
    fn drive(rec: &mut Recorder, cycles: i64, mut each: impl FnMut(&Recorder)) {
        let n = 3;
        let mut record = CycleRecord::new(n);
        for k in 0..cycles {
            let t = k as f64 * 1e-3;
            let probes: Vec<AxisProbe> = (0..n)
                .map(|i| AxisProbe {
                    x: 0.01 * (k as f64) + i as f64,
                    x_d: 0.011 * (k as f64) + i as f64,
                    clock_error_ns: (k % 7) as f64 - 3.0,
                    u: 0.1 * i as f64,
                    saturated: false,
                })
                .collect();
            rec.cycle(k, t, &probes);
            record.k = k;
            for i in 0..n {
                record.u[i] = 0.5 - 0.1 * (k as f64) * i as f64;
                record.sample_time[i] = t - 1e-4;
            }
            rec.computed(k, &record);
            // Axis 3's command of every fifth cycle never arrives.
            for i in 0..n {
                if !(i == 2 && k % 5 == 0) {
                    rec.applied(i, t + 1e-4 * (i + 1) as f64, record.u[i]);
                }
            }
            each(rec);
        }
    }

    /// The recorder's result, without node or link counters.
    fn result(rec: Recorder) -> RunResult {
        rec.finish(
            "t",
            MasterCounters::default(),
            Vec::new(),
            LinkCounters::default(),
            Vec::new(),
            Vec::new(),
        )
    }

    /// The clocks' figures count the second half of the run: per slave the largest
    /// |error|, the RMS and the mean (a clock's bias, with its sign).
    #[test]
    fn clock_figures_count_the_second_half() {
        let mut rec = Recorder::new(2, 10, 1e-3, false);
        for k in 0..10 {
            // Slave 1: 10 ns on odd cycles, 0 on even ones; slave 2: −100 ns, and −1 000 ns
            // in the first half (not counted).
            let probes: Vec<AxisProbe> = [(k % 2) as f64 * 10.0, if k < 5 { -1e3 } else { -100.0 }]
                .iter()
                .map(|&c| AxisProbe {
                    clock_error_ns: c,
                    ..AxisProbe::AT_REST
                })
                .collect();
            rec.cycle(k, k as f64 * 1e-3, &probes);
        }
        let r = result(rec);
        // Cycles 5..=9: slave 1 reads 10, 0, 10, 0, 10.
        assert_eq!(r.clock_error_max_ns, [10.0, 100.0]);
        assert_eq!(r.clock_error_mean_ns, [6.0, -100.0]);
        assert_eq!(r.clock_error_rms_ns, [60f64.sqrt(), 100.0]);
    }

    /// A law run that comes after the next cycle has started (a real-time master held up
    /// by its host) gets trace rows with its own cycle's axis states, not the next cycle's.
    #[test]
    fn a_late_law_run_records_its_own_cycles_state() {
        let n = 2;
        let mut rec = Recorder::new(n, 3, 1e-3, true);
        let probe = |k: i64| -> Vec<AxisProbe> {
            (0..n)
                .map(|i| AxisProbe {
                    x: k as f64 + 0.1 * i as f64,
                    x_d: k as f64 + 0.5,
                    clock_error_ns: k as f64,
                    u: 0.0,
                    saturated: false,
                })
                .collect()
        };
        let mut record = CycleRecord::new(n);
        rec.cycle(0, 0.0, &probe(0));
        rec.computed(0, &record);
        // Cycle 1 starts before its law runs.
        rec.cycle(1, 1e-3, &probe(1));
        rec.cycle(2, 2e-3, &probe(2));
        record.k = 1;
        rec.computed(1, &record);
        let r = result(rec);
        let t = &r.trace;
        // Rows: cycle 0's two axes, then cycle 1's.
        assert_eq!(t.t, vec![0.0, 1e-3]);
        assert_eq!(t.x, vec![0.0, 0.1, 1.0, 1.1]);
        assert_eq!(t.x_d, vec![0.5, 0.5, 1.5, 1.5]);
        assert_eq!(t.clock_error_ns, vec![0.0, 0.0, 1.0, 1.0]);
    }

    /// A streaming recorder hands on exactly the rows a keeping one keeps, apply times
    /// included (NaN where a command never arrived), and holds no more than one cycle's
    /// rows at any time: its memory does not grow with the run.
    #[test]
    fn a_streamed_trace_has_the_kept_rows_in_bounded_memory() {
        let cycles = 200;
        let mut kept = Recorder::new(3, cycles, 1e-3, true);
        drive(&mut kept, cycles, |_| {});
        let kept = result(kept);
        let sink = Kept::<TraceRow>::default();
        let rows = sink.0.clone();
        let mut streamed = Recorder::new(3, cycles, 1e-3, false);
        streamed.stream_trace(Box::new(sink));
        let mut most = 0;
        drive(&mut streamed, cycles, |r| most = most.max(r.trace.len()));
        let streamed = result(streamed);
        assert_eq!(most, 3, "one cycle's rows at most");
        assert!(streamed.trace.is_empty());
        let got = rows.lock().expect("rows").clone();
        let want: Vec<TraceRow> = kept.trace.rows().collect();
        assert_eq!(got.len(), 3 * cycles as usize);
        // (NaN apply times: compare the text.)
        assert_eq!(format!("{got:?}"), format!("{want:?}"));
        assert!(got.iter().any(|r| r.apply_time.is_nan()));
        assert_eq!(streamed.summary.sync_rmse, kept.summary.sync_rmse);
    }
}
