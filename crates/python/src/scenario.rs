//! Scenarios: load (a built-in name, a path, TOML text, a dict), change keys the way the
//! CLI's `sweep --set` does, and read the values in effect.
//!
//! A scenario crosses into Python as its TOML text and its origin (what it was loaded from,
//! named in errors); every function validates it again here, which takes microseconds.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use ringsync::sweep::SweepAxis;
use ringsync::{Loaded, ScenarioError as LibScenarioError};

use crate::convert::{dict_to_table, literal, table_to_py, to_toml};
use crate::{ScenarioError, to_py};

/// The reference scenario whose values fill what a scenario's text leaves out (a test in
/// the model keeps `scenarios/paper-2015.toml` equal to `Scenario::default`).
const DEFAULTS: &str = "paper-2015";

/// The names of the built-in scenarios.
#[pyfunction]
fn scenarios() -> Vec<String> {
    ringsync::builtin_names().map(str::to_string).collect()
}

/// Loads a built-in scenario by name or a scenario file by path: (text, origin).
#[pyfunction]
fn load(py: Python<'_>, source: String) -> PyResult<(String, String)> {
    let l = crate::guard(py, move || ringsync::load(&source))?;
    Ok((l.text, l.origin))
}

/// Validates scenario text; returns what Python shows of it without parsing TOML itself.
#[pyfunction]
fn parse<'py>(py: Python<'py>, text: String, origin: String) -> PyResult<Bound<'py, PyDict>> {
    let l = crate::guard(py, move || ringsync::parse(&text, &origin))?;
    info(py, &l)
}

/// A few facts of a loaded scenario, as a dict.
fn info<'py>(py: Python<'py>, l: &Loaded) -> PyResult<Bound<'py, PyDict>> {
    let s = &l.scenario;
    let d = PyDict::new(py);
    d.set_item("name", &s.name)?;
    d.set_item("description", &s.description)?;
    d.set_item("axes", s.axes_count())?;
    d.set_item("seed", s.seed)?;
    d.set_item("duration_s", s.duration.secs())?;
    d.set_item("cycle_s", s.ring.cycle.secs())?;
    d.set_item("law", s.law_name())?;
    d.set_item("hash", format!("{:016x}", l.hash))?;
    Ok(d)
}

/// A dict of scenario keys (dotted keys or nested dicts) as TOML text.
#[pyfunction]
fn from_dict(d: &Bound<'_, PyDict>) -> PyResult<String> {
    let t = dict_to_table("", d)?;
    toml::to_string(&t)
        .map_err(|e| ScenarioError::new_err(format!("cannot write the dict as TOML: {e}")))
}

/// The scenario `text` (from `origin`) with `items` [(dotted key, value)] set, validated,
/// exactly as `ringsync sweep --set KEY=VALUE` makes a case (same errors): (text, origin).
#[pyfunction]
fn with_values(
    py: Python<'_>,
    text: String,
    origin: String,
    items: Vec<(String, Bound<'_, PyAny>)>,
) -> PyResult<(String, String)> {
    let mut pairs = Vec::with_capacity(items.len());
    for (key, value) in &items {
        // The key checked as the CLI checks it, before anything runs.
        axis(key, Vec::new())?;
        pairs.push((key.clone(), literal(&to_toml(key, value)?)));
    }
    if pairs.is_empty() {
        return Ok((text, origin));
    }
    crate::guard(py, move || {
        let set = ringsync::with_values(&ringsync::parse(&text, &origin)?, &pairs)?;
        Ok((set.text, set.origin))
    })
}

/// A sweep axis for `key`, the key checked as the CLI checks `--set KEY=…`.
pub(crate) fn axis(key: &str, values: Vec<String>) -> PyResult<SweepAxis> {
    let mut a: SweepAxis = format!("{key}=0").parse().map_err(to_py)?;
    a.values = values;
    Ok(a)
}

/// Every key of the scenario `text` with its value in effect: the text's own, and the
/// reference scenario's for what the text leaves out. Nested dicts; `axis` a list of dicts.
#[pyfunction]
fn values<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyDict>> {
    let t = effective(text).map_err(|e| to_py(e.into()))?;
    table_to_py(py, &t)
}

/// TOML text as a table (syntax errors as the library words them, without line numbers:
/// the text was validated before).
fn parse_table(text: &str, origin: &str) -> Result<toml::Table, LibScenarioError> {
    toml::from_str(text).map_err(|e| LibScenarioError::Syntax {
        origin: origin.to_string(),
        message: ringsync::layers::model::scenario::toml_message(e.message()),
    })
}

/// The values in effect for the scenario `text`: the reference scenario's tables with the
/// text's keys laid over them. Rules as the scenario's schema has them: a table merges key by
/// key, except that a table with another `kind` (`[trajectory]`, `[plant]`) replaces the
/// default whole; each `[[axis]]` table is laid over the first default axis table (the
/// defaults of an axis); `[control.params]` and the keys of a two-link-arm `[plant]` are
/// listed as written (their defaults belong to the law or the arm).
pub(crate) fn effective(text: &str) -> Result<toml::Table, LibScenarioError> {
    let defaults = ringsync::builtin(DEFAULTS).unwrap_or_default();
    let mut base = parse_table(defaults, DEFAULTS)?;
    let user = parse_table(text, "scenario")?;
    let axis_default = base
        .get("axis")
        .and_then(|a| a.as_array())
        .and_then(|a| a.first())
        .and_then(|t| t.as_table())
        .cloned()
        .unwrap_or_default();
    let expand = |axes: &toml::Value| -> toml::Value {
        match axes {
            toml::Value::Array(items) => toml::Value::Array(
                items
                    .iter()
                    .map(|item| match item {
                        toml::Value::Table(t) => {
                            let mut full = axis_default.clone();
                            merge(&mut full, t.clone());
                            toml::Value::Table(full)
                        }
                        other => other.clone(),
                    })
                    .collect(),
            ),
            other => other.clone(),
        }
    };
    if let Some(a) = base.get("axis").map(&expand) {
        base.insert("axis".into(), a);
    }
    for (k, v) in user {
        let v = if k == "axis" { expand(&v) } else { v };
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(old)), toml::Value::Table(new)) if same_kind(old, &new) => {
                merge(old, new)
            }
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
    Ok(base)
}

