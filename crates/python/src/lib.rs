//! # ringsync-python
//!
//! The extension module `ringsync._ringsync`: a thin PyO3 binding over the `ringsync`
//! library crate, the same front door the `ringsync` command uses. The public Python API
//! (`ringsync.load`, `simulate`, `check`, `sweep`, the `Scenario`, `Run`, `Check` and
//! `Sweep` classes) is the pure-Python package in `python/ringsync/`, which calls the
//! functions here; `python/ringsync/_ringsync.pyi` types them. docs/python.md is the
//! walk-through.
//!
//! The functions here take and return plain data (a scenario travels as its TOML text and
//! origin), so that the Python side can pickle, cache and later hand work to other processes
//! (Dask) without reaching into Rust objects. The one Rust object is `SimRun`, a finished
//! simulation, which keeps the run for its arrays and for writing the CLI's files.
//!
//! Every call that does work releases the GIL (`Python::detach`) and catches a Rust panic,
//! which becomes `ringsync.RunError` instead of ending the interpreter (`guard`).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use ringsync::Stop;

mod convert;
mod run;
mod scenario;
mod sweep;

// The docstrings' examples are added by python/ringsync/__init__.py (an indented example
// here would be a Rust doctest).
create_exception!(
    ringsync,
    ScenarioError,
    PyValueError,
    "A scenario, a scenario key or a value is invalid, a scenario name or file is unknown, or an argument (a seed, a count, a directory) is out of its range.\n\nA ValueError. The message is one line: for a scenario, the one the `ringsync` command prints for the same input (after `ringsync: error: `); it names the key or the argument, the value and what is allowed."
);
create_exception!(
    ringsync,
    RunError,
    PyRuntimeError,
    "The work failed (I/O, an internal error); the input was fine. A RuntimeError. A Rust panic inside ringsync is raised as this error too, naming the panic, and the interpreter goes on."
);

/// Longest line of an error message [characters], as the CLI cuts it.
const ERROR_LINE_CHARS: usize = 400;

/// `text` with every line cut as the CLI cuts its error lines (the middle goes).
pub(crate) fn readable(text: &str) -> String {
    text.lines()
        .map(|l| ringsync::layers::model::scenario::clip_middle(l, ERROR_LINE_CHARS))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A library error as a Python exception: bad input (the CLI's exit status 2) is a
/// `ScenarioError`, a failure a `RunError`; the message is the CLI's.
pub(crate) fn to_py(e: ringsync::Error) -> PyErr {
    let msg = readable(&e.to_string());
    if e.is_usage() {
        ScenarioError::new_err(msg)
    } else {
        RunError::new_err(msg)
    }
}

/// Runs `work` without the GIL, a panic inside it turned into `RunError`.
pub(crate) fn guard<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, ringsync::Error> + Send,
) -> PyResult<T> {
    let done = py.detach(|| catch_unwind(AssertUnwindSafe(work)));
    match done {
        Ok(r) => r.map_err(to_py),
        Err(panic) => Err(panicked(panic.as_ref())),
    }
}

/// Runs `work` without the GIL on a thread of its own, looking for Ctrl-C
/// (KeyboardInterrupt, a Jupyter kernel's interrupt) every 50 ms: on it, the [`Stop`] flag
/// `work` was given rises, the work ends early (a run at its next cycle, a sweep before its
/// next case), and the interrupt is raised once the thread has finished. A panic becomes
/// `RunError`, as in [`guard`].
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    work: impl FnOnce(&Stop) -> Result<T, ringsync::Error> + Send,
) -> PyResult<T> {
    interruptible_ticking(py, work, &mut |_, _| Ok(()))
}

/// [`interruptible`], calling `tick(py, finished)` every 50 ms while the work runs and once
/// when it has finished (for a progress line).
pub(crate) fn interruptible_ticking<T: Send>(
    py: Python<'_>,
    work: impl FnOnce(&Stop) -> Result<T, ringsync::Error> + Send,
    tick: &mut dyn FnMut(Python<'_>, bool) -> PyResult<()>,
) -> PyResult<T> {
    let stop = Stop::new();
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|scope| {
        let flag = stop.clone();
        scope.spawn(move || {
            let _ = tx.send(catch_unwind(AssertUnwindSafe(|| work(&flag))));
        });
        let mut interrupted: Option<PyErr> = None;
        let mut rx = rx;
        loop {
            let (got, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(50)), rx));
            rx = back;
            match got {
                Ok(done) => {
                    // The last tick ends a progress line, interrupted or not.
                    let ticked = tick(py, true);
                    return match (interrupted, done) {
                        (Some(e), _) => Err(e),
                        (None, Ok(r)) => ticked.and_then(|()| r.map_err(to_py)),
                        (None, Err(panic)) => Err(panicked(panic.as_ref())),
                    };
                }
                Err(RecvTimeoutError::Timeout) => {
                    if interrupted.is_none() {
                        if let Err(e) = py.check_signals() {
                            stop.raise();
                            interrupted = Some(e);
                        } else if let Err(e) = tick(py, false) {
                            stop.raise();
                            interrupted = Some(e);
                        }
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(interrupted.unwrap_or_else(|| {
                        RunError::new_err(
                            "internal error in ringsync: the work ended without a result",
                        )
                    }));
                }
            }
        }
    })
}

