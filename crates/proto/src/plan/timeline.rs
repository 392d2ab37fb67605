//! The event-level timeline of one cycle: every frame on every node of the physical ring
//! path, first and last bit, in nanoseconds from the cycle start.

use serde::Serialize;

use super::CyclePlan;
use crate::time::{Duration, Instant};

/// A node of the ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Node {
    /// The master, node 0.
    Master,
    /// Slave i, 1-based.
    Slave(u32),
}

/// Which frame of the cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameRef {
    /// Lumped frame j of the train (0-based).
    Lumped(u32),
    /// The command to slave i.
    Command(u32),
    /// The response of slave i.
    Response(u32),
}

/// An interval on one node's MAC: first bit to last bit [ns from the cycle start].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Span {
    /// First bit.
    pub start: Instant,
    /// Last bit.
    pub end: Instant,
}

/// One frame at one node: when it came in and, if the node sends or forwards it, when it
/// went out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Passage {
    /// The frame.
    pub frame: FrameRef,
    /// The node.
    pub node: Node,
    /// Reception at this node's MAC (none at the sender).
    pub rx: Option<Span>,
    /// Transmission from this node's MAC (none at the final receiver).
    pub tx: Option<Span>,
}

/// A phase of the cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseKind {
    /// Clock-sync phase: the lumped frame(s) round the ring.
    Sync,
    /// T_rest: the master computes.
    Rest,
    /// The time slice of slave i.
    Slice(u32),
    /// Reserve slice k (1-based) for retries.
    Reserve(u32),
    /// Idle until the next cycle.
    Idle,
}

/// A phase with its bounds [ns from the cycle start].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Phase {
    /// Which phase.
    pub kind: PhaseKind,
    /// Start.
    pub start: Instant,
    /// End.
    pub end: Instant,
}

/// Every frame passage and every phase of one loss-free cycle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Timeline {
    /// Cycle time \[ns\].
    pub t_cyc: Duration,
    /// Frame passages, in the order the frames are sent, each frame along its path.
    pub passages: Vec<Passage>,
    /// Phases in time order.
    pub phases: Vec<Phase>,
}

/// Sends frames along ring paths and records their passages.
struct Router {
    passages: Vec<Passage>,
    /// First-bit latency of one hop [ns].
    hop: Duration,
    /// Residence of a forwarding slave [ns].
    residence: Duration,
}

impl Router {
    /// Follows one frame from `origin` (first bit out at `t0`, `dur` long) through `path`;
    /// every node but the last forwards it after the residence. Returns when its last bit
    /// reaches the last node.
    fn route(
        &mut self,
        frame: FrameRef,
        origin: Node,
        (t0, dur): (Instant, Duration),
        path: impl Iterator<Item = Node>,
    ) -> Instant {
        let mut path = path.peekable();
        self.passages.push(Passage {
            frame,
            node: origin,
            rx: None,
            tx: Some(Span {
                start: t0,
                end: t0 + dur,
            }),
        });
        let mut tx_start = t0;
        let mut last_end = t0 + dur;
        while let Some(node) = path.next() {
            let rx_start = tx_start + self.hop;
            let rx = Span {
                start: rx_start,
                end: rx_start + dur,
            };
            last_end = rx.end;
            let tx = path.peek().is_some().then(|| {
                tx_start = rx_start + self.residence;
                Span {
                    start: tx_start,
                    end: tx_start + dur,
                }
            });
            self.passages.push(Passage {
                frame,
                node,
                rx: Some(rx),
                tx,
            });
        }
        last_end
    }
}

impl Timeline {
    pub(super) fn build(plan: &CyclePlan) -> Timeline {
        let n = plan.params.slaves;
        let gap = plan.link.gap();
        let slaves = move || (1..=n).map(Node::Slave);
        let mut r = Router {
            passages: Vec::new(),
            hop: plan.hop,
            residence: plan.params.residence,
        };
        let mut back = Instant::ZERO;
        for (j, &dur) in plan.lumped.frame_time.iter().enumerate() {
            let t0 = Instant::ZERO + plan.lumped.frame_offset(j, gap);
            let path = slaves().chain(core::iter::once(Node::Master));
            back = r.route(FrameRef::Lumped(j as u32), Node::Master, (t0, dur), path);
        }
        let p2p = Instant::ZERO + plan.event.p2p_start;
        let mut phases = vec![
            Phase {
                kind: PhaseKind::Sync,
                start: Instant::ZERO,
                end: back,
            },
            Phase {
                kind: PhaseKind::Rest,
                start: back,
                end: p2p,
            },
        ];
        let mut start = p2p;
        for i in 1..=n {
            let cmd_end = r.route(
                FrameRef::Command(i),
                Node::Master,
                (start, plan.t_cmf),
                (1..=i).map(Node::Slave),
            );
            let resp_start = cmd_end + plan.params.response_delay;
            let path = (i + 1..=n)
                .map(Node::Slave)
                .chain(core::iter::once(Node::Master));
            let end = r.route(
                FrameRef::Response(i),
                Node::Slave(i),
                (resp_start, plan.t_rmf),
                path,
            );
            let end = end + plan.event.turnaround;
            phases.push(Phase {
                kind: PhaseKind::Slice(i),
                start,
                end,
            });
            start = end;
        }
        for k in 1..=plan.reserve_slices {
            let end = start + plan.event.reserve_slice;
            phases.push(Phase {
                kind: PhaseKind::Reserve(k),
                start,
                end,
            });
            start = end;
        }
        let cycle_end = Instant::ZERO + plan.params.t_cyc;
        if cycle_end > start {
            phases.push(Phase {
                kind: PhaseKind::Idle,
                start,
                end: cycle_end,
            });
        }
        Timeline {
            t_cyc: plan.params.t_cyc,
            passages: r.passages,
            phases,
        }
    }

    /// The phase of the given kind, if any.
    pub fn phase(&self, kind: PhaseKind) -> Option<&Phase> {
        self.phases.iter().find(|p| p.kind == kind)
    }

    /// End of the last non-idle phase [ns from the cycle start].
    pub fn busy_end(&self) -> Instant {
        self.phases
            .iter()
            .filter(|p| p.kind != PhaseKind::Idle)
            .map(|p| p.end)
            .max()
            .unwrap_or(Instant::ZERO)
    }
}
