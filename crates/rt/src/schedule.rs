//! The schedule of a real ring: the plan's P2P start, slices and command arrivals replaced
//! by what calibration measured on this host, and the clock windows widened for the
//! runtime (software stamps; commands are always checked at the loop's reading). Everything else in the nodes' configurations is the scenario's, as built by
//! `Scenario::build`.

use ringsync_model::Spec;
use ringsync_model::spec::timestamp_tolerance;
use ringsync_proto::node::MeasuredSchedule;
use ringsync_proto::{Duration, PlanKind};

use crate::calibrate::Calibration;
use crate::run::RtError;

/// How far from a node's clock a received timestamp may be in the runtime, ahead or behind
/// (software stamps: the slaves' clocks are good to tens of µs, measured in
/// docs/runtime.md; a command, or a software-stamped frame, read later than this after a
/// host stall is refused as stale).
pub const RT_TIMESTAMP_TOLERANCE: Duration = Duration::from_us(200);

/// How the refusal of a measured ring that does not fit its cycle begins (a launcher
/// measures again when its master says so).
pub const DOES_NOT_FIT: &str = "the measured ring needs";

/// The master's P2P schedule on the measured ring \[ns\].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Schedule {
    /// P2P start: after the lumped frame's measured round trip (twice its p99, + 20 µs),
    /// and never before the plan's.
    pub p2p_start: i64,
    /// One slice: the slowest slave's measured p99 command-to-response time plus its
    /// response delay.
    pub slice: i64,
    /// How long the master waits for a response beyond its slice.
    pub response_timeout: i64,
}

/// Sets `spec`'s master and slaves to the ring `cal` measured: the schedule (P2P start,
/// slices, each command's arrival), each slave's path delay, and clock windows for software
/// timestamps. Fails, naming what to change, when the measured ring does not fit the cycle.
pub fn apply(
    spec: &mut Spec,
    cal: &Calibration,
    response_timeout: Duration,
) -> Result<Schedule, RtError> {
    let n = spec.axes();
    let s = &spec.scenario;
    let t_cyc = s.ring.cycle.0.as_ns();
    let t_ti = s.ring.response_delay.0.as_ns();
    let slice = cal.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti;
    let p2p_start = (2 * cal.round_trip.p99 + 20_000).max(spec.master.p2p_start.as_ns());
    let timeout = response_timeout.as_ns();
    let need = cycle_need(
        spec,
        cal,
        p2p_start,
        spec.master.turnaround.as_ns(),
        timeout,
    );
    let m = &mut spec.master;
    if m.plan == PlanKind::P2pLumped {
        if need.total() > t_cyc {
            let us = |ns: i64| ns as f64 * 1e-3;
            let before = match n {
                0 | 1 => String::new(),
                _ => format!(
                    " + the {} slices before the last {:.1} µs at their p99",
                    n - 1,
                    us(need.before)
                ),
            };
            return Err(RtError::Config(format!(
                "{DOES_NOT_FIT} {:.1} µs per cycle (P2P start {:.1} µs{before} + the last slice's {:.1} µs + a response timeout of {:.1} µs); the cycle is {:.1} µs: use a longer --cycle or a shorter --response-timeout",
                us(need.total()),
                us(p2p_start),
                us(need.last),
                us(timeout),
                us(t_cyc)
            )));
        }
        let measured = MeasuredSchedule {
            p2p_start: Duration::from_ns(p2p_start),
            slice: Duration::from_ns(slice),
            guard: Duration::from_ns(timeout),
            command_transit: cal.command.iter().map(|c| Duration::from_ns(*c)).collect(),
            typical_slice: cal
                .slice
                .iter()
                .map(|p| Duration::from_ns(p.p50 + t_ti))
                .collect(),
        };
        *m = m.clone().with_measured(&measured);
        // The ring model the master works out a broken ring's cycle from (the copy's stamp
        // shift above all): the measured link and residence, not the plan's wire figures
        // (a process per node takes tens of µs a hop).
        if let Some(model) = &mut m.ring {
            model.hop = cal.start_up.measured.link;
            model.residence = median_residence(cal).unwrap_or(model.residence);
        }
    } else {
        let frame = spec.plan.lumped_only.lumped.frame_time[0].as_ns();
        for i in 0..n {
            m.command_arrival[i] = Duration::from_ns(cal.path[i] + frame);
        }
    }
    // The clock window: software stamps and commands read late, and what free-running clocks drift apart
    // when the scenario turns clock sync off (as the simulator allows for it); and twice
    // the measured ring's path, where a hop is a process's wake-up (a path the master's
    // model of a broken ring misses by a few hops, after a second break, must not make the
    // slaves refuse every sync).
    let ring_path = ring_path_ns(cal.start_up.measured.link.as_ns(), median_residence(cal), n);
    let tolerance = RT_TIMESTAMP_TOLERANCE
        .max(timestamp_tolerance(s))
        .max(Duration::from_ns(2 * ring_path));
    m.timestamp_tolerance = tolerance;
    let (plan, p2p) = (m.plan, m.p2p_start);
    for (c, path) in spec.slaves.iter_mut().zip(&cal.path) {
        c.path_delay = Duration::from_ns(*path);
        c.clock_window = tolerance;
        if plan == PlanKind::P2pLumped {
            c.p2p_start = p2p;
        }
    }
    Ok(Schedule {
        p2p_start,
        slice,
        response_timeout: timeout,
    })
}

