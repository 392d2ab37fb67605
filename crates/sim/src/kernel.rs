//! The simulator's event queue: events ordered by (true time, sequence), the sequence
//! breaking ties in the order events were scheduled, so that a run is a pure function of its
//! scenario and seed.
//!
//! Three stores make it up, popped together in that one order:
//! - most events (frames arriving, responses leaving, cycle probes) sit in a short vector
//!   sorted newest-last;
//! - the master's timeout, of which only the latest scheduled counts, sits in a slot of its
//!   own: scheduling it again replaces the pending one;
//! - the slaves' encoder latches, one pending per slave, sit in a store of their own (on a
//!   long ring they would make every insertion into the vector walk and shift O(n)
//!   entries): an array scanned for the earliest on a short ring, a binary heap indexed by
//!   slave on a longer one; rescheduling a slave's latch moves its entry.
//!
//! A replaced timeout or latch never reaches the driver (no stale entry waits in the queue
//! for its time); the scheduling calls return the time it had, for whoever counts them.

/// A slave's encoder latch, as [`Queue::pop`] yields it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Latch {
    /// True time [ns].
    pub t: i64,
    /// The slave (0-based).
    pub slave: usize,
}

/// (time, sequence) as one number that orders as the pair does: the time's bits with the
/// sign flipped (so that unsigned order is signed order) above the sequence.
type Key = u128;

/// No entry: after every real key (whose sequence never reaches `u64::MAX`).
const EMPTY: Key = Key::MAX;

fn key(t: i64, seq: u64) -> Key {
    (Key::from((t as u64) ^ (1 << 63)) << 64) | Key::from(seq)
}

fn time_of(k: Key) -> i64 {
    (((k >> 64) as u64) ^ (1 << 63)) as i64
}

struct Queued<E> {
    key: Key,
    ev: E,
}

/// What [`Queue::pop`] yields.
pub(crate) enum Next<E> {
    /// An event at its time.
    Event(i64, E),
    /// The master's timeout at its time [ns].
    Timer(i64),
    /// A latch.
    Latch(Latch),
}

/// Rings of at most this many slaves keep their latches in a plain array, scanned for the
/// earliest; longer ones in a heap.
const FLAT: usize = 8;

/// Slot of a slave with no pending latch in [`Latches::pos`].
const NONE: usize = usize::MAX;

/// The slaves' pending latches, one per slave, so that a rescheduled latch is moved rather
/// than left stale: on a short ring each slave's key in an array with the earliest kept;
/// on a longer one a binary min-heap of (key, slave) with each slave's place in it.
struct Latches {
    /// Short ring: each slave's key ([`EMPTY`]: none).
    keys: Vec<Key>,
    /// Short ring: the earliest key and its slave.
    min: (Key, usize),
    heap: Vec<(Key, usize)>,
    /// Long ring: each slave's index in `heap`, or [`NONE`].
    pos: Vec<usize>,
    flat: bool,
}

impl Latches {
    fn new(n: usize) -> Self {
        let flat = n <= FLAT;
        Latches {
            keys: if flat { vec![EMPTY; n] } else { Vec::new() },
            min: (EMPTY, NONE),
            heap: Vec::with_capacity(if flat { 0 } else { n }),
            pos: if flat { Vec::new() } else { vec![NONE; n] },
            flat,
        }
    }

    /// The earliest of the short ring's keys.
    fn earliest(keys: &[Key]) -> (Key, usize) {
        let mut best = (EMPTY, NONE);
        for (i, &k) in keys.iter().enumerate() {
            if k < best.0 {
                best = (k, i);
            }
        }
        best
    }

    fn put(&mut self, i: usize, e: (Key, usize)) {
        self.pos[e.1] = i;
        self.heap[i] = e;
    }

    /// Moves the entry at `i` up while it comes before its parent.
    fn sift_up(&mut self, mut i: usize) {
        let e = self.heap[i];
        while i > 0 {
            let parent = (i - 1) / 2;
            let p = self.heap[parent];
            if e.0 >= p.0 {
                break;
            }
            self.put(i, p);
            i = parent;
        }
        self.put(i, e);
    }

    /// Moves the entry at `i` down while a child comes before it.
    fn sift_down(&mut self, mut i: usize) {
        let e = self.heap[i];
        let len = self.heap.len();
        loop {
            let left = 2 * i + 1;
            if left >= len {
                break;
            }
            let right = left + 1;
            let c = if right < len && self.heap[right].0 < self.heap[left].0 {
                right
            } else {
                left
            };
            let child = self.heap[c];
            if child.0 >= e.0 {
                break;
            }
            self.put(i, child);
            i = c;
        }
        self.put(i, e);
    }

