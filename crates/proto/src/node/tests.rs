//! The nodes driven by hand: a test owns time and carries every frame itself, with no
//! delay on the links (the simulator tests the timing; these test what the nodes decide).

use super::testbed::PdMotion;
use super::*;
use crate::plan::{CyclePlan, RingParams};
use crate::time::Duration;

const T_CYC: i64 = 1_000_000;
/// Encoder resolution [rad per count]: a power of two, so positions compare exactly.
const RES: f64 = 1.0 / 1_048_576.0;

fn ring(n: u32, lead: Duration) -> (Master, Vec<Slave>) {
    let plan = CyclePlan::new(&RingParams {
        slaves: n,
        ..RingParams::default()
    })
    .expect("plan");
    let n = n as usize;
    let cfg = MasterConfig::from_plan(&plan, Duration::ZERO, vec![RES; n]);
    let master = Master::new(cfg, Box::new(PdMotion::new(n, 15.12, 1e9, RES)));
    let slaves = (0..n)
        .map(|i| {
            Slave::new(SlaveConfig {
                sample_lead: lead,
                // Free-running clocks read true time: local time is the test's time.
                clock_sync: false,
                ..SlaveConfig::new((i + 1) as u16, Duration::from_ns(T_CYC), plan.d_c[i])
            })
        })
        .collect();
    (master, slaves)
}

/// Runs slave `s`'s encoder latches due up to `t`, with the axis at `counts`.
fn latch(s: &mut Slave, t: i64, counts: i64) {
    while s.poll_timeout().as_ns() <= t {
        let at = s.poll_timeout();
        s.handle_sample(at, counts);
    }
}

/// Runs the master's timers due up to `t`; every lumped frame it sends goes round the ring
/// at once (slaves in order, then back to the master). Other frames are dropped.
fn master_until(m: &mut Master, slaves: &mut [Slave], t: i64) {
    while m.poll_timeout().as_ns() <= t {
        let now = m.poll_timeout();
        m.handle_timeout(now);
        while let Some(mut tx) = m.poll_transmit() {
            if tx.bytes.get(1) != Some(&(ringsync_wire::FrameKind::Lumped as u8)) {
                continue;
            }
            for s in slaves.iter_mut() {
                assert_eq!(
                    s.handle_frame(now, now, &mut tx.bytes),
                    FrameOutcome::Forward
                );
            }
            m.handle_frame(now, &tx.bytes);
        }
    }
}

/// Runs the master's timers due up to `t` with no slave answering: the lumped frames it
/// sent, held back (to go round later, or never); every other frame is dropped.
fn master_alone(m: &mut Master, t: i64) -> Vec<Vec<u8>> {
    let mut lumped = Vec::new();
    while m.poll_timeout().as_ns() <= t {
        let now = m.poll_timeout();
        m.handle_timeout(now);
        while let Some(tx) = m.poll_transmit() {
            if tx.bytes.get(1) == Some(&(ringsync_wire::FrameKind::Lumped as u8)) {
                lumped.push(tx.bytes);
            }
        }
    }
    lumped
}

#[test]
fn a_sample_carried_twice_is_counted_stale_and_not_taken_again() {
    let (mut m, mut s) = ring(2, Duration::ZERO);
    let p2p = m.config().p2p_start.as_ns();
    // Cycle 0: both slaves latch at the cycle start, before the lumped frame passes.
    latch(&mut s[0], 0, 100);
    latch(&mut s[1], 0, 200);
    master_until(&mut m, &mut s, p2p);
    assert_eq!(m.record().k, 0);
    assert_eq!(m.record().fresh, vec![true, true]);
    assert_eq!(m.record().position, vec![100.0 * RES, 200.0 * RES]);
    // Cycle 1: slave 2 latches only after the frame has passed it (its clock lags), so the
    // frame carries its cycle-0 sample again.
    master_until(&mut m, &mut s, T_CYC - 1);
    latch(&mut s[0], T_CYC, 110);
    master_until(&mut m, &mut s, T_CYC + p2p);
    latch(&mut s[1], T_CYC + 5_000, 210);
    assert_eq!(m.record().k, 1);
    assert_eq!(m.record().fresh, vec![true, false]);
    assert_eq!(m.record().sample_time, vec![1e-3, 0.0]);
    assert_eq!(m.record().position, vec![110.0 * RES, 200.0 * RES]);
    let c = m.counters();
    assert_eq!((c.samples_stale, c.samples_missing), (1, 0));
    // Cycle 2: slave 2's cycle-1 sample (latched late) is newer: taken, fresh.
    master_until(&mut m, &mut s, 2 * T_CYC - 1);
    latch(&mut s[0], 2 * T_CYC, 120);
    master_until(&mut m, &mut s, 2 * T_CYC + p2p);
    assert_eq!(m.record().fresh, vec![true, true]);
    assert_eq!(m.record().sample_time, vec![2e-3, 1e-3]);
    assert_eq!(m.counters().samples_stale, 1);
}

