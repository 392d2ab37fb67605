//! Real runs of the reference scenario on loopback UDP and on a veth ring of network
//! namespaces. They need root for the veth cases (CI runs as root); without it they fail with
//! the reason rather than pass silently. Runs are serialised: they measure real time.

use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, OnceLock};

use ringsync::layers::model::locate::RingBreak;
use ringsync::layers::proto::node::Reject;
use ringsync::layers::runtime::netns::ringsync_namespaces;
use ringsync::layers::runtime::{Flap, Forgery};
use ringsync::{
    Duration, FaultStep, Kill, RtOptions, RtResult, Scenario, SimPrediction, TransportKind,
    predict as sim_prediction,
};

/// A real-time run through the front door.
fn run(s: &Scenario, opts: &RtOptions, stop: &AtomicBool) -> ringsync::Result<RtResult> {
    ringsync::run_rt(s, opts, stop, Vec::new())
}

static SERIAL: Mutex<()> = Mutex::new(());
static PREDICTION: OnceLock<SimPrediction> = OnceLock::new();

fn ours_left() -> Vec<String> {
    let mine = format!("ringsync-{}-", std::process::id());
    ringsync_namespaces()
        .into_iter()
        .filter(|n| n.starts_with(&mine))
        .collect()
}

fn run_ref(opts: RtOptions) -> RtResult {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let stop = AtomicBool::new(false);
    let r = run(&Scenario::default(), &opts, &stop)
        .unwrap_or_else(|e| panic!("the {} ring did not run: {e}", opts.transport.name()));
    assert!(
        ours_left().is_empty(),
        "namespaces left behind: {:?}",
        ours_left()
    );
    r
}

/// A run the host left alone: its longest outage (consecutive cycles that lost their
/// lumped frame or a command) shorter than W, and no more than W cycles left unstarted at
/// the end. A virtual machine's host now and then holds the loop off its CPU for
/// milliseconds on end (docs/runtime.md: the host's stalls, measured without the ring); when
/// that cuts the ring for W cycles, the slaves' watchdogs put the drives in their safe state
/// and the master stops the group, as they must, and the run is an experiment in stopping
/// axes, not a measurement of the runtime. The criterion is the ring's own outage counter,
/// not the figures the test then checks; such a run is repeated (at most [`ATTEMPTS`] in
/// all), and when every attempt was cut the test fails. Shorter outages stay in the
/// measured runs. Measured over 30 UDP runs of this build here: 29 with outages under W,
/// Sync-RMSE within −13.4 % and +10.1 % of the simulator's; one cut for 8 cycles.
///
/// A run is also the host's doing when the host stalled the loop into an overrun in 2 % of
/// its cycles or more, by the ring's own stall accounting: with both cores busy (the suite
/// run under `stress-ng --cpu 2`), one run had 370 overruns with cycle-start lateness p99 of
/// 2.3 ms, and its Sync-RMSE was 2.3× the simulator's. Such a run measures the host, not the
/// runtime, and is repeated like a cut one. Tests of what a fault does, not of the figures
/// the runs measure, leave the 2 % rule out: they assert what the ring did about the fault
/// (counted, survived, named), and a busy host's stalls change that only when they stop the
/// group (a loaded CI host stalled 3 % to 30 % of the cycles of four link-flap runs in a
/// row, and every one rode out the flap).
fn run_undisturbed(opts: RtOptions) -> RtResult {
    run_uncut(opts, |r| host_stalled(r).or_else(|| host_outage(r)))
}

/// Why a run measures the host rather than the runtime: the host stalled the loop into an
/// overrun in 2 % of its cycles or more (see [`run_undisturbed`]).
fn host_stalled(r: &RtResult) -> Option<String> {
    let t = &r.timing;
    (t.overruns_stalled as i64 * 50 >= t.cycles_planned).then(|| {
        format!(
            "the host stalled {} of {} cycles into overruns (longest stall {} µs)",
            t.overruns_stalled,
            t.cycles_planned,
            t.stalls.max / 1_000
        )
    })
}

