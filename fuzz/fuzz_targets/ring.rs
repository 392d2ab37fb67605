//! The whole ring on a hostile wire: a [`Testbed`] (master and 4 slaves, W = 5, brake, limit
//! 1 rad; the master runs `ringsync-model`'s `ControlMotion`, PD on the testbed's cosine with
//! the group stop's ramps and its brake and torque-off orders) driven through an arbitrary
//! sequence of operations: run for up to 20 ms (300 ms in
//! all, then a tail of W + 3 cycles); inject a sealed forged frame in front of any node
//! (commands and responses with any header and payload fields, lumped frames with any cycle,
//! sequence, stamp, first slot and slot count, raw sealed bytes); set tap rules that drop,
//! duplicate or delay (and so reorder) the next real frames of a kind on their way to a node;
//! kill one slave. The master stays alive.
//!
//! # Invariants (each a panic, so the fuzzer reports it)
//! - No panic anywhere (overflow checks are on in fuzz builds).
//! - Every frame leaving the master parses, and its commands are finite and within ±10 V.
//! - Every `Apply` and `Brake` is finite and within ±10 V; no `Apply` after the slave's
//!   `TorqueOff` or `WatchdogExpired`, nor while it brakes. Each slave's status agrees with
//!   its events (TORQUE_OFF, BRAKING, FAULT), CLOCK_UNLOCKED with its clock, its clock's
//!   rate stays within 1000 ppm of 1 and its last lumped cycle on the wire's time line
//!   (at most `Instant::HORIZON`/T: a stamp past the horizon never moved it).
//! - Every command a slave applied (`Testbed::applied`, time t, slave i, u) is a command frame
//!   addressed to slave i that reached it at exactly t (the master's, recorded as the tap saw
//!   it leave the master, or one the fuzzer injected), with u = its value clipped to ±10 V,
//!   and whose cycle c is the cycle in progress: the slave's synchronised time S at t lies in
//!   [c·T + p2p_start − w, (c + 1)·T + w] (w = `clock_window`, the window `check_command`
//!   allows; no command before the cycle's P2P phase). S is read from a copy of the slave's
//!   clock taken at the check before t or at the one after it (the checks run once a cycle,
//!   at k·T + 700 µs, after the cycle's lumped frame and commands): the earlier copy when no
//!   lumped frame reached the slave between that check and t, the later one when none
//!   reached it between t and the later check, either copy when frames reached it only at t
//!   (their order against the command is not known). When frames reached it on both sides of
//!   t and it took some, it used a clock between the two copies, which the harness does not
//!   have: the window is not checked for that command (its value, address and cycle order
//!   are); this hides, never invents, a violation. A copy of a slave that had taken no lumped
//!   frame yet is no copy: such a slave has no time line and takes no command. (Before its clock
//!   locks, the slave places a command by its last frame plus the local time since; its
//!   clock reads the same then, because the rate is first measured by the frame that locks
//!   it.) In true time the window does not hold: the slaves synchronise one way, so a path
//!   delay the configuration does not know shifts a slave's whole time line (docs/fuzzing.md
//!   has the counterexample). With `RINGSYNC_FUZZ_TRUE_TIME=1` the true-time window is
//!   asserted as well (exploration mode: it fails).
//! - A slave applies commands in strictly increasing cycles (so never twice for one cycle),
//!   until its clock re-locks to a new master time line or restarts its acquisition (which
//!   begins a new time line, and, since F4's fix, forgets the last command): either resets
//!   that history. A restart shows only in the slave's counter, not as an event: when one
//!   came between two checks, the history is reset at every command after a lumped frame
//!   that reached the slave in that interval (this hides, never invents, a violation).
//! - The master's orders are obeyed: each response a slave sends (seen as it leaves the
//!   slave) answers a command that reached it `response_delay` before; if it took that
//!   command as new (not a repeat of the cycle's earlier try) and the command is the
//!   master's, its orders show in the response's status (TORQUE_OFF; BRAKE as BRAKING or
//!   TORQUE_OFF; STOP as STOPPING) and in the slave's status from then on (checked at every
//!   check, so within a cycle).
//! - `CommandMismatch`: the master's `command_mismatches` grows between two checks by no more
//!   than the responses that reached it in between and would mismatch (echo and cycle agree,
//!   status not FAULT, and either BRAKING or TORQUE_OFF for an axis the master had not
//!   ordered, or an applied command not the master's command of that cycle to that axis,
//!   clipped if SATURATED). Such a response is either a forgery (the wire has no
//!   authentication: a forged response can claim anything, and stopping on it is the safe
//!   answer) or comes from a slave that really applied, in that cycle, a command the master
//!   did not send (an injected one, invariant above), or that really brakes or is off by an
//!   order no command of the master's carried (a forged order). A stop for a mismatch names
//!   such a response. The count is a bound, not an equality: the ring does not see which
//!   responses the master took (the `master` target checks that exactly). Once the master
//!   has counted a mismatch, its next law run comes with the group stop.
//! - An axis whose true error |x^d − x| exceeds the limit plus 0.1 rad is, within W + 2
//!   cycles, either stopping (`Master::is_stopping`) or its slave is in its safe state
//!   (status FAULT, BRAKING or TORQUE_OFF).
//! - A forged order is noticed (F5, fixed in 02bbcce): a drive that is off or braking
//!   (status TORQUE_OFF or BRAKING) without its own watchdog (no FAULT) while the master is
//!   not stopping was stopped by an order the master did not give (it orders only during a
//!   stop); within W + 2 cycles the master stops the group (by the next law run after it
//!   takes the slave's response showing it, or by the response watchdog if none comes).
//!
//! # Out of scope
//! The wire has no authentication: a CRC says the bytes are intact, not who sent them. A
//! forged frame whose *data* is bit-identical to the truth (a lumped frame whose slots are
//! copied from the real one, with only time, cycle and sequence lied about) cannot be told
//! from the real one, and neither can a forged command for the cycle in progress that reaches
//! its slave in the P2P phase before the master's: the slave takes it (and then refuses the
//! master's as a duplicate); the master sees the mismatch in the response and stops. A
//! forged order (BRAKE, TORQUE_OFF) is taken the same way and caught the same way. Forged
//! lumped frames here always carry slots copied from the last real lumped frame the tap saw,
//! and a forged command applied inside its cycle window counts as sent.
#![no_main]

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::rc::Rc;
use std::sync::OnceLock;

