//! One [`Master`] alone (4 axes, the testbed's plan; its motion `ringsync-model`'s
//! `ControlMotion`, PD on a cosine with the group stop's ramps and orders, a stop timeout of
//! 300 ms; the proposed plan, with the plan's P2P schedule or one as measured on real links
//! (`MasterConfig::with_measured`, any that fits the cycle), or the lumped-only plan), fed an
//! arbitrary interleaving of
//! `handle_timeout` (at `poll_timeout()`, or later: a driver that wakes late) and
//! `handle_frame` (at any time up to the next deadline): its own last lumped frame returned
//! with any slots and header fields, forged responses and commands with any fields (cycles
//! near the master's, times near now or at the time line's horizon), sealed and unsealed raw
//! bytes, and whole cycles of a perfect ring (every lumped frame back with fresh samples near
//! the desired path, every command answered with what it carried), with quirks, so that the
//! fuzzer reaches the law, the slices, the retries, the watchdogs, the group stop and its
//! orders.
//!
//! The harness mirrors what the master must have taken: each returned lumped frame it
//! accepted (its "last seen" cycle moves) and the samples in it that were newer than the last
//! one and not from the future, and each response it accepted (nothing counted as refused).
//!
//! # Invariants
//! - No panic.
//! - Every frame it sends parses; leaves at the time of the call that sent it (never before
//!   an earlier one); a lumped frame is stamped with that time and carries the cycle in
//!   progress (which advances by one at a time), no flags on the proposed plan, STOP|BRAKE
//!   on the lumped-only plan from the group stop on (none before). A command targets an
//!   axis 1..=4, carries the cycle of the last lumped frame, retry 0 or 1, a finite value
//!   within ±10 V, STOP iff the group stops, BRAKE iff the axis was ordered to brake,
//!   TORQUE_OFF iff it was ordered off, and 0 V when ordered or blind (no fresh sample for
//!   W law runs). No command on the lumped-only plan.
//! - Acceptance: a response is taken only if it answers the open slice (the last command
//!   sent: its target, cycle and retry), once.
//! - `CommandMismatch`: `command_mismatches` moves only when a response is taken, by one,
//!   exactly when its status is not FAULT and either shows BRAKING or TORQUE_OFF for an axis
//!   this master has not ordered (a forged order: F5, fixed in 02bbcce) or, without those,
//!   its applied command is not what the master sent in that slice (clipped, if the response
//!   says SATURATED). A mismatch counted since the last law run stops the group at the next
//!   one, and a stop for a mismatch names such a response's axis, sent and applied values.
//! - Watchdogs: a law run (a cycle end on the lumped-only plan) after W in a row without a
//!   newly taken sample of an axis (late samples count) stops the group; a stop for no
//!   feedback names such an axis, and one for no response an axis whose slices went
//!   unanswered W cycles in a row.
//! - Orders (the group stop): only while stopping; per axis at most a Brake, then at most a
//!   TorqueOff, nothing after; Brake for an axis without feedback (or every axis on the
//!   lumped-only plan, at the stop), TorqueOff for one that cannot follow its ramp, has
//!   held still at the end of it, or at the stop timeout, by which every axis is off.
//!   `Master::order` agrees.
//! - Timestamps: no sample from the future (so none past `Instant::HORIZON`) reaches the
//!   master's feedback: each record's sampling instants (written slots on the lumped-only
//!   plan) are at most now + `timestamp_tolerance`.
//! - `poll_timeout()`: after `handle_timeout(t)` (t ≥ the deadline d it answered) the next
//!   deadline is ≥ d − turnaround. It is not always ≥ t: a driver that wakes late gets the
//!   deadlines it missed (past ones, to run at once); and a slice that ends by its response
//!   within the last `turnaround` of a cycle pulls the next slice to after the cycle's end,
//!   where the master finds nothing fits and answers the next cycle's start, which is then
//!   up to `turnaround` in the past (the next lumped frame leaves that late, stamped with its
//!   real send time). After `handle_frame(t)` the deadline is unchanged, or t + turnaround
//!   (a response ended the slice). At most 64 calls in a row at one time (no livelock).
//! - The record after `Computed { k }` is cycle k's, k increases; with the proposed plan
//!   its commands are finite and within ±10 V (with the lumped-only plan they are what the
//!   slaves reported, finite by the wire format).
//! - A group stop happens at most once and is final.
//! - Counters never decrease.
#![no_main]

use std::collections::HashSet;

