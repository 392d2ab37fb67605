//! The simulator's event queue: events ordered by (true time, sequence), the sequence
//! breaking ties in the order events were scheduled, so that a run is a pure function of its
//! scenario and seed.
//!
//! Two stores make it up. Most events (frames arriving, responses leaving, the master's
//! timeout, cycle probes) sit in a short vector sorted newest-last; the slaves' encoder
//! latches, one per slave, sit in a binary heap of their own, since on a long ring they would
//! make every insertion into the vector walk and shift O(n) entries.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A slave's pending encoder latch; `generation` invalidates a latch that was rescheduled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Latch {
    /// True time [ns].
    pub t: i64,
    /// Scheduling order.
    pub seq: u64,
    /// The slave (0-based).
    pub slave: usize,
    /// The slave's latch generation when it was scheduled.
    pub generation: u64,
}

struct Queued<E> {
    t: i64,
    seq: u64,
    ev: E,
}

/// What [`Queue::pop`] yields.
pub(crate) enum Next<E> {
    /// An event at its time.
    Event(i64, E),
    /// A latch.
    Latch(Latch),
}

/// The event queue (see the module docs).
pub(crate) struct Queue<E> {
    /// Pending events sorted by (time, sequence) descending: the next one is last.
    q: Vec<Queued<E>>,
    latches: BinaryHeap<Reverse<Latch>>,
    seq: u64,
}

impl<E> Queue<E> {
    /// An empty queue for a ring of `n` slaves.
    pub fn new(n: usize) -> Self {
        Queue {
            q: Vec::with_capacity(64),
            latches: BinaryHeap::with_capacity(2 * n + 2),
            seq: 0,
        }
    }

    /// Schedules `ev` at true time `t` [ns], after every event already scheduled at `t`.
    pub fn push(&mut self, t: i64, ev: E) {
        self.seq += 1;
        // The new entry has the largest sequence number, so it goes after every entry later
        // than `t`. New events are mostly near-future: scan from the near end.
        let mut at = self.q.len();
        while at > 0 && self.q[at - 1].t <= t {
            at -= 1;
        }
        self.q.insert(
            at,
            Queued {
                t,
                seq: self.seq,
                ev,
            },
        );
    }

    /// Schedules slave `slave`'s latch of generation `generation` at true time `t` [ns].
    pub fn push_latch(&mut self, t: i64, slave: usize, generation: u64) {
        self.seq += 1;
        self.latches.push(Reverse(Latch {
            t,
            seq: self.seq,
            slave,
            generation,
        }));
    }

    /// The next event or latch in (time, sequence) order.
    pub fn pop(&mut self) -> Option<Next<E>> {
        let latch_first = match (self.latches.peek(), self.q.last()) {
            (Some(Reverse(l)), Some(e)) => (l.t, l.seq) < (e.t, e.seq),
            (Some(_), None) => true,
            (None, _) => false,
        };
        if latch_first {
            self.latches.pop().map(|Reverse(l)| Next::Latch(l))
        } else {
            self.q.pop().map(|e| Next::Event(e.t, e.ev))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Events come out by time, ties in scheduling order, latches interleaved by the same
    /// rule.
    #[test]
    fn time_then_scheduling_order() {
        let mut q = Queue::new(2);
        q.push(5, 'a');
        q.push_latch(5, 0, 1);
        q.push(3, 'b');
        q.push(5, 'c');
        q.push_latch(1, 1, 1);
        let mut out = Vec::new();
        while let Some(n) = q.pop() {
            out.push(match n {
                Next::Event(t, e) => format!("{t}{e}"),
                Next::Latch(l) => format!("{}L{}", l.t, l.slave),
            });
        }
        assert_eq!(out, ["1L1", "3b", "5a", "5L0", "5c"]);
    }
}
