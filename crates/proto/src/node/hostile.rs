//! The nodes on a hostile wire: forged, duplicated, stale, reordered, future-stamped and
//! wrong-cycle frames, all with a valid CRC, driven through the [`Testbed`]. And the fault
//! reactions: the group stop that ends in torque off, the slave's own brake.

use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Flags, FrameKind, LumpedRepr, ResponseRepr, SlotCodec,
    Status,
};

use super::testbed::{Fate, Hop, Testbed, TestbedConfig, seal};
use super::*;
use crate::time::{Duration, Instant};

const MS: i64 = 1_000_000;

fn ring() -> Testbed {
    Testbed::new(TestbedConfig::default())
}

fn lumped(cycle: u32, stamp: u64, slots: usize) -> Vec<u8> {
    let repr = LumpedRepr {
        common: Common {
            cycle,
            seq: 999,
            ..Common::default()
        },
        master_time_ns: stamp,
        first_slot: 0,
        slots: vec![FeedbackSlot::default(); slots],
    };
    let mut b = vec![0; repr.buffer_len()];
    repr.emit(&mut b).expect("emit lumped");
    b
}

fn command(cycle: u32, target: u16, v: f32, retry: u8, sample: u64) -> Vec<u8> {
    let repr = CommandRepr {
        common: Common {
            cycle,
            retry,
            ..Common::default()
        },
        target,
        command_v: v,
        sample_time_ns: sample,
        link_ns: 0,
    };
    let mut b = vec![0; repr.buffer_len()];
    repr.emit(&mut b).expect("emit command");
    b
}

fn response(cycle: u32, source: u16, retry: u8) -> Vec<u8> {
    let repr = ResponseRepr {
        common: Common {
            cycle,
            retry,
            ..Common::default()
        },
        source,
        status: Status::empty(),
        echo_cycle: cycle,
        position: 0,
        velocity: 0,
        sample_time_ns: 0,
        applied_v: 0.0,
    };
    let mut b = vec![0; repr.buffer_len()];
    repr.emit(&mut b).expect("emit response");
    b
}

fn is_kind(b: &[u8], k: FrameKind) -> bool {
    b.get(1) == Some(&(k as u8))
}

fn cycle_of(b: &[u8]) -> i64 {
    i64::from(u32::from_le_bytes([b[4], b[5], b[6], b[7]]))
}

/// Slave i's (1-based) synchronised clock minus true time now [ns].
fn clock_error(r: &Testbed, i: usize) -> i64 {
    let now = r.now();
    r.slaves[i - 1].clock().to_sync(r.local(i, now)).as_ns() - now
}

