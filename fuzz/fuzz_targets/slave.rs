//! One [`Slave`] alone (address 1-4, its clock any fixed offset from the master's, brake or
//! torque-off safe state, the proposed plan or the lumped-only plan with its own law), fed an
//! arbitrary interleaving of encoder latches (`handle_sample`, at any time or when
//! `poll_timeout` asks) and frames (`handle_frame`): forged lumped frames of both kinds,
//! commands and responses with any field (times and cycles mostly near the master's), sealed
//! and unsealed raw bytes, and the frames of a normal cycle (so that the fuzzer reaches a
//! locked clock and applied commands). Time never goes backwards.
//!
//! # Invariants
//! - No panic.
//! - Every `Apply` and `Brake` is finite and within ±u_max; `Apply` comes only from a frame,
//!   `Brake` only from a latch; none after `TorqueOff` (latched, at most once); no `Apply`
//!   after `WatchdogExpired` (FAULT is latched; at most once).
//! - At most one `Apply` per cycle, and the applied cycles increase, until a `Relocked` event
//!   (a new master time line: its cycles are new). Known finding F1 (docs/fuzzing.md): a
//!   slave of the lumped-only plan also takes command frames, which its plan never carries,
//!   and applies one for a cycle its own law has already applied; until that is fixed the
//!   two histories (commands, lumped-only frames) are checked apart.
//! - Each response the slave sends answers the command just taken: it parses, comes from the
//!   slave's address, echoes the command's cycle and retry, carries a finite command within
//!   ±u_max, and leaves `response_delay` after the command's last bit. Nothing else is sent.
//! - A frame the slave does not take (no sync, re-lock, command or retry counted, not
//!   consumed) changes nothing observable: no event, no transmission, the same status,
//!   command and `poll_timeout`, and a forwarded frame leaves byte for byte as it came. A
//!   dropped frame is counted once in `rejected`. A taken lumped frame leaves with a valid CRC.
//! - `poll_timeout` (local time of the next latch): a latch never moves it backwards. Frames
//!   move it only by moving the clock: a taken sync steps the synchronised clock to the
//!   frame (by up to `timestamp_tolerance` forward or `late_limit` back at the receive
//!   instant, plus the new rate's lever arm), a re-lock by anything. What holds across
//!   both is that the latch stays on the synchronised grid: `to_sync(poll_timeout())` is the
//!   next latch instant k·T − lead (− the velocity window), within the round trip's rounding.
//! - Counters never decrease.
//!
//! Encoder counts are any i64 within ±(2^62 − 1) (known finding F2: a latch-to-latch
//! difference that saturates to `i64::MIN` panics in the brake reaction).
#![no_main]

use std::collections::HashSet;

use libfuzzer_sys::arbitrary::{self, Arbitrary, Unstructured};
use libfuzzer_sys::fuzz_target;
use ringsync_control::{AxisTrajectory, Cosine, Gains, Pd, VelocitySource};
use ringsync_proto::node::{
    FrameOutcome, LumpedOnlyControl, SafeState, Slave, SlaveConfig, SlaveCounters, SlaveEvent,
};
use ringsync_proto::{Duration, Instant};
use ringsync_wire::{CommandRepr, Frame, ResponseRepr, Status};

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
    /// between): the lumped frame on time (`late_ns` late), then the command with `value`.
    /// Bits of `skip`: 0 leaves out the lumped frame, 1 the command, 2 the latches; 3 adds a
    /// retry of the command, 4 a copy of the lumped frame, 5 a copy of the command.
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
}

