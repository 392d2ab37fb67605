//! One [`Slave`] alone (address 1-4, its clock any fixed offset from the master's, brake or
//! torque-off safe state, P2P start 0 or the plan's, the proposed plan or the lumped-only
//! plan with its own law, `ringsync-model`'s `SlaveControl` running PD), fed an arbitrary interleaving of encoder latches (`handle_sample`,
//! at any time or when `poll_timeout` asks, any count) and frames (`handle_frame`): forged
//! lumped frames of both kinds, commands and responses with any field (times and cycles
//! mostly near the master's, or at the time line's horizon), sealed and unsealed raw bytes,
//! and the frames of a normal cycle, with the master's orders (STOP, BRAKE, TORQUE_OFF) if
//! the fuzzer asks, so that the fuzzer reaches a locked clock, applied commands, retries,
//! the watchdog, the brake and re-locks. Time never goes backwards.
//!
//! # Invariants
//! - No panic.
//! - Events: `Apply` and `Brake` are finite and within ±u_max. `Apply` comes only from a
//!   frame, and never after `TorqueOff`, `WatchdogExpired` or `Braking`. `Braking` at most
//!   once, never after `TorqueOff`: from a frame when ordered (`BRAKE`), from a latch whose
//!   watchdog just expired when not. `Brake` only from a latch, only while braking.
//!   `TorqueOff` at most once: `Commanded` from a frame, the others from a latch (`Watchdog`
//!   right after the watchdog expired with the torque-off safe state, `Standstill` and
//!   `BrakeTimeout` while braking). `WatchdogExpired` at most once, from a latch.
//!   `Relocked` only from a frame.
//! - The status agrees with the events: TORQUE_OFF iff torque went off (and
//!   `Slave::torque_off`), BRAKING iff braking and not off, FAULT and WATCHDOG iff the
//!   watchdog expired, CLOCK_UNLOCKED iff the clock is not locked (a lock needs two syncs).
//!   The clock's rate stays within `MAX_RATE_ERROR` of 1. The last lumped cycle taken lies
//!   on the wire's time line (at most `HORIZON`/T).
//! - At most one `Apply` per cycle and the applied cycles increase, command frames and
//!   lumped-only frames alike, until a `Relocked` event or an acquisition restart (a new
//!   master time line: its cycles are new). A lumped-only slave refuses every command frame (`UnexpectedKind`)
//!   and sends nothing.
//! - A command taken as new (answered, not a repeat): TORQUE_OFF in it shows in the status
//!   at once, BRAKE as BRAKING or TORQUE_OFF, STOP as STOPPING; without those, a drive that
//!   follows commands applies exactly the command clipped to ±u_max, and one that does not
//!   applies nothing. A lumped-only frame taken with BRAKE: BRAKING or TORQUE_OFF.
//! - Each response the slave sends answers the command just taken: it parses, comes from
//!   the slave's address, echoes the command's cycle and retry, carries the slave's status
//!   and its command now (finite, within ±u_max), and leaves `response_delay` after the
//!   command's last bit. Nothing else is sent.
//! - A frame the slave does not take (no sync, re-lock, command, retry or delay frame
//!   counted, not consumed) changes nothing observable: no event, no transmission, the same status,
//!   command, `poll_timeout`, latch count and last lumped cycle, and a forwarded frame
//!   leaves byte for byte as it came. A dropped frame is counted once in `rejected`. A taken
//!   lumped frame leaves with a valid CRC. A frame whose timestamp (lumped stamp, command
//!   sampling instant) lies past `Instant::HORIZON` is never taken.
//! - `poll_timeout` (local time of the next latch): a latch never moves it backwards. Frames
//!   move it only by moving the clock (a taken sync steps the clock within the window, an
//!   acquisition restart or a re-lock by anything, and the sampling instant is put back on
//!   the new time line). What holds across all of them: `to_sync(poll_timeout())` is the
//!   next latch instant k·T − lead (− the velocity window) on the synchronised grid, within
//!   the round trip's rounding.
//! - Counters never decrease.
//! - Liveness: in the nominal cycles, a locked slave takes a lumped frame newer than its
//!   last that reaches it within its clock window, and a command of the cycle in progress by
//!   its clock (inside [c·T + p2p_start − w, (c + 1)·T + w]) newer than the last it took on
//!   the current time line: a re-lock or an acquisition restart forgets the last command
//!   (F4, fixed in 02bbcce: a restart used to keep the abandoned line's, and the slave
//!   refused the new line's commands as stale until its cycles passed that one).
#![no_main]