use libfuzzer_sys::arbitrary::{self, Arbitrary, Unstructured};
use libfuzzer_sys::fuzz_target;
use ringsync_control::{AxisTrajectory, Cosine, Gains, Pd, VelocitySource};
use ringsync_model::motion::{ControlMotion, StopSettings};
use ringsync_proto::node::{
    Master, MasterConfig, MasterCounters, MasterEvent, MeasuredSchedule, OffReason, StopOrder,
    StopReason, Transmit,
};
use ringsync_proto::{CyclePlan, Duration, Instant, RingParams};
use ringsync_wire::{
    CommandRepr, FeedbackSlot, Flags, LumpedOnlySlot, LumpedRepr, Pdu, ResponseRepr, Status,
};

#[path = "forge.rs"]
mod forge;
#[path = "seal.rs"]
mod seal;

use forge::{CYCLE_NS as T, CycleSel, Head, Resp, Slot, When};

/// Axes.
const N: usize = 4;
/// Drive range [V].
const U_MAX: f64 = 10.0;
/// Longest input in master time [ns].
const TOTAL: i64 = 2_000 * T;
/// Most a driver wakes late [ns].
const MAX_LATE: u32 = 2_000_000;
/// The stop's longest time here (300 ms, so that inputs reach it) [ns].
const STOP_TIMEOUT: i64 = 300 * T;
/// How long an axis holds still at the end of its stop ramp before its torque goes off [ns]
/// (`StopSettings::default()`'s).
const STOP_HOLD: i64 = 100 * T;
/// The following-error limit [rad].
const FE_LIMIT: f64 = 1.0;

/// The master's set-up, the first bytes of an input.
#[derive(Arbitrary, Debug)]
struct Setup {
    lumped_only: bool,
    /// On the proposed plan: the P2P phase as measured on real links
    /// (`MasterConfig::with_measured`, as the runtime sets it) instead of the plan's.
    measured: Option<Measured>,
}

/// A measured P2P schedule, always one that fits the cycle (P2P start + 4 slices + guard
/// well under 1 ms, as the runtime requires).
#[derive(Arbitrary, Debug)]
struct Measured {
    /// The P2P start this many µs after the plan's (the runtime never starts earlier).
    p2p_after_us: u8,
    /// Slice and guard [ns], at least 1 µs and 0.
    slice_ns: u16,
    guard_ns: u16,
    /// Per slave: the command's transit and its typical slice [ns].
    transit_ns: [u16; N],
    typical_ns: [u16; N],
}

impl Measured {
    fn schedule(&self, plan_p2p: Duration) -> MeasuredSchedule {
        let ns = |x: u16| Duration::from_ns(i64::from(x));
        MeasuredSchedule {
            p2p_start: plan_p2p + Duration::from_us(i64::from(self.p2p_after_us)),
            slice: ns(self.slice_ns.max(1_000)),
            guard: ns(self.guard_ns),
            command_transit: self.transit_ns.iter().map(|&x| ns(x)).collect(),
            typical_slice: self.typical_ns.iter().map(|&x| ns(x)).collect(),
        }
    }
}

#[derive(Arbitrary, Debug)]
enum Op {
    /// `handle_timeout` at `poll_timeout()`, or `late` after it.
    Timeout { late: Late },
    /// A frame arriving `after_ns` (mod 1.2 ms) after the last input, capped at the next
    /// deadline.
    Frame { after_ns: u32, frame: MFrame },
    /// `1 + cycles % 64` cycles of a perfect ring; positions `error` counts off the desired path;
    /// `quirk` bit 0 loses the lumped frame, bit 1 axis `quirk >> 4`'s responses, bit 2
    /// marks that axis FAULT, bit 3 makes the samples 1 µs late, bit 6 makes that axis's
    /// responses report 1 V more than the command, bit 7 report BRAKING.
    Ring { cycles: u8, error: i32, quirk: u8 },
}

#[derive(Arbitrary, Debug, Clone, Copy)]
enum Late {
    OnTime,
    By(u32),
}

#[derive(Arbitrary, Debug)]
enum MFrame {
    /// The master's last lumped frame back, slots rewritten, header fields replaced.
    Returned {
        slots: Vec<Slot>,
        cycle: Option<CycleSel>,
        seq: Option<u16>,
        stamp: Option<When>,
        first: Option<u16>,
        count: Option<u8>,
    },
    Response {
        head: Head,
        resp: Resp,
    },
    Command {
        head: Head,
        target: u8,
        value: f32,
        sample: When,
    },
    Sealed(Vec<u8>),
    Raw(Vec<u8>),
}

/// The last command sent: the open slice, if the master has one.
#[derive(Debug, Clone, Copy)]
struct Sent {
    axis: usize,
    cycle: u32,
    retry: u8,
    value: f32,
}

