//! Sweeps: the library's cases (the product of the grid's values, several seeds each) run
//! on threads inside Rust with the GIL released, as `ringsync sweep` runs them; or, for a
//! distributed sweep (Dask), as plain data: [`sweep_cases`] lists the cases, [`run_cases`]
//! runs some of them anywhere (a pure function of the cases' text) and [`sweep_collect`]
//! assembles the results into the same rows and means as [`sweep`].

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use ringsync::sweep::{
    Case, CaseResult, Labels, Sweep, SweepAxis, cases, default_jobs, run_cases as run_all,
};

use crate::convert::{literal, to_toml, whole};
use crate::guard;
use crate::scenario::axis;

/// The most seeds per combination of a sweep's values.
pub(crate) const MAX_SEEDS: u64 = ringsync::sweep::MAX_SEEDS as u64;

/// The most threads a sweep runs on, as the CLI's `--jobs`.
pub(crate) const MAX_JOBS: u64 = ringsync::sweep::MAX_JOBS as u64;

/// The `seeds` argument checked: a whole number 1 ..= [`MAX_SEEDS`].
fn seeds_arg(seeds: &Bound<'_, PyAny>) -> PyResult<u32> {
    let n = whole(
        "seeds",
        seeds,
        1,
        MAX_SEEDS,
        " (seeds per combination of the grid's values)",
    )?;
    Ok(u32::try_from(n).unwrap_or(u32::MAX))
}

/// The `jobs` argument checked: a whole number 1 ..= [`MAX_JOBS`], or None for the CPUs.
fn jobs_arg(jobs: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    match jobs {
        None => Ok(default_jobs()),
        Some(j) => {
            let n = whole("jobs", j, 1, MAX_JOBS, " (threads)")?;
            Ok(usize::try_from(n).unwrap_or(1))
        }
    }
}

/// For each label of a case, the index of its value in its axis (the first equal one).
fn indices(labels: &Labels, axes: &[SweepAxis]) -> Vec<usize> {
    labels
        .iter()
        .zip(axes)
        .map(|((_, v), a)| a.values.iter().position(|x| x == v).unwrap_or(0))
        .collect()
}

/// The grid [(dotted key, values)] as the library's sweep axes (values as TOML literals).
fn sweep_axes(grid: &[(String, Vec<Bound<'_, PyAny>>)]) -> PyResult<Vec<SweepAxis>> {
    let mut axes = Vec::with_capacity(grid.len());
    for (key, values) in grid {
        let lits = values
            .iter()
            .map(|v| to_toml(key, v).map(|t| literal(&t)))
            .collect::<PyResult<Vec<String>>>()?;
        axes.push(axis(key, lits)?);
    }
    Ok(axes)
}

/// A case's result as a dict: `track_rmse`, `sync_rmse` [rad], the counters,
/// `clock_error_max_ns` [ns], `group_stop_s` [s], `group_stop_reason`, `peak_u` [V],
/// `saturated_cycles`, and for a part program `contour_rmse` and `contour_max` [mm] (None
/// otherwise).
fn result_dict<'py>(py: Python<'py>, r: &CaseResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("track_rmse", r.track_rmse)?;
    d.set_item("sync_rmse", r.sync_rmse)?;
    d.set_item("lumped_lost", r.lumped_lost)?;
    d.set_item("retries", r.retries)?;
    d.set_item("commands_lost", r.commands_lost)?;
    d.set_item("clock_error_max_ns", r.clock_error_max_ns)?;
    d.set_item("group_stop_s", r.group_stop_s)?;
    d.set_item("group_stop_reason", r.group_stop_reason.clone())?;
    d.set_item("peak_u", r.peak_u)?;
    d.set_item("saturated_cycles", r.saturated_cycles)?;
    d.set_item("contour_rmse", r.contour_rmse)?;
    d.set_item("contour_max", r.contour_max)?;
    Ok(d)
}

/// A dict made by [`result_dict`] read back (the error names the missing or bad field).
fn result_of(d: &Bound<'_, PyDict>) -> PyResult<CaseResult> {
    fn field<'py, T: FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<T> {
        let v = d.get_item(key)?.ok_or_else(|| {
            pyo3::exceptions::PyValueError::new_err(format!("a case result lacks {key}"))
        })?;
        v.extract::<T>().map_err(|e| {
            let e: PyErr = e.into();
            pyo3::exceptions::PyValueError::new_err(format!("a case result's {key}: {e}"))
        })
    }
    Ok(CaseResult {
        track_rmse: field(d, "track_rmse")?,
        sync_rmse: field(d, "sync_rmse")?,
        lumped_lost: field(d, "lumped_lost")?,
        retries: field(d, "retries")?,
        commands_lost: field(d, "commands_lost")?,
        clock_error_max_ns: field(d, "clock_error_max_ns")?,
        group_stop_s: field(d, "group_stop_s")?,
        group_stop_reason: field(d, "group_stop_reason")?,
        peak_u: field(d, "peak_u")?,
        saturated_cycles: field(d, "saturated_cycles")?,
        contour_rmse: field(d, "contour_rmse")?,
        contour_max: field(d, "contour_max")?,
    })
}

