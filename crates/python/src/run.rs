//! Simulating and checking: [`SimRun`] keeps a finished simulation for its arrays, its
//! metrics and the CLI's files; `check` hands back the CLI's `check --json` report.

use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use ringsync::layers::report::sim::summary_json;
use ringsync::layers::report::{check_json, check_text};
use ringsync::{OutDir, RunResult, Scenario, SimOptions, Trace, Verdict};

use crate::convert::json_to_py;
use crate::guard;

/// A finished simulation (opaque to Python; `ringsync.Run` wraps it).
#[pyclass(frozen, module = "ringsync._ringsync")]
pub struct SimRun {
    /// The scenario as run (its seed the one used).
    scenario: Scenario,
    /// FNV-1a hash of the scenario's text, named in summary.json.
    hash: u64,
    /// The run, with its trace.
    result: RunResult,
}

/// Simulates the scenario `text` (from `origin`), with `seed` instead of the scenario's
/// when given, keeping the trace: what `ringsync sim` runs.
#[pyfunction]
#[pyo3(signature = (text, origin, seed=None))]
fn simulate(py: Python<'_>, text: String, origin: String, seed: Option<u64>) -> PyResult<SimRun> {
    guard(py, move || {
        let loaded = ringsync::parse(&text, &origin)?;
        let mut scenario = loaded.scenario;
        if let Some(seed) = seed {
            scenario.seed = seed;
        }
        let opts = SimOptions {
            trace: true,
            ..SimOptions::default()
        };
        let result = ringsync::simulate(&scenario, &opts)?;
        Ok(SimRun {
            scenario,
            hash: loaded.hash,
            result,
        })
    })
}

/// `column` (group-major, `n` per group) as a 2-D array of groups × n.
fn grid<'py>(py: Python<'py>, column: &[f64], n: usize) -> PyResult<Bound<'py, PyAny>> {
    let rows = column.len().checked_div(n).unwrap_or(0);
    let a = PyArray1::from_slice(py, column).reshape([rows, n])?;
    Ok(a.into_any())
}

#[pymethods]
impl SimRun {
    /// The trace as arrays: `time` (cycles,) [s]; `x_d`, `x`, `e`, `eps` [rad], `u` [V],
    /// `sample_time`, `apply_time` [s] and `clock_error_ns` [ns], each cycles × axes.
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t: &Trace = &self.result.trace;
        let n = t.axes.max(1);
        let d = PyDict::new(py);
        d.set_item("time", PyArray1::from_slice(py, &t.t))?;
        for (name, col) in [
            ("x_d", &t.x_d),
            ("x", &t.x),
            ("e", &t.e),
            ("eps", &t.eps),
            ("u", &t.u),
            ("sample_time", &t.sample_time),
            ("apply_time", &t.apply_time),
            ("clock_error_ns", &t.clock_error_ns),
        ] {
            d.set_item(name, grid(py, col, n)?)?;
        }
        Ok(d)
    }

    /// summary.json's text, exactly as `ringsync sim` writes it.
    fn summary_json(&self) -> PyResult<String> {
        let v = summary_json(&self.scenario, self.hash, &self.result);
        let text = serde_json::to_string_pretty(&v)
            .map_err(|e| crate::RunError::new_err(format!("cannot format JSON: {e}")))?;
        Ok(format!("{text}\n"))
    }

    /// summary.json's content as a dict.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &summary_json(&self.scenario, self.hash, &self.result))
    }

    /// The run's figures as a flat dict, taken from the run itself (not through JSON).
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.result;
        let m = &r.summary;
        let d = PyDict::new(py);
        d.set_item("track_rmse", m.track_rmse)?;
        d.set_item("sync_rmse", m.sync_rmse)?;
        d.set_item("samples", m.samples)?;
        d.set_item("cycles", r.cycles)?;
        d.set_item("t_cyc_s", self.scenario.ring.cycle.secs())?;
        d.set_item(
            "clock_error_max_ns",
            r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        )?;
        d.set_item("group_stop_s", r.group_stop.map(|(t, _)| t))?;
        d.set_item(
            "group_stop_reason",
            r.group_stop
                .map(|(_, why)| ringsync::sweep::stop_reason(&why)),
        )?;
        d.set_item("frames_sent", r.master.frames_sent)?;
        d.set_item("frames_lost", r.links.lost)?;
        d.set_item("frames_corrupted", r.links.corrupted)?;
        d.set_item("lumped_lost", r.master.lumped_lost)?;
        d.set_item("retries", r.master.retries)?;
        d.set_item("commands_lost", r.master.commands_lost)?;
        let axes = &m.axes;
        let per_axis = |f: fn(&ringsync::layers::control::metrics::AxisSummary) -> f64| {
            axes.iter().map(f).collect::<Vec<f64>>()
        };
        d.set_item("rms_e", per_axis(|a| a.rms_e))?;
        d.set_item("max_e", per_axis(|a| a.max_e))?;
        d.set_item("rms_eps", per_axis(|a| a.rms_eps))?;
        d.set_item("max_eps", per_axis(|a| a.max_eps))?;
        d.set_item("rms_u", per_axis(|a| a.rms_u))?;
        d.set_item("peak_u", per_axis(|a| a.peak_u))?;
        d.set_item(
            "saturations",
            axes.iter().map(|a| a.saturations).collect::<Vec<u64>>(),
        )?;
        d.set_item("clock_error_rms_ns", r.clock_error_rms_ns.clone())?;
        Ok(d)
    }

    /// The CLI's few lines on the run.
    fn text(&self) -> String {
        ringsync::sim_text(&self.scenario, &self.result)
    }

    /// Writes the CLI's files into `dir` (replaced as a whole, as `ringsync sim --out`
    /// replaces it): summary.json, trace.csv, the figures, report.html.
    fn save(&self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        guard(py, || {
            let mut out = OutDir::create("save: directory", &dir)?;
            ringsync::write_sim(
                &mut out,
                &self.scenario,
                self.hash,
                &self.result,
                None,
                ringsync::Outputs::ALL,
            )?;
            out.commit()
        })
    }

    /// Number of axes.
    #[getter]
    fn axes(&self) -> usize {
        self.scenario.axes_count()
    }

    /// The seed the run used.
    #[getter]
    fn seed(&self) -> u64 {
        self.scenario.seed
    }

    /// The scenario's name.
    #[getter]
    fn name(&self) -> String {
        self.scenario.name.clone()
    }
}

/// Checks the scenario `text` as `ringsync check --json` does: (report, text).
#[pyfunction]
#[pyo3(signature = (text, origin, points=4001))]
fn check<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    points: usize,
) -> PyResult<(Bound<'py, PyAny>, String, bool)> {
    let (json, text, stable) = guard(py, move || {
        let s = ringsync::parse(&text, &origin)?.scenario;
        let r = ringsync::check(&s, points.max(1))?;
        Ok((
            check_json(&r),
            check_text(&r),
            r.verdict() == Verdict::Stable,
        ))
    })?;
    Ok((json_to_py(py, &json)?, text, stable))
}

/// Registers the simulation functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SimRun>()?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    Ok(())
}
