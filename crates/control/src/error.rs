//! Errors of the control layer.

/// A bad parameter or a call that does not fit the configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControlError {
    /// A parameter outside its allowed range (NaN included).
    #[error("{name} = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// Parameter name, e.g. `kp[2]` or `a_max`.
        name: String,
        /// The value given.
        value: f64,
        /// The allowed range, with units.
        expected: std::borrow::Cow<'static, str>,
    },
    /// A law parameter the law does not declare.
    #[error("control law {law} has no parameter '{key}': its parameters are {known}")]
    UnknownParameter {
        /// The law's registry name.
        law: &'static str,
        /// The key given.
        key: String,
        /// The keys it declares, comma-separated, or `none`.
        known: String,
    },
    /// Coupling needs at least `min` axes.
    #[error("{what} needs at least {min} axes, got {n}")]
    TooFewAxes {
        /// What needs them.
        what: &'static str,
        /// Axes given.
        n: usize,
        /// Axes needed.
        min: usize,
    },
    /// An axis index past the last axis.
    #[error("axis {axis} does not exist: there are {n} axes (0-based)")]
    AxisOutOfRange {
        /// Index given.
        axis: usize,
        /// Number of axes.
        n: usize,
    },
    /// A numerical method did not converge.
    #[error("{what} did not converge")]
    NoConvergence {
        /// Which computation.
        what: &'static str,
    },
    /// An analysis whose assumptions the configuration does not meet.
    #[error("{what} does not apply: {why}")]
    NotApplicable {
        /// Which analysis.
        what: &'static str,
        /// Which assumption fails, and for what.
        why: String,
    },
    /// A slice or vector of the wrong length.
    #[error("{what}: expected {expected} values, got {got}")]
    LengthMismatch {
        /// Which slice.
        what: &'static str,
        /// Length needed.
        expected: usize,
        /// Length given.
        got: usize,
    },
}

/// Checks that `value` is finite and ≥ `min` (or > `min` when `strict`).
pub(crate) fn check(
    name: &str,
    value: f64,
    min: f64,
    strict: bool,
    expected: &'static str,
) -> Result<f64, ControlError> {
    let ok = value.is_finite() && if strict { value > min } else { value >= min };
    if ok {
        Ok(value)
    } else {
        Err(invalid(name, value, expected))
    }
}

/// `name = value` refused: `expected` says what is allowed.
fn invalid(name: &str, value: f64, expected: &'static str) -> ControlError {
    ControlError::InvalidParameter {
        name: name.to_string(),
        value,
        expected: expected.into(),
    }
}

/// Largest magnitude of a gain (and of the sync coupling's α): beyond about 10¹⁵⁴ a law's
/// products overflow double precision into a command that is not a number, and no drive's
/// volts per radian come anywhere near this.
pub const MAX_GAIN: f64 = 1e12;

/// [`check`], and at most [`MAX_GAIN`] in magnitude (`expected` says both).
pub(crate) fn check_gain(
    name: &str,
    value: f64,
    min: f64,
    strict: bool,
    expected: &'static str,
) -> Result<f64, ControlError> {
    let v = check(name, value, min, strict, expected)?;
    if v.abs() > MAX_GAIN {
        return Err(invalid(name, value, expected));
    }
    Ok(v)
}

/// Checks a slice's length.
pub(crate) fn check_len(
    what: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), ControlError> {
    if expected == got {
        Ok(())
    } else {
        Err(ControlError::LengthMismatch {
            what,
            expected,
            got,
        })
    }
}
