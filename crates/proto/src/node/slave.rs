//! The slave node of the proposed plan: takes the master's timestamp from the passing lumped
//! frame (clock sync), writes its feedback into its own slot, applies its command when it
//! arrives and answers after T_ti, and applies its local fault reaction when no valid
//! command arrives for W cycles.
//!
//! Sampling: at synchronised time k·T_cyc − lead the slave latches its encoder count; the
//! velocity is the count difference over the window that ends there, so the driver is asked
//! for the count twice per cycle ([`Slave::poll_timeout`], [`Slave::handle_sample`]). The
//! paper samples at the cycle start (lead 0), which suits hardware clocks synchronised to
//! well under the lumped frame's first hop; a lead (EtherCAT's "input shift") keeps the
//! latch ahead of the frame when the clocks are only good to tens of µs (software
//! timestamps).
//!
//! # Frame acceptance
//! Nothing from the wire is trusted ([`super::reject`]). A lumped frame is taken (its
//! timestamp for the clock, its slot for the feedback) only when its cycle counter matches
//! its own send stamp, both are newer than the last lumped frame taken, and the stamp plus
//! the path delay lies within `clock_window` of the slave's own estimate of master time,
//! ahead or behind. (The window is symmetric on purpose: a frame taken at the edge of it
//! moves the clock by at most the window, so the next frame on time is still inside it. A
//! window wider behind than ahead would let late frames walk the clock out of it for good.)
//! A command is taken only when its
//! cycle is the one in progress by the slave's clock, its cycle is newer than the last
//! command taken (a retry of that command is answered again, not applied again), and the
//! sample it was computed from is not in the future. Refused frames change nothing: a
//! lumped frame is forwarded unchanged, a command is not answered, the watchdog is not fed.
//!
//! Acquisition: the first lumped frame is taken on trust; until a second frame agrees
//! with it (within the window, newer, the local time between them matching the master time
//! between them) the slave is not locked, and a frame that disagrees starts acquisition
//! afresh from itself. A single stray frame (a frame left in a socket from an earlier run,
//! a forgery before the master's first frame) therefore cannot capture a slave.
//!
//! A clock step beyond the window is never taken from one frame or a burst. When the
//! master's time line really moves (the master restarted), frames of the new time line are
//! consistent with each other but not with the slave's clock; after `relock_after` of them
//! with no frame of the old time line in between, the slave re-locks to the new one
//! ([`SlaveEvent::Relocked`]). While it waits it takes no command, so its watchdog has long
//! put the axis in its safe state.
//!
//! # Fault reaction
//! When no valid command arrives for W cycles (the master or the ring is gone) the slave
//! applies its configured [`SafeState`], as a drive does (CiA 402 "quick stop, then
//! disable"): `TorqueOff` cuts torque at once; `Brake` damps the axis's own measured
//! velocity (u = −K_b·v, clipped) until it stands still for [`STANDSTILL_SAMPLES`] samples,
//! or for at most `brake_timeout`, then cuts torque. A `TORQUE_OFF` command from the master
//! cuts torque too. Torque off is latched.

use std::collections::VecDeque;

use ringsync_wire::{
    CommandRepr, Common, DelayMarker, DelaySlot, FeedbackSlot, Flags, Frame, FrameKind,
    LumpedOnlySlot, LumpedPayload, Pdu, ResponseRepr, SlotCodec, Status,
};

use super::clock::SyncClock;
use super::reject::{Reject, Rejections, unwrap_cycle};
use super::{Outbox, Transmit, TransmitPdu, WireFrame};
use crate::time::{Duration, Instant};

/// Consecutive samples with at most one count of motion over the velocity window after
/// which a braking axis is taken to stand still.
pub const STANDSTILL_SAMPLES: u32 = 10;

/// What a slave that loses its master does with its axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum SafeState {
    /// Cut torque at once (the axis coasts against its friction).
    TorqueOff,
    /// Damp the axis's own velocity to standstill, then cut torque.
    #[default]
    Brake,
}

impl SafeState {
    /// The name used in scenarios and outputs.
    pub fn name(self) -> &'static str {
        match self {
            SafeState::TorqueOff => "torque-off",
            SafeState::Brake => "brake",
        }
    }
}

impl std::str::FromStr for SafeState {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "torque-off" => Ok(SafeState::TorqueOff),
            "brake" => Ok(SafeState::Brake),
            other => Err(format!(
                "unknown safe state '{other}': use \"brake\" or \"torque-off\""
            )),
        }
    }
}

/// Why a drive's torque went off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum TorqueOffCause {
    /// The master ordered it (a command with the `TORQUE_OFF` flag).
    Commanded,
    /// The watchdog expired and the safe state is `TorqueOff`.
    Watchdog,
    /// The brake reaction brought the axis to standstill.
    Standstill,
    /// The brake reaction ran out of time.
    BrakeTimeout,
}

impl TorqueOffCause {
    /// The name used in outputs.
    pub fn name(self) -> &'static str {
        match self {
            TorqueOffCause::Commanded => "ordered by the master",
            TorqueOffCause::Watchdog => "watchdog, safe state torque-off",
            TorqueOffCause::Standstill => "brake reached standstill",
            TorqueOffCause::BrakeTimeout => "brake timed out",
        }
    }
}

/// What a slave of the lumped-only plan (ref. \[3\]) runs on the data its lumped frame
/// carries: its own axis's command from the feedback of every axis the frame holds.
/// `ringsync-model` implements it with the control library's laws.
pub trait SlaveLaw: Send {
    /// Number of axes of the ring.
    fn axes(&self) -> usize;
    /// The command \[V\] for this slave's own axis `me` (0-based) at `now` [s, synchronised
    /// clock], from `slots` (length [`SlaveLaw::axes`]): axis a's feedback as the frame
    /// carries it (this slave's own fresh sample at `me`), or `None` where the frame holds
    /// none for it (or the slave refused it).
    fn command(&mut self, me: usize, slots: &[Option<FeedbackSlot>], now: f64) -> f64;
}

