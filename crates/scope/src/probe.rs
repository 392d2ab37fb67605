//! The scope's [`Observer`]: it runs where the ring's driver runs (in `ringsync rt`, the
//! real-time loop), turns each cycle into one fixed-size [`Row`] and hands it over a
//! bounded channel with `try_send`. When the channel is full the row is dropped and
//! counted (halscope's overrun count); the loop never waits for the scope and never
//! allocates for it. The server's pump drains the channel (`try_recv` only, so the sender
//! never takes the channel's waker lock).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::Instant;

use ringsync::layers::model::monitor::MonitorEvent;
use ringsync::layers::model::observer::NodeView;
use ringsync::layers::model::result::RingChange;
use ringsync::layers::proto::node::MonitorKind;
use ringsync::{AxisProbe, FaultEvent, FaultStep, Observer};

use crate::ab::AbReport;
use crate::frame::NODE_FIELDS;

/// Most axes the scope shows (the first ones of a larger ring).
pub const MAX_AXES: usize = 16;
/// Columns per axis: e \[rad\], ε \[rad\], x^d \[rad\], u \[V\], clock error \[ns\], status bits.
pub const PER_AXIS: usize = 6;
/// Columns before the axes: t \[s\], cycle-start lateness \[µs\] (NaN when unknown: sim).
pub const LEAD: usize = 2;
/// Most columns of a row.
pub const MAX_COLUMNS: usize = LEAD + PER_AXIS * MAX_AXES;
/// Most nodes (master and slaves) of a row.
pub const MAX_NODES: usize = MAX_AXES + 1;
/// Rows the channel holds: 2 s of a 1 ms ring.
pub const CAPACITY: usize = 2048;

/// Status bits of an axis (the status column).
pub mod status {
    /// In sync: the sync monitor neither warns nor has tripped.
    pub const IN_SYNC: u32 = 1;
    /// The sync-error warning is raised.
    pub const SYNC_WARNING: u32 = 2;
    /// The sync-error monitor tripped (latched).
    pub const SYNC_TRIP: u32 = 4;
    /// The following-error warning is raised.
    pub const FOLLOWING_WARNING: u32 = 8;
    /// The following-error monitor tripped (latched).
    pub const FOLLOWING_TRIP: u32 = 16;
    /// The axis stops on its ramp (group stop).
    pub const STOPPING: u32 = 32;
    /// The drive's torque is off.
    pub const TORQUE_OFF: u32 = 64;
    /// The drive brakes on its own (lost master, or ordered).
    pub const BRAKING: u32 = 128;
    /// The slave's watchdog expired (no command for W cycles).
    pub const WATCHDOG: u32 = 256;
}

/// Node states (the node block's `state` field).
pub use ringsync::layers::model::observer::node_state;

/// One cycle as the scope sees it.
#[derive(Debug, Clone, Copy)]
pub struct Row {
    /// Cycle index k.
    pub k: i64,
    /// The columns (the first `LEAD + PER_AXIS·n` used).
    pub cols: [f32; MAX_COLUMNS],
    /// Per node: frames, rejected, retries, outages, state.
    pub nodes: [u32; MAX_NODES * NODE_FIELDS],
}

impl Row {
    fn new() -> Self {
        Row {
            k: 0,
            cols: [0.0; MAX_COLUMNS],
            nodes: [0; MAX_NODES * NODE_FIELDS],
        }
    }
}

/// Something that happened, for the page's event list (sent as JSON).
#[derive(Debug, Clone, Copy)]
pub enum Event {
    /// A monitor raised or cleared a warning, or tripped.
    Monitor(MonitorEvent),
    /// A step of a fault reaction.
    Fault(FaultEvent),
    /// The master found the ring changed (a link broke, healed, or the break moved).
    Ring(RingChange),
}

/// The receiving end, for the server's pump.
#[derive(Debug)]
pub struct Feed {
    /// Rows.
    pub rows: Receiver<Row>,
    /// Events.
    pub events: Receiver<Event>,
    /// Rows dropped because the channel was full.
    pub drops: Arc<AtomicU64>,
}

/// Paces a replay: cycle k is handed over no earlier than t_k / speed after the first.
#[derive(Debug, Clone, Copy)]
struct Pace {
    speed: f64,
    start: Option<Instant>,
}

