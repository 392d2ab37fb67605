//! The deterministic co-simulator of ringsync: the sans-IO nodes of `ringsync-proto`, built
//! from a scenario by `ringsync-model`, driven by an event queue (`kernel`) on modelled
//! links (`link`) and oscillators. Same scenario and seed: identical results.

pub mod calibrate;
mod kernel;
mod link;
pub mod predict;
pub mod run;

pub use predict::{SimPrediction, predict};
pub use ringsync_model::result::RunResult;
pub use ringsync_model::{Scenario, ScenarioError, builtin, builtin_names};
pub use run::{RunOptions, Stop, run, run_with_progress, simulate};
