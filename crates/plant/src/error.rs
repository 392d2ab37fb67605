//! Errors of the plant layer.

/// A bad plant parameter or call.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// A parameter outside its allowed range.
    #[error("plant parameter {name} = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// Parameter name, e.g. `inertia`.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range, with units.
        expected: &'static str,
    },
    /// A slice of the wrong length.
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

/// Checks `value` is finite and within [min, max] (max inclusive); `min_exclusive` makes
/// the lower bound strict.
pub(crate) fn check(
    name: &'static str,
    value: f64,
    min: f64,
    min_exclusive: bool,
    expected: &'static str,
) -> Result<f64, PlantError> {
    let ok = value.is_finite()
        && if min_exclusive {
            value > min
        } else {
            value >= min
        };
    if ok {
        Ok(value)
    } else {
        Err(PlantError::InvalidParameter {
            name,
            value,
            expected,
        })
    }
}
