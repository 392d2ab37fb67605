//! The cycle on a ring with one broken link (ring redundancy, docs/planner.md "A broken
//! link"): the master owns both ends of the ring and reaches every slave from one end or the
//! other.
//!
//! Links are numbered 1..=n+1: link j joins node j−1 to node j, node 0 and node n+1 being
//! the master's two ports (A, toward slave 1, where frames normally leave; B, toward slave
//! n, where they normally come back). With link j broken:
//!
//! - a frame sent on port A is processed by slaves 1..j−1 on its way out, turned back by
//!   slave j−1 (the port facing the break loops back, as an EtherCAT slave's does) and
//!   relayed by slaves j−2..1 back to port A;
//! - a frame sent on port B is relayed (not processed) by slaves n..j+1, turned back by
//!   slave j, and processed by slaves j..n on its way to port B. A slave processes frames
//!   only in the ring's forward direction, so its order of processing never changes.
//!
//! Every path is hops of L (PHY tx + cable + PHY rx) with a residence T_t at every node
//! between sender and receiver, the turning slave included. From these:
//!
//! ```text
//! a = j − 1 slaves on side A, b = n − j + 1 on side B
//! first bit at slave s, side A:  s·L + (s−1)·T_t                      (as on the whole ring)
//! first bit at slave s, side B:  (b + s − j)·L + (b + s − j − 1)·T_t
//! Δ = side B − side A          = (n + 1 − 2j)·(L + T_t)               (the same for every s)
//! lumped frame back, side A:     2a·L + (2a − 1)·T_t                   (+ its wire time)
//! lumped frame back, side B:     2b·L + (2b − 1)·T_t
//! slice, side A: T_cmf + T_ti + T_rmf + 2a·L + (2a − 2)·T_t (+ turnaround)
//! slice, side B: T_cmf + T_ti + T_rmf + 2b·L + (2b − 2)·T_t (+ turnaround)
//! ```
//!
//! A lumped frame's stamp is its send time, and a slave adds its configured path delay
//! (side A's) to it. The master stamps the copy it sends on port B with its send time + Δ,
//! so that the same addition gives each slave of side B its true arrival: the clock sync
//! works across the break without a slave knowing which way a frame came. When Δ < 0 the
//! copy on port B leaves −Δ after the cycle start, so that its stamp stays in its cycle.

use serde::Serialize;

use super::CyclePlan;
use crate::time::Duration;

/// The scalars of a ring that the broken ring's timing depends on (kept by the master to
/// work out the timing of whichever link breaks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct RingModel {
    /// Number of slaves n.
    pub slaves: u32,
    /// First-bit latency L of one hop \[ns\].
    pub hop: Duration,
    /// Residence T_t of a slave between receiving and relaying \[ns\].
    pub residence: Duration,
    /// Time to send the lumped frame(s) \[ns\].
    pub t_lmf: Duration,
    /// Wire time of a command frame \[ns\].
    pub t_cmf: Duration,
    /// Wire time of a response frame \[ns\].
    pub t_rmf: Duration,
    /// T_ti: last bit of a command in to first bit of its response out \[ns\].
    pub response_delay: Duration,
    /// T_rest between the sync phase and the P2P phase \[ns\].
    pub t_rest: Duration,
    /// The master's wait after a response \[ns\].
    pub turnaround: Duration,
    /// Number of reserve slices.
    pub reserve_slices: u32,
    /// Cycle time T_cyc \[ns\].
    pub t_cyc: Duration,
}

