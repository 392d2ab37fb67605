//! Python values to TOML values and back: scenarios travel as TOML, so a dict, an override
//! or a sweep's grid becomes TOML here, and a scenario's tables come back as dicts.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use crate::ScenarioError;

/// What a scenario value may be, for error messages.
const ALLOWED: &str = "a number, a string (durations with a unit, e.g. \"1ms\"), a bool, a list of these, or a table (dict)";

/// The deepest nesting of lists and tables (dicts) inside one scenario value: a scenario is a
/// few levels deep (`axis` is a list of tables), so anything deeper is a mistake, such as a
/// list that contains itself. The limit keeps the conversion's recursion bounded.
pub(crate) const MAX_DEPTH: usize = 32;

/// A Python value as a TOML value; `key` names it in errors. Numpy scalars and arrays are
/// taken by value (`int`, `float`, `bool`, `.tolist()`). A value nested more than
/// [`MAX_DEPTH`] levels deep (or containing itself) is a `ScenarioError` naming `key`.
pub(crate) fn to_toml(key: &str, v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    value(key, key, v, 0)
}

/// The error for a value of `root` nested deeper than [`MAX_DEPTH`].
fn too_deep(root: &str) -> PyErr {
    ScenarioError::new_err(crate::readable(&format!(
        "{root}: the value is nested more than {MAX_DEPTH} levels deep (lists or tables inside each other, or a list or dict that contains itself): allowed {ALLOWED}, a few levels deep"
    )))
}

/// [`to_toml`] at `depth` levels inside the value of `root` (the key the caller gave);
/// `key` is where in it `v` is (`control.kp[2]`).
fn value(root: &str, key: &str, v: &Bound<'_, PyAny>, depth: usize) -> PyResult<toml::Value> {
    if depth > MAX_DEPTH {
        return Err(too_deep(root));
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v.extract::<i64>().map(toml::Value::Integer).map_err(|_| {
            ScenarioError::new_err(format!(
                "{key} = {} is out of range: allowed an integer within ±2^63",
                repr(v)
            ))
        });
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return table(key, Some(root), d, depth + 1).map(toml::Value::Table);
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items: PyResult<Vec<toml::Value>> = v
            .try_iter()?
            .enumerate()
            .map(|(i, item)| value(root, &format!("{key}[{i}]"), &item?, depth + 1))
            .collect();
        return items.map(toml::Value::Array);
    }
    // Numpy: bool_, integer and floating scalars, and arrays (by their nested lists; an
    // object array may hold itself, so this counts as a level too).
    let np_type = v
        .get_type()
        .module()
        .map(|m| m.to_string())
        .unwrap_or_default();
    if np_type == "numpy" && v.hasattr("tolist")? {
        return value(root, key, &v.call_method0("tolist")?, depth + 1);
    }
    Err(ScenarioError::new_err(format!(
        "{key} = {} is not a scenario value: allowed {ALLOWED}",
        repr(v)
    )))
}

/// `repr(v)`, or a placeholder when even that fails.
pub(crate) fn repr(v: &Bound<'_, PyAny>) -> String {
    v.repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "<value>".into())
}

/// A dict of scenario keys as a TOML table: dotted keys (`"control.alpha"`) and nested dicts
/// (`{"control": {"alpha": 0.3}}`) alike; `within` is the key of the dict itself ("" at
/// the top).
pub(crate) fn dict_to_table(within: &str, d: &Bound<'_, PyDict>) -> PyResult<toml::Table> {
    table(within, None, d, 0)
}

/// [`dict_to_table`] at `depth` levels inside the value of `root` (None at the top: each
/// key is then its own root).
fn table(
    within: &str,
    root: Option<&str>,
    d: &Bound<'_, PyDict>,
    depth: usize,
) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let k: String = k.extract().map_err(|_| {
            ScenarioError::new_err(format!(
                "{} is not a scenario key: keys are strings like \"control.alpha\"",
                repr(&k)
            ))
        })?;
        let full = if within.is_empty() {
            k.clone()
        } else {
            format!("{within}.{k}")
        };
        let value = value(root.unwrap_or(&full), &full, &v, depth)?;
        insert(&mut t, &k, value, &full)?;
    }
    Ok(t)
}

