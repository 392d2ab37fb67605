//! The sans-IO ringsync protocol layer: integer-nanosecond [time] and the
//! [cycle plan](plan) of eq. 1-2, and the sans-IO ring [nodes](node).

pub mod node;
pub mod plan;
pub mod time;

pub use plan::{CyclePlan, PlanError, PlanKind, RingParams, max_slaves};
pub use time::{Duration, Instant};