use std::collections::HashSet;

use libfuzzer_sys::arbitrary::{self, Arbitrary, Unstructured};
use libfuzzer_sys::fuzz_target;
use ringsync_control::{AxisTrajectory, Cosine, Gains, Pd, VelocitySource};
use ringsync_model::motion::SlaveControl;
use ringsync_proto::node::clock::MAX_RATE_ERROR;
use ringsync_proto::node::{
    FrameOutcome, Reject, SafeState, Slave, SlaveConfig, SlaveCounters, SlaveEvent, TorqueOffCause,
};
use ringsync_proto::{CyclePlan, Duration, Instant, RingParams};
use ringsync_wire::{CommandRepr, Flags, Frame, ResponseRepr, Status};

#[path = "forge.rs"]
mod forge;
#[path = "seal.rs"]
mod seal;

use forge::{CYCLE_NS as T, Head, Resp, Slot, When};

/// Axes on the ring (the lumped-only law's size).
const N: usize = 4;
/// Largest gap between two inputs [ns].
const MAX_GAP: u32 = 2_000_000;

#[derive(Arbitrary, Debug)]
struct Setup {
    address: u8,
    /// Slave clock minus master clock [ns].
    offset_ns: i32,
    torque_off: bool,
    lumped_only: bool,
    /// Commands from the plan's P2P start on (else from the cycle start on).
    p2p: bool,
}

#[derive(Arbitrary, Debug)]
enum Op {
    /// An encoder latch `after_ns` (mod 2 ms) after the last input.
    Sample { after_ns: u32, counts: Counts },
    /// An encoder latch when the slave asked for it (or `late_ns` after, or now if that has
    /// passed).
    Latch { late_ns: u16, counts: Counts },
    /// A frame whose first bit arrives `after_ns` (mod 2 ms) after the last input and whose
    /// last bit `dur_ns` after that.
    Frame {
        after_ns: u32,
        dur_ns: u16,
        frame: SFrame,
    },
    /// The next `1 + repeat % 16` cycles as a real master sends them (latches as asked in
    /// between): the lumped frame on time (`late_ns` late), then the command with `value`
    /// in the P2P phase. Bits of `skip`: 0 leaves out the lumped frame, 1 the command, 2 the
    /// latches; 3 adds a retry of the command, 4 a copy of the lumped frame, 5 a copy of the
    /// command; 6 makes it an order to brake (STOP and BRAKE on the command, or on the
    /// lumped-only frame), 7 to cut torque (STOP and TORQUE_OFF on the command).
    Nominal {
        value: f32,
        skip: u8,
        late_ns: u16,
        repeat: u8,
    },
    /// The master's time line steps by `us` µs (a master that restarted, or whose time base
    /// was set): the frames of `Nominal` follow it.
    Step { us: i32 },
}

#[derive(Arbitrary, Debug, Clone, Copy)]
enum Counts {
    Delta(i16),
    Raw(i64),
}

#[derive(Arbitrary, Debug)]
enum SFrame {
    /// A lumped frame of kind 1 (or 4); stamp relative to master time now.
    Lumped {
        head: Head,
        kind4: bool,
        stamp: When,
        first: u16,
        count: Option<u8>,
        slots: Vec<Slot>,
    },
    Command {
        head: Head,
        target: u8,
        value: f32,
        sample: When,
    },
    Response {
        head: Head,
        resp: Resp,
    },
    Sealed(Vec<u8>),
    Raw(Vec<u8>),
}

/// What the driver can see of the slave.
#[derive(Clone, Copy, PartialEq, Debug)]
struct Seen {
    counters: SlaveCounters,
    status: Status,
    command: f64,
    pt: Instant,
    samples: i64,
    torque_off: bool,
    last_lumped: Option<i64>,
}