fn stops(r: &Testbed) -> Vec<(i64, StopReason)> {
    r.master_events
        .iter()
        .filter_map(|(t, e)| match e {
            MasterEvent::GroupStop { reason, .. } => Some((*t, *reason)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_clean_ring_refuses_nothing_and_tracks_its_motion() {
    let mut r = ring();
    r.run_until(1_000 * MS);
    assert_eq!(r.master.counters().rejected.total(), 0);
    for s in &r.slaves {
        assert_eq!(s.counters().rejected.total(), 0, "{:?}", s.counters());
    }
    assert!(stops(&r).is_empty());
    assert!(r.worst_error() < 0.1, "error {}", r.worst_error());
    // Every slave took one command per cycle and every clock followed the master's.
    for (i, s) in r.slaves.iter().enumerate() {
        assert!(s.counters().commands >= 999, "{:?}", s.counters());
        assert!(clock_error(&r, i + 1).abs() < 100);
    }
}

/// Commands with a valid CRC but another cycle's counter are refused, counted, never
/// applied, and do not feed the slave's watchdog. Before the fix a slave applied any
/// valid-CRC command addressed to it and reset its watchdog.
#[test]
fn forged_wrong_cycle_commands_are_refused_and_never_applied() {
    let mut r = ring();
    r.run_until(100 * MS);
    for k in 100..400i64 {
        // At 1 kHz, mid-cycle: a command 7 cycles ahead and one 3 behind, at 10 V.
        let t = k * MS + 500_000;
        r.inject(2, t, command((k + 7) as u32, 2, 10.0, 0, (k * MS) as u64));
        r.inject(
            2,
            t + 1_000,
            command((k - 3) as u32, 2, -10.0, 0, (k * MS) as u64),
        );
        r.run_until(t + 2_000);
    }
    r.run_until(400 * MS);
    let c = r.slaves[1].counters();
    assert_eq!(c.rejected.get(Reject::WrongCycle), 600, "{c:?}");
    assert!(
        r.applied.iter().all(|&(_, s, u)| s != 2 || u.abs() < 5.0),
        "a forged 10 V command was applied"
    );
    assert!(stops(&r).is_empty());
    assert!(r.worst_error() < 0.1);

    // With the master gone, the same forgeries do not keep the slave's watchdog fed.
    r.dead[0] = true;
    for k in 400..500i64 {
        let t = k * MS + 500_000;
        r.inject(2, t, command((k + 7) as u32, 2, 10.0, 0, (k * MS) as u64));
        r.run_until(t + 1_000);
    }
    let expiry = r
        .slave_events
        .iter()
        .find(|(_, s, e)| *s == 2 && *e == SlaveEvent::WatchdogExpired)
        .map(|(t, _, _)| *t)
        .expect("slave 2's watchdog expired");
    assert!(
        expiry <= 400 * MS + 7 * MS,
        "expired at {expiry} ns, W = 5 cycles after 400 ms"
    );
}

/// A returning lumped frame whose slot claims a sample 1000 s in the future: the master
/// refuses that slot and keeps taking the real samples after it. Before the fix every later
/// sample was "stale", the axis ran on frozen feedback and its command wound up to 10 V.
#[test]
fn a_future_stamped_sample_does_not_freeze_the_feedback() {
    let mut r = ring();
    r.tap = Some(Box::new(|hop: &Hop, b: &mut Vec<u8>| {
        if hop.to == 0 && is_kind(b, FrameKind::Lumped) && cycle_of(b) == 50 {
            // Slave 1's slot: sampling timestamp at payload 12 + 8.
            let at = 12 + 12 + 8;
            b[at..at + 8].copy_from_slice(&1_000_000_000_000u64.to_le_bytes());
            seal(b);
        }
        Fate::Deliver
    }));
    r.run_until(1_000 * MS);
    let c = r.master.counters();
    assert_eq!(c.rejected.get(Reject::FutureTimestamp), 1, "{c:?}");
    assert_eq!(c.samples_stale, 0);
    assert!(stops(&r).is_empty(), "{:?}", stops(&r));
    assert!(r.worst_error() < 0.1, "error {}", r.worst_error());
    let u_max = r.applied.iter().map(|a| a.2.abs()).fold(0.0, f64::max);
    assert!(u_max < 5.0, "command {u_max} V");
}

/// Bursts of 30 valid-CRC lumped frames at every slave: with a wrong cycle and a far
/// timestamp; with a cycle that matches a far-future timestamp; with a far-past one. None
/// moves a clock, none faults a slave. Before the fix the clock filter took the 21st frame
/// of a burst and every slave's clock stepped.
#[test]
fn bursts_of_forged_lumped_frames_never_step_the_clocks() {
    let mut r = ring();
    r.run_until(300 * MS + 500_000);
    let far = 50_000 * MS as u64;
    for (cycle, stamp) in [(7u32, far), (50_000, far), (1, MS as u64)] {
        for _ in 0..30 {
            r.inject(1, r.now(), lumped(cycle, stamp, 4));
        }
        r.run_until(r.now() + 100_000);
    }
    r.run_until(1_000 * MS);
    // Each forged frame passes every slave (refused, forwarded unchanged) and the master.
    for s in &r.slaves {
        let c = s.counters().rejected;
        assert_eq!(c.get(Reject::WrongCycle), 30, "{c:?}");
        assert_eq!(c.get(Reject::FutureTimestamp), 30, "{c:?}");
        assert_eq!(c.get(Reject::Stale), 30, "{c:?}");
        assert!(!s.status().contains(Status::FAULT));
    }
    assert_eq!(r.master.counters().rejected.get(Reject::WrongCycle), 90);
    for i in 1..=4 {
        assert!(
            clock_error(&r, i).abs() < 100,
            "slave {i} clock off by {} ns",
            clock_error(&r, i)
        );
    }
    assert!(
        r.slave_events
            .iter()
            .all(|(_, _, e)| matches!(e, SlaveEvent::Apply { .. }))
    );
    assert!(stops(&r).is_empty());
}

/// Timestamps at the end of the time line: refused as overflows, no panic (a debug build
/// panicked on the slave's clock arithmetic before the fix).
#[test]
fn an_overflowing_timestamp_is_refused_without_a_panic() {
    let mut r = ring();
    r.run_until(50 * MS + 500_000);
    let t = r.now();
    r.inject(1, t, lumped(0, u64::MAX, 4));
    r.inject(1, t + 1, lumped(u32::MAX, i64::MAX as u64, 4));
    r.inject(3, t + 2, command(50, 3, 1.0, 0, u64::MAX));
    r.run_until(200 * MS);
    let c = r.slaves[0].counters().rejected;
    assert_eq!(c.get(Reject::Overflow), 2, "{c:?}");
    assert_eq!(r.slaves[2].counters().rejected.get(Reject::Overflow), 3);
    assert!(stops(&r).is_empty());
}

/// Every frame arrives twice: each is taken once. A command is never applied twice and a
/// lumped frame never read twice.
#[test]
fn duplicated_frames_are_taken_once() {
    let mut r = ring();
    r.tap = Some(Box::new(|_: &Hop, _: &mut Vec<u8>| Fate::Duplicate {
        after: 300,
    }));
    r.run_until(500 * MS);
    let m = r.master.counters();
    assert!(m.rejected.get(Reject::Duplicate) >= 500, "{m:?}");
    for (i, s) in r.slaves.iter().enumerate() {
        let c = s.counters();
        assert!(
            c.rejected.get(Reject::Duplicate) >= 500,
            "slave {}: {c:?}",
            i + 1
        );
        // At most one command applied per cycle, though every one came twice.
        let mut cycles: Vec<i64> = r
            .applied
            .iter()
            .filter(|a| a.1 == i + 1)
            .map(|a| a.0 / MS)
            .collect();
        let all = cycles.len();
        cycles.dedup();
        assert_eq!(
            cycles.len(),
            all,
            "slave {} applied twice in a cycle",
            i + 1
        );
        assert!(c.commands >= 495, "{c:?}");
    }
    assert!(stops(&r).is_empty());
    assert!(r.worst_error() < 0.1);
}

/// Frames of cycle 100 replayed at cycle 200: the slave refuses the lumped frame as stale
/// and the command as another cycle's; the master refuses the lumped frame.
#[test]
fn replayed_frames_are_refused() {
    let mut r = ring();
    let seen = std::rc::Rc::new(std::cell::RefCell::new(Vec::<(usize, Vec<u8>)>::new()));
    let keep = seen.clone();
    r.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
        if cycle_of(b) == 100 && (hop.to == 1 || hop.to == 3) {
            keep.borrow_mut().push((hop.to, b.clone()));
        }
        Fate::Deliver
    }));
    r.run_until(200 * MS + 500_000);
    let before = r.slaves[2].counters().commands;
    for (to, b) in seen.borrow().iter() {
        r.inject(*to, r.now(), b.clone());
    }
    r.run_until(200 * MS + 600_000);
    let s1 = r.slaves[0].counters().rejected;
    assert!(s1.get(Reject::Stale) >= 1, "{s1:?}");
    let s3 = r.slaves[2].counters().rejected;
    assert!(s3.get(Reject::WrongCycle) >= 1, "{s3:?}");
    assert_eq!(
        r.slaves[2].counters().commands,
        before,
        "nothing replayed was applied"
    );
    r.run_until(300 * MS);
    assert!(r.master.counters().rejected.get(Reject::WrongCycle) >= 1);
    assert!(stops(&r).is_empty());
}

/// Slave 2's response of cycle 100 is held back 15 µs: it comes after its slice has closed
/// and is refused; the master retries the slice in a reserve slice, the slave answers the
/// retry without applying the command again, and no command is lost.
#[test]
fn a_late_response_is_refused_and_its_slice_retried() {
    let mut r = ring();
    r.tap = Some(Box::new(|hop: &Hop, b: &mut Vec<u8>| {
        // Slave 2's own response (source at payload byte 0), first attempt.
        let own = b.get(12) == Some(&2) && b[3] == 0;
        if hop.from == 2 && is_kind(b, FrameKind::Response) && cycle_of(b) == 100 && own {
            return Fate::Delay { by: 15_000 };
        }
        Fate::Deliver
    }));
    r.run_until(300 * MS);
    let m = r.master.counters();
    assert_eq!(m.rejected.get(Reject::Unsolicited), 1, "{m:?}");
    assert_eq!((m.slices_failed, m.retries, m.retries_ok), (1, 1, 1));
    assert_eq!(m.commands_lost, 0);
    assert_eq!(r.slaves[1].counters().duplicates, 1);
    assert!(stops(&r).is_empty());
}

/// Responses that answer nothing: from a slave whose slice is not open, of another cycle.
#[test]
fn foreign_and_wrong_cycle_responses_are_refused() {
    let mut r = ring();
    r.run_until(100 * MS);
    // Cycle 100's P2P phase starts after the plan's T_syn (≈ 130 µs); slice 1 is open at
    // about 135 µs.
    let p2p = r.master.config().p2p_start.as_ns();
    r.run_until(100 * MS + p2p + 2_000);
    let t = r.now();
    r.inject(0, t, response(100, 3, 0));
    r.inject(0, t, response(101, 1, 0));
    r.inject(0, t, response(100, 9, 0));
    r.run_until(200 * MS);
    let m = r.master.counters();
    assert_eq!(m.rejected.get(Reject::Unsolicited), 2, "{m:?}");
    assert_eq!(m.rejected.get(Reject::WrongCycle), 1, "{m:?}");
    assert_eq!(m.commands_lost, 0);
}

/// From cycle 100 the frames keep carrying slave 2's sample of cycle 100 (a frozen slave
/// or a forger replaying it): the feedback watchdog, counted in the master's cycles, stops
/// the group after W cycles without a fresh sample.
#[test]
fn frozen_feedback_trips_the_watchdog_within_w_cycles() {
    let mut r = ring();
    let frozen = std::rc::Rc::new(std::cell::RefCell::new(None::<Vec<u8>>));
    let keep = frozen.clone();
    r.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
        if hop.to == 0 && is_kind(b, FrameKind::Lumped) && cycle_of(b) >= 100 {
            let at = 12 + 12 + FeedbackSlot::LEN;
            let slot = at..at + FeedbackSlot::LEN;
            let mut k = keep.borrow_mut();
            match k.as_ref() {
                None => *k = Some(b[slot].to_vec()),
                Some(old) => {
                    b[slot].copy_from_slice(old);
                    seal(b);
                }
            }
        }
        Fate::Deliver
    }));
    r.run_until(200 * MS);
    let s = stops(&r);
    assert_eq!(s.len(), 1, "{s:?}");
    assert_eq!(s[0].1, StopReason::NoFeedback { axis: 1 });
    // Fresh at cycle 100, then W = 5 law runs without: the stop comes at cycle 105.
    assert!(
        (105 * MS..106 * MS).contains(&s[0].0),
        "stop at {} ns",
        s[0].0
    );
    assert!(r.master.counters().samples_stale >= 5);
}