struct Harness {
    m: Master,
    now: i64,
    /// The last transmit's time, lumped frame's cycle and bytes.
    last_tx: i64,
    cycle: Option<u32>,
    last_lumped: Option<Vec<u8>>,
    /// Frames sent since the perfect ring last answered.
    sent: Vec<Transmit>,
    /// When the group stop began [ns].
    stopped: Option<i64>,
    orders: [Option<StopOrder>; N],
    last_k: Option<i64>,
    same_time_calls: u32,
    lumped_only: bool,
    w: u32,
    tolerance: i64,
    /// The last command sent (the open slice), until a response to it is taken.
    open: Option<Sent>,
    /// Mismatches the master had to count since the last law run: (axis, sent, applied).
    mismatches: HashSet<(usize, u32, u32)>,
    /// Mirror of the master's feedback: the newest sample taken per axis [ns], whether one
    /// was taken since the last law run, law runs since one was, and cycles in a row
    /// without a response taken.
    latest: [Option<u64>; N],
    fed: [bool; N],
    since_fresh: [u32; N],
    acked: [bool; N],
    missed: [u32; N],
}

impl Harness {
    fn new(setup: &Setup) -> Self {
        let lumped_only = setup.lumped_only;
        let plan = CyclePlan::new(&RingParams {
            slaves: N as u32,
            ..RingParams::default()
        })
        .unwrap_or_else(|e| panic!("plan: {e}"));
        let res = std::f64::consts::TAU / f64::from(1u32 << 20);
        let mut cfg = if lumped_only {
            MasterConfig::lumped_only(&plan, vec![res; N])
        } else {
            let cfg = MasterConfig::from_plan(&plan, Duration::ZERO, vec![res; N]);
            match &setup.measured {
                Some(m) => {
                    let p2p = cfg.p2p_start;
                    cfg.with_measured(&m.schedule(p2p))
                }
                None => cfg,
            }
        };
        cfg.watchdog_cycles = 5;
        let w = cfg.watchdog_cycles;
        let tolerance = cfg.timestamp_tolerance.as_ns();
        let law = Pd::new(Gains::uniform(N, 3.182, 1.591, 0.0), false)
            .unwrap_or_else(|e| panic!("law: {e}"));
        let traj =
            Cosine::with_peak_speed(15.12, 2.0).unwrap_or_else(|e| panic!("trajectory: {e}"));
        // The motion the simulator and the runtime run (`ringsync-model`): the law, the
        // supervision, the group stop's ramps and orders.
        let motion = ControlMotion::new(
            Box::new(law),
            VelocitySource::Reported,
            vec![AxisTrajectory::Cosine(traj); N],
            vec![res; N],
            Duration::from_ns(T),
            StopSettings {
                following_error_limit: FE_LIMIT,
                hold: Duration::from_ns(STOP_HOLD),
                timeout: Duration::from_ns(STOP_TIMEOUT),
                ..StopSettings::default()
            },
        );
        let m = Master::new(cfg, Box::new(motion));
        Harness {
            m,
            now: 0,
            last_tx: i64::MIN,
            cycle: None,
            last_lumped: None,
            sent: Vec::new(),
            stopped: None,
            orders: [None; N],
            last_k: None,
            same_time_calls: 0,
            lumped_only,
            w,
            tolerance,
            open: None,
            mismatches: HashSet::new(),
            latest: [None; N],
            fed: [false; N],
            since_fresh: [0; N],
            acked: [false; N],
            missed: [0; N],
        }
    }

    fn turnaround(&self) -> i64 {
        self.m.config().turnaround.as_ns()
    }

    /// `handle_timeout` at the deadline, `late` after it, or now if that has passed.
    fn timeout(&mut self, late: i64) {
        let d = self.m.poll_timeout().as_ns();
        let t = d.saturating_add(late).max(self.now);
        if t == self.now {
            self.same_time_calls += 1;
            assert!(self.same_time_calls <= 64, "64 calls at {t} ns: a livelock");
        } else {
            self.same_time_calls = 0;
        }
        self.now = t;
        let before = self.m.counters();
        let k = self.m.cycle();
        self.m.handle_timeout(Instant::from_ns(t));
        let next = self.m.poll_timeout().as_ns();
        assert!(
            next >= d - self.turnaround(),
            "deadline {d} ns answered at {t} ns, next deadline {next} ns"
        );
        assert_eq!(
            self.m.counters().command_mismatches,
            before.command_mismatches,
            "a mismatch counted without a response"
        );
        let ended = self.m.cycle() != k;
        if ended {
            assert_eq!(self.m.cycle(), k + 1, "cycle {k} -> {}", self.m.cycle());
            self.cycle_ended();
        }
        self.drain(t, &before, ended);
    }

