//! Start-up calibration of the ring's real delays. The paper's slaves synchronise from the
//! master's send time and a path delay "measured once at configuration" (docs/system.md,
//! "The cycle plan"); in software the delays are not the planner's wire figures, so the runtime measures
//! them before the run: lumped frames round the ring (delay from the master's send to each
//! slave, round trip) and one command/response exchange per slave (its time slice).

use std::io;

use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Frame, FrameKind, LumpedRepr, ResponseRepr, Status,
};

use crate::stats::Percentiles;
use crate::sys::now_ns;
use crate::timing::STALL;
use crate::transport::{MAX_PDU, Port};

/// The measured delays [ns].
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Rounds measured per figure.
    pub rounds: usize,
    /// Rounds measured again because the host held the loop off its CPU during them
    /// (a stall of [`STALL`] or more between two clock readings).
    pub repeated: usize,
    /// Median delay from the master's send to each slave's read of the lumped frame.
    pub path: Vec<i64>,
    /// Lumped frame round trip.
    pub round_trip: Percentiles,
    /// Median delay from the master's send to slave i's read of its command.
    pub command: Vec<i64>,
    /// Time slice per slave: command sent to response read at the master.
    pub slice: Vec<Percentiles>,
}

/// One pass of a frame round the ring: the read time at each node [ns from the send], and
/// whether the host held the loop off its CPU meanwhile (then the times measure the host).
struct Pass {
    seen: Vec<Option<i64>>,
    stalled: bool,
}

/// Sends `first` from node `from` and lets the ring carry it: `visit(node, bytes)` is called
/// at every node that reads a frame and returns whether that node sends it on (changed or
/// not) or the frame ends there.
fn pass(
    ports: &mut [Box<dyn Port>],
    from: usize,
    first: &[u8],
    visit: &mut dyn FnMut(usize, &mut Vec<u8>) -> bool,
) -> io::Result<Pass> {
    let nodes = ports.len();
    let mut out = Pass {
        seen: vec![None; nodes],
        stalled: false,
    };
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
                out.seen[node] = Some(tick(&mut out.stalled) - t0);
                let mut bytes = buf[..len].to_vec();
                if !visit(node, &mut bytes) {
                    return Ok(out);
                }
                port.send(&bytes)?;
            }
        }
        // The loop reads the clock at least once per sweep of the ports, a few µs apart.
        let now = tick(&mut out.stalled);
        if !got && now > deadline {
            return Ok(out);
        }
    }
}

/// Repeats `one` until it gives a pass the host did not stall, at most `tries` times; the
/// last pass otherwise. Counts the passes thrown away.
fn unstalled(
    tries: usize,
    repeated: &mut usize,
    mut one: impl FnMut() -> io::Result<Pass>,
) -> io::Result<Pass> {
    let mut p = one()?;
    for _ in 1..tries {
        if !p.stalled {
            break;
        }
        *repeated += 1;
        p = one()?;
    }
    Ok(p)
}

/// A pass the host stalled is measured again at most this many times.
const TRIES: usize = 5;

