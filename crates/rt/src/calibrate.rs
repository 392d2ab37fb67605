//! Start-up calibration of the ring's real delays. The paper's slaves synchronise from the
//! master's send time and a path delay "measured once at configuration" (SYSTEM.md section
//! 2); in software the delays are not the planner's wire figures, so the runtime measures
//! them before the run: lumped frames round the ring (delay from the master's send to each
//! slave, round trip) and one command/response exchange per slave (its time slice).

use std::io;

use ringsync_wire::{
    CommandRepr, Common, FeedbackSlot, Frame, FrameKind, LumpedRepr, ResponseRepr, Status,
};

use crate::stats::Percentiles;
use crate::sys::now_ns;
use crate::transport::{MAX_PDU, Port};

/// The measured delays [ns].
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Rounds measured per figure.
    pub rounds: usize,
    /// Median delay from the master's send to each slave's read of the lumped frame.
    pub path: Vec<i64>,
    /// Lumped frame round trip.
    pub round_trip: Percentiles,
    /// Median delay from the master's send to slave i's read of its command.
    pub command: Vec<i64>,
    /// Time slice per slave: command sent to response read at the master.
    pub slice: Vec<Percentiles>,
}

/// Sends `first` from node `from` and lets the ring carry it: `visit(node, bytes)` is called
/// at every node that reads a frame and returns what that node sends on (the same or a new
/// frame), or `None` when the frame ends there. Returns the read times [ns] per node.
fn pass(
    ports: &mut [Box<dyn Port>],
    from: usize,
    first: &[u8],
    visit: &mut dyn FnMut(usize, &mut Vec<u8>) -> bool,
) -> io::Result<Vec<Option<i64>>> {
    let nodes = ports.len();
    let mut seen = vec![None; nodes];
    let mut buf = vec![0u8; MAX_PDU];
    let t0 = now_ns();
    ports[from].send(first)?;
    let deadline = t0 + 20_000_000;
    loop {
        let mut got = false;
        for node in 0..nodes {
            if let Some(len) = ports[node].recv(&mut buf)? {
                got = true;
                seen[node] = Some(now_ns() - t0);
                let mut bytes = buf[..len].to_vec();
                if !visit(node, &mut bytes) {
                    return Ok(seen);
                }
                ports[node].send(&bytes)?;
            }
        }
        if !got && now_ns() > deadline {
            return Ok(seen);
        }
    }
}

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
    for _ in 0..rounds {
        // Each slave checks the CRC and seals the frame again, as it does when it writes
        // its slot.
        let seen = pass(ports, 0, &lbuf, &mut |node, bytes| {
            if node == 0 {
                return false;
            }
            if let Ok(mut f) = Frame::new_checked(&mut bytes[..])
                && f.check().is_ok()
            {
                f.fill_crc();
            }
            true
        })?;
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
            let seen = pass(ports, 0, &cbuf, &mut |node, bytes| {
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
            })?;
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
        path: path.iter().map(|v| Percentiles::of(v).p50).collect(),
        round_trip: Percentiles::of(&rtt),
        command: command.iter().map(|v| Percentiles::of(v).p50).collect(),
        slice: slice.iter().map(|v| Percentiles::of(v)).collect(),
    })
}