/// What a call gave: from a latch or from a frame.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Source {
    Latch,
    Frame,
}

struct Harness {
    s: Slave,
    address: u16,
    offset: i64,
    u_max: f64,
    safe_state: SafeState,
    p2p_start: i64,
    now: i64,
    counts: i64,
    /// The next latch is the window's start (else the sampling instant).
    window_next: bool,
    /// Cycles applied on this master time line, and the last one (command frames and
    /// lumped-only frames share one history).
    applied: HashSet<u32>,
    last_applied: Option<u32>,
    /// The cycle of the last command taken (answered) on this time line.
    last_taken: Option<u32>,
    torque_off: bool,
    braking: bool,
    watchdog: bool,
    lumped_kind: u8,
}

impl Harness {
    fn new(setup: &Setup) -> Self {
        let address = 1 + u16::from(setup.address % N as u8);
        let mut cfg = SlaveConfig::new(
            address,
            Duration::from_ns(T),
            Duration::from_us(i64::from(address)),
        );
        if setup.torque_off {
            cfg.safe_state = SafeState::TorqueOff;
        }
        if setup.p2p {
            cfg.p2p_start = plan_p2p_start();
        }
        let u_max = cfg.u_max;
        let safe_state = cfg.safe_state;
        let p2p_start = cfg.p2p_start.as_ns();
        let s = if setup.lumped_only {
            let law = Pd::new(Gains::uniform(N, 3.182, 1.591, 0.0), false)
                .unwrap_or_else(|e| panic!("law: {e}"));
            let traj =
                Cosine::with_peak_speed(15.12, 2.0).unwrap_or_else(|e| panic!("trajectory: {e}"));
            let control = SlaveControl::new(
                Box::new(law),
                VelocitySource::Reported,
                vec![AxisTrajectory::Cosine(traj); N],
                vec![cfg.resolution; N],
                cfg.cycle,
            );
            Slave::with_law(cfg, Box::new(control))
        } else {
            Slave::new(cfg)
        };
        Harness {
            s,
            address,
            offset: i64::from(setup.offset_ns),
            u_max,
            safe_state,
            p2p_start,
            now: 0,
            counts: 0,
            window_next: true,
            applied: HashSet::new(),
            last_applied: None,
            last_taken: None,
            torque_off: false,
            braking: false,
            watchdog: false,
            lumped_kind: if setup.lumped_only { 4 } else { 1 },
        }
    }

    fn seen(&self) -> Seen {
        Seen {
            counters: self.s.counters(),
            status: self.s.status(),
            command: self.s.command(),
            pt: self.s.poll_timeout(),
            samples: self.s.samples_taken(),
            torque_off: self.s.torque_off(),
            last_lumped: self.s.last_lumped_cycle(),
        }
    }

    /// Master time now (the slave's clock runs `offset` ahead of it) [ns].
    fn master_now(&self) -> i64 {
        self.now.saturating_sub(self.offset)
    }

    /// The next encoder count: any i64.
    fn counts(&mut self, c: Counts) -> i64 {
        self.counts = match c {
            Counts::Delta(d) => self.counts.saturating_add(i64::from(d)),
            Counts::Raw(v) => v,
        };
        self.counts
    }

    fn sample(&mut self, at: i64, counts: i64) {
        self.now = self.now.max(at);
        let before = self.seen();
        self.s.handle_sample(Instant::from_ns(self.now), counts);
        self.window_next = !self.window_next;
        let after = self.seen();
        assert!(
            after.pt >= before.pt,
            "a latch moved poll_timeout back: {:?} -> {:?}",
            before.pt,
            after.pt
        );
        check_counters(&before.counters, &after.counters);
        assert!(self.s.poll_transmit().is_none(), "a latch sent a frame");
        let mut expired = false;
        while let Some(ev) = self.s.poll_event() {
            self.event(ev, Source::Latch, expired);
            expired |= ev == SlaveEvent::WatchdogExpired;
        }
        if expired {
            // The safe state follows the watchdog at once, unless the drive is off already
            // (or was braking by order).
            match self.safe_state {
                SafeState::TorqueOff => assert!(self.torque_off, "the watchdog left torque on"),
                SafeState::Brake => assert!(
                    self.braking || self.torque_off,
                    "the watchdog expired and the drive neither brakes nor is off"
                ),
            }
        }
        self.check_state();
        self.check_grid();
    }

