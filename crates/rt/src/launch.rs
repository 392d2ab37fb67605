//! `ringsync rt --processes`: the launcher of a ring of node processes (docs/runtime.md,
//! "One process per node"). It builds the ring's links (UDP sockets on loopback, or the
//! veth ring of network namespaces), writes the [`NodePlan`] every node reads, starts
//! `ringsync node slave --index I` for each slave and `ringsync node master`
//! ([`crate::supervise`]: each in its own process group, its standard error relayed), waits
//! for them, and merges their [`NodeRecord`]s into one run's result, the same
//! summary.json and trace.csv an in-process run writes. Whatever happens (a node that dies,
//! Ctrl-C, SIGTERM, SIGHUP, the deadline), every child is stopped and reaped, the
//! namespaces and links are removed and the plan's directory is deleted.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use ringsync_model::Spec;
use ringsync_model::observer::{NodeView, Observer};
use ringsync_model::record::{AxisProbe, Recorder};
use ringsync_model::result::{LinkCounters, RunResult};
use ringsync_model::scenario::Scenario;
use ringsync_proto::node::{MasterCounters, SlaveCounters};

use crate::inject::{Injected, InjectorPlan};
use crate::netns::VethRing;
use crate::node::{Live, NodeLink, NodePlan, NodeRecord, Tap, Tapped, read_record};
use crate::run::{Injection, RtError, RtOptions, RtResult, Streamed, io_err};
use crate::supervise::{ChildSpec, Ended, supervise};
use crate::sys;
use crate::timing::Timing;
use crate::transport::TransportKind;

/// Time to start the processes before the master's start-up phase begins [ns].
const SPAWN: i64 = 800_000_000;
/// Time the start-up phase has besides its probes ([`crate::node::PROBE_INTERVAL`] apart,
/// or a cycle when shorter) [ns].
const START_UP_MARGIN: i64 = 300_000_000;

/// What a process run does not do yet, named; `None` when `opts` asks for none of it.
fn unsupported(s: &Scenario, opts: &RtOptions) -> Option<&'static str> {
    if !s.faults.break_link.is_empty() && opts.transport == TransportKind::Udp {
        Some("a broken link over UDP (--break-link, faults.break_link; use --transport veth)")
    } else {
        None
    }
}

/// The directory of one launch's plan and records, removed on drop.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Where a ring of node processes keeps the frames its nodes send, and what takes them
/// merged ([`run_processes`]).
pub struct Capture<'a, 'b> {
    /// The directory the nodes' frame files go in (in a directory of their own, removed
    /// once merged): beside the capture's file, so that they do not grow in a temporary
    /// directory that may be memory (about 75 MB a minute on the reference ring at 1 ms).
    pub beside: &'a Path,
    /// What takes every frame, in time order.
    pub sink: &'a mut crate::frames::FrameSink<'b>,
}