/// Why a run was cut by the host: an outage of W cycles or more, or W cycles never started,
/// with host stalls that account for it. An outage of W without such stalls is the ring's
/// own failure, and fails the test at once.
fn host_outage(r: &RtResult) -> Option<String> {
    let t = &r.timing;
    let w = u64::from(r.scenario.faults.watchdog_cycles);
    // The host may also hold the loop past the run's end: cycles it never started.
    let unstarted = (t.cycles_planned - t.cycles) as u64;
    if t.longest_outage < w && unstarted < w {
        return None;
    }
    // Only the host's doing if the host held the loop for a cycle or more, or stalled as
    // many of the lost cycles as the outage is long.
    let t_cyc = r.scenario.ring.cycle.0.as_ns();
    assert!(
        t.stalls.max >= t_cyc || t.overruns_stalled >= t.longest_outage,
        "an outage of {} cycles without a host stall of a cycle (longest {} µs, {} stalled overruns): the ring failed, not the host; stop {:?}, rejected {}",
        t.longest_outage,
        t.stalls.max / 1_000,
        t.overruns_stalled,
        r.run.group_stop,
        ringsync::layers::runtime::run::rejected_summary(&r.run)
    );
    Some(format!(
        "outage of {} cycles, {unstarted} unstarted (W = {w}), host stall up to {} µs",
        t.longest_outage,
        t.stalls.max / 1_000
    ))
}

/// Runs until a run is not cut by the host (`cut` says why one was), at most
/// [`ATTEMPTS`] times.
fn run_uncut(opts: RtOptions, cut: impl Fn(&RtResult) -> Option<String>) -> RtResult {
    let mut why = Vec::new();
    for _ in 0..ATTEMPTS {
        let r = run_ref(opts.clone());
        match cut(&r) {
            None => {
                if !why.is_empty() {
                    eprintln!("earlier runs were cut by the host: {why:?}");
                }
                return r;
            }
            Some(w) => {
                eprintln!(
                    "cut run ({w}): stalls {:?}, stop {:?}, located {:?}, rejected {}",
                    r.timing.stalls,
                    r.run.group_stop,
                    r.run.ring_break,
                    ringsync::layers::runtime::run::rejected_summary(&r.run)
                );
                why.push(w);
            }
        }
    }
    panic!("the host cut every {} run: {why:?}", opts.transport.name());
}

/// A run cut by the host before `t` [s]: a group stop that came before the fault the test
/// injects at `t`.
fn stopped_before(r: &RtResult, t: f64) -> Option<String> {
    r.run
        .group_stop
        .filter(|(at, _)| *at < t)
        .map(|(at, reason)| {
            format!(
                "group stop at {at:.3} s ({}) before the fault at {t} s",
                reason.name()
            )
        })
}

/// See [`run_undisturbed`].
const ATTEMPTS: usize = 4;

/// W of the measured runs: docs/runtime.md's advice for a virtual machine, whose host now
/// and then holds the loop for several ms (with the reference W = 5 such a freeze is a
/// group stop, and the run measures stopping axes).
const VM_W: u32 = 20;

/// The options of a measured run of the reference motion on `transport`.
fn measured(transport: TransportKind) -> RtOptions {
    RtOptions {
        transport,
        watchdog_cycles: Some(VM_W),
        ..RtOptions::default()
    }
}