/// The finished sweep as the dict the Python side reads: `rows` (one per run, in the order
/// of the product, seeds innermost) and `means` (one per combination), each naming its
/// values by their index in the grid, `seeds` and `jobs`.
fn sweep_dict<'py>(
    py: Python<'py>,
    sw: &Sweep,
    axes: &[SweepAxis],
    seeds: u32,
    jobs: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let rows = PyList::empty(py);
    for (c, r) in sw.cases.iter().zip(&sw.results) {
        let d = PyDict::new(py);
        d.set_item("values", indices(&c.labels, axes))?;
        d.set_item("seed", c.seed)?;
        d.update(result_dict(py, r)?.as_mapping())?;
        rows.append(d)?;
    }
    let means = PyList::empty(py);
    for m in &sw.means {
        let d = PyDict::new(py);
        d.set_item("values", indices(&m.labels, axes))?;
        d.set_item("runs", m.runs)?;
        d.set_item("track_rmse", m.track_rmse)?;
        d.set_item("sync_rmse", m.sync_rmse)?;
        d.set_item("sync_rmse_std", m.sync_rmse_std)?;
        means.append(d)?;
    }
    let out = PyDict::new(py);
    out.set_item("rows", rows)?;
    out.set_item("means", means)?;
    out.set_item("seeds", seeds)?;
    out.set_item("jobs", jobs)?;
    Ok(out)
}

/// Sweeps the scenario `text` over `grid` [(dotted key, values)], `seeds` seeds each
/// (1 ..= [`MAX_SEEDS`]), on `jobs` threads (1 ..= [`MAX_JOBS`]; default: the CPUs): see
/// [`sweep_dict`]. With `progress`, a line `ringsync sweep: DONE/ALL runs` on
/// `sys.stderr`, rewritten as runs finish (at most every 50 ms), ended by a newline.
#[pyfunction]
#[pyo3(signature = (text, origin, grid, seeds=None, jobs=None, progress=false))]
fn sweep<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    grid: Vec<(String, Vec<Bound<'py, PyAny>>)>,
    seeds: Option<Bound<'py, PyAny>>,
    jobs: Option<Bound<'py, PyAny>>,
    progress: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let seeds = seeds.as_ref().map_or(Ok(1), seeds_arg)?;
    let jobs = jobs_arg(jobs.as_ref())?.max(1);
    let axes = sweep_axes(&grid)?;
    let axes_run = axes.clone();
    // (runs done, runs in all), as the threads report them.
    let counts = Arc::new((AtomicUsize::new(0), AtomicUsize::new(0)));
    let seen = Arc::clone(&counts);
    let mut shown = None;
    let mut tick = |py: Python<'_>, finished: bool| -> PyResult<()> {
        let (done, all) = (
            counts.0.load(Ordering::Relaxed),
            counts.1.load(Ordering::Relaxed),
        );
        if !progress || all == 0 || (shown == Some(done) && !finished) {
            return Ok(());
        }
        shown = Some(done);
        let end = if finished { "\n" } else { "" };
        let err = py.import("sys")?.getattr("stderr")?;
        err.call_method1(
            "write",
            (format!("\rringsync sweep: {done}/{all} runs{end}"),),
        )?;
        err.call_method0("flush")?;
        Ok(())
    };
    let work = move |stop: &ringsync::Stop| {
        let base = ringsync::parse(&text, &origin)?;
        let cs: Vec<Case> = cases(&base, &axes_run, seeds, false)?;
        let runs = cs.len();
        seen.1.store(runs, Ordering::Relaxed);
        let results = ringsync::sweep::run_cases_until(
            &cs,
            jobs,
            &|done, _| {
                seen.0.fetch_max(done, Ordering::Relaxed);
            },
            stop,
        );
        Ok((Sweep::new(&base, &axes_run, seeds, cs, results)?, runs))
    };
    let (sw, runs): (Sweep, usize) = crate::interruptible_ticking(py, work, &mut tick)?;
    // The threads used: no more than there are runs.
    sweep_dict(py, &sw, &axes, seeds, jobs.min(runs.max(1)))
}