/// A lumped frame that comes back after the law ran (late, as after a host stall) brings
/// samples the next law run takes as new: they are not dropped with the cycle.
#[test]
fn samples_that_come_back_after_the_law_ran_are_the_next_runs() {
    let (mut m, mut s) = ring(2, Duration::ZERO);
    let p2p = m.config().p2p_start.as_ns();
    latch(&mut s[0], 0, 100);
    latch(&mut s[1], 0, 200);
    master_until(&mut m, &mut s, p2p);
    assert_eq!(m.record().fresh, vec![true, true]);
    // Cycle 1: the lumped frame goes round only after the law ran.
    master_until(&mut m, &mut s, T_CYC - 1);
    latch(&mut s[0], T_CYC, 110);
    latch(&mut s[1], T_CYC, 210);
    let held = master_alone(&mut m, T_CYC + p2p);
    assert_eq!(m.record().k, 1);
    assert_eq!(m.record().fresh, vec![false, false]);
    let late = Instant::from_ns(T_CYC + p2p + 10_000);
    for mut bytes in held {
        for sl in s.iter_mut() {
            assert_eq!(
                sl.handle_frame(late, late, &mut bytes),
                FrameOutcome::Forward
            );
        }
        m.handle_frame(late, &bytes);
    }
    // Cycle 2: its lumped frame is lost; the law runs on cycle 1's late samples, new to it.
    master_alone(&mut m, 2 * T_CYC + p2p);
    assert_eq!(m.record().k, 2);
    assert_eq!(m.record().fresh, vec![true, true]);
    assert_eq!(m.record().sample_time, vec![1e-3, 1e-3]);
    assert_eq!(m.record().position, vec![110.0 * RES, 210.0 * RES]);
    // Cycle 3: nothing new came; the same samples are not new again.
    master_alone(&mut m, 3 * T_CYC + p2p);
    assert_eq!(m.record().fresh, vec![false, false]);
}

#[test]
fn the_sampling_lead_moves_both_latches_and_the_sample_time() {
    let lead = Duration::from_us(100);
    let (_, mut s) = ring(2, lead);
    let s = &mut s[0];
    // Cycle k: the velocity window opens at k·T − lead − 125 µs and the sample is taken at
    // k·T − lead.
    for k in 1..4i64 {
        latch(s, (k - 1) * T_CYC, 0);
        assert_eq!(s.poll_timeout().as_ns(), k * T_CYC - 100_000 - 125_000);
        latch(s, k * T_CYC - 100_001, 0);
        assert_eq!(s.poll_timeout().as_ns(), k * T_CYC - 100_000);
    }
    // Lead 0 (the paper): the sample at the cycle start.
    let (_, mut s0) = ring(2, Duration::ZERO);
    latch(&mut s0[0], 0, 0);
    assert_eq!(s0[0].poll_timeout().as_ns(), T_CYC - 125_000);
}

/// A measured schedule replaces the plan's P2P figures: command i arrives after the earlier
/// slices' typical round trips and turnarounds, plus its own transit.
#[test]
fn a_measured_schedule_places_each_command() {
    let plan = CyclePlan::new(&RingParams {
        slaves: 3,
        ..RingParams::default()
    })
    .expect("plan");
    let cfg = MasterConfig::from_plan(&plan, Duration::ZERO, vec![1e-3; 3]);
    let us = Duration::from_us;
    let m = MeasuredSchedule {
        p2p_start: us(300),
        slice: us(40),
        guard: us(200),
        command_transit: vec![us(5), us(9), us(13)],
        typical_slice: vec![us(20), us(30), us(35)],
    };
    let turn = cfg.turnaround;
    let c = cfg.with_measured(&m);
    assert_eq!((c.p2p_start, c.slice, c.guard), (us(300), us(40), us(200)));
    assert_eq!(
        c.command_arrival,
        vec![
            us(305),
            us(300) + us(20) + turn + us(9),
            us(300) + us(20) + us(30) + turn * 2 + us(13),
        ]
    );
}

