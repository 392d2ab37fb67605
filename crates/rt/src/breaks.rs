//! Broken links as the nodes beside them sense them, as a PHY senses its link: from the
//! scenario's `faults.break_link` schedule, alike in one process and in a process per node.
//! Link `l` runs from node l − 1 to node l: link 1 from the master's port A to slave 1,
//! link n + 1 from slave n to the master's port B.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;

use ringsync_model::scenario::LinkBreak;
use ringsync_wire::Frame;

use crate::transport::Port;

/// The ring's scheduled breaks (see the module docs).
#[derive(Debug, Clone, Default)]
pub(crate) struct Breaks {
    breaks: Vec<LinkBreak>,
    /// Links in the ring: n + 1.
    links: usize,
}

impl Breaks {
    /// The breaks of a ring of `slaves` slaves.
    pub fn new(breaks: Vec<LinkBreak>, slaves: usize) -> Self {
        Breaks {
            breaks,
            links: slaves + 1,
        }
    }

    /// Whether no link ever breaks.
    pub fn is_empty(&self) -> bool {
        self.breaks.is_empty()
    }

    /// Whether link `link` is broken at true time `t` [ns].
    pub fn down(&self, link: usize, t: i64) -> bool {
        self.breaks
            .iter()
            .any(|b| b.link as usize == link && b.broken_at(t))
    }

    /// Whether slave `node` is cut off from both of the master's ports at `t` (a link
    /// broken on either side of it): what it would turn back could only go round between
    /// the breaks for ever, so it is dropped instead (as the simulator's walk gives up).
    pub fn cut_off(&self, node: usize, t: i64) -> bool {
        (1..=node).any(|l| self.down(l, t)) && (node + 1..=self.links).any(|l| self.down(l, t))
    }
}

/// How often a node reads its interfaces' carrier [ns] (a PHY's link-down detection
/// takes milliseconds too).
pub(crate) const CARRIER_POLL: i64 = 2_000_000;

/// What one node knows of its two links: from the scenario's schedule (the launcher's
/// rings, and one process), or from its interfaces' carrier (a ring on the host's own
/// interfaces, where a cable is pulled by hand). The link behind is the one frames arrive
/// on (the master's port B), the link ahead the one they leave on (its port A).
pub(crate) struct NodeLinks {
    /// 0 the master, i slave i.
    node: usize,
    schedule: Breaks,
    /// Carrier sensing: the state [behind, ahead] as last read, and when to read next.
    carrier: Option<(Cell<[bool; 2]>, Cell<i64>)>,
    /// Frames this node turned beside its broken link behind (kind, cycle, sequence
    /// number, retry), the latest last: one turned again has gone round a segment cut off at both ends.
    turned: RefCell<VecDeque<(u8, u32, u16, u8)>>,
}

impl NodeLinks {
    /// Node `node`'s links, known from `schedule`.
    pub fn scheduled(node: usize, schedule: Breaks) -> Self {
        NodeLinks {
            node,
            schedule,
            carrier: None,
            turned: RefCell::new(VecDeque::new()),
        }
    }

    /// Node `node`'s links, known from its interfaces' carrier.
    pub fn sensed(node: usize) -> Self {
        NodeLinks {
            node,
            schedule: Breaks::default(),
            carrier: Some((Cell::new([true; 2]), Cell::new(i64::MIN))),
            turned: RefCell::new(VecDeque::new()),
        }
    }

    /// Whether a link may break (then both directions are read).
    pub fn may_break(&self) -> bool {
        self.carrier.is_some() || !self.schedule.is_empty()
    }

    /// Whether the link behind is down at `t` [ns].
    pub fn behind_down(&self, t: i64) -> bool {
        match &self.carrier {
            Some((up, _)) => !up.get()[0],
            None => {
                let link = if self.node == 0 {
                    self.schedule.links
                } else {
                    self.node
                };
                self.schedule.down(link, t)
            }
        }
    }

    /// Whether the link ahead is down at `t` [ns].
    pub fn ahead_down(&self, t: i64) -> bool {
        match &self.carrier {
            Some((up, _)) => !up.get()[1],
            None => self.schedule.down(self.node + 1, t),
        }
    }

    /// Whether this slave is cut off from both of the master's ports at `t`
    /// ([`Breaks::cut_off`]); from the carrier, only its own two links tell (a segment cut
    /// off further away is found by [`NodeLinks::turned_before`]).
    pub fn cut_off(&self, t: i64) -> bool {
        match &self.carrier {
            Some((up, _)) => up.get() == [false, false],
            None => self.schedule.cut_off(self.node, t),
        }
    }

