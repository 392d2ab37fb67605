//! Sweeps: the library's cases (the product of the grid's values, several seeds each) run
//! on threads inside Rust with the GIL released, as `ringsync sweep` runs them.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use ringsync::sweep::{Case, Labels, Sweep, SweepAxis, cases, default_jobs, run_cases};

use crate::convert::{literal, to_toml};
use crate::guard;
use crate::scenario::axis;

/// For each label of a case, the index of its value in its axis (the first equal one).
fn indices(labels: &Labels, axes: &[SweepAxis]) -> Vec<usize> {
    labels
        .iter()
        .zip(axes)
        .map(|((_, v), a)| a.values.iter().position(|x| x == v).unwrap_or(0))
        .collect()
}

/// Sweeps the scenario `text` over `grid` [(dotted key, values)], `seeds` seeds each, on
/// `jobs` threads (default: the CPUs): a dict with `rows` (one per run, in the order of
/// the product, seeds innermost) and `means` (one per combination), each naming its values
/// by their index in the grid.
#[pyfunction]
#[pyo3(signature = (text, origin, grid, seeds=1, jobs=None))]
fn sweep<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    grid: Vec<(String, Vec<Bound<'py, PyAny>>)>,
    seeds: u32,
    jobs: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut axes = Vec::with_capacity(grid.len());
    for (key, values) in &grid {
        let lits = values
            .iter()
            .map(|v| to_toml(key, v).map(|t| literal(&t)))
            .collect::<PyResult<Vec<String>>>()?;
        axes.push(axis(key, lits)?);
    }
    let jobs = jobs.unwrap_or_else(default_jobs).max(1);
    let axes_run = axes.clone();
    let sw: Sweep = guard(py, move || {
        let base = ringsync::parse(&text, &origin)?;
        let cs: Vec<Case> = cases(&base, &axes_run, seeds, false)?;
        let results = run_cases(&cs, jobs, &|_, _| {});
        Sweep::new(&base, &axes_run, seeds, cs, results)
    })?;
    let rows = PyList::empty(py);
    for (c, r) in sw.cases.iter().zip(&sw.results) {
        let d = PyDict::new(py);
        d.set_item("values", indices(&c.labels, &axes))?;
        d.set_item("seed", c.seed)?;
        d.set_item("track_rmse", r.track_rmse)?;
        d.set_item("sync_rmse", r.sync_rmse)?;
        d.set_item("lumped_lost", r.lumped_lost)?;
        d.set_item("retries", r.retries)?;
        d.set_item("commands_lost", r.commands_lost)?;
        d.set_item("clock_error_max_ns", r.clock_error_max_ns)?;
        d.set_item("group_stop_s", r.group_stop_s)?;
        d.set_item("group_stop_reason", r.group_stop_reason.clone())?;
        rows.append(d)?;
    }
    let means = PyList::empty(py);
    for m in &sw.means {
        let d = PyDict::new(py);
        d.set_item("values", indices(&m.labels, &axes))?;
        d.set_item("runs", m.runs)?;
        d.set_item("track_rmse", m.track_rmse)?;
        d.set_item("sync_rmse", m.sync_rmse)?;
        d.set_item("sync_rmse_std", m.sync_rmse_std)?;
        means.append(d)?;
    }
    let out = PyDict::new(py);
    out.set_item("rows", rows)?;
    out.set_item("means", means)?;
    out.set_item("jobs", jobs)?;
    Ok(out)
}

/// Registers the sweep function.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    Ok(())
}
