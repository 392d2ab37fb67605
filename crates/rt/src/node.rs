//! One node per process: `ringsync node master` and `ringsync node slave --index I`
//! (docs/runtime.md, "One process per node"). Each process is one device of the ring: the
//! unchanged sans-IO node, its own port (a UDP socket, or raw Ethernet on two interfaces,
//! in a network namespace or not), its own clock (a slave's oscillator over the host's
//! monotonic clock), its own loop and scheduling, and for a slave its simulated axis.
//!
//! The processes of a ring share a [`NodePlan`]: the scenario's text, the runtime's
//! overrides, every node's link, and an **epoch**, the host's `CLOCK_MONOTONIC` reading at
//! the run's time 0 (so the processes must run on one host; true time is that clock less
//! the epoch). Before time 0 the nodes measure the ring's delays themselves
//! ([`crate::calibrate`]'s figures, [`ringsync_proto::node::calibrate`]'s phase): the master
//! starts its probes `start_up_ns` before the epoch, each slave answers them in its start-up
//! phase and takes the path delay the master sends it. Then the run: the master's cycles
//! from time 0; each slave latches, follows the master's clock (software stamps: the
//! instant its loop reads a frame; or the kernel's, the instant the frame reached its
//! socket, [`NodePlan::stamps`]) and drives its axis.
//!
//! Each process writes a [`NodeRecord`]: what its node saw, as the events the recorder of an
//! in-process run is told (cycle starts with the axis's true state, law runs, applied
//! commands, fault steps, monitor events, ring changes), with the true time of each, plus
//! its counters. The launcher ([`crate::launch`]) merges them into one run's result.

use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};

use ringsync_model::Spec;
use ringsync_model::devices::Devices;
use ringsync_model::monitor::MonitorEvent;
use ringsync_model::observer::{NodeView, Observer};
use ringsync_model::oscillator::Oscillator;
use ringsync_model::record::{AxisProbe, FaultEvent};
use ringsync_model::result::RingChange;
use ringsync_model::scenario::LinkBreak;
use ringsync_model::scenario::Scenario;
use ringsync_model::spec::timestamp_tolerance;
use ringsync_proto::node::{
    CalibrationConfig, CalibrationState, Calibrator, CycleRecord, FrameOutcome, Master,
    MasterCounters, Port as MasterPort, Slave, SlaveCounters, WireFrame,
};
use ringsync_proto::{Duration, Instant};

use crate::breaks::{Breaks, NodeLinks};
use crate::calibrate::Calibration;
use crate::clock::Clock;
use crate::frames::{self, CapturingPort};
use crate::realtime::{Pin, Realtime};
use crate::ring::{RT_CLOCK_FILTER, RX_RETRY};
use crate::run::{RtError, RtOptions, Stamps, io_err};
use crate::schedule::{self, RT_TIMESTAMP_TOLERANCE, Schedule};
use crate::sys;
use crate::timing::{Timing, TimingLog};
use crate::transport::{MAX_PDU, Port, VethPort};

/// Where one node's frames come from and go.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeLink {
    /// UDP datagrams: the node's socket, and the next node's.
    Udp {
        /// This node's socket.
        listen: SocketAddr,
        /// The next node's socket (the master's, for slave n).
        next: SocketAddr,
    },
    /// Raw Ethernet (EtherType 0x88B5) on the interface from the previous node and the one
    /// to the next, inside network namespace `netns` when given (real interfaces: none).
    Raw {
        /// The network namespace to open the sockets in (`/run/netns/NAME`).
        netns: Option<String>,
        /// The interface frames arrive on.
        rx_if: String,
        /// The interface frames leave on.
        tx_if: String,
    },
}

/// What every process of one ring shares (the launcher writes it as JSON; docs/runtime.md
/// shows one written by hand for real interfaces).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NodePlan {
    /// The scenario's TOML text.
    pub scenario: String,
    /// Where it came from (for messages).
    pub origin: String,
    /// The runtime's overrides of the scenario \[ns\]: duration, cycle, sampling lead.
    pub duration_ns: Option<i64>,
    /// Cycle time override \[ns\].
    pub cycle_ns: Option<i64>,
    /// W override.
    pub watchdog_cycles: Option<u32>,
    /// Sampling lead override \[ns\].
    pub sample_lead_ns: Option<i64>,
    /// How long the master waits for a response beyond its slice \[ns\].
    pub response_timeout_ns: i64,
    /// Delay probes of the start-up phase.
    pub probes: usize,
    /// `CLOCK_MONOTONIC` at the run's time 0 \[ns\] (one host's clock).
    pub epoch_ns: i64,
    /// The master starts its probes this long before time 0 \[ns\].
    pub start_up_ns: i64,
    /// SCHED_FIFO priority of every node's loop (0: the normal scheduler). Equal: on one
    /// shared CPU the master's busy-wait before its cycle start then holds the CPU, and the
    /// slaves' latches due meanwhile run just after its send (a latch takes the axis at
    /// its own instant however late it runs); slaves one above the master made it send
    /// 40 µs late in the median (docs/runtime.md).
    pub priority: i32,
    /// The master's busy-wait before its deadlines \[ns\] (the slaves sleep).
    pub spin_ns: i64,
    /// Lock memory.
    pub lock_memory: bool,
    /// Each node's link, index 0 the master.
    pub links: Vec<NodeLink>,
    /// The nodes read their interfaces' carrier to know a broken link (a ring on the
    /// host's own interfaces, `ringsync node plan`); otherwise they know it from the
    /// scenario's `faults.break_link` schedule (the launcher's rings).
    #[serde(default)]
    pub sense_carrier: bool,
    /// The one CPU every node process is pinned to (the launcher claims it against other
    /// runs); None: the nodes run unpinned.
    #[serde(default)]
    pub cpu: Option<usize>,
    /// Where each node keeps the frames it sends, for the run's capture
    /// ([`crate::frames`]); None: not kept.
    #[serde(default)]
    pub capture_dir: Option<std::path::PathBuf>,
    /// How every node stamps the frames it receives: [`Stamps::Software`] or
    /// [`Stamps::Kernel`]; [`Stamps::Phy`] (the default), which needs one loop that sees
    /// every send, is taken as software.
    #[serde(default)]
    pub stamps: Stamps,
    /// A slave taken out of the ring during the run (`--kill-slave`), if any.
    #[serde(default)]
    pub kill: Option<NodeKill>,
    /// A link down for a while over UDP (`--flap-link`): its sending node drops what it
    /// would send on it then (on veth the launcher takes the link down itself).
    #[serde(default)]
    pub flap: Option<NodeFlap>,
    /// Every node writes what it sees on its standard output as the run goes ([`Live`],
    /// one JSON line each), for a live view (`--scope`).
    #[serde(default)]
    pub live: bool,
}