use libfuzzer_sys::arbitrary::{self, Arbitrary, Unstructured};
use libfuzzer_sys::fuzz_target;
use ringsync_control::{AxisTrajectory, Cosine, Gains, Pd, VelocitySource};
use ringsync_model::motion::{ControlMotion, StopSettings};
use ringsync_proto::Duration;
use ringsync_proto::node::clock::MAX_RATE_ERROR;
use ringsync_proto::node::reject::unwrap_cycle;
use ringsync_proto::node::testbed::{Fate, Hop, RESOLUTION, Testbed, TestbedConfig};
use ringsync_proto::node::{MasterEvent, SlaveEvent, StopReason, SyncClock, TorqueOffCause};
use ringsync_wire::{CommandRepr, Flags, Pdu, ResponseRepr, Status};

#[path = "forge.rs"]
mod forge;
#[path = "seal.rs"]
mod seal;

use forge::{CYCLE_NS as T, CycleSel, Head, Resp, When};

/// Drive range [V].
const U_MAX: f64 = 10.0;
/// The checks run once a cycle at this offset into it (after the lumped frame and the
/// commands of an undisturbed cycle) [ns].
const CHECK_AT: i64 = 700_000;
/// Longest single run [ns].
const MAX_RUN: i64 = 20 * T;
/// Longest input, before the tail [ns].
const TOTAL: i64 = 300 * T;
/// Margin on the following-error limit for the true error [rad].
const FE_MARGIN: f64 = 0.1;
/// Largest delay the tap or an injection adds [ns].
const MAX_DELAY: u32 = 3_000_000;
/// At most this many tap rules are active at once.
const MAX_RULES: usize = 8;
/// How long records of frames are kept after their time [ns] (a response leaves its slave
/// a few µs after the command it answers, maybe after the check).
const KEEP: i64 = 3 * T;

#[derive(Arbitrary, Debug)]
enum Op {
    /// Run the ring for `us` µs (at most 20 ms).
    Run { us: u16 },
    /// Put a forged frame in front of node `to % 5` (0 = master), `after_us` µs from now.
    Inject {
        to: u8,
        after_us: u16,
        frame: Forgery,
    },
    /// Add a tap rule for the next real frames.
    Tap(Rule),
    /// Slave `1 + slave % 4` dies (at most one slave; the master stays alive).
    Kill { slave: u8 },
}

#[derive(Arbitrary, Debug)]
enum Forgery {
    /// A command frame; cycle relative to the cycle in progress, sample time to now.
    Command {
        head: Head,
        target: u8,
        value: f32,
        sample: When,
    },
    /// A response frame.
    Response { head: Head, resp: Resp },
    /// A lumped frame built from the last real one the tap saw (its slots copied), with any
    /// of its header fields replaced.
    Lumped {
        cycle: Option<CycleSel>,
        seq: Option<u16>,
        stamp: Option<When>,
        first: Option<u16>,
        count: Option<u8>,
        flags: u8,
    },
    /// Any bytes, sealed (CRC fixed where the header's length puts it).
    Raw(Vec<u8>),
}

#[derive(Arbitrary, Debug, Clone, Copy)]
struct Rule {
    kind: KindSel,
    /// Node `to % 6` (5: any node).
    to: u8,
    fate: FateSel,
    /// The rule applies to this many frames (at least 1).
    count: u8,
}

#[derive(Arbitrary, Debug, Clone, Copy, PartialEq)]
enum KindSel {
    Any,
    Lumped,
    Command,
    Response,
}

#[derive(Arbitrary, Debug, Clone, Copy)]
enum FateSel {
    Drop,
    Duplicate { after_ns: u32 },
    Delay { by_ns: u32 },
}

impl Rule {
    fn matches(&self, hop: &Hop, kind: Option<u8>) -> bool {
        let to = usize::from(self.to % 6);
        let kind_ok = match self.kind {
            KindSel::Any => true,
            KindSel::Lumped => kind == Some(1),
            KindSel::Command => kind == Some(2),
            KindSel::Response => kind == Some(3),
        };
        kind_ok && (to == 5 || to == hop.to)
    }

    fn fate(&self) -> Fate {
        match self.fate {
            FateSel::Drop => Fate::Drop,
            FateSel::Duplicate { after_ns } => Fate::Duplicate {
                after: i64::from(after_ns % MAX_DELAY),
            },
            FateSel::Delay { by_ns } => Fate::Delay {
                by: i64::from(by_ns % MAX_DELAY),
            },
        }
    }
}

/// A command frame reaching slave `slave` (addressed to it).
#[derive(Debug, Clone, Copy)]
struct Delivery {
    cycle: u32,
    retry: u8,
    flags: Flags,
    value: f32,
    from_master: bool,
}