/// What a cycle of the measured ring needs [ns] ([`cycle_need`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CycleNeed {
    p2p_start: i64,
    /// The n − 1 slices before the last, together, at their p99.
    before: i64,
    /// What each slice takes beyond its probe's round trip less the slave's residence:
    /// T_ti, the master's turnaround, the command's and response's wire time.
    per: i64,
    /// The last slice's deadline: the slowest p99 + T_ti.
    last: i64,
    /// The response timeout beyond the last slice.
    timeout: i64,
}

impl CycleNeed {
    fn total(&self) -> i64 {
        self.p2p_start + self.before + self.last + self.timeout
    }
}

/// What a cycle of the measured ring needs: the P2P start, the n − 1 slices before the last
/// at the p99 of their sum, and the last slice's whole deadline (its p99 + the response
/// timeout). The master opens a slice only when its deadline falls within the cycle, and a
/// slice ends when its response is back: a cycle fits when its last slice still opens in
/// 99 cycles of 100. A cycle whose slices run longer loses its last command (counted:
/// `commands_lost`) rather than overrunning.
///
/// The sum's p99 comes from the probes' round trips taken n − 1 at a time (consecutive
/// probes, each less its slave's residence, plus T_ti, the master's turnaround and the
/// command's and response's wire time), never more than each slice so at its p99 (the rule
/// before, with the wire time). Every slice at its p99 refused rings whose whole P2P phase
/// measured 270-290 µs at its p99 for four slices, at 1 ms, because one slice's p99 was
/// 150 µs (one process per node on one CPU, docs/runtime.md); every slice at its median
/// let rings start whose last slice opened in half the cycles or none (a run at 1 ms
/// stopped after 80 ms; `crates/ringsync/tests/schedule_fit.rs`).
fn cycle_need(
    spec: &Spec,
    cal: &Calibration,
    p2p_start: i64,
    turnaround: i64,
    timeout: i64,
) -> CycleNeed {
    let n = cal.slice.len();
    let k = n.saturating_sub(1);
    let t_ti = spec.scenario.ring.response_delay.0.as_ns();
    let last = cal.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti;
    // A command is read whole before its slave answers, and the response is read whole by
    // the master: two frames' wire time, which a probe's round trip (stamped at its first
    // bit in the simulator) need not hold.
    let wire = spec.plan.t_cmf.as_ns() + spec.plan.t_rmf.as_ns();
    let per = t_ti + turnaround + wire;
    let m = &cal.start_up.measured;
    let rtt: Vec<i64> = m.round_trips.iter().map(|d| d.as_ns()).collect();
    let residences: i64 = m.residence.iter().take(k).map(|r| r.as_ns()).sum();
    let each_at_p99 = k as i64 * (last - t_ti + per);
    let before = if k == 0 {
        0
    } else if rtt.is_empty() {
        each_at_p99
    } else {
        let sums: Vec<i64> = (0..rtt.len())
            .map(|j| (0..k).map(|q| rtt[(j + q) % rtt.len()]).sum::<i64>() - residences)
            .collect();
        (crate::stats::Percentiles::of(&sums).p99 + k as i64 * per).min(each_at_p99)
    };
    CycleNeed {
        p2p_start,
        before,
        per,
        last,
        timeout,
    }
}