/// What a node of a ring with a live view ([`NodePlan::live`]) writes on its standard
/// output as the run goes, one JSON line each.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Live {
    /// One of its events, as its record keeps it.
    Tap(Tapped),
    /// Its counters and state at cycle `k`'s start.
    View {
        /// Cycle index.
        k: i64,
        /// The node's view.
        view: NodeView,
    },
    /// (The master) how late its loop started cycle `k` \[ns\], and whether the host
    /// stalled it then.
    Timing {
        /// Cycle index.
        k: i64,
        /// Lateness \[ns\].
        lateness_ns: i64,
        /// A host stall.
        stalled: bool,
    },
}

/// Messages a node's live feed holds before it drops one (its writer thread is behind).
const LIVE_QUEUE: usize = 8192;

/// A node's live feed ([`NodePlan::live`]): messages go through a bounded queue to a
/// writer thread at the normal priority, on any CPU (a full queue drops and counts, never
/// blocks the loop).
#[derive(Clone)]
struct LiveTx {
    tx: SyncSender<Live>,
    dropped: Arc<AtomicU64>,
}

impl LiveTx {
    /// Starts the writer thread on standard output.
    fn start() -> io::Result<(LiveTx, std::thread::JoinHandle<()>)> {
        let (tx, rx) = sync_channel::<Live>(LIVE_QUEUE);
        let writer = std::thread::Builder::new()
            .name("rt-live".into())
            .spawn(move || {
                use std::io::Write as _;
                // Started from the loop's thread: not its priority, nor its CPU.
                sys::set_normal();
                let mut w = io::BufWriter::new(io::stdout().lock());
                while let Ok(m) = rx.recv() {
                    for m in std::iter::once(m).chain(rx.try_iter()) {
                        if serde_json::to_writer(&mut w, &m).is_err() || w.write_all(b"\n").is_err()
                        {
                            return;
                        }
                    }
                    if w.flush().is_err() {
                        return;
                    }
                }
            })?;
        Ok((
            LiveTx {
                tx,
                dropped: Arc::new(AtomicU64::new(0)),
            },
            writer,
        ))
    }

    fn send(&self, m: Live) {
        if self.tx.try_send(m).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// A link flap a node carries out itself (UDP, [`NodePlan::flap`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeFlap {
    /// The link's sending node (0 the master).
    pub from: usize,
    /// Down from [ns from time 0].
    pub at_ns: i64,
    /// Up again at [ns from time 0].
    pub until_ns: i64,
}

impl NodeFlap {
    /// Whether node `node`'s send forward at `t` [ns] falls in this flap.
    fn drops(flap: Option<NodeFlap>, node: usize, t: i64) -> bool {
        flap.is_some_and(|f| f.from == node && (f.at_ns..f.until_ns).contains(&t))
    }
}

/// A slave taken out of a ring of node processes (`--kill-slave`): from `at_ns` on its
/// process reads, sends and latches nothing more (the launcher takes its veth links down
/// too), while its axis goes on with its last command, as one process takes a slave out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeKill {
    /// The slave (1-based).
    pub slave: usize,
    /// When [ns from time 0].
    pub at_ns: i64,
}

impl NodePlan {
    /// The ring this plan runs: the scenario with the runtime's overrides, built.
    pub fn spec(&self) -> Result<Spec, RtError> {
        let s = Scenario::from_toml(&self.scenario, &self.origin)?;
        let opts = RtOptions {
            duration: self.duration_ns.map(Duration::from_ns),
            cycle: self.cycle_ns.map(Duration::from_ns),
            watchdog_cycles: self.watchdog_cycles,
            sample_lead: self.sample_lead_ns.map(Duration::from_ns),
            ..RtOptions::default()
        };
        let spec = crate::run::as_run(&s, &opts).build()?;
        if self.links.len() != spec.axes() + 1 {
            return Err(RtError::Config(format!(
                "the node plan has {} links for a ring of {} nodes",
                self.links.len(),
                spec.axes() + 1
            )));
        }
        Ok(spec)
    }

    /// Reads a plan written as JSON.
    pub fn read(path: &Path) -> Result<NodePlan, RtError> {
        // A plan that cannot be read is bad input (exit status 2), as a scenario file is.
        let text = ringsync_model::bounded::read_text(path, MAX_PLAN_BYTES, "a node plan")
            .map_err(|e| {
                RtError::Config(format!("cannot read the node plan {}: {e}", path.display()))
            })?;
        serde_json::from_str(&text).map_err(|e| {
            RtError::Config(format!(
                "the node plan {} is not valid: {e}",
                path.display()
            ))
        })
    }
}

/// What a node saw, with the true time it happened \[ns\].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tapped {
    /// True time \[ns\].
    pub t: i64,
    /// What.
    pub ev: Tap,
}

/// One event of a node, as the recorder of an in-process run is told it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tap {
    /// Cycle `k` started: the master's probe (every axis's desired position) or a slave's
    /// (its own axis's true state, at index 0).
    Cycle {
        /// Cycle index.
        k: i64,
        /// The probes.
        probes: Vec<AxisProbe>,
    },
    /// The master's law ran for cycle `k`.
    Computed {
        /// Cycle index.
        k: i64,
        /// What it computed.
        record: CycleRecord,
    },
    /// A drive took a command [axis 0-based, t s, u V].
    Applied {
        /// Axis (0-based).
        axis: usize,
        /// When \[s\].
        t: f64,
        /// The command \[V\].
        u: f64,
    },
    /// A step of a fault reaction.
    Fault(FaultEvent),
    /// A monitor's warning or trip.
    Monitor(MonitorEvent),
    /// The ring changed.
    Ring(RingChange),
}

