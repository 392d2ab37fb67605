//! The law registry: every control law by the name scenarios and outputs use, with a
//! one-line description, the parameters it takes besides the common `[control]` keys, and
//! how to build it.
//!
//! **Adding a law** is one file and one line. The file, `crates/control/src/law/<module>.rs`,
//! holds the law (a type implementing [`ControlLaw`]) and one `pub const ENTRY:` [`LawEntry`]
//! that names it, declares its own parameters ([`ParamSpec`]: key, unit, default, allowed
//! range) and builds it from a [`LawParams`]. The line is the module's name in the
//! `laws!` list in `law/mod.rs`, which declares the module and puts its entry in `LAWS`.
//! Nothing else changes: scenarios find the law by its name (`control.law`), its parameters
//! are checked generically (`[control.params]`, one value for every axis or a list of n), and
//! `ringsync check` runs the discrete-time stability check on its own `compute`.

use super::{ControlLaw, Gains, SyncParams};
use crate::error::ControlError;

/// One parameter a law declares for itself: a value per axis, set in a scenario's
/// `[control.params]` table under [`ParamSpec::key`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Key in `[control.params]`, e.g. `kx`.
    pub key: &'static str,
    /// One line: what it is, with its symbol.
    pub doc: &'static str,
    /// Unit, e.g. `V/rad` (`1` for a pure number).
    pub unit: &'static str,
    /// The value when a scenario does not set it.
    pub default: f64,
    /// Smallest allowed value (inclusive).
    pub min: f64,
    /// Largest allowed value (inclusive); `f64::INFINITY` for no upper bound.
    pub max: f64,
}

impl ParamSpec {
    /// Whether `value` is finite and within [min, max].
    pub fn allows(&self, value: f64) -> bool {
        value.is_finite() && value >= self.min && value <= self.max
    }

    /// The allowed range in words, with the unit, e.g. `0 ..= 100 V/rad` or `>= 0 V/rad`.
    pub fn allowed(&self) -> String {
        if self.max == f64::INFINITY {
            format!(">= {} {}", self.min, self.unit)
        } else {
            format!("{} ..= {} {}", self.min, self.max, self.unit)
        }
    }
}

/// What a law is built from: what every law may use from a scenario's `[control]` table, and
/// the law's own parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct LawParams {
    /// Per-axis gains and drive limits (K_P, K_D, K_E, K_H, K_C, u_max).
    pub gains: Gains,
    /// Whether standard PD adds the feed-forward K_H·ẍ^d + K_C·ẋ^d (the coupled laws always
    /// add it; with K_H = K_C = 0 it is zero).
    pub feed_forward: bool,
    /// The coupling's parameters: α, Δ_H, Δ_C, the sign model, the estimator, whether the
    /// own sample is extrapolated.
    pub sync: SyncParams,
    /// The law's own parameters, one value per axis each: (key, values).
    pub own: Vec<(&'static str, Vec<f64>)>,
}

impl LawParams {
    /// Common parameters and no own ones yet ([`LawEntry::build`] fills in the defaults).
    pub fn new(gains: Gains, feed_forward: bool, sync: SyncParams) -> Self {
        LawParams {
            gains,
            feed_forward,
            sync,
            own: Vec::new(),
        }
    }

    /// Sets the law's own parameter `key` to `values` (one per axis), replacing it if set.
    pub fn set(&mut self, key: &'static str, values: Vec<f64>) {
        match self.own.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => *v = values,
            None => self.own.push((key, values)),
        }
    }

    /// The values of the law's own parameter `key`, one per axis.
    pub fn get(&self, key: &str) -> Option<&[f64]> {
        self.own
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, v)| v.as_slice())
    }

    /// The values of `key`, which law `law` declares, from parameters [`LawEntry::build`]
    /// has checked and completed (for the law's `make`); an error if it is missing.
    pub fn values(&self, law: &'static str, key: &str) -> Result<&[f64], ControlError> {
        self.get(key).ok_or_else(|| ControlError::UnknownParameter {
            law,
            key: key.to_string(),
            known: self
                .own
                .iter()
                .map(|(k, _)| *k)
                .collect::<Vec<_>>()
                .join(", "),
        })
    }
}

