//! Where a ring broke, from the nodes' own "last seen" counters.

use ringsync_proto::Instant;
use ringsync_proto::node::{Master, Slave};

/// Where a ring broke, told from what each node last received (EtherCAT's working-counter
/// idea: every node keeps a counter of the frames it took, so the first node along the ring
/// whose counter stopped is behind the break, whatever the timing was).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingBreak {
    /// Every node still received this cycle's frames: the stop did not come from the ring.
    Whole,
    /// Slave `i` (1-based) stopped running: it neither samples nor forwards.
    Node(usize),
    /// The link from node `from` to node `to` (0 = the master, i = slave i) carries
    /// nothing, though the node behind it still runs.
    Link {
        /// Sending node (0 = master).
        from: usize,
        /// Receiving node (0 = master).
        to: usize,
    },
}

impl RingBreak {
    /// One line naming the failed node or link (nodes as "master" and "slave i").
    pub fn describe(&self) -> String {
        let node = |i: usize| {
            if i == 0 {
                "master".to_string()
            } else {
                format!("slave {i}")
            }
        };
        match *self {
            RingBreak::Whole => "none: every node received the cycle's frames".into(),
            RingBreak::Node(i) => format!("slave {i} (it stopped running)"),
            RingBreak::Link { from, to } => {
                format!(
                    "link {} → {} (the node behind it still runs)",
                    node(from),
                    node(to)
                )
            }
        }
    }

    /// The failed slave (1-based), if a node failed.
    pub fn slave(&self) -> Option<usize> {
        match *self {
            RingBreak::Node(i) => Some(i),
            _ => None,
        }
    }
}

/// Where the ring broke at the master's cycle `k`: `slaves_seen[i]` is the last cycle slave
/// i + 1 took a lumped frame of, `master_seen` the last cycle whose lumped frame came back,
/// `running[i]` whether slave i + 1 still runs. A node is behind the break when it took no
/// lumped frame of the last two cycles; the first such node along the ring names it.
pub fn locate_break(
    k: i64,
    slaves_seen: &[Option<i64>],
    master_seen: Option<i64>,
    running: &[bool],
) -> RingBreak {
    let behind = |seen: Option<i64>| seen.is_none_or(|c| c < k - 1);
    for (i, seen) in slaves_seen.iter().enumerate() {
        if behind(*seen) {
            return if running.get(i).copied().unwrap_or(true) {
                RingBreak::Link { from: i, to: i + 1 }
            } else {
                RingBreak::Node(i + 1)
            };
        }
    }
    if behind(master_seen) {
        RingBreak::Link {
            from: slaves_seen.len(),
            to: 0,
        }
    } else {
        RingBreak::Whole
    }
}

/// [`locate_break`] for a ring of nodes at the group stop at `at` (the master's time),
/// each node's "running" told by its own heartbeat: a slave runs while its encoder latches
/// keep up with the cycles (its sample counter is within two of the cycle). The cycle it
/// is told at is the master's, but no later than one after the newest whose lumped frame
/// went out a cycle time before `at` ([`Master::settled_cycle`]; in the simulator always
/// the master's): a master its host held up runs the missed cycles back to back, and nodes
/// that have not yet seen those frames are not behind a break (after such a stall the
/// nodes before a broken link had seen the cycle before the stall, and slave 1 was named).
pub fn locate_break_of(master: &Master, slaves: &[Slave], at: Instant) -> RingBreak {
    let k = master
        .settled_cycle(at)
        .map_or(master.cycle(), |c| master.cycle().min(c + 1));
    let seen: Vec<Option<i64>> = slaves.iter().map(|s| s.last_lumped_cycle()).collect();
    let running: Vec<bool> = slaves.iter().map(|s| s.samples_taken() >= k - 1).collect();
    locate_break(k, &seen, master.last_lumped_cycle(), &running)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_node_that_stopped_receiving_names_the_break() {
        let k = 100;
        let all = [true; 4];
        let fresh = [Some(100), Some(100), Some(99), Some(100)];
        assert_eq!(locate_break(k, &fresh, Some(100), &all), RingBreak::Whole);
        // Slave 3 stopped receiving at cycle 90, and so did everything after it.
        let broken = [Some(100), Some(100), Some(90), Some(90)];
        assert_eq!(
            locate_break(k, &broken, Some(90), &all),
            RingBreak::Link { from: 2, to: 3 }
        );
        // The same with slave 3 dead: the node, not the link.
        let dead = [true, true, false, true];
        assert_eq!(
            locate_break(k, &broken, Some(90), &dead),
            RingBreak::Node(3)
        );
        // Nothing ever reached slave 1.
        assert_eq!(
            locate_break(k, &[None; 4], None, &all),
            RingBreak::Link { from: 0, to: 1 }
        );
        // Every slave took its frames; the master got none back.
        assert_eq!(
            locate_break(k, &fresh, Some(80), &all),
            RingBreak::Link { from: 4, to: 0 }
        );
        assert_eq!(
            RingBreak::Link { from: 4, to: 0 }.describe(),
            "link slave 4 → master (the node behind it still runs)"
        );
    }
}