    /// Latches as asked up to `until` (at most 8).
    fn latch_until(&mut self, until: i64) {
        for _ in 0..8 {
            let pt = self.s.poll_timeout().as_ns();
            if pt > until {
                break;
            }
            self.sample(pt, self.counts);
        }
    }

    /// One event, from a latch or a frame; `expired`: the watchdog expired earlier in the
    /// same call.
    fn event(&mut self, ev: SlaveEvent, from: Source, expired: bool) {
        if forge::tracing() && !matches!(ev, SlaveEvent::Apply { .. } | SlaveEvent::Brake { .. }) {
            eprintln!("  {} ns: {ev:?}", self.now);
        }
        match ev {
            SlaveEvent::Apply { u } => {
                assert!(u.is_finite() && u.abs() <= self.u_max, "{ev:?}");
                assert_eq!(from, Source::Frame, "{ev:?} from a latch");
                assert!(!self.torque_off, "{ev:?} after torque off");
                assert!(!self.braking, "{ev:?} while braking");
                assert!(!self.watchdog, "{ev:?} after the watchdog expired");
            }
            SlaveEvent::Brake { u } => {
                assert!(u.is_finite() && u.abs() <= self.u_max, "{ev:?}");
                assert_eq!(from, Source::Latch, "{ev:?} from a frame");
                assert!(self.braking && !self.torque_off, "{ev:?} while not braking");
            }
            SlaveEvent::Braking { ordered } => {
                assert!(!self.braking, "braking twice");
                assert!(!self.torque_off, "braking after torque off");
                if ordered {
                    assert_eq!(from, Source::Frame, "{ev:?} from a latch");
                } else {
                    assert!(
                        from == Source::Latch && expired && self.safe_state == SafeState::Brake,
                        "{ev:?} without the watchdog"
                    );
                }
                self.braking = true;
            }
            SlaveEvent::TorqueOff { cause } => {
                assert!(!self.torque_off, "torque off twice");
                match cause {
                    TorqueOffCause::Commanded => assert_eq!(from, Source::Frame, "{ev:?}"),
                    TorqueOffCause::Watchdog => assert!(
                        from == Source::Latch && expired && self.safe_state == SafeState::TorqueOff,
                        "{ev:?}"
                    ),
                    TorqueOffCause::Standstill | TorqueOffCause::BrakeTimeout => {
                        assert!(from == Source::Latch && self.braking, "{ev:?}")
                    }
                }
                self.torque_off = true;
                self.braking = false;
            }
            SlaveEvent::WatchdogExpired => {
                assert_eq!(from, Source::Latch, "{ev:?} from a frame");
                assert!(!self.watchdog, "the watchdog expired twice");
                self.watchdog = true;
            }
            SlaveEvent::Relocked { .. } => {
                assert_eq!(from, Source::Frame, "{ev:?} from a latch");
                self.applied.clear();
                self.last_applied = None;
                self.last_taken = None;
            }
            // The slave starts running (`Slave::new`): no delay frame, forged or not, ends a
            // start-up phase it never had.
            SlaveEvent::Calibrated { .. } => panic!("{ev:?} without a start-up phase"),
        }
    }

    /// The status and the clock agree with what the events said.
    fn check_state(&self) {
        let st = self.s.status();
        let has = |b: Status| st.contains(b);
        assert_eq!(has(Status::TORQUE_OFF), self.torque_off, "status {st:?}");
        assert_eq!(self.s.torque_off(), self.torque_off, "status {st:?}");
        assert_eq!(
            has(Status::BRAKING),
            self.braking && !self.torque_off,
            "status {st:?}"
        );
        assert_eq!(has(Status::FAULT), self.watchdog, "status {st:?}");
        assert_eq!(has(Status::WATCHDOG), self.watchdog, "status {st:?}");
        let clock = self.s.clock();
        assert_eq!(
            has(Status::CLOCK_UNLOCKED),
            !clock.is_locked(),
            "status {st:?}"
        );
        assert!(
            !clock.is_locked() || self.s.counters().syncs >= 2,
            "locked after {} syncs",
            self.s.counters().syncs
        );
        let rate = clock.rate();
        assert!(
            (rate - 1.0).abs() <= MAX_RATE_ERROR * (1.0 + 1e-9),
            "clock rate {rate}"
        );
        if let Some(c) = self.s.last_lumped_cycle() {
            assert!(
                (-1..=forge::HORIZON_NS / T).contains(&c),
                "last lumped cycle {c}"
            );
        }
    }

