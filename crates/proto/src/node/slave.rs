//! The slave node of the proposed plan: takes the master's timestamp from the passing lumped
//! frame (clock sync), writes its feedback into its own slot, applies its command when it
//! arrives and answers after T_ti, and goes to its safe state (0 V, FAULT | WATCHDOG) when no
//! valid command arrives for W cycles.
//!
//! Sampling: at synchronised time k·T_cyc − lead the slave latches its encoder count; the
//! velocity is the count difference over the window that ends there, so the driver is asked
//! for the count twice per cycle ([`Slave::poll_timeout`], [`Slave::handle_sample`]). The
//! paper samples at the cycle start (lead 0), which suits hardware clocks synchronised to
//! well under the lumped frame's first hop; a lead (EtherCAT's "input shift") keeps the
//! latch ahead of the frame when the clocks are only good to tens of µs (software
//! timestamps).

use std::collections::VecDeque;

use ringsync_control::{
    AxisTrajectory, ControlInput, ControlLaw, ControlOutput, Controller, Feedback, Trajectory,
    VelocitySource,
};
use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Frame, FrameKind, LumpedOnlySlot, LumpedPayload,
    ResponseRepr, SlotCodec, Status,
};

use super::Transmit;
use super::clock::SyncClock;
use crate::time::{Duration, Instant};

/// What a slave needs to run the control law itself (the lumped-only plan of ref. [3]).
pub struct LumpedOnlyControl {
    /// The law, for all n axes (the slave uses its own axis's command).
    pub law: Box<dyn ControlLaw>,
    /// Where ė comes from.
    pub velocity: VelocitySource,
    /// The desired motion of every axis (the slaves evaluate it themselves).
    pub trajectories: Vec<AxisTrajectory>,
    /// Encoder resolution of every axis [rad per count].
    pub resolution: Vec<f64>,
}

impl std::fmt::Debug for LumpedOnlyControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LumpedOnlyControl")
            .field("law", &self.law.name())
            .finish_non_exhaustive()
    }
}

/// The law, history and scratch of a slave that controls its own axis.
struct SlaveLaw {
    trajectories: Vec<AxisTrajectory>,
    resolution: Vec<f64>,
    controller: Controller<Box<dyn ControlLaw>>,
    fb: Feedback,
    input: ControlInput,
    out: ControlOutput,
    /// Sampling instant of the newest sample taken into the history, per axis [ns].
    seen: Vec<u64>,
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
    /// Drive range ±u_max [V].
    pub u_max: f64,
}

/// Something the driver must act on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlaveEvent {
    /// Apply this command to the drive [V] from now on.
    Apply {
        /// The command after clipping [V].
        u: f64,
    },
    /// The watchdog expired: the drive is at 0 V from now on.
    WatchdogExpired,
}

/// What the hardware does with a received frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameOutcome {
    /// Forward it (possibly modified) after the residence time.
    Forward,
    /// It was for this slave; it ends here.
    Consumed,
    /// Bad frame (CRC, format); dropped and counted.
    Dropped,
}

/// Counters that explain every lost cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SlaveCounters {
    /// Lumped frames taken (clock syncs).
    pub syncs: u64,
    /// Valid commands applied.
    pub commands: u64,
    /// Frames dropped for a bad CRC or format.
    pub bad_frames: u64,
    /// Commands seen again (retries of an already applied cycle).
    pub duplicates: u64,
}

/// Which encoder latch comes next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Latch {
    /// Start of the velocity window.
    Window,
    /// The sampling instant.
    Sample,
}

/// A slave.
pub struct Slave {
    cfg: SlaveConfig,
    clock: SyncClock,
    /// Index k of the next sampling instant k·T_cyc.
    k: i64,
    latch: Latch,
    window_counts: i64,
    sample: FeedbackSlot,
    u: f64,
    status: Status,
    cycles_without_command: u32,
    last_cycle_applied: Option<u32>,
    seq: u16,
    out: VecDeque<Transmit>,
    events: VecDeque<SlaveEvent>,
    counters: SlaveCounters,
    law: Option<SlaveLaw>,
    spares: super::Spares,
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
    /// A slave of the lumped-only plan: it runs `control` on the data the lumped frame
    /// carries and applies its own axis's command as the frame passes.
    pub fn with_law(cfg: SlaveConfig, control: LumpedOnlyControl) -> Self {
        let n = control.law.axes();
        let t_cyc = cfg.cycle.as_ns() as f64 * 1e-9;
        let LumpedOnlyControl {
            law,
            velocity,
            trajectories,
            resolution,
        } = control;
        let controller = Controller::new(law, velocity);
        let mut s = Slave::new(cfg);
        s.law = Some(SlaveLaw {
            trajectories,
            resolution,
            controller,
            fb: Feedback::new(n),
            input: ControlInput::new(n, t_cyc),
            out: ControlOutput::new(n),
            seen: vec![u64::MAX; n],
        });
        s
    }