/// Configuration of one slave.
#[derive(Debug, Clone, PartialEq)]
pub struct SlaveConfig {
    /// Address on the ring, 1..=n.
    pub address: u16,
    /// Cycle time T_cyc.
    pub cycle: Duration,
    /// D_i: master send time of a frame to its first bit at this slave (from the cycle plan).
    pub path_delay: Duration,
    /// T_ti: last bit of the command in to first bit of the response out.
    pub response_delay: Duration,
    /// Encoder-difference window for the velocity.
    pub velocity_window: Duration,
    /// Sampling lead: the encoder latches at synchronised time k·T_cyc − lead (0: at the
    /// cycle start, as in the paper).
    pub sample_lead: Duration,
    /// W: cycles without a valid command before the safe state.
    pub watchdog_cycles: u32,
    /// Whether to synchronise the clock to the master.
    pub clock_sync: bool,
    /// Drive range ±u_max \[V\].
    pub u_max: f64,
    /// Encoder resolution [rad per count] (the brake reaction's velocity).
    pub resolution: f64,
    /// How far from the slave's own estimate of master time a received timestamp may be,
    /// ahead or behind (the clock error plus the link jitter the slave allows; a command's
    /// cycle is placed with the same allowance).
    pub clock_window: Duration,
    /// Frames of a new, self-consistent master time line outside the clock window are
    /// taken as a real clock step after this long with no frame of the old time line.
    pub relock_after: Duration,
    /// Start of the P2P phase from the cycle start: the master computes there, so no
    /// command of a cycle can come earlier (one that does is not the master's).
    pub p2p_start: Duration,
    /// The local reaction when the master is lost.
    pub safe_state: SafeState,
    /// K_b of the brake reaction u = −K_b·v [V·s/rad].
    pub brake_gain: f64,
    /// Longest brake before the torque goes off anyway.
    pub brake_timeout: Duration,
    /// Behind transparent relays (its path delay its links alone, address × L): take the
    /// master's running estimate of a link from its commands
    /// ([`CommandRepr::link_ns`](ringsync_wire::CommandRepr)) and make the path delay
    /// address × that link, when it stays within half the clock window of the path the
    /// start-up phase gave. `false`: a link in a command is refused (counted).
    pub follow_link: bool,
}

impl SlaveConfig {
    /// Slave `address` on a ring of cycle `cycle`, `path_delay` from the master, with the
    /// reference ring's other settings: T_ti 2 µs, a 125 µs velocity window, no sampling
    /// lead, W = 5, synchronised clock, ±10 V, a 20-bit encoder, a clock window of ±50 µs,
    /// re-lock after 100 cycles, commands taken from the cycle start on (set `p2p_start`
    /// from the plan), brake with K_b = 1.591 V·s/rad for at most 2 s.
    pub fn new(address: u16, cycle: Duration, path_delay: Duration) -> Self {
        SlaveConfig {
            address,
            cycle,
            path_delay,
            response_delay: Duration::from_us(2),
            velocity_window: Duration::from_us(125),
            sample_lead: Duration::ZERO,
            watchdog_cycles: 5,
            clock_sync: true,
            u_max: 10.0,
            resolution: std::f64::consts::TAU / f64::from(1u32 << 20),
            clock_window: Duration::from_us(50),
            relock_after: cycle * 100,
            p2p_start: Duration::ZERO,
            safe_state: SafeState::Brake,
            brake_gain: 1.591,
            brake_timeout: Duration::from_ms(2_000),
            follow_link: false,
        }
    }
}

/// Something the driver must act on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlaveEvent {
    /// Apply this command from the master to the drive \[V\] from now on.
    Apply {
        /// The command after clipping \[V\].
        u: f64,
    },
    /// The watchdog expired: the master is lost; the safe state's reaction follows.
    WatchdogExpired,
    /// The drive began to brake on its own: ordered by the master (`BRAKE`), or its safe
    /// state after the watchdog.
    Braking {
        /// Whether the master ordered it.
        ordered: bool,
    },
    /// The drive's own brake command (the `Brake` safe state) \[V\] from now on.
    Brake {
        /// The command after clipping \[V\].
        u: f64,
    },
    /// The drive's torque is off from now on (latched; the drive holds 0 V).
    TorqueOff {
        /// Why.
        cause: TorqueOffCause,
    },
    /// The start-up phase ended: the slave took the path delay the master measured and
    /// follows the master's clock from now on.
    Calibrated {
        /// Its path delay: master send to this slave's first bit in.
        path_delay: Duration,
    },
    /// The clock re-locked to a new master time line.
    Relocked {
        /// The step taken \[ns\]: new time line minus the slave's clock.
        step: Duration,
    },
}

/// What the hardware does with a received frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameOutcome {
    /// Forward it (possibly modified) after the residence time.
    Forward,
    /// It was for this slave; it ends here.
    Consumed,
    /// Bad or refused frame for this slave; dropped and counted.
    Dropped,
}

/// Counters that explain every lost cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct SlaveCounters {
    /// Lumped frames taken (clock syncs).
    pub syncs: u64,
    /// Valid commands applied.
    pub commands: u64,
    /// Retries of a command already applied, answered again (not applied again).
    pub duplicates: u64,
    /// Frames refused, per reason.
    pub rejected: Rejections,
    /// Clock re-locks to a new master time line.
    pub relocks: u64,
    /// Clock acquisitions started afresh (a frame disagreed with the frames before it
    /// before the clock had locked).
    pub acquisitions_restarted: u64,
    /// Delay frames answered: probes written in the start-up phase, closing frames taken
    /// or acknowledged again.
    pub delay_frames: u64,
    /// Links the master sent with its commands that this slave did not take: it does not
    /// follow the link ([`SlaveConfig::follow_link`]), or address × link would move its
    /// path delay more than half the clock window from the start-up's (the command itself
    /// is applied).
    pub links_refused: u64,
    /// Times it moved its path delay to the master's link estimate.
    pub link_updates: u64,
}

/// Which encoder latch comes next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Latch {
    /// Start of the velocity window.
    Window,
    /// The sampling instant.
    Sample,
}

/// The drive's state.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Drive {
    /// Following the master's commands.
    Enabled,
    /// Braking on its own: since local time `since` [ns]; `still` samples at standstill.
    Braking { since: i64, still: u32 },
    /// Torque off (latched).
    Off,
}

/// Frames of a foreign time line seen in a row: the first and last one's local receive
/// time and the last one's master time at the slave [ns].
#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    first_local: i64,
    last_local: i64,
    last_at: i64,
}