    /// `to_sync(poll_timeout())` is the next latch instant on the synchronised grid.
    fn check_grid(&self) {
        let cfg = self.s.config();
        let k = self.s.samples_taken();
        let mut target = k.saturating_mul(cfg.cycle.as_ns()) - cfg.sample_lead.as_ns();
        if self.window_next {
            target -= cfg.velocity_window.as_ns();
        }
        let clock = self.s.clock();
        let rate = clock.rate();
        let pt = self.s.poll_timeout();
        let sane = |v: i64| v.unsigned_abs() < 1 << 50;
        // Away from the ends of the time line, where the f64 lever arm loses nanoseconds.
        let s_now = clock.to_sync(Instant::from_ns(self.now)).as_ns();
        if (0.5..=2.0).contains(&rate)
            && sane(target)
            && sane(pt.as_ns())
            && sane(s_now.saturating_sub(target))
        {
            let back = clock.to_sync(pt).as_ns();
            assert!(
                (back - target).abs() <= 3,
                "poll_timeout {pt:?} reads {back} on the synchronised clock, the latch is at \
                 {target} (rate {rate})"
            );
        }
    }

    fn frame(&mut self, at: i64, dur: i64, mut bytes: Vec<u8>) {
        self.now = self.now.max(at);
        let rx_start = self.now;
        let rx_end = self.now.saturating_add(dur);
        let input = bytes.clone();
        let cmd = CommandRepr::parse(&input).ok();
        let header = Frame::new_checked(&input[..]).ok();
        let cycle = header.as_ref().map(|f| f.cycle());
        let sound = header.as_ref().is_some_and(|f| f.check().is_ok());
        let flags = header.as_ref().map_or(Flags::empty(), |f| {
            Flags::from_bits(f.flags_byte()).unwrap_or_default()
        });
        let before = self.seen();
        // The drive follows commands (no fault, no brake, torque on).
        let enabled = !self.watchdog && !self.braking && !self.torque_off;
        let outcome = self.s.handle_frame(
            Instant::from_ns(rx_start),
            Instant::from_ns(rx_end),
            &mut bytes,
        );
        self.now = rx_end;
        let after = self.seen();
        let (b, a) = (&before.counters, &after.counters);
        check_counters(b, a);
        let took = a.syncs != b.syncs
            || a.relocks != b.relocks
            || a.commands != b.commands
            || a.duplicates != b.duplicates
            || a.delay_frames != b.delay_frames
            || outcome == FrameOutcome::Consumed;
        let mut tx = Vec::new();
        while let Some(t) = self.s.poll_transmit() {
            tx.push(t);
        }
        let mut events = Vec::new();
        while let Some(ev) = self.s.poll_event() {
            events.push(ev);
        }
        if forge::wire_time(&input).is_some_and(forge::past_horizon)
            && matches!(input.get(1), Some(1 | 2 | 4))
        {
            assert!(
                !took,
                "a frame stamped past the horizon was taken ({outcome:?}, {a:?})"
            );
        }
        if !took {
            assert!(
                events.is_empty() && tx.is_empty(),
                "a frame not taken gave {events:?}, sent {tx:?}"
            );
            let (mut b2, mut a2) = (before, after);
            b2.counters = SlaveCounters::default();
            a2.counters = SlaveCounters::default();
            assert_eq!(b2, a2, "a frame not taken changed the slave");
            if outcome == FrameOutcome::Forward {
                assert_eq!(bytes, input, "a frame not taken was forwarded changed");
            }
        }
        if outcome == FrameOutcome::Dropped {
            assert_eq!(
                a.rejected.total(),
                b.rejected.total() + 1,
                "a dropped frame counted other than once"
            );
        }
        if outcome == FrameOutcome::Forward && bytes != input {
            let f = Frame::new_checked(&bytes[..]).expect("a forwarded frame has a header");
            assert!(
                f.check().is_ok(),
                "a taken lumped frame leaves with a bad CRC"
            );
        }
        // A lumped-only slave takes no command frame (finding F1, fixed).
        if self.lumped_kind == 4 && sound && input.get(1) == Some(&2) {
            assert_eq!(
                outcome,
                FrameOutcome::Dropped,
                "a lumped-only slave: {cmd:?}"
            );
            assert_eq!(
                a.rejected.get(Reject::UnexpectedKind),
                b.rejected.get(Reject::UnexpectedKind) + 1
            );
        }
        // The samples moved to a new time line: the next latch is a window's start.
        if after.samples != before.samples {
            assert!(took, "a frame not taken moved the sampling instant");
            self.window_next = true;
        }
        // Acquisition started afresh from this frame: a new time line, whose cycles are new
        // (as after a re-lock), and the slave forgets the command it took on the abandoned
        // one (F4, fixed in 02bbcce): the liveness check expects the new line's commands to
        // be taken whatever cycle the old line had reached.
        if a.acquisitions_restarted != b.acquisitions_restarted {
            self.applied.clear();
            self.last_applied = None;
            self.last_taken = None;
        }
        let mut applies = Vec::new();
        for &ev in &events {
            if let SlaveEvent::Apply { u } = ev {
                let c = cycle.expect("an Apply from a frame with a header");
                applies.push(u);
                assert!(
                    self.applied.insert(c),
                    "cycle {c} applied twice ({outcome:?}, {cmd:?})"
                );
                let last = self.last_applied;
                assert!(
                    last.is_none_or(|l| c.wrapping_sub(l) as i32 > 0),
                    "cycle {c} applied after cycle {last:?}"
                );
                self.last_applied = Some(c);
            }
            self.event(ev, Source::Frame, false);
        }
        assert!(applies.len() <= 1, "one frame, {} Apply", applies.len());
        let st = after.status;
        // A lumped-only frame taken with BRAKE: the drive brakes (or is off).
        if self.lumped_kind == 4 && a.syncs != b.syncs && flags.contains(Flags::BRAKE) {
            assert!(
                st.contains(Status::BRAKING) || st.contains(Status::TORQUE_OFF),
                "a BRAKE order taken, status {st:?}"
            );
        }
        if !tx.is_empty() {
            let c = cmd.unwrap_or_else(|| panic!("a response to a frame that is no command"));
            self.last_taken = Some(c.common.cycle);
            // Taken as new (not a repeat of the last command): the orders in it are obeyed.
            if a.duplicates == b.duplicates {
                let f = c.common.flags;
                if f.contains(Flags::TORQUE_OFF) {
                    assert!(
                        st.contains(Status::TORQUE_OFF),
                        "{c:?} taken, status {st:?}"
                    );
                }
                if f.contains(Flags::BRAKE) {
                    assert!(
                        st.contains(Status::BRAKING) || st.contains(Status::TORQUE_OFF),
                        "{c:?} taken, status {st:?}"
                    );
                }
                if f.contains(Flags::STOP) {
                    assert!(st.contains(Status::STOPPING), "{c:?} taken, status {st:?}");
                }
                let obeys = !f.contains(Flags::TORQUE_OFF) && !f.contains(Flags::BRAKE);
                if enabled && obeys {
                    let u = forge::clip(f64::from(c.command_v), self.u_max);
                    assert_eq!(applies, [u], "{c:?} taken by a drive that follows commands");
                } else {
                    assert!(applies.is_empty(), "{c:?} applied by a drive that does not");
                }
            } else {
                assert!(applies.is_empty(), "a repeat of {c:?} applied again");
            }
        }
        for t in &tx {
            let c = cmd.unwrap_or_else(|| panic!("a response to a frame that is no command"));
            assert_eq!(self.lumped_kind, 1, "a lumped-only slave answered {c:?}");
            let r = ResponseRepr::parse(&t.bytes).expect("the slave's response parses");
            assert_eq!(r.source, self.address);
            assert_eq!(
                (r.echo_cycle, r.common.cycle),
                (c.common.cycle, c.common.cycle)
            );
            assert_eq!(r.common.retry, c.common.retry);
            assert!(r.applied_v.is_finite() && f64::from(r.applied_v).abs() <= self.u_max);
            assert_eq!(r.applied_v, after.command as f32, "the response's command");
            assert_eq!(r.status, st, "the response's status");
            let delay = self.s.config().response_delay.as_ns();
            assert_eq!(t.at.as_ns(), rx_end.saturating_add(delay), "response time");
        }
        assert!(tx.len() <= 1, "one command, {} responses", tx.len());
        self.check_state();
        self.check_grid();
    }

