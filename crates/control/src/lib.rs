//! The science of the paper as a library (docs/system.md, "Errors" to "Metrics"): what turns feedback into
//! commands and how a run is judged.
//!
//! - [`trajectory`]: x^d, ẋ^d, ẍ^d (cosine, trapezoid, sequences);
//! - [`coupling`]: ε = T·e, E = (I + αT)·e and its inverse, the ring Laplacian (eq. 3-7);
//! - [`estimator`]: the motion message estimators (a trait, so that one may keep state) and
//!   the error history (eq. 11-13);
//! - [`law`]: the law registry; standard PD, the sync controller (eq. 9, 14), the ring-coupled
//!   baseline, adjacent cross-coupling;
//! - [`dob`]: a disturbance observer per axis (not in the paper), through the nominal model;
//! - [`identify`]: H = J/K_a, C = b/K_a and F = T_c/K_a of a torque axis from a run (least
//!   squares on the integrated axis model), the feed-forward that cancels it;
//! - [`metrics`]: Track-RMSE and Sync-RMSE (eq. 26-27) and per-axis figures;
//! - [`stability`]: the paper's conditions along a trajectory and a discrete-time check.
//!
//! Units: rad, rad/s, rad/s², V, s. Every law is O(n) per cycle and allocates nothing after
//! construction.

pub mod coupling;
pub mod dob;
mod error;
pub mod estimator;
pub mod identify;
pub mod law;
pub mod metrics;
pub mod stability;
pub mod trajectory;

pub use coupling::Coupling;
pub use error::{ControlError, MAX_GAIN};
pub use estimator::{ErrorHistory, Estimator, EstimatorKind, Signal};
pub use law::{
    ControlInput, ControlLaw, ControlOutput, Controller, ErrorObserver, Feedback, Gains, Pd,
    RingCoupled, Sign, SyncController, SyncParams, VelocitySource,
};
pub use metrics::{Metrics, Summary};
pub use trajectory::{
    AxisTrajectory, Cosine, GroupTrajectories, PathAxis, Sequence, State, Trajectory, Trapezoid,
};
