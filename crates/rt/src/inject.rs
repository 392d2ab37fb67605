//! Fault injection onto a running ring, from a thread of its own and sockets of its own,
//! like a faulty or hostile device on the wire: garbage (random bytes, bad CRCs), forged
//! frames with a valid CRC (commands of another cycle, lumped frames from the future, bursts
//! of sync frames with a wrong cycle and a far timestamp), and link flaps.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::thread::JoinHandle;

use ringsync_model::rng::Rng;
use ringsync_model::scenario::LinkBreak;
use ringsync_proto::Duration;
use ringsync_wire::{CommandRepr, Common, FeedbackSlot, LumpedRepr};

use crate::netns::VethRing;
use crate::sys;
use crate::transport::{Port, RawSender, UdpSender, VethPort};

/// The nearest cycle ahead a forged command is stamped with: 200 cycles (200 ms at 1 ms),
/// so that it is still a wrong cycle when it is read: 18 times the longest stall a loaded
/// CI host gave the ring's loop (11 ms), 6 times the longest under
/// `stress-ng --cpu 2 --cpu-load 60 --sched fifo --sched-prio 90` (35 ms).
pub const FAR_AHEAD: i64 = 200;

/// A kind of forged frame with a valid CRC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Forgery {
    /// Commands of another cycle, ±10 V, each at its target's input link, 1000 a second:
    /// 2 to 1000 cycles behind, or [`FAR_AHEAD`] to 1000 cycles ahead. Never nearer ahead:
    /// a command stamped a few cycles ahead is a current command once a stall of the host
    /// has held it that long (the injector preempted between reading the clock and sending,
    /// or the slave's loop between its arrival and its read), and a slave rightly takes it.
    WrongCycleCommands,
    /// Lumped frames stamped 1 s in the future with a cycle that matches the stamp, into
    /// slave 1's input link, 100 a second.
    FutureLumped,
    /// Once a second, 30 lumped frames back to back with a wrong cycle and a timestamp 10 s
    /// ahead, into slave 1's input link.
    SyncBurst,
}

impl Forgery {
    /// Every kind.
    pub const ALL: [Forgery; 3] = [
        Forgery::WrongCycleCommands,
        Forgery::FutureLumped,
        Forgery::SyncBurst,
    ];

    /// The name used on the command line and in summary.json.
    pub fn name(self) -> &'static str {
        match self {
            Forgery::WrongCycleCommands => "wrong-cycle-commands",
            Forgery::FutureLumped => "future-lumped",
            Forgery::SyncBurst => "sync-burst",
        }
    }

    /// Bursts per second.
    fn rate(self) -> f64 {
        match self {
            Forgery::WrongCycleCommands => 1_000.0,
            Forgery::FutureLumped => 100.0,
            Forgery::SyncBurst => 1.0,
        }
    }

    fn index(self) -> usize {
        match self {
            Forgery::WrongCycleCommands => 0,
            Forgery::FutureLumped => 1,
            Forgery::SyncBurst => 2,
        }
    }
}

impl std::str::FromStr for Forgery {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Forgery::ALL
            .iter()
            .copied()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown forgery '{s}': use {}",
                    Forgery::ALL.map(Forgery::name).join(", ")
                )
            })
    }
}

/// A link taken down for a while and brought up again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Flap {
    /// The link's sending node (0 = master, i = slave i); it ends at the next node.
    pub from: usize,
    /// When it goes down, from the run's start.
    pub at: Duration,
    /// How long it stays down.
    pub down_for: Duration,
}

impl Flap {
    /// Parses a link written `A-B` (A, B: `m` for the master or a slave number, B the node
    /// after A on a ring of `n` slaves) into its sending node.
    pub fn parse_link(s: &str, n: usize) -> Result<usize, String> {
        let node = |t: &str| -> Result<usize, String> {
            match t.trim() {
                "m" | "master" => Ok(0),
                v => v
                    .parse::<usize>()
                    .ok()
                    .filter(|i| (1..=n).contains(i))
                    .ok_or_else(|| format!("'{v}' is not a node: use m or 1..={n}")),
            }
        };
        let (a, b) = s
            .split_once('-')
            .ok_or_else(|| format!("link '{s}' is not A-B, e.g. 2-3, m-1 or {n}-m"))?;
        let (a, b) = (node(a)?, node(b)?);
        if b != (a + 1) % (n + 1) {
            return Err(format!(
                "'{s}' is not a link of the ring: node {a}'s link goes to {}",
                if a == n {
                    "m".to_string()
                } else {
                    (a + 1).to_string()
                }
            ));
        }
        Ok(a)
    }