/// The ring the nodes ran, as the simulator can run it: `ran` (the nodes' configuration:
/// the measured schedule and command arrivals) with every hop taking the measured link L
/// and every slave the median of the measured residences, since the simulator's links are
/// all alike and so are its slaves. Each slave's clock takes this simulated ring's own
/// path, i·L + (i − 1)·r, as the nodes' start-up phase gave each real slave the path of
/// the real ring: the measured paths, which a ring of like hops does not reproduce when
/// the residences differ, would put a constant error of microseconds on the simulated
/// clocks that the run's clocks do not have (a ring of node processes, residences 12.4,
/// 6.9, 6.7 and 6.7 µs: 5.4 µs on three clocks, a Sync-RMSE of 69 µrad predicted for a
/// compensated law whose run gave 30 and whose ring simulates at 10). What it cannot take
/// from the measurement: the hops' spread (no jitter is added: the simulator's scenario
/// jitter stands) and the software stamps' error (its slaves stamp as the scenario says).
/// [`MEASURED_RING_ASSUMPTION`] says so in the outputs.
pub fn measured_ring(ran: &Spec, cal: &Calibration) -> Spec {
    let mut spec = ran.clone();
    spec.plan.hop = cal.start_up.measured.link;
    if let Some(r) = median_residence(cal) {
        spec.scenario.ring.residence.0 = r;
    }
    let (hop, residence) = (spec.plan.hop, spec.scenario.ring.residence.0);
    for (i, c) in (0i64..).zip(spec.slaves.iter_mut()) {
        c.path_delay = hop * (i + 1) + residence * i;
    }
    spec
}

/// The first-bit path of the whole ring of `n` slaves, `link` \[ns\] a hop and `residence`
/// a slave: (n + 1)·L + n·r \[ns\].
pub fn ring_path_ns(link: i64, residence: Option<Duration>, n: usize) -> i64 {
    let n = n as i64;
    (n + 1) * link + n * residence.map_or(0, |r| r.as_ns())
}

/// The median of the slaves' measured residences (the upper one of an even count).
fn median_residence(cal: &Calibration) -> Option<Duration> {
    let mut r: Vec<Duration> = cal.start_up.measured.residence.clone();
    r.sort_unstable();
    r.get(r.len() / 2).copied()
}

/// What the simulator's prediction for the ring as measured ([`measured_ring`]) assumes.
pub const MEASURED_RING_ASSUMPTION: &str = "the ring as the start-up phase measured it: the nodes' schedule, every link the measured L and every slave the median measured residence, each slave's clock this simulated ring's path (as the start-up phase gave the real slaves the real ring's), the law's command arrivals those of this simulated ring (a warm-up, as the runtime takes its own); the hops' spread and the stamps' error are not modelled";

#[cfg(test)]
mod tests {
    use ringsync_model::Scenario;
    use ringsync_model::result::StartUp;
    use ringsync_proto::node::DelayMeasurement;

    use super::*;
    use crate::stats::Percentiles;

    fn us(v: i64) -> Duration {
        Duration::from_ns(v * 1000)
    }

    fn pct(p50: i64, p99: i64) -> Percentiles {
        Percentiles {
            count: 10,
            p50,
            p99,
            p999: p99,
            max: p99,
        }
    }

    /// A measured ring of four slaves: round trip 200 µs, slices of 180 µs.
    fn calibration() -> Calibration {
        Calibration {
            rounds: 10,
            repeated: 0,
            path: vec![35_000, 75_000, 120_000, 150_000],
            round_trip: pct(200_000, 200_000),
            command: vec![35_000, 75_000, 120_000, 150_000],
            slice: vec![pct(180_000, 180_000); 4],
            start_up: StartUp {
                measured: DelayMeasurement {
                    probes: 10,
                    probes_back: 10,
                    complete: 10,
                    round_trips: vec![us(200); 10],
                    link: us(35),
                    residence: vec![us(9), us(3), us(40), us(5)],
                    path: vec![us(35), us(79), us(117), us(192)],
                    closing_sent: 4,
                },
                taken: vec![None; 4],
                planned: Vec::new(),
                resolution: Duration::from_ns(8),
                slaves_rejected: 0,
                took: us(20_000),
            },
        }
    }