/// Measures the ring of `ports` (node 0 the master) over `rounds` rounds each.
pub fn calibrate(ports: &mut [Box<dyn Port>], rounds: usize) -> io::Result<Calibration> {
    let n = ports.len() - 1;
    let mut path: Vec<Vec<i64>> = vec![Vec::new(); n];
    let mut rtt = Vec::new();
    let lumped = LumpedRepr {
        common: Common::default(),
        master_time_ns: 0,
        first_slot: 0,
        slots: vec![FeedbackSlot::default(); n],
    };
    let mut lbuf = vec![0u8; lumped.buffer_len()];
    lumped
        .emit(&mut lbuf)
        .map_err(|e| io::Error::other(e.to_string()))?;
    let mut repeated = 0;
    for _ in 0..rounds {
        // Each slave checks the CRC and seals the frame again, as it does when it writes
        // its slot.
        let seen = unstalled(TRIES, &mut repeated, || {
            pass(ports, 0, &lbuf, &mut |node, bytes| {
                if node == 0 {
                    return false;
                }
                if let Ok(mut f) = Frame::new_checked(&mut bytes[..])
                    && f.check().is_ok()
                {
                    f.fill_crc();
                }
                true
            })
        })?
        .seen;
        for (i, p) in path.iter_mut().enumerate() {
            if let Some(t) = seen[i + 1] {
                p.push(t);
            }
        }
        if let Some(t) = seen[0] {
            rtt.push(t);
        }
    }
    let mut command: Vec<Vec<i64>> = vec![Vec::new(); n];
    let mut slice: Vec<Vec<i64>> = vec![Vec::new(); n];
    for target in 1..=n {
        let cmd = CommandRepr {
            common: Common::default(),
            target: target as u16,
            command_v: 0.0,
            sample_time_ns: 0,
        };
        let mut cbuf = vec![0u8; cmd.buffer_len()];
        cmd.emit(&mut cbuf)
            .map_err(|e| io::Error::other(e.to_string()))?;
        let resp = ResponseRepr {
            common: Common::default(),
            source: target as u16,
            status: Status::empty(),
            echo_cycle: 0,
            position: 0,
            velocity: 0,
            sample_time_ns: 0,
            applied_v: 0.0,
        };
        let mut rbuf = vec![0u8; resp.buffer_len()];
        resp.emit(&mut rbuf)
            .map_err(|e| io::Error::other(e.to_string()))?;
        for _ in 0..rounds {
            let seen = unstalled(TRIES, &mut repeated, || {
                pass(ports, 0, &cbuf, &mut |node, bytes| {
                    if node == 0 {
                        return false;
                    }
                    let kind = Frame::new_checked(&bytes[..])
                        .ok()
                        .and_then(|f| f.check().ok());
                    if node == target && kind == Some(FrameKind::Command) {
                        bytes.clone_from(&rbuf);
                    }
                    true
                })
            })?
            .seen;
            if let (Some(c), Some(s)) = (seen[target], seen[0]) {
                command[target - 1].push(c);
                slice[target - 1].push(s);
            }
        }
    }
    let incomplete = path.iter().chain(&command).any(|v| v.is_empty()) || rtt.is_empty();
    if incomplete {
        return Err(io::Error::new(
            io::ErrorKind::TimedOut,
            "calibration frames did not make it round the ring (a node does not forward)",
        ));
    }
    Ok(Calibration {
        rounds,
        repeated,
        path: path.iter().map(|v| Percentiles::of(v).p50).collect(),
        round_trip: Percentiles::of(&rtt),
        command: command.iter().map(|v| Percentiles::of(v).p50).collect(),
        slice: slice.iter().map(|v| Percentiles::of(v)).collect(),
    })
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

    fn round(ports: &mut [Box<dyn Port>]) -> Pass {
        pass(ports, 0, &[1, 2, 3], &mut |node, _| node != 0).expect("pass")
    }

    #[test]
    fn a_host_stall_anywhere_in_a_pass_is_seen() {
        // At the master's send (before the loop's first reading), at a slave's forwarding,
        // at the master's final read (the sweep that ends the pass).
        for slow in [(0, true), (2, true), (0, false)] {
            let p = round(&mut MemPort::ring(5, Some(slow)));
            assert!(p.seen.iter().all(Option::is_some), "{slow:?}");
            assert!(p.stalled, "a 200 µs stall at {slow:?} went unseen");
        }
        // Without one, most passes are clean (this test's own thread may be preempted now
        // and then on a busy machine).
        let clean = (0..20)
            .filter(|_| !round(&mut MemPort::ring(5, None)).stalled)
            .count();
        assert!(clean > 0);
    }

    fn passes(stalled: &'static [bool]) -> impl FnMut() -> io::Result<Pass> {
        let mut k = 0;
        move || {
            let p = Pass {
                seen: vec![Some(k as i64)],
                stalled: stalled[k.min(stalled.len() - 1)],
            };
            k += 1;
            Ok(p)
        }
    }

    #[test]
    fn a_stalled_pass_is_measured_again() {
        let mut repeated = 0;
        let p = unstalled(TRIES, &mut repeated, passes(&[true, true, false])).expect("pass");
        assert_eq!((p.seen[0], p.stalled, repeated), (Some(2), false, 2));
        // A clean first pass is kept as it is.
        let p = unstalled(TRIES, &mut repeated, passes(&[false])).expect("pass");
        assert_eq!((p.seen[0], repeated), (Some(0), 2));
        // A host that stalls every pass: the last of TRIES is taken.
        let mut repeated = 0;
        let p = unstalled(TRIES, &mut repeated, passes(&[true])).expect("pass");
        assert_eq!((p.seen[0], p.stalled), (Some(TRIES as i64 - 1), true));
        assert_eq!(repeated, TRIES - 1);
    }
}