/// A response reaching the master at `at`; `forged`: bytes the fuzzer injected.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    at: i64,
    resp: ResponseRepr,
    forged: bool,
}

/// What the tap and the injections record, shared with the tap closure.
#[derive(Default)]
struct Shared {
    rules: Vec<(Rule, u8)>,
    /// The last real lumped frame the tap saw.
    last_lumped: Option<Vec<u8>>,
    /// Every command frame the master sent (its bytes), and its value per (cycle, target).
    master_commands: HashSet<Vec<u8>>,
    master_values: HashMap<(u32, u16), f32>,
    /// Every frame the fuzzer injected (its bytes).
    injected: HashSet<Vec<u8>>,
    /// Commands to slave i (addressed to it) reaching it at time t: key (i, t).
    deliveries: HashMap<(usize, i64), Vec<Delivery>>,
    /// Times at which lumped frames reach each slave (index i − 1), since the last check.
    lumped_at: Vec<Vec<i64>>,
    /// Responses reaching the master, not yet checked.
    at_master: Vec<Arrival>,
    /// Responses as they leave the slave that sent them: (time, slave, response).
    own: Vec<(i64, usize, ResponseRepr)>,
}

impl Shared {
    fn deliver(&mut self, slave: usize, at: i64, bytes: &[u8]) {
        if let Ok(c) = CommandRepr::parse(bytes)
            && usize::from(c.target) == slave
        {
            let from_master = self.master_commands.contains(bytes);
            self.deliveries
                .entry((slave, at))
                .or_default()
                .push(Delivery {
                    cycle: c.common.cycle,
                    retry: c.common.retry,
                    flags: c.common.flags,
                    value: c.command_v,
                    from_master,
                });
        }
    }

    fn lumped_to(&mut self, slave: usize, at: i64) {
        if let Some(v) = self.lumped_at.get_mut(slave.wrapping_sub(1)) {
            v.push(at);
        }
    }

    fn response_to_master(&mut self, at: i64, bytes: &[u8]) {
        if let Ok(resp) = ResponseRepr::parse(bytes) {
            let forged = self.injected.contains(bytes);
            self.at_master.push(Arrival { at, resp, forged });
        }
    }

    fn tap(&mut self, hop: &Hop, b: &[u8]) -> Fate {
        let kind = b.get(1).copied();
        if hop.from == 0 {
            let pdu = Pdu::parse(b)
                .unwrap_or_else(|e| panic!("a frame leaving the master does not parse: {e:?}"));
            if let Pdu::Command(c) = pdu {
                assert!(
                    c.command_v.is_finite() && f64::from(c.command_v).abs() <= U_MAX,
                    "the master sent {c:?}"
                );
                self.master_commands.insert(b.to_vec());
                self.master_values
                    .insert((c.common.cycle, c.target), c.command_v);
            }
        }
        if kind == Some(1) {
            self.last_lumped = Some(b.to_vec());
        }
        // A slave's own response, as it leaves it (not one it forwards).
        if kind == Some(3)
            && hop.from != 0
            && !self.injected.contains(b)
            && let Ok(r) = ResponseRepr::parse(b)
            && usize::from(r.source) == hop.from
        {
            self.own.push((hop.at, hop.from, r));
        }
        let mut fate = Fate::Deliver;
        if let Some(k) = self.rules.iter().position(|(r, _)| r.matches(hop, kind)) {
            fate = self.rules[k].0.fate();
            self.rules[k].1 -= 1;
            if self.rules[k].1 == 0 {
                self.rules.remove(k);
            }
        }
        let times = match fate {
            Fate::Deliver => [Some(hop.at), None],
            Fate::Drop => [None, None],
            Fate::Duplicate { after } => [Some(hop.at), Some(hop.at + after.max(0))],
            Fate::Delay { by } => [Some(hop.at + by.max(0)), None],
        };
        for at in times.into_iter().flatten() {
            match kind {
                Some(1) => self.lumped_to(hop.to, at),
                Some(2) if hop.to != 0 => self.deliver(hop.to, at, b),
                Some(3) if hop.to == 0 => self.response_to_master(at, b),
                _ => {}
            }
        }
        fate
    }
}

/// A slave's clock and the lumped frames it had taken, at a step boundary.
#[derive(Clone)]
struct ClockAt {
    clock: SyncClock,
    syncs: u64,
    /// `acquisitions_restarted`.
    restarts: u64,
}

fn true_time_mode() -> bool {
    static MODE: OnceLock<bool> = OnceLock::new();
    *MODE.get_or_init(|| std::env::var_os("RINGSYNC_FUZZ_TRUE_TIME").is_some())
}

/// Whether a command of wire cycle `cycle` is in its cycle window at synchronised time `s`:
/// [c·T + p2p − w, (c + 1)·T + w].
fn in_window(s: i64, cycle: u32, p2p: i64, w: i64) -> bool {
    let c = unwrap_cycle(cycle, s.div_euclid(T));
    let start = c.saturating_mul(T);
    s >= start.saturating_add(p2p).saturating_sub(w)
        && s <= start.saturating_add(T).saturating_add(w)
}

/// Whether a response's applied command agrees with the master's `sent` (the master's
/// rule: equal, or clipped towards zero with the same sign when it says SATURATED).
fn agrees(r: &ResponseRepr, sent: f32) -> bool {
    let applied = r.applied_v;
    if r.status.contains(Status::SATURATED) {
        applied.abs() <= sent.abs() && applied * sent > 0.0
    } else {
        applied == sent
    }
}

