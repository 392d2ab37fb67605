//! Sans-IO ring nodes: the [`Master`] and the [`Slave`]. A node never reads a clock and
//! never touches a socket: time and bytes are passed in, frames and deadlines come out, so
//! the simulator and the real runtime drive the very same code (ARCHITECTURE.md).
//!
//! Times a node sees and returns are on its own local clock (its hardware timestamp
//! counter); the driver converts between local and true time.

pub mod calibrate;
pub mod clock;
pub mod link;
pub mod master;
pub mod motion;
pub mod reject;
pub mod slave;
pub mod testbed;

pub use calibrate::{
    CalibrationConfig, CalibrationError, CalibrationState, Calibrator, DelayMeasurement,
};
pub use clock::{ClockFilter, SyncClock};
pub use master::{
    Master, MasterConfig, MasterCounters, MasterEvent, MeasuredSchedule, OffReason, RingState,
    StopOrder, StopReason,
};
pub use motion::{
    CycleRecord, MonitorKind, MonitorNews, Motion, MotionInput, MotionOutput, Setpoint,
};
pub use reject::{Reject, Rejections};
pub use slave::{
    FrameOutcome, SafeState, Slave, SlaveConfig, SlaveCounters, SlaveEvent, SlaveLaw,
    TorqueOffCause,
};

use std::collections::VecDeque;

use ringsync_wire::Pdu;

use crate::time::Instant;

/// Spare frame buffers a node reuses for its next sends, so that a steady ring allocates
/// nothing per frame: the driver hands back the buffers of the frames it is done with
/// ([`Master::recycle`], [`Slave::recycle`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct Spares(Vec<Vec<u8>>);

impl Spares {
    /// At most this many buffers are kept.
    const MAX: usize = 16;

    /// A zeroed buffer of `len` bytes, a spare one when there is one.
    pub(crate) fn take(&mut self, len: usize) -> Vec<u8> {
        let mut b = self.0.pop().unwrap_or_default();
        b.clear();
        b.resize(len, 0);
        b
    }

    /// Keeps `b` for a later send.
    pub(crate) fn give(&mut self, b: Vec<u8>) {
        if self.0.len() < Self::MAX && b.capacity() > 0 {
            self.0.push(b);
        }
    }
}

/// One of the master's two ends of the ring (docs/planner.md, "A broken link"). A slave
/// sends every frame on its forward port, which is given as [`Port::A`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Port {
    /// Toward slave 1: where the master's frames leave on a whole ring.
    #[default]
    A,
    /// Toward slave n: where the master's frames come back on a whole ring.
    B,
}

impl Port {
    /// "A" or "B".
    pub fn name(self) -> &'static str {
        match self {
            Port::A => "A",
            Port::B => "B",
        }
    }
}

/// A frame to put on the ring port, first bit at `at` on the sender's local clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transmit {
    /// When the first bit leaves [local ns].
    pub at: Instant,
    /// The master's port it leaves on (a slave's frames: [`Port::A`], its forward port).
    pub port: Port,
    /// The PDU.
    pub bytes: Vec<u8>,
}

/// A frame to send, decoded: what [`Master::poll_pdu`] and [`Slave::poll_pdu`] return to a
/// driver that carries frames between nodes without their bytes (the simulator). A node
/// queues only frames that emit ([`Pdu::validate`]), so these are exactly the frames
/// `poll_transmit` would have given as bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct TransmitPdu {
    /// When the first bit leaves [local ns].
    pub at: Instant,
    /// The master's port it leaves on (a slave's frames: [`Port::A`], its forward port).
    pub port: Port,
    /// The PDU.
    pub pdu: Pdu,
}

/// A frame as a driver carries it from node to node: its bytes (the runtime; the
/// simulator's captures and corrupted frames), or decoded (the simulator's typed frames,
/// whose bytes and CRC nobody reads). A node takes either: `handle_frame` checks the
/// bytes (length, CRC, layout) and then applies the same checks against its state as
/// `handle_pdu` does to a decoded frame.
#[derive(Debug, Clone, PartialEq)]
pub enum WireFrame {
    /// The PDU's bytes, header to CRC.
    Bytes(Vec<u8>),
    /// The PDU, decoded.
    Pdu(Pdu),
}

impl WireFrame {
    /// The frame's bytes: `Bytes` as they are, a decoded PDU emitted (empty if it cannot
    /// be; a node never queues one that cannot).
    pub fn into_bytes(self) -> Vec<u8> {
        match self {
            WireFrame::Bytes(b) => b,
            WireFrame::Pdu(p) => {
                let mut b = Vec::new();
                let _ = p.emit_into(&mut b);
                b
            }
        }
    }
}

/// The frames a node has queued, decoded and checked emittable; bytes are built when the
/// driver polls for bytes.
#[derive(Debug, Clone, Default)]
pub(crate) struct Outbox {
    queue: VecDeque<TransmitPdu>,
    spares: Spares,
}

impl Outbox {
    /// Queues `pdu` to leave at `at`; false (and nothing queued) if it cannot be emitted.
    #[inline]
    pub(crate) fn push(&mut self, at: Instant, pdu: Pdu) -> bool {
        self.push_on(at, Port::A, pdu)
    }

    /// Queues `pdu` to leave at `at` on `port`; false (and nothing queued) if it cannot be
    /// emitted. (Inlined where the PDU is built, so that it is written into the queue
    /// rather than copied from where its fields were just stored.)
    #[inline]
    pub(crate) fn push_on(&mut self, at: Instant, port: Port, pdu: Pdu) -> bool {
        if pdu.validate().is_err() {
            return false;
        }
        self.queue.push_back(TransmitPdu { at, port, pdu });
        true
    }

    /// The next frame, decoded.
    pub(crate) fn pop_pdu(&mut self) -> Option<TransmitPdu> {
        self.queue.pop_front()
    }

    /// The next frame as bytes (in a spare buffer), with the PDU it was built from.
    pub(crate) fn pop_bytes(&mut self) -> Option<(Transmit, Pdu)> {
        let TransmitPdu { at, port, pdu } = self.queue.pop_front()?;
        let mut bytes = self.spares.take(pdu.buffer_len());
        // Checked when queued: emit cannot fail here.
        let _ = pdu.emit(&mut bytes);
        Some((Transmit { at, port, bytes }, pdu))
    }

    /// Keeps a buffer for a later send.
    pub(crate) fn recycle(&mut self, b: Vec<u8>) {
        self.spares.give(b);
    }
}

#[cfg(test)]
mod hostile;
#[cfg(test)]
mod tests;