/// Runs the scenario of TOML `text` (from `origin`) as one process per node, `program`
/// being the `ringsync` executable the nodes run as (`ringsync node …`). `stop` ends the
/// run early. With `capture`, every node keeps the frames it sends ([`crate::frames`]) and
/// the capture's sink is handed them all in time order once the nodes are done (the
/// result's `streamed` says so, and how many the nodes' queues dropped). `observers` watch
/// the run as it goes, from what the nodes write as they run ([`crate::node::Live`],
/// merged by [`live_merge`]); none: the nodes write nothing.
pub fn run_processes(
    text: &str,
    origin: &str,
    opts: &RtOptions,
    program: &Path,
    stop: &AtomicBool,
    capture: Option<Capture<'_, '_>>,
    observers: Vec<Box<dyn Observer>>,
) -> Result<RtResult, RtError> {
    let scenario = Scenario::from_toml(text, origin)?;
    if let Some(what) = unsupported(&scenario, opts) {
        return Err(RtError::Config(format!(
            "{what} is not run with one process per node yet: drop --processes"
        )));
    }
    let run_scenario = crate::run::as_run(&scenario, opts);
    let spec = run_scenario.build()?;
    let n = spec.axes();
    let say = |m: &str| {
        if opts.verbose {
            eprintln!("ringsync rt: {m}");
        }
    };
    // The links.
    let (mut links, veth) = match opts.transport {
        TransportKind::Raw => {
            return Err(RtError::Config(
                "--processes runs its ring on UDP or veth; a ring on the host's own interfaces is started by hand: `ringsync node plan` (docs/runtime.md, \"Real interfaces\")".into(),
            ));
        }
        TransportKind::Udp => (udp_links(n)?, None),
        TransportKind::Veth => {
            say(&format!(
                "creating {} network namespaces and veth links",
                n + 1
            ));
            let ring = Arc::new(VethRing::create(n + 1)?);
            let links = (0..=n)
                .map(|i| NodeLink::Raw {
                    netns: Some(ring.netns(i)),
                    rx_if: ring.in_if(i),
                    tx_if: ring.out_if(i),
                })
                .collect();
            (links, Some(ring))
        }
    };
    let t_cyc = spec.scenario.ring.cycle.0.as_ns();
    let start_up = start_up_ns(opts, t_cyc);
    let scratch = Scratch(std::env::temp_dir().join(format!(
        "ringsync-nodes-{}-{}",
        std::process::id(),
        sys::now_ns()
    )));
    std::fs::create_dir_all(&scratch.0)
        .map_err(io_err(&format!("creating {}", scratch.0.display())))?;
    let plan_path = scratch.0.join("plan.json");
    let record = |i: usize| scratch.0.join(format!("node-{i}.json"));
    // The slaves first, so that they listen when the master's probes come.
    let child = |i: usize| {
        let mut args: Vec<OsString> = vec!["node".into()];
        if i == 0 {
            args.push("master".into());
        } else {
            args.extend(["slave".into(), "--index".into(), i.to_string().into()]);
        }
        args.extend([
            "--plan".into(),
            plan_path.clone().into_os_string(),
            "--out".into(),
            record(i).into_os_string(),
        ]);
        ChildSpec {
            name: if i == 0 {
                "master".into()
            } else {
                format!("slave {i}")
            },
            program: program.to_path_buf(),
            args,
            env: Vec::new(),
            stdout: None,
        }
    };
    let mut observers = Some(observers).filter(|o| !o.is_empty());
    // One CPU for every node (claimed here, for the whole run; `--cpu N`, or by default
    // the last no other run holds): a frame's hop is then a wake-up on the same CPU, not a
    // cross-CPU one, which a 1 ms cycle needs on a small host (docs/runtime.md, "One
    // process per node"). `--no-pin`: unpinned.
    let pin = match opts.realtime.cpu {
        crate::realtime::Pin::Shared(_) => crate::realtime::Pin::Off,
        p => p,
    };
    let (cpu, line) = crate::realtime::claim_cpu(pin);
    let mut pin_warning = None;
    match line {
        Some(w) if w.starts_with("warning") => {
            eprintln!("ringsync rt: {w}");
            pin_warning = Some(w);
        }
        Some(l) => say(&format!("nodes {l}")),
        None => {}
    }
    let frames_dir = match &capture {
        Some(c) => {
            let d = Scratch(c.beside.join(format!(
                ".ringsync-frames-{}-{}",
                std::process::id(),
                sys::now_ns()
            )));
            std::fs::create_dir_all(&d.0)
                .map_err(io_err(&format!("creating {}", d.0.display())))?;
            Some(d)
        }
        None => None,
    };
    let frame_file = |i: usize| {
        frames_dir
            .as_ref()
            .map(|d| d.0.join(crate::frames::file_name(i)))
    };
    let mut tries = 1;
    let (plan, sup, injected, flap_down_ns) = loop {
        let epoch = sys::now_ns() + SPAWN + start_up;
        let mut plan = node_plan(text, origin, opts, links.clone(), epoch)?;
        plan.cpu = cpu.as_ref().map(|c| c.cpu());
        plan.capture_dir = frames_dir.as_ref().map(|d| d.0.clone());
        plan.live = observers.is_some();
        crate::node::write_plan(&plan, &plan_path)?;
        let mut children: Vec<ChildSpec> = (1..=n).chain([0]).map(child).collect();
        // A live view: every node's standard output into one merge that tells the
        // observers (handed back for another attempt when the start-up is refused).
        let merger = match observers.take() {
            Some(obs) => {
                let (tx, rx) = std::sync::mpsc::channel();
                for (c, i) in children.iter_mut().zip((1..=n).chain([0])) {
                    c.stdout = Some((i, tx.clone()));
                }
                let merge = move || live_merge(&rx, obs, n, t_cyc);
                Some(
                    std::thread::Builder::new()
                        .name("rt-live-merge".into())
                        .spawn(merge)
                        .map_err(io_err("starting the live view's merge"))?,
                )
            }
            None => None,
        };
        say(&format!(
            "starting {} node processes; start-up phase {:.0} ms, then {} cycles of {:.1} µs",
            n + 1,
            start_up as f64 * 1e-6,
            spec.scenario.duration.0.as_ns() / t_cyc,
            t_cyc as f64 * 1e-3
        ));
        let run_for = epoch - sys::now_ns() + spec.scenario.duration.0.as_ns();
        let deadline = std::time::Instant::now()
            + std::time::Duration::from_nanos(u64::try_from(run_for).unwrap_or(0))
            + std::time::Duration::from_secs(10);
        // Broken links: the veth link taken down (and up) at its time; the nodes beside it
        // sense it from the same schedule, as a PHY senses its link.
        let t0 = Arc::new(std::sync::atomic::AtomicI64::new(epoch));
        let stop_breaks = Arc::new(AtomicBool::new(false));
        let breakers: Vec<_> = match &veth {
            Some(v) => run_scenario
                .faults
                .break_link
                .iter()
                .map(|b| {
                    say(&crate::inject::break_line(b));
                    crate::inject::spawn_break(v.clone(), *b, t0.clone(), stop_breaks.clone())
                })
                .collect(),
            None => Vec::new(),
        };
        let breakers: Vec<_> = breakers
            .into_iter()
            .chain(plan.kill.map(|k| {
                crate::inject::spawn_take_out(
                    veth.clone(),
                    k.slave,
                    ringsync_proto::Duration::from_ns(k.at_ns),
                    t0.clone(),
                    stop_breaks.clone(),
                    opts.verbose,
                )
            }))
            .collect();
        // A link flap: on veth the link itself, at its time; over UDP its sending node
        // drops what it would carry.
        if let Some(f) = opts.flap {
            say(&crate::inject::flap_line(&f, n, veth.is_some()));
        }
        let flapper = match (opts.flap, &veth) {
            (Some(f), Some(v)) => Some(crate::inject::spawn_flap(
                v.clone(),
                f,
                t0.clone(),
                stop_breaks.clone(),
            )),
            _ => None,
        };
        // Frames injected (garbage, forgeries): the launcher is the faulty device, sending
        // onto the ring's links while the run goes (not into the start-up phase).
        let injected = Arc::new(Injected::default());
        let injector = if opts.garbage_rate > 0.0 || !opts.forge.is_empty() {
            let udp: Vec<_> = plan
                .links
                .iter()
                .filter_map(|l| match l {
                    NodeLink::Udp { listen, .. } => Some(*listen),
                    NodeLink::Raw { .. } => None,
                })
                .collect();
            let senders = crate::inject::senders(&veth, &udp)
                .map_err(io_err("opening the injector's sockets"))?;
            Some(crate::inject::spawn(
                senders,
                InjectorPlan {
                    garbage_rate: opts.garbage_rate,
                    forgeries: opts.forge.clone(),
                    slaves: n,
                    t_cyc,
                    seed: spec.scenario.seed,
                    t0: t0.clone(),
                    run_for: Some(spec.scenario.duration.0),
                },
                injected.clone(),
                stop_breaks.clone(),
            ))
        } else {
            None
        };
        let sup = supervise(children, stop, deadline, std::time::Duration::from_secs(2));
        stop_breaks.store(true, std::sync::atomic::Ordering::SeqCst);
        for h in breakers {
            if let Ok(Err(why)) = h.join() {
                eprintln!("ringsync rt: warning: a link break did not happen: {why}");
            }
        }
        if let Some(h) = injector {
            let _ = h.join();
        }
        let flap_down_ns = crate::inject::flap_down_ns(flapper);
        // Every child is gone, and with them the last senders of the live view's lines:
        // the merge has told the observers all.
        if let Some(m) = merger {
            observers = m.join().ok();
        }
        let sup = sup.map_err(io_err("starting the node processes"))?;
        // The master found the measured ring too slow for the cycle: a host that held the
        // nodes off their CPUs while the probes went round makes the round trips' p99 a host
        // figure. Measure again with a fresh ring of processes (as one process measures
        // again), if the run has not begun (no link of a broken-link schedule has gone
        // down): fresh UDP ports, no record of this attempt left.
        if let Some(f) = sup.first_failure
            && sup.children[f].name == "master"
            && sup.children[f]
                .stderr_tail
                .contains(crate::schedule::DOES_NOT_FIT)
            && tries < crate::run::START_UP_TRIES
            && sys::now_ns() < epoch
            && !stop.load(std::sync::atomic::Ordering::SeqCst)
        {
            for i in 0..=n {
                let _ = std::fs::remove_file(record(i));
                if let Some(f) = frame_file(i) {
                    let _ = std::fs::remove_file(f);
                }
            }
            if opts.transport == TransportKind::Udp {
                links = udp_links(n)?;
            }
            say(&format!(
                "start-up phase {tries} of {}: {}; measuring again",
                crate::run::START_UP_TRIES,
                sup.children[f]
                    .stderr_tail
                    .lines()
                    .last()
                    .unwrap_or("")
                    .trim()
            ));
            tries += 1;
            continue;
        }
        break (plan, sup, injected, flap_down_ns);
    };
    // Every child is gone: the namespaces may go.
    drop(veth);
    if sup.timed_out {
        return Err(RtError::Node(
            "the node processes outlived the run by 10 s and were stopped".into(),
        ));
    }
    if let Some(f) = sup.first_failure {
        let c = &sup.children[f];
        let how = match c.ended {
            Ended::Exited(code) => format!("exited with status {code}"),
            Ended::Signalled(sig) => format!("was killed by signal {sig}"),
            Ended::Killed => "was killed".into(),
        };
        let last = c.stderr_tail.lines().last().unwrap_or("").trim();
        // The ring measured too slow for the cycle, every time: bad input, as in one process.
        if c.name == "master"
            && let Some(at) = last.find(crate::schedule::DOES_NOT_FIT)
        {
            return Err(RtError::Config(last[at..].to_string()));
        }
        return Err(RtError::Node(format!(
            "node process {} {how}{}",
            c.name,
            if last.is_empty() {
                String::new()
            } else {
                format!(": {last}")
            }
        )));
    }
    let records = (0..=n)
        .map(|i| read_record(&record(i)))
        .collect::<Result<Vec<_>, _>>()?;
    let mut r = gather(&plan, &records, sup.stopped, opts.trace)?;
    r.timing.flap_down_ns = flap_down_ns;
    r.injected.garbage = injected.garbage.load(std::sync::atomic::Ordering::SeqCst);
    r.injected.forged = opts
        .forge
        .iter()
        .map(|f| (*f, injected.forged(*f)))
        .collect();
    // The capture: every node's frames, merged in time order; a frame a node kept and the
    // merge did not find (a file cut short) is counted with those its queue dropped.
    if let Some(c) = capture {
        let files: Vec<_> = (0..=n)
            .filter_map(|i| frame_file(i).map(|f| (i, f)))
            .collect();
        let merged =
            crate::frames::merge(&files, c.sink).map_err(io_err("merging the nodes' frames"))?;
        let kept: u64 = records.iter().map(|rec| rec.frames_kept).sum();
        r.streamed.capture = true;
        r.streamed.frames_dropped = records.iter().map(|rec| rec.frames_not_kept).sum::<u64>()
            + kept.saturating_sub(merged);
    }
    if let Some(w) = pin_warning {
        r.realtime.push(format!("nodes: {w}"));
    }
    Ok(r)
}