/// The master is gone at full speed. With `brake`, each slave damps its own axis to
/// standstill and then cuts torque; with `torque-off` it cuts torque at once and the axis
/// coasts (the testbed's axes have no friction: they keep their speed).
#[test]
fn a_slave_that_loses_its_master_brakes_or_cuts_torque() {
    for safe_state in [SafeState::Brake, SafeState::TorqueOff] {
        let mut r = Testbed::new(TestbedConfig {
            safe_state,
            ..TestbedConfig::default()
        });
        r.run_until(500 * MS);
        r.dead[0] = true;
        r.run_until(1_000 * MS);
        for i in 1..=4 {
            let ev: Vec<&SlaveEvent> = r
                .slave_events
                .iter()
                .filter(|(t, s, _)| *s == i && *t > 500 * MS)
                .map(|(_, _, e)| e)
                .collect();
            assert!(ev.contains(&&SlaveEvent::WatchdogExpired));
            let cause = ev.iter().find_map(|e| match e {
                SlaveEvent::TorqueOff { cause } => Some(*cause),
                _ => None,
            });
            let v = r.axes[i - 1].v;
            match safe_state {
                SafeState::Brake => {
                    assert_eq!(cause, Some(TorqueOffCause::Standstill), "slave {i}");
                    assert!(v.abs() < 0.1, "axis {i} at {v} rad/s");
                }
                SafeState::TorqueOff => {
                    assert_eq!(cause, Some(TorqueOffCause::Watchdog), "slave {i}");
                    assert!(v.abs() > 10.0, "axis {i} coasts at {v} rad/s");
                }
            }
            assert!(r.slaves[i - 1].torque_off());
            assert!(r.slaves[i - 1].status().contains(Status::TORQUE_OFF));
        }
    }
}

