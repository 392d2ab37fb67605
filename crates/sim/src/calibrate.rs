//! The start-up phase in the simulator: the master's [`Calibrator`] and every slave in its
//! start-up phase ([`Slave::calibrating`]) exchange delay frames over the scenario's links
//! until each slave has the path delay the nodes measured (docs/planner.md, "Delays measured
//! by the nodes"). It runs before the run, on links of its own: the run's random draws (loss,
//! jitter) are the same with or without it.
//!
//! Frames go one at a time (a probe is back long before the next is sent), so the phase
//! needs no event queue: each frame is carried from node to node as the run carries it
//! (`Link::send`, cut-through, each slave's first bit out T_t after its first bit in).

use ringsync_model::oscillator::Oscillator;
use ringsync_model::spec::Spec;
use ringsync_proto::node::{
    CalibrationConfig, CalibrationError, CalibrationState, Calibrator, FrameOutcome, Slave,
    WireFrame,
};
use ringsync_proto::{Duration, Instant};

use crate::link::{Delivery, Link};

/// Probes of the start-up phase when a scenario does not say.
pub const DEFAULT_PROBES: u32 = 32;

pub use ringsync_model::result::StartUp;

/// Runs the start-up phase of `spec`'s ring with `probes` probes.
///
/// # Errors
/// When the phase fails: no probe came back whole, a slave did not take its delay, or the
/// ring has more slaves than one delay frame carries.
pub fn calibrate(spec: &Spec, probes: u32) -> Result<StartUp, CalibrationError> {
    let s = &spec.scenario;
    let n = spec.axes();
    let cycle = s.ring.cycle.0;
    let mut cal = Calibrator::new(CalibrationConfig::new(n, cycle, probes), Instant::ZERO);
    let mut slaves: Vec<Slave> = spec
        .slaves
        .iter()
        .cloned()
        .map(Slave::calibrating)
        .collect();
    let osc = Oscillator::for_scenario(s);
    let limit = cycle.as_ns() * (i64::from(probes) + 2 + i64::from(cal.config().closing_tries));
    let mut link = Link::new(spec, limit, false);
    let residence = link.residence();
    let mut end = 0;
    while let Some(t) = cal.poll_timeout() {
        end = t.as_ns();
        cal.handle_timeout(t);
        while let Some(tx) = cal.poll_transmit() {
            let mut d = link.send(0, tx.at.as_ns(), WireFrame::Bytes(tx.bytes));
            while let Delivery::Arrive {
                node,
                rx_start,
                at,
                frame,
                ..
            } = d
            {
                let mut bytes = frame.into_bytes();
                if node == 0 {
                    cal.handle_frame(Instant::from_ns(rx_start), &bytes);
                    break;
                }
                let (i, o) = (node - 1, &osc[node - 1]);
                let out = slaves[i].handle_frame(o.local(rx_start), o.local(at), &mut bytes);
                if out != FrameOutcome::Forward {
                    break;
                }
                let tx_start = rx_start + residence;
                slaves[i].handle_forwarded(o.local(tx_start));
                d = link.send(node, tx_start, WireFrame::Bytes(bytes));
            }
        }
    }
    let state = cal.state().clone();
    let measured = cal.measurement().cloned();
    match (state, measured) {
        (CalibrationState::Done, Some(measured)) => Ok(StartUp {
            measured,
            taken: slaves.iter().map(Slave::path_delay).collect(),
            planned: spec.plan.d_c.clone(),
            resolution: s.clock.timestamp_resolution.0,
            slaves_rejected: slaves.iter().map(|s| s.counters().rejected.total()).sum(),
            took: Duration::from_ns(end),
        }),
        (CalibrationState::Failed(e), _) => Err(e),
        // The loop ends only when the phase has.
        _ => Err(CalibrationError::NoCompleteProbe {
            sent: 0,
            back: 0,
            late: 0,
            silent: Vec::new(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use ringsync_model::Scenario;

    use super::*;

    fn ring(toml: &str) -> Spec {
        Scenario::from_toml(toml, "test")
            .expect("valid")
            .build()
            .expect("build")
    }

    #[test]
    fn the_measured_path_delays_agree_with_the_planner_within_the_timestamp_resolution() {
        // The reference ring (8 ns stamps, ±50 ppm, offsets), then 16 slaves on 1 Gbit/s
        // with 1 ns stamps and long cables, then RMII PHYs with a slow residence.
        for toml in [
            "",
            "[ring]\nslaves = 16\nbit_rate = \"1G\"\ncable_m = 40.0\n[clock]\ntimestamp_resolution = \"1ns\"\n",
            "[ring]\nslaves = 8\nphy_rx = \"380ns\"\nphy_tx = \"170ns\"\nresidence = \"2500ns\"\n",
        ] {
            let spec = ring(toml);
            let c = calibrate(&spec, DEFAULT_PROBES).expect("calibrated");
            assert_eq!(c.measured.probes_back, DEFAULT_PROBES, "{toml}");
            assert_eq!(c.measured.link, spec.plan.hop, "{toml}");
            let res = c.resolution.as_ns();
            for (i, (m, p)) in c.measured.path.iter().zip(&c.planned).enumerate() {
                let err = (m.as_ns() - p.as_ns()).abs();
                assert!(err <= res, "{toml}: slave {} off by {err} ns", i + 1);
                assert_eq!(c.taken[i], Some(*m));
            }
            assert_eq!(c.slaves_rejected, 0);
        }
    }

    #[test]
    fn jitter_and_loss_cost_probes_not_the_figures() {
        // Every hop up to 40 ns late, 5 % of frames lost round the ring: the medians hold
        // the path delays within the jitter's mean per hop.
        let spec = ring("[ring]\njitter = \"40ns\"\n[faults]\nloss = 0.05\n");
        let c = calibrate(&spec, DEFAULT_PROBES).expect("calibrated");
        assert!(c.measured.probes_back < DEFAULT_PROBES);
        for (i, (m, p)) in c.measured.path.iter().zip(&c.planned).enumerate() {
            let hops = i as i64 + 1;
            let err = m.as_ns() - p.as_ns();
            assert!(
                (0..=hops * 40).contains(&err),
                "slave {}: {err} ns against the plan",
                i + 1
            );
            assert_eq!(c.taken[i], Some(*m));
        }
    }
}
