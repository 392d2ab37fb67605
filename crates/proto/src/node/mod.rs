//! Sans-IO ring nodes: the [`Master`] and the [`Slave`]. A node never reads a clock and
//! never touches a socket: time and bytes are passed in, frames and deadlines come out, so
//! the simulator and the real runtime drive the very same code (ARCHITECTURE.md).
//!
//! Times a node sees and returns are on its own local clock (its hardware timestamp
//! counter); the driver converts between local and true time.

pub mod clock;
pub mod master;
pub mod motion;
pub mod reject;
pub mod slave;
pub mod testbed;

pub use clock::{ClockFilter, SyncClock};
pub use master::{
    Master, MasterConfig, MasterCounters, MasterEvent, MeasuredSchedule, OffReason, StopOrder,
    StopReason,
};
pub use motion::{
    CycleRecord, MonitorKind, MonitorNews, Motion, MotionInput, MotionOutput, Setpoint,
};
pub use reject::{Reject, Rejections};
pub use slave::{
    FrameOutcome, SafeState, Slave, SlaveConfig, SlaveCounters, SlaveEvent, SlaveLaw,
    TorqueOffCause,
};

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

/// A frame to put on the ring port, first bit at `at` on the sender's local clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transmit {
    /// When the first bit leaves [local ns].
    pub at: Instant,
    /// The PDU.
    pub bytes: Vec<u8>,
}

#[cfg(test)]
mod hostile;
#[cfg(test)]
mod tests;
