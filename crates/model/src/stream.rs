//! Where a driver streams a run's bulk results while the run goes, instead of keeping them:
//! the trace rows ([`TraceSink`], given to the recorder with
//! [`Devices::stream_trace`](crate::devices::Devices::stream_trace)) and the frames sent
//! ([`CaptureSink`]). A real-time run then takes the same memory whatever its duration.
//!
//! A sink is called from the driver's loop: each call must be short and must never block
//! (hand the item to a bounded queue; a writer thread formats and writes it). A sink that
//! cannot keep up drops what does not fit and counts it, so that the run is never held up
//! and the loss is reported.

use crate::result::{Captured, TraceRow};

/// Takes the trace rows of a run as the recorder completes them: one cycle's rows (axes in
/// order) once the commands they hold have taken effect, i.e. at the next cycle start.
pub trait TraceSink: Send + std::fmt::Debug {
    /// One complete row.
    fn row(&mut self, row: TraceRow);
    /// Rows dropped so far (not taken because the sink was full).
    fn dropped(&self) -> u64;
}

/// Takes the frames a driver sends, as it sends them.
pub trait CaptureSink: Send + std::fmt::Debug {
    /// One frame.
    fn frame(&mut self, frame: Captured);
    /// Frames dropped so far (not taken because the sink was full).
    fn dropped(&self) -> u64;
}

/// A sink that keeps everything in memory, for tests and for callers that want the items
/// back.
#[derive(Debug)]
pub struct Kept<T>(pub std::sync::Arc<std::sync::Mutex<Vec<T>>>);

impl<T> Default for Kept<T> {
    fn default() -> Self {
        Kept(std::sync::Arc::default())
    }
}

impl TraceSink for Kept<TraceRow> {
    fn row(&mut self, row: TraceRow) {
        if let Ok(mut v) = self.0.lock() {
            v.push(row);
        }
    }
    fn dropped(&self) -> u64 {
        0
    }
}

impl CaptureSink for Kept<Captured> {
    fn frame(&mut self, frame: Captured) {
        if let Ok(mut v) = self.0.lock() {
            v.push(frame);
        }
    }
    fn dropped(&self) -> u64 {
        0
    }
}