    /// The frame of `f`, times relative to master time now.
    fn build(&self, f: &SFrame) -> Vec<u8> {
        let m = self.master_now();
        let cycle = m.div_euclid(T);
        match f {
            SFrame::Lumped {
                head,
                kind4,
                stamp,
                first,
                count,
                slots,
            } => {
                let len = if *kind4 { 32 } else { 20 };
                let mut data = Vec::new();
                for s in slots {
                    s.put(m, len, &mut data);
                }
                let first = if first & 0x8000 != 0 {
                    *first
                } else {
                    first % 8
                };
                let count = count.map_or(slots.len() as u16, |c| u16::from(c % 32));
                forge::lumped(
                    if *kind4 { 4 } else { 1 },
                    head.flags,
                    head.retry,
                    head.cycle.resolve(cycle),
                    head.seq,
                    stamp.resolve(m),
                    first,
                    count,
                    &data,
                )
            }
            SFrame::Command {
                head,
                target,
                value,
                sample,
            } => forge::command(
                head,
                cycle,
                forge::address(*target),
                *value,
                sample.resolve(m),
            ),
            SFrame::Response { head, resp } => forge::response(head, resp, cycle, m),
            SFrame::Sealed(raw) => seal::sealed(raw).unwrap_or_else(|| raw.clone()),
            SFrame::Raw(raw) => raw.clone(),
        }
    }

