//! The links as the run's own sync lumped frames measure them, behind transparent relays.
//!
//! Behind transparent relays (a ring of node processes with kernel stamps) every node adds
//! to a sync lumped frame's stamp the time it held the frame, so a frame that went round
//! the whole ring comes back to the master stamped with its send time plus every
//! residence: what the master reads then, less that stamp, is the ring's n + 1 links alone.
//! The start-up phase measured one link L and each slave took i·L as its path delay; when
//! the run's links differ from the start-up's by δ, slave i's clock is off by i·δ, a bias
//! that grows along the ring (docs/runtime.md, "The links as the run measures them").
//!
//! [`LinkEstimate`] takes each round trip the master sees and, every [`WINDOW`] of them,
//! the median divided by n + 1: the master sends it with every command
//! ([`CommandRepr::link_ns`](ringsync_wire::CommandRepr)), and a slave that follows it
//! takes its address times the link as its path delay.

use crate::time::Duration;

/// Round trips per estimate: the median of this many (the kernel's stamps have a long
/// tail, hundreds of µs in a host stall, which a median rides out).
pub const WINDOW: usize = 64;

/// The master's running estimate of one link's delay from the round trips of its sync
/// lumped frames (transparent relays).
#[derive(Debug, Clone)]
pub struct LinkEstimate {
    /// Links per round trip: n + 1.
    hops: i64,
    /// The longest round trip taken [ns] (a cycle: a frame back later is not this cycle's).
    longest: i64,
    window: [i64; WINDOW],
    filled: usize,
    current: Option<Duration>,
    estimates: u64,
}

impl LinkEstimate {
    /// The estimate for a ring of `n` slaves whose frames come back within `cycle`.
    pub fn new(n: usize, cycle: Duration) -> Self {
        LinkEstimate {
            hops: i64::try_from(n).unwrap_or(i64::MAX).saturating_add(1),
            longest: cycle.as_ns(),
            window: [0; WINDOW],
            filled: 0,
            current: None,
            estimates: 0,
        }
    }

    /// A sync lumped frame that went round the whole ring came back at `now` [ns, master
    /// clock] stamped `stamp` \[ns\]. A round trip below zero or beyond a cycle is not taken
    /// (returns false).
    pub fn note(&mut self, now: i64, stamp: u64) -> bool {
        let Some(rt) = i64::try_from(stamp).ok().and_then(|s| now.checked_sub(s)) else {
            return false;
        };
        if rt < 0 || rt > self.longest {
            return false;
        }
        self.window[self.filled] = rt;
        self.filled += 1;
        if self.filled == WINDOW {
            self.filled = 0;
            let (_, median, _) = self.window.select_nth_unstable(WINDOW / 2);
            let per_link = (*median + self.hops / 2) / self.hops;
            self.current = Some(Duration::from_ns(per_link));
            self.estimates += 1;
        }
        true
    }

    /// One link's delay as the last window of round trips measured it, once there is one.
    pub fn current(&self) -> Option<Duration> {
        self.current
    }

    /// The estimate as a command carries it: ns in a u16, 0 for none (or for a link too
    /// long for the field, 65.5 µs).
    pub fn wire(&self) -> u16 {
        self.current
            .and_then(|d| u16::try_from(d.as_ns()).ok())
            .unwrap_or(0)
    }

    /// How many estimates have been made (one per [`WINDOW`] round trips).
    pub fn estimates(&self) -> u64 {
        self.estimates
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nothing before a whole window; then the median over n + 1 links, rounded, which
    /// a tail of stalled round trips does not move; round trips out of range are refused.
    #[test]
    fn the_median_round_trip_over_the_links() {
        let mut e = LinkEstimate::new(4, Duration::from_ns(1_000_000));
        for k in 0..WINDOW - 1 {
            // 9 000 ns, a fifth of them stalled by 300 µs.
            let rt = if k % 5 == 0 { 309_000 } else { 9_000 };
            assert!(e.note(10_000_000 + rt, 10_000_000));
        }
        assert_eq!((e.current(), e.wire()), (None, 0));
        assert!(e.note(10_009_003, 10_000_000));
        assert_eq!(e.current(), Some(Duration::from_ns(1_800)));
        assert_eq!((e.wire(), e.estimates()), (1_800, 1));
        assert!(!e.note(5, 10), "came back before it left");
        assert!(!e.note(2_000_001, 1_000_000), "longer than a cycle");
        assert!(!e.note(0, u64::MAX), "a stamp beyond i64");
        // The next window moves it.
        for _ in 0..WINDOW {
            e.note(1_000_000 + 7_502, 1_000_000);
        }
        assert_eq!((e.wire(), e.estimates()), (1_500, 2));
    }

    /// A link the u16 field cannot carry goes out as none.
    #[test]
    fn a_link_too_long_for_the_field_is_none() {
        let mut e = LinkEstimate::new(0, Duration::from_ns(10_000_000));
        for _ in 0..WINDOW {
            e.note(70_000, 0);
        }
        assert_eq!(e.current(), Some(Duration::from_ns(70_000)));
        assert_eq!(e.wire(), 0);
    }
}