/// What one node process hands the launcher.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct NodeRecord {
    /// The node: 0 the master, i slave i.
    pub node: usize,
    /// What it saw, in its order.
    pub events: Vec<Tapped>,
    /// The master's counters.
    pub master: Option<MasterCounters>,
    /// The slave's counters.
    pub slave: Option<SlaveCounters>,
    /// The master's start-up figures.
    pub calibration: Option<Calibration>,
    /// The master's schedule on the measured ring.
    pub schedule: Option<Schedule>,
    /// The path delay the slave took \[ns\].
    pub path_delay_ns: Option<i64>,
    /// Behind transparent relays: the slave's path delay when the run ended \[ns\] (it
    /// follows the master's estimate of the links).
    #[serde(default)]
    pub path_delay_end_ns: Option<i64>,
    /// Behind transparent relays: the master's last estimate of one link from its frames'
    /// round trips \[ns\], and how many estimates it made.
    #[serde(default)]
    pub link_in_run: Option<(i64, u64)>,
    /// Frames the slave refused in its start-up phase.
    pub start_up_rejected: u64,
    /// The master's timing of the run.
    pub timing: Option<Timing>,
    /// Real-time settings applied (or not).
    pub realtime: Vec<String>,
    /// Frames the node read, and when it last read one \[s\].
    pub frames_read: u64,
    /// When it last read one [s, true time].
    pub last_read_s: Option<f64>,
    /// The node was told to stop before the end.
    pub interrupted: bool,
    /// Frames it had to drop beside a broken link: its link ahead broken and it cut off
    /// from both of the master's ports, or a frame it turned a second time (a slave); or
    /// the port's own link broken (the master).
    #[serde(default)]
    pub broken_dropped: u64,
    /// Receive errors (a link gone down: its direction is read again [`RX_RETRY`] later).
    #[serde(default)]
    pub receive_errors: u64,
    /// The clock window a slave ran with \[ns\].
    #[serde(default)]
    pub clock_window_ns: Option<i64>,
    /// Frames it kept for the capture.
    #[serde(default)]
    pub frames_kept: u64,
    /// Frames its capture queue could not take.
    #[serde(default)]
    pub frames_not_kept: u64,
    /// When this slave was taken out of the ring ([`NodeKill`]) [s from time 0].
    #[serde(default)]
    pub taken_out_s: Option<f64>,
    /// Frames this node dropped on a flapping link ([`NodeFlap`]).
    #[serde(default)]
    pub flap_dropped: u64,
    /// Frames still waiting on the node's port when it ended, read then and handed to no
    /// node: those it would have refused as malformed, and well-formed ones (injected
    /// frames among them).
    #[serde(default)]
    pub unread_at_end: (u64, u64),
    /// Messages of its live feed dropped ([`NodePlan::live`]: the writer was behind).
    #[serde(default)]
    pub live_dropped: u64,
    /// Sync lumped frames whose stamp this node moved on by the time it held them
    /// (transparent relays, kernel stamps: `Relay`).
    #[serde(default)]
    pub relay_corrected: u64,
    /// Frames it relayed without looking into them (backward on a broken ring) that failed
    /// their checks (the next node refuses them), or lumped frames whose stamp would have
    /// overflowed: passed on untouched.
    #[serde(default)]
    pub relay_uncorrected: u64,
}

/// A node's relays of sync lumped frames. Transparent (kernel stamps): as a PTP
/// transparent clock corrects a sync message for its time in the bridge, the node adds to
/// the frame's stamp how long it held it, from its kernel receive stamp to just before the
/// send, on its own clock (the master: from the instant it stamped the frame); the slaves'
/// path delays are then their links alone, and a relay's wake-up and forwarding time, which
/// varies from frame to frame by tens of µs on a busy host, no longer reaches the clocks
/// after it. Plain (software stamps): frames pass as they came.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Relay {
    transparent: bool,
}

impl Relay {
    /// The relays of a node stamping with `stamps`.
    pub(crate) fn of(stamps: Stamps) -> Relay {
        Relay {
            transparent: stamps.in_processes() == Stamps::Kernel,
        }
    }

    /// Adds `held_ns` to `pdu`'s stamp if it is a sync lumped frame and the relays are
    /// transparent, counting in `rec`; anything else passes as it is.
    fn pass(self, pdu: &mut [u8], held_ns: i64, rec: &mut NodeRecord) {
        if !self.transparent {
            return;
        }
        match ringsync_wire::add_to_master_time(pdu, held_ns.max(0) as u64) {
            Ok(ringsync_wire::Relayed::Corrected) => rec.relay_corrected += 1,
            Ok(ringsync_wire::Relayed::NotLumped) => {}
            Ok(ringsync_wire::Relayed::Overflow) | Err(_) => rec.relay_uncorrected += 1,
        }
    }
}

/// An observer that keeps the events of one node.
struct Tapper {
    /// The slave's axis (0-based), or `None` for the master.
    axis: Option<usize>,
    now: Arc<AtomicI64>,
    events: Arc<Mutex<Vec<Tapped>>>,
    live: Option<LiveTx>,
}

impl Tapper {
    fn push(&self, ev: Tap) {
        let t = self.now.load(Ordering::Relaxed);
        let e = Tapped { t, ev };
        if let Some(l) = &self.live {
            l.send(Live::Tap(e.clone()));
        }
        if let Ok(mut v) = self.events.lock() {
            v.push(e);
        }
    }
}

impl Observer for Tapper {
    fn cycle(&mut self, k: i64, _t: f64, axes: &[AxisProbe]) {
        let probes = match self.axis {
            Some(i) => axes.get(i).copied().into_iter().collect(),
            None => axes.to_vec(),
        };
        self.push(Tap::Cycle { k, probes });
    }
    fn computed(&mut self, k: i64, record: &CycleRecord) {
        if self.axis.is_none() {
            self.push(Tap::Computed {
                k,
                record: record.clone(),
            });
        }
    }
    fn applied(&mut self, axis: usize, t: f64, u: f64) {
        if self.axis == Some(axis) {
            self.push(Tap::Applied { axis, t, u });
        }
    }
    fn fault(&mut self, event: &FaultEvent) {
        self.push(Tap::Fault(*event));
    }
    fn monitor(&mut self, event: &MonitorEvent) {
        if self.axis.is_none() {
            self.push(Tap::Monitor(*event));
        }
    }
    fn ring(&mut self, change: &RingChange) {
        if self.axis.is_none() {
            self.push(Tap::Ring(*change));
        }
    }
    fn nodes(&mut self, k: i64, master: &Master, slaves: &[Slave]) {
        // This node alone: the others of its `Devices` are not the ring's.
        let Some(l) = &self.live else {
            return;
        };
        let view = match self.axis {
            None => NodeView::of_master(master),
            Some(i) => match slaves.get(i) {
                Some(s) => NodeView::of_slave(s, k),
                None => return,
            },
        };
        l.send(Live::View { k, view });
    }
}

