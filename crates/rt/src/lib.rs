//! The real-time runtime of ringsync: the same sans-IO master and slaves as the simulator,
//! driven through the same `Devices` by the monotonic clock and real sockets. Transports:
//! UDP on loopback, and raw Ethernet (EtherType 0x88B5) on a ring of veth pairs between
//! network namespaces. The slaves' axes are simulated in real time. See `docs/runtime.md`.
//!
//! The rooms: [`run`](mod@run) (options, results, the steps of a run), [`transport`] (ports and
//! [`TransportKind::open`]), [`calibrate`], [`schedule`], [`ring`] (the loop), [`timing`],
//! [`clock`] (the clock and wait discipline the loop shares with [`host`], the probe behind
//! `ringsync latency`), [`inject`] (faults), [`realtime`] (CPU, priority, memory), [`netns`];
//! [`node`] (one node per process: `ringsync node`).

mod breaks;
pub mod calibrate;
pub mod clock;
pub mod frames;
pub mod host;
pub mod inject;
pub mod launch;
pub mod netns;
pub mod node;
pub mod realtime;
pub mod ring;
pub mod run;
pub mod schedule;
pub mod stats;
pub mod supervise;
mod sys;
pub mod timing;
pub mod transport;

pub use inject::{Flap, Forgery};
pub use realtime::{Applied, CpuClaim, Pin, Realtime};
pub use run::{
    Kill, LinksInRun, RtError, RtOptions, RtResult, Sinks, Stamps, Streamed, run, run_observed,
    run_streamed,
};
pub use timing::Timing;
pub use transport::TransportKind;

/// Installs the Ctrl-C (SIGINT), SIGTERM and SIGHUP (terminal closed) handler: the returned
/// flag rises on the signal and a run then ends cleanly, removing its namespaces and links.
pub fn stop_flag() -> &'static std::sync::atomic::AtomicBool {
    sys::stop_flag()
}

/// [`stop_flag`] for work with nothing outside the process to clean up (a simulation, a
/// sweep): the first signal raises the flag, a second one takes the signal's default action
/// (the process ends at once). [`stop_flag`] called afterwards puts back the flag-only
/// handler (the same flag).
pub fn stop_flag_or_twice_exit() -> &'static std::sync::atomic::AtomicBool {
    sys::stop_flag_or_twice_exit()
}