/// A slave driven by hand through a real step of the master's clock: the frames of the
/// new time line are refused for `relock_after`, then the slave re-locks once. A burst of
/// such frames between frames of the old time line never re-locks it.
#[test]
fn a_real_clock_step_relocks_after_a_bounded_time_and_a_burst_never_does() {
    let t_cyc = Duration::from_ms(1);
    let path = Duration::from_us(1);
    let mut s = Slave::new(SlaveConfig::new(1, t_cyc, path));
    let feed = |s: &mut Slave, k: i64, master_k: i64| {
        let rx = Instant::from_ns(k * MS + 1_000);
        let mut b = lumped(master_k as u32, (master_k * MS) as u64, 1);
        let _ = s.handle_frame(rx, rx, &mut b);
    };
    for k in 0..50 {
        feed(&mut s, k, k);
    }
    // A burst of 30 frames of a time line 5 s ahead, then the old one goes on.
    for k in 50..80 {
        feed(&mut s, k, k + 5_000);
    }
    for k in 80..400 {
        feed(&mut s, k, k);
    }
    assert_eq!(s.counters().relocks, 0);
    assert_eq!(s.counters().rejected.get(Reject::FutureTimestamp), 30);
    // Now the master really steps 5 s ahead and stays there.
    for k in 400..700 {
        feed(&mut s, k, k + 5_000);
    }
    let c = s.counters();
    assert_eq!(c.relocks, 1, "{c:?}");
    // Refused for relock_after (100 cycles), then taken.
    assert_eq!(c.rejected.get(Reject::FutureTimestamp), 30 + 100);
    let step = std::iter::from_fn(|| s.poll_event())
        .find_map(|e| match e {
            SlaveEvent::Relocked { step } => Some(step),
            _ => None,
        })
        .expect("a relock event");
    assert!((step.as_ns() - 5_000 * MS).abs() < 10_000, "step {step}");
    let now = Instant::from_ns(700 * MS);
    assert!((s.clock().to_sync(now).as_ns() - (5_700 * MS)).abs() < 10_000);
    // The old time line is now the foreign one.
    feed(&mut s, 700, 700);
    assert_eq!(s.counters().rejected.get(Reject::Stale), 1);
}