/// Opens node `node`'s port on `link` (its frames to the next node; a node process has no
/// backward port: a broken ring is not run this way yet).
pub fn open_port(link: &NodeLink, node: usize) -> io::Result<Box<dyn Port>> {
    match link {
        NodeLink::Udp { listen, next } => {
            let sock = UdpSocket::bind(listen)?;
            sock.set_nonblocking(true)?;
            Ok(Box::new(crate::transport::UdpPort::single(sock, *next)))
        }
        NodeLink::Raw {
            netns,
            rx_if,
            tx_if,
        } => Ok(Box::new(VethPort::open_named(
            netns.as_deref(),
            rx_if,
            tx_if,
            node,
        )?)),
    }
}

/// The start-up phase sends a probe at most this often (once per cycle at shorter
/// cycles): a long cycle need not make the phase long.
pub const PROBE_INTERVAL: Duration = Duration::from_ms(2);

/// The last frames of a run still go round after the master's last cycle: a slave runs on
/// this long after the end [ns].
const TAIL: i64 = 50_000_000;

/// Runs node `node` (0 the master, i slave i) of `plan` until the run's end or `stop`, and
/// returns what it saw.
pub fn run_node(plan: &NodePlan, node: usize, stop: &AtomicBool) -> Result<NodeRecord, RtError> {
    let mut spec = plan.spec()?;
    let n = spec.axes();
    let link = plan.links.get(node).ok_or_else(|| {
        RtError::Config(format!(
            "slave {node} is not on this ring: its slaves are 1 to {n} (the master is `ringsync node master`)"
        ))
    })?;
    // A node started after the run's start cannot take part: say so, rather than let its
    // start-up phase fail as if it had been given too little time.
    let late = Clock::starting_at(plan.epoch_ns).now();
    if late >= 0 {
        return Err(RtError::Config(format!(
            "the run this node plan describes started {:.1} s ago: write a new plan (`ringsync node plan`; its --start-in leaves time to start every node)",
            late as f64 * 1e-9
        )));
    }
    let port = open_port(link, node).map_err(io_err("opening the node's port"))?;
    // (The writer thread starts before the real-time settings, which are the calling
    // thread's alone: it stays at the normal priority, on any CPU.)
    let (mut port, frames) = match &plan.capture_dir {
        Some(dir) => {
            let (tx, writer) = frames::frame_file(&dir.join(frames::file_name(node)))
                .map_err(io_err("creating the node's frame file"))?;
            let kept: Box<dyn Port> = Box::new(CapturingPort::new(port, tx, plan.epoch_ns));
            (kept, Some(writer))
        }
        None => (port, None),
    };
    let realtime = Realtime {
        spin: Duration::from_ns(if node == 0 { plan.spin_ns } else { 0 }),
        priority: plan.priority,
        cpu: plan.cpu.map_or(Pin::Off, Pin::Shared),
        lock_memory: plan.lock_memory,
    };
    let applied = realtime.apply();
    let mut rec = NodeRecord {
        node,
        realtime: applied.lines.clone(),
        ..NodeRecord::default()
    };
    if plan.stamps.in_processes() == Stamps::Kernel {
        port.enable_kernel_stamps().map_err(|e| {
            RtError::Node(format!(
                "the kernel will not stamp the frames this node receives (SO_TIMESTAMPNS): {e}; run with --stamps software"
            ))
        })?;
    }
    let mut clock = Clock::starting_at(plan.epoch_ns);
    // The clock windows of the runtime (software stamps), as an in-process run sets them.
    let tolerance = RT_TIMESTAMP_TOLERANCE.max(timestamp_tolerance(&spec.scenario));
    spec.master.timestamp_tolerance = tolerance;
    for c in &mut spec.slaves {
        c.clock_window = tolerance;
    }
    if node == 0 {
        run_master(&mut spec, plan, port.as_mut(), &mut clock, stop, &mut rec)?;
    } else {
        run_slave(
            &mut spec,
            node - 1,
            plan,
            port.as_mut(),
            &mut clock,
            stop,
            &mut rec,
        )?;
    }
    drop(applied);
    // Every frame sent is in the writer's queue: the file is written whole.
    drop(port);
    if let Some(w) = frames {
        (rec.frames_kept, rec.frames_not_kept) =
            w.finish().map_err(io_err("writing the node's frames"))?;
    }
    Ok(rec)
}

/// Shared state of a node's loop and its tap.
struct TapHandle {
    now: Arc<AtomicI64>,
    events: Arc<Mutex<Vec<Tapped>>>,
    live: Option<LiveTx>,
}

fn tap(dev: &mut Devices, axis: Option<usize>, live: Option<LiveTx>) -> TapHandle {
    let t = TapHandle {
        now: Arc::new(AtomicI64::new(0)),
        events: Arc::new(Mutex::new(Vec::new())),
        live,
    };
    dev.observe(Box::new(Tapper {
        axis,
        now: t.now.clone(),
        events: t.events.clone(),
        live: t.live.clone(),
    }));
    t
}

impl TapHandle {
    /// (The master) cycle `k`'s start, `lateness_ns` late, for the live feed.
    fn timing(&self, k: i64, lateness_ns: i64, stalled: bool) {
        if let Some(l) = &self.live {
            l.send(Live::Timing {
                k,
                lateness_ns,
                stalled,
            });
        }
    }
    fn at(&self, t: i64) {
        self.now.store(t, Ordering::Relaxed);
    }
    fn take(&self) -> Vec<Tapped> {
        self.events
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default()
    }
}

