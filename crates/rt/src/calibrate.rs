//! The start-up phase on a real ring: the nodes measure the ring's delays before the run
//! (docs/planner.md, "Delays measured by the nodes"). The master's [`Calibrator`] sends its
//! delay probes round the ring; every slave is the real sans-IO node in its start-up phase
//! ([`Slave::calibrating`]), reading each probe at the loop's reading time on its own clock
//! and reporting how long it held it; the master sends each slave the path delay it
//! computed, and the slave takes it. The runtime carries the frames and nothing else: it
//! computes no node's answer.
//!
//! From the same probes the master has its round trip, from which the runtime plans its
//! P2P phase: a command to slave i and its response cross the ring once, as a probe does,
//! less slave i's residence, plus the response delay T_ti.

use std::io;

use ringsync_model::Spec;
use ringsync_model::oscillator::Oscillator;
use ringsync_model::result::StartUp;
use ringsync_proto::node::{
    CalibrationConfig, CalibrationError, CalibrationState, Calibrator, FrameOutcome, Slave,
};
use ringsync_proto::{Duration, Instant};

use crate::stats::Percentiles;
use crate::sys::now_ns;
use crate::timing::STALL;
use crate::transport::{MAX_PDU, Port};

/// What the start-up phase measured \[ns\].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Calibration {
    /// Probes sent.
    pub rounds: usize,
    /// Probes not counted because the host held the loop off its CPU while they went round
    /// (a stall of [`STALL`] or more between two clock readings): they measure the host.
    pub repeated: usize,
    /// Each slave's path delay as the nodes measured it and the slave took it: master send
    /// to the slave's reading of a frame.
    pub path: Vec<i64>,
    /// Probe round trip, master send to its reading of the probe back.
    pub round_trip: Percentiles,
    /// Master send to slave i's reading of its command: its path delay (a command is relayed
    /// like a probe).
    pub command: Vec<i64>,
    /// Time slice per slave, command sent to response read at the master, less T_ti: the
    /// round trip less slave i's residence.
    pub slice: Vec<Percentiles>,
    /// The nodes' figures (one link, each residence, the path delays) and what each slave
    /// took.
    pub start_up: StartUp,
}

/// What befell a frame at a node, for the driver of [`pass`]'s caller.
enum Hop<'a> {
    /// Node `node` read the frame at true time `t` [ns]; `bytes` may be changed in place.
    /// Returns whether the node sends it on.
    Read {
        node: usize,
        t: i64,
        bytes: &'a mut Vec<u8>,
    },
    /// Node `node` sent the frame on, the send done at true time `t` [ns].
    Sent { node: usize, t: i64 },
}

/// One pass of a frame round the ring: whether the host held the loop off its CPU
/// meanwhile (then the times measure the host).
struct Pass {
    stalled: bool,
}

