//! Sans-IO ring nodes: the [`Master`] and the [`Slave`]. A node never reads a clock and
//! never touches a socket: time and bytes are passed in, frames and deadlines come out, so
//! the simulator and the real runtime drive the very same code (ARCHITECTURE.md).
//!
//! Times a node sees and returns are on its own local clock (its hardware timestamp
//! counter); the driver converts between local and true time.

pub mod clock;
pub mod master;
pub mod slave;

pub use clock::{ClockFilter, SyncClock};
pub use master::{CycleRecord, Master, MasterConfig, MasterCounters, MasterEvent, StopReason};
pub use slave::{FrameOutcome, LumpedOnlyControl, Slave, SlaveConfig, SlaveCounters, SlaveEvent};

use crate::time::Instant;

/// A frame to put on the ring port, first bit at `at` on the sender's local clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transmit {
    /// When the first bit leaves [local ns].
    pub at: Instant,
    /// The PDU.
    pub bytes: Vec<u8>,
}

#[cfg(test)]
mod tests;
