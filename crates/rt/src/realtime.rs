//! What a real-time loop asks of the operating system: a CPU of its own, the FIFO
//! scheduler, memory that never pages, and busy-waiting for the last part of each wait.
//! Each request that is not granted falls back with one warning; the loop runs anyway.

use ringsync_proto::Duration;

use crate::sys;

/// Real-time settings of a loop thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Realtime {
    /// Busy-wait this long before each deadline instead of sleeping.
    pub spin: Duration,
    /// SCHED_FIFO priority (1-99); 0 keeps the normal scheduler.
    pub priority: i32,
    /// CPU to pin the loop to (None: do not pin).
    pub cpu: Option<usize>,
    /// Lock memory (mlockall).
    pub lock_memory: bool,
}

impl Default for Realtime {
    /// Spin 150 µs, SCHED_FIFO 80, pinned to the last CPU, memory locked (measured on this
    /// kind of machine: DEPENDENCIES.md, docs/runtime.md).
    fn default() -> Self {
        Realtime {
            spin: Duration::from_us(150),
            priority: 80,
            cpu: Some(sys::cpus().saturating_sub(1)),
            lock_memory: true,
        }
    }
}

impl Realtime {
    /// Applies the settings to the calling thread (and, for memory, the process): one line
    /// per setting, what was done or a warning with the reason when it was not allowed.
    pub fn apply(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(cpu) = self.cpu {
            match sys::pin_to_cpu(cpu) {
                Ok(()) => out.push(format!("pinned to CPU {cpu}")),
                Err(e) => out.push(format!(
                    "warning: cannot pin to CPU {cpu} ({e}); running unpinned"
                )),
            }
        }
        if self.priority > 0 {
            match sys::set_fifo(self.priority) {
                Ok(()) => out.push(format!("SCHED_FIFO priority {}", self.priority)),
                Err(e) => out.push(format!(
                    "warning: cannot use SCHED_FIFO ({e}); running with the normal scheduler"
                )),
            }
        }
        if self.lock_memory {
            match sys::lock_memory() {
                Ok(()) => out.push("memory locked".into()),
                Err(e) => out.push(format!("warning: cannot lock memory ({e})")),
            }
        }
        out.push(format!(
            "busy-wait the last {:.0} µs before each deadline",
            self.spin.as_ns() as f64 * 1e-3
        ));
        out
    }
}
