//! Watching a run as it goes: an [`Observer`] is told every cycle start (the axes' true
//! states), every law run (what the master computed), every command a drive took and every
//! step of a fault reaction. The [recorder](crate::record::Recorder) that makes a run's
//! result is one observer; a streaming writer, a live scope or arrays for Python are others
//! ([`Devices::observe`](crate::devices::Devices::observe)).

use ringsync_proto::node::{CycleRecord, Master, Slave};

use crate::monitor::MonitorEvent;
use crate::record::{AxisProbe, FaultEvent};
use crate::result::RingChange;

/// What a run tells those who watch it. Every method has an empty default: implement what
/// you need. Times are true (master) time; axes are 0-based in the calls (1-based in
/// [`FaultEvent`], as in summary.json).
pub trait Observer: Send {
    /// Cycle `k` begins at true time `t` [s]; `axes[i]` is axis i's true state then.
    fn cycle(&mut self, k: i64, t: f64, axes: &[AxisProbe]) {
        let _ = (k, t, axes);
    }
    /// The master's law ran for cycle `k`: what it computed (in the lumped-only plan: what
    /// the slaves applied, as the returning frame tells).
    fn computed(&mut self, k: i64, record: &CycleRecord) {
        let _ = (k, record);
    }
    /// Axis `axis`'s drive took the command `u` [V] at true time `t` [s].
    fn applied(&mut self, axis: usize, t: f64, u: f64) {
        let _ = (axis, t, u);
    }
    /// One step of a fault reaction.
    fn fault(&mut self, event: &FaultEvent) {
        let _ = event;
    }
    /// A sync-error or following-error monitor raised or cleared a warning, or tripped.
    fn monitor(&mut self, event: &MonitorEvent) {
        let _ = event;
    }
    /// The master found the ring changed: a link broke, healed, or the break moved
    /// (`cycles_lost` is 0 here: it is counted afterwards, in the run's result).
    fn ring(&mut self, change: &RingChange) {
        let _ = change;
    }
    /// After the cycle start `k` (right after [`Observer::cycle`]): the nodes themselves,
    /// for their counters and states (the recorder does not need this; a live scope does).
    /// Only observers added with [`Devices::observe`](crate::devices::Devices::observe) are
    /// called.
    fn nodes(&mut self, k: i64, master: &Master, slaves: &[Slave]) {
        let _ = (k, master, slaves);
    }
    /// A real-time driver's account of cycle `k`'s start: how late the loop started it
    /// [ns] and whether the host stalled then. The simulator never calls it.
    fn timing(&mut self, k: i64, lateness_ns: i64, stalled: bool) {
        let _ = (k, lateness_ns, stalled);
    }
}
