//! Scenario files: every parameter of a run, in TOML, validated with errors that name the key,
//! the value and the allowed range.
//!
//! Every key is optional and defaults to the reference scenario `paper-2015`
//! (`scenarios/paper-2015.toml`, which a test keeps equal to [`Scenario::default`]). Unknown
//! keys are errors.
//!
//! The rooms: [`schema`] (the tables and keys, as data), [`load`] (names, files, text),
//! [`validate`] (ranges and cross-key rules), [`build`] (the run's objects), [`error`];
//! [`plant`] holds the `[plant]` table whole (schema, checks, parameters).

pub mod build;
pub mod error;
pub mod load;
pub mod machine;
pub mod plant;
pub mod schema;
pub mod validate;

pub use error::{ECHO_CHARS, ScenarioError, clip, clip_middle, toml_message};
pub use load::{MAX_SCENARIO_BYTES, builtin, builtin_names, fnv1a};
pub use machine::{
    MachineAxis, MachineAxisSpec, MachineMap, MachineSpec, ProgramText, builtin_program,
    builtin_programs,
};
pub use plant::{ARM_MAX_STEP, ArmSpec, PlantSpec};
pub use schema::*;
pub use validate::{EncoderBits, MIN_ENCODER_BITS, VELOCITY_MARGIN};

#[cfg(test)]
mod tests;