struct Harness {
    s: Slave,
    address: u16,
    offset: i64,
    u_max: f64,
    now: i64,
    counts: i64,
    /// The next latch is the window's start (else the sampling instant).
    window_next: bool,
    /// Cycles applied on this master time line, and the last one, per frame kind that
    /// carried the command (0: command frame, 1: lumped-only frame; see F1).
    applied: HashSet<(usize, u32)>,
    last_applied: [Option<u32>; 2],
    torque_off: bool,
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
        let u_max = cfg.u_max;
        let s = if setup.lumped_only {
            let law = Pd::new(Gains::uniform(N, 3.182, 1.591, 0.0), false)
                .unwrap_or_else(|e| panic!("law: {e}"));
            let traj =
                Cosine::with_peak_speed(15.12, 2.0).unwrap_or_else(|e| panic!("trajectory: {e}"));
            let resolution = cfg.resolution;
            Slave::with_law(
                cfg,
                LumpedOnlyControl {
                    law: Box::new(law),
                    velocity: VelocitySource::Reported,
                    trajectories: vec![AxisTrajectory::Cosine(traj); N],
                    resolution: vec![resolution; N],
                },
            )
        } else {
            Slave::new(cfg)
        };
        Harness {
            s,
            address,
            offset: i64::from(setup.offset_ns),
            u_max,
            now: 0,
            counts: 0,
            window_next: true,
            applied: HashSet::new(),
            last_applied: [None; 2],
            torque_off: false,
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
        }
    }

    /// Master time now (the slave's clock runs `offset` ahead of it) [ns].
    fn master_now(&self) -> i64 {
        self.now.saturating_sub(self.offset)
    }

    /// The next encoder count. Kept within ±(2^62 − 1), so that the difference of two
    /// latches never saturates to `i64::MIN` (known finding F2: `brake_step` takes its `abs`).
    fn counts(&mut self, c: Counts) -> i64 {
        const MAX: i64 = (1 << 62) - 1;
        self.counts = match c {
            Counts::Delta(d) => self.counts.saturating_add(i64::from(d)),
            Counts::Raw(v) => v,
        }
        .clamp(-MAX, MAX);
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
        while let Some(ev) = self.s.poll_event() {
            assert!(
                !matches!(ev, SlaveEvent::Apply { .. } | SlaveEvent::Relocked { .. }),
                "a latch gave {ev:?}"
            );
            self.event(ev);
        }
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

    fn event(&mut self, ev: SlaveEvent) {
        match ev {
            SlaveEvent::Apply { u } | SlaveEvent::Brake { u } => {
                assert!(u.is_finite() && u.abs() <= self.u_max, "{ev:?}");
                assert!(!self.torque_off, "{ev:?} after torque off");
                if let SlaveEvent::Apply { .. } = ev {
                    assert!(!self.watchdog, "{ev:?} after the watchdog expired");
                }
            }
            SlaveEvent::TorqueOff { .. } => {
                assert!(!self.torque_off, "torque off twice");
                self.torque_off = true;
            }
            SlaveEvent::WatchdogExpired => {
                assert!(!self.watchdog, "the watchdog expired twice");
                self.watchdog = true;
            }
            SlaveEvent::Relocked { .. } => {
                self.applied.clear();
                self.last_applied = [None; 2];
            }
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
        let cycle = Frame::new_checked(&input[..]).ok().map(|f| f.cycle());
        let before = self.seen();
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
            || outcome == FrameOutcome::Consumed;
        let mut tx = Vec::new();
        while let Some(t) = self.s.poll_transmit() {
            tx.push(t);
        }
        let mut events = Vec::new();
        while let Some(ev) = self.s.poll_event() {
            events.push(ev);
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
        for ev in events {
            if let SlaveEvent::Apply { .. } = ev {
                let c = cycle.expect("an Apply from a frame with a header");
                let via = usize::from(cmd.is_none());
                assert!(
                    self.applied.insert((via, c)),
                    "cycle {c} applied twice ({outcome:?}, {cmd:?})"
                );
                let last = self.last_applied[via];
                assert!(
                    last.is_none_or(|l| c.wrapping_sub(l) as i32 > 0),
                    "cycle {c} applied after cycle {last:?}"
                );
                self.last_applied[via] = Some(c);
            }
            self.event(ev);
        }
        for t in &tx {
            let c = cmd.unwrap_or_else(|| panic!("a response to a frame that is no command"));
            let r = ResponseRepr::parse(&t.bytes).expect("the slave's response parses");
            assert_eq!(r.source, self.address);
            assert_eq!(
                (r.echo_cycle, r.common.cycle),
                (c.common.cycle, c.common.cycle)
            );
            assert_eq!(r.common.retry, c.common.retry);
            assert!(r.applied_v.is_finite() && f64::from(r.applied_v).abs() <= self.u_max);
            let delay = self.s.config().response_delay.as_ns();
            assert_eq!(t.at.as_ns(), rx_end.saturating_add(delay), "response time");
        }
        assert!(tx.len() <= 1, "one command, {} responses", tx.len());
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
        if skip & 4 == 0 {
            self.latch_until(at);
        }
        if skip & 1 == 0 {
            let len = if self.lumped_kind == 4 { 32 } else { 20 };
            let b = forge::lumped(
                self.lumped_kind,
                0,
                0,
                k as u32,
                k as u16,
                (k * T) as u64,
                0,
                N as u16,
                &vec![0; N * len],
            );
            self.frame(at, 1_000, copy(&b));
            if skip & 16 != 0 {
                self.frame(at + 5_000, 1_000, b);
            }
        }
        let at = local(k * T + 200_000 + path);
        if skip & 4 == 0 {
            self.latch_until(at);
        }
        // The lumped-only plan carries no command frames.
        if skip & 2 == 0 && self.lumped_kind == 1 {
            let head = Head {
                cycle: forge::CycleSel::Raw(k as u32),
                retry: 0,
                flags: 0,
                seq: 0,
            };
            let b = forge::command(&head, k, self.address, value, ((k - 1) * T) as u64);
            self.frame(at, 2_000, copy(&b));
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

fn check_counters(b: &SlaveCounters, a: &SlaveCounters) {
    assert!(
        a.syncs >= b.syncs
            && a.commands >= b.commands
            && a.duplicates >= b.duplicates
            && a.relocks >= b.relocks
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