    /// The master ended a cycle: slices unanswered count, and on the lumped-only plan its
    /// feedback watchdog ran.
    fn cycle_ended(&mut self) {
        if self.lumped_only {
            self.law_ran();
        } else {
            for i in 0..N {
                self.missed[i] = if self.acked[i] { 0 } else { self.missed[i] + 1 };
            }
        }
        self.acked = [false; N];
        self.open = None;
    }

    /// The law ran (the proposed plan) or the cycle ended (lumped-only): the feedback
    /// watchdog counts.
    fn law_ran(&mut self) {
        for i in 0..N {
            self.since_fresh[i] = if std::mem::take(&mut self.fed[i]) {
                0
            } else {
                self.since_fresh[i].saturating_add(1)
            };
        }
    }

    /// Runs every deadline up to `until`, then returns the time a frame may arrive at.
    fn timeouts_until(&mut self, until: i64) -> i64 {
        for _ in 0..256 {
            if self.m.poll_timeout().as_ns() > until {
                break;
            }
            self.timeout(0);
        }
        until.max(self.now)
    }

    fn frame(&mut self, at: i64, bytes: &[u8]) {
        let t = self.timeouts_until(at);
        self.now = t;
        self.same_time_calls = 0;
        let d = self.m.poll_timeout().as_ns();
        let before = self.m.counters();
        let seen = self.m.last_lumped_cycle();
        self.m.handle_frame(Instant::from_ns(t), bytes);
        let after = self.m.counters();
        let next = self.m.poll_timeout().as_ns();
        assert!(
            next == d || next == t + self.turnaround(),
            "a frame at {t} ns moved the deadline {d} -> {next} ns"
        );
        // What the master took, mirrored.
        let newest = t.saturating_add(self.tolerance).max(0) as u64;
        if self.m.last_lumped_cycle() != seen {
            self.took_lumped(bytes, newest);
        }
        let mut expect = 0;
        if bytes.get(1) == Some(&3) && after.rejected.total() == before.rejected.total() {
            let r = ResponseRepr::parse(bytes)
                .unwrap_or_else(|e| panic!("the master took a response that does not parse: {e}"));
            let Some(s) = self.open.take() else {
                panic!("the master took {r:?} with no slice open");
            };
            assert!(
                usize::from(r.source) == s.axis + 1
                    && r.common.cycle == s.cycle
                    && r.echo_cycle == s.cycle
                    && r.common.retry == s.retry,
                "the master took {r:?} in the slice of {s:?}"
            );
            self.acked[s.axis] = true;
            // The master's rule (F5's fix, 02bbcce): a drive in its own safe state says FAULT
            // and is not checked; one braking or off must have been ordered so by this
            // master; any other must have applied what it was sent.
            let stopped = Status::BRAKING.bits() | Status::TORQUE_OFF.bits();
            let (sent, applied) = (s.value, r.applied_v);
            let ok = if r.status.contains(Status::FAULT) {
                true
            } else if r.status.bits() & stopped != 0 {
                self.orders[s.axis].is_some()
            } else if r.status.contains(Status::SATURATED) {
                applied.abs() <= sent.abs() && applied * sent > 0.0
            } else {
                applied == sent
            };
            if !ok {
                expect = 1;
                self.mismatches
                    .insert((s.axis, sent.to_bits(), applied.to_bits()));
            }
        }
        assert_eq!(
            after.command_mismatches - before.command_mismatches,
            expect,
            "command mismatches counted"
        );
        self.drain(t, &before, false);
    }

    /// The master took a returned lumped frame: the samples it had to take.
    fn took_lumped(&mut self, bytes: &[u8], newest: u64) {
        let slots: Vec<(usize, FeedbackSlot)> = if self.lumped_only {
            let l = LumpedRepr::<LumpedOnlySlot>::parse(bytes)
                .unwrap_or_else(|e| panic!("the master took a lumped frame that fails: {e}"));
            let first = usize::from(l.first_slot);
            l.slots
                .iter()
                .enumerate()
                .map(|(k, s)| (first + k, s.feedback))
                .collect()
        } else {
            let l = LumpedRepr::<FeedbackSlot>::parse(bytes)
                .unwrap_or_else(|e| panic!("the master took a lumped frame that fails: {e}"));
            let first = usize::from(l.first_slot);
            l.slots
                .iter()
                .enumerate()
                .map(|(k, s)| (first + k, *s))
                .collect()
        };
        for (i, s) in slots {
            if i >= N || !s.written || s.sample_time_ns > newest {
                continue;
            }
            if self.lumped_only {
                self.fed[i] = true;
            } else if self.latest[i].is_none_or(|l| s.sample_time_ns > l) {
                self.latest[i] = Some(s.sample_time_ns);
                self.fed[i] = true;
            }
        }
    }