    /// Schedules slave `slave`'s latch at `k`, replacing its pending one; returns the
    /// replaced one's time.
    fn set(&mut self, k: Key, slave: usize) -> Option<i64> {
        if self.flat {
            let old = std::mem::replace(&mut self.keys[slave], k);
            if self.min.1 == slave {
                self.min = Self::earliest(&self.keys);
            } else if k < self.min.0 {
                self.min = (k, slave);
            }
            return (old != EMPTY).then(|| time_of(old));
        }
        match self.pos[slave] {
            NONE => {
                self.heap.push((k, slave));
                self.sift_up(self.heap.len() - 1);
                None
            }
            i => {
                let old = self.heap[i].0;
                self.heap[i].0 = k;
                if k < old {
                    self.sift_up(i);
                } else {
                    self.sift_down(i);
                }
                Some(time_of(old))
            }
        }
    }

    /// The earliest pending key ([`EMPTY`]: none).
    fn first(&self) -> Key {
        if self.flat {
            self.min.0
        } else {
            self.heap.first().map_or(EMPTY, |e| e.0)
        }
    }

    /// Takes the earliest pending latch (there is one).
    fn pop(&mut self) -> Latch {
        let (k, slave) = if self.flat {
            let top = self.min;
            self.keys[top.1] = EMPTY;
            self.min = Self::earliest(&self.keys);
            top
        } else {
            let last = self.heap.pop().unwrap_or((EMPTY, NONE));
            let top = if self.heap.is_empty() {
                last
            } else {
                let top = self.heap[0];
                self.heap[0] = last;
                self.sift_down(0);
                top
            };
            self.pos[top.1] = NONE;
            top
        };
        Latch {
            t: time_of(k),
            slave,
        }
    }
}

/// The event queue (see the module docs).
pub(crate) struct Queue<E> {
    /// Pending events sorted by key descending: the next one is last.
    q: Vec<Queued<E>>,
    /// The master's pending timeout ([`EMPTY`]: none).
    timer: Key,
    latches: Latches,
    seq: u64,
}

impl<E> Queue<E> {
    /// An empty queue for a ring of `n` slaves.
    pub fn new(n: usize) -> Self {
        Queue {
            q: Vec::with_capacity(64),
            timer: EMPTY,
            latches: Latches::new(n),
            seq: 0,
        }
    }

    /// Schedules `ev` at true time `t` [ns], after every event already scheduled at `t`.
    #[inline]
    pub fn push(&mut self, t: i64, ev: E) {
        self.seq += 1;
        let k = key(t, self.seq);
        // The new entry has the largest sequence number, so it goes after every entry later
        // than `t`. New events are mostly near-future: scan from the near end.
        let mut at = self.q.len();
        while at > 0 && self.q[at - 1].key < k {
            at -= 1;
        }
        self.q.insert(at, Queued { key: k, ev });
    }

    /// Schedules the master's timeout at true time `t` [ns] (none for `None`), in place of
    /// the pending one; returns the replaced one's time.
    pub fn set_timer(&mut self, t: Option<i64>) -> Option<i64> {
        let old = self.timer;
        self.timer = match t {
            Some(t) => {
                self.seq += 1;
                key(t, self.seq)
            }
            None => EMPTY,
        };
        (old != EMPTY).then(|| time_of(old))
    }

    /// Schedules slave `slave`'s latch at true time `t` [ns], in place of its pending one;
    /// returns the replaced one's time.
    pub fn set_latch(&mut self, t: i64, slave: usize) -> Option<i64> {
        self.seq += 1;
        self.latches.set(key(t, self.seq), slave)
    }