/// Sends `first` from node `from` (its send done at true time `origin` + returned reading)
/// and lets the ring carry it: `on` is told of every node that reads the frame (and says
/// whether it goes on) and of every send. True time is the monotonic clock less `origin`.
fn pass(
    ports: &mut [Box<dyn Port>],
    from: usize,
    first: &[u8],
    origin: i64,
    on: &mut dyn FnMut(Hop<'_>) -> bool,
) -> io::Result<Pass> {
    let mut out = Pass { stalled: false };
    let mut buf = vec![0u8; MAX_PDU];
    // Every clock reading is checked against the one before, from the send on: a send or
    // a read is where the kernel most often hands the CPU to another task, and a gap there
    // that went unchecked (before the first reading after the send, or in the sweep that
    // ends the pass) was kept as a slow ring (a normal-priority loop under load measured
    // slices of 300-1100 µs and refused the 1 ms cycle).
    let t0 = now_ns();
    let mut last = t0;
    let mut tick = |stalled: &mut bool| {
        let now = now_ns();
        *stalled |= now - last >= STALL;
        last = now;
        now
    };
    ports[from].send(first)?;
    let deadline = t0 + 20_000_000;
    loop {
        let mut got = false;
        for (node, port) in ports.iter_mut().enumerate() {
            if let Some(len) = port.recv(&mut buf)? {
                got = true;
                let t = tick(&mut out.stalled);
                let mut bytes = buf[..len].to_vec();
                let read = Hop::Read {
                    node,
                    t: t - origin,
                    bytes: &mut bytes,
                };
                if !on(read) {
                    return Ok(out);
                }
                port.send(&bytes)?;
                let t = tick(&mut out.stalled);
                on(Hop::Sent {
                    node,
                    t: t - origin,
                });
            }
        }
        // The loop reads the clock at least once per sweep of the ports, a few µs apart.
        let now = tick(&mut out.stalled);
        if !got && now > deadline {
            return Ok(out);
        }
    }
}

/// Runs the nodes' start-up phase on the ring of `ports` (node 0 the master) with `rounds`
/// probes: the master and `spec`'s slaves, each slave on its own oscillator (the same as
/// the run's). A probe the host stalled is not handed back to the master (the master counts
/// it lost).
pub fn calibrate(
    ports: &mut [Box<dyn Port>],
    spec: &Spec,
    rounds: usize,
) -> io::Result<Calibration> {
    let n = ports.len() - 1;
    let cycle = spec.scenario.ring.cycle.0;
    let probes = u32::try_from(rounds).unwrap_or(u32::MAX).max(2);
    // The ring waits for each frame to come back (or 20 ms), so the probes need no spacing
    // of their own: one per pass.
    let mut cfg = CalibrationConfig::new(n, cycle, probes);
    cfg.interval = Duration::from_ns(1);
    let mut cal = Calibrator::new(cfg, Instant::ZERO);
    let mut slaves: Vec<Slave> = spec
        .slaves
        .iter()
        .cloned()
        .map(Slave::calibrating)
        .collect();
    let osc = Oscillator::for_scenario(&spec.scenario);
    let origin = now_ns();
    let mut repeated = 0;
    let mut buf = vec![0u8; MAX_PDU];
    while let Some(at) = cal.poll_timeout() {
        let now = Instant::from_ns(now_ns() - origin).max(at);
        cal.handle_timeout(now);
        while let Some(tx) = cal.poll_transmit() {
            let len = tx.bytes.len();
            buf[..len].copy_from_slice(&tx.bytes);
            let mut back: Option<(i64, Vec<u8>)> = None;
            let p = pass(ports, 0, &buf[..len], origin, &mut |hop| match hop {
                Hop::Read { node: 0, t, bytes } => {
                    back = Some((t, std::mem::take(bytes)));
                    false
                }
                Hop::Read { node, t, bytes } => {
                    let local = osc[node - 1].local(t);
                    slaves[node - 1].handle_frame(local, local, bytes) == FrameOutcome::Forward
                }
                Hop::Sent { node, t } => {
                    if node > 0 {
                        slaves[node - 1].handle_forwarded(osc[node - 1].local(t));
                    }
                    true
                }
            })?;
            if p.stalled {
                repeated += 1;
            } else if let Some((t, bytes)) = back {
                cal.handle_frame(Instant::from_ns(t), &bytes);
            }
        }
    }
    let m = match (cal.state(), cal.measurement()) {
        (CalibrationState::Done, Some(m)) => m.clone(),
        (CalibrationState::Failed(e), _) => return Err(failed(e)),
        _ => {
            return Err(failed(&CalibrationError::NotAcknowledged {
                slaves: vec![],
            }));
        }
    };
    let taken: Vec<Option<Duration>> = slaves.iter().map(Slave::path_delay).collect();
    let rejected = slaves.iter().map(|s| s.counters().rejected.total()).sum();
    Ok(Calibration::of(
        m,
        taken,
        repeated,
        rejected,
        spec,
        Duration::from_ns(now_ns() - origin),
    ))
}

impl Calibration {
    /// The runtime's figures from the master's measurement `m`: the path delay each slave
    /// took (`taken`; a slave that took none, which a finished phase rules out, counts with
    /// the master's figure), the probes not counted after a host stall (`repeated`), the
    /// frames the slaves refused (`rejected`), how long the phase took (`took`).
    pub fn of(
        m: ringsync_proto::node::DelayMeasurement,
        taken: Vec<Option<Duration>>,
        repeated: usize,
        rejected: u64,
        spec: &Spec,
        took: Duration,
    ) -> Calibration {
        let path: Vec<i64> = taken
            .iter()
            .zip(&m.path)
            .map(|(t, p)| t.unwrap_or(*p).as_ns())
            .collect();
        let rtt: Vec<i64> = m.round_trips.iter().map(|d| d.as_ns()).collect();
        let slice = m
            .residence
            .iter()
            .map(|r| {
                let v: Vec<i64> = rtt.iter().map(|t| t - r.as_ns()).collect();
                Percentiles::of(&v)
            })
            .collect();
        Calibration {
            rounds: m.probes as usize,
            repeated,
            command: path.clone(),
            path,
            round_trip: Percentiles::of(&rtt),
            slice,
            start_up: StartUp {
                taken,
                planned: spec.plan.d_c.clone(),
                resolution: spec.scenario.clock.timestamp_resolution.0,
                slaves_rejected: rejected,
                took,
                measured: m,
            },
        }
    }
}

fn failed(e: &CalibrationError) -> io::Error {
    io::Error::new(
        io::ErrorKind::TimedOut,
        format!("the start-up phase failed: {e}"),
    )
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;
    use std::sync::{Arc, Mutex};

    use super::*;

    /// A ring in memory: node i sends to node i + 1 (the last to node 0). A send or a read
    /// at `slow` takes 200 µs, as when the kernel hands the CPU to another task there.
    struct MemPort {
        node: usize,
        queues: Arc<Mutex<Vec<VecDeque<Vec<u8>>>>>,
        slow: Option<(usize, bool)>,
    }

    impl MemPort {
        fn ring(nodes: usize, slow: Option<(usize, bool)>) -> Vec<Box<dyn Port>> {
            let queues = Arc::new(Mutex::new(vec![VecDeque::new(); nodes]));
            (0..nodes)
                .map(|node| {
                    Box::new(MemPort {
                        node,
                        queues: queues.clone(),
                        slow,
                    }) as Box<dyn Port>
                })
                .collect()
        }

        fn maybe_slow(&self, send: bool) {
            if self.slow == Some((self.node, send)) {
                std::thread::sleep(std::time::Duration::from_micros(200));
            }
        }
    }

    impl Port for MemPort {
        fn send(&mut self, pdu: &[u8]) -> io::Result<()> {
            self.maybe_slow(true);
            let mut q = self
                .queues
                .lock()
                .map_err(|_| io::Error::other("poisoned"))?;
            let next = (self.node + 1) % q.len();
            q[next].push_back(pdu.to_vec());
            Ok(())
        }

        fn recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
            let got = self
                .queues
                .lock()
                .map_err(|_| io::Error::other("poisoned"))?[self.node]
                .pop_front();
            Ok(got.map(|f| {
                self.maybe_slow(false);
                buf[..f.len()].copy_from_slice(&f);
                f.len()
            }))
        }

        fn rx_fd(&self) -> std::os::fd::RawFd {
            -1
        }
    }

    /// A pass of a 3-byte frame round the ring: the pass, and how many nodes read it.
    fn round(ports: &mut [Box<dyn Port>]) -> (Pass, usize) {
        let mut read = 0;
        let p = pass(ports, 0, &[1, 2, 3], 0, &mut |hop| match hop {
            Hop::Read { node, .. } => {
                read += 1;
                node != 0
            }
            Hop::Sent { .. } => true,
        })
        .expect("pass");
        (p, read)
    }

    #[test]
    fn a_host_stall_anywhere_in_a_pass_is_seen() {
        // At the master's send (before the loop's first reading), at a slave's forwarding,
        // at the master's final read (the sweep that ends the pass).
        for slow in [(0, true), (2, true), (0, false)] {
            let (p, read) = round(&mut MemPort::ring(5, Some(slow)));
            assert_eq!(read, 5, "{slow:?}");
            assert!(p.stalled, "a 200 µs stall at {slow:?} went unseen");
        }
        // Without one, most passes are clean (this test's own thread may be preempted now
        // and then on a busy machine).
        let clean = (0..20)
            .filter(|_| !round(&mut MemPort::ring(5, None)).0.stalled)
            .count();
        assert!(clean > 0);
    }

    #[test]
    fn the_real_nodes_measure_the_ring_and_every_slave_takes_its_delay() {
        let s = ringsync_model::Scenario::from_toml("", "test").expect("scenario");
        let spec = s.build().expect("spec");
        let mut ports = MemPort::ring(spec.axes() + 1, None);
        let c = calibrate(&mut ports, &spec, 50).expect("calibrated");
        assert_eq!(c.rounds, 50);
        let m = &c.start_up.measured;
        assert!(m.complete >= 1 && m.complete as usize + c.repeated <= 50);
        // Each slave took what the master measured, and the path grows round the ring by
        // a link and a residence per slave.
        for (i, t) in c.start_up.taken.iter().enumerate() {
            assert_eq!(*t, Some(m.path[i]));
            assert_eq!(c.path[i], m.path[i].as_ns());
        }
        for w in m.path.windows(2) {
            assert!(w[1] > w[0], "{:?}", m.path);
        }
        assert_eq!(c.start_up.slaves_rejected, 0);
    }
}