    /// What a call gave; `ended`: it ended a cycle.
    fn drain(&mut self, t: i64, before: &MasterCounters, ended: bool) {
        check_counters(before, &self.m.counters());
        // Events first: those of a law run come before the commands it sends.
        let mut events = Vec::new();
        while let Some(ev) = self.m.poll_event() {
            events.push(ev);
        }
        let computed = events
            .iter()
            .any(|e| matches!(e, MasterEvent::Computed { .. }));
        if computed && !self.lumped_only {
            self.law_ran();
        }
        for ev in events {
            self.event(t, ev);
        }
        if computed && !self.lumped_only || ended && self.lumped_only {
            // The watchdogs: a blind axis stops the group.
            for i in 0..N {
                if self.since_fresh[i] >= self.w {
                    assert!(
                        self.stopped.is_some(),
                        "axis {} without a new sample for {} law runs, no stop",
                        i + 1,
                        self.since_fresh[i]
                    );
                }
            }
            if computed && !self.lumped_only {
                let r = self.m.record();
                for i in 0..N {
                    if self.since_fresh[i] >= self.w || self.orders[i].is_some() {
                        assert_eq!(r.u[i], 0.0, "axis {} blind or ordered: {r:?}", i + 1);
                    }
                }
            }
        }
        if let Some(at) = self.stopped
            && computed
            && !self.lumped_only
            && t >= at + STOP_TIMEOUT + 1_000
        {
            assert!(
                self.orders.iter().all(|o| *o == Some(StopOrder::TorqueOff)),
                "the stop timed out, orders {:?}",
                self.orders
            );
        }
        for i in 0..N {
            assert_eq!(self.m.order(i), self.orders[i], "axis {}'s order", i + 1);
        }
        while let Some(tx) = self.m.poll_transmit() {
            self.transmit(t, &tx);
            self.sent.push(tx);
        }
        assert!(
            self.stopped.is_none() || self.m.is_stopping(),
            "the group stop ended"
        );
        assert_eq!(
            self.stopped.is_some(),
            self.m.is_stopping(),
            "a stop unseen"
        );
    }

    fn event(&mut self, t: i64, ev: MasterEvent) {
        if forge::tracing() && !matches!(ev, MasterEvent::Computed { .. }) {
            eprintln!("  {t} ns: {ev:?}");
        }
        match ev {
            MasterEvent::Computed { k } => {
                assert!(
                    self.last_k.is_none_or(|l| k > l),
                    "cycle {k} computed again"
                );
                self.last_k = Some(k);
                let r = self.m.record();
                assert_eq!(r.k, k, "the record is not cycle {k}'s");
                let newest = (t.saturating_add(self.tolerance)) as f64 * 1e-9;
                for i in 0..N {
                    let u = r.u[i];
                    assert!(u.is_finite(), "record {r:?}");
                    if !self.lumped_only {
                        assert!(u.abs() <= U_MAX, "record {r:?}");
                    }
                    if !self.lumped_only || r.fresh[i] {
                        assert!(
                            r.sample_time[i] <= newest * (1.0 + 1e-12),
                            "axis {}: a sample from the future in {r:?} at {t} ns",
                            i + 1
                        );
                    }
                }
                // A mismatch counted since the last law run stops the group at this one.
                assert!(
                    self.mismatches.is_empty() || self.stopped.is_some(),
                    "mismatches {:?} counted, cycle {k} computed without a group stop",
                    self.mismatches
                );
                self.mismatches.clear();
            }
            MasterEvent::GroupStop { at, reason } => {
                assert!(self.stopped.is_none(), "a second group stop: {ev:?}");
                assert_eq!(at.as_ns(), t, "{ev:?}");
                self.stopped = Some(t);
                match reason {
                    StopReason::NoFeedback { axis } => assert!(
                        self.since_fresh[axis] >= self.w,
                        "{ev:?} after {} law runs without a sample",
                        self.since_fresh[axis]
                    ),
                    StopReason::NoResponse { axis } => assert!(
                        self.missed[axis] >= self.w,
                        "{ev:?} after {} cycles without a response",
                        self.missed[axis]
                    ),
                    StopReason::CommandMismatch {
                        axis,
                        sent,
                        applied,
                    } => assert!(
                        self.mismatches
                            .contains(&(axis, sent.to_bits(), applied.to_bits())),
                        "{ev:?}, mismatches seen {:?}",
                        self.mismatches
                    ),
                    _ => {}
                }
                assert!(reason.axis() < N, "{ev:?}");
            }
            // Every frame is handed over as arriving on port B: the ring never looks broken.
            MasterEvent::Ring { .. } => panic!("{ev:?}: frames on port B alone broke the ring"),
            MasterEvent::Monitor { .. } => {}
            MasterEvent::Order {
                at,
                axis,
                order,
                why,
            } => {
                let Some(stop) = self.stopped else {
                    panic!("{ev:?} before any stop");
                };
                assert_eq!(at.as_ns(), t, "{ev:?}");
                assert!(axis < N, "{ev:?}");
                let had = self.orders[axis];
                match order {
                    StopOrder::Brake => {
                        assert_eq!(had, None, "{ev:?} after {had:?}");
                        match why {
                            OffReason::NoFeedback => assert!(
                                !self.lumped_only
                                    && (self.since_fresh[axis] >= self.w
                                        || self.latest[axis].is_none()),
                                "{ev:?} with feedback"
                            ),
                            OffReason::LumpedOnly => {
                                assert!(self.lumped_only && t == stop, "{ev:?}")
                            }
                            _ => panic!("{ev:?}: a brake for that reason"),
                        }
                    }
                    StopOrder::TorqueOff => {
                        assert!(!self.lumped_only, "{ev:?} on the lumped-only plan");
                        assert_ne!(had, Some(StopOrder::TorqueOff), "{ev:?} twice");
                        match why {
                            OffReason::StopTimeout => {
                                assert!(t >= stop + STOP_TIMEOUT - 1_000, "{ev:?}")
                            }
                            OffReason::StopComplete => assert!(
                                had.is_none() && t >= stop + STOP_HOLD - 1_000,
                                "{ev:?} after {had:?}"
                            ),
                            OffReason::FollowingError { error } => assert!(
                                had.is_none() && error.abs() > FE_LIMIT,
                                "{ev:?} after {had:?}"
                            ),
                            _ => panic!("{ev:?}: torque off for that reason"),
                        }
                    }
                }
                self.orders[axis] = Some(order);
            }
        }
    }