/// A slave's drive, as its events tell.
#[derive(Debug, Clone, Copy, Default)]
struct Drive {
    braking: bool,
    off: bool,
    watchdog: bool,
    /// The last command it took (answered): cycle, retry, time; and its last re-lock.
    last_take: Option<(u32, u8, i64)>,
    relocked_at: Option<i64>,
    /// Status bits it must show from now on (orders it took).
    must: u16,
    /// It began to brake, or cut torque, on an order that no command of the master's
    /// carried (`Braking { ordered: true }` or `TorqueOff { cause: Commanded }` from a frame
    /// with no master command with that flag reaching it then): a forged order.
    unordered: bool,
}

struct Harness {
    ring: Testbed,
    shared: Rc<RefCell<Shared>>,
    /// Per slave: its clock at the last check, and when that was.
    clocks: Vec<ClockAt>,
    checked_at: i64,
    /// Checked so far: entries of `applied`, `slave_events` and `master_events`.
    applied_seen: usize,
    events_seen: usize,
    master_seen: usize,
    /// Per slave: the last cycle applied since its last re-lock.
    last_cycle: Vec<Option<u32>>,
    /// Per slave and wire cycle: the commands it applied (f32 bits, the master's).
    applied_by: HashMap<(usize, u32), Vec<(u32, bool)>>,
    drives: Vec<Drive>,
    /// Responses that reached the master and would mismatch: (time, axis, applied bits,
    /// master's command bits if known).
    mismatching: Vec<(i64, usize, u32, Option<u32>)>,
    mismatches: u64,
    /// Per axis: since when its true error has been over the limit, without a stop.
    over_since: Vec<Option<i64>>,
    /// Per axis: since when its drive has been off or braking by an order the master did
    /// not give (status TORQUE_OFF or BRAKING without FAULT), without a stop.
    unordered_since: Vec<Option<i64>>,
    /// Per axis (0-based): when the master first gave it an order (`MasterEvent::Order`).
    ordered_at: Vec<Option<i64>>,
    /// When the group stop began.
    stopped_at: Option<i64>,
    /// The check at which the master was first seen to have counted a mismatch: its next
    /// law run (any `Computed` after it) comes with the group stop.
    mismatch_due: Option<i64>,
    window: i64,
    p2p: i64,
    response_delay: i64,
    hop: i64,
    limit: f64,
    w: i64,
}

impl Harness {
    fn new() -> Self {
        let cfg = TestbedConfig::default();
        let limit = cfg.following_error_limit;
        let w = i64::from(cfg.watchdog_cycles);
        let hop = cfg.hop_ns;
        let n = cfg.slaves as usize;
        // The master runs the motion the simulator and the runtime run (`ringsync-model`):
        // PD on the testbed's cosine, the group stop's ramps and its brake and torque-off
        // orders (the testbed's own `PdMotion` gives no orders).
        let law = Pd::new(Gains::uniform(n, 3.182, 1.591, 0.0), false)
            .unwrap_or_else(|e| panic!("law: {e}"));
        let traj = Cosine::with_peak_speed(cfg.peak_speed, 2.0)
            .unwrap_or_else(|e| panic!("trajectory: {e}"));
        let motion = ControlMotion::new(
            Box::new(law),
            VelocitySource::Reported,
            vec![AxisTrajectory::Cosine(traj); n],
            vec![RESOLUTION; n],
            Duration::from_ns(T),
            StopSettings {
                following_error_limit: limit,
                ..StopSettings::default()
            },
        );
        let mut ring = Testbed::with_motion(cfg, Box::new(motion));
        let n = ring.slaves.len();
        let shared = Rc::new(RefCell::new(Shared {
            lumped_at: vec![Vec::new(); n],
            ..Shared::default()
        }));
        let tap = shared.clone();
        ring.tap = Some(Box::new(move |hop: &Hop, b: &mut Vec<u8>| {
            tap.borrow_mut().tap(hop, b)
        }));
        let sc = ring.slaves[0].config();
        let (window, p2p, response_delay) = (
            sc.clock_window.as_ns(),
            sc.p2p_start.as_ns(),
            sc.response_delay.as_ns(),
        );
        let clocks = ring
            .slaves
            .iter()
            .map(|s| ClockAt {
                clock: s.clock().clone(),
                syncs: s.counters().syncs,
                restarts: s.counters().acquisitions_restarted,
            })
            .collect();
        Harness {
            ring,
            shared,
            clocks,
            checked_at: 0,
            applied_seen: 0,
            events_seen: 0,
            master_seen: 0,
            last_cycle: vec![None; n],
            applied_by: HashMap::new(),
            drives: vec![Drive::default(); n],
            mismatching: Vec::new(),
            mismatches: 0,
            over_since: vec![None; n],
            unordered_since: vec![None; n],
            ordered_at: vec![None; n],
            stopped_at: None,
            mismatch_due: None,
            window,
            p2p,
            response_delay,
            hop,
            limit,
            w,
        }
    }

    /// Runs to `until`, checking at every k·T + [`CHECK_AT`] on the way and at `until`.
    fn run_to(&mut self, until: i64) {
        while self.ring.now() < until {
            let now = self.ring.now();
            let next = ((now - CHECK_AT).div_euclid(T) + 1) * T + CHECK_AT;
            let next = next.min(until);
            self.ring.run_until(next);
            self.check();
        }
    }

