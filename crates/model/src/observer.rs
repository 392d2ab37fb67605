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
    /// Cycle `k` begins at true time `t` \[s\]; `axes[i]` is axis i's true state then.
    fn cycle(&mut self, k: i64, t: f64, axes: &[AxisProbe]) {
        let _ = (k, t, axes);
    }
    /// The master's law ran for cycle `k`: what it computed (in the lumped-only plan: what
    /// the slaves applied, as the returning frame tells).
    fn computed(&mut self, k: i64, record: &CycleRecord) {
        let _ = (k, record);
    }
    /// Axis `axis`'s drive took the command `u` \[V\] at true time `t` \[s\].
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
    /// called. By default, what [`Observer::node_views`] is told of them.
    fn nodes(&mut self, k: i64, master: &Master, slaves: &[Slave]) {
        let m = NodeView::of_master(master);
        let views: Vec<NodeView> = std::iter::once(m)
            .chain(slaves.iter().map(|s| {
                NodeView::of_slave(s, master.cycle()).with_master_stopping(master.is_stopping())
            }))
            .collect();
        self.node_views(k, &views);
    }
    /// After the cycle start `k`: each node's counters and state, the master's first, then
    /// slave 1's … (what [`Observer::nodes`] tells by default; a ring of node processes,
    /// whose nodes are elsewhere, tells only this).
    fn node_views(&mut self, k: i64, views: &[NodeView]) {
        let _ = (k, views);
    }
    /// A real-time driver's account of cycle `k`'s start: how late the loop started it
    /// \[ns\] and whether the host stalled then. The simulator never calls it.
    fn timing(&mut self, k: i64, lateness_ns: i64, stalled: bool) {
        let _ = (k, lateness_ns, stalled);
    }
}

/// The states a live view gives a node ([`NodeView::state`]).
pub mod node_state {
    /// Running.
    pub const RUNNING: u32 = 0;
    /// The group stop is under way.
    pub const STOPPING: u32 = 1;
    /// Braking on its own.
    pub const BRAKING: u32 = 2;
    /// Torque off.
    pub const TORQUE_OFF: u32 = 3;
    /// No lumped frame reached it for 2 cycles or more.
    pub const SILENT: u32 = 4;
    /// In its safe state after a fault.
    pub const FAULT: u32 = 5;
    /// Names, by code.
    pub const NAMES: [&str; 6] = [
        "running",
        "stopping",
        "braking",
        "torque off",
        "silent",
        "fault",
    ];
}

/// One node at a cycle start, as a live scope shows it: four counters and a state (the
/// master's: frames sent, refused, retries, frames lost; a slave's: syncs and commands
/// taken, refused, duplicates, cycles without a sync), and a slave's drive flags.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct NodeView {
    /// The four counters (see the type's docs).
    pub counters: [u64; 4],
    /// A [`node_state`] code.
    pub state: u32,
    /// The master's group stop is under way.
    pub stopping: bool,
    /// A slave's drive has its torque off.
    pub torque_off: bool,
    /// A slave's drive is braking.
    pub braking: bool,
    /// A slave's watchdog expired.
    pub watchdog: bool,
}

impl NodeView {
    /// The master's view.
    pub fn of_master(m: &Master) -> Self {
        let c = m.counters();
        let stopping = m.is_stopping();
        NodeView {
            counters: [
                c.frames_sent,
                c.rejected.total(),
                c.retries,
                c.lumped_lost + c.commands_lost,
            ],
            state: if stopping {
                node_state::STOPPING
            } else {
                node_state::RUNNING
            },
            stopping,
            ..NodeView::default()
        }
    }

    /// A slave's view at the master's cycle `k`, as the slave alone knows it (the master's
    /// group stop added by [`NodeView::with_master_stopping`]).
    pub fn of_slave(s: &Slave, k: i64) -> Self {
        use ringsync_wire::Status;
        let c = s.counters();
        let st = s.status();
        let silent = s.last_lumped_cycle().is_none_or(|l| l + 2 < k) && k >= 2;
        let state = if st.contains(Status::FAULT) {
            node_state::FAULT
        } else if s.torque_off() {
            node_state::TORQUE_OFF
        } else if st.contains(Status::BRAKING) {
            node_state::BRAKING
        } else if silent {
            node_state::SILENT
        } else if st.contains(Status::STOPPING) {
            node_state::STOPPING
        } else {
            node_state::RUNNING
        };
        NodeView {
            counters: [
                c.syncs + c.commands,
                c.rejected.total(),
                c.duplicates,
                u64::try_from(k).unwrap_or(0).saturating_sub(c.syncs),
            ],
            state,
            stopping: false,
            torque_off: s.torque_off(),
            braking: st.contains(Status::BRAKING),
            watchdog: st.contains(Status::WATCHDOG),
        }
    }

    /// A slave's view once the master's group stop is known: stopping, and a running
    /// slave shown as stopping.
    pub fn with_master_stopping(mut self, stopping: bool) -> Self {
        if stopping {
            self.stopping = true;
            if self.state == node_state::RUNNING {
                self.state = node_state::STOPPING;
            }
        }
        self
    }
}