/// The master: its start-up phase before time 0, then its cycles.
fn run_master(
    spec: &mut Spec,
    plan: &NodePlan,
    port: &mut dyn Port,
    clock: &mut Clock,
    stop: &AtomicBool,
    rec: &mut NodeRecord,
) -> Result<(), RtError> {
    let n = spec.axes();
    let t_cyc = spec.scenario.ring.cycle.0;
    let mut buf = vec![0u8; MAX_PDU];
    let mut fds = [sys::pollfd(port.rx_fd())];
    // 1. The start-up phase: one probe per cycle from `start_up_ns` before time 0.
    let origin = -plan.start_up_ns;
    let mut cfg = CalibrationConfig::new(n, t_cyc, u32::try_from(plan.probes).unwrap_or(u32::MAX));
    cfg.interval = t_cyc.min(PROBE_INTERVAL);
    let relay = Relay::of(plan.stamps);
    cfg.transparent = relay.transparent;
    let mut cal = Calibrator::new(cfg, Instant::from_ns(origin));
    sys::sleep_until(plan.epoch_ns + origin);
    // The last instant the master acted at: frames are stamped no earlier.
    let mut floor = origin;
    while let Some(due) = cal.poll_timeout() {
        if stop.load(Ordering::Relaxed) {
            rec.interrupted = true;
            return Ok(());
        }
        let now = clock.now();
        if now >= 0 {
            return Err(RtError::Node(format!(
                "the start-up phase ran past the run's start ({:.1} ms given, {} of {} probes sent): give it more time",
                plan.start_up_ns as f64 * 1e-6,
                cal.measurement().map_or(0, |m| m.probes),
                plan.probes
            )));
        }
        if now >= due.as_ns() {
            floor = now;
            cal.handle_timeout(Instant::from_ns(now));
            while let Some(tx) = cal.poll_transmit() {
                port.send(&tx.bytes)
                    .map_err(io_err("sending a delay probe"))?;
            }
            continue;
        }
        clock
            .wait_readable_until(&mut fds, due.as_ns())
            .map_err(io_err("waiting for delay probes"))?;
        while let Some(len) = port.recv(&mut buf).map_err(io_err("reading"))? {
            // Every probe counts: the medians ride out the host's stalls. (The in-process
            // runtime drops a probe whose pass the host stalled; here a send that wakes the
            // next node's process takes tens of µs itself, and a stall of another process
            // is not this one's to see.)
            let t = rx_time(clock, port, floor);
            floor = t;
            cal.handle_frame(Instant::from_ns(t), &buf[..len]);
        }
    }
    let m = match cal.state() {
        CalibrationState::Done => cal.measurement().cloned(),
        CalibrationState::Failed(e) => {
            return Err(RtError::Node(format!("the start-up phase failed: {e}")));
        }
        _ => None,
    }
    .ok_or_else(|| RtError::Node("the start-up phase did not finish".into()))?;
    // Every slave acknowledged the delay the master sent it.
    let taken = m.path.iter().map(|d| Some(*d)).collect();
    let took = Duration::from_ns(clock.now() - origin);
    let calibration = Calibration::of(m, taken, 0, 0, spec, took);
    let response_timeout = Duration::from_ns(plan.response_timeout_ns);
    let sched = schedule::apply(spec, &calibration, response_timeout)?;
    if relay.transparent {
        spec.master.transparent_link = Some(calibration.start_up.measured.link);
    }
    rec.calibration = Some(calibration);
    rec.schedule = Some(sched);
    if clock.now() >= 0 {
        return Err(RtError::Node(format!(
            "the start-up phase ran past the run's start ({:.1} ms given): give it more time",
            plan.start_up_ns as f64 * 1e-6
        )));
    }
    // 2. The cycles.
    let t_cyc = t_cyc.as_ns();
    let cycles = spec.scenario.duration.0.as_ns() / t_cyc;
    let end = cycles * t_cyc;
    let mut dev = Devices::new(spec, cycles, false)?;
    let live = start_live(plan)?;
    let tap = tap(&mut dev, None, live.as_ref().map(|l| l.0.clone()));
    let mut log = TimingLog::new(cycles);
    let (mut k, mut probe_k) = (0i64, 0i64);
    let spin = plan.spin_ns;
    let shared_cpu = plan.cpu.is_some();
    // Frames to send, each with whether it goes out of port B.
    let mut out: Vec<(bool, Vec<u8>)> = Vec::new();
    let port_b = dev.port_b_node();
    // A broken ring: the master senses its ports' links (as a PHY does) and sends out of
    // both; frames come back to either port.
    let links = if plan.sense_carrier {
        NodeLinks::sensed(0)
    } else {
        NodeLinks::scheduled(0, Breaks::new(spec.scenario.faults.break_link.clone(), n))
    };
    let mut port_events: std::collections::VecDeque<_> = if plan.sense_carrier {
        Default::default()
    } else {
        LinkBreak::port_changes(&spec.scenario.faults.break_link, n).into()
    };
    // Reading paused after a receive error, per direction (forward, backward).
    let mut paused = [None; 2];
    let flap = plan.flap;
    let mut flap_dropped = 0u64;
    let mut send =
        |port: &mut dyn Port, log: &mut TimingLog, t: i64, (b_side, bytes): (bool, Vec<u8>)| {
            // Port B is the link behind, port A the link ahead.
            if !b_side && NodeFlap::drops(flap, 0, t) {
                flap_dropped += 1;
            } else if if b_side {
                links.behind_down(t)
            } else {
                links.ahead_down(t)
            } {
                log.timing.broken_dropped += 1;
            } else if if b_side {
                port.send_back(&bytes)
            } else {
                port.send(&bytes)
            }
            .is_err()
            {
                log.timing.send_errors += 1;
            }
        };
    loop {
        if stop.load(Ordering::Relaxed) {
            rec.interrupted = true;
            break;
        }
        let now = clock.now();
        if now >= end {
            break;
        }
        while port_events.front().is_some_and(|e| e.0 <= now) {
            if let Some((_, p, up)) = port_events.pop_front() {
                tap.at(now);
                dev.master_link(now, p, up);
            }
        }
        for (side, change) in [MasterPort::B, MasterPort::A]
            .into_iter()
            .zip(links.sense(port, now))
        {
            if let Some(up) = change {
                tap.at(now);
                dev.master_link(now, side, up);
            }
        }
        if probe_k < cycles && probe_k * t_cyc <= now {
            tap.at(probe_k * t_cyc);
            // Once a cycle: a system clock set during the run moves the kernel's stamps.
            clock.measure_realtime();
            dev.probe(probe_k, probe_k * t_cyc);
            probe_k += 1;
            continue;
        }
        let mut got = false;
        // Frames back at port B (round the ring), then at port A (turned back beside a
        // broken link).
        for side in [MasterPort::B, MasterPort::A] {
            if side == MasterPort::A && !links.may_break() {
                break;
            }
            while let Some(len) = read_dir(
                port,
                side == MasterPort::A,
                &mut paused,
                &mut buf,
                clock.now(),
                &mut log.timing.receive_errors,
            ) {
                got = true;
                let t = rx_time(clock, port, floor);
                floor = t;
                rec.frames_read += 1;
                rec.last_read_s = Some(t as f64 * 1e-9);
                log.master_rx(t);
                tap.at(t);
                let news =
                    dev.master_frame_port(side, t, &buf[..len], &mut |from, _, f: WireFrame| {
                        out.push((from == port_b, f.into_bytes()))
                    });
                if news.computed {
                    log.computed(t);
                }
                for mut f in out.drain(..) {
                    // The master stamped the frame at `t`: it held it until now.
                    relay.pass(&mut f.1, clock.now() - t, rec);
                    send(port, &mut log, t, f);
                }
            }
        }
        let m = dev.master_deadline();
        let now = clock.now();
        if m <= now && m < end {
            if m == k * t_cyc {
                let c = dev.master.counters();
                let stall = clock.take_stall();
                let late = log.cycle_start(k, now, m, c.lumped_lost + c.commands_lost, stall);
                tap.timing(k, late, stall >= crate::timing::STALL);
                clock.note_stall(late);
                k += 1;
            }
            tap.at(now);
            floor = now;
            let news = dev.master_timeout(now, &mut |from, _, f: WireFrame| {
                out.push((from == port_b, f.into_bytes()))
            });
            if news.computed {
                log.computed(now);
            }
            for mut f in out.drain(..) {
                relay.pass(&mut f.1, clock.now() - now, rec);
                send(port, &mut log, now, f);
            }
            continue;
        }
        if got {
            continue;
        }
        let wake = m
            .min(probe_k * t_cyc)
            .min(end)
            .min(port_events.front().map_or(i64::MAX, |e| e.0))
            .min(links.next_sense())
            .min(paused.iter().flatten().copied().min().unwrap_or(i64::MAX));
        // On the CPU the slaves share, at their priority, the master does not busy-wait
        // while frames are going round: SCHED_FIFO keeps the CPU for a spinning thread, and
        // a lumped frame still going round when it began to spin before its P2P start
        // waited out the spin in a relay's socket (or in the kernel's receive work, which
        // a loaded host hands to a thread at normal priority), came back late, and the law
        // ran on the cycle before's samples (the reference ring, one CPU: 4-97 lumped
        // frames late in 1 000 cycles, in some runs every one, the axes then drifting to a
        // following error). It waits for them until the deadline itself.
        let waiting = shared_cpu && dev.master.awaiting_frames();
        if waiting || wake - now > spin {
            if dev.master.awaiting_frames() {
                let until = if waiting { wake } else { wake - spin };
                wait_frames(clock, port, links.may_break(), &paused, until)
                    .map_err(io_err("waiting for frames"))?;
            } else {
                clock.sleep_until(wake - spin);
            }
        }
        // (Busy-waiting for the cycle start, it keeps the CPU: a slave's latch that falls
        // due meanwhile runs just after the send, at its own instant. Yielding to it cost
        // the cycle start 7-12 µs at the median for nothing.)
    }
    // What came after the run's end (an injector's last frames): read once the slaves'
    // tail is over, and counted.
    rec.flap_dropped = flap_dropped;
    if !rec.interrupted {
        clock.sleep_until(end + TAIL);
    }
    rec.unread_at_end = crate::ring::drain_port(port);
    let counters = dev.master.counters();
    rec.broken_dropped = log.timing.broken_dropped;
    rec.receive_errors = log.timing.receive_errors;
    rec.timing = Some(log.finish(&counters));
    rec.master = Some(counters);
    rec.link_in_run = dev.master.link_estimate().map(|(d, k)| (d.as_ns(), k));
    rec.events = tap.take();
    drop((tap, dev));
    rec.live_dropped = end_live(live);
    Ok(())
}