    /// When the carrier is next read [ns] (never, from the schedule).
    pub fn next_sense(&self) -> i64 {
        self.carrier
            .as_ref()
            .map_or(i64::MAX, |(_, next)| next.get().max(0))
    }

    /// Reads the carrier if it is due at `now` [ns]: each side's new state where it
    /// changed ([behind, ahead]).
    pub fn sense(&self, port: &dyn Port, now: i64) -> [Option<bool>; 2] {
        let Some((up, next)) = &self.carrier else {
            return [None; 2];
        };
        if now < next.get() {
            return [None; 2];
        }
        next.set(now + CARRIER_POLL);
        let Some(read) = port.links_up() else {
            return [None; 2];
        };
        let was = up.replace(read);
        [0, 1].map(|s| (was[s] != read[s]).then_some(read[s]))
    }

    /// Whether the frame `bytes`, about to be turned here, was turned here before: from
    /// the carrier a node cannot tell that a link further away is broken too, and a frame
    /// in a segment cut off at both ends would go round it for ever. Remembers it.
    pub fn turned_before(&self, bytes: &[u8]) -> bool {
        // (From the schedule, `cut_off` knows every break.)
        if self.carrier.is_none() {
            return false;
        }
        let Ok(f) = Frame::new_checked(bytes) else {
            return false;
        };
        let id = (f.kind_byte(), f.cycle(), f.seq(), f.retry());
        let mut seen = self.turned.borrow_mut();
        if seen.contains(&id) {
            return true;
        }
        if seen.len() == TURNED_KEPT {
            seen.pop_front();
        }
        seen.push_back(id);
        false
    }
}

/// How many turned frames a node remembers.
const TURNED_KEPT: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    /// Links 2 and 4 of a four-slave ring broken: slaves 2 and 3 are cut off, 1 and 4 are
    /// not; after the heal of link 4 nobody is.
    #[test]
    fn a_slave_between_two_breaks_is_cut_off() {
        let b = |s: &str| s.parse::<LinkBreak>().expect("break");
        let breaks = Breaks::new(vec![b("2@1s"), b("4@2s..3s")], 4);
        let s = 1_000_000_000;
        assert!(breaks.down(2, s) && !breaks.down(2, s - 1));
        assert!(!breaks.down(4, s) && breaks.down(4, 2 * s) && !breaks.down(4, 3 * s));
        for (node, cut) in [(1, false), (2, true), (3, true), (4, false)] {
            assert_eq!(breaks.cut_off(node, 2 * s), cut, "slave {node}");
            assert!(!breaks.cut_off(node, 3 * s), "slave {node} after the heal");
        }
    }

    /// A node's link behind is the one frames arrive on (the master's port B, link n + 1),
    /// the one ahead the one they leave on; from the carrier a frame turned twice is a
    /// frame going round a segment cut off at both ends, a retried one is not.
    #[test]
    fn a_node_knows_its_links_behind_and_ahead() {
        let b = |s: &str| s.parse::<LinkBreak>().expect("break");
        let breaks = Breaks::new(vec![b("1@1s"), b("5@2s")], 4);
        let s = 1_000_000_000;
        let master = NodeLinks::scheduled(0, breaks.clone());
        assert!(master.ahead_down(s) && !master.behind_down(s));
        assert!(master.behind_down(2 * s) && master.may_break());
        let slave1 = NodeLinks::scheduled(1, breaks);
        assert!(slave1.behind_down(s) && !slave1.ahead_down(s));
        let sensed = NodeLinks::sensed(2);
        assert!(sensed.may_break() && !sensed.behind_down(0) && !sensed.cut_off(0));
        let frame = |retry: u8| {
            let mut v = Vec::new();
            ringsync_wire::Pdu::Command(ringsync_wire::CommandRepr {
                common: ringsync_wire::Common {
                    retry,
                    cycle: 7,
                    seq: 3,
                    ..ringsync_wire::Common::default()
                },
                target: 2,
                command_v: 1.0,
                sample_time_ns: 5,
                link_ns: 0,
            })
            .emit_into(&mut v)
            .expect("emit");
            v
        };
        assert!(!sensed.turned_before(&frame(0)));
        assert!(sensed.turned_before(&frame(0)), "the same frame again");
        assert!(
            !sensed.turned_before(&frame(1)),
            "its retry is another frame"
        );
        // From the schedule, the cut-off test knows every break.
        assert!(!slave1.turned_before(&frame(0)) && !slave1.turned_before(&frame(0)));
    }
}