/// UDP links for a ring of n slaves on free ports of loopback (bound here, then let go
/// for the nodes to bind).
fn udp_links(n: usize) -> Result<Vec<NodeLink>, RtError> {
    let socks = (0..=n)
        .map(|_| UdpSocket::bind("127.0.0.1:0"))
        .collect::<std::io::Result<Vec<_>>>()
        .map_err(io_err("finding free UDP ports on 127.0.0.1"))?;
    let addrs = socks
        .iter()
        .map(UdpSocket::local_addr)
        .collect::<std::io::Result<Vec<_>>>()
        .map_err(io_err("finding free UDP ports on 127.0.0.1"))?;
    Ok((0..=n)
        .map(|i| NodeLink::Udp {
            listen: addrs[i],
            next: addrs[(i + 1) % (n + 1)],
        })
        .collect())
}

/// The host's `CLOCK_MONOTONIC` now \[ns\]: the clock a plan's epoch is on.
pub fn monotonic_now_ns() -> i64 {
    sys::now_ns()
}

/// How long the master's start-up phase takes on a cycle of `t_cyc` \[ns\] with `opts`'
/// probes (each [`crate::node::PROBE_INTERVAL`] apart, or a cycle when shorter, and a
/// margin) \[ns\].
pub fn start_up_ns(opts: &RtOptions, t_cyc: i64) -> i64 {
    let probes = opts.calibration_rounds.max(2) as i64;
    probes * t_cyc.min(crate::node::PROBE_INTERVAL.as_ns()) + START_UP_MARGIN
}