/// Slave `i` (0-based): its start-up phase, then the run with its axis.
fn run_slave(
    spec: &mut Spec,
    i: usize,
    plan: &NodePlan,
    port: &mut dyn Port,
    clock: &mut Clock,
    stop: &AtomicBool,
    rec: &mut NodeRecord,
) -> Result<(), RtError> {
    let t_cyc = spec.scenario.ring.cycle.0.as_ns();
    let cycles = spec.scenario.duration.0.as_ns() / t_cyc;
    let end = cycles * t_cyc;
    let osc = Oscillator::for_scenario(&spec.scenario)
        .get(i)
        .copied()
        .ok_or_else(|| RtError::Config(format!("slave {} is not on this ring", i + 1)))?;
    let mut buf = vec![0u8; MAX_PDU];
    let mut fds = [sys::pollfd(port.rx_fd())];
    // 1. The start-up phase: answer the probes until the master's closing frame gives the
    //    slave its path delay (it must come before the run's start).
    let mut node = Slave::calibrating(spec.slaves[i].clone());
    // The last instant the slave acted at: frames are stamped no earlier.
    let mut floor = i64::MIN;
    let delay = loop {
        if stop.load(Ordering::Relaxed) {
            rec.interrupted = true;
            return Ok(());
        }
        if let Some(d) = node.path_delay() {
            break d;
        }
        let now = clock.now();
        if now >= 0 {
            return Err(RtError::Node(format!(
                "slave {} had no path delay from the master by the run's start (the master's probes did not reach it)",
                i + 1
            )));
        }
        clock
            .wait_readable_until(&mut fds, now + 10_000_000)
            .map_err(io_err("waiting for delay probes"))?;
        while let Some(len) = port.recv(&mut buf).map_err(io_err("reading"))? {
            let t = rx_time(clock, port, floor);
            floor = t;
            rec.frames_read += 1;
            let bytes = &mut buf[..len];
            if node.handle_frame(osc.local(t), osc.local(t), bytes) == FrameOutcome::Forward {
                // The frame leaves when the send begins (the next node's kernel stamps it
                // within the call), as the master stamps its probes.
                let sent = clock.now();
                let _ = port.send(bytes);
                node.handle_forwarded(osc.local(sent));
            }
        }
    };
    spec.slaves[i].path_delay = delay;
    // Behind transparent relays its path is its links alone: it follows the master's
    // estimate of the links as the run's frames measure them.
    spec.slaves[i].follow_link = Relay::of(plan.stamps).transparent;
    // The clock window at least twice the ring's path, as the master's schedule sets its
    // own (`schedule::apply`): the slave's estimate of that path, from its own path delay
    // over its share of the hops (slave 1's counts no residence). What it used goes into
    // its record.
    let n = spec.axes() as i64;
    let ring_path = delay.as_ns().saturating_mul(n + 1) / (i as i64 + 1);
    let window = &mut spec.slaves[i].clock_window;
    *window = (*window).max(Duration::from_ns(2 * ring_path));
    rec.clock_window_ns = Some(window.as_ns());
    rec.path_delay_ns = Some(delay.as_ns());
    rec.start_up_rejected = node.counters().rejected.total();
    // 2. The run: the same node, running, with the delay it took (a fresh `Slave` of the
    //    devices, configured with it).
    let mut dev = Devices::new(spec, cycles, false)?;
    let live = start_live(plan)?;
    let relay = Relay::of(plan.stamps);
    // The runtime's clock servo, with its outlier limit at least twice this slave's path:
    // a software stamp here carries a process wake-up per hop (tens of µs each on this
    // machine), and with the one-process limit of 50 µs most syncs of the far slaves were
    // taken as outliers, their rate never measured, and their clocks ran off at their
    // oscillators' drift (160-210 µs/s).
    let mut filter = RT_CLOCK_FILTER;
    filter.outlier_limit = filter
        .outlier_limit
        .map(|l| l.max(Duration::from_ns(delay.as_ns().saturating_mul(2))));
    for sl in &mut dev.slaves {
        sl.clock_mut().set_filter(filter);
    }
    let tap = tap(&mut dev, Some(i), live.as_ref().map(|l| l.0.clone()));
    let mut pending: Vec<(i64, Vec<u8>)> = Vec::new();
    let mut probe_k = 0i64;
    let mut probed = 0i64;
    // A broken ring: the slave senses its two links (as its PHYs do), turns back what its
    // broken link ahead would carry, and takes what comes back to it beside a broken link
    // behind.
    let me = i + 1;
    // Taken out of the ring (`--kill-slave`): when, and whether it has happened.
    let kill_at = plan
        .kill
        .filter(|k| k.slave == i + 1)
        .map_or(i64::MAX, |k| k.at_ns);
    let mut dead = false;
    let links = if plan.sense_carrier {
        NodeLinks::sensed(me)
    } else {
        NodeLinks::scheduled(
            me,
            Breaks::new(spec.scenario.faults.break_link.clone(), spec.axes()),
        )
    };
    let mut paused = [None; 2];
    let mut receive_errors = 0u64;
    let flap = plan.flap;
    // Frames dropped: beside a broken link, and on a flapping one.
    let forward = |port: &mut dyn Port, t: i64, bytes: &[u8], dropped: &mut [u64; 2]| {
        if NodeFlap::drops(flap, i + 1, t) {
            dropped[1] += 1;
        } else if !links.ahead_down(t) {
            let _ = port.send(bytes);
        } else if !links.cut_off(t) {
            let _ = port.send_back(bytes);
        } else {
            dropped[0] += 1;
        }
    };
    let mut dropped = [0u64; 2];
    // The timers due by `now`, in time order: latches, cycle probes, responses, each at its
    // own instant, the latest of which `floor` keeps (a frame that reached the node after
    // it keeps its stamp, however long the timers took to run).
    // (A slave taken out sends nothing: `dead`.)
    let timers = |dev: &mut Devices,
                  pending: &mut Vec<(i64, Vec<u8>)>,
                  probe_k: &mut i64,
                  port: &mut dyn Port,
                  dropped: &mut [u64; 2],
                  now: i64,
                  dead: bool,
                  floor: &mut i64| loop {
        // Nothing of the axis happens from the run's end on (the master has stopped): the
        // tail only carries the last frames round.
        // (A slave taken out no longer latches: its node has stopped; its axis goes on
        // with its last command, as one process takes a slave out.)
        let latch = Some(dev.latch_at(i))
            .filter(|&l| l < end && !dead)
            .unwrap_or(i64::MAX);
        let probe = if *probe_k < cycles {
            *probe_k * t_cyc
        } else {
            i64::MAX
        };
        let (j, send) = pending
            .iter()
            .enumerate()
            .min_by_key(|(_, p)| p.0)
            .map_or((usize::MAX, i64::MAX), |(j, p)| (j, p.0));
        let first = latch.min(probe).min(send);
        if first > now || first == i64::MAX {
            return first;
        }
        tap.at(first);
        *floor = (*floor).max(first);
        // On a tie the cycle's probe first, as in the in-process loop.
        if first == probe {
            dev.probe(*probe_k, probe);
            *probe_k += 1;
        } else if first == latch {
            dev.latch(i, latch, &mut |_, at, f: WireFrame| {
                pending.push((at, f.into_bytes()))
            });
        } else {
            let (at, b) = pending.swap_remove(j);
            if !dead {
                forward(port, at, &b, dropped);
            }
        }
    };
    loop {
        if stop.load(Ordering::Relaxed) {
            rec.interrupted = true;
            break;
        }
        let now = clock.now();
        if now >= end + TAIL {
            break;
        }
        if !dead && now >= kill_at {
            // Taken out: nothing read, sent or latched from now on; the axis goes on.
            dead = true;
            rec.taken_out_s = Some(now as f64 * 1e-9);
            pending.clear();
        }
        // The carrier, when the links are known from it.
        let _ = links.sense(port, now);
        // Frames first, each after the timers due before it reached the node (its kernel
        // stamp may be well before the process woke), then the timers due by now.
        let mut got = false;
        // Frames coming round the ring, then (a broken ring) frames coming backward.
        for back in [false, true] {
            if dead || (back && !links.may_break()) {
                break;
            }
            while let Some(len) = read_dir(
                port,
                back,
                &mut paused,
                &mut buf,
                clock.now(),
                &mut receive_errors,
            ) {
                got = true;
                let t = rx_time(clock, port, floor);
                floor = t;
                // Everything due before the frame first (as in the in-process loop).
                timers(
                    &mut dev,
                    &mut pending,
                    &mut probe_k,
                    port,
                    &mut dropped,
                    t,
                    dead,
                    &mut floor,
                );
                rec.frames_read += 1;
                rec.last_read_s = Some(t as f64 * 1e-9);
                let bytes = &mut buf[..len];
                // How long this slave held a frame it passes on, by its own clock.
                let held =
                    |clock: &mut Clock| osc.local(clock.now()).as_ns() - osc.local(t).as_ns();
                if back && !links.behind_down(t) {
                    // A relay backward: the link behind is whole.
                    relay.pass(bytes, held(clock), rec);
                    let _ = port.send_back(bytes);
                    continue;
                }
                if back && (links.cut_off(t) || links.turned_before(bytes)) {
                    dropped[0] += 1;
                    continue;
                }
                // Round the ring, or turned here beside the broken link behind.
                tap.at(t);
                let outcome = dev.slave_frame(i, t, t, bytes, &mut |_, at, f: WireFrame| {
                    pending.push((at, f.into_bytes()))
                });
                if outcome == FrameOutcome::Forward {
                    relay.pass(bytes, held(clock), rec);
                    forward(port, t, bytes, &mut dropped);
                }
            }
        }
        let now = clock.now();
        let next = timers(
            &mut dev,
            &mut pending,
            &mut probe_k,
            port,
            &mut dropped,
            now,
            dead,
            &mut floor,
        );
        if probe_k != probed {
            // Once a cycle: a system clock set during the run moves the kernel's stamps.
            probed = probe_k;
            clock.measure_realtime();
        }
        if got {
            continue;
        }
        let wake = next
            .min(end + TAIL)
            .min(links.next_sense())
            .min(paused.iter().flatten().copied().min().unwrap_or(i64::MAX));
        if dead {
            clock.sleep_until(wake);
        } else {
            wait_frames(clock, port, links.may_break(), &paused, wake.min(kill_at))
                .map_err(io_err("waiting for frames"))?;
        }
    }
    rec.unread_at_end = if dead {
        (0, 0)
    } else {
        crate::ring::drain_port(port)
    };
    rec.slave = Some(dev.slaves[i].counters());
    rec.path_delay_end_ns = dev.slaves[i].path_delay().map(|d| d.as_ns());
    [rec.broken_dropped, rec.flap_dropped] = dropped;
    rec.receive_errors = receive_errors;
    rec.events = tap.take();
    drop((tap, dev));
    rec.live_dropped = end_live(live);
    Ok(())
}