/// The `RunError` for a caught panic, with its message.
pub(crate) fn panicked(payload: &(dyn std::any::Any + Send)) -> PyErr {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into());
    RunError::new_err(format!(
        "internal error in ringsync (a bug; please report it with the scenario): {what}"
    ))
}

/// Panics in Rust with `message`, inside [`guard`]: for the tests that show a panic
/// becomes `RunError` and the interpreter lives on.
#[pyfunction]
fn _panic(py: Python<'_>, message: String) -> PyResult<()> {
    guard(py, move || -> Result<(), ringsync::Error> {
        panic!("{message}")
    })
}

/// The extension module `ringsync._ringsync` (private: use the package `ringsync`).
#[pymodule]
fn _ringsync(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("ScenarioError", py.get_type::<ScenarioError>())?;
    m.add("RunError", py.get_type::<RunError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(_panic, m)?)?;
    scenario::register(m)?;
    run::register(m)?;
    sweep::register(m)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use pyo3::types::PyDict;

    use super::*;

    /// Runs `f` attached to an embedded interpreter (started once).
    fn attached(f: impl for<'py> FnOnce(Python<'py>)) {
        Python::initialize();
        Python::attach(f)
    }

    #[test]
    fn a_panic_becomes_run_error_and_python_lives_on() {
        attached(|py| {
            let e = guard(py, || -> Result<(), ringsync::Error> { panic!("boom") })
                .expect_err("a panic is an error");
            assert!(e.is_instance_of::<RunError>(py));
            assert!(e.to_string().contains("boom"), "{e}");
            assert_eq!(
                py.eval(c"1 + 1", None, None)
                    .and_then(|v| v.extract::<i64>())
                    .ok(),
                Some(2)
            );
        });
    }

    #[test]
    fn bad_input_is_scenario_error_with_the_cli_message() {
        attached(|py| {
            let lib = ringsync::parse("[ring]\nslaves = 0\n", "t").expect_err("bad");
            let msg = lib.to_string();
            let e = to_py(lib);
            assert!(e.is_instance_of::<ScenarioError>(py));
            assert!(e.is_instance_of::<pyo3::exceptions::PyValueError>(py));
            assert_eq!(e.value(py).to_string(), msg);
        });
    }

    #[test]
    fn a_list_that_holds_itself_is_an_error_naming_its_key() {
        attached(|py| {
            let a = pyo3::types::PyList::empty(py);
            a.append(&a).expect("append");
            let e = convert::to_toml("control.kp", &a).expect_err("too deep");
            assert!(e.is_instance_of::<ScenarioError>(py));
            assert!(
                e.value(py)
                    .to_string()
                    .starts_with("control.kp: the value is nested more than 32 levels deep"),
                "{e}"
            );
        });
    }

    #[test]
    fn whole_numbers_are_checked_against_their_range() {
        attached(|py| {
            let check = |code: &std::ffi::CStr| {
                let v = py.eval(code, None, None).expect("value");
                convert::whole("points", &v, 1, 10, "").map_err(|e| e.value(py).to_string())
            };
            assert_eq!(check(c"7"), Ok(7));
            assert_eq!(
                check(c"0"),
                Err("points = 0 is out of range: allowed a whole number 1 ..= 10".into())
            );
            assert!(check(c"-1").is_err_and(|m| m.contains("out of range")));
            assert!(check(c"2**70").is_err_and(|m| m.contains("out of range")));
            assert!(check(c"True").is_err_and(|m| m.contains("a bool")));
            assert!(check(c"2.0").is_err_and(|m| m.contains("not a whole number")));
        });
    }

    #[test]
    fn dotted_keys_and_nested_dicts_make_one_table() {
        attached(|py| {
            let d = PyDict::new(py);
            d.set_item("control.alpha", 0.25).expect("item");
            let ring = PyDict::new(py);
            ring.set_item("slaves", 2).expect("item");
            d.set_item("ring", ring).expect("item");
            d.set_item("clock.sync", false).expect("item");
            let t = convert::dict_to_table("", &d).expect("table");
            assert_eq!(t["control"]["alpha"].as_float(), Some(0.25));
            assert_eq!(t["ring"]["slaves"].as_integer(), Some(2));
            assert_eq!(t["clock"]["sync"].as_bool(), Some(false));
            // A key given as a value and as a table is an error naming it.
            d.set_item("ring.slaves.x", 1).expect("item");
            let e = convert::dict_to_table("", &d).expect_err("clash");
            assert!(e.is_instance_of::<ScenarioError>(py));
            assert!(e.to_string().contains("ring.slaves.x"), "{e}");
        });
    }
}
