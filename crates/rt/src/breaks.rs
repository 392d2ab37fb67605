//! Broken links as the nodes beside them sense them, as a PHY senses its link: from the
//! scenario's `faults.break_link` schedule, alike in one process and in a process per node.
//! Link `l` runs from node l − 1 to node l: link 1 from the master's port A to slave 1,
//! link n + 1 from slave n to the master's port B.

use ringsync_model::scenario::LinkBreak;

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
}
