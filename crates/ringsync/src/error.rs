//! The one error of the library. It tells bad input (a scenario, an option, a path the
//! caller named: fix the input and call again) from a failure while doing the work (I/O,
//! sockets, the host): [`Error::is_usage`]. The CLI maps the first to exit status 2 and the
//! second to 1.

use ringsync_model::ScenarioError;

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scenario is invalid: the message names the key, the value and what is allowed.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A ring the planner cannot plan: a figure out of range (named by its `RingParams`
    /// field), or a cycle too short for the ring.
    #[error(transparent)]
    Plan(#[from] ringsync_proto::PlanError),
    /// Other bad input: an option or a path; the message names it and what was expected.
    #[error("{0}")]
    Input(String),
    /// A file or directory could not be read or written.
    #[error("{context}: {source}")]
    Io {
        /// What was being done, naming the path.
        context: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The real-time runtime failed (sockets, namespaces).
    #[error(transparent)]
    Rt(ringsync_rt::RtError),
    /// Another failure while doing the work.
    #[error("{0}")]
    Failed(String),
    /// The caller's stop flag rose (Ctrl-C): the work ended early; the message says where.
    #[error("{0}")]
    Interrupted(String),
}

/// The library's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Whether the caller's input is at fault (exit status 2), not the work (exit status 1).
    pub fn is_usage(&self) -> bool {
        matches!(self, Error::Scenario(_) | Error::Plan(_) | Error::Input(_))
    }

    /// An I/O error while doing `context` (which names the path).
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            context: context.into(),
            source,
        }
    }
}

impl From<ringsync_rt::RtError> for Error {
    fn from(e: ringsync_rt::RtError) -> Self {
        match e {
            ringsync_rt::RtError::Scenario(e) => Error::Scenario(e),
            ringsync_rt::RtError::Config(m) => Error::Input(m),
            other => Error::Rt(other),
        }
    }
}

impl From<ringsync_sim::run::RunError> for Error {
    fn from(e: ringsync_sim::run::RunError) -> Self {
        match e {
            ringsync_sim::run::RunError::Scenario(e) => Error::Scenario(e),
            ringsync_sim::run::RunError::Unsupported(m) => Error::Input(m),
            // The simulated ring is the scenario's: a start-up phase that fails there fails
            // on what the scenario asks (more slaves than a delay frame holds, a slave
            // silent from the start).
            e @ ringsync_sim::run::RunError::StartUp(_) => Error::Input(e.to_string()),
            e @ ringsync_sim::run::RunError::Interrupted { .. } => {
                Error::Interrupted(e.to_string())
            }
        }
    }
}

impl From<ringsync_model::check::CheckError> for Error {
    fn from(e: ringsync_model::check::CheckError) -> Self {
        match e {
            ringsync_model::check::CheckError::Scenario(e) => Error::Scenario(e),
            // Gains the arithmetic cannot hold: the scenario's fault, as a bad value is.
            e @ ringsync_model::check::CheckError::Control(
                ringsync_control::ControlError::InvalidParameter { .. },
            ) => Error::Input(e.to_string()),
            other => Error::Failed(other.to_string()),
        }
    }
}

impl From<serde_json::Error> for Error {
    fn from(e: serde_json::Error) -> Self {
        Error::Failed(format!("cannot format JSON: {e}"))
    }
}