/// The scope's observer (see the module docs).
#[derive(Debug)]
pub struct ScopeObserver {
    rows: SyncSender<Row>,
    events: SyncSender<Event>,
    drops: Arc<AtomicU64>,
    n: usize,
    row: Row,
    pending: bool,
    status: [u32; MAX_AXES],
    /// The latest lateness the driver told: (cycle, µs).
    timing: Option<(i64, f32)>,
    pace: Option<Pace>,
    /// Feeding in alternate periods only, and what each kind of period measured; sent
    /// when the observer is dropped (the run's end).
    ab: Option<(AbReport, SyncSender<AbReport>)>,
}

impl ScopeObserver {
    /// An observer of a ring of `n` axes (the first [`MAX_AXES`] shown) holding `capacity`
    /// rows, and the feed that drains it. With `pace`, cycle k is handed over no earlier
    /// than t_k / `pace` \[s\] after the first (a replay of the simulator at `pace`× real
    /// speed); without, never waits.
    pub fn new(n: usize, capacity: usize, pace: Option<f64>) -> (Self, Feed) {
        let (rows, rrx) = sync_channel(capacity.max(1));
        let (events, erx) = sync_channel(256);
        let drops = Arc::new(AtomicU64::new(0));
        let o = ScopeObserver {
            rows,
            events,
            drops: drops.clone(),
            n: n.min(MAX_AXES),
            row: Row::new(),
            pending: false,
            status: [status::IN_SYNC; MAX_AXES],
            timing: None,
            pace: pace
                .filter(|s| s.is_finite() && *s > 0.0)
                .map(|speed| Pace { speed, start: None }),
            ab: None,
        };
        (
            o,
            Feed {
                rows: rrx,
                events: erx,
                drops,
            },
        )
    }

    /// Feeds the pages in alternate periods of `period_cycles` cycles only (the first
    /// feeds) and measures the cycle-start lateness of each kind of period ([`crate::ab`]);
    /// the report arrives on the returned receiver when the observer is dropped.
    pub fn alternate(mut self, period_cycles: i64) -> (Self, Receiver<AbReport>) {
        let (tx, rx) = sync_channel(1);
        self.ab = Some((
            AbReport {
                period_cycles: period_cycles.max(1),
                ..AbReport::default()
            },
            tx,
        ));
        (self, rx)
    }

    /// Columns of a row for this ring.
    pub fn columns(&self) -> usize {
        LEAD + PER_AXIS * self.n
    }

