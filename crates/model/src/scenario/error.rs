//! What is wrong with a scenario: one error type whose messages name the key, the value and
//! what is allowed, and the maps from the control and plant layers' errors back to the
//! scenario keys they came from.

use std::fmt;

use ringsync_control::ControlError;
use ringsync_plant::PlantError;

/// What is wrong with a scenario.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// The text is not valid TOML, or a value has the wrong type, or a key is unknown.
    #[error("{origin}: {message}")]
    Syntax {
        /// File name or scenario name.
        origin: String,
        /// One line: where and what.
        message: String,
    },
    /// A value out of its range.
    #[error("{key} = {value} is out of range: allowed {allowed}")]
    OutOfRange {
        /// Dotted key, e.g. `ring.slaves` or `axis[2].viscous`.
        key: String,
        /// The value given.
        value: String,
        /// The allowed range, with units.
        allowed: String,
    },
    /// A key in `[control.params]` that the chosen law does not declare.
    #[error(
        "control.params.{key} is not a parameter of control.law = \"{law}\": its parameters are {known}{owners}"
    )]
    UnknownParameter {
        /// The key given.
        key: String,
        /// The chosen law's registry name.
        law: String,
        /// The keys the law declares, comma-separated, or `none`.
        known: String,
        /// `; <key> is a parameter of "<law>"` when another law declares it, else empty.
        owners: String,
    },
    /// A name that is not a built-in scenario or a readable file.
    #[error("unknown scenario '{0}': not a built-in scenario ({1}) and no such file")]
    Unknown(String, String),
    /// A part program that cannot be read, interpreted or planned.
    #[error("{file}: {message}")]
    Program {
        /// The program file (or built-in name).
        file: String,
        /// Where in it (line and column) and what is wrong.
        message: String,
    },
    /// The file could not be read.
    #[error("cannot read {path}: {reason}")]
    Io {
        /// Path given.
        path: String,
        /// The operating system's reason.
        reason: String,
    },
}

pub(crate) fn out_of_range(
    key: impl Into<String>,
    value: impl fmt::Display,
    allowed: impl Into<String>,
) -> ScenarioError {
    ScenarioError::OutOfRange {
        key: key.into(),
        value: shortened(value.to_string()),
        allowed: allowed.into(),
    }
}

/// The TOML parser's (or deserialiser's) message for a [`ScenarioError::Syntax`]: on one
/// line, a number it quotes in scientific notation where its digits would run long, cut in
/// the middle to at most about 2 × [`ECHO_CHARS`] characters.
pub fn toml_message(message: &str) -> String {
    let one_line = message.trim().replace('\n', " ");
    clip_middle(&shorten_quoted_numbers(&one_line), 2 * ECHO_CHARS).into_owned()
}

/// `message` with each number quoted in backticks (as the TOML parser quotes a value of the
/// wrong type) passed through [`shortened`].
fn shorten_quoted_numbers(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    for (i, part) in message.split('`').enumerate() {
        if i > 0 {
            out.push('`');
        }
        // Odd parts lie between backticks.
        if i % 2 == 1 {
            out.push_str(&shortened(part.to_string()));
        } else {
            out.push_str(part);
        }
    }
    out
}

/// A value's text for a message: a plain decimal longer than 24 characters (a number's
/// `Display`, which never uses an exponent: 1e300 has 301 digits) in scientific notation.
fn shortened(text: String) -> String {
    let plain = text
        .bytes()
        .all(|b| b.is_ascii_digit() || b == b'-' || b == b'.');
    match text.parse::<f64>() {
        Ok(x) if plain && text.len() > 24 => short_number(x),
        _ => text,
    }
}

/// `text` cut to at most `max_chars` characters, with an ellipsis where it was cut: values
/// and source lines echoed in error messages stay readable.
pub fn clip(text: &str, max_chars: usize) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(max_chars) {
        None => text.into(),
        Some((at, _)) => format!("{}…", &text[..at]).into(),
    }
}

/// `text` cut in the middle to at most about `max_chars` characters: the start and the last
/// 60 characters stay, so a message that echoes a long value still ends with what was
/// expected.
pub fn clip_middle(text: &str, max_chars: usize) -> std::borrow::Cow<'_, str> {
    const TAIL: usize = 60;
    let n = text.chars().count();
    if n <= max_chars {
        return text.into();
    }
    let head: String = text.chars().take(max_chars.saturating_sub(TAIL)).collect();
    let tail: String = text.chars().skip(n - TAIL.min(max_chars)).collect();
    format!("{head}…{tail}").into()
}

pub(crate) use ringsync_proto::plan::short_number;

/// `x` with `d` decimals, or in scientific notation with `d` where that would be long or
/// show nothing.
pub(crate) fn fixed(x: f64, d: usize) -> String {
    if x == 0.0 || !x.is_finite() || (1e-3..1e9).contains(&x.abs()) {
        format!("{x:.d$}")
    } else {
        format!("{x:.d$e}")
    }
}

/// Longest echo of a source line or value in a [`ScenarioError`] \[characters\].
pub const ECHO_CHARS: usize = 120;

/// Maps a control-layer error to the scenario key it came from.
pub(crate) fn control_error(e: &ControlError) -> ScenarioError {
    match e {
        ControlError::InvalidParameter {
            name,
            value,
            expected,
        } => {
            // Gains are reported as kp[2] (an index from 0): in the scenario that is
            // control.kp (axis 3), axes numbered from 1 as everywhere else; a drive's limit
            // u_max[2] comes from the axis's table (axis[2], the table's index). The
            // trajectory's names are the library's: its keys are the scenario's.
            let key = match name.split_once('[') {
                Some(("u_max", rest)) => format!("axis[{}].u_max", rest.trim_end_matches(']')),
                Some((g, rest)) => {
                    let i = rest.trim_end_matches(']');
                    match i.parse::<usize>() {
                        Ok(i) => format!("control.{g} (axis {})", i + 1),
                        Err(_) => format!("control.{g} (axis {i})"),
                    }
                }
                None if *name == "v_peak" => "control.peak_speed".to_string(),
                None => format!("control.{name}"),
            };
            out_of_range(key, short_number(*value), expected.to_string())
        }
        other => out_of_range("control", "?", other.to_string()),
    }
}

pub(crate) fn plant_error(axis: usize, e: &PlantError) -> ScenarioError {
    match e {
        PlantError::InvalidParameter {
            name,
            value,
            expected,
        } => {
            if *name == "axis" {
                return out_of_range("axis", "[]", *expected);
            }
            let key = match *name {
                "inertia" | "torque_constant" => "j_over_ka, rated_torque or u_max",
                "viscous_friction" => "viscous",
                "coulomb_friction" => "coulomb_fraction",
                "velocity_gain" => "velocity_gain",
                other => other,
            };
            out_of_range(format!("axis[{axis}].{key}"), value, *expected)
        }
        other => out_of_range(format!("axis[{axis}]"), "?", other.to_string()),
    }
}

impl ScenarioError {
    pub(crate) fn prefixed(self, section: &str) -> ScenarioError {
        match self {
            ScenarioError::OutOfRange {
                key,
                value,
                allowed,
            } => ScenarioError::OutOfRange {
                key: key.replacen("control.", &format!("{section}."), 1),
                value,
                allowed,
            },
            other => other,
        }
    }
}