    fn inject(&mut self, to: u8, after_us: u16, frame: &Forgery) {
        let now = self.ring.now();
        let to = usize::from(to % 5);
        let at = now + (i64::from(after_us) * 1_000).min(i64::from(MAX_DELAY));
        let cycle = now.div_euclid(T);
        let bytes = match frame {
            Forgery::Command {
                head,
                target,
                value,
                sample,
            } => forge::command(
                head,
                cycle,
                forge::address(*target),
                *value,
                sample.resolve(now),
            ),
            Forgery::Response { head, resp } => forge::response(head, resp, cycle, now),
            Forgery::Lumped {
                cycle: c,
                seq,
                stamp,
                first,
                count,
                flags,
            } => {
                let sh = self.shared.borrow();
                let base = sh.last_lumped.as_deref();
                // The real frame's fields and slots, or an empty frame for 4 slaves.
                let (b_cycle, b_seq, b_stamp, b_first, slots): (u32, u16, u64, u16, Vec<u8>) =
                    match base {
                        Some(b) if b.len() >= 28 => {
                            let n = usize::from(u16::from_le_bytes([b[22], b[23]]));
                            let end = (24 + n * 20).min(b.len() - 4);
                            (
                                u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
                                u16::from_le_bytes([b[8], b[9]]),
                                u64::from_le_bytes(b[12..20].try_into().unwrap_or([0; 8])),
                                u16::from_le_bytes([b[20], b[21]]),
                                b[24..end].to_vec(),
                            )
                        }
                        _ => (cycle as u32, 0, (cycle * T) as u64, 0, vec![0; 80]),
                    };
                let avail = slots.len() / 20;
                let count = count.map_or(avail, |c| usize::from(c % 16));
                // Slots copied from the real frame, repeated if the forger claims more.
                let mut data = Vec::with_capacity(count * 20);
                for k in 0..count {
                    if avail == 0 {
                        data.extend_from_slice(&[0; 20]);
                    } else {
                        let j = k % avail;
                        data.extend_from_slice(&slots[j * 20..j * 20 + 20]);
                    }
                }
                forge::lumped(
                    1,
                    *flags,
                    0,
                    c.map_or(b_cycle, |c| c.resolve(cycle)),
                    seq.unwrap_or(b_seq),
                    stamp.map_or(b_stamp, |s| s.resolve(now)),
                    first.unwrap_or(b_first),
                    count as u16,
                    &data,
                )
            }
            Forgery::Raw(raw) => match seal::sealed(raw) {
                Some(b) => b,
                None => raw.clone(),
            },
        };
        {
            let mut sh = self.shared.borrow_mut();
            sh.injected.insert(bytes.clone());
            if to == 0 {
                sh.response_to_master(at, &bytes);
            } else {
                sh.deliver(to, at, &bytes);
                if bytes.get(1) == Some(&1) {
                    sh.lumped_to(to, at);
                }
            }
        }
        self.ring.inject(to, at, bytes);
    }