/// The cycle with link `link` broken (see the module docs). Every time is from the cycle
/// start.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BrokenRing {
    /// The broken link j, 1..=n+1 (link j joins node j−1 to node j; 0 and n+1 are the
    /// master).
    pub link: u32,
    /// Slaves reached from port A: 1..=this (0: none).
    pub side_a: u32,
    /// Slaves n − side_b + 1..=n are reached from port B.
    pub side_b: u32,
    /// Δ: how much later a lumped frame reaches a slave of side B than it would reach it on
    /// the whole ring; the copy on port B is stamped its send time + Δ \[ns\].
    pub stamp_shift: Duration,
    /// When the copy on port B leaves, after the copy on port A: max(0, −Δ) \[ns\].
    pub b_delay: Duration,
    /// First bit of the lumped frame at each slave 1..n \[ns\].
    pub lumped_at: Vec<Duration>,
    /// Last bit of the lumped frame(s) back at port A (None: side A is empty) \[ns\].
    pub lumped_back_a: Option<Duration>,
    /// Last bit of the lumped frame(s) back at port B (None: side B is empty) \[ns\].
    pub lumped_back_b: Option<Duration>,
    /// Start of the P2P phase: both copies back, then T_rest \[ns\].
    pub p2p_start: Duration,
    /// Slice of a slave of side A (None: side A is empty) \[ns\].
    pub slice_a: Option<Duration>,
    /// Slice of a slave of side B (None: side B is empty) \[ns\].
    pub slice_b: Option<Duration>,
    /// The master's slice: the longer of the two \[ns\].
    pub slice: Duration,
    /// Last bit of each slave's command at the slave, first try \[ns\].
    pub command_arrival: Vec<Duration>,
    /// Shortest cycle that holds the broken ring's plan \[ns\].
    pub min_t_cyc: Duration,
    /// Idle time left in T_cyc; negative when the broken ring's plan does not fit \[ns\].
    pub t_idle: Duration,
}

impl RingModel {
    /// The model of `plan`'s ring.
    pub fn of(plan: &CyclePlan) -> Self {
        RingModel {
            slaves: plan.slaves(),
            hop: plan.hop,
            residence: plan.params.residence,
            t_lmf: plan.t_lmf,
            t_cmf: plan.t_cmf,
            t_rmf: plan.t_rmf,
            response_delay: plan.params.response_delay,
            t_rest: plan.params.t_rest,
            turnaround: plan.event.turnaround,
            reserve_slices: plan.reserve_slices,
            t_cyc: plan.params.t_cyc,
        }
    }

    /// `hops`·L + (`hops` − 1)·T_t: the first-bit delay of a path of `hops` hops (0 for none).
    fn path(&self, hops: i64) -> Duration {
        if hops <= 0 {
            Duration::ZERO
        } else {
            self.hop * hops + self.residence * (hops - 1)
        }
    }

    /// The cycle with link `link` broken; `None` unless 1 ≤ link ≤ n + 1.
    pub fn broken(&self, link: u32) -> Option<BrokenRing> {
        let n = i64::from(self.slaves);
        let j = i64::from(link);
        if j < 1 || j > n + 1 {
            return None;
        }
        let (a, b) = (j - 1, n - j + 1);
        let trav = self.hop + self.residence;
        let stamp_shift = trav * (n + 1 - 2 * j);
        let b_delay = (-stamp_shift).max(Duration::ZERO);
        let lumped_at: Vec<Duration> = (1..=n)
            .map(|s| {
                if s < j {
                    self.path(s)
                } else {
                    b_delay + self.path(b + s - j)
                }
            })
            .collect();
        let back = |hops: i64| self.t_lmf + self.path(hops);
        let lumped_back_a = (a > 0).then(|| back(2 * a));
        let lumped_back_b = (b > 0).then(|| b_delay + back(2 * b));
        let last_back = lumped_back_a
            .into_iter()
            .chain(lumped_back_b)
            .max()
            .unwrap_or(Duration::ZERO);
        let p2p_start = last_back + self.t_rest;
        let frames = self.t_cmf + self.response_delay + self.t_rmf + self.turnaround;
        // Command leg h1 hops, response leg h2 hops: (h1 + h2)·L + (h1 + h2 − 2)·T_t.
        let round = |hops: i64| frames + self.hop * hops + self.residence * (hops - 2);
        let slice_a = (a > 0).then(|| round(2 * a));
        let slice_b = (b > 0).then(|| round(2 * b));
        let slice = slice_a
            .into_iter()
            .chain(slice_b)
            .max()
            .unwrap_or(Duration::ZERO);
        let mut at = p2p_start;
        let command_arrival = (1..=n)
            .map(|s| {
                let (leg, own) = if s < j {
                    (self.path(s), slice_a)
                } else {
                    (self.path(b + s - j), slice_b)
                };
                let arrival = at + leg + self.t_cmf;
                at += own.unwrap_or(slice);
                arrival
            })
            .collect();
        let min_t_cyc = p2p_start
            + slice_a.unwrap_or(Duration::ZERO) * a
            + slice_b.unwrap_or(Duration::ZERO) * b
            + slice * i64::from(self.reserve_slices);
        Some(BrokenRing {
            link,
            side_a: a as u32,
            side_b: b as u32,
            stamp_shift,
            b_delay,
            lumped_at,
            lumped_back_a,
            lumped_back_b,
            p2p_start,
            slice_a,
            slice_b,
            slice,
            command_arrival,
            min_t_cyc,
            t_idle: self.t_cyc - min_t_cyc,
        })
    }
}

