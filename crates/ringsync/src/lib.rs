//! # ringsync
//!
//! The library of ringsync: plan, simulate and run a networked CNC ring with position
//! synchronisation (Huang et al. 2015: a master and n servo axes on a ring; one lumped frame
//! per cycle for clock sync and feedback, point-to-point time slices for commands; a sync
//! controller with a motion message estimator). It is the one front door: the `ringsync`
//! command, the Python package and remote sweep workers all call these functions, so they
//! run the same code. Every function takes plain data and returns a result.
//!
//! | step | function | what comes back |
//! |---|---|---|
//! | load a scenario (name, path or text), set keys | [`load`], [`parse`], [`with_values`] | [`Loaded`] |
//! | plan the cycle (eq. 1-2) | [`plan`], [`plan_of`] | [`CyclePlan`] |
//! | check the loop's stability | [`check`] | [`CheckReport`] |
//! | plan a part program without a ring | [`plan_program`] | [`ProgramPlan`] |
//! | simulate (deterministic) | [`simulate`], [`simulate_with`] (observers, progress) | [`RunResult`] |
//! | sweep keys over seeds | [`sweep::cases`], [`run_case`], [`sweep::run_cases`], [`sweep::aggregate`] | [`sweep::Case`], [`sweep::CaseResult`], [`sweep::Mean`] |
//! | identify the axes of a run (H, C, F) | [`identify::identify_run`], [`identify::identified_toml`] | [`identify::Identification`] |
//! | reproduce the paper's Table 1 over seeds | [`reproduce()`], [`reproduce_with`] | [`Reproduction`] |
//! | run in real time | [`run_rt`] (stop flag, observers), [`predict`], [`predict_rt`] | [`RtResult`], [`SimPrediction`], [`RtPrediction`] |
//! | write results atomically | [`OutDir`], [`write_sim`], [`sweep::write_sweep`], [`write_reproduction`], [`rt::write_rt`] | files |
//!
//! Errors are one type, [`Error`]; [`Error::is_usage`] tells bad input from a failure.
//!
//! ```
//! // The reference scenario, shortened, simulated with the paper's sync controller.
//! let mut s = ringsync::load("paper-2015")?.scenario;
//! s.duration.0 = ringsync::Duration::from_ms(500);
//! let r = ringsync::simulate(&s, &ringsync::SimOptions::default())?;
//! println!("Track-RMSE {:.5} rad, Sync-RMSE {:.7} rad", r.summary.track_rmse, r.summary.sync_rmse);
//! assert!(r.summary.sync_rmse < r.summary.track_rmse);
//! # Ok::<(), ringsync::Error>(())
//! ```
//!
//! The crates underneath (`ringsync-model`, `-sim`, `-rt`, `-proto`, `-control`, `-plant`,
//! `-wire`, `-report`) are the rooms of the house; docs/architecture.md shows where each kind
//! of change goes.

mod check;
mod error;
pub mod identify;
mod load;
pub mod output;
mod plan;
pub mod program;
pub mod reproduce;
pub mod rt;
mod simulate;
pub mod stream;
pub mod sweep;

pub use check::{CheckReport, Verdict, check};
pub use error::{Error, Result};
pub use load::{Loaded, key_value, load, parse, with_values};
pub use output::OutDir;
pub use plan::{plan, plan_of};
pub use program::{ProgramPlan, plan_program};
pub use reproduce::{ReproOptions, Reproduction, reproduce, reproduce_with, write_reproduction};
pub use ringsync_sim::Stop;
pub use rt::{RtPrediction, SimPrediction, predict, predict_rt, run_rt};
pub use simulate::{Outputs, SimOptions, sim_text, simulate, simulate_with, write_sim};
pub use sweep::run_case;

pub use ringsync_model::observer::Observer;
pub use ringsync_model::record::{AxisProbe, FaultEvent, FaultStep};
pub use ringsync_model::result::{Trace, TraceRow};
pub use ringsync_model::{RunResult, Scenario, ScenarioError, Spec, builtin, builtin_names};
pub use ringsync_proto::node::CycleRecord;
pub use ringsync_proto::{CyclePlan, Duration, PlanKind, RingParams};
pub use ringsync_rt::{Kill, RtOptions, RtResult, Stamps, TransportKind};

/// The crates underneath, for what the front door does not cover (driving nodes by hand,
/// the wire format, the control library).
pub mod layers {
    pub use ringsync_control as control;
    pub use ringsync_model as model;
    pub use ringsync_path as path;
    pub use ringsync_proto as proto;
    pub use ringsync_report as report;
    pub use ringsync_rt as runtime;
    pub use ringsync_sim as sim;
    pub use ringsync_wire as wire;
}
