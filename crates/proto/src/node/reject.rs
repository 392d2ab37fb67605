//! Frame acceptance: nothing from the wire is trusted. A CRC only says that the bytes are
//! the ones a sender wrote, not that the sender is the master, nor that the frame belongs to
//! this cycle. Every node checks each received frame against its own state (cycle,
//! source, target, the echo of what it sent, sequence, timestamps against its own clock)
//! before the frame changes anything. A refused frame changes nothing and is counted here,
//! per reason.

/// Why a node refused a frame (or, at the master, one feedback slot of a lumped frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reject {
    /// Bad CRC, header, flags or payload layout (what the wire layer refuses).
    Malformed,
    /// A kind this node never receives in its plan or its phase (a command at the master, a
    /// lumped-only frame on the proposed plan's ring, a sync frame before a slave has its
    /// path delay, a delay probe once it runs, …).
    UnexpectedKind,
    /// The cycle counter is not the cycle in progress by the node's own clock (a command
    /// for another cycle, a lumped frame whose cycle does not match its own timestamp).
    WrongCycle,
    /// A timestamp ahead of the node's own clock by more than the path delay and the
    /// clock tolerance allow (a sample from the future, a sync from the future).
    FutureTimestamp,
    /// Older than what the node last accepted from the same source, or later than the
    /// node's clock allows for a frame of the cycle in progress.
    Stale,
    /// The same frame again: a lumped frame back twice, a command or response already taken.
    Duplicate,
    /// Not an answer to anything the node asked: a returning lumped frame that is not one
    /// the master sent (stamp, sequence or layout differ), a response from a slave whose
    /// slice is not open.
    Unsolicited,
    /// A wire value beyond what the node can use: arithmetic on it would overflow (a
    /// timestamp beyond the time line), or a path delay not shorter than the cycle.
    Overflow,
}

impl Reject {
    /// Every reason, in the order of the counters.
    pub const ALL: [Reject; 8] = [
        Reject::Malformed,
        Reject::UnexpectedKind,
        Reject::WrongCycle,
        Reject::FutureTimestamp,
        Reject::Stale,
        Reject::Duplicate,
        Reject::Unsolicited,
        Reject::Overflow,
    ];

    /// The name used in summary.json and the runtime's progress line.
    pub fn name(self) -> &'static str {
        match self {
            Reject::Malformed => "malformed",
            Reject::UnexpectedKind => "unexpected_kind",
            Reject::WrongCycle => "wrong_cycle",
            Reject::FutureTimestamp => "future_timestamp",
            Reject::Stale => "stale",
            Reject::Duplicate => "duplicate",
            Reject::Unsolicited => "unsolicited",
            Reject::Overflow => "overflow",
        }
    }
}

impl core::fmt::Display for Reject {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Frames (and feedback slots) a node refused, per reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Rejections {
    counts: [u64; 8],
}

impl Rejections {
    /// Counts one refusal.
    pub fn count(&mut self, r: Reject) {
        let i = Reject::ALL.iter().position(|x| *x == r).unwrap_or(0);
        self.counts[i] = self.counts[i].saturating_add(1);
    }
    /// Refusals for reason `r`.
    pub fn get(&self, r: Reject) -> u64 {
        Reject::ALL
            .iter()
            .position(|x| *x == r)
            .map_or(0, |i| self.counts[i])
    }
    /// Every refusal.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }
    /// (reason, count) for every reason, in a fixed order.
    pub fn iter(&self) -> impl Iterator<Item = (Reject, u64)> + '_ {
        Reject::ALL.iter().copied().zip(self.counts.iter().copied())
    }
    /// The sum of two sets of counters.
    pub fn plus(mut self, other: &Rejections) -> Rejections {
        for (a, b) in self.counts.iter_mut().zip(other.counts) {
            *a = a.saturating_add(b);
        }
        self
    }
}

/// The full cycle index congruent to the wire's 32-bit `cycle` that lies nearest to
/// `near` (the node's own idea of the cycle): the wire counter wraps, the nodes count in i64.
pub fn unwrap_cycle(cycle: u32, near: i64) -> i64 {
    let d = cycle.wrapping_sub(near as u32) as i32;
    near.saturating_add(i64::from(d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_per_reason() {
        let mut r = Rejections::default();
        r.count(Reject::WrongCycle);
        r.count(Reject::WrongCycle);
        r.count(Reject::Overflow);
        assert_eq!(r.get(Reject::WrongCycle), 2);
        assert_eq!(r.get(Reject::Overflow), 1);
        assert_eq!(r.get(Reject::Stale), 0);
        assert_eq!(r.total(), 3);
        assert_eq!(r.plus(&r).total(), 6);
        let names: Vec<&str> = r.iter().map(|(k, _)| k.name()).collect();
        assert_eq!(names.len(), 8);
        assert_eq!(names[2], "wrong_cycle");
    }

    #[test]
    fn wire_cycles_unwrap_near_the_node_cycle() {
        assert_eq!(unwrap_cycle(7, 7), 7);
        assert_eq!(unwrap_cycle(6, 7), 6);
        assert_eq!(unwrap_cycle(9, 7), 9);
        // Across the 32-bit wrap.
        let near = (1i64 << 32) + 2;
        assert_eq!(unwrap_cycle(u32::MAX, near), (1i64 << 32) - 1);
        assert_eq!(unwrap_cycle(3, near), (1i64 << 32) + 3);
        assert_eq!(unwrap_cycle(0, -1), 0);
    }
}