/// The reference motion (4 s) against the simulator's mean over 8 seeds: Sync-RMSE within
/// 20 % (the tolerance; one simulated run alone moves by about ±10 % with the seed),
/// Track-RMSE within 2 %, no group stop, and the ring kept its schedule in most cycles.
fn matches_simulator(r: &RtResult) {
    // Simulated once, and never beside a real-time run: a simulation on the other CPU
    // disturbs the ring being measured.
    let p = {
        let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        *PREDICTION.get_or_init(|| sim_prediction(&r.scenario, 8).expect("simulates"))
    };
    // The reference as the runtime runs it: the default scenario with the runtime's
    // sampling lead and the W of a virtual machine.
    let mut reference = Scenario::default();
    reference.clock.sample_lead.0 = ringsync::layers::runtime::run::SAMPLE_LEAD;
    reference.faults.watchdog_cycles = VM_W;
    assert_eq!(r.scenario, reference, "the prediction is for the reference");
    let m = &r.run.summary;
    let dev = (m.sync_rmse - p.sync_rmse).abs() / p.sync_rmse;
    eprintln!(
        "measured {:.6}/{:.7}, simulator {:.6}/{:.7}; overruns {}, lateness p99 {} ns",
        m.track_rmse,
        m.sync_rmse,
        p.track_rmse,
        p.sync_rmse,
        r.timing.overruns,
        r.timing.lateness.p99
    );
    assert!(
        dev < 0.20,
        "Sync-RMSE {} vs simulator {} ({:.1} %)",
        m.sync_rmse,
        p.sync_rmse,
        100.0 * dev
    );
    assert!((m.track_rmse - p.track_rmse).abs() / p.track_rmse < 0.02);
    assert!(r.run.group_stop.is_none(), "{:?}", r.run.group_stop);
    // What the ring reports about itself, never a count the host can steal: every cycle
    // it started has its lateness; the overruns the host did not cause are few.
    let t = &r.timing;
    assert!(t.cycles_planned == 4000 && t.cycles <= 4000, "{t:?}");
    assert_eq!(t.lateness.count, t.cycles as usize);
    let own = t.overruns - t.overruns_stalled;
    assert!(own < 200, "{own} overruns in cycles the host did not stall");
    // Every slave synchronised on every cycle but those the host stalled, and its clock
    // followed the master's.
    for c in &r.run.slaves {
        assert!(
            c.syncs as i64 >= t.cycles - 2 * t.cycles_stalled as i64 - 20,
            "{c:?} {t:?}"
        );
    }

    assert_eq!(
        r.timing.latches_late, 0,
        "latches after their axis moved on; stalls {:?}, faults {:?}",
        r.timing.stalls, r.run.faults
    );
    // With the sampling lead every latch comes before its lumped frame. A sample goes round
    // twice only after the host froze the loop for about a cycle: the loop then takes the
    // overdue latches (the next cycle's too) before it reads the frame waiting in a socket,
    // so that frame carries the next cycle's sample and the next frame carries it again.
    // At most one per axis and stalled cycle (measured: 0-18 in 4 s runs, 4-17 a minute).
    let n = r.run.slaves.len() as u64;
    assert!(
        r.run.master.samples_stale <= n * r.timing.cycles_stalled,
        "{} stale samples, {} stalled cycles",
        r.run.master.samples_stale,
        r.timing.cycles_stalled
    );
    let clock = r.run.clock_error_max_ns.iter().copied().fold(0.0, f64::max);
    assert!(clock < 200_000.0, "clock error {clock} ns");
}

/// On a ring nobody attacks, the nodes refuse only frames that a host stall made late
/// (read after their cycle, or after the clock window).
fn refuses_only_late_frames(r: &RtResult) {
    let t = &r.timing;
    let n = r.run.slaves.len() as u64;
    let refused = r
        .run
        .slaves
        .iter()
        .fold(r.run.master.rejected, |a, c| a.plus(&c.rejected));
    for why in [
        Reject::Malformed,
        Reject::UnexpectedKind,
        Reject::FutureTimestamp,
        Reject::Duplicate,
        Reject::Overflow,
    ] {
        assert_eq!(refused.get(why), 0, "{why}: {refused:?}");
    }
    assert!(
        refused.total() <= 4 * (n + 1) * (t.cycles_stalled + 1),
        "{refused:?} with {} stalled cycles",
        t.cycles_stalled
    );
}

#[test]
fn udp_ring_runs_the_reference_motion_like_the_simulator() {
    let r = run_undisturbed(measured(TransportKind::Udp));
    matches_simulator(&r);
    refuses_only_late_frames(&r);
}

#[test]
fn veth_ring_runs_the_reference_motion_like_the_simulator() {
    let r = run_undisturbed(measured(TransportKind::Veth));
    matches_simulator(&r);
    refuses_only_late_frames(&r);
}