impl CyclePlan {
    /// The cycle with link `link` broken (see [`RingModel::broken`]); `None` unless
    /// 1 ≤ link ≤ n + 1.
    pub fn broken(&self, link: u32) -> Option<BrokenRing> {
        RingModel::of(self).broken(link)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::RingParams;

    /// Walks a path node by node on the broken ring (an independent model of the module's
    /// formulas): the first-bit delay from a sender to the first slave that processes the
    /// frame, counting a hop per link and a residence per node passed on the way.
    fn walk_to(plan: &CyclePlan, link: i64, target: i64, from_b: bool) -> Duration {
        let n = i64::from(plan.slaves());
        let (l, t) = (plan.hop, plan.params.residence);
        // Positions 0..=n+1 (0 and n+1 the master's ports); link k joins k−1 and k.
        let (mut at, mut dir) = if from_b { (n + 1, -1) } else { (0, 1) };
        let mut d = Duration::ZERO;
        let mut first = true;
        loop {
            let next_link = if dir > 0 { at + 1 } else { at };
            if next_link == link {
                assert!(!first, "the sender's own link is broken");
                dir = -dir;
                // The turning slave takes the frame in the forward direction.
                if dir > 0 && at == target {
                    return d;
                }
                continue;
            }
            if !first {
                d += t;
            }
            first = false;
            at += dir;
            d += l;
            if dir > 0 && at == target {
                return d;
            }
            assert!((1..=n).contains(&at), "walked off the ring");
        }
    }

    #[test]
    fn a_walk_of_every_path_gives_the_formulas() {
        for slaves in [1u32, 2, 4, 7] {
            let plan = CyclePlan::new(&RingParams {
                slaves,
                ..RingParams::default()
            })
            .expect("plan");
            let n = i64::from(slaves);
            for j in 1..=n + 1 {
                let br = plan.broken(j as u32).expect("link in range");
                assert_eq!(i64::from(br.side_a + br.side_b), n);
                for s in 1..=n {
                    let from_b = s >= j;
                    let walked = walk_to(&plan, j, s, from_b);
                    let sent = if from_b { br.b_delay } else { Duration::ZERO };
                    assert_eq!(
                        br.lumped_at[s as usize - 1],
                        sent + walked,
                        "n {n} j {j} s {s}"
                    );
                    // The stamp shift makes the whole ring's path delay the true one.
                    if from_b {
                        assert_eq!(plan.d_c[s as usize - 1] + br.stamp_shift, walked);
                    }
                }
            }
        }
    }

    #[test]
    fn the_whole_rings_figures_bound_the_broken_ones() {
        let plan = CyclePlan::new(&RingParams::default()).expect("plan");
        // n = 4: the master's own links broken put every slave on one side, round trips of
        // 2n hops against n + 1 on the whole ring.
        for j in [1u32, 5] {
            let br = plan.broken(j).expect("in range");
            assert_eq!(br.side_a.max(br.side_b), 4);
            assert!(br.p2p_start > plan.event.p2p_start);
            assert!(br.slice > plan.event.slot[0]);
        }
        // A break in the middle: both sides shorter than the ring.
        let br = plan.broken(3).expect("in range");
        assert_eq!((br.side_a, br.side_b), (2, 2));
        assert!(br.slice < plan.event.slot[0]);
        assert!(br.t_idle > Duration::ZERO);
        assert!(plan.broken(0).is_none() && plan.broken(6).is_none());
    }
}