/// The plan of a ring of node processes: the scenario of TOML `text` (from `origin`) run
/// with `opts`, node i on `links[i]` (0 the master), the run's time 0 at `epoch_ns` on the
/// host's `CLOCK_MONOTONIC` (the master's start-up phase begins [`start_up_ns`] before).
pub fn node_plan(
    text: &str,
    origin: &str,
    opts: &RtOptions,
    links: Vec<NodeLink>,
    epoch_ns: i64,
) -> Result<NodePlan, RtError> {
    let scenario = crate::run::as_run(&Scenario::from_toml(text, origin)?, opts);
    let t_cyc = scenario.ring.cycle.0.as_ns();
    let plan = NodePlan {
        scenario: text.to_string(),
        origin: origin.to_string(),
        duration_ns: opts.duration.map(|d| d.as_ns()),
        cycle_ns: opts.cycle.map(|d| d.as_ns()),
        watchdog_cycles: opts.watchdog_cycles,
        sample_lead_ns: Some(scenario.clock.sample_lead.0.as_ns()),
        response_timeout_ns: opts.response_timeout.as_ns(),
        probes: opts.calibration_rounds.max(2),
        epoch_ns,
        start_up_ns: start_up_ns(opts, t_cyc),
        priority: opts.realtime.priority,
        spin_ns: opts.realtime.spin.as_ns(),
        lock_memory: opts.realtime.lock_memory,
        links,
        sense_carrier: false,
        cpu: None,
        capture_dir: None,
        stamps: opts.stamps.in_processes(),
        kill: opts.kill.map(|k| crate::node::NodeKill {
            slave: k.slave,
            at_ns: k.at.as_ns(),
        }),
        // On veth the launcher takes the link down itself.
        flap: opts
            .flap
            .filter(|_| opts.transport != TransportKind::Veth)
            .map(|f| crate::node::NodeFlap {
                from: f.from,
                at_ns: f.at.as_ns(),
                until_ns: f.at.as_ns() + f.down_for.as_ns(),
            }),
        live: false,
    };
    // Checks the links and the slave taken out against the ring.
    let n = plan.spec()?.axes();
    if let Some(k) = plan.kill
        && (k.slave == 0 || k.slave > n)
    {
        return Err(RtError::Config(format!(
            "--kill-slave {} is not a slave of this ring (1..={n})",
            k.slave
        )));
    }
    Ok(plan)
}