/// A TORQUE_OFF order (here forged into cycle 100's command to slave 2) is latched: the
/// slave cuts torque and applies none of the master's later commands.
#[test]
fn a_torque_off_order_is_latched() {
    let mut r = ring();
    r.tap = Some(Box::new(|hop: &Hop, b: &mut Vec<u8>| {
        if hop.to == 2 && is_kind(b, FrameKind::Command) && cycle_of(b) == 100 && b[12] == 2 {
            b[2] = Flags::STOP.with(Flags::TORQUE_OFF).bits();
            seal(b);
        }
        Fate::Deliver
    }));
    r.run_until(300 * MS);
    assert!(r.slaves[1].torque_off());
    assert!(r.slaves[1].status().contains(Status::TORQUE_OFF));
    assert!(r.axes[1].off && r.axes[1].u == 0.0);
    let last = r
        .applied
        .iter()
        .filter(|a| a.1 == 2)
        .map(|a| a.0)
        .max()
        .unwrap_or(0);
    assert!(last < 100 * MS, "slave 2 applied a command at {last} ns");
    // The master did not order it: its response says TORQUE_OFF, so something else
    // commands the axis, and the group stops at the next law run (fuzzing finding F5: the
    // others used to go on until the following error tripped, 77-354 ms later).
    let s = stops(&r);
    assert_eq!(s.len(), 1, "{s:?}");
    let (t, reason) = s[0];
    assert!(
        matches!(reason, StopReason::CommandMismatch { axis: 1, .. }),
        "{reason:?}"
    );
    assert!((100 * MS..102 * MS).contains(&t), "stopped at {t} ns");
}

/// A lumped frame of cycle 5000 and its command (left over from an earlier run), then the
/// master from cycle 1: the slave restarts its acquisition and takes the master's commands
/// (fuzzing finding F4: the stray command's cycle held off every command of the new time
/// line as stale, up to 2^31 cycles).
#[test]
fn a_stray_command_does_not_hold_off_the_next_time_line() {
    let mut s = Slave::new(SlaveConfig::new(
        1,
        Duration::from_ms(1),
        Duration::from_us(1),
    ));
    let mut feed = |local: i64, mut b: Vec<u8>| {
        let t = Instant::from_ns(local);
        s.handle_frame(t, t, &mut b)
    };
    let _ = feed(1_000, lumped(5_000, (5_000 * MS) as u64, 1));
    let _ = feed(200_000, command(5_000, 1, 1.0, 0, (4_999 * MS) as u64));
    for k in 1..=10i64 {
        let _ = feed(k * MS + 1_000, lumped(k as u32, (k * MS) as u64, 1));
        let out = feed(
            k * MS + 200_000,
            command(k as u32, 1, 0.5, 0, ((k - 1) * MS) as u64),
        );
        // From cycle 2 on, two agreeing frames have locked the clock.
        if k >= 2 {
            assert_eq!(out, FrameOutcome::Consumed, "cycle {k}");
        }
    }
    let c = s.counters();
    assert_eq!(c.acquisitions_restarted, 1);
    assert_eq!(c.rejected.get(Reject::Stale), 0, "{c:?}");
}

/// A stray lumped frame (one left in a socket by an earlier run, or a forgery) reaches
/// every slave before the master's first: it cannot capture them. The first real frame
/// disagrees with it and starts acquisition afresh; the second agrees and locks.
#[test]
fn a_stray_frame_before_the_first_cannot_capture_a_slave() {
    let mut r = ring();
    r.inject(1, 0, lumped(300, 300 * MS as u64, 4));
    r.run_until(200 * MS);
    assert!(stops(&r).is_empty(), "{:?}", stops(&r));
    for (i, s) in r.slaves.iter().enumerate() {
        let c = s.counters();
        assert!(c.commands >= 198, "slave {}: {c:?}", i + 1);
        assert_eq!(c.rejected.total(), 0, "slave {}: {c:?}", i + 1);
        assert!(clock_error(&r, i + 1).abs() < 100);
    }
}

/// A lumped frame stamped at the end of the time line reaches the slaves before the
/// master's first: refused as an overflow. Before the fix it was taken on trust, the
/// sampling instant k·T saturated, and every driver spun forever on the same latch.
#[test]
fn a_stamp_at_the_end_of_the_time_line_is_refused() {
    let mut r = ring();
    let stamp = (i64::MAX - 1_000) as u64;
    r.inject(1, 0, lumped((stamp / MS as u64) as u32, stamp, 4));
    let near = (Instant::HORIZON.as_ns() + 1) as u64;
    r.inject(1, 10, lumped((near / MS as u64) as u32, near, 4));
    r.run_until(200 * MS);
    for s in &r.slaves {
        assert_eq!(
            s.counters().rejected.get(Reject::Overflow),
            2,
            "{:?}",
            s.counters()
        );
        assert!(s.samples_taken() >= 200 && s.samples_taken() <= 202);
    }
    assert!(stops(&r).is_empty());
}

