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
        // Each slice ends when its response is back; only a slice whose response is lost
        // runs to its deadline (slice + timeout), and the master opens no slice that would
        // end after the cycle.
        let need = p2p_start + n as i64 * slice + timeout;
        if need > t_cyc {
            return Err(RtError::Config(format!(
                "the measured ring needs {:.1} µs per cycle (P2P start {:.1} µs + {n} slices of {:.1} µs + a response timeout of {:.1} µs); the cycle is {:.1} µs: use a longer --cycle or a shorter --response-timeout",
                need as f64 * 1e-3,
                p2p_start as f64 * 1e-3,
                slice as f64 * 1e-3,
                timeout as f64 * 1e-3,
                t_cyc as f64 * 1e-3
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
    } else {
        let frame = spec.plan.lumped_only.lumped.frame_time[0].as_ns();
        for i in 0..n {
            m.command_arrival[i] = Duration::from_ns(cal.path[i] + frame);
        }
    }
    // The clock window: software stamps and commands read late, and what free-running clocks drift apart
    // when the scenario turns clock sync off (as the simulator allows for it).
    let tolerance = RT_TIMESTAMP_TOLERANCE.max(timestamp_tolerance(s));
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