/// A slave taken out mid-run: the master stops the group within W cycles, the report
/// names the slave from the nodes' own counters (on both transports), and every other
/// axis ends with its torque off.
#[test]
fn a_slave_taken_out_is_named_and_the_group_stops_within_w_cycles() {
    for transport in [TransportKind::Veth, TransportKind::Udp] {
        let opts = RtOptions {
            transport,
            duration: Some(Duration::from_ms(1500)),
            kill: Some(Kill {
                slave: 2,
                at: Duration::from_ms(1000),
            }),
            ..RtOptions::default()
        };
        let r = run_uncut(opts, |r| stopped_before(r, 1.0));
        let w = i64::from(r.scenario.faults.watchdog_cycles);
        assert_eq!(
            r.run.ring_break,
            Some(RingBreak::Node(2)),
            "{}",
            transport.name()
        );
        let (t, _) = r.run.group_stop.expect("a group stop");
        assert!(t > 1.0, "stopped at {t}");
        let cycles = r.detection_cycles.expect("detected");
        assert!(cycles <= w + 1, "detected after {cycles} cycles, W = {w}");
        // The ring is broken at slave 2: the master orders every axis's torque off (it has
        // no feedback); slaves 3 and 4 no longer get commands and brake on their own.
        for axis in [1, 3, 4] {
            assert!(
                r.run
                    .faults
                    .iter()
                    .any(|f| f.axis == axis && matches!(f.step, FaultStep::TorqueOff(_))),
                "{}: axis {axis}: {:?}",
                transport.name(),
                r.run.faults
            );
        }
        let mut wd: Vec<usize> = r.run.watchdog.iter().map(|(s, _)| *s).collect();
        wd.sort_unstable();
        assert!(wd.contains(&3) && wd.contains(&4), "{wd:?}");
    }
}

/// Forged frames with a valid CRC on a running ring, for the whole 4 s run: commands of
/// other cycles at 1 kHz, lumped frames from the future, bursts of 30 sync frames. They
/// change nothing: no stop, no axis off its path, no command beyond what the master sent,
/// the motion as the simulator predicts; and every forgery is counted as refused.
#[test]
fn forged_frames_are_refused_and_change_nothing() {
    for transport in [TransportKind::Udp, TransportKind::Veth] {
        let r = run_undisturbed(RtOptions {
            forge: Forgery::ALL.to_vec(),
            ..measured(transport)
        });
        let name = transport.name();
        let inj = |f: Forgery| {
            r.injected
                .forged
                .iter()
                .find(|(k, _)| *k == f)
                .map_or(0, |(_, n)| *n)
        };
        let (commands, future, burst) = (
            inj(Forgery::WrongCycleCommands),
            inj(Forgery::FutureLumped),
            inj(Forgery::SyncBurst),
        );
        assert!(
            commands > 3000 && future > 300 && burst >= 90,
            "{name}: {:?}",
            r.injected
        );
        let slaves = r.run.slaves.iter().fold(
            Default::default(),
            |a: ringsync::layers::proto::node::Rejections, c| a.plus(&c.rejected),
        );
        let n = r.run.slaves.len() as u64;
        // Every forged command reaches its target and is refused (a few may still be in a
        // socket at the end); each forged lumped frame passes every slave.
        assert!(
            slaves.get(Reject::WrongCycle) + 5 >= commands + n * burst,
            "{name}: {slaves:?}"
        );
        assert!(
            slaves.get(Reject::FutureTimestamp) + 5 * n >= n * future,
            "{name}: {slaves:?}"
        );
        assert!(r.run.master.rejected.get(Reject::WrongCycle) + 5 >= future + burst);
        let (sent, applied) = &r.run.command_max;
        for (i, (s, a)) in sent.iter().zip(applied).enumerate() {
            assert!(
                a <= &(s + 1e-5),
                "{name}: axis {} applied {a} V, the master sent at most {s} V",
                i + 1
            );
            assert!(*a < 5.0, "{name}: axis {} applied {a} V", i + 1);
        }
        let limit = r.scenario.faults.following_error_limit;
        for a in &r.run.summary.axes {
            assert!(a.max_e < limit, "{name}: {a:?}");
        }
        matches_simulator(&r);
    }
}