    fn check(&mut self) {
        let now = self.ring.now();
        let n = self.ring.slaves.len();
        // Events: the drive range, the drive's state; re-locks reset a slave's history.
        let mut relocked: Vec<Option<i64>> = vec![None; n];
        let shared = self.shared.borrow();
        // Whether a command of the master's carrying `flag` reached slave i at t.
        let master_order = |i: usize, t: i64, flag: Flags| {
            shared.deliveries.get(&(i, t)).is_some_and(|v| {
                v.iter()
                    .any(|c| c.from_master && c.flags.bits() & flag.bits() != 0)
            })
        };
        for &(t, i, ev) in &self.ring.slave_events[self.events_seen..] {
            let d = &mut self.drives[i - 1];
            match ev {
                SlaveEvent::Apply { u } => {
                    assert!(
                        u.is_finite() && u.abs() <= U_MAX,
                        "slave {i}: {ev:?} at {t}"
                    );
                    assert!(
                        !d.braking && !d.off && !d.watchdog,
                        "slave {i}: {ev:?} at {t} ns, drive {d:?}"
                    );
                }
                SlaveEvent::Brake { u } => {
                    assert!(
                        u.is_finite() && u.abs() <= U_MAX,
                        "slave {i}: {ev:?} at {t}"
                    );
                    assert!(d.braking && !d.off, "slave {i}: {ev:?} at {t}, drive {d:?}");
                }
                SlaveEvent::Braking { ordered } => {
                    assert!(
                        !d.braking && !d.off,
                        "slave {i}: {ev:?} at {t}, drive {d:?}"
                    );
                    d.braking = true;
                    if ordered && !master_order(i, t, Flags::BRAKE) {
                        d.unordered = true;
                    }
                }
                SlaveEvent::TorqueOff { cause } => {
                    assert!(!d.off, "slave {i}: {ev:?} at {t}, drive {d:?}");
                    d.off = true;
                    d.braking = false;
                    if cause == TorqueOffCause::Commanded && !master_order(i, t, Flags::TORQUE_OFF)
                    {
                        d.unordered = true;
                    }
                }
                SlaveEvent::WatchdogExpired => {
                    assert!(!d.watchdog, "slave {i}: {ev:?} at {t} twice");
                    d.watchdog = true;
                }
                SlaveEvent::Relocked { .. } => {
                    relocked[i - 1] = Some(t);
                    d.relocked_at = Some(t);
                }
                // The testbed's slaves start running (`Slave::new`): they have no start-up
                // phase to end, whatever delay frame the wire forges.
                SlaveEvent::Calibrated { .. } => {
                    panic!("slave {i}: {ev:?} at {t} ns without a start-up phase")
                }
            }
        }
        drop(shared);
        self.events_seen = self.ring.slave_events.len();
        self.check_applied(now, &mut relocked);
        self.check_orders();
        self.check_mismatches(now);
        // Each slave's status and clock.
        for (k, s) in self.ring.slaves.iter().enumerate() {
            let (st, d) = (s.status(), &self.drives[k]);
            let i = k + 1;
            assert_eq!(st.contains(Status::TORQUE_OFF), d.off, "slave {i}: {st:?}");
            assert_eq!(
                st.contains(Status::BRAKING),
                d.braking && !d.off,
                "slave {i}: {st:?}"
            );
            assert_eq!(st.contains(Status::FAULT), d.watchdog, "slave {i}: {st:?}");
            assert_eq!(
                st.contains(Status::CLOCK_UNLOCKED),
                !s.clock().is_locked(),
                "slave {i}: {st:?}"
            );
            assert!(
                st.bits() & d.must != 0 || d.must == 0,
                "slave {i}: status {st:?}, orders taken demand {:#x}",
                d.must
            );
            let rate = s.clock().rate();
            assert!(
                (rate - 1.0).abs() <= MAX_RATE_ERROR * (1.0 + 1e-9),
                "slave {i}: clock rate {rate}"
            );
            if let Some(c) = s.last_lumped_cycle() {
                assert!(
                    (-1..=forge::HORIZON_NS / T).contains(&c),
                    "slave {i}: last lumped cycle {c}"
                );
            }
        }
        self.checked_at = now;
        // Following error: a stop or the slave's safe state within W + 2 cycles.
        let ring = &self.ring;
        let safe = Status::FAULT.bits() | Status::BRAKING.bits() | Status::TORQUE_OFF.bits();
        for a in 0..ring.axes.len() {
            let err = (ring.desired(a + 1, now) - ring.axes[a].x).abs();
            let stopped = ring.master.is_stopping() || ring.slaves[a].status().bits() & safe != 0;
            if err <= self.limit + FE_MARGIN || stopped {
                self.over_since[a] = None;
                continue;
            }
            let since = *self.over_since[a].get_or_insert(now);
            assert!(
                now - since <= (self.w + 2) * T,
                "axis {} off its path by {err} rad since {since} ns, no stop at {now} ns \
                 (status {:?})",
                a + 1,
                ring.slaves[a].status()
            );
        }
        // F5 (fixed in 02bbcce): a drive off or braking (not by its own watchdog: no FAULT)
        // while the master is not stopping was stopped by an order the master did not give
        // (it orders only during a stop). The master notices: the slave's next response
        // shows it (a mismatch, the group stops at the next law run), or no response comes
        // (the response watchdog). Within W + 2 cycles the master stops the group.
        for a in 0..ring.axes.len() {
            let st = ring.slaves[a].status();
            let off = st.contains(Status::TORQUE_OFF) || st.contains(Status::BRAKING);
            if !off || st.contains(Status::FAULT) || ring.master.is_stopping() {
                self.unordered_since[a] = None;
                continue;
            }
            let since = *self.unordered_since[a].get_or_insert(now);
            assert!(
                now - since <= (self.w + 2) * T,
                "slave {} stopped by an order the master did not give (status {st:?}) \
                 since {since} ns, no group stop at {now} ns (F5)",
                a + 1
            );
        }
    }

    /// Every command applied: on the wire for that slave at that time, in its window.
    fn check_applied(&mut self, now: i64, relocked: &mut [Option<i64>]) {
        let ring = &self.ring;
        let end: Vec<ClockAt> = ring
            .slaves
            .iter()
            .map(|s| ClockAt {
                clock: s.clock().clone(),
                syncs: s.counters().syncs,
                restarts: s.counters().acquisitions_restarted,
            })
            .collect();
        let shared = self.shared.borrow();
        // Per slave: the time of its last command applied in this step (or the last check).
        let mut prev = vec![self.checked_at; ring.slaves.len()];
        for &(t, i, u) in &ring.applied[self.applied_seen..] {
            if relocked[i - 1].is_some_and(|r| r <= t) {
                relocked[i - 1] = None;
                self.last_cycle[i - 1] = None;
            }
            let local = ring.local(i, t);
            let start = &self.clocks[i - 1];
            let stop = &end[i - 1];
            // Which copy of the clock the slave used at t (see the module doc): `None` when
            // it took lumped frames on both sides of t, and used a state between the copies.
            let ls = &shared.lumped_at[i - 1];
            // An acquisition restart begins a new time line, whose cycles are new (and the
            // slave forgets the last command: F4's fix). It happened on a lumped frame; if the
            // slave restarted in this step and a lumped frame reached it since its last
            // command (at the same instant included), the history may have been reset.
            if stop.restarts != start.restarts && ls.iter().any(|&x| x >= prev[i - 1] && x <= t) {
                self.last_cycle[i - 1] = None;
            }
            prev[i - 1] = t;
            let before = ls.iter().any(|&x| x > self.checked_at && x < t);
            let after = ls.iter().any(|&x| x > t && x <= now);
            let at_t = ls.contains(&t);
            let copies: Option<Vec<&ClockAt>> = if stop.syncs == start.syncs {
                Some(vec![start])
            } else {
                match (before, at_t, after) {
                    (false, false, _) => Some(vec![start]),
                    (_, false, false) => Some(vec![stop]),
                    (false, true, false) => Some(vec![start, stop]),
                    _ => None,
                }
            };
            // A slave that had taken no lumped frame has no time line: it takes no command.
            let s_at: Option<Vec<i64>> = copies.map(|c| {
                c.iter()
                    .filter(|c| c.syncs > 0)
                    .map(|c| c.clock.to_sync(local).as_ns())
                    .collect()
            });
            let cands = shared.deliveries.get(&(i, t)).cloned().unwrap_or_default();
            let last = self.last_cycle[i - 1];
            let newer = |c: u32| last.is_none_or(|l| c.wrapping_sub(l) as i32 > 0);
            let fits = |d: &Delivery| {
                forge::clip(f64::from(d.value), U_MAX) == u
                    && s_at.as_ref().is_none_or(|s_at| {
                        s_at.iter()
                            .any(|&s| in_window(s, d.cycle, self.p2p, self.window))
                    })
            };
            let Some(d) = cands
                .iter()
                .filter(|d| fits(d) && newer(d.cycle))
                .min_by_key(|d| (!d.from_master, d.cycle.wrapping_sub(last.unwrap_or(0))))
            else {
                panic!(
                    "slave {i} applied {u} V at {t} ns (synchronised time {s_at:?}): no command \
                     for it reached it then with that value, in its cycle window and newer than \
                     cycle {last:?}; commands that reached it then: {cands:?}"
                );
            };
            if true_time_mode() {
                assert!(
                    in_window(t, d.cycle, self.p2p, self.window),
                    "slave {i} applied cycle {}'s command at true time {t} ns ({d:?})",
                    d.cycle
                );
            }
            self.last_cycle[i - 1] = Some(d.cycle);
            self.applied_by
                .entry((i, d.cycle))
                .or_default()
                .push(((u as f32).to_bits(), d.from_master));
        }
        self.applied_seen = ring.applied.len();
        // A re-lock, or a restart that may have come, after the last command applied in this
        // step.
        for (i, r) in relocked.iter().enumerate() {
            let restarted = end[i].restarts != self.clocks[i].restarts
                && shared.lumped_at[i]
                    .iter()
                    .any(|&x| x >= prev[i] && x <= now);
            if r.is_some() || restarted {
                self.last_cycle[i] = None;
            }
        }
        drop(shared);
        let mut shared = self.shared.borrow_mut();
        shared.deliveries.retain(|&(_, at), _| at > now - KEEP);
        for v in &mut shared.lumped_at {
            v.retain(|&at| at > now);
        }
        self.clocks = end;
    }