    /// The link's name, e.g. `slave 2 → slave 3`.
    pub fn name(&self, n: usize) -> String {
        let node = |i: usize| {
            if i == 0 {
                "master".to_string()
            } else {
                format!("slave {i}")
            }
        };
        format!("{} → {}", node(self.from), node((self.from + 1) % (n + 1)))
    }
}

/// Frames injected so far, per kind.
#[derive(Debug, Default)]
pub struct Injected {
    /// Garbage and bad-CRC frames.
    pub garbage: AtomicU64,
    /// Forged frames per [`Forgery`] (index in [`Forgery::ALL`]).
    pub forged: [AtomicU64; 3],
}

impl Injected {
    /// Forged frames of kind `f` injected.
    pub fn forged(&self, f: Forgery) -> u64 {
        self.forged[f.index()].load(Ordering::SeqCst)
    }
}

/// What the injector thread needs to know of the ring.
pub struct InjectorPlan {
    /// Garbage frames a second (0: none).
    pub garbage_rate: f64,
    /// Forgeries to send.
    pub forgeries: Vec<Forgery>,
    /// Slaves n.
    pub slaves: usize,
    /// Cycle time \[ns\].
    pub t_cyc: i64,
    /// Seed of the injector's draws.
    pub seed: u64,
    /// CLOCK_MONOTONIC at the run's true time 0 \[ns\] (0 until the run starts).
    pub t0: Arc<AtomicI64>,
    /// Inject only while the run goes, from time 0 for this long, then stop (a ring of node
    /// processes: its start-up phase and its tail are not the run's); `None`: from now
    /// until told to stop.
    pub run_for: Option<Duration>,
}

/// One sender onto each link: `senders[i]` puts frames on the link into node i + 1 (the
/// link out of node i), for veth; for UDP straight to node (i + 1)'s socket.
pub fn senders(
    veth: &Option<Arc<VethRing>>,
    udp_targets: &[std::net::SocketAddr],
) -> io::Result<Vec<Box<dyn Port>>> {
    match veth {
        Some(v) => (0..v.nodes())
            .map(|i| {
                VethPort::injector(v, i).map(|fd| Box::new(RawSender::new(fd, i)) as Box<dyn Port>)
            })
            .collect(),
        None => {
            let nodes = udp_targets.len();
            (0..nodes)
                .map(|i| {
                    UdpSender::new(udp_targets[(i + 1) % nodes])
                        .map(|p| Box::new(p) as Box<dyn Port>)
                })
                .collect()
        }
    }
}

/// Starts the injector: it runs until `stop` rises and counts what it sent in `counts`.
pub fn spawn(
    mut senders: Vec<Box<dyn Port>>,
    plan: InjectorPlan,
    counts: Arc<Injected>,
    stop: Arc<AtomicBool>,
) -> JoinHandle<()> {
    std::thread::spawn(move || {
        sys::set_normal();
        let mut rng = Rng::stream(plan.seed, 0x6A7B);
        let start = sys::now_ns();
        // Next send of garbage (index 3) and of each forgery.
        let mut next = [i64::MAX; 4];
        for f in &plan.forgeries {
            next[f.index()] = start + (rng.unit() / f.rate() * 1e9) as i64;
        }
        if plan.garbage_rate > 0.0 {
            next[3] = start + (rng.unit() / plan.garbage_rate * 1e9) as i64;
        }
        while !stop.load(Ordering::SeqCst) {
            let (which, at) = next
                .iter()
                .copied()
                .enumerate()
                .min_by_key(|(_, t)| *t)
                .unwrap_or((0, i64::MAX));
            if at == i64::MAX {
                return;
            }
            // Sleep in slices so that a stop is seen within 10 ms.
            if sys::now_ns() < at {
                sys::sleep_until(at.min(sys::now_ns() + 10_000_000));
                continue;
            }
            // Forgeries are aimed at the running ring: none before it starts.
            let t0 = plan.t0.load(Ordering::SeqCst);
            if let Some(d) = plan.run_for {
                if t0 > 0 && sys::now_ns() >= t0 + d.as_ns() {
                    return;
                }
                if t0 == 0 || sys::now_ns() < t0 {
                    next[which] = next[which].max(t0);
                    continue;
                }
            }
            if which < 3 && (t0 == 0 || sys::now_ns() < t0) {
                next[which] += (1e9 / Forgery::ALL[which].rate()) as i64;
                continue;
            }
            let cycle = (sys::now_ns() - t0).max(0) / plan.t_cyc.max(1);
            if which == 3 {
                let link = (rng.next_u64() % senders.len() as u64) as usize;
                if senders[link].send(&garbage(&mut rng, plan.slaves)).is_ok() {
                    counts.garbage.fetch_add(1, Ordering::SeqCst);
                }
                next[3] += (2.0 * rng.unit() / plan.garbage_rate * 1e9) as i64;
                continue;
            }
            let f = Forgery::ALL[which];
            for (link, frame) in forged(f, &mut rng, cycle, plan.t_cyc, plan.slaves) {
                if senders[link].send(&frame).is_ok() {
                    counts.forged[which].fetch_add(1, Ordering::SeqCst);
                }
            }
            next[which] += (1e9 / f.rate()) as i64;
        }
    })
}