    fn hand_over(&mut self) {
        if !std::mem::take(&mut self.pending) {
            return;
        }
        for i in 0..self.n {
            self.row.cols[LEAD + PER_AXIS * i + 5] = self.status[i] as f32;
        }
        match self.rows.try_send(self.row) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.drops.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    fn event(&mut self, e: Event) {
        // Events are rare; one that finds the queue full is lost (the status columns
        // still show the state it changed).
        let _ = self.events.try_send(e);
    }
}

impl Drop for ScopeObserver {
    fn drop(&mut self) {
        self.hand_over();
        if let Some((report, tx)) = self.ab.take() {
            let _ = tx.try_send(report);
        }
    }
}

impl Observer for ScopeObserver {
    fn cycle(&mut self, k: i64, t: f64, axes: &[AxisProbe]) {
        self.hand_over();
        if self.ab.as_ref().is_some_and(|(r, _)| !r.feeds(k)) {
            return;
        }
        if let Some(p) = &mut self.pace {
            let now = Instant::now();
            let start = *p.start.get_or_insert(now);
            let due = start + std::time::Duration::from_secs_f64((t / p.speed).max(0.0));
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        let n = self.n.min(axes.len());
        let r = &mut self.row;
        r.k = k;
        r.cols[0] = t as f32;
        r.cols[1] = match self.timing {
            Some((tk, us)) if tk == k => us,
            _ => f32::NAN,
        };
        let s: f64 = axes.iter().take(n).map(|a| a.x_d - a.x).sum();
        for (i, a) in axes.iter().take(n).enumerate() {
            let e = a.x_d - a.x;
            let eps = if n >= 2 {
                e - (s - e) / (n - 1) as f64
            } else {
                0.0
            };
            let c = &mut r.cols[LEAD + PER_AXIS * i..LEAD + PER_AXIS * (i + 1)];
            c[0] = e as f32;
            c[1] = eps as f32;
            c[2] = a.x_d as f32;
            c[3] = a.u as f32;
            c[4] = a.clock_error_ns as f32;
        }
        self.pending = true;
    }

    fn timing(&mut self, k: i64, lateness_ns: i64, _stalled: bool) {
        if let Some((r, _)) = &mut self.ab {
            if r.feeds(k) {
                r.fed.add(lateness_ns);
            } else {
                r.idle.add(lateness_ns);
            }
        }
        let us = lateness_ns as f32 * 1e-3;
        self.timing = Some((k, us));
        if self.pending && self.row.k == k {
            self.row.cols[1] = us;
        }
    }

    fn node_views(&mut self, _k: i64, views: &[NodeView]) {
        let r = &mut self.row;
        let sat = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        for (i, v) in views.iter().take(MAX_NODES).enumerate() {
            let at = i * NODE_FIELDS;
            let [a, b, c, d] = v.counters;
            r.nodes[at..at + NODE_FIELDS].copy_from_slice(&[
                sat(a),
                sat(b),
                sat(c),
                sat(d),
                v.state,
            ]);
            // Slave i's axis (i − 1): its drive's flags beside the monitors' bits.
            if i == 0 || i > self.n {
                continue;
            }
            let bits = &mut self.status[i - 1];
            let keep = status::IN_SYNC
                | status::SYNC_WARNING
                | status::SYNC_TRIP
                | status::FOLLOWING_WARNING
                | status::FOLLOWING_TRIP;
            *bits &= keep;
            for (on, b) in [
                (v.stopping, status::STOPPING),
                (v.torque_off, status::TORQUE_OFF),
                (v.braking, status::BRAKING),
                (v.watchdog, status::WATCHDOG),
            ] {
                if on {
                    *bits |= b;
                }
            }
        }
    }

    fn monitor(&mut self, ev: &MonitorEvent) {
        if let Some(bits) = ev.axis.checked_sub(1).and_then(|i| self.status.get_mut(i)) {
            let b = match ev.kind {
                MonitorKind::SyncWarning => status::SYNC_WARNING,
                MonitorKind::SyncTrip => status::SYNC_TRIP,
                MonitorKind::FollowingWarning => status::FOLLOWING_WARNING,
                MonitorKind::FollowingTrip => status::FOLLOWING_TRIP,
            };
            if ev.raised {
                *bits |= b;
            } else {
                *bits &= !b;
            }
            if *bits & (status::SYNC_WARNING | status::SYNC_TRIP) == 0 {
                *bits |= status::IN_SYNC;
            } else {
                *bits &= !status::IN_SYNC;
            }
        }
        self.event(Event::Monitor(*ev));
    }

    fn fault(&mut self, ev: &FaultEvent) {
        if !matches!(ev.step, FaultStep::Relocked(_)) || ev.t > 0.0 {
            self.event(Event::Fault(*ev));
        }
    }

    fn ring(&mut self, change: &RingChange) {
        self.event(Event::Ring(*change));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe(e: f64) -> AxisProbe {
        AxisProbe {
            x: 0.0,
            x_d: e,
            clock_error_ns: 0.0,
            u: 0.0,
            saturated: false,
        }
    }

    /// Nobody drains: the channel fills, then every further row is dropped and counted,
    /// and the observer never waits.
    #[test]
    fn a_full_buffer_drops_and_counts() {
        let (mut o, feed) = ScopeObserver::new(2, 16, None);
        for k in 0..40 {
            o.cycle(k, k as f64 * 1e-3, &[probe(0.1), probe(0.0)]);
        }
        drop(o);
        let got: Vec<Row> = feed.rows.try_iter().collect();
        assert_eq!(got.len(), 16);
        assert_eq!(got[0].k, 0);
        assert_eq!(feed.drops.load(Ordering::Relaxed), 40 - 16);
        // ε of axis 1 = 0.1 − 0/1, of axis 2 = 0 − 0.1.
        assert_eq!(got[3].cols[LEAD + 1], 0.1);
        assert_eq!(got[3].cols[LEAD + PER_AXIS + 1], -0.1);
        assert_eq!(got[3].cols[LEAD + 5], status::IN_SYNC as f32);
    }
}