    /// The ring as measured takes the measured link and the median residence, gives each
    /// slave's clock that ring's own path, keeps the nodes' schedule, and changes nothing
    /// else.
    #[test]
    fn the_measured_ring_takes_the_link_and_the_median_residence() {
        let s = Scenario::from_toml("duration = \"10ms\"\n", "test").expect("scenario");
        let mut ran = s.build().expect("spec");
        let cal = calibration();
        ran.scenario.ring.cycle.0 = Duration::from_ms(3);
        apply(&mut ran, &cal, Duration::from_us(200)).expect("fits");
        let m = measured_ring(&ran, &cal);
        assert_eq!(m.plan.hop, us(35));
        // Sorted 3, 5, 9, 40: the upper median.
        assert_eq!(m.scenario.ring.residence.0, us(9));
        assert_ne!(m.plan.hop, ran.plan.hop);
        // Slave i's path: i links of 35 µs and i − 1 residences of 9 µs (the nodes
        // measured 35, 75, 120 and 150 µs, which no ring of like slaves gives).
        let paths: Vec<Duration> = m.slaves.iter().map(|c| c.path_delay).collect();
        assert_eq!(paths, [us(35), us(79), us(123), us(167)]);
        let mut back = m.clone();
        back.plan.hop = ran.plan.hop;
        back.scenario.ring.residence = ran.scenario.ring.residence;
        for (b, r) in back.slaves.iter_mut().zip(&ran.slaves) {
            b.path_delay = r.path_delay;
        }
        assert_eq!(format!("{back:?}"), format!("{ran:?}"));
    }

    /// A cycle needs the P2P start, the slices before the last at their sum's p99 (from the
    /// probes' round trips), and the last slice's deadline: a ring whose slices spread
    /// little fits where every slice at its p99 did not; a few outliers among the probes
    /// make it no stricter than that; a ring that does not fit is refused naming each term.
    #[test]
    fn a_cycle_needs_the_p99_of_the_slices_before_the_last_and_its_deadline() {
        let s = Scenario::from_toml("duration = \"10ms\"\n", "test").expect("scenario");
        let spec = s.build().expect("spec");
        let t_ti = spec.scenario.ring.response_delay.0.as_ns();
        let mut cal = calibration();
        // Round trips of 50-59 µs; the slices' own p99 150 µs (a heavy tail the probes'
        // sums do not have); residences 9, 3, 40 and 5 µs.
        cal.start_up.measured.round_trips = (0..200).map(|j| us(50 + j % 10)).collect();
        cal.round_trip = pct(55_000, 59_000);
        cal.slice = vec![pct(45_000, 150_000); 4];
        let need = cycle_need(&spec, &cal, 200_000, 0, 100_000);
        let before = need.before - 3 * need.per;
        assert!(
            (3 * 50_000 - 52_000..=3 * 59_000 - 52_000).contains(&before),
            "{need:?}"
        );
        assert!(need.per >= t_ti, "{need:?}");
        assert_eq!(need.last, 150_000 + t_ti);
        assert_eq!(need.total(), 200_000 + need.before + need.last + 100_000);
        let mut fits = spec.clone();
        fits.scenario.ring.cycle.0 = Duration::from_us(700);
        let sched = apply(&mut fits, &cal, Duration::from_us(100)).expect("fits 700 µs");
        // The master's slice deadline is the last slice's.
        assert_eq!(sched.slice, need.last);
        // Every slice at its p99 would need 4 · 150 µs besides: the rule before refused it.
        assert!(sched.p2p_start + 4 * sched.slice + 100_000 > 700_000);
        // A master's turnaround after each slice before the last.
        let turned = cycle_need(&spec, &cal, 200_000, 1_000, 100_000);
        assert_eq!(turned.before, need.before + 3_000);
        // Two probes the host held 5 ms: no stricter than every slice at its p99.
        cal.start_up.measured.round_trips[17] = us(5_000);
        cal.start_up.measured.round_trips[120] = us(5_000);
        let held = cycle_need(&spec, &cal, 200_000, 0, 100_000);
        assert_eq!(held.before, 3 * (150_000 + held.per), "{held:?}");
        // One ring, one slave: no slice before the last.
        let mut one = calibration();
        one.slice.truncate(1);
        assert_eq!(cycle_need(&spec, &one, 0, 0, 0).before, 0);
        // Too short a cycle: refused, naming the terms.
        let mut refused = spec.clone();
        refused.scenario.ring.cycle.0 = Duration::from_us(500);
        let e = apply(&mut refused, &calibration(), Duration::from_us(100))
            .expect_err("too slow")
            .to_string();
        assert!(e.starts_with(DOES_NOT_FIT), "{e}");
        assert!(e.contains("the 3 slices before the last"), "{e}");
        assert!(e.contains("the cycle is 500.0 µs"), "{e}");
    }
}