/// The slave's phase: measuring the ring's delays with the master, or running.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Start-up: the path delay is not known yet. The slave answers the master's delay
    /// probes with its residence and waits for the closing frame with its path delay; it
    /// takes no sync lumped frame (it could not place the master's time) and no command.
    Calibrating {
        /// The last probe it wrote: its sequence number and its first bit's local time.
        probe: Option<(u16, Instant)>,
        /// That probe's residence once the driver reported its send
        /// ([`Slave::handle_forwarded`]): (sequence number, ns on this slave's clock).
        residence: Option<(u16, u32)>,
        /// The last frame handled was that probe, written: the next send the driver reports
        /// is its.
        written: bool,
    },
    /// Following the master: clock sync, feedback, commands.
    Running,
}

/// A command that passed acceptance: apply it, or answer a retry of the last one again.
enum CommandAction {
    Apply,
    Repeat,
}

/// A slave of the ring: one servo drive's node. It latches its encoder at its synchronised
/// sampling instants, writes the sample into its slot of each lumped frame and follows the
/// master's clock from the frame's timestamps, forwards every frame not for it, applies the
/// command of its time slice and answers it, and puts its drive in its safe state when the
/// master is lost for W cycles. With the lumped-only plan it runs its own law
/// ([`SlaveLaw`]) on the frame's feedback instead of taking commands.
///
/// It is sans-IO, like quinn-proto's `Connection`. Its time is its own local clock (its
/// hardware timestamp counter); the driver converts between local and true time.
///
/// # Driving it
///
/// A driver calls, in this order:
///
/// 1. [`poll_timeout`](Slave::poll_timeout): the local time of the next encoder latch;
/// 2. then [`handle_sample`](Slave::handle_sample) with the encoder count at that instant;
///    whenever a frame arrives, [`handle_frame`](Slave::handle_frame) with its first and
///    last bit's local times; it returns whether to forward the frame (modified in place:
///    a lumped frame carries this slave's sample on);
/// 3. after either, [`poll_transmit`](Slave::poll_transmit) until `None` (responses, each
///    with its send instant), then [`poll_event`](Slave::poll_event) until `None` (apply a
///    command, brake, torque off, the watchdog expired, the clock re-locked);
/// 4. optionally [`recycle`](Slave::recycle) the buffers of frames it is done with.
///
/// # Getters
///
/// [`config`](Slave::config), [`counters`](Slave::counters), [`clock`](Slave::clock)
/// (local ↔ synchronised time), [`status`](Slave::status), [`command`](Slave::command),
/// [`torque_off`](Slave::torque_off), [`last_lumped_cycle`](Slave::last_lumped_cycle),
/// [`samples_taken`](Slave::samples_taken).
pub struct Slave {
    cfg: SlaveConfig,
    phase: Phase,
    clock: SyncClock,
    /// Index k of the next sampling instant k·T_cyc.
    k: i64,
    latch: Latch,
    window_counts: i64,
    sample: FeedbackSlot,
    u: f64,
    status: Status,
    drive: Drive,
    cycles_without_command: u32,
    /// Cycle and retry count of the last command taken.
    last_command: Option<(u32, u8)>,
    /// The last lumped frame taken: its full cycle, its send stamp [master ns], and its
    /// local receive time with the master time it reached this slave [ns].
    last_lumped: Option<(i64, i64)>,
    anchor: Option<(i64, i64)>,
    /// Two agreeing lumped frames have been taken: the slave follows its own time line.
    acquired: bool,
    candidate: Option<Candidate>,
    seq: u16,
    out: Outbox,
    events: VecDeque<SlaveEvent>,
    counters: SlaveCounters,
    /// The path delay the slave was given, or took in its start-up phase: what a link from
    /// the master may move it from.
    given_path: Duration,
    law: Option<Box<dyn SlaveLaw>>,
    /// Scratch for the frame's slots handed to the law.
    law_slots: Vec<Option<FeedbackSlot>>,
}

impl std::fmt::Debug for Slave {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slave")
            .field("cfg", &self.cfg)
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

impl Slave {
    /// A slave of the lumped-only plan: it runs `law` on the data the lumped frame
    /// carries and applies its own axis's command as the frame passes.
    pub fn with_law(cfg: SlaveConfig, law: Box<dyn SlaveLaw>) -> Self {
        let n = law.axes();
        let mut s = Slave::new(cfg);
        s.law = Some(law);
        s.law_slots = vec![None; n];
        s
    }

    /// A slave at rest, its first sampling instant at synchronised time 0.
    pub fn new(cfg: SlaveConfig) -> Self {
        let clock = SyncClock::new(cfg.clock_sync);
        Slave {
            given_path: cfg.path_delay,
            cfg,
            phase: Phase::Running,
            clock,
            k: 0,
            latch: Latch::Window,
            window_counts: 0,
            sample: FeedbackSlot::default(),
            u: 0.0,
            status: Status::CLOCK_UNLOCKED,
            drive: Drive::Enabled,
            cycles_without_command: 0,
            last_command: None,
            last_lumped: None,
            anchor: None,
            acquired: false,
            candidate: None,
            seq: 0,
            out: Outbox::default(),
            events: VecDeque::new(),
            counters: SlaveCounters::default(),
            law: None,
            law_slots: Vec::new(),
        }
    }

    /// A slave in its start-up phase: its path delay (`cfg.path_delay` is ignored) comes
    /// from the master's delay measurement ([`crate::node::calibrate`]). Until the closing
    /// frame gives it, the slave answers delay probes and takes no sync lumped frame and no
    /// command.
    pub fn calibrating(mut cfg: SlaveConfig) -> Self {
        cfg.path_delay = Duration::ZERO;
        let mut s = Slave::new(cfg);
        s.phase = Phase::Calibrating {
            probe: None,
            residence: None,
            written: false,
        };
        s
    }

    /// The path delay the slave works with: `None` while it waits for the master's
    /// measurement ([`Slave::calibrating`]).
    pub fn path_delay(&self) -> Option<Duration> {
        match self.phase {
            Phase::Calibrating { .. } => None,
            Phase::Running => Some(self.cfg.path_delay),
        }
    }

