//! The real-time runtime of ringsync: the same sans-IO master and slaves as the simulator,
//! driven by the monotonic clock and real sockets. Transports: UDP on loopback, and raw
//! Ethernet (EtherType 0x88B5) on a ring of veth pairs between network namespaces. The
//! slaves' axes are simulated in real time. See `docs/runtime.md`.

pub mod calibrate;
pub mod host;
pub mod inject;
pub mod netns;
pub mod realtime;
pub mod run;
pub mod stats;
mod sys;
pub mod transport;

pub use inject::{Flap, Forgery};
pub use realtime::{Applied, CpuClaim, Pin, Realtime};
pub use run::{Kill, RtError, RtOptions, RtResult, Timing, run};
pub use transport::TransportKind;

/// Installs the Ctrl-C (SIGINT), SIGTERM and SIGHUP (terminal closed) handler: the returned
/// flag rises on the signal and a run then ends cleanly, removing its namespaces and links.
pub fn stop_flag() -> &'static std::sync::atomic::AtomicBool {
    sys::stop_flag()
}