    /// The next cycle as a real master sends it.
    fn nominal(&mut self, value: f32, skip: u8, late: i64) {
        let copy = |b: &Vec<u8>| b.clone();
        let k = (self.master_now().div_euclid(T) + 1).max(0);
        let path = i64::from(self.address) * 1_000;
        let offset = self.offset;
        let local = |m: i64| m.saturating_add(offset);
        let at = local(k * T + path + late);
        let brake = skip & 64 != 0;
        let cut = skip & 128 != 0;
        if skip & 4 == 0 {
            self.latch_until(at);
        }
        if skip & 1 == 0 {
            let len = if self.lumped_kind == 4 { 32 } else { 20 };
            // The lumped-only plan orders every drive to brake in its lumped frame.
            let flags = if brake && self.lumped_kind == 4 {
                Flags::STOP.with(Flags::BRAKE).bits()
            } else {
                0
            };
            let b = forge::lumped(
                self.lumped_kind,
                flags,
                0,
                k as u32,
                k as u16,
                (k * T) as u64,
                0,
                N as u16,
                &vec![0; N * len],
            );
            // A locked slave takes a newer frame that reaches it within its clock window.
            let window = self.s.config().clock_window.as_ns();
            let clock = self.s.clock();
            let due = clock.is_locked()
                && self
                    .s
                    .last_lumped_cycle()
                    .is_none_or(|c| k >= c.saturating_add(2))
                && (k * T + path - clock.to_sync(Instant::from_ns(at.max(self.now))).as_ns()).abs()
                    <= window - 2;
            let syncs = self.s.counters().syncs;
            self.frame(at, 1_000, copy(&b));
            if due {
                assert!(
                    self.s.counters().syncs > syncs,
                    "the lumped frame of cycle {k}, in the window of a locked clock, was not \
                     taken: {:?}",
                    self.s.counters()
                );
            }
            if skip & 16 != 0 {
                self.frame(at + 5_000, 1_000, b);
            }
        }
        // In the P2P phase, in this slave's slice.
        let at = local(k * T + self.p2p_start + 20_000 * i64::from(self.address) + path);
        if skip & 4 == 0 {
            self.latch_until(at);
        }
        // The lumped-only plan carries no command frames.
        if skip & 2 == 0 && self.lumped_kind == 1 {
            let mut flags = Flags::empty();
            if brake {
                flags = flags.with(Flags::STOP).with(Flags::BRAKE);
            }
            if cut {
                flags = flags.with(Flags::STOP).with(Flags::TORQUE_OFF);
            }
            let head = Head {
                cycle: forge::CycleSel::Raw(k as u32),
                retry: 0,
                flags: flags.bits(),
                seq: 0,
            };
            let b = forge::command(&head, k, self.address, value, ((k - 1) * T) as u64);
            // A locked slave takes (answers) a command of the cycle in progress by its clock
            // that is newer than the last one it took.
            let window = self.s.config().clock_window.as_ns();
            let clock = self.s.clock();
            // The frame arrives when it is due, or now if that has passed (`Harness::frame`).
            let s_rx = clock
                .to_sync(Instant::from_ns(at.max(self.now) + 2_000))
                .as_ns();
            let due = clock.is_locked()
                && k >= 1
                && value.is_finite()
                && s_rx >= k * T + self.p2p_start - window + 2
                && s_rx <= (k + 1) * T + window - 2
                && self
                    .last_taken
                    .is_none_or(|l| (k as u32).wrapping_sub(l) as i32 > 0);
            let last = self.last_taken;
            self.frame(at, 2_000, copy(&b));
            if due {
                assert_eq!(
                    self.last_taken,
                    Some(k as u32),
                    "the command of cycle {k}, in the slave's window and newer than cycle \
                     {last:?}, was not taken: {:?}",
                    self.s.counters()
                );
            }
            if skip & 32 != 0 {
                self.frame(at + 3_000, 2_000, copy(&b));
            }
            if skip & 8 != 0 {
                let retry = Head { retry: 1, ..head };
                let b = forge::command(&retry, k, self.address, value, ((k - 1) * T) as u64);
                self.frame(at + 20_000, 2_000, b);
            }
        }
    }
}