    /// A slave at rest, its first sampling instant at synchronised time 0.
    pub fn new(cfg: SlaveConfig) -> Self {
        let clock = SyncClock::new(cfg.clock_sync);
        Slave {
            cfg,
            clock,
            k: 0,
            latch: Latch::Window,
            window_counts: 0,
            sample: FeedbackSlot::default(),
            u: 0.0,
            status: Status::CLOCK_UNLOCKED,
            cycles_without_command: 0,
            last_cycle_applied: None,
            seq: 0,
            out: VecDeque::new(),
            events: VecDeque::new(),
            counters: SlaveCounters::default(),
            spares: super::Spares::default(),
            law: None,
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
    /// The command applied now [V].
    pub fn command(&self) -> f64 {
        self.u
    }

    fn sample_instant(&self) -> Instant {
        Instant::from_ns(self.k * self.cfg.cycle.as_ns()) - self.cfg.sample_lead
    }

    /// Hands back the buffer of a frame the driver is done with (sent, consumed or
    /// dropped), for the slave's next sends. Optional: without it the slave allocates.
    pub fn recycle(&mut self, buf: Vec<u8>) {
        self.spares.give(buf);
    }

    /// Local time of the next encoder latch; call [`Slave::handle_sample`] then.
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
                let w = self.cfg.velocity_window.as_ns() as f64 * 1e-9;
                let velocity = (counts - self.window_counts) as f64 / w;
                let sync_now = self.clock.to_sync(now);
                self.sample = FeedbackSlot {
                    position: clamp_i32(counts),
                    velocity: clamp_i32(velocity.round() as i64),
                    sample_time_ns: sync_now.as_ns().max(0) as u64,
                    status: self.status,
                    written: true,
                };
                self.latch = Latch::Window;
                self.k += 1;
                self.tick_watchdog();
            }
        }
    }

    fn tick_watchdog(&mut self) {
        if self.status.contains(Status::WATCHDOG) {
            return;
        }
        self.cycles_without_command += 1;
        if self.cycles_without_command > self.cfg.watchdog_cycles {
            self.u = 0.0;
            self.status = self.status.with(Status::FAULT).with(Status::WATCHDOG);
            self.events.push_back(SlaveEvent::WatchdogExpired);
        }
    }

    /// A frame whose first bit arrived at local `rx_start` and last bit at `rx_end`. A lumped
    /// frame is modified in place (this slave's slot, then the CRC).
    pub fn handle_frame(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        bytes: &mut [u8],
    ) -> FrameOutcome {
        let Ok(mut frame) = Frame::new_checked(&mut bytes[..]) else {
            self.counters.bad_frames += 1;
            return FrameOutcome::Dropped;
        };
        let kind = match frame.check() {
            Ok(k) => k,
            Err(_) => {
                self.counters.bad_frames += 1;
                return FrameOutcome::Dropped;
            }
        };
        match kind {
            FrameKind::Lumped => {
                let Ok(mut p) = LumpedPayload::new_checked(frame.payload_mut(), kind) else {
                    self.counters.bad_frames += 1;
                    return FrameOutcome::Dropped;
                };
                let sent = Instant::from_ns(p.master_time_ns() as i64);
                if let Some(k) = p.slot_index(self.cfg.address) {
                    self.clock.sync(rx_start, sent, self.cfg.path_delay);
                    self.counters.syncs += 1;
                    if self.clock.is_locked() {
                        self.status =
                            Status::from_bits(self.status.bits() & !Status::CLOCK_UNLOCKED.bits())
                                .unwrap_or(self.status);
                    }
                    if let Some(slot) = p.slot_bytes_mut(k) {
                        // Infallible for a feedback slot of the right length.
                        let _ = self.sample.emit(slot);
                    }
                    frame.fill_crc();
                }
                FrameOutcome::Forward
            }
            FrameKind::Command => {
                let Ok(cmd) = CommandRepr::parse_verified(bytes) else {
                    self.counters.bad_frames += 1;
                    return FrameOutcome::Dropped;
                };
                if cmd.target != self.cfg.address {
                    return FrameOutcome::Forward;
                }
                self.take_command(&cmd, rx_end);
                FrameOutcome::Consumed
            }
            FrameKind::LumpedOnly if self.law.is_some() => {
                self.take_lumped_only(rx_start, rx_end, &mut frame);
                FrameOutcome::Forward
            }
            FrameKind::Response | FrameKind::LumpedOnly => FrameOutcome::Forward,
        }
    }

    /// The lumped-only plan: sync, write the fresh sample, run the law on what the frame
    /// carries (this cycle's data of the slaves before, last cycle's of those after), apply
    /// and record the own command.
    fn take_lumped_only(
        &mut self,
        rx_start: Instant,
        rx_end: Instant,
        frame: &mut Frame<&mut [u8]>,
    ) {
        let me = usize::from(self.cfg.address) - 1;
        let Ok(mut p) = LumpedPayload::new_checked(frame.payload_mut(), FrameKind::LumpedOnly)
        else {
            self.counters.bad_frames += 1;
            return;
        };
        let Some(k_me) = p.slot_index(self.cfg.address) else {
            return;
        };
        let sent = Instant::from_ns(p.master_time_ns() as i64);
        self.clock.sync(rx_start, sent, self.cfg.path_delay);
        self.counters.syncs += 1;
        if self.clock.is_locked() {
            self.status = Status::from_bits(self.status.bits() & !Status::CLOCK_UNLOCKED.bits())
                .unwrap_or(self.status);
        }
        let first = usize::from(p.first_slot());
        let now = self.clock.to_sync(rx_end);
        let Some(law) = self.law.as_mut() else { return };
        let n = law.seen.len();
        for a in 0..n {
            law.fb.fresh[a] = false;
        }
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
            if slot.sample_time_ns == law.seen[a]
                || slot.sample_time_ns == 0 && law.seen[a] != u64::MAX
            {
                continue;
            }
            let ts = slot.sample_time_ns as f64 * 1e-9;
            let res = law.resolution[a];
            law.fb.position[a] = f64::from(slot.position) * res;
            law.fb.velocity[a] = f64::from(slot.velocity) * res;
            law.fb.sample_time[a] = ts;
            law.fb.desired[a] = law.trajectories[a].at(ts);
            law.fb.fresh[a] = true;
            law.seen[a] = slot.sample_time_ns;
        }
        let t = now.as_ns() as f64 * 1e-9;
        for a in 0..n {
            law.input.apply_time[a] = t;
            law.input.desired[a] = law.trajectories[a].at(t);
        }
        let u = if law
            .controller
            .update(&law.fb, &law.input, &mut law.out)
            .is_ok()
        {
            law.out.u[me]
        } else {
            0.0
        };
        if !self.status.contains(Status::FAULT) {
            let (u, sat) = ringsync_plant::saturate(u, self.cfg.u_max);
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
    }

    fn take_command(&mut self, cmd: &CommandRepr, rx_end: Instant) {
        if self.last_cycle_applied == Some(cmd.common.cycle) {
            self.counters.duplicates += 1;
        } else if !self.status.contains(Status::FAULT) {
            let (u, sat) = ringsync_plant::saturate(f64::from(cmd.command_v), self.cfg.u_max);
            self.u = u;
            let mut st = self.status;
            st = Status::from_bits(st.bits() & !Status::SATURATED.bits()).unwrap_or(st);
            if sat {
                st = st.with(Status::SATURATED);
            }
            if cmd.common.flags.contains(ringsync_wire::Flags::STOP) {
                st = st.with(Status::STOPPING);
            }
            self.status = st;
            self.events.push_back(SlaveEvent::Apply { u });
            self.counters.commands += 1;
        }
        self.last_cycle_applied = Some(cmd.common.cycle);
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
        let mut buf = self.spares.take(resp.buffer_len());
        if resp.emit(&mut buf).is_ok() {
            self.out.push_back(Transmit {
                at: rx_end + self.cfg.response_delay,
                bytes: buf,
            });
        }
    }

    /// The next frame this slave originates (responses).
    pub fn poll_transmit(&mut self) -> Option<Transmit> {
        self.out.pop_front()
    }

    /// The next event for the driver.
    pub fn poll_event(&mut self) -> Option<SlaveEvent> {
        self.events.pop_front()
    }
}

fn clamp_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}