/// A node's live feed when its plan asks for one ([`NodePlan::live`]): the sender, and
/// the writer thread to join at the end ([`end_live`]).
type LiveFeed = Option<(LiveTx, std::thread::JoinHandle<()>)>;

fn start_live(plan: &NodePlan) -> Result<LiveFeed, RtError> {
    if !plan.live {
        return Ok(None);
    }
    LiveTx::start()
        .map(Some)
        .map_err(io_err("starting the node's live feed"))
}

/// Ends a live feed once every other sender is gone (the node's devices and tap dropped):
/// its writer has written what the queue held. Returns the messages it dropped.
fn end_live(live: LiveFeed) -> u64 {
    let Some((l, writer)) = live else {
        return 0;
    };
    let dropped = l.dropped.load(Ordering::Relaxed);
    drop(l);
    let _ = writer.join();
    dropped
}

/// The next frame waiting on `port` from one direction (`back`: frames coming backward
/// round the ring, `paused[1]`; else `paused[0]`), read into `buf`: its length. A receive
/// error (a link gone down: the socket reports it, and would keep the poll awake) pauses
/// that direction for [`RX_RETRY`], as in one process, and counts in `errors`.
fn read_dir(
    port: &mut dyn Port,
    back: bool,
    paused: &mut [Option<i64>; 2],
    buf: &mut [u8],
    now: i64,
    errors: &mut u64,
) -> Option<usize> {
    let p = &mut paused[usize::from(back)];
    if p.is_some_and(|until| now < until) {
        return None;
    }
    *p = None;
    match if back {
        port.recv_back(buf)
    } else {
        port.recv(buf)
    } {
        Ok(read) => read,
        Err(_) => {
            *errors += 1;
            *p = Some(now + RX_RETRY);
            None
        }
    }
}