/// The P2P start of the 4-slave reference plan (the testbed's) [ns].
fn plan_p2p_start() -> Duration {
    static P2P: std::sync::OnceLock<Duration> = std::sync::OnceLock::new();
    *P2P.get_or_init(|| {
        let plan = CyclePlan::new(&RingParams {
            slaves: N as u32,
            ..RingParams::default()
        })
        .unwrap_or_else(|e| panic!("plan: {e}"));
        plan.event.p2p_start
    })
}

fn check_counters(b: &SlaveCounters, a: &SlaveCounters) {
    assert!(
        a.syncs >= b.syncs
            && a.commands >= b.commands
            && a.duplicates >= b.duplicates
            && a.relocks >= b.relocks
            && a.acquisitions_restarted >= b.acquisitions_restarted
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
    while !u.is_empty() {
        let Ok(op) = Op::arbitrary(&mut u) else {
            break;
        };
        if forge::tracing() {
            eprintln!("{op:?}");
        }
        match op {
            Op::Sample { after_ns, counts } => {
                let c = h.counts(counts);
                h.sample(h.now + i64::from(after_ns % MAX_GAP), c);
            }
            Op::Latch { late_ns, counts } => {
                let c = h.counts(counts);
                let at =
                    h.s.poll_timeout()
                        .as_ns()
                        .saturating_add(i64::from(late_ns));
                h.sample(at, c);
            }
            Op::Frame {
                after_ns,
                dur_ns,
                frame,
            } => {
                let b = h.build(&frame);
                h.frame(h.now + i64::from(after_ns % MAX_GAP), i64::from(dur_ns), b);
            }
            Op::Nominal {
                value,
                skip,
                late_ns,
                repeat,
            } => {
                for _ in 0..=repeat % 16 {
                    h.nominal(value, skip, i64::from(late_ns));
                }
            }
            Op::Step { us } => h.offset = h.offset.saturating_sub(i64::from(us) * 1_000),
        }
    }
    if forge::tracing() {
        eprintln!("at {} ns: {:?} {:?}", h.now, h.s.counters(), h.s.status());
    }
});
