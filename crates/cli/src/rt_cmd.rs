//! `ringsync rt`: the scenario's motion in real time over UDP or a veth ring.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use ringsync::Duration;
use ringsync::layers::runtime::{Flap, Forgery, Pin, Realtime};
use ringsync::{Kill, RtOptions, TransportKind};

use crate::sim_cmd::out_dir;
use crate::{CliError, Outcome, out};

/// Which transport carries the frames.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Transport {
    /// UDP datagrams on 127.0.0.1, one socket per node (no privileges needed).
    Udp,
    /// Raw Ethernet frames on a ring of veth pairs, one network namespace per node (root).
    Veth,
}

pub(crate) fn duration(s: &str) -> Result<Duration, String> {
    let d: Duration = s.parse().map_err(|e| format!("{e}"))?;
    if d.as_ns() < 0 {
        return Err(format!("{s} is negative"));
    }
    Ok(d)
}

/// Options of `ringsync rt`.
#[derive(Args, Debug)]
pub struct RtArgs {
    /// Scenario file or built-in name (see `ringsync scenario list`).
    scenario: String,
    /// Set a scenario key before the run, as `sim --set` and `check --set` do (e.g.
    /// `--set control.law=ccc`); the options below apply on top.
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = crate::sim_cmd::key_value)]
    set: Vec<(String, String)>,
    /// How the frames travel.
    #[arg(long, value_enum)]
    transport: Transport,
    /// Directory for summary.json and trace.csv; checked before the run, replaced as a whole
    /// when it ends (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Run this long instead of the scenario's duration (e.g. 60s).
    #[arg(long, value_parser = duration)]
    duration: Option<Duration>,
    /// Cycle time instead of the scenario's (e.g. 500us), to find the fastest one this
    /// machine holds.
    #[arg(long, value_parser = duration)]
    cycle: Option<Duration>,
    /// W instead of the scenario's faults.watchdog_cycles: cycles without a command before
    /// a slave goes to 0 V, without a response or feedback before the master stops the
    /// group. On a virtual machine the host can freeze the loop for several ms (see
    /// `ringsync latency`); W must be longer, or such a freeze ends the run in a group stop.
    #[arg(long, value_name = "W")]
    watchdog_cycles: Option<u32>,
    /// Also write every frame the nodes send, with its send time, as pcapng.
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
    #[command(flatten)]
    realtime: RealtimeArgs,
    /// How long the master waits for a response beyond the measured time slice.
    #[arg(long, value_parser = duration, default_value = "200us")]
    response_timeout: Duration,
    /// Take this slave (1-based) out of the ring mid-run: it reads and sends nothing more
    /// (its sockets close; with --processes its process goes silent) and, on veth, its
    /// links go down.
    #[arg(long, requires = "kill_at")]
    kill_slave: Option<usize>,
    /// When to take the slave out, from the start (e.g. 1s).
    #[arg(long, value_parser = duration, requires = "kill_slave")]
    kill_at: Option<Duration>,
    /// Inject garbage and bad-CRC frames onto the ring at this rate [frames/s].
    #[arg(long, default_value_t = 0.0)]
    inject_garbage: f64,
    /// Inject forged frames with a valid CRC (repeatable): wrong-cycle-commands (commands
    /// 2-1000 cycles behind or 200-1000 ahead at ±10 V, 1000/s), future-lumped (lumped frames stamped 1 s ahead,
    /// 100/s), sync-burst (30 lumped frames with a wrong cycle and a far timestamp, 1/s).
    #[arg(long, value_name = "KIND")]
    forge: Vec<Forgery>,
    /// Take a link down for a while: A-B, the link from node A to the next node B (m is the
    /// master), e.g. 2-3, m-1, 4-m. veth: both ends go down with `ip`; UDP: the runtime
    /// drops what the link would carry.
    #[arg(long, value_name = "A-B", requires_all = ["flap_at", "flap_for"])]
    flap_link: Option<String>,
    /// When the link goes down, from the start (e.g. 1s).
    #[arg(long, value_parser = duration, requires = "flap_link")]
    flap_at: Option<Duration>,
    /// How long the link stays down (e.g. 8ms).
    #[arg(long, value_parser = duration, requires = "flap_link")]
    flap_for: Option<Duration>,
    /// Break link I at T, and heal it at T2 with I@T..T2 (repeatable; replaces the
    /// scenario's faults.break_link). Link I joins node I-1 to node I, 0 and n+1 being the
    /// master's two ports; the nodes beside it sense it, as a PHY does, and the master
    /// reaches every slave from both ends (docs/safety.md, "Ring redundancy"). veth: the
    /// link goes down with `ip`; UDP: the nodes beside it stop sending on it.
    #[arg(long, value_name = "I@T")]
    break_link: Vec<String>,
    /// Slaves latch their encoders this long before each cycle start (default: the
    /// scenario's clock.sample_lead, or 100us when that is 0). Software-stamped clocks are
    /// off by tens of µs, and a host stall can hold the loop past the latch; a latch after
    /// the lumped frame has passed sends last cycle's sample.
    #[arg(long, value_parser = duration)]
    sample_lead: Option<Duration>,
    /// How the slaves stamp the lumped frames their clocks follow: phy (the default in one
    /// loop, --in-process: the instant the master sent the frame plus the slave's path
    /// delay, as the scenario's hardware stamps on links of constant delay), kernel (node
    /// processes only, their default: the instant the frame reached the node's socket,
    /// before its process woke; every relay adds the time it held a sync lumped frame to
    /// its stamp, as a PTP transparent clock) or software (the instant the loop reads the
    /// frame: the clocks then see the loop's forwarding jitter, µs to tens of µs).
    #[arg(long, value_name = "KIND")]
    stamps: Option<ringsync::Stamps>,
    /// Skip the simulator's prediction for the same scenario.
    #[arg(long)]
    no_sim_prediction: bool,
    /// Run every node as its own process (`ringsync node master`, `ringsync node slave
    /// --index I`), each with its own port, clock and loop, and gather their results: the
    /// default on veth; on UDP this option asks for it. The nodes stamp frames with the
    /// kernel's receive time (--stamps), all pinned to one CPU (the last no other run has
    /// claimed, --cpu N, or --no-pin), which a 1 ms cycle needs on a small host; --pcap:
    /// every frame each node sent, merged once they are done; --kill-slave: that slave's
    /// process goes silent; frames injected by the launcher; --scope: fed by what the nodes
    /// write as they run. A broken link (--break-link) on veth only.
    #[arg(long, conflicts_with = "in_process")]
    processes: bool,
    /// Run every node in one loop of this process (the default on UDP): the slaves can
    /// then stamp frames as PHYs would (--stamps phy, its default), which no ring of
    /// processes can emulate.
    #[arg(long)]
    in_process: bool,
    #[cfg(feature = "scope")]
    #[command(flatten)]
    scope: crate::scope_opt::RtScopeArgs,
}