    /// The driver sent on the frame this slave handled last, its first bit out at local
    /// `tx_start`: when that frame was a delay probe the slave wrote, the slave reports this
    /// residence in the next probe (two-step, as a transparent clock's follow-up). After any
    /// other frame (a duplicate, a frame not for it, a response) it changes nothing.
    pub fn handle_forwarded(&mut self, tx_start: Instant) {
        if let Phase::Calibrating {
            probe: Some((seq, rx)),
            residence,
            written,
        } = &mut self.phase
            && std::mem::take(written)
        {
            let held = tx_start.as_ns().saturating_sub(rx.as_ns());
            if let Ok(ns) = u32::try_from(held) {
                *residence = Some((*seq, ns));
            }
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SlaveConfig {
        &self.cfg
    }
    /// The synchronised clock, to set its servo's filter.
    pub fn clock_mut(&mut self) -> &mut SyncClock {
        &mut self.clock
    }
    /// The synchronised clock.
    pub fn clock(&self) -> &SyncClock {
        &self.clock
    }
    /// Counters.
    pub fn counters(&self) -> SlaveCounters {
        self.counters
    }
    /// Status bits.
    pub fn status(&self) -> Status {
        self.status
    }
    /// The command applied now \[V\].
    pub fn command(&self) -> f64 {
        self.u
    }
    /// Whether the drive's torque is off.
    pub fn torque_off(&self) -> bool {
        self.drive == Drive::Off
    }
    /// The full cycle index of the last lumped frame taken: the node's "last seen"
    /// counter, from which a driver tells where a ring broke.
    pub fn last_lumped_cycle(&self) -> Option<i64> {
        self.last_lumped.map(|(c, _)| c)
    }
    /// Encoder latches taken so far (the node's own heartbeat: it advances as long as the
    /// slave runs, whatever reaches it).
    pub fn samples_taken(&self) -> i64 {
        self.k
    }

    fn sample_instant(&self) -> Instant {
        Instant::from_ns(self.k.saturating_mul(self.cfg.cycle.as_ns())) - self.cfg.sample_lead
    }

    /// The slave's own estimate of master time at local time `local`: its synchronised
    /// clock once locked; before that (or without clock sync), the last lumped frame taken
    /// plus the local time since; `None` before any.
    fn master_now(&self, local: Instant) -> Option<i64> {
        if self.cfg.clock_sync && self.clock.is_locked() && self.anchor.is_some() {
            return Some(self.clock.to_sync(local).as_ns());
        }
        self.anchor
            .map(|(l, m)| m.saturating_add(local.as_ns().saturating_sub(l)))
    }

    fn reject(&mut self, r: Reject) {
        self.counters.rejected.count(r);
    }

    /// Hands back the buffer of a frame the driver is done with (sent, consumed or
    /// dropped), for the slave's next sends. Optional: without it the slave allocates.
    pub fn recycle(&mut self, buf: Vec<u8>) {
        self.out.recycle(buf);
    }

    /// Local time of the next encoder latch; call [`Slave::handle_sample`] then.
    #[must_use]
    pub fn poll_timeout(&self) -> Instant {
        let at = match self.latch {
            Latch::Window => self.sample_instant() - self.cfg.velocity_window,
            Latch::Sample => self.sample_instant(),
        };
        self.clock.to_local(at)
    }

    /// The encoder count latched at local time `now` (the time [`Slave::poll_timeout`] gave).
    pub fn handle_sample(&mut self, now: Instant, counts: i64) {
        match self.latch {
            Latch::Window => {
                self.window_counts = counts;
                self.latch = Latch::Sample;
            }
            Latch::Sample => {
                let moved = counts.saturating_sub(self.window_counts);
                let w = self.cfg.velocity_window.as_ns() as f64 * 1e-9;
                let velocity = moved as f64 / w;
                let sync_now = self.clock.to_sync(now);
                self.sample = FeedbackSlot {
                    position: clamp_i32(counts),
                    velocity: clamp_i32(crate::time::round_i64(velocity)),
                    sample_time_ns: sync_now.as_ns().max(0) as u64,
                    status: self.status,
                    written: true,
                };
                self.latch = Latch::Window;
                self.k += 1;
                self.tick_watchdog(now);
                self.brake_step(now, moved, velocity);
            }
        }
    }

    fn tick_watchdog(&mut self, now: Instant) {
        if self.status.contains(Status::WATCHDOG) {
            return;
        }
        self.cycles_without_command += 1;
        if self.cycles_without_command > self.cfg.watchdog_cycles {
            self.u = 0.0;
            self.status = self.status.with(Status::FAULT).with(Status::WATCHDOG);
            self.events.push_back(SlaveEvent::WatchdogExpired);
            match (self.drive, self.cfg.safe_state) {
                (Drive::Off, _) => {}
                (_, SafeState::TorqueOff) => self.cut_torque(TorqueOffCause::Watchdog),
                (_, SafeState::Brake) => self.begin_brake(now, false),
            }
        }
    }

    /// One step of the brake reaction at a sample: `moved` counts over the velocity window,
    /// `velocity` [counts/s].
    fn brake_step(&mut self, now: Instant, moved: i64, velocity: f64) {
        let Drive::Braking { since, still } = self.drive else {
            return;
        };
        let still = if moved.unsigned_abs() <= 1 {
            still + 1
        } else {
            0
        };
        if still >= STANDSTILL_SAMPLES {
            self.cut_torque(TorqueOffCause::Standstill);
            return;
        }
        if now.as_ns().saturating_sub(since) > self.cfg.brake_timeout.as_ns() {
            self.cut_torque(TorqueOffCause::BrakeTimeout);
            return;
        }
        let (u, _) = saturate(
            -self.cfg.brake_gain * velocity * self.cfg.resolution,
            self.cfg.u_max,
        );
        self.u = u;
        self.drive = Drive::Braking { since, still };
        self.events.push_back(SlaveEvent::Brake { u });
    }

    /// The drive starts braking on its own at local time `now` (unless it already brakes
    /// or its torque is off).
    fn begin_brake(&mut self, now: Instant, ordered: bool) {
        if self.drive != Drive::Enabled {
            return;
        }
        self.status = self.status.with(Status::BRAKING);
        self.drive = Drive::Braking {
            since: now.as_ns(),
            still: 0,
        };
        self.events.push_back(SlaveEvent::Braking { ordered });
    }

    fn cut_torque(&mut self, cause: TorqueOffCause) {
        self.u = 0.0;
        self.drive = Drive::Off;
        self.status = Status::from_bits(self.status.bits() & !Status::BRAKING.bits())
            .unwrap_or(self.status)
            .with(Status::TORQUE_OFF);
        self.events.push_back(SlaveEvent::TorqueOff { cause });
    }

    /// A frame whose first bit arrived at local `rx_start` and last bit at `rx_end`. A lumped
    /// frame is modified in place (this slave's slot, then the CRC) once it is accepted.
    /// The outcome says whether the driver forwards it to the next node.
    #[must_use]
    pub fn handle_frame(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        bytes: &mut [u8],
    ) -> FrameOutcome {
        let Ok(mut frame) = Frame::new_checked(&mut bytes[..]) else {
            self.reject(Reject::Malformed);
            return FrameOutcome::Dropped;
        };
        let kind = match frame.check() {
            Ok(k) => k,
            Err(_) => {
                self.reject(Reject::Malformed);
                return FrameOutcome::Dropped;
            }
        };
        if let Phase::Calibrating { written, .. } = &mut self.phase {
            // Only the probe this frame turns out to be is the next send's.
            *written = false;
        }
        if matches!(self.phase, Phase::Calibrating { .. }) || kind == FrameKind::Delay {
            let seq = frame.seq();
            let outcome = self.calibration_frame(rx_start, kind, seq, frame.payload_mut());
            if kind == FrameKind::Delay && outcome == FrameOutcome::Forward {
                // The CRC covers the slot just written (unchanged bytes give the same CRC).
                frame.fill_crc();
            }
            return outcome;
        }
        match kind {
            FrameKind::Lumped if self.law.is_none() => {
                let cycle = frame.cycle();
                let Ok(mut p) = LumpedPayload::new_checked(frame.payload_mut(), kind) else {
                    self.reject(Reject::Malformed);
                    return FrameOutcome::Dropped;
                };
                let Some(k) = p.slot_index(self.cfg.address) else {
                    return FrameOutcome::Forward;
                };
                if let Err(r) = self.take_sync(rx_start, cycle, p.master_time_ns()) {
                    self.reject(r);
                    return FrameOutcome::Forward;
                }
                if let Some(slot) = p.slot_bytes_mut(k) {
                    // Infallible for a feedback slot of the right length.
                    let _ = self.sample.emit(slot);
                }
                frame.fill_crc();
                FrameOutcome::Forward
            }
            // The lumped-only plan carries no commands: a slave that runs its own law takes
            // none (it would apply it on top of its law's output).
            FrameKind::Command if self.law.is_some() => {
                self.reject(Reject::UnexpectedKind);
                FrameOutcome::Dropped
            }
            FrameKind::Command => {
                let Ok(cmd) = CommandRepr::parse_verified(bytes) else {
                    self.reject(Reject::Malformed);
                    return FrameOutcome::Dropped;
                };
                if cmd.target != self.cfg.address {
                    return FrameOutcome::Forward;
                }
                match self.check_command(&cmd, rx_end) {
                    Ok(action) => {
                        self.take_command(&cmd, rx_end, action);
                        FrameOutcome::Consumed
                    }
                    Err(r) => {
                        self.reject(r);
                        FrameOutcome::Dropped
                    }
                }
            }
            FrameKind::LumpedOnly if self.law.is_some() => {
                self.take_lumped_only(rx_start, rx_end, &mut frame)
            }
            // A lumped frame of the other plan: not ours to read; the ring carries it on.
            FrameKind::Lumped | FrameKind::LumpedOnly | FrameKind::Delay => {
                self.reject(Reject::UnexpectedKind);
                FrameOutcome::Forward
            }
            FrameKind::Response => FrameOutcome::Forward,
        }
    }

    /// A frame in the start-up phase, or a delay frame in any phase (its header and CRC
    /// checked; `payload` in place): a delay probe gets this slave's residence report, a
    /// closing frame gives it its path delay (once running, a closing frame with the delay
    /// it took is acknowledged again, for a master whose first acknowledgement was lost);
    /// in the start-up phase a sync lumped frame is carried on untouched and a command
    /// dropped, both counted (the slave cannot place them yet).
    fn calibration_frame(
        &mut self,
        rx_start: Instant,
        kind: FrameKind,
        seq: u16,
        payload: &mut [u8],
    ) -> FrameOutcome {
        match kind {
            FrameKind::Delay => {}
            FrameKind::Response => return FrameOutcome::Forward,
            FrameKind::Command => {
                self.reject(Reject::UnexpectedKind);
                return FrameOutcome::Dropped;
            }
            FrameKind::Lumped | FrameKind::LumpedOnly => {
                self.reject(Reject::UnexpectedKind);
                return FrameOutcome::Forward;
            }
        }
        let Ok(mut p) = LumpedPayload::new_checked(payload, kind) else {
            self.reject(Reject::Malformed);
            return FrameOutcome::Dropped;
        };
        let Some(k) = p.slot_index(self.cfg.address) else {
            return FrameOutcome::Forward;
        };
        let Some(slot) = p.slot_bytes(k).and_then(|b| DelaySlot::parse(b).ok()) else {
            self.reject(Reject::Malformed);
            return FrameOutcome::Dropped;
        };
        let written = match self.delay_slot(rx_start, seq, slot) {
            Ok(w) => w,
            Err(r) => {
                self.reject(r);
                return FrameOutcome::Forward;
            }
        };
        if let Some(b) = p.slot_bytes_mut(k) {
            // Infallible for a delay slot of the right length.
            let _ = written.emit(b);
        }
        self.counters.delay_frames += 1;
        FrameOutcome::Forward
    }

    /// This slave's answer to its slot of a delay frame (probe `seq`, first bit in at local
    /// `rx_start`): the slot to write back, or why the frame is refused. A closing frame
    /// (a path delay in the slot) ends the start-up phase.
    fn delay_slot(
        &mut self,
        rx_start: Instant,
        seq: u16,
        slot: DelaySlot,
    ) -> Result<DelaySlot, Reject> {
        let ack = DelaySlot {
            marker: DelayMarker::Written,
            ..slot
        };
        let Phase::Calibrating {
            probe,
            residence,
            written,
        } = &mut self.phase
        else {
            let mine = i64::from(slot.path_delay_ns) == self.cfg.path_delay.as_ns();
            return if slot.path_delay_ns != 0 && mine {
                Ok(ack)
            } else {
                Err(Reject::UnexpectedKind)
            };
        };
        if slot.path_delay_ns != 0 {
            // A path delay is a fraction of the cycle: the master's send to this slave.
            let d = Duration::from_ns(i64::from(slot.path_delay_ns));
            if d >= self.cfg.cycle {
                return Err(Reject::Overflow);
            }
            self.cfg.path_delay = d;
            self.given_path = d;
            self.phase = Phase::Running;
            self.events
                .push_back(SlaveEvent::Calibrated { path_delay: d });
            return Ok(ack);
        }
        if probe.is_some_and(|(s, _)| s == seq) {
            return Err(Reject::Duplicate);
        }
        let answer = match residence.take() {
            Some((of, ns)) => DelaySlot {
                residence_ns: ns,
                path_delay_ns: 0,
                residence_of: of,
                marker: DelayMarker::Residence,
            },
            None => DelaySlot {
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            },
        };
        *probe = Some((seq, rx_start));
        *written = true;
        Ok(answer)
    }

    /// A decoded frame whose first bit arrived at local `rx_start` and last bit at `rx_end`
    /// (a driver that carries frames without their bytes): the checks of
    /// [`Slave::handle_frame`] after the decoding, with the same effect; a lumped frame
    /// gets this slave's slot written in place, to be forwarded on
    /// [`FrameOutcome::Forward`].
    pub fn handle_pdu(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        pdu: &mut Pdu,
    ) -> FrameOutcome {
        // The start-up phase reads and writes delay frames in place: through their bytes.
        if matches!(self.phase, Phase::Calibrating { .. }) {
            return self.handle_pdu_as_bytes(rx_start, rx_end, pdu);
        }
        match pdu {
            Pdu::Lumped(l) if self.law.is_none() => {
                let k = usize::from(self.cfg.address)
                    .checked_sub(usize::from(l.first_slot) + 1)
                    .filter(|&k| k < l.slots.len());
                let Some(k) = k else {
                    return FrameOutcome::Forward;
                };
                if let Err(r) = self.take_sync(rx_start, l.common.cycle, l.master_time_ns) {
                    self.reject(r);
                    return FrameOutcome::Forward;
                }
                l.slots[k] = self.sample;
                FrameOutcome::Forward
            }
            Pdu::Command(_) if self.law.is_some() => {
                self.reject(Reject::UnexpectedKind);
                FrameOutcome::Dropped
            }
            Pdu::Command(cmd) => {
                if cmd.target != self.cfg.address {
                    return FrameOutcome::Forward;
                }
                match self.check_command(cmd, rx_end) {
                    Ok(action) => {
                        self.take_command(cmd, rx_end, action);
                        FrameOutcome::Consumed
                    }
                    Err(r) => {
                        self.reject(r);
                        FrameOutcome::Dropped
                    }
                }
            }
            // The lumped-only plan's slaves read and write the frame in place: through
            // its bytes.
            Pdu::LumpedOnly(_) if self.law.is_some() => {
                self.handle_pdu_as_bytes(rx_start, rx_end, pdu)
            }
            Pdu::Lumped(_) | Pdu::LumpedOnly(_) => {
                self.reject(Reject::UnexpectedKind);
                FrameOutcome::Forward
            }
            Pdu::Response(_) => FrameOutcome::Forward,
            Pdu::Delay(_) => self.handle_pdu_as_bytes(rx_start, rx_end, pdu),
        }
    }

    /// [`Slave::handle_frame`] on the bytes of `pdu`, which takes the frame as modified.
    fn handle_pdu_as_bytes(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        pdu: &mut Pdu,
    ) -> FrameOutcome {
        let mut bytes = Vec::new();
        if pdu.emit_into(&mut bytes).is_err() {
            self.reject(Reject::Malformed);
            return FrameOutcome::Dropped;
        }
        let outcome = self.handle_frame(rx_start, rx_end, &mut bytes);
        if let Ok(p) = Pdu::parse(&bytes) {
            *pdu = p;
        }
        outcome
    }

    /// Checks a lumped frame that carries this slave's slot (its `cycle` and send `stamp`,
    /// received at local `rx`) and, if it passes, takes it for the clock.
    fn take_sync(&mut self, rx: Instant, cycle: u32, stamp: u64) -> Result<(), Reject> {
        let sent = Instant::from_wire(stamp).ok_or(Reject::Overflow)?;
        let at = sent
            .checked_add(self.cfg.path_delay)
            .ok_or(Reject::Overflow)?;
        // The master stamps a lumped frame with its send time, in its cycle (a late master
        // up to one cycle after): the counter must match the stamp.
        let t = self.cfg.cycle.as_ns().max(1);
        let stamp_cycle = sent.as_ns().div_euclid(t);
        let c = unwrap_cycle(cycle, stamp_cycle);
        if c != stamp_cycle && c != stamp_cycle - 1 {
            return Err(Reject::WrongCycle);
        }
        // Against the slave's own time line: newer than the last frame taken, and within
        // the clock window. A frame that fails only these may belong to a new time line.
        let acquired = self.acquired;
        let verdict = match (self.last_lumped, self.master_now(rx)) {
            (Some((last_c, last_stamp)), _) if c == last_c || sent.as_ns() == last_stamp => {
                return Err(Reject::Duplicate);
            }
            (Some((last_c, last_stamp)), _) if c < last_c || sent.as_ns() < last_stamp => {
                Err(Reject::Stale)
            }
            (_, Some(expect)) => {
                let err = at.as_ns().saturating_sub(expect);
                if err > self.cfg.clock_window.as_ns() {
                    Err(Reject::FutureTimestamp)
                } else if err < -self.cfg.clock_window.as_ns() {
                    Err(Reject::Stale)
                } else {
                    Ok(())
                }
            }
            (_, None) => Ok(()), // the first frame: nothing to check it against
        };
        match verdict {
            Ok(()) => {
                self.candidate = None;
                self.clock.sync(rx, at);
                self.acquired = self.last_lumped.is_some();
            }
            // Not yet locked: the frames so far disagree with this one; start over from it,
            // and forget the command taken on the abandoned time line (its cycle would hold
            // off every command of the new one as stale).
            Err(_) if !acquired => {
                self.clock.restart(rx, at);
                self.candidate = None;
                self.last_command = None;
                self.counters.acquisitions_restarted += 1;
            }
            Err(r) => {
                if !self.relock(rx, at) {
                    return Err(r);
                }
            }
        }
        let first = self.last_lumped.is_none() || !acquired;
        self.last_lumped = Some((c, sent.as_ns()));
        self.anchor = Some((rx.as_ns(), at.as_ns()));
        self.counters.syncs += 1;
        if first || !self.acquired {
            self.resync_sampling(rx);
        }
        if self.clock.is_locked() {
            self.status = Status::from_bits(self.status.bits() & !Status::CLOCK_UNLOCKED.bits())
                .unwrap_or(self.status);
        }
        Ok(())
    }

    /// Puts the next sampling instant after local time `rx` on the clock's time line: the
    /// first sampling instant k·T_cyc − lead later than now (or the one just before, if its
    /// latch is still to come). A clock that was stepped (its
    /// first frames, a restart of acquisition, a re-lock) would otherwise leave the sample
    /// counter where the old time line had it: hundreds of latches in a burst, or none for
    /// as long as the step.
    fn resync_sampling(&mut self, rx: Instant) {
        let now = self.clock.to_sync(rx).as_ns();
        let t = self.cfg.cycle.as_ns().max(1);
        let next = now
            .saturating_add(self.cfg.sample_lead.as_ns())
            .div_euclid(t)
            .saturating_add(1);
        // The instant just passed may still be due (its latch not taken yet): leave it.
        if self.k != next && self.k != next - 1 {
            self.k = next;
            self.latch = Latch::Window;
        }
    }

    /// A lumped frame outside the slave's time line, received at `rx`, reaching it at
    /// master time `at`: one more frame of a candidate new time line. True when the
    /// candidate has lasted `relock_after` and the clock re-locked to it.
    fn relock(&mut self, rx: Instant, at: Instant) -> bool {
        let (l, m) = (rx.as_ns(), at.as_ns());
        let consistent = self.candidate.is_some_and(|c| {
            let dm = m.saturating_sub(c.last_at);
            let dl = l.saturating_sub(c.last_local);
            dm > 0 && (dm - dl).abs() <= self.cfg.clock_window.as_ns()
        });
        // A frame that fits neither time line (a stray one) leaves the candidate alone, so
        // that it cannot hold off a re-lock; the candidate is dropped only when it has been
        // silent for ten cycles.
        if let Some(c) = self.candidate
            && !consistent
            && l.saturating_sub(c.last_local) <= 10 * self.cfg.cycle.as_ns()
        {
            return false;
        }
        let first = match self.candidate {
            Some(c) if consistent => c.first_local,
            _ => l,
        };
        self.candidate = Some(Candidate {
            first_local: first,
            last_local: l,
            last_at: m,
        });
        if l.saturating_sub(first) < self.cfg.relock_after.as_ns() {
            return false;
        }
        let step = self
            .master_now(rx)
            .map_or(Duration::ZERO, |e| Duration::from_ns(m.saturating_sub(e)));
        self.clock.relock(rx, at);
        self.resync_sampling(rx);
        self.candidate = None;
        self.last_lumped = None;
        self.last_command = None;
        self.counters.relocks += 1;
        self.events.push_back(SlaveEvent::Relocked { step });
        true
    }

    /// The lumped-only plan: sync, write the fresh sample, run the law on what the frame
    /// carries (this cycle's data of the slaves before, last cycle's of those after), apply
    /// and record the own command.
    fn take_lumped_only(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        frame: &mut Frame<&mut [u8]>,
    ) -> FrameOutcome {
        let me = usize::from(self.cfg.address).saturating_sub(1);
        let cycle = frame.cycle();
        let flags = Flags::from_bits(frame.flags_byte()).unwrap_or_default();
        let Ok(mut p) = LumpedPayload::new_checked(frame.payload_mut(), FrameKind::LumpedOnly)
        else {
            self.reject(Reject::Malformed);
            return FrameOutcome::Dropped;
        };
        let Some(k_me) = p.slot_index(self.cfg.address) else {
            return FrameOutcome::Forward;
        };
        if let Err(r) = self.take_sync(rx_start, cycle, p.master_time_ns()) {
            self.reject(r);
            return FrameOutcome::Forward;
        }
        // The master stopped the group: in this plan it cannot command the axes, so every
        // slave brakes on its own.
        if flags.contains(Flags::BRAKE) {
            self.begin_brake(rx_end, true);
        }
        let first = usize::from(p.first_slot());
        let now = self.clock.to_sync(rx_end);
        // A slot may not carry a sample from the future (by this slave's clock).
        let newest = now
            .as_ns()
            .saturating_add(self.cfg.clock_window.as_ns())
            .max(0) as u64;
        let mut future = 0;
        let n = self.law_slots.len();
        self.law_slots.fill(None);
        for k in 0..usize::from(p.slot_count()) {
            let a = first + k;
            if a >= n {
                break;
            }
            let slot = if a == me {
                self.sample
            } else {
                match p.slot_bytes(k).map(LumpedOnlySlot::parse) {
                    Some(Ok(s)) => s.feedback,
                    _ => continue,
                }
            };
            if slot.sample_time_ns > newest {
                future += 1;
                continue;
            }
            self.law_slots[a] = Some(slot);
        }
        let t = now.as_ns() as f64 * 1e-9;
        let Some(law) = self.law.as_mut() else {
            return FrameOutcome::Forward;
        };
        let u = law.command(me, &self.law_slots, t);
        for _ in 0..future {
            self.reject(Reject::FutureTimestamp);
        }
        if !self.status.contains(Status::FAULT) && self.drive == Drive::Enabled {
            let (u, sat) = drive_command(u, self.cfg.u_max);
            self.u = u;
            let mut st = Status::from_bits(self.status.bits() & !Status::SATURATED.bits())
                .unwrap_or(self.status);
            if sat {
                st = st.with(Status::SATURATED);
            }
            self.status = st;
            self.events.push_back(SlaveEvent::Apply { u });
            self.counters.commands += 1;
            self.cycles_without_command = 0;
        }
        if let Some(bytes) = p.slot_bytes_mut(k_me) {
            let mut mine = LumpedOnlySlot::parse(bytes).unwrap_or_default();
            mine.feedback = FeedbackSlot {
                status: self.status,
                ..self.sample
            };
            mine.command_v = self.u as f32;
            let _ = mine.emit(bytes);
        }
        frame.fill_crc();
        FrameOutcome::Forward
    }

    /// Whether a command for this slave, received (last bit) at local `rx`, may be taken.
    fn check_command(&self, cmd: &CommandRepr, rx: Instant) -> Result<CommandAction, Reject> {
        // Place it on the slave's own time line: a command belongs to the cycle in
        // progress (its slice or a retry of it); before any lumped frame there is none.
        let now = self.master_now(rx).ok_or(Reject::WrongCycle)?;
        let t = self.cfg.cycle.as_ns().max(1);
        let c = unwrap_cycle(cmd.common.cycle, now.div_euclid(t));
        let tol = self.cfg.clock_window.as_ns();
        let start = c.checked_mul(t).ok_or(Reject::Overflow)?;
        let opens = start.saturating_add(self.cfg.p2p_start.as_ns());
        if now < opens.saturating_sub(tol) || now > start.saturating_add(t).saturating_add(tol) {
            return Err(Reject::WrongCycle);
        }
        // The sample the command was computed from cannot be in the future.
        let sampled = Instant::from_wire(cmd.sample_time_ns).ok_or(Reject::Overflow)?;
        if sampled.as_ns() > now.saturating_add(tol) {
            return Err(Reject::FutureTimestamp);
        }
        match self.last_command {
            Some((last, last_retry)) => {
                let d = cmd.common.cycle.wrapping_sub(last) as i32;
                if d < 0 {
                    Err(Reject::Stale)
                } else if d == 0 && cmd.common.retry > last_retry {
                    Ok(CommandAction::Repeat)
                } else if d == 0 {
                    Err(Reject::Duplicate)
                } else {
                    Ok(CommandAction::Apply)
                }
            }
            None => Ok(CommandAction::Apply),
        }
    }

    /// The master's estimate of one link [ns] in an accepted command: the path delay
    /// becomes address × link if the slave follows the link and that stays within half
    /// the clock window of the path it was given; otherwise it is refused (counted).
    fn take_link(&mut self, link_ns: u16) {
        let path = i64::from(link_ns).checked_mul(i64::from(self.cfg.address));
        let plausible = path.filter(|p| {
            p.checked_sub(self.given_path.as_ns())
                .is_some_and(|d| d.abs() <= self.cfg.clock_window.as_ns() / 2)
        });
        match plausible {
            Some(p) if self.cfg.follow_link => {
                if p != self.cfg.path_delay.as_ns() {
                    self.cfg.path_delay = Duration::from_ns(p);
                    self.counters.link_updates += 1;
                }
            }
            _ => self.counters.links_refused += 1,
        }
    }

    fn take_command(&mut self, cmd: &CommandRepr, rx_end: Instant, action: CommandAction) {
        let flags = cmd.common.flags;
        match action {
            CommandAction::Repeat => self.counters.duplicates += 1,
            CommandAction::Apply => {
                if cmd.link_ns != 0 {
                    self.take_link(cmd.link_ns);
                }
                if flags.contains(Flags::TORQUE_OFF) && self.drive != Drive::Off {
                    self.cut_torque(TorqueOffCause::Commanded);
                }
                if flags.contains(Flags::BRAKE) {
                    self.begin_brake(rx_end, true);
                }
                if !self.status.contains(Status::FAULT) && self.drive == Drive::Enabled {
                    let (u, sat) = drive_command(f64::from(cmd.command_v), self.cfg.u_max);
                    self.u = u;
                    let mut st = self.status;
                    st = Status::from_bits(st.bits() & !Status::SATURATED.bits()).unwrap_or(st);
                    if sat {
                        st = st.with(Status::SATURATED);
                    }
                    self.status = st;
                    self.events.push_back(SlaveEvent::Apply { u });
                    self.counters.commands += 1;
                }
                if flags.contains(Flags::STOP) {
                    self.status = self.status.with(Status::STOPPING);
                }
            }
        }
        self.last_command = Some((cmd.common.cycle, cmd.common.retry));
        if !self.status.contains(Status::WATCHDOG) {
            self.cycles_without_command = 0;
        }
        self.seq = self.seq.wrapping_add(1);
        let resp = ResponseRepr {
            common: Common {
                cycle: cmd.common.cycle,
                seq: self.seq,
                retry: cmd.common.retry,
                ..Common::default()
            },
            source: self.cfg.address,
            status: self.status,
            echo_cycle: cmd.common.cycle,
            position: self.sample.position,
            velocity: self.sample.velocity,
            sample_time_ns: self.sample.sample_time_ns,
            applied_v: self.u as f32,
        };
        self.out
            .push(rx_end + self.cfg.response_delay, Pdu::Response(resp));
    }

    /// The next frame this slave originates (a response), with its send instant; `None`
    /// when there is none (call after each `handle_*` until `None`).
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        self.out.pop_bytes().map(|(tx, _)| tx)
    }

    /// The next frame this slave originates, decoded (in place of
    /// [`Slave::poll_transmit`], for a driver that carries frames without their bytes).
    #[must_use]
    pub fn poll_pdu(&mut self) -> Option<TransmitPdu> {
        self.out.pop_pdu()
    }

    /// The next frame this slave originates with its send instant (local): decoded
    /// ([`Slave::poll_pdu`]) when `decoded`, else as bytes ([`Slave::poll_transmit`]).
    #[must_use]
    pub fn poll_frame(&mut self, decoded: bool) -> Option<(Instant, WireFrame)> {
        if decoded {
            self.poll_pdu().map(|t| (t.at, WireFrame::Pdu(t.pdu)))
        } else {
            self.poll_transmit()
                .map(|t| (t.at, WireFrame::Bytes(t.bytes)))
        }
    }

    /// The next event for the driver; `None` when there is none (call after draining
    /// [`Slave::poll_transmit`]).
    #[must_use]
    pub fn poll_event(&mut self) -> Option<SlaveEvent> {
        self.events.pop_front()
    }
}

/// The command the drive applies, `u` clipped to ±`limit`, and whether the drive is
/// saturated: `u` was clipped, or it is at the limit to the wire's precision (a command the
/// master clipped arrives as the limit rounded to f32: the drive is pinned at its range all
/// the same, and the SATURATED status says so).
pub(crate) fn drive_command(u: f64, limit: f64) -> (f64, bool) {
    let (clipped, beyond) = saturate(u, limit);
    (clipped, beyond || u.abs() >= f64::from(limit as f32))
}

/// `u` clipped to ±`limit`, and whether it was clipped.
pub(crate) fn saturate(u: f64, limit: f64) -> (f64, bool) {
    if u > limit {
        (limit, true)
    } else if u < -limit {
        (-limit, true)
    } else {
        (u, false)
    }
}

fn clamp_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}