/// A random frame: half plain random bytes, half a well-formed command with a wrong CRC.
fn garbage(rng: &mut Rng, slaves: usize) -> Vec<u8> {
    if rng.next_u64().is_multiple_of(2) {
        let len = 1 + (rng.next_u64() % 100) as usize;
        (0..len).map(|_| rng.next_u64() as u8).collect()
    } else {
        let mut b = command(
            rng.next_u64() as u32,
            1 + (rng.next_u64() % slaves.max(1) as u64) as u16,
            10.0,
            0,
        );
        let last = b.len() - 1;
        b[last] ^= 0x5A;
        b
    }
}

fn command(cycle: u32, target: u16, v: f32, sample_time_ns: u64) -> Vec<u8> {
    let cmd = CommandRepr {
        common: Common {
            cycle,
            ..Common::default()
        },
        target,
        command_v: v,
        sample_time_ns,
        link_ns: 0,
    };
    let mut b = vec![0u8; cmd.buffer_len()];
    let _ = cmd.emit(&mut b);
    b
}

fn lumped(cycle: u32, stamp: u64, slots: usize) -> Vec<u8> {
    let repr = LumpedRepr {
        common: Common {
            cycle,
            ..Common::default()
        },
        master_time_ns: stamp,
        first_slot: 0,
        slots: vec![FeedbackSlot::default(); slots.min(73)],
    };
    let mut b = vec![0u8; repr.buffer_len()];
    let _ = repr.emit(&mut b);
    b
}

/// The frames of one forgery at the ring's cycle `cycle`, each with the link to put it on.
fn forged(f: Forgery, rng: &mut Rng, cycle: i64, t_cyc: i64, n: usize) -> Vec<(usize, Vec<u8>)> {
    match f {
        Forgery::WrongCycleCommands => {
            let target = 1 + (rng.next_u64() % n.max(1) as u64) as usize;
            // Always another cycle: behind only when there is a cycle that far behind.
            let behind = 2 + (rng.next_u64() % 999) as i64;
            let c = if cycle >= behind && rng.next_u64().is_multiple_of(2) {
                cycle - behind
            } else {
                cycle + FAR_AHEAD + (rng.next_u64() % (1001 - FAR_AHEAD) as u64) as i64
            };
            let v = if rng.next_u64().is_multiple_of(2) {
                10.0
            } else {
                -10.0
            };
            let at = (cycle * t_cyc).max(0) as u64;
            vec![(target - 1, command(c as u32, target as u16, v, at))]
        }
        Forgery::FutureLumped => {
            let c = cycle + 1_000;
            vec![(0, lumped(c as u32, (c * t_cyc) as u64, n))]
        }
        Forgery::SyncBurst => {
            let stamp = ((cycle + 10_000) * t_cyc) as u64;
            (0..30)
                .map(|_| (0, lumped(rng.next_u64() as u32, stamp, n)))
                .collect()
        }
    }
}