/// One run's result from what its node processes saw (`records`, one per node, any order)
/// on the ring `plan` describes: the launcher's, or a ring started by hand (`ringsync node
/// gather`). `stopped`: the run was told to stop early. `trace`: keep the per-cycle trace.
pub fn gather(
    plan: &NodePlan,
    records: &[NodeRecord],
    stopped: bool,
    trace: bool,
) -> Result<RtResult, RtError> {
    let spec = plan.spec()?;
    let n = spec.axes();
    // Exactly one record per node, in node order.
    let mut by_node: Vec<Option<&NodeRecord>> = vec![None; n + 1];
    for r in records {
        match by_node.get_mut(r.node) {
            Some(slot @ None) => *slot = Some(r),
            Some(Some(_)) => {
                return Err(RtError::Config(format!(
                    "two records of node {} (0 the master)",
                    r.node
                )));
            }
            None => {
                return Err(RtError::Config(format!(
                    "a record of node {}, on a ring of {} nodes (0 the master)",
                    r.node,
                    n + 1
                )));
            }
        }
    }
    let records: Vec<NodeRecord> = by_node
        .iter()
        .enumerate()
        .map(|(i, r)| {
            r.cloned().ok_or_else(|| {
                RtError::Config(format!(
                    "no record of {}",
                    if i == 0 {
                        "the master".to_string()
                    } else {
                        format!("slave {i}")
                    }
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let transport = match &plan.links[0] {
        NodeLink::Udp { .. } => TransportKind::Udp,
        NodeLink::Raw { netns: Some(_), .. } => TransportKind::Veth,
        NodeLink::Raw { netns: None, .. } => TransportKind::Raw,
    };
    let response_timeout = ringsync_proto::Duration::from_ns(plan.response_timeout_ns);
    let interrupted = stopped || records.iter().any(|r| r.interrupted);
    let master = &records[0];
    let mut run = merge(&spec, &records, trace);
    if let Some((t, _)) = run.group_stop {
        run.ring_break
            .get_or_insert_with(|| ring_break(&spec, &records, t));
    }
    // A slave taken out (`--kill-slave`): when its process went silent, and how many
    // cycles later the master stopped the group (cycles begun, as one process counts them).
    let t_cyc = spec.scenario.ring.cycle.0.as_ns().max(1) as f64 * 1e-9;
    let killed = plan
        .kill
        .and_then(|k| Some((k.slave, records.get(k.slave)?.taken_out_s?)));
    let detection_cycles = killed
        .zip(run.group_stop.as_ref())
        .map(|((_, at), (t, _))| (t / t_cyc).floor() as i64 - (at / t_cyc).floor() as i64);
    let mut realtime = master.realtime.clone();
    realtime.push(format!(
        "one process per node ({} processes), each its own loop; slaves sleep to their deadlines",
        n + 1
    ));
    // A slave whose CPU differs from the master's (a pin refused, or a ring by hand).
    let pin_of = |r: &NodeRecord| r.realtime.iter().find(|l| l.contains("pin")).cloned();
    for r in records.iter().skip(1) {
        if let Some(l) = pin_of(r).filter(|l| Some(l) != pin_of(master).as_ref()) {
            realtime.push(format!("slave {}: {l}", r.node));
        }
    }
    let Some(mut calibration) = master.calibration.clone() else {
        return Err(RtError::Node(if interrupted {
            "interrupted in the start-up phase, before the run began: no results".into()
        } else {
            "the master ended without its start-up figures".into()
        }));
    };
    // What each slave took, and refused, in its own start-up phase.
    let su = &mut calibration.start_up;
    for (t, r) in su.taken.iter_mut().zip(records.iter().skip(1)) {
        *t = r.path_delay_ns.map(ringsync_proto::Duration::from_ns);
    }
    su.slaves_rejected = records.iter().skip(1).map(|r| r.start_up_rejected).sum();
    run.start_up = Some(calibration.start_up.clone());
    // The master's configuration: the same schedule from the same figures.
    let mut ran = spec.clone();
    crate::schedule::apply(&mut ran, &calibration, response_timeout)?;
    // Each slave's clock window as it ran (its own estimate of the ring's path).
    for (c, r) in ran.slaves.iter_mut().zip(records.iter().skip(1)) {
        if let Some(w) = r.clock_window_ns {
            c.clock_window = ringsync_proto::Duration::from_ns(w);
        }
    }
    let counted_malformed = crate::run::malformed_counted(&run);
    let links_in_run =
        (plan.stamps.in_processes() == crate::Stamps::Kernel).then(|| crate::run::LinksInRun {
            link_ns: master.link_in_run.map(|(l, _)| l),
            estimates: master.link_in_run.map_or(0, |(_, k)| k),
            path_delay_end_ns: records
                .iter()
                .skip(1)
                .map(|r| r.path_delay_end_ns)
                .collect(),
            refused: records
                .iter()
                .skip(1)
                .filter_map(|r| r.slave.map(|c| c.links_refused))
                .sum(),
        });
    Ok(RtResult {
        links_in_run,
        scenario: spec.scenario.clone(),
        spec: ran,
        transport,
        stamps: plan.stamps.in_processes(),
        run,
        timing: Timing {
            // Every node's frames dropped beside a broken link.
            broken_dropped: records.iter().map(|r| r.broken_dropped).sum(),
            receive_errors: records.iter().map(|r| r.receive_errors).sum(),
            flap_dropped: records.iter().map(|r| r.flap_dropped).sum(),
            relay_corrected: records.iter().map(|r| r.relay_corrected).sum(),
            relay_uncorrected: records.iter().map(|r| r.relay_uncorrected).sum(),
            ..master.timing.clone().unwrap_or_default()
        },
        schedule: master.schedule.unwrap_or(crate::schedule::Schedule {
            p2p_start: 0,
            slice: 0,
            response_timeout: response_timeout.as_ns(),
        }),
        calibration,
        realtime,
        // What the nodes made of frames injected (the launcher adds what it injected).
        injected: Injection {
            counted_malformed,
            malformed_unread: records.iter().map(|r| r.unread_at_end.0).sum(),
            valid_unread: records.iter().map(|r| r.unread_at_end.1).sum(),
            ..Injection::default()
        },
        nodes_rx: records
            .iter()
            .map(|r| (r.frames_read, r.last_read_s))
            .collect(),
        interrupted,
        killed,
        detection_cycles,
        streamed: Streamed {
            live_dropped: records.iter().map(|r| r.live_dropped).sum(),
            ..Streamed::default()
        },
    })
}

/// Cycles a node may be ahead of one that has not told a cycle's start before the merge
/// hands that cycle over without it (a node that stopped, or a slow pipe).
const LIVE_LAG: i64 = 8;

/// One cycle of a live view being put together from the nodes' lines.
struct LiveCycle {
    probes: Vec<AxisProbe>,
    /// Each node's axis state (its cycle start) told.
    told: Vec<bool>,
    views: Vec<Option<NodeView>>,
    timing: Option<(i64, bool)>,
}

impl LiveCycle {
    /// Every node has told its cycle start and its view, and the master its lateness.
    fn complete(&self) -> bool {
        self.timing.is_some()
            && self.told.iter().all(|t| *t)
            && self.views.iter().all(Option::is_some)
    }
}

/// Tells `observers` what the `n` + 1 nodes of a ring with a live view write (`lines`: the
/// node's index and one [`Live`] line), as one process tells its observers: cycle k (of
/// `t_cyc` ns) once every node has told its start and its view (the master's desired
/// positions, each slave's own axis) and the master its lateness, then that timing and the
/// nodes' views; the other events as they come.
/// A cycle some node has not told is handed over once another node is `LIVE_LAG` cycles
/// on, with that node's last axis state and view. Returns the observers when the lines end.
pub fn live_merge(
    lines: &std::sync::mpsc::Receiver<(usize, String)>,
    mut observers: Vec<Box<dyn Observer>>,
    n: usize,
    t_cyc: i64,
) -> Vec<Box<dyn Observer>> {
    let mut cycles: BTreeMap<i64, LiveCycle> = BTreeMap::new();
    let mut next = 0i64;
    let mut newest = -1i64;
    let mut last_probe = vec![AxisProbe::AT_REST; n];
    let mut last_view = vec![NodeView::default(); n + 1];
    let fresh = || LiveCycle {
        probes: vec![AxisProbe::AT_REST; n],
        told: vec![false; n + 1],
        views: vec![None; n + 1],
        timing: None,
    };
    let mut hand_over = |observers: &mut [Box<dyn Observer>], k: i64, c: LiveCycle| {
        let mut probes = c.probes;
        for (i, p) in probes.iter_mut().enumerate() {
            if c.told[i + 1] {
                last_probe[i] = *p;
            } else {
                // Not told: the axis as last told, under this cycle's desired position.
                *p = AxisProbe {
                    x_d: p.x_d,
                    ..last_probe[i]
                };
            }
        }
        for (v, last) in c.views.iter().zip(last_view.iter_mut()) {
            if let Some(v) = v {
                *last = *v;
            }
        }
        let stopping = last_view[0].stopping;
        let views: Vec<NodeView> = last_view
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if i == 0 {
                    *v
                } else {
                    v.with_master_stopping(stopping)
                }
            })
            .collect();
        let t = k as f64 * t_cyc as f64 * 1e-9;
        for o in observers.iter_mut() {
            o.cycle(k, t, &probes);
            if let Some((late, stalled)) = c.timing {
                o.timing(k, late, stalled);
            }
            o.node_views(k, &views);
        }
    };
    for (node, line) in lines.iter() {
        let Ok(live) = serde_json::from_str::<Live>(&line) else {
            continue;
        };
        if node > n {
            continue;
        }
        match live {
            Live::Tap(Tapped {
                ev: Tap::Cycle { k, probes },
                ..
            }) => {
                if k < next {
                    continue;
                }
                let c = cycles.entry(k).or_insert_with(fresh);
                if node == 0 {
                    for (a, m) in c.probes.iter_mut().zip(&probes) {
                        a.x_d = m.x_d;
                    }
                } else if let (Some(a), Some(s)) = (c.probes.get_mut(node - 1), probes.first()) {
                    *a = AxisProbe { x_d: a.x_d, ..*s };
                }
                c.told[node] = true;
                newest = newest.max(k);
            }
            Live::Tap(Tapped { ev, .. }) => {
                for o in observers.iter_mut() {
                    match &ev {
                        Tap::Cycle { .. } => {}
                        Tap::Computed { k, record } => o.computed(*k, record),
                        Tap::Applied { axis, t, u } => o.applied(*axis, *t, *u),
                        Tap::Fault(f) => o.fault(f),
                        Tap::Monitor(m) => o.monitor(m),
                        Tap::Ring(c) => o.ring(c),
                    }
                }
            }
            Live::View { k, view } if k >= next => {
                cycles.entry(k).or_insert_with(fresh).views[node] = Some(view);
            }
            Live::Timing {
                k,
                lateness_ns,
                stalled,
            } if k >= next => {
                cycles.entry(k).or_insert_with(fresh).timing = Some((lateness_ns, stalled));
            }
            Live::View { .. } | Live::Timing { .. } => {}
        }
        // Hand over, in order, every cycle all nodes have told, and one left behind.
        while let Some(c) = cycles.get(&next) {
            if !c.complete() && newest < next + LIVE_LAG {
                break;
            }
            if let Some(c) = cycles.remove(&next) {
                hand_over(&mut observers, next, c);
            }
            next += 1;
        }
    }
    // The lines have ended: what is left, in order.
    for (k, c) in std::mem::take(&mut cycles) {
        hand_over(&mut observers, k, c);
    }
    observers
}

/// Where the ring of node processes broke at a group stop at `t` [s], from what each node
/// last read (the processes keep no master's view of the slaves, as one process does):
/// [`locate_break`](ringsync_model::locate::locate_break) with a node's last frame read for
/// the last lumped frame it took (behind a break nothing reaches a node, and ahead of it
/// the cycles go on after the stop), and a slave taken out (`--kill-slave`) as one that
/// stopped running.
fn ring_break(spec: &Spec, records: &[NodeRecord], t: f64) -> ringsync_model::locate::RingBreak {
    let t_cyc = spec.scenario.ring.cycle.0.as_ns().max(1) as f64 * 1e-9;
    let cycle = |s: f64| (s / t_cyc).floor() as i64;
    let seen = |r: &NodeRecord| r.last_read_s.map(cycle);
    let slaves = records.get(1..).unwrap_or_default();
    let running: Vec<bool> = slaves
        .iter()
        .map(|r| r.taken_out_s.is_none_or(|out| out > t))
        .collect();
    let slaves_seen: Vec<Option<i64>> = slaves.iter().map(seen).collect();
    ringsync_model::locate::locate_break(
        cycle(t),
        &slaves_seen,
        records.first().and_then(seen),
        &running,
    )
}

/// One run's result from the records of its nodes: every cycle's probe made of the
/// master's desired positions and each slave's own axis, and every event, replayed into a
/// recorder in true-time order (as an in-process run's recorder is told them).
pub fn merge(spec: &Spec, records: &[NodeRecord], trace: bool) -> RunResult {
    let n = spec.axes();
    let t_cyc = spec.scenario.ring.cycle.0.as_ns();
    let cycles = spec.scenario.duration.0.as_ns() / t_cyc;
    let zero = AxisProbe::AT_REST;
    // Each cycle's probes: x_d from the master, the rest from each slave.
    let mut probes: BTreeMap<i64, Vec<AxisProbe>> = BTreeMap::new();
    for r in records {
        for e in &r.events {
            if let Tap::Cycle { k, probes: p } = &e.ev {
                let row = probes.entry(*k).or_insert_with(|| vec![zero; n]);
                if r.node == 0 {
                    for (a, m) in row.iter_mut().zip(p) {
                        a.x_d = m.x_d;
                    }
                } else if let (Some(a), Some(s)) = (row.get_mut(r.node - 1), p.first()) {
                    a.x = s.x;
                    a.clock_error_ns = s.clock_error_ns;
                    a.u = s.u;
                    a.saturated = s.saturated;
                }
            }
        }
    }
    let mut events: Vec<(i64, usize, usize, &Tap)> = records
        .iter()
        .flat_map(|r| {
            r.events
                .iter()
                .enumerate()
                .map(move |(j, e)| (e.t, r.node, j, &e.ev))
        })
        .collect();
    events.sort_by_key(|(t, node, j, _)| (*t, *node, *j));
    // The cycles every node saw the start of: a partial run (a node stopped earlier than
    // another) keeps only those, so that no axis's row is made up.
    let last = records
        .iter()
        .map(|r| {
            r.events
                .iter()
                .filter_map(|e| match e.ev {
                    Tap::Cycle { k, .. } => Some(k),
                    _ => None,
                })
                .max()
                .unwrap_or(-1)
        })
        .min()
        .unwrap_or(-1)
        .min(cycles - 1);
    let end = (last + 1) * t_cyc;
    let mut rec = Recorder::new(n, cycles, t_cyc as f64 * 1e-9, trace);
    if let (Ok(Some(map)), Ok(Some(path))) =
        (spec.scenario.machine_map(), spec.scenario.planned_path())
    {
        rec = rec.with_contour(map, path);
    }
    let mut last_k = -1;
    for (t, _, _, ev) in events {
        if t >= end {
            break;
        }
        match ev {
            Tap::Cycle { k, .. } => {
                if *k > last_k
                    && let Some(p) = probes.get(k)
                {
                    rec.cycle(*k, *k as f64 * t_cyc as f64 * 1e-9, p);
                    last_k = *k;
                }
            }
            Tap::Computed { k, .. } if *k > last => {}
            Tap::Computed { k, record } => rec.computed(*k, record),
            Tap::Applied { axis, t, u } => rec.applied(*axis, *t, *u),
            Tap::Fault(f) => rec.fault(f),
            Tap::Monitor(m) => rec.monitor(m),
            Tap::Ring(c) => rec.ring(c),
        }
    }
    let master: MasterCounters = records.first().and_then(|r| r.master).unwrap_or_default();
    let slaves: Vec<SlaveCounters> = (1..=n)
        .map(|i| {
            records
                .iter()
                .find(|r| r.node == i)
                .and_then(|r| r.slave)
                .unwrap_or_default()
        })
        .collect();
    let mut run = rec.finish(
        &spec.scenario.name,
        master,
        slaves,
        LinkCounters::default(),
        Vec::new(),
        Vec::new(),
    );
    run.cycles = last + 1;
    run
}

#[cfg(test)]
mod tests {
    use ringsync_model::record::{FaultEvent, FaultStep};
    use ringsync_proto::node::SafeState;

    use super::*;
    use crate::node::Tapped;

    fn probe(x: f64, x_d: f64) -> AxisProbe {
        AxisProbe {
            x,
            x_d,
            clock_error_ns: 0.0,
            u: 0.0,
            saturated: false,
        }
    }

    /// A node's record with the cycle starts `0..cycles` (1 ms apart).
    fn record(node: usize, n: usize, cycles: i64) -> NodeRecord {
        let events = (0..cycles)
            .map(|k| Tapped {
                t: k * 1_000_000,
                ev: Tap::Cycle {
                    k,
                    probes: if node == 0 {
                        vec![probe(0.0, 0.5); n]
                    } else {
                        vec![probe(0.5, 0.0)]
                    },
                },
            })
            .collect();
        NodeRecord {
            node,
            events,
            ..NodeRecord::default()
        }
    }

    #[test]
    fn the_merge_keeps_only_cycles_every_node_saw_and_nothing_after_them() {
        let spec = Scenario::from_toml("duration = \"10ms\"\n", "test")
            .expect("scenario")
            .build()
            .expect("spec");
        let n = spec.axes();
        let mut records: Vec<NodeRecord> = (0..=n).map(|i| record(i, n, 6)).collect();
        // Slave 3 stopped after cycle 2 (a SIGTERM that reached it first); slave 1's
        // watchdog fired later, after the cycles every node saw.
        records[3] = record(3, n, 3);
        records[1].events.push(Tapped {
            t: 4_500_000,
            ev: Tap::Fault(FaultEvent {
                t: 4.5e-3,
                axis: 1,
                step: FaultStep::Watchdog(SafeState::Brake),
            }),
        });
        let run = merge(&spec, &records, true);
        assert_eq!(run.cycles, 3);
        assert!(run.faults.is_empty() && run.watchdog.is_empty());
        // Every row takes x_d from the master (0.5; its own x, 0, is not the axes') and x
        // from each slave (0.5; its x_d, 0, is not the master's): e = 0 on every axis.
        assert_eq!(run.summary.track_rmse, 0.0);
        assert_eq!(run.summary.samples, 3);
    }

    /// What a live view is told, in order: ("c", k, axis 0's x, x_d), ("t", k, lateness),
    /// ("v", k, views).
    type Calls = std::sync::Arc<std::sync::Mutex<Vec<(char, i64, f64, f64)>>>;
    #[derive(Default)]
    struct Seen(Calls);

    impl Observer for Seen {
        fn cycle(&mut self, k: i64, _t: f64, axes: &[AxisProbe]) {
            if let Ok(mut v) = self.0.lock() {
                v.push(('c', k, axes[1].x, axes[1].x_d));
            }
        }
        fn timing(&mut self, k: i64, lateness_ns: i64, _stalled: bool) {
            if let Ok(mut v) = self.0.lock() {
                v.push(('t', k, lateness_ns as f64, 0.0));
            }
        }
        fn node_views(&mut self, k: i64, views: &[NodeView]) {
            if let Ok(mut v) = self.0.lock() {
                v.push(('v', k, views.len() as f64, views[2].counters[0] as f64));
            }
        }
    }

    /// The nodes' lines come in any order across nodes: a cycle is told once its every
    /// part is in (slave 2's axis, the master's desired position and lateness, each view),
    /// in cycle order; a node that stops telling (slave 2 after cycle 1) holds its cycles
    /// back only until another is [`LIVE_LAG`] cycles on, then shows as it last was; what
    /// is left is told when the lines end.
    #[test]
    fn a_live_view_is_told_each_cycle_whole_and_in_order() {
        let n = 2;
        let line = |l: &Live| serde_json::to_string(l).expect("json");
        let cycle = |node: usize, k: i64| {
            let probes = if node == 0 {
                vec![probe(0.0, 10.0 + k as f64); n]
            } else {
                vec![probe(k as f64 + node as f64 / 10.0, 0.0)]
            };
            line(&Live::Tap(Tapped {
                t: k,
                ev: Tap::Cycle { k, probes },
            }))
        };
        let view = |k: i64, frames: u64| {
            line(&Live::View {
                k,
                view: NodeView {
                    counters: [frames, 0, 0, 0],
                    ..NodeView::default()
                },
            })
        };
        let timing = |k: i64| {
            line(&Live::Timing {
                k,
                lateness_ns: 100 + k,
                stalled: false,
            })
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let send = |node: usize, l: String| tx.send((node, l)).expect("send");
        // Cycle 0: slave 2 first, the master's lateness last.
        send(2, cycle(2, 0));
        send(2, view(0, 1));
        send(1, cycle(1, 0));
        send(0, cycle(0, 0));
        send(1, view(0, 1));
        send(0, view(0, 1));
        send(9, cycle(2, 0)); // a node that is not on the ring: ignored
        send(0, "not a line of ours".into());
        send(0, timing(0));
        // Cycles 1..=12: slave 2 tells cycle 1 only.
        for k in 1..=12 {
            for node in 0..=n {
                if node == 2 && k > 1 {
                    continue;
                }
                send(node, cycle(node, k));
                send(node, view(k, 1 + k as u64));
            }
            send(0, timing(k));
        }
        drop(tx);
        let seen = Seen::default();
        let got = seen.0.clone();
        let observers: Vec<Box<dyn Observer>> = vec![Box::new(seen)];
        let back = live_merge(&rx, observers, n, 1_000_000);
        assert_eq!(back.len(), 1);
        let got = got.lock().expect("lock").clone();
        // Three calls a cycle, cycles 0..=12 in order.
        let ks: Vec<i64> = got.iter().map(|g| g.1).collect();
        let want: Vec<i64> = (0..=12).flat_map(|k| [k, k, k]).collect();
        assert_eq!(ks, want);
        // Cycle 0 whole: slave 2's axis and the master's desired position, its lateness.
        assert_eq!(got[0], ('c', 0, 0.2, 10.0));
        assert_eq!(got[1], ('t', 0, 100.0, 0.0));
        assert_eq!(got[2], ('v', 0, 3.0, 1.0));
        // After cycle 1, slave 2 as it last was (x 1.2, 2 frames), under each cycle's x_d.
        for k in 2..=12 {
            let at = 3 * k as usize;
            assert_eq!(got[at], ('c', k, 1.2, 10.0 + k as f64));
            assert_eq!(got[at + 2], ('v', k, 3.0, 2.0));
        }
    }
}