    /// Orders the slaves took (from their responses) show in their status.
    fn check_orders(&mut self) {
        let mut shared = self.shared.borrow_mut();
        let mut own = std::mem::take(&mut shared.own);
        own.sort_by_key(|o| o.0);
        for (at, i, r) in own {
            let t = at - self.hop - self.response_delay;
            let d = &mut self.drives[i - 1];
            let cands: Vec<Delivery> = shared
                .deliveries
                .get(&(i, t))
                .map(|v| {
                    v.iter()
                        .filter(|c| c.cycle == r.common.cycle && c.retry == r.common.retry)
                        .copied()
                        .collect()
                })
                .unwrap_or_default();
            assert!(
                !cands.is_empty(),
                "slave {i} sent {r:?} at {at} ns, no command for it reached it at {t} ns"
            );
            // A repeat of the cycle's earlier try (no re-lock since) does not take the
            // command's orders again.
            let repeat = d.last_take.is_some_and(|(c, retry, when)| {
                c == r.common.cycle
                    && retry < r.common.retry
                    && d.relocked_at.is_none_or(|x| x <= when || x > t)
            });
            d.last_take = Some((r.common.cycle, r.common.retry, t));
            if repeat || !cands.iter().all(|c| c.from_master) {
                continue;
            }
            let mut must = 0;
            let flags = cands.iter().fold(Flags::DEFINED, |f, c| f & c.flags.bits());
            if flags & Flags::TORQUE_OFF.bits() != 0 {
                must = Status::TORQUE_OFF.bits();
            } else if flags & Flags::BRAKE.bits() != 0 {
                must = Status::BRAKING.bits() | Status::TORQUE_OFF.bits();
            }
            assert!(
                must == 0 || r.status.bits() & must != 0,
                "slave {i} took the master's order {cands:?} at {t} ns, answered {r:?}"
            );
            if flags & Flags::STOP.bits() != 0 {
                assert!(
                    r.status.contains(Status::STOPPING),
                    "slave {i} took the master's stop {cands:?} at {t} ns, answered {r:?}"
                );
            }
            // Latched: torque off stays; braking ends in torque off.
            if must != 0 && d.must != Status::TORQUE_OFF.bits() {
                d.must = must;
            }
        }
    }