/// A link down for 8 ms with W = 25: it costs the cycles
/// it lasts, not the run; every port reads frames again after it. On veth the receiving
/// end goes down, so its socket reports a receive error: before the fix one receive error
/// disabled a port for good and the run ended in a group stop.
#[test]
fn a_link_flap_shorter_than_w_costs_cycles_not_the_run() {
    for transport in [TransportKind::Veth, TransportKind::Udp] {
        let opts = RtOptions {
            transport,
            duration: Some(Duration::from_ms(2000)),
            watchdog_cycles: Some(25),
            flap: Some(Flap {
                from: 2,
                at: Duration::from_ms(1000),
                down_for: Duration::from_ms(8),
            }),
            ..RtOptions::default()
        };
        // A flap the host stretched to W cycles (less the port's re-read delay) is not
        // shorter than W, and the run tests something else: with `ip` switching the link,
        // a busy host stretched every one of 24 flaps to 29-54 ms.
        let r = run_uncut(opts, |r| {
            let t_cyc = r.scenario.ring.cycle.0.as_ns();
            let w = i64::from(r.scenario.faults.watchdog_cycles);
            let longest = w * t_cyc - ringsync::layers::runtime::ring::RX_RETRY - t_cyc;
            match r.timing.flap_down_ns {
                Some(d) if d >= longest => Some(format!(
                    "the host stretched the flap to at most {} µs (W is {} µs)",
                    d / 1_000,
                    w * t_cyc / 1_000
                )),
                _ => host_outage(r),
            }
        });
        let name = transport.name();
        let t = &r.timing;
        assert!(
            r.run.group_stop.is_none(),
            "{name}: {:?} {t:?}",
            r.run.group_stop
        );
        assert!(t.overruns >= 5, "{name}: the flap cost no cycle? {t:?}");
        assert!(t.longest_outage < 25, "{name}: {t:?}");
        match transport {
            TransportKind::Veth => {
                assert!(t.flap_down_ns.is_some_and(|d| d >= 8_000_000), "{t:?}");
                assert!(t.receive_errors >= 1, "{t:?}");
            }
            TransportKind::Udp => assert!(t.flap_dropped > 0, "{t:?}"),
        }
        for (i, (_, last)) in r.nodes_rx.iter().enumerate() {
            assert!(
                last.is_some_and(|s| s > 1.9),
                "{name}: node {i} read nothing after the flap: {:?}",
                r.nodes_rx
            );
        }
    }
}

/// A link down for longer than W: the group stops, and the report names the link (the
/// nodes behind it still run), not a node.
#[test]
fn a_link_down_longer_than_w_is_named() {
    for transport in [TransportKind::Veth, TransportKind::Udp] {
        let opts = RtOptions {
            transport,
            duration: Some(Duration::from_ms(1500)),
            flap: Some(Flap {
                from: 2,
                at: Duration::from_ms(1000),
                down_for: Duration::from_ms(200),
            }),
            ..RtOptions::default()
        };
        let r = run_uncut(opts, |r| stopped_before(r, 1.0));
        assert!(r.run.group_stop.is_some(), "{}", transport.name());
        assert_eq!(
            r.run.ring_break,
            Some(RingBreak::Link { from: 2, to: 3 }),
            "{}",
            transport.name()
        );
    }
}

#[test]
fn garbage_and_bad_crc_frames_are_counted_and_ignored() {
    let r = run_undisturbed(RtOptions {
        garbage_rate: 500.0,
        ..measured(TransportKind::Udp)
    });
    let (injected, counted) = (r.injected.garbage, r.injected.counted_malformed);
    assert!(injected > 1500, "{injected} injected");
    // The last frame or two may still be in a socket when the run ends.
    assert!(
        counted <= injected && counted + 3 >= injected,
        "{counted} of {injected}"
    );
    matches_simulator(&r);
}
