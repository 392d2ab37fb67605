//! What both drivers of a ring share, the simulator (`ringsync-sim`) and the real-time
//! runtime (`ringsync-rt`):
//!
//! - the [scenario] (schema, validation) and the ring it builds, a [`Spec`];
//! - the one driver kit, [`Devices`]: master, slaves, their oscillators,
//!   the [axes] and the [recorder](record), with [observers](observer) that watch the
//!   run as it goes;
//! - the master's [motion] application (the control law, supervision, the group
//!   stop) behind `ringsync-proto`'s `Motion` trait;
//! - the [results](result) (the trace in columns) and the [sinks](stream) a real-time run
//!   streams them to, where a ring [broke](locate), the seeded
//!   [random streams](rng), the [oscillators](oscillator) and the stability [check].
//!
//! The reference scenario is `paper-2015` (docs/system.md, "The reference scenario").

pub mod axes;
pub mod bounded;
pub mod check;
pub mod contour;
pub mod devices;
pub mod locate;
pub mod monitor;
pub mod motion;
pub mod observer;
pub mod oscillator;
pub mod record;
pub mod result;
pub mod rng;
pub mod scenario;
pub mod spec;
pub mod stream;

pub use devices::Devices;
pub use observer::Observer;
pub use result::RunResult;
/// The control laws and their registry (`law::LAWS`), from `ringsync-control`.
pub use ringsync_control::law;
pub use scenario::{Scenario, ScenarioError, builtin, builtin_names};
pub use spec::Spec;