/// The real-time options shared by `ringsync rt` and `ringsync latency`.
#[derive(Args, Debug)]
pub struct RealtimeArgs {
    /// Busy-wait this long before each deadline.
    #[arg(long, value_parser = duration, default_value = "150us")]
    spin: Duration,
    /// SCHED_FIFO priority of the loop (1-99); 0 keeps the normal scheduler.
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(0..=99))]
    priority: i32,
    /// CPU to pin the loop to, or every node process of a ring of processes (default: the
    /// last one no other ringsync run has claimed; one another run holds is not shared:
    /// the ring then runs unpinned, with a warning).
    #[arg(long)]
    cpu: Option<usize>,
    /// Do not pin the loop (or the node processes) to a CPU.
    #[arg(long, conflicts_with = "cpu")]
    no_pin: bool,
    /// Do not lock memory (mlockall).
    #[arg(long)]
    no_mlock: bool,
}

impl RealtimeArgs {
    /// Refuses a `--spin` longer than the cycle `t_cyc` and a `--cpu` this host does not
    /// have.
    pub fn check(&self, t_cyc: Duration) -> Result<(), CliError> {
        if self.spin > t_cyc {
            return Err(CliError::Usage(format!(
                "--spin {} is longer than the cycle ({t_cyc}): expected 0 ..= the cycle",
                self.spin
            )));
        }
        self.check_cpu()
    }