/// For ten cycles in a row every lumped frame comes back 50 µs after the P2P start (a
/// link with jitter): its samples are taken late, after the law ran. The axes are not
/// blind: no feedback stop. Before the fix the watchdog counted only samples taken before
/// the law's run, and the ring stopped after W = 5 such cycles.
#[test]
fn samples_that_come_back_late_still_feed_the_watchdog() {
    let mut r = ring();
    let late = r.master.config().p2p_start.as_ns() + 50_000;
    r.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
        if hop.to == 0 && is_kind(b, FrameKind::Lumped) && (100..110).contains(&cycle_of(b)) {
            return Fate::Delay { by: late };
        }
        Fate::Deliver
    }));
    r.run_until(300 * MS);
    assert!(stops(&r).is_empty(), "{:?}", stops(&r));
    assert_eq!(r.master.counters().lumped_lost, 10);
    assert!(r.worst_error() < 0.1, "{}", r.worst_error());
}

/// The real lumped frame of cycle 300 to slave 1 is lost, and a forger sends two frames
/// that lie about the time between them (1 ns of master time in 20 µs). Before the fix the
/// clock took the rate 20000/1 from them: every later frame fell outside its window and
/// the slave sampled once every 2.5 s. Now the rate stays within 1000 ppm of 1.
#[test]
fn two_lying_frames_cannot_set_a_clock_rate() {
    let mut r = ring();
    r.tap = Some(Box::new(|hop: &Hop, b: &mut Vec<u8>| {
        if hop.to == 1 && is_kind(b, FrameKind::Lumped) && cycle_of(b) == 300 {
            return Fate::Drop;
        }
        Fate::Deliver
    }));
    r.run_until(300 * MS + 500_000);
    r.inject(1, 301 * MS - 29_000, lumped(300, 301 * MS as u64, 4));
    r.inject(1, 301 * MS - 9_000, lumped(301, 301 * MS as u64 + 1, 4));
    r.run_until(1_000 * MS);
    for (i, s) in r.slaves.iter().enumerate() {
        assert!(
            (s.clock().rate() - 1.0).abs() < 1e-3,
            "slave {}: {}",
            i + 1,
            s.clock().rate()
        );
        assert!(
            s.samples_taken() >= 995,
            "slave {}: {}",
            i + 1,
            s.samples_taken()
        );
    }
    assert!(stops(&r).is_empty(), "{:?}", stops(&r));
}

/// Forged commands of the cycle in progress. One before the P2P phase (the master
/// computes there, so none of its commands comes earlier) is refused. One during the P2P
/// phase, ahead of the master's own, is taken by the slave (nothing in it can tell): but
/// the slave's response says what it applied, the master sees that it is not what it sent,
/// and stops the group. Before the fix the forged 10 V was applied every cycle unnoticed.
#[test]
fn a_forged_command_of_the_current_cycle_is_refused_or_caught() {
    let mut r = ring();
    r.run_until(100 * MS);
    r.inject(2, 100 * MS + 20_000, command(100, 2, 10.0, 0, 0));
    r.run_until(100 * MS + 25_000);
    assert_eq!(r.slaves[1].counters().rejected.get(Reject::WrongCycle), 1);
    assert!(r.applied.iter().all(|a| a.2 != 10.0));
    // During the P2P phase, before the master's command to slave 2 (its slice is second).
    let p2p = r.master.config().p2p_start.as_ns();
    r.run_until(200 * MS);
    r.inject(2, 200 * MS + p2p + 1_000, command(200, 2, 10.0, 0, 0));
    r.run_until(210 * MS);
    let s = stops(&r);
    assert!(
        matches!(
            s.first(),
            Some((_, StopReason::CommandMismatch { axis: 1, .. }))
        ),
        "{s:?}"
    );
    assert_eq!(r.master.counters().command_mismatches, 1);
}

/// The master really steps to a new time line, and a stray frame of a third time line
/// comes every 50 ms. The stray frames do not hold off the re-lock (before the fix each
/// one restarted the candidate, and the slave never re-locked).
#[test]
fn stray_frames_do_not_hold_off_a_relock() {
    let t_cyc = Duration::from_ms(1);
    let mut s = Slave::new(SlaveConfig::new(1, t_cyc, Duration::from_us(1)));
    let feed = |s: &mut Slave, k: i64, master_k: i64| {
        let rx = Instant::from_ns(k * MS + 1_000);
        let mut b = lumped(master_k as u32, (master_k * MS) as u64, 1);
        let _ = s.handle_frame(rx, rx, &mut b);
    };
    for k in 0..50 {
        feed(&mut s, k, k);
    }
    for k in 50..400 {
        feed(&mut s, k, k + 5_000);
        if k % 50 == 25 {
            feed(&mut s, k, k + 90_000);
        }
    }
    assert_eq!(s.counters().relocks, 1, "{:?}", s.counters());
}