/// Takes the link out of node `flap.from` down at `flap.at` from the run's start and up
/// again `flap.down_for` later (veth: the receiving end, switched in process with two
/// system calls each way, so the flap lasts what it was asked to within microseconds);
/// returns how long it was down \[ns\], from before the call that took it down to after the
/// call that brought it up (`None` when the run ended first), or why it could not switch
/// the link. The thread enters the link's namespace and stays there.
pub fn spawn_flap(
    veth: Arc<VethRing>,
    flap: Flap,
    t0: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
) -> JoinHandle<Result<Option<i64>, String>> {
    spawn_link_switch(veth, flap.from, flap.at, Some(flap.down_for), t0, stop)
}

/// A broken link (`faults.break_link`, `--break-link`) on a veth ring: link `b.link` (from
/// node `b.link` − 1) goes down at `b.at` and, if it heals, up again at `b.heal`; returns
/// How long a flap's link was down \[ns\], once its thread (`flapper`, [`spawn_flap`]) has
/// ended; a flap that could not happen is said as a warning (whether or not the run is
/// verbose: the run lacks the fault it was asked for).
pub fn flap_down_ns(flapper: Option<JoinHandle<Result<Option<i64>, String>>>) -> Option<i64> {
    match flapper.map(|h| h.join()) {
        Some(Ok(Ok(d))) => d,
        Some(Ok(Err(why))) => {
            eprintln!("ringsync rt: warning: the link flap did not happen: {why}");
            None
        }
        _ => None,
    }
}

/// The line a run says of a link flap: `link A → B goes down at T s for D ms`, and over
/// UDP (`veth` false) who drops what it would carry.
pub fn flap_line(f: &Flap, n: usize, veth: bool) -> String {
    format!(
        "link {} goes down at {:.3} s for {:.1} ms{}",
        f.name(n),
        f.at.as_ns() as f64 * 1e-9,
        f.down_for.as_ns() as f64 * 1e-6,
        if veth {
            ""
        } else {
            " (UDP: the runtime drops what it would carry)"
        }
    )
}

/// The line a run says of a scheduled break: `link I breaks at T s[ and heals at T2 s]`.
pub fn break_line(b: &LinkBreak) -> String {
    format!(
        "link {} breaks at {:.3} s{}",
        b.link,
        b.at.as_ns() as f64 * 1e-9,
        b.heal
            .map(|h| format!(" and heals at {:.3} s", h.as_ns() as f64 * 1e-9))
            .unwrap_or_default(),
    )
}

/// how long it was down as [`spawn_flap`] does (`None`: it was still down at the end).
pub fn spawn_break(
    veth: Arc<VethRing>,
    b: LinkBreak,
    t0: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
) -> JoinHandle<Result<Option<i64>, String>> {
    let from = (b.link as usize).saturating_sub(1);
    let down_for = b.heal.map(|h| h - b.at);
    spawn_link_switch(veth, from, b.at, down_for, t0, stop)
}

/// Takes the link out of node `from` down at `at` from the run's start and, with
/// `down_for`, up again that much later.
fn spawn_link_switch(
    veth: Arc<VethRing>,
    from: usize,
    at: Duration,
    down_for: Option<Duration>,
    t0: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
) -> JoinHandle<Result<Option<i64>, String>> {
    std::thread::spawn(move || {
        sys::set_normal();
        let (netns, ifname) = veth.link_end(from);
        let fail = |what: &str, e: std::io::Error| format!("{what} {ifname} in {netns}: {e}");
        sys::enter_netns(&netns).map_err(|e| fail("entering the namespace of", e))?;
        let ctl = sys::control_socket().map_err(|e| fail("a control socket for", e))?;
        if !wait_for(&t0, at, &stop) {
            return Ok(None);
        }
        let start = sys::now_ns();
        sys::set_interface_up(&ctl, &ifname, false).map_err(|e| fail("taking down", e))?;
        let Some(down_for) = down_for else {
            return Ok(None);
        };
        // Down until the heal, or the run's end (the namespaces go with the run).
        let up_at = start + down_for.as_ns();
        while sys::now_ns() < up_at {
            if stop.load(Ordering::SeqCst) {
                return Ok(None);
            }
            sys::sleep_until((sys::now_ns() + 1_000_000).min(up_at));
        }
        sys::set_interface_up(&ctl, &ifname, true).map_err(|e| fail("bringing up", e))?;
        Ok(Some(sys::now_ns() - start))
    })
}