    /// Refuses a `--cpu` this host does not have.
    pub fn check_cpu(&self) -> Result<(), CliError> {
        if let Some(cpu) = self.cpu {
            let cpus = std::thread::available_parallelism().map_or(1, usize::from);
            if cpu >= cpus {
                return Err(CliError::Usage(format!(
                    "--cpu {cpu}: this host gives the run CPUs 0 ..= {}",
                    cpus - 1
                )));
            }
        }
        Ok(())
    }

    /// The settings these options ask for.
    pub fn settings(&self) -> Realtime {
        Realtime {
            spin: self.spin,
            priority: self.priority,
            cpu: match (self.no_pin, self.cpu) {
                (true, _) => Pin::Off,
                (false, Some(c)) => Pin::Cpu(c),
                (false, None) => Pin::Auto,
            },
            lock_memory: !self.no_mlock,
        }
    }
}

/// Runs `ringsync rt`: exit status 3 when the run ends in a group stop, 1 when it is
/// interrupted (its partial results written all the same).
pub(crate) fn rt(args: &RtArgs) -> Result<Outcome, CliError> {
    let loaded = ringsync::with_values(&ringsync::load(&args.scenario)?, &args.set)?;
    let loaded = if args.break_link.is_empty() {
        loaded
    } else {
        let list: Vec<String> = args.break_link.iter().map(|b| format!("{b:?}")).collect();
        let set = [(
            "faults.break_link".to_string(),
            format!("[{}]", list.join(", ")),
        )];
        ringsync::with_values(&loaded, &set)?
    };
    let s = &loaded.scenario;
    if !(args.inject_garbage >= 0.0 && args.inject_garbage <= 100_000.0) {
        return Err(CliError::Usage(format!(
            "--inject-garbage {} is out of range (0 to 100000 frames/s)",
            args.inject_garbage
        )));
    }
    let n = s.axes_count();
    if let Some(c) = args.cycle
        && c <= Duration::ZERO
    {
        return Err(CliError::Usage(format!(
            "--cycle {} s: a cycle must last some time (e.g. 1ms)",
            c.as_ns() as f64 * 1e-9
        )));
    }
    args.realtime.check(args.cycle.unwrap_or(s.ring.cycle.0))?;
    // The faults must fall inside the run, or they would silently never happen.
    let run_for = args.duration.unwrap_or(s.duration.0);
    for (flag, at) in [("--kill-at", args.kill_at), ("--flap-at", args.flap_at)] {
        if let Some(at) = at
            && at >= run_for
        {
            let s = |d: Duration| d.as_ns() as f64 * 1e-9;
            return Err(CliError::Usage(format!(
                "{flag} {} s is not inside the run ({} s): the fault would never happen",
                s(at),
                s(run_for)
            )));
        }
    }
    if let Some(b) = s.faults.break_link.iter().find(|b| b.at >= run_for) {
        let secs = |d: Duration| d.as_ns() as f64 * 1e-9;
        return Err(CliError::Usage(format!(
            "the break of link {} at {} s (--break-link or faults.break_link) is not inside the run ({} s): it would never happen",
            b.link,
            secs(b.at),
            secs(run_for)
        )));
    }
    if let Some(d) = args.flap_for
        && d <= Duration::ZERO
    {
        return Err(CliError::Usage(format!(
            "--flap-for {} s: the link must stay down for some time (e.g. 8ms)",
            d.as_ns() as f64 * 1e-9
        )));
    }
    let flap = match (&args.flap_link, args.flap_at, args.flap_for) {
        (Some(link), Some(at), Some(down_for)) => Some(Flap {
            from: Flap::parse_link(link, n)
                .map_err(|e| CliError::Usage(format!("--flap-link {link}: {e}")))?,
            at,
            down_for,
        }),
        _ => None,
    };
    // Before the ring runs: an --out that cannot be written fails now, not after the run.
    let mut dir = out_dir(&args.out, &loaded)?;
    // A ring of node processes: the default on veth, asked for on UDP.
    let processes = match args.transport {
        Transport::Veth => !args.in_process,
        Transport::Udp => args.processes,
    };
    let stamps = match (processes, args.stamps) {
        (false, None) => ringsync::Stamps::Phy,
        (true, None) => ringsync::Stamps::Kernel,
        (false, Some(ringsync::Stamps::Kernel)) => {
            return Err(CliError::Usage(
                "--stamps kernel is for a ring of node processes (the default on veth; --processes on UDP): use phy or software in one loop".into(),
            ));
        }
        (true, Some(ringsync::Stamps::Phy)) => {
            return Err(CliError::Usage(
                "--stamps phy needs the one loop that sees the master's sends (--in-process): a ring of node processes stamps kernel or software".into(),
            ));
        }
        (_, Some(s)) => s,
    };
    let opts = RtOptions {
        transport: match args.transport {
            Transport::Udp => TransportKind::Udp,
            Transport::Veth => TransportKind::Veth,
        },
        duration: args.duration,
        cycle: args.cycle,
        watchdog_cycles: args.watchdog_cycles,
        realtime: args.realtime.settings(),
        response_timeout: args.response_timeout,
        capture: args.pcap.is_some(),
        kill: args
            .kill_slave
            .zip(args.kill_at)
            .map(|(slave, at)| Kill { slave, at }),
        garbage_rate: args.inject_garbage,
        forge: args.forge.clone(),
        flap,
        sample_lead: args.sample_lead,
        stamps,
        verbose: true,
        ..RtOptions::default()
    };
    let stop = ringsync::layers::runtime::stop_flag();
    #[cfg(feature = "scope")]
    let (scope, observers) = crate::scope_opt::start_ab(
        args.scope.scope,
        args.scope.scope_ab,
        &ringsync::layers::runtime::run::as_run(s, &opts),
        ringsync_scope::Source::Realtime,
        "rt",
    )?;
    #[cfg(not(feature = "scope"))]
    let observers = Vec::new();
    // trace.csv and the capture are written as the run goes: its memory does not grow
    // with its duration.
    let r = if processes {
        ringsync::rt::run_rt_processes(
            &mut dir,
            &loaded,
            &opts,
            stop,
            args.pcap.as_deref(),
            observers,
        )?
    } else {
        ringsync::rt::run_rt_streamed(
            &mut dir,
            s,
            loaded.hash,
            &opts,
            stop,
            observers,
            args.pcap.as_deref(),
        )?
    };
    #[cfg(feature = "scope")]
    scope.finish(&r.scenario, loaded.hash, &r.run);
    write_run(
        dir,
        &r,
        &loaded,
        !args.no_sim_prediction,
        args.pcap.as_deref(),
        &args.out,
    )?;
    if r.interrupted {
        return Err(CliError::Failure(match args.transport {
            Transport::Veth => {
                "interrupted; partial results written, namespaces and links removed".into()
            }
            Transport::Udp => "interrupted; partial results written".into(),
        }));
    }
    Ok(Outcome::flagged_if(r.run.group_stop.is_some()))
}

/// Writes a real-time run into `dir` (shown as `shown`) and commits it: summary.json (with
/// the simulator's predictions, the scenario as run and the ring as measured, when
/// `predict`), trace.csv, scenario.toml, the capture to `pcap`; then prints the run's text.
pub(crate) fn write_run(
    mut dir: ringsync::OutDir,
    r: &ringsync::RtResult,
    loaded: &ringsync::Loaded,
    predict: bool,
    pcap: Option<&std::path::Path>,
    shown: &std::path::Path,
) -> Result<(), CliError> {
    let prediction = if predict {
        Some(ringsync::predict_rt(r, 8)?)
    } else {
        None
    };
    ringsync::rt::write_rt(&mut dir, r, loaded.hash, prediction, pcap)?;
    ringsync::identify::write_scenario(&dir, loaded, None)?;
    dir.commit()?;
    out(&format!(
        "{}  wrote {}/summary.json and trace.csv\n",
        ringsync::rt::rt_text(r, prediction),
        shown.display()
    ))?;
    Ok(())
}
