//! Scenarios and the deterministic co-simulator of ringsync.
//!
//! A [`Scenario`] is a TOML file in which every parameter of the reference scenario
//! (docs/system.md, "The reference scenario") is a field; see `scenarios/paper-2015.toml`, the built-in one.

pub mod check;
pub mod nodes;
pub mod record;
pub mod rng;
pub mod run;
pub mod scenario;
pub mod sweep;

pub use run::{RunOptions, RunResult, run, run_with_progress};
pub use scenario::{Scenario, ScenarioError, builtin, builtin_names};