    fn transmit(&mut self, t: i64, tx: &Transmit) {
        assert_eq!(
            tx.at.as_ns(),
            t,
            "a frame sent at another time than the call's"
        );
        assert!(tx.at.as_ns() >= self.last_tx, "frames sent out of order");
        self.last_tx = tx.at.as_ns();
        let pdu = Pdu::parse(&tx.bytes)
            .unwrap_or_else(|e| panic!("the master sent a frame that does not parse: {e:?}"));
        match pdu {
            Pdu::Lumped(l) => {
                assert!(!self.lumped_only, "a kind-1 frame on the lumped-only plan");
                assert_eq!(l.common.flags, Flags::empty(), "lumped frame {l:?}");
                self.lumped(l.common.cycle, l.master_time_ns, t, &tx.bytes);
            }
            Pdu::LumpedOnly(l) => {
                assert!(self.lumped_only, "a kind-4 frame on the proposed plan");
                let flags = if self.stopped.is_some() {
                    Flags::STOP.with(Flags::BRAKE)
                } else {
                    Flags::empty()
                };
                assert_eq!(l.common.flags, flags, "lumped-only frame {:?}", l.common);
                self.lumped(l.common.cycle, l.master_time_ns, t, &tx.bytes);
            }
            Pdu::Command(c) => self.command(&c),
            Pdu::Response(r) => panic!("the master sent a response: {r:?}"),
            // Delay frames belong to the start-up phase (`node::calibrate`), which this
            // target's master, running from its first cycle, does not have.
            Pdu::Delay(d) => panic!("the master sent a delay frame: {:?}", d.common),
        }
    }

    fn command(&mut self, c: &CommandRepr) {
        assert!(!self.lumped_only, "a command on the lumped-only plan");
        let v = f64::from(c.command_v);
        assert!(v.is_finite() && v.abs() <= U_MAX, "command {c:?}");
        assert!((1..=N as u16).contains(&c.target), "command {c:?}");
        assert_eq!(Some(c.common.cycle), self.cycle, "command {c:?}");
        assert!(c.common.retry <= 1, "command {c:?}");
        let axis = usize::from(c.target) - 1;
        let f = c.common.flags;
        let order = self.orders[axis];
        assert_eq!(f.contains(Flags::STOP), self.stopped.is_some(), "{c:?}");
        assert_eq!(
            f.contains(Flags::TORQUE_OFF),
            order == Some(StopOrder::TorqueOff),
            "{c:?} with order {order:?}"
        );
        assert_eq!(
            f.contains(Flags::BRAKE),
            order == Some(StopOrder::Brake),
            "{c:?} with order {order:?}"
        );
        if order.is_some() || self.since_fresh[axis] >= self.w {
            assert_eq!(c.command_v, 0.0, "{c:?} to an axis blind or ordered");
        }
        self.open = Some(Sent {
            axis,
            cycle: c.common.cycle,
            retry: c.common.retry,
            value: c.command_v,
        });
    }

