//! Scenarios (and, next, the deterministic co-simulator) of ringsync.
//!
//! A [`Scenario`] is a TOML file in which every parameter of the reference scenario
//! (SYSTEM.md section 6) is a field; see `scenarios/paper-2015.toml`, the built-in one.

pub mod check;
pub mod scenario;

pub use scenario::{Scenario, ScenarioError, builtin, builtin_names};
