//! Part programs for ringsync (docs/programs.md): what a CNC does between a G-code file and
//! the setpoints its axes get every cycle.
//!
//! - [`program`]: the interpreter, G-code text to canonical lines, arcs and dwells;
//! - [`geometry`]: the curves of a path, each by arc length, with the frame (tangent,
//!   curvature and its derivative) that turns path motion into axis motion;
//! - [`blend`]: corners replaced by quintic blends that meet both neighbours in point,
//!   tangent and curvature, within the path tolerance;
//! - [`mod@plan`]: the look-ahead and the jerk-limited feed along the path, under every
//!   machine axis's velocity, acceleration and jerk limit; the planned path at any instant,
//!   and the contour error (the distance from a point to the programmed path);
//! - [`circular`]: the ISO 230-4 circular test;
//! - [`check`]: the setpoints sampled at a cycle against the limits and the program;
//! - [`corpus`]: generated programs for tests and benchmarks.
//!
//! Units: mm, s. Nothing here knows about rings, drives or time sources.

pub mod blend;
pub mod check;
pub mod circular;
pub mod corpus;
pub mod geometry;
pub mod plan;
pub mod program;
pub mod vec3;

pub use plan::{Limits, Machine, PathState, PlanError, PlannedPath, plan};
pub use program::{Move, MoveKind, Program, ProgramError, Source, interpret};
pub use vec3::Vec3;