    fn lumped(&mut self, cycle: u32, stamp: u64, t: i64, bytes: &[u8]) {
        assert_eq!(
            stamp,
            t.max(0) as u64,
            "lumped frame stamped {stamp}, sent at {t}"
        );
        if let Some(c) = self.cycle {
            let d = cycle.wrapping_sub(c);
            assert!(d <= 1, "lumped frame of cycle {cycle} after cycle {c}");
        }
        self.cycle = Some(cycle);
        self.last_lumped = Some(bytes.to_vec());
    }

    fn build(&self, f: &MFrame) -> Vec<u8> {
        let now = self.now;
        let k = i64::from(self.cycle.unwrap_or(0));
        match f {
            MFrame::Returned {
                slots,
                cycle,
                seq,
                stamp,
                first,
                count,
            } => {
                let base = self.last_lumped.as_deref().unwrap_or(&[]);
                let field = |at: usize, n: usize| -> u64 {
                    base.get(at..at + n).map_or(0, |b| {
                        b.iter()
                            .rev()
                            .fold(0u64, |acc, &x| (acc << 8) | u64::from(x))
                    })
                };
                let kind = if self.lumped_only { 4 } else { 1 };
                let len = if self.lumped_only { 32 } else { 20 };
                let n = count.map_or(field(22, 2) as usize, |c| usize::from(c % 16));
                let mut data = Vec::with_capacity(n * len);
                for i in 0..n {
                    match slots.get(i) {
                        Some(s) => s.put(now, len, &mut data),
                        None => data.resize(data.len() + len, 0),
                    }
                }
                forge::lumped(
                    kind,
                    field(2, 1) as u8,
                    0,
                    cycle.map_or(field(4, 4) as u32, |c| c.resolve(k)),
                    seq.unwrap_or(field(8, 2) as u16),
                    stamp.map_or(field(12, 8), |s| s.resolve(now)),
                    first.unwrap_or(field(20, 2) as u16),
                    n as u16,
                    &data,
                )
            }
            MFrame::Response { head, resp } => forge::response(head, resp, k, now),
            MFrame::Command {
                head,
                target,
                value,
                sample,
            } => forge::command(
                head,
                k,
                forge::address(*target),
                *value,
                sample.resolve(now),
            ),
            MFrame::Sealed(raw) => seal::sealed(raw).unwrap_or_else(|| raw.clone()),
            MFrame::Raw(raw) => raw.clone(),
        }
    }

    /// Answers what the master sent as a perfect ring would, for `cycles` cycles.
    fn ring(&mut self, cycles: u8, error: i32, quirk: u8) {
        let axis = usize::from(quirk >> 4) % N;
        let start = self.cycle.unwrap_or(0);
        self.sent.clear();
        for _ in 0..512 {
            let done = self.cycle.unwrap_or(0).wrapping_sub(start);
            if done > u32::from(cycles % 64) || self.now > TOTAL {
                break;
            }
            // The answers to what went out, in time order, each before the next deadline.
            let sent = std::mem::take(&mut self.sent);
            let mut answers: Vec<(i64, Vec<u8>)> = sent
                .iter()
                .filter_map(|tx| self.answer(tx, error, quirk, axis))
                .collect();
            answers.sort_by_key(|a| a.0);
            if answers.is_empty() {
                self.timeout(0);
            }
            for (at, b) in answers {
                self.frame(at, &b);
            }
        }
    }