/// Found by the fuzzer: a slave of the lumped-only plan took a command frame (that plan
/// carries none) and applied it on top of its own law's output.
#[test]
fn a_lumped_only_slave_takes_no_command() {
    /// A law that always commands 1 V.
    struct One;
    impl SlaveLaw for One {
        fn axes(&self) -> usize {
            1
        }
        fn command(&mut self, _: usize, _: &[Option<FeedbackSlot>], _: f64) -> f64 {
            1.0
        }
    }
    let t_cyc = Duration::from_ms(1);
    let control = Box::new(One);
    let mut s = Slave::with_law(SlaveConfig::new(1, t_cyc, Duration::from_us(1)), control);
    let rx = Instant::from_ns(3_200_000);
    let mut b = command(3, 1, 10.0, 0, 3_000_000);
    assert_eq!(s.handle_frame(rx, rx, &mut b), FrameOutcome::Dropped);
    assert_eq!(s.counters().rejected.get(Reject::UnexpectedKind), 1);
    assert!(s.poll_event().is_none());
    assert!(s.poll_transmit().is_none());
}

/// Found by the fuzzer: an encoder count difference of i64::MIN made the brake's
/// standstill test overflow (a panic in debug builds).
#[test]
fn the_brake_survives_any_encoder_count() {
    let mut s = Slave::new(SlaveConfig::new(1, Duration::from_ms(1), Duration::ZERO));
    // No command ever: after W cycles the slave brakes.
    for _ in 0..12 {
        let at = s.poll_timeout();
        s.handle_sample(at, 0);
        let at = s.poll_timeout();
        s.handle_sample(at, 0);
    }
    assert!(s.status().contains(Status::BRAKING) || s.torque_off());
    let at = s.poll_timeout();
    s.handle_sample(at, 0);
    let at = s.poll_timeout();
    s.handle_sample(at, i64::MIN);
}

/// Found by the fuzzer: one lumped frame 60 µs (or 450 µs) late at slave 2, before the
/// clock window was symmetric and rates were bounded, threw its clock off until a re-lock
/// and the group stopped. Now the late frame is refused (or taken within the window) and
/// the clock stays put.
#[test]
fn one_late_sync_frame_does_not_throw_a_clock_off() {
    for late in [40_000, 60_000, 450_000] {
        let mut r = ring();
        r.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
            if hop.to == 2 && is_kind(b, FrameKind::Lumped) && cycle_of(b) == 50 {
                return Fate::Delay { by: late };
            }
            Fate::Deliver
        }));
        r.run_until(300 * MS);
        assert!(stops(&r).is_empty(), "{late} ns: {:?}", stops(&r));
        assert!(
            clock_error(&r, 2).abs() < 1_000,
            "{late} ns: {}",
            clock_error(&r, 2)
        );
        assert_eq!(r.slaves[1].counters().relocks, 0);
    }
}

/// The testbed's master, afresh, expecting transparent relays on links of `link` ns.
fn expect_transparent(r: &mut Testbed, link: i64) {
    let mut cfg = r.master.config().clone();
    cfg.transparent_link = Some(Duration::from_ns(link));
    r.master = Master::new(
        cfg,
        Box::new(super::testbed::PdMotion::new(
            4,
            15.12,
            1.0,
            super::testbed::RESOLUTION,
        )),
    );
}

/// Relays that hold each sync lumped frame for a varying time (0-10 µs, as a process that
/// must wake): when each adds the time it held the frame to the frame's stamp (a
/// transparent relay, `ringsync_wire::add_to_master_time`) and the master expects it, every
/// clock follows the master's within 100 ns; the same relays without the correction throw
/// the far slaves' clocks µs off; and a master that does not expect the correction refuses
/// its frames back.
#[test]
fn transparent_relays_keep_the_clocks_exact_through_varying_residences() {
    let run = |correct: bool, expect: bool| {
        let mut r = ring();
        if expect {
            expect_transparent(&mut r, 1_000);
        }
        let mut draw = 12_345u64;
        r.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
            if hop.from == 0 || !is_kind(b, FrameKind::Lumped) {
                return Fate::Deliver;
            }
            draw = draw
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let held = (draw >> 33) % 10_000;
            if correct {
                assert_eq!(
                    ringsync_wire::add_to_master_time(b, held),
                    Ok(ringsync_wire::Relayed::Corrected)
                );
            }
            Fate::Delay { by: held as i64 }
        }));
        r.run_until(500 * MS + 300_000);
        let errors: Vec<i64> = (1..=4).map(|i| clock_error(&r, i)).collect();
        (r, errors)
    };
    let (r, errors) = run(true, true);
    assert!(errors.iter().all(|e| e.abs() < 100), "{errors:?}");
    assert_eq!(
        r.master.counters().rejected.total(),
        0,
        "{:?}",
        r.master.counters()
    );
    assert!(stops(&r).is_empty());
    let (_, errors) = run(false, false);
    assert!(errors[3].abs() > 5_000, "uncorrected: {errors:?}");
    let (r, _) = run(true, false);
    assert!(
        r.master.counters().rejected.get(Reject::Unsolicited) >= 400,
        "{:?}",
        r.master.counters()
    );
}