/// The settled cycle: the newest whose lumped frame went out a cycle time ago. A master
/// that runs on time settles the cycle before its current one; one that runs the cycles a
/// host stall made it miss back to back settles none of them until a cycle time has passed.
#[test]
fn a_master_late_by_a_stall_settles_only_the_cycles_sent_a_cycle_ago() {
    let (mut m, _) = ring(2, Duration::ZERO);
    let step = |m: &mut Master, until: i64| {
        while m.poll_timeout().as_ns() <= until {
            let at = m.poll_timeout();
            m.handle_timeout(at);
            while m.poll_transmit().is_some() {}
        }
    };
    // On time through cycle 5: at 5.5 ms, cycle 4's frame went out 1.5 ms before.
    step(&mut m, 5 * T_CYC + T_CYC / 2);
    assert_eq!(m.cycle(), 5);
    assert_eq!(
        m.settled_cycle(Instant::from_ns(5 * T_CYC + T_CYC / 2)),
        Some(4)
    );
    // The host holds the master until 12.2 ms; it then runs cycles 6-12 at once.
    let late = 12 * T_CYC + T_CYC / 5;
    while m.cycle() < 12 {
        m.handle_timeout(Instant::from_ns(late));
        while m.poll_transmit().is_some() {}
    }
    m.handle_timeout(Instant::from_ns(late));
    assert_eq!(m.cycle(), 12);
    // Only cycle 5's frame went out a cycle time before: none of the ones just sent.
    assert_eq!(m.settled_cycle(Instant::from_ns(late)), Some(5));
    // A cycle time later they have.
    assert_eq!(m.settled_cycle(Instant::from_ns(late + T_CYC)), Some(12));
}

/// A lumped frame reflected back to port A (a PHY in loopback, a replay) on a whole ring:
/// its echo is refused nowhere else, the genuine one still comes round to port B and is
/// taken, and the master does not take the reflection for a break (it wrote no slot, and
/// the frame also went round).
#[test]
fn a_frame_reflected_to_port_a_breaks_nothing() {
    let (mut m, mut slaves) = ring(2, Duration::ZERO);
    for cycle in 0..3 {
        let t0 = cycle * T_CYC;
        for s in slaves.iter_mut() {
            latch(s, t0, 100);
        }
        // (The last cycle ends at this one's start, then the lumped frame goes.)
        let now = m.poll_timeout();
        assert_eq!(now.as_ns(), t0, "the cycle starts with the lumped frame");
        m.handle_timeout(now);
        let mut tx = match m.poll_transmit() {
            Some(tx) => tx,
            None => {
                m.handle_timeout(m.poll_timeout());
                m.poll_transmit().expect("the lumped frame")
            }
        };
        assert_eq!(tx.port, Port::A);
        // The reflection, unwritten, back at port A first.
        m.handle_frame_on(Port::A, now, &tx.bytes);
        for s in slaves.iter_mut() {
            assert_eq!(
                s.handle_frame(now, now, &mut tx.bytes),
                FrameOutcome::Forward
            );
        }
        m.handle_frame_on(Port::B, now, &tx.bytes);
        assert_eq!(m.counters().rejected.total(), 0, "cycle {cycle}");
        // The P2P start: the law runs on the genuine echo's samples.
        let p2p = m.poll_timeout();
        m.handle_timeout(p2p);
        while m.poll_transmit().is_some() {}
        assert_eq!(m.ring(), RingState::Whole, "cycle {cycle}");
        master_until(&mut m, &mut slaves, t0 + T_CYC - 1);
    }
    assert_eq!(m.counters().ring_breaks, 0);
    assert!(m.record().fresh.iter().all(|f| *f), "{:?}", m.record());
}

/// With port A's link down the master reaches every slave from port B, its copy there
/// stamped ahead by Δ. Behind transparent relays (each adds its hold to the stamp) Δ counts
/// the links alone, L·(n + 1 − 2j); otherwise the model's hops and residences.
#[test]
fn behind_transparent_relays_a_broken_ring_shifts_the_port_b_stamp_by_the_links_alone() {
    for link in [None, Some(Duration::from_ns(2_000))] {
        let (master, _) = ring(4, Duration::ZERO);
        let mut cfg = master.config().clone();
        let model = cfg.ring.expect("a ring model");
        cfg.transparent_link = link;
        let mut m = Master::new(cfg, Box::new(PdMotion::new(4, 15.12, 1e9, RES)));
        m.handle_link(Instant::ZERO, Port::A, false);
        master_until(&mut m, &mut [], 3 * T_CYC);
        assert_eq!(m.ring(), RingState::Broken { link: 1 });
        let b = m.broken_ring().expect("broken");
        // Link 1 broken: every slave on side B, n + 1 − 2j = 3.
        let expected = match link {
            Some(l) => l * 3,
            None => (model.hop + model.residence) * 3,
        };
        assert_eq!(b.stamp_shift, expected, "{link:?}");
    }
}