    fn answer(&self, tx: &Transmit, error: i32, quirk: u8, axis: usize) -> Option<(i64, Vec<u8>)> {
        let t = tx.at.as_ns();
        match Pdu::parse(&tx.bytes).ok()? {
            Pdu::Lumped(l) if quirk & 1 == 0 => {
                let mut data = Vec::new();
                for k in 0..l.slots.len() {
                    self.slot(usize::from(l.first_slot) + k, t, error, quirk, axis)
                        .put(0, 20, &mut data);
                }
                Some((
                    t + 20_000,
                    self.relumped(1, &l.common, t, l.first_slot, &data),
                ))
            }
            Pdu::LumpedOnly(l) if quirk & 1 == 0 => {
                let mut data = Vec::new();
                for k in 0..l.slots.len() {
                    self.slot(usize::from(l.first_slot) + k, t, error, quirk, axis)
                        .put(0, 32, &mut data);
                }
                Some((
                    t + 30_000,
                    self.relumped(4, &l.common, t, l.first_slot, &data),
                ))
            }
            Pdu::Command(c) => {
                let i = usize::from(c.target) - 1;
                if quirk & 2 != 0 && i == axis {
                    return None;
                }
                let mut status = 0;
                let mut applied = c.command_v;
                if i == axis {
                    if quirk & 4 != 0 {
                        status |= Status::FAULT.bits();
                    }
                    if quirk & 64 != 0 {
                        applied += 1.0;
                    }
                    if quirk & 128 != 0 {
                        status |= Status::BRAKING.bits();
                    }
                }
                let head = Head {
                    cycle: CycleSel::Raw(c.common.cycle),
                    retry: c.common.retry,
                    flags: 0,
                    seq: 0,
                };
                let resp = Resp {
                    source: c.target as u8,
                    status,
                    echo: CycleSel::Raw(c.common.cycle),
                    position: 0,
                    velocity: 0,
                    sample: When::Raw(c.sample_time_ns),
                    applied,
                };
                let hops = (N - i) as i64 * 1_000;
                Some((t + 8_000 + hops, forge::response(&head, &resp, 0, 0)))
            }
            _ => None,
        }
    }

    fn relumped(
        &self,
        kind: u8,
        c: &ringsync_wire::Common,
        t: i64,
        first: u16,
        data: &[u8],
    ) -> Vec<u8> {
        let n = (data.len() / if kind == 4 { 32 } else { 20 }) as u16;
        forge::lumped(
            kind,
            c.flags.bits(),
            0,
            c.cycle,
            c.seq,
            t as u64,
            first,
            n,
            data,
        )
    }

    /// Axis i's slot, sampled at the cycle start `t` (quirk bit 3: 1 µs later).
    fn slot(&self, i: usize, t: i64, error: i32, quirk: u8, axis: usize) -> Slot {
        let res = self.m.config().resolution.get(i).copied().unwrap_or(1.0);
        let ts = if quirk & 8 != 0 { t + 1_000 } else { t };
        let d = self.m.desired(i.min(N - 1), ts as f64 * 1e-9);
        let counts = |x: f64| (x / res).round().clamp(-2e9, 2e9) as i32;
        Slot {
            position: counts(d.x).saturating_add(if i == axis { error } else { 0 }),
            velocity: counts(d.v),
            sample: When::Raw(ts.max(0) as u64),
            status: if quirk & 4 != 0 && i == axis { 1 } else { 0 },
            written: 1,
            command: 0.0,
        }
    }
}

fn check_counters(b: &MasterCounters, a: &MasterCounters) {
    assert!(
        a.frames_sent >= b.frames_sent
            && a.lumped_lost >= b.lumped_lost
            && a.samples_missing >= b.samples_missing
            && a.samples_stale >= b.samples_stale
            && a.slices_failed >= b.slices_failed
            && a.retries >= b.retries
            && a.retries_ok >= b.retries_ok
            && a.commands_lost >= b.commands_lost
            && a.command_mismatches >= b.command_mismatches
            && a.rejected
                .iter()
                .zip(b.rejected.iter())
                .all(|(x, y)| x.1 >= y.1),
        "counters went back: {b:?} -> {a:?}"
    );
}

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let Ok(setup) = Setup::arbitrary(&mut u) else {
        return;
    };
    if forge::tracing() {
        eprintln!("{setup:?}");
    }
    let mut h = Harness::new(&setup);
    while !u.is_empty() && h.now < TOTAL {
        let Ok(op) = Op::arbitrary(&mut u) else {
            break;
        };
        if forge::tracing() {
            eprintln!("{op:?}");
        }
        match op {
            Op::Timeout { late } => {
                let late = match late {
                    Late::OnTime => 0,
                    Late::By(ns) => i64::from(ns % MAX_LATE),
                };
                h.timeout(late);
            }
            Op::Frame { after_ns, frame } => {
                let b = h.build(&frame);
                h.frame(h.now + i64::from(after_ns % 1_200_000), &b);
            }
            Op::Ring {
                cycles,
                error,
                quirk,
            } => h.ring(cycles, error, quirk),
        }
    }
    if forge::tracing() {
        eprintln!(
            "at {} ns: {:?}, stopping {}",
            h.now,
            h.m.counters(),
            h.m.is_stopping()
        );
    }
});