/// Links slower than the start-up phase measured (1 000 ns per hop where the slaves were
/// given 1 400 ns per hop as their links alone, i·L): each slave's clock runs ahead by i ×
/// 400 ns. Behind transparent relays the master measures the links from its frames' round
/// trips and sends the estimate with its commands; slaves that follow it take i × 1 000 ns
/// and their clocks come within 100 ns. A slave that does not follow the link refuses it
/// (counted) and keeps the path it was given; a link that would move a path by more than
/// half the clock window is refused too.
#[test]
fn behind_transparent_relays_the_slaves_follow_the_links_the_master_measures() {
    let run = |given_link: i64, follow: bool| {
        let mut r = ring();
        expect_transparent(&mut r, given_link);
        for (k, s) in r.slaves.iter_mut().enumerate() {
            let i = k as i64 + 1;
            *s = Slave::new(SlaveConfig {
                path_delay: Duration::from_ns(given_link * i),
                follow_link: follow,
                ..s.config().clone()
            });
        }
        r.run_until(500 * MS + 300_000);
        let errors: Vec<i64> = (1..=4).map(|i| clock_error(&r, i)).collect();
        (r, errors)
    };
    let (r, errors) = run(1_400, true);
    assert!(errors.iter().all(|e| e.abs() < 100), "{errors:?}");
    assert_eq!(
        r.master.link_estimate().map(|(d, _)| d),
        Some(Duration::from_ns(1_000))
    );
    for (k, s) in r.slaves.iter().enumerate() {
        assert_eq!(
            s.path_delay(),
            Some(Duration::from_ns(1_000 * (k as i64 + 1)))
        );
        assert_eq!(
            (s.counters().link_updates, s.counters().links_refused),
            (1, 0)
        );
    }
    assert!(stops(&r).is_empty());
    // Not following: each clock ahead by i × 400 ns, every link refused.
    let (r, errors) = run(1_400, false);
    for (k, e) in errors.iter().enumerate() {
        let ahead = 400 * (k as i64 + 1);
        assert!((e - ahead).abs() < 100, "slave {}: {errors:?}", k + 1);
    }
    assert!(r.slaves.iter().all(|s| s.counters().links_refused > 400
        && s.path_delay() == Some(Duration::from_ns(1_400 * (s.config().address as i64)))));
    // Given 14 µs per hop: slave 4 would move 52 µs, beyond half its ±50 µs window.
    let (r, _) = run(14_000, true);
    let s4 = &r.slaves[3];
    assert_eq!(s4.path_delay(), Some(Duration::from_ns(56_000)));
    assert!(s4.counters().links_refused > 0 && s4.counters().link_updates == 0);
}

/// A link rides only in a command the slave accepted: forged commands of another cycle
/// that carry one (1.5 µs, which a following slave would take: 3 µs from its 2 µs path,
/// within half its window) are refused whole, and the slave's path does not move.
#[test]
fn a_link_in_a_refused_command_moves_no_path() {
    let mut r = ring();
    let cfg = r.slaves[1].config().clone();
    r.slaves[1] = Slave::new(SlaveConfig {
        follow_link: true,
        ..cfg
    });
    r.run_until(100 * MS);
    let with_link = |cycle: u32| {
        let repr = CommandRepr {
            common: Common {
                cycle,
                ..Common::default()
            },
            target: 2,
            command_v: 10.0,
            sample_time_ns: 0,
            link_ns: 1_500,
        };
        let mut b = vec![0; repr.buffer_len()];
        repr.emit(&mut b).expect("emit command");
        b
    };
    for k in 100..200i64 {
        r.inject(2, k * MS + 500_000, with_link((k + 7) as u32));
        r.run_until(k * MS + 600_000);
    }
    r.run_until(200 * MS);
    let s = &r.slaves[1];
    let c = s.counters();
    assert_eq!(c.rejected.get(Reject::WrongCycle), 100, "{c:?}");
    assert_eq!((c.link_updates, c.links_refused), (0, 0), "{c:?}");
    assert_eq!(s.path_delay(), Some(Duration::from_ns(2_000)));
    assert!(clock_error(&r, 2).abs() < 100);
}