/// One law of the registry.
#[derive(Debug, Clone, Copy)]
pub struct LawEntry {
    /// The name in scenarios (`control.law`) and in `reproduce`, e.g. `sync`. The name in a
    /// run's outputs is the built law's [`ControlLaw::name`] (`pd+ff` for PD with
    /// feed-forward).
    pub name: &'static str,
    /// One line: what the law is and where it comes from.
    pub description: &'static str,
    /// Fewest axes it runs on (2 for a coupling).
    pub min_axes: usize,
    /// Its own parameters, in `[control.params]`.
    pub params: &'static [ParamSpec],
    /// Makes the law from checked parameters (every declared key present, n values each,
    /// in range): call [`LawEntry::build`], which checks them first.
    pub make: fn(&LawParams) -> Result<Box<dyn ControlLaw>, ControlError>,
}

impl LawEntry {
    /// The declared parameter `key`.
    pub fn param(&self, key: &str) -> Option<&'static ParamSpec> {
        self.params.iter().find(|p| p.key == key)
    }

    /// Checks the own parameters of `p` and builds the law: a key the law does not declare
    /// is an error, a declared key not set takes its default on every axis, each must have
    /// one value per axis (n = the number of gains) within its range. Errors name the key as
    /// `params.<key>[axis]`.
    pub fn build(&self, p: &LawParams) -> Result<Box<dyn ControlLaw>, ControlError> {
        let n = p.gains.axes();
        if let Some((key, _)) = p.own.iter().find(|(k, _)| self.param(k).is_none()) {
            return Err(ControlError::UnknownParameter {
                law: self.name,
                key: (*key).to_string(),
                known: self.param_list(),
            });
        }
        let mut full = LawParams {
            own: Vec::with_capacity(self.params.len()),
            ..p.clone()
        };
        for spec in self.params {
            let values = match p.get(spec.key) {
                Some(v) if v.len() != n => {
                    return Err(ControlError::LengthMismatch {
                        what: spec.key,
                        expected: n,
                        got: v.len(),
                    });
                }
                Some(v) => v.to_vec(),
                None => vec![spec.default; n],
            };
            if let Some((i, &v)) = values.iter().enumerate().find(|(_, v)| !spec.allows(**v)) {
                return Err(ControlError::InvalidParameter {
                    name: format!("params.{}[{i}]", spec.key),
                    value: v,
                    expected: spec.allowed().into(),
                });
            }
            full.own.push((spec.key, values));
        }
        (self.make)(&full)
    }

    /// The declared keys, comma-separated, or `none`.
    pub fn param_list(&self) -> String {
        if self.params.is_empty() {
            "none".to_string()
        } else {
            let keys: Vec<&str> = self.params.iter().map(|p| p.key).collect();
            keys.join(", ")
        }
    }
}

/// The law named `name`.
pub fn find(name: &str) -> Option<&'static LawEntry> {
    super::LAWS.iter().copied().find(|e| e.name == name)
}

/// The names of every law, in registry order.
pub fn names() -> impl Iterator<Item = &'static str> {
    super::LAWS.iter().map(|e| e.name)
}

/// The laws that declare a parameter `key`, comma-separated (empty when none does).
pub fn laws_with_param(key: &str) -> String {
    super::LAWS
        .iter()
        .filter(|e| e.param(key).is_some())
        .map(|e| format!("\"{}\"", e.name))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The error text for a name that is not a law: `unknown control law 'pid': expected one of
/// pd, sync, …`.
pub fn unknown_law(name: &str) -> String {
    format!(
        "unknown control law '{name}': expected one of {}",
        names().collect::<Vec<_>>().join(", ")
    )
}

/// Declares the laws' modules and [`LAWS`], the list of their entries: one line per law.
macro_rules! laws {
    ($($module:ident),+ $(,)?) => {
        $(pub mod $module;)+
        /// Every law of the registry, in the order they are listed (docs/control.md).
        pub static LAWS: &[&registry::LawEntry] = &[$(&$module::ENTRY),+];
    };
}
pub(crate) use laws;

/// Every law with its description and its own parameters (key, unit, default, allowed
/// range, meaning), as text for `ringsync scenario laws`.
pub fn catalogue() -> String {
    let mut text = String::new();
    for e in super::LAWS {
        text.push_str(&format!("{:<14} {}\n", e.name, e.description));
        text.push_str(&format!(
            "{:<14} runs on {} or more axes; [control.params]:{}\n",
            "",
            e.min_axes,
            if e.params.is_empty() { " none" } else { "" }
        ));
        for p in e.params {
            text.push_str(&format!(
                "{:<16} {} = {} {} (allowed {}): {}\n",
                "",
                p.key,
                p.default,
                p.unit,
                p.allowed(),
                p.doc
            ));
        }
    }
    text
}
