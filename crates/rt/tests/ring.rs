//! Real runs of the reference scenario on loopback UDP and on a veth ring of network
//! namespaces. They need root for the veth cases (CI runs as root); without it they fail with
//! the reason rather than pass silently. Runs are serialised: they measure real time.

use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, OnceLock};

use ringsync_proto::Duration;
use ringsync_rt::netns::ringsync_namespaces;
use ringsync_rt::{Kill, RtOptions, RtResult, SimPrediction, TransportKind, run, sim_prediction};
use ringsync_sim::Scenario;

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
/// lumped frame or a command) shorter than W. A virtual machine's host now and then holds
/// the loop off its CPU for milliseconds on end (docs/runtime.md: the host's stalls,
/// measured without the ring); when that cuts the ring for W cycles, the slaves' watchdogs
/// put the drives at 0 V and the master stops the group, as they must, and the run is an
/// experiment in coasting axes, not a measurement of the runtime. The criterion is the
/// ring's own outage counter, not the figures the test then checks; such a run is repeated
/// (at most [`ATTEMPTS`] in all), and when every attempt was cut the test fails. Shorter
/// outages stay in the measured runs. Measured over 30 UDP runs of this build here: 29
/// with outages under W, Sync-RMSE within −13.4 % and +10.1 % of the simulator's; one cut
/// for 8 cycles.
fn run_undisturbed(opts: RtOptions) -> RtResult {
    let w = u64::from(Scenario::default().faults.watchdog_cycles);
    let mut outages = Vec::new();
    for _ in 0..ATTEMPTS {
        let r = run_ref(opts.clone());
        if r.timing.longest_outage < w {
            if !outages.is_empty() {
                eprintln!(
                    "earlier runs were cut by the host: outages of {outages:?} cycles (W = {w})"
                );
            }
            return r;
        }
        outages.push(r.timing.longest_outage);
    }
    panic!(
        "the host cut every {} run: outages of {outages:?} cycles (W = {w})",
        opts.transport.name()
    );
}

/// See [`run_undisturbed`].
const ATTEMPTS: usize = 3;

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
    // sampling lead.
    let mut reference = Scenario::default();
    reference.clock.sample_lead.0 = ringsync_rt::run::SAMPLE_LEAD;
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
    assert_eq!(r.timing.cycles, 4000);
    assert!(r.timing.overruns < 200, "{} overruns", r.timing.overruns);
    assert_eq!(r.timing.lateness.count, 4000);
    // Every slave synchronised on (nearly) every cycle, and its clock followed the master's.
    for c in &r.run.slaves {
        assert!(c.syncs > 3900, "{c:?}");
    }
    assert_eq!(
        r.timing.latches_late, 0,
        "latches after their axis moved on"
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

#[test]
fn udp_ring_runs_the_reference_motion_like_the_simulator() {
    let r = run_undisturbed(RtOptions {
        transport: TransportKind::Udp,
        ..RtOptions::default()
    });
    matches_simulator(&r);
}

#[test]
fn veth_ring_runs_the_reference_motion_like_the_simulator() {
    let r = run_undisturbed(RtOptions {
        transport: TransportKind::Veth,
        ..RtOptions::default()
    });
    matches_simulator(&r);
}

#[test]
fn a_slave_taken_out_stops_the_group_within_w_cycles() {
    let r = run_ref(RtOptions {
        transport: TransportKind::Veth,
        duration: Some(Duration::from_ms(1500)),
        kill: Some(Kill {
            slave: 2,
            at: Duration::from_ms(1000),
        }),
        ..RtOptions::default()
    });
    let w = i64::from(r.scenario.faults.watchdog_cycles);
    let f = r.failure.as_ref().expect("a group stop with a diagnosis");
    assert_eq!(f.node, 2, "{f:?}");
    assert!(f.detected_s > 1.0, "{f:?}");
    let cycles = r.detection_cycles.expect("detected");
    assert!(cycles <= w + 1, "detected after {cycles} cycles, W = {w}");
    // The ring is broken at slave 2: the others lose their commands and go to 0 V.
    let mut wd: Vec<usize> = r.run.watchdog.iter().map(|(s, _)| *s).collect();
    wd.sort_unstable();
    assert_eq!(wd, vec![1, 3, 4]);
}

#[test]
fn garbage_and_bad_crc_frames_are_counted_and_ignored() {
    let r = run_undisturbed(RtOptions {
        transport: TransportKind::Udp,
        garbage_rate: 500.0,
        ..RtOptions::default()
    });
    let (injected, counted) = r.garbage;
    assert!(injected > 1500, "{injected} injected");
    // The last frame or two may still be in a socket when the run ends.
    assert!(
        counted <= injected && counted + 3 >= injected,
        "{counted} of {injected}"
    );
    matches_simulator(&r);
}