/// Whether two tables are of the same `kind` (or neither has one).
fn same_kind(a: &toml::Table, b: &toml::Table) -> bool {
    match (a.get("kind"), b.get("kind")) {
        (Some(x), Some(y)) => x == y,
        _ => true,
    }
}

/// Lays `new` over `base`, table by table.
fn merge(base: &mut toml::Table, new: toml::Table) {
    for (k, v) in new {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(old)), toml::Value::Table(new)) if same_kind(old, &new) => {
                merge(old, new)
            }
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The commented TOML text of a built-in scenario, or None.
#[pyfunction]
fn builtin_text(name: &str) -> Option<&'static str> {
    ringsync::builtin(name)
}

/// The control laws of the registry with their parameters, as `ringsync scenario laws`
/// prints them.
#[pyfunction]
fn laws() -> String {
    ringsync::layers::control::law::registry::catalogue()
}

/// The control laws of the registry as data, in registry order (what [`laws`] prints): one
/// dict per law with `name`, `description`, `min_axes` and `params`, a list of dicts with
/// `key`, `doc`, `unit`, `default`, `min` and `max` (`inf` for no upper bound) of the law's
/// own parameters (`[control.params]`).
#[pyfunction]
fn law_registry(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for e in ringsync::layers::control::law::LAWS {
        let params = PyList::empty(py);
        for p in e.params {
            let d = PyDict::new(py);
            d.set_item("key", p.key)?;
            d.set_item("doc", p.doc)?;
            d.set_item("unit", p.unit)?;
            d.set_item("default", p.default)?;
            d.set_item("min", p.min)?;
            d.set_item("max", p.max)?;
            params.append(d)?;
        }
        let d = PyDict::new(py);
        d.set_item("name", e.name)?;
        d.set_item("description", e.description)?;
        d.set_item("min_axes", e.min_axes)?;
        d.set_item("params", params)?;
        out.append(d)?;
    }
    Ok(out)
}

/// Registers the scenario functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(scenarios, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(parse, m)?)?;
    m.add_function(wrap_pyfunction!(from_dict, m)?)?;
    m.add_function(wrap_pyfunction!(with_values, m)?)?;
    m.add_function(wrap_pyfunction!(values, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_text, m)?)?;
    m.add_function(wrap_pyfunction!(laws, m)?)?;
    m.add_function(wrap_pyfunction!(law_registry, m)?)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize as _;

    /// The values in effect describe the same scenario as the text they came from.
    #[test]
    fn the_values_in_effect_are_the_scenario() {
        let texts = [
            ringsync::builtin("paper-2015")
                .unwrap_or_default()
                .to_string(),
            ringsync::builtin("arm-2link")
                .unwrap_or_default()
                .to_string(),
            "duration = \"1s\"\n[control]\nalpha = 0.25\n[[axis]]\nu_max = 5.0\n".to_string(),
            "[trajectory]\nkind = \"trapezoid\"\ndistance = 2.0\nv_max = 4.0\na_max = 40.0\n"
                .to_string(),
        ];
        for text in texts {
            let s = ringsync::parse(&text, "t").expect("valid").scenario;
            let t = effective(&text).expect("table");
            let again = ringsync::Scenario::deserialize(toml::Value::Table(t.clone()))
                .expect("the values in effect deserialize");
            assert_eq!(again, s, "{text}");
            // Every default key is there.
            assert!(t["control"].get("alpha").is_some());
            assert!(t["axis"][0].get("encoder_bits").is_some());
        }
    }
}