    /// Every mismatch the master counted is a response that reached it and would mismatch;
    /// the real ones come from slaves that applied a command the master did not send, or
    /// that a forged order stopped. A counted mismatch stops the group at the next law run.
    fn check_mismatches(&mut self, now: i64) {
        // The master's orders so far (given at its law runs, before the responses that
        // follow them).
        for (t, ev) in &self.ring.master_events[self.master_seen..] {
            if let MasterEvent::Order { axis, .. } = ev
                && let Some(o) = self.ordered_at.get_mut(*axis)
            {
                o.get_or_insert(*t);
            }
        }
        let mut shared = self.shared.borrow_mut();
        let arrivals = std::mem::take(&mut shared.at_master);
        let (due, later): (Vec<Arrival>, Vec<Arrival>) =
            arrivals.into_iter().partition(|a| a.at <= now);
        shared.at_master = later;
        let stopped = Status::BRAKING.bits() | Status::TORQUE_OFF.bits();
        let mut candidates = 0u64;
        for a in due {
            let r = &a.resp;
            let sent = shared
                .master_values
                .get(&(r.common.cycle, r.source))
                .copied();
            let axis = usize::from(r.source).wrapping_sub(1);
            // The master's rule (`check_applied`): FAULT is the drive's own safe state, not
            // checked; BRAKING or TORQUE_OFF must be this master's order (given before the
            // response came; one at the same instant counts as not yet given, which only
            // widens the bound); anything else must be the command sent.
            let halted = r.status.bits() & stopped != 0;
            let ordered = self
                .ordered_at
                .get(axis)
                .copied()
                .flatten()
                .is_some_and(|o| o < a.at);
            let would = r.echo_cycle == r.common.cycle
                && !r.status.contains(Status::FAULT)
                && if halted {
                    !ordered
                } else {
                    sent.is_none_or(|v| !agrees(r, v))
                };
            if !would {
                continue;
            }
            candidates += 1;
            self.mismatching
                .push((a.at, axis, r.applied_v.to_bits(), sent.map(f32::to_bits)));
            if !a.forged && halted {
                // A real response of a drive halted without the master's order: a frame
                // other than the master's commands stopped it.
                let i = usize::from(r.source);
                assert!(
                    self.drives.get(axis).is_some_and(|d| d.unordered),
                    "slave {i}'s response {r:?} at {} ns shows a halted drive the master did \
                     not order, but no order other than the master's reached it",
                    a.at
                );
            } else if !a.forged && sent.is_some() {
                let i = usize::from(r.source);
                let by = self.applied_by.get(&(i, r.common.cycle));
                assert!(
                    by.is_some_and(|v| v
                        .iter()
                        .any(|&(bits, master)| !master && bits == r.applied_v.to_bits())),
                    "slave {i}'s response {r:?} at {} ns says it applied other than the \
                     master's {sent:?}, but what it applied in that cycle was {by:?}",
                    a.at
                );
            }
        }
        let counted = self.ring.master.counters().command_mismatches;
        assert!(
            counted - self.mismatches <= candidates,
            "the master counted {} mismatches since {} ns, {candidates} responses could be",
            counted - self.mismatches,
            self.checked_at
        );
        // Mismatches counted before `due`: every law run after it comes with the stop.
        let due = self.mismatch_due;
        if counted > self.mismatches && self.mismatch_due.is_none() {
            self.mismatch_due = Some(now);
        }
        self.mismatches = counted;
        for (t, ev) in &self.ring.master_events[self.master_seen..] {
            match ev {
                MasterEvent::GroupStop { .. } => {
                    self.stopped_at.get_or_insert(*t);
                }
                MasterEvent::Computed { k } if due.is_some_and(|d| *t > d) => assert!(
                    self.stopped_at.is_some_and(|s| s <= *t),
                    "the master counted a mismatch by {due:?} ns, computed cycle {k} at {t} ns \
                     without a group stop"
                ),
                _ => {}
            }
            if let MasterEvent::GroupStop {
                reason:
                    StopReason::CommandMismatch {
                        axis,
                        sent,
                        applied,
                    },
                ..
            } = ev
            {
                assert!(
                    self.mismatching.iter().any(|&(_, a, ap, s)| a == *axis
                        && ap == applied.to_bits()
                        && s.is_none_or(|s| s == sent.to_bits())),
                    "{ev:?} at {t} ns: no such response reached the master ({:?})",
                    self.mismatching
                );
            }
        }
        self.master_seen = self.ring.master_events.len();
        self.mismatching.retain(|m| m.0 > now - KEEP);
        let cycle = (now / T) as u32;
        shared
            .master_values
            .retain(|&(c, _), _| cycle.wrapping_sub(c) < 8 || c.wrapping_sub(cycle) < 8);
        self.applied_by
            .retain(|&(_, c), _| cycle.wrapping_sub(c) < 8 || c.wrapping_sub(cycle) < 8);
    }
}

fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let mut h = Harness::new();
    let mut killed = false;
    while !u.is_empty() && h.ring.now() < TOTAL {
        let Ok(op) = Op::arbitrary(&mut u) else {
            break;
        };
        if forge::tracing() {
            eprintln!("{op:?}");
        }
        match op {
            Op::Run { us } => {
                let until = (h.ring.now() + (i64::from(us) * 1_000).min(MAX_RUN)).min(TOTAL);
                h.run_to(until);
            }
            Op::Inject {
                to,
                after_us,
                frame,
            } => h.inject(to, after_us, &frame),
            Op::Tap(rule) => {
                let mut sh = h.shared.borrow_mut();
                if sh.rules.len() < MAX_RULES {
                    sh.rules.push((rule, rule.count.max(1)));
                }
            }
            Op::Kill { slave } => {
                if !killed {
                    killed = true;
                    h.ring.dead[1 + usize::from(slave % 4)] = true;
                }
            }
        }
    }
    // A tail long enough for every pending check to conclude.
    let tail = h.ring.now() + (h.w + 3) * T;
    h.run_to(tail);
    if forge::tracing() {
        for (t, ev) in &h.ring.master_events {
            if !matches!(ev, MasterEvent::Computed { .. }) {
                eprintln!("  {t} ns: master {ev:?}");
            }
        }
        for (t, i, ev) in &h.ring.slave_events {
            if !matches!(ev, SlaveEvent::Apply { .. } | SlaveEvent::Brake { .. }) {
                eprintln!("  {t} ns: slave {i} {ev:?}");
            }
        }
        eprintln!(
            "at {} ns: master {:?}, stopping {}",
            h.ring.now(),
            h.ring.master.counters(),
            h.ring.master.is_stopping()
        );
        for (i, s) in h.ring.slaves.iter().enumerate() {
            eprintln!("slave {}: {:?} {:?}", i + 1, s.counters(), s.status());
        }
        eprintln!("applied {}", h.ring.applied.len());
    }
});