/// Waits until `at` from the run's start (`t0`, `CLOCK_MONOTONIC` [ns]; 0 until known):
/// false when `stop` comes first.
fn wait_for(t0: &AtomicI64, at: Duration, stop: &AtomicBool) -> bool {
    loop {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        let t = t0.load(Ordering::SeqCst);
        if t > 0 && sys::now_ns() >= t + at.as_ns() {
            return true;
        }
        sys::sleep_until(sys::now_ns() + 200_000);
    }
}

/// A ring of node processes loses slave `slave` at `at` from the run's start (`t0`): the
/// slave's own process goes silent then ([`crate::node::NodeKill`]); here its veth links
/// (when `veth`) go down with it, as one process takes a slave out, and `say` tells it.
pub fn spawn_take_out(
    veth: Option<Arc<VethRing>>,
    slave: usize,
    at: Duration,
    t0: Arc<AtomicI64>,
    stop: Arc<AtomicBool>,
    say: bool,
) -> JoinHandle<Result<Option<i64>, String>> {
    std::thread::spawn(move || {
        sys::set_normal();
        if !wait_for(&t0, at, &stop) {
            return Ok(None);
        }
        if say {
            eprintln!(
                "ringsync rt: slave {slave} taken out at {:.3} s",
                at.as_ns() as f64 * 1e-9
            );
        }
        if let Some(v) = veth {
            v.take_down(slave)
                .map_err(|e| format!("taking slave {slave}'s links down: {e}"))?;
        }
        Ok(None)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_parse_as_adjacent_nodes() {
        assert_eq!(Flap::parse_link("2-3", 4), Ok(2));
        assert_eq!(Flap::parse_link("m-1", 4), Ok(0));
        assert_eq!(Flap::parse_link("4-m", 4), Ok(4));
        assert!(
            Flap::parse_link("2-4", 4)
                .expect_err("an error")
                .contains("goes to 3")
        );
        assert!(
            Flap::parse_link("5-m", 4)
                .expect_err("an error")
                .contains("1..=4")
        );
        assert!(
            Flap::parse_link("23", 4)
                .expect_err("an error")
                .contains("A-B")
        );
        let f = Flap {
            from: 4,
            at: Duration::ZERO,
            down_for: Duration::ZERO,
        };
        assert_eq!(f.name(4), "slave 4 → master");
    }

    /// At the ring's first cycles a forged command is still of another cycle (it once was
    /// clamped to cycle 0 and, in cycle 0, applied).
    #[test]
    fn forged_commands_are_never_of_the_cycle_in_progress() {
        let mut rng = Rng::stream(3, 4);
        for cycle in [0, 1, 5, 999, 1000, 4000] {
            for _ in 0..200 {
                for (_, b) in forged(Forgery::WrongCycleCommands, &mut rng, cycle, 1_000_000, 4) {
                    let Ok(ringsync_wire::Pdu::Command(c)) = ringsync_wire::Pdu::parse(&b) else {
                        panic!("not a command");
                    };
                    let off = (i64::from(c.common.cycle) - cycle).abs();
                    assert!((2..=1000).contains(&off), "cycle {cycle}: {off}");
                }
            }
        }
    }

    #[test]
    fn forged_frames_carry_a_valid_crc_and_the_promised_lie() {
        let mut rng = Rng::stream(1, 2);
        for f in Forgery::ALL {
            for (link, b) in forged(f, &mut rng, 500, 1_000_000, 4) {
                let pdu = ringsync_wire::Pdu::parse(&b).expect("valid CRC and layout");
                match pdu {
                    ringsync_wire::Pdu::Command(c) => {
                        let off = (i64::from(c.common.cycle) - 500).abs();
                        assert!((2..=1000).contains(&off), "{off}");
                        assert_ne!(c.common.cycle, 500);
                        assert_eq!(link + 1, usize::from(c.target));
                    }
                    ringsync_wire::Pdu::Lumped(l) => {
                        assert_eq!(link, 0);
                        assert!(l.master_time_ns >= 1_500 * 1_000_000);
                    }
                    other => panic!("{other:?}"),
                }
            }
        }
        assert_eq!("sync-burst".parse::<Forgery>(), Ok(Forgery::SyncBurst));
        assert!(
            "x".parse::<Forgery>()
                .expect_err("an error")
                .contains("wrong-cycle-commands")
        );
    }
}
