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

/// The master's P2P schedule on the measured ring [ns].
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
    let m = &mut spec.master;
    let slice = cal.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti;
    let p2p_start = (2 * cal.round_trip.p99 + 20_000).max(m.p2p_start.as_ns());
    let timeout = response_timeout.as_ns();
    if m.plan == PlanKind::P2pLumped {
        let need = cycle_need(cal, p2p_start, t_ti, m.turnaround.as_ns(), timeout);
        if need.total() > t_cyc {
            let us = |ns: i64| ns as f64 * 1e-3;
            let before = match n {
                0 | 1 => String::new(),
                _ => format!(
                    " + {} slices of typically {:.1} µs in all, one of them {:.1} µs longer at its p99,",
                    n - 1,
                    us(need.typical),
                    us(need.worst_extra)
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
    /// The slices before the last, each at its slave's median (command to response, + T_ti,
    /// + the master's turnaround to the next command), summed.
    typical: i64,
    /// One of them at its p99: the largest p99 − median of those slices.
    worst_extra: i64,
    /// The last slice's deadline: the slowest p99 + T_ti.
    last: i64,
    /// The response timeout beyond the last slice.
    timeout: i64,
}

impl CycleNeed {
    fn total(&self) -> i64 {
        self.p2p_start + self.typical + self.worst_extra + self.last + self.timeout
    }
}

/// What a cycle of the measured ring needs: the P2P start, the slices before the last at
/// their median but one at its p99, and the last slice's whole deadline (its p99 + the
/// response timeout). The master opens a slice only when its deadline falls within the
/// cycle, and a slice ends when its response is back: a cycle fits when its last slice
/// still opens after one slow slice. A cycle with more slow slices loses its last command
/// (counted: `commands_lost`) rather than overrunning; a ring whose last slice opens only
/// in the typical cycle's last microseconds would lose it in most cycles (a slave then runs
/// into its watchdog: a run at 1 ms measured a need of 991 µs by the typical slices alone
/// and stopped after 80 ms). Every slice at its p99 (the rule before) refused rings whose
/// P2P phase measured 270-290 µs at its p99 for four slices, at 1 ms, because one slice's
/// p99 was 150 µs: one process per node on one CPU (docs/runtime.md).
fn cycle_need(
    cal: &Calibration,
    p2p_start: i64,
    t_ti: i64,
    turnaround: i64,
    timeout: i64,
) -> CycleNeed {
    let before = &cal.slice[..cal.slice.len().saturating_sub(1)];
    CycleNeed {
        p2p_start,
        typical: before.iter().map(|p| p.p50 + t_ti + turnaround).sum(),
        worst_extra: before
            .iter()
            .map(|p| (p.p99 - p.p50).max(0))
            .max()
            .unwrap_or(0),
        last: cal.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti,
        timeout,
    }
}

/// The ring the nodes ran, as the simulator can run it: `ran` (the nodes' configuration:
/// the measured schedule, path delays and command arrivals) with every hop taking the
/// measured link L and every slave the median of the measured residences, since the
/// simulator's links are all alike and so are its slaves. What it cannot take from the
/// measurement: the hops' spread (no jitter is added: the simulator's scenario jitter
/// stands) and the software stamps' error (its slaves stamp as the scenario says).
/// [`MEASURED_RING_ASSUMPTION`] says so in the outputs.
pub fn measured_ring(ran: &Spec, cal: &Calibration) -> Spec {
    let mut spec = ran.clone();
    spec.plan.hop = cal.start_up.measured.link;
    if let Some(r) = median_residence(cal) {
        spec.scenario.ring.residence.0 = r;
    }
    spec
}

/// The first-bit path of the whole ring of `n` slaves, `link` [ns] a hop and `residence`
/// a slave: (n + 1)·L + n·r [ns].
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
pub const MEASURED_RING_ASSUMPTION: &str = "the ring as the start-up phase measured it: the nodes' schedule, path delays and command timing, every link the measured L and every slave the median measured residence; the hops' spread and the stamps' error are not modelled";

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

    /// The ring as measured takes the measured link and the median residence, keeps the
    /// nodes' schedule, and changes nothing else.
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
        let mut back = m.clone();
        back.plan.hop = ran.plan.hop;
        back.scenario.ring.residence = ran.scenario.ring.residence;
        assert_eq!(format!("{back:?}"), format!("{ran:?}"));
    }

    /// A cycle needs the P2P start, the slices before the last at their median but one at
    /// its p99, and the last slice's deadline: a ring whose slices have long p99 tails fits
    /// when their medians leave room, and is refused, naming each term, when they do not.
    #[test]
    fn a_cycle_needs_median_slices_one_slow_and_the_last_deadline() {
        let s = Scenario::from_toml("duration = \"10ms\"\n", "test").expect("scenario");
        let spec = s.build().expect("spec");
        let t_ti = spec.scenario.ring.response_delay.0.as_ns();
        let mut cal = calibration();
        // Round trips of 50 µs (p99 150 µs: P2P start 320 µs); slices of 45 µs (p99
        // 150 µs), slave 3's median 50 µs and p99 200 µs.
        cal.round_trip = pct(50_000, 150_000);
        cal.slice = vec![
            pct(45_000, 150_000),
            pct(45_000, 150_000),
            pct(50_000, 200_000),
            pct(45_000, 150_000),
        ];
        let need = cycle_need(&cal, 320_000, t_ti, 0, 100_000);
        assert_eq!(need.typical, 2 * 45_000 + 50_000 + 3 * t_ti);
        assert_eq!(need.worst_extra, 150_000);
        assert_eq!(need.last, 200_000 + t_ti);
        assert_eq!(
            need.total(),
            320_000 + 140_000 + 3 * t_ti + 150_000 + 200_000 + t_ti + 100_000
        );
        // The master's turnaround follows each slice before the last.
        assert_eq!(
            cycle_need(&cal, 320_000, t_ti, 1_000, 100_000).total(),
            need.total() + 3_000
        );
        let mut fits = spec.clone();
        fits.scenario.ring.cycle.0 = Duration::from_ms(1);
        let sched = apply(&mut fits, &cal, Duration::from_us(100)).expect("fits 1 ms");
        assert_eq!(sched.p2p_start, 320_000);
        // The master's slice deadline is the last slice's.
        assert_eq!(sched.slice, need.last);
        // Every slice at its p99 would need 320 + 4 · 200 + 100 µs: the old rule refused it.
        assert!(320_000 + 4 * sched.slice + 100_000 > 1_000_000);
        // One ring, one slave: no slice before the last.
        let mut one = calibration();
        one.slice.truncate(1);
        let alone = cycle_need(&one, 0, 0, 0, 0);
        assert_eq!((alone.typical, alone.worst_extra), (0, 0));
        // Never more than every slice at its p99 (the rule before), however the medians
        // and spreads of the slaves differ.
        let mut r = ringsync_model::rng::Rng::stream(1, 2);
        for _ in 0..1000 {
            let mut uneven = calibration();
            uneven.slice = (0..4)
                .map(|_| {
                    let p50 = (r.unit() * 200_000.0) as i64;
                    pct(p50, p50 + (r.unit() * 200_000.0) as i64)
                })
                .collect();
            let slice = uneven.slice.iter().map(|p| p.p99).max().unwrap_or(0) + t_ti;
            let need = cycle_need(&uneven, 320_000, t_ti, 0, 100_000);
            assert!(need.total() <= 320_000 + 4 * slice + 100_000, "{need:?}");
        }
        // With a 200 µs timeout the last slice no longer opens after a slow one: refused,
        // naming the terms.
        let mut refused = spec.clone();
        refused.scenario.ring.cycle.0 = Duration::from_ms(1);
        let e = apply(&mut refused, &cal, Duration::from_us(200))
            .expect_err("too slow")
            .to_string();
        assert!(e.starts_with(DOES_NOT_FIT), "{e}");
        assert!(e.contains("3 slices of typically"), "{e}");
        assert!(e.contains("the cycle is 1000.0 µs"), "{e}");
    }
}