/// The whole number `v` given for the argument `name` of a public function, checked to be
/// within `lo ..= hi`; `what` follows the range in the message (e.g. " (2^63 - 1, what a
/// scenario's seed holds)"). Any integral value is taken (`int`, numpy integers: anything
/// with `__index__`), a bool is not; anything else, or a number out of range, is a
/// `ScenarioError` naming `name` and the range (never an `OverflowError`).
pub(crate) fn whole(
    name: &str,
    v: &Bound<'_, PyAny>,
    lo: u64,
    hi: u64,
    what: &str,
) -> PyResult<u64> {
    let shown = || crate::readable(&repr(v));
    let allowed = format!("allowed a whole number {lo} ..= {hi}{what}");
    let type_name = v
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default();
    if v.is_instance_of::<PyBool>() || type_name == "bool_" || type_name == "bool" {
        return Err(ScenarioError::new_err(format!(
            "{name} = {} is a bool, not a number: {allowed}",
            shown()
        )));
    }
    let index = v
        .py()
        .import("operator")
        .and_then(|m| m.getattr("index"))
        .and_then(|index| index.call1((v,)));
    let Ok(index) = index else {
        return Err(ScenarioError::new_err(format!(
            "{name} = {} is not a whole number: {allowed}",
            shown()
        )));
    };
    match index.extract::<i128>().ok().map(u64::try_from) {
        Some(Ok(n)) if (lo..=hi).contains(&n) => Ok(n),
        _ => Err(ScenarioError::new_err(format!(
            "{name} = {} is out of range: {allowed}",
            shown()
        ))),
    }
}

/// Inserts `value` at the dotted `key` of `t`, creating tables on the way and merging a
/// table into one already there. `full` names the key in errors.
pub(crate) fn insert(
    t: &mut toml::Table,
    key: &str,
    value: toml::Value,
    full: &str,
) -> PyResult<()> {
    let (head, rest) = match key.split_once('.') {
        Some((h, r)) => (h, Some(r)),
        None => (key, None),
    };
    if head.is_empty() {
        return Err(ScenarioError::new_err(format!(
            "'{full}' is not a scenario key like ring.slaves"
        )));
    }
    // `axis[1].u_max` changes one table of a scenario that has them; a dict is a whole
    // scenario file, where the list is given whole.
    if let Some((name, _)) = head.split_once('[') {
        return Err(ScenarioError::new_err(format!(
            "{full}: an indexed key changes one table of a loaded scenario (ringsync.load(\"paper-2015\").set(\"{full}\", value)); in a dict give the list whole: {{\"{name}\": [{{…}}, {{…}}]}}"
        )));
    }
    let not_a_table = || {
        ScenarioError::new_err(format!(
            "{full}: {head} is given both as a value and as a table"
        ))
    };
    match rest {
        Some(rest) => {
            let entry = t
                .entry(head.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            let inner = entry.as_table_mut().ok_or_else(not_a_table)?;
            insert(inner, rest, value, full)
        }
        None => match (t.get_mut(head), value) {
            (Some(toml::Value::Table(old)), toml::Value::Table(new)) => {
                for (k, v) in new {
                    insert(old, &k, v, full)?;
                }
                Ok(())
            }
            (Some(_), _) => Err(not_a_table()),
            (None, value) => {
                t.insert(head.to_string(), value);
                Ok(())
            }
        },
    }
}

/// A TOML value as a Python object: tables become dicts, arrays lists, datetimes strings.
pub(crate) fn to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let items: PyResult<Vec<Bound<'py, PyAny>>> = a.iter().map(|x| to_py(py, x)).collect();
            PyList::new(py, items?)?.into_any()
        }
        toml::Value::Table(t) => table_to_py(py, t)?.into_any(),
    })
}

/// A TOML table as a dict (in the table's key order).
pub(crate) fn table_to_py<'py>(py: Python<'py>, t: &toml::Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in t {
        d.set_item(k, to_py(py, v)?)?;
    }
    Ok(d)
}

/// A JSON value as a Python object (numbers stay exact: integers as int, others as float).
pub(crate) fn json_to_py<'py>(
    py: Python<'py>,
    v: &serde_json::Value,
) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(a) => {
            let items: PyResult<Vec<Bound<'py, PyAny>>> =
                a.iter().map(|x| json_to_py(py, x)).collect();
            PyList::new(py, items?)?.into_any()
        }
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// How a value is written after `KEY=` in the CLI's `sweep --set KEY=V`: a string bare when
/// the CLI would read it back as that same string (`hold`, `1ms`), quoted otherwise
/// (`"true"`); anything else as TOML writes it (`0.3`, `[1.0, 2.0]`).
pub(crate) fn literal(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) if reads_back_as_string(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Whether `s` written bare after `KEY=` reads back as the string `s` (the CLI takes a value
/// that is not TOML as a string).
fn reads_back_as_string(s: &str) -> bool {
    !s.is_empty()
        && s.trim() == s
        && !s.contains(',')
        && toml::from_str::<toml::Table>(&format!("x = {s}")).is_err()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals_read_back_as_the_cli_reads_them() {
        assert_eq!(literal(&toml::Value::Float(0.3)), "0.3");
        assert_eq!(literal(&toml::Value::Integer(2)), "2");
        assert_eq!(literal(&toml::Value::String("hold".into())), "hold");
        assert_eq!(literal(&toml::Value::String("1ms".into())), "1ms");
        assert_eq!(literal(&toml::Value::String("true".into())), "\"true\"");
        assert_eq!(literal(&toml::Value::String("3".into())), "\"3\"");
        assert_eq!(
            literal(&toml::Value::Array(vec![
                toml::Value::Float(1.0),
                toml::Value::Float(2.5)
            ])),
            "[1.0, 2.5]"
        );
    }
}
