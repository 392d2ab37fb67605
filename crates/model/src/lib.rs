//! What both drivers of a ring share, the simulator (`ringsync-sim`) and the real-time
//! runtime (`ringsync-rt`): the [scenario](scenario) (schema, validation, building), the
//! ring it builds ([`nodes`]: the nodes' configurations, oscillators, servo axes, where a
//! ring broke), the per-cycle [recorder](record), the [results](result), the seeded
//! [random streams](rng) and the stability [check].
//!
//! The scenario's reference is `paper-2015` (docs/system.md, "The reference scenario").

pub mod check;
pub mod motion;
pub mod nodes;
pub mod record;
pub mod result;
pub mod rng;
pub mod scenario;

pub use result::RunResult;
pub use scenario::{Scenario, ScenarioError, builtin, builtin_names};