/// One case of a sweep as plain data: (the index of each swept value in the grid, the
/// seed, the case as JSON text, its cost in axis-cycles).
type CaseData = (Vec<usize>, u64, String, f64);

/// The cases of a sweep as plain data, validated, in the order of the product (seeds
/// innermost): for each, (value indices in the grid, seed, the case as JSON text, its cost
/// in axis-cycles: cycles × axes, what a run's time grows with).
#[pyfunction]
#[pyo3(signature = (text, origin, grid, seeds=None))]
fn sweep_cases<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    grid: Vec<(String, Vec<Bound<'py, PyAny>>)>,
    seeds: Option<Bound<'py, PyAny>>,
) -> PyResult<Vec<CaseData>> {
    let seeds = seeds.as_ref().map_or(Ok(1), seeds_arg)?;
    let axes = sweep_axes(&grid)?;
    guard(py, move || {
        let base = ringsync::parse(&text, &origin)?;
        let cs = cases(&base, &axes, seeds, false)?;
        let mut out = Vec::with_capacity(cs.len());
        for c in &cs {
            let s = c.scenario()?;
            let cycles =
                (s.duration.0.as_ns() as f64 / s.ring.cycle.0.as_ns().max(1) as f64).ceil();
            let cost = cycles * s.axes_count() as f64;
            out.push((
                indices(&c.labels, &axes),
                c.seed,
                serde_json::to_string(c)?,
                cost,
            ));
        }
        Ok(out)
    })
}

/// Runs cases given as JSON text (from [`sweep_cases`]) on `jobs` threads: a pure function
/// of the text (same cases, same results, in any process). One result dict per case, in
/// order (see [`result_dict`]); the first failed case raises, named.
#[pyfunction]
#[pyo3(signature = (cases, jobs=None))]
fn run_cases<'py>(
    py: Python<'py>,
    cases: Vec<String>,
    jobs: Option<Bound<'py, PyAny>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let jobs = match jobs {
        Some(j) => jobs_arg(Some(&j))?,
        None => 1,
    };
    let results = guard(py, move || {
        let cs = cases
            .iter()
            .map(|t| {
                serde_json::from_str::<Case>(t)
                    .map_err(|e| ringsync::Error::Input(format!("not a sweep case: {e}")))
            })
            .collect::<ringsync::Result<Vec<Case>>>()?;
        let results = run_all(&cs, jobs.max(1), &|_, _| {});
        cs.iter()
            .zip(results)
            .map(|(c, r)| {
                r.map_err(|e| match e {
                    ringsync::Error::Scenario(e) => {
                        ringsync::Error::Input(format!("case {}: {e}", c.name()))
                    }
                    other => other,
                })
            })
            .collect::<ringsync::Result<Vec<CaseResult>>>()
    })?;
    results.iter().map(|r| result_dict(py, r)).collect()
}

/// Assembles the results of every case of a sweep (one dict per case, in the order of
/// [`sweep_cases`], as [`run_cases`] gives them) into the same dict as [`sweep`]: the rows
/// and the means over the seeds, computed as the in-process sweep computes them.
#[pyfunction]
#[pyo3(signature = (text, origin, grid, seeds, results, jobs=None))]
fn sweep_collect<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    grid: Vec<(String, Vec<Bound<'py, PyAny>>)>,
    seeds: Bound<'py, PyAny>,
    results: Vec<Bound<'py, PyDict>>,
    jobs: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let seeds = seeds_arg(&seeds)?;
    let jobs = match jobs {
        Some(j) => jobs_arg(Some(&j))?,
        None => 1,
    };
    let axes = sweep_axes(&grid)?;
    let results = results
        .iter()
        .map(|d| result_of(d).map(Ok))
        .collect::<PyResult<Vec<ringsync::Result<CaseResult>>>>()?;
    let axes_run = axes.clone();
    let sw: Sweep = guard(py, move || {
        let base = ringsync::parse(&text, &origin)?;
        let cs: Vec<Case> = cases(&base, &axes_run, seeds, false)?;
        if cs.len() != results.len() {
            return Err(ringsync::Error::Input(format!(
                "the sweep has {} cases, {} results were given",
                cs.len(),
                results.len()
            )));
        }
        Sweep::new(&base, &axes_run, seeds, cs, results)
    })?;
    sweep_dict(py, &sw, &axes, seeds, jobs)
}

/// Registers the sweep functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_cases, m)?)?;
    m.add_function(wrap_pyfunction!(run_cases, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_collect, m)?)?;
    Ok(())
}