    /// The next event, timeout or latch in (time, sequence) order.
    pub fn pop(&mut self) -> Option<Next<E>> {
        let event = self.q.last().map_or(EMPTY, |e| e.key);
        let latch = self.latches.first();
        if self.timer < event && self.timer < latch {
            let t = time_of(self.timer);
            self.timer = EMPTY;
            Some(Next::Timer(t))
        } else if latch < event {
            Some(Next::Latch(self.latches.pop()))
        } else {
            self.q.pop().map(|e| Next::Event(time_of(e.key), e.ev))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Events come out by time, ties in scheduling order, the timeout and latches
    /// interleaved by the same rule; a replaced timeout or latch does not come out.
    #[test]
    fn time_then_scheduling_order() {
        let mut q = Queue::new(2);
        q.push(5, 'a');
        assert_eq!(q.set_latch(5, 0), None);
        assert_eq!(q.set_timer(Some(9)), None);
        q.push(3, 'b');
        assert_eq!(q.set_timer(Some(5)), Some(9));
        q.push(5, 'c');
        assert_eq!(q.set_latch(7, 1), None);
        assert_eq!(q.set_latch(1, 1), Some(7));
        let mut out = Vec::new();
        while let Some(n) = q.pop() {
            out.push(match n {
                Next::Event(t, e) => format!("{t}{e}"),
                Next::Timer(t) => format!("{t}T"),
                Next::Latch(l) => format!("{}L{}", l.t, l.slave),
            });
        }
        assert_eq!(out, ["1L1", "3b", "5a", "5L0", "5T", "5c"]);
    }

    /// The queue against the plain model it replaces: every scheduled timeout and latch
    /// stays in one list ordered by (time, sequence), the replaced ones marked stale and
    /// skipped when they come out. Same order of what comes out, and as many replaced
    /// entries returned as stale ones skipped.
    #[test]
    fn replacing_gives_what_skipping_stale_entries_gives() {
        #[derive(Clone, Copy, PartialEq, Debug)]
        enum Kind {
            Event(u32),
            Timer,
            Latch(usize),
        }
        let mut r = ringsync_model::rng::Rng::stream(12, 3);
        for round in 0..200 {
            let n = [1, 2, 3, 4, 8, 9, 16, 33][round % 8];
            let mut q: Queue<u32> = Queue::new(n);
            // The plain model: (t, seq, kind, live).
            let mut all: Vec<(i64, u64, Kind, bool)> = Vec::new();
            let mut seq = 0u64;
            let (mut replaced, mut stale) = (0, 0);
            let mut now = 0i64;
            let mut got = Vec::new();
            let mut want = Vec::new();
            let mut id = 0u32;
            for _ in 0..400 {
                let dt = (r.unit() * 20.0) as i64;
                let t = now + dt;
                match (r.unit() * 5.0) as u32 {
                    0 => {
                        seq += 1;
                        id += 1;
                        q.push(t, id);
                        all.push((t, seq, Kind::Event(id), true));
                    }
                    1 => {
                        let t = (r.unit() > 0.1).then_some(t);
                        if q.set_timer(t).is_some() {
                            replaced += 1;
                        }
                        for e in all.iter_mut().filter(|e| e.2 == Kind::Timer) {
                            e.3 = false;
                        }
                        if let Some(t) = t {
                            seq += 1;
                            all.push((t, seq, Kind::Timer, true));
                        }
                    }
                    2 | 3 => {
                        let i = (r.unit() * n as f64) as usize % n;
                        if q.set_latch(t, i).is_some() {
                            replaced += 1;
                        }
                        for e in all.iter_mut().filter(|e| e.2 == Kind::Latch(i)) {
                            e.3 = false;
                        }
                        seq += 1;
                        all.push((t, seq, Kind::Latch(i), true));
                    }
                    _ => {
                        if let Some(next) = q.pop() {
                            let k = match next {
                                Next::Event(t, e) => (t, Kind::Event(e)),
                                Next::Timer(t) => (t, Kind::Timer),
                                Next::Latch(l) => (l.t, Kind::Latch(l.slave)),
                            };
                            now = k.0;
                            got.push(k);
                        }
                        // The model pops until it yields a live entry.
                        while let Some(m) = (0..all.len()).min_by_key(|&j| (all[j].0, all[j].1)) {
                            let e = all.remove(m);
                            if e.3 {
                                want.push((e.0, e.2));
                                break;
                            }
                            stale += 1;
                        }
                    }
                }
            }
            assert_eq!(got, want, "round {round}");
            // Drain both.
            while let Some(next) = q.pop() {
                got.push(match next {
                    Next::Event(t, e) => (t, Kind::Event(e)),
                    Next::Timer(t) => (t, Kind::Timer),
                    Next::Latch(l) => (l.t, Kind::Latch(l.slave)),
                });
            }
            all.sort_by_key(|e| (e.0, e.1));
            for e in all {
                if e.3 {
                    want.push((e.0, e.2));
                } else {
                    stale += 1;
                }
            }
            assert_eq!(got, want, "round {round}");
            assert_eq!(replaced, stale, "round {round}");
        }
    }
}