/// When the frame `port` just gave reached this node [ns from time 0]: the kernel's
/// receive stamp when the port has one, kept within [`floor`, now] (a node's events stay in
/// time order whatever the two clocks' offset); now otherwise.
fn rx_time(clock: &mut Clock, port: &dyn Port, floor: i64) -> i64 {
    let now = clock.now();
    match port.kernel_stamp() {
        Some(stamp) => clock.from_realtime(stamp).clamp(floor.min(now), now),
        None => now,
    }
}

/// Waits on `clock` until `wake` [ns] or a frame on a direction a node's loop reads (the
/// backward one only on a ring that may break) that is not paused; no allocation.
fn wait_frames(
    clock: &mut Clock,
    port: &dyn Port,
    both: bool,
    paused: &[Option<i64>; 2],
    wake: i64,
) -> io::Result<i64> {
    let mut fds = [sys::pollfd(port.rx_fd()); 2];
    let mut len = 0;
    for fd in [
        paused[0].is_none().then(|| port.rx_fd()),
        port.back_fd().filter(|_| both && paused[1].is_none()),
    ]
    .into_iter()
    .flatten()
    {
        fds[len] = sys::pollfd(fd);
        len += 1;
    }
    clock.wait_readable_until(&mut fds[..len], wake)
}

/// Writes `rec` as JSON to `path`, whole or not at all (a temporary file renamed).
pub fn write_record(rec: &NodeRecord, path: &Path) -> Result<(), RtError> {
    write_json(serde_json::to_vec(rec), path, "the node's record")
}

/// Writes `plan` as JSON to `path`, whole or not at all (a temporary file renamed).
pub fn write_plan(plan: &NodePlan, path: &Path) -> Result<(), RtError> {
    write_json(serde_json::to_vec_pretty(plan), path, "the node plan")
}

/// `json` (`what`, for messages) in `path`, written to a temporary file renamed.
fn write_json(json: serde_json::Result<Vec<u8>>, path: &Path, what: &str) -> Result<(), RtError> {
    let tmp = path.with_extension("json.part");
    let text = json.map_err(|e| RtError::Config(format!("cannot write {what}: {e}")))?;
    std::fs::write(&tmp, text).map_err(io_err(&format!("writing {}", tmp.display())))?;
    std::fs::rename(&tmp, path).map_err(io_err(&format!("writing {}", path.display())))
}

/// Largest node plan read \[bytes\] (a plan grows with the ring's nodes and links).
pub const MAX_PLAN_BYTES: u64 = 64 << 20;

/// Largest node record read \[bytes\]: a record holds its node's trace, about 100 bytes a
/// cycle (a 600 s run at 1 ms: some 60 MB; an hour, some 360 MB).
pub const MAX_RECORD_BYTES: u64 = 2 << 30;

/// Reads a record [`write_record`] wrote.
pub fn read_record(path: &Path) -> Result<NodeRecord, RtError> {
    // A record the caller names that cannot be read is bad input, as a missing plan is.
    let text = ringsync_model::bounded::read_text(path, MAX_RECORD_BYTES, "a node record")
        .map_err(|e| {
            RtError::Config(format!(
                "cannot read the node record {}: {e}",
                path.display()
            ))
        })?;
    serde_json::from_str(&text).map_err(|e| {
        RtError::Config(format!(
            "the node record {} is not valid: {e}",
            path.display()
        ))
    })
}
