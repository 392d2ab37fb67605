//! Simulating and checking: [`SimRun`] keeps a finished simulation for its arrays, its
//! metrics and the CLI's files; `check` hands back the CLI's `check --json` report.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use ringsync::layers::report::sim::{summary_json, write_trace_csv};
use ringsync::layers::report::{check_json, check_text, plan_json};
use ringsync::{OutDir, RunResult, Scenario, SimOptions, Trace, Verdict};

use crate::convert::{json_to_py, whole};
use crate::{ScenarioError, guard};

/// The largest seed: a scenario's `seed` is a TOML integer (signed 64-bit).
pub(crate) const MAX_SEED: u64 = i64::MAX.unsigned_abs();

/// What follows the seeds' range in an error message.
pub(crate) const SEED_RANGE: &str =
    " (2^63 - 1: a scenario's seed is a signed 64-bit TOML integer)";

/// The most points `check` evaluates the paper's conditions at (`ringsync check --points`
/// takes 1 ..= 1 000 000 too).
pub(crate) const MAX_POINTS: u64 = 1_000_000;

/// The most prediction seeds of a real-time run (as many as `reproduce` takes).
const MAX_PREDICTION_SEEDS: u64 = ringsync::reproduce::MAX_SEEDS as u64;

/// A finished simulation (opaque to Python; `ringsync.Run` wraps it).
#[pyclass(frozen, module = "ringsync._ringsync")]
pub struct SimRun {
    /// The scenario as run (its seed the one used).
    scenario: Scenario,
    /// FNV-1a hash of the scenario's text, named in summary.json.
    hash: u64,
    /// The run, with its trace.
    result: RunResult,
    /// For a real-time run: its summary.json (the simulator's fields plus the timing) and
    /// the lines `ringsync rt` prints.
    rt: Option<(serde_json::Value, String)>,
    /// The scenario as loaded (its text and origin), for the run's scenario.toml.
    loaded: ringsync::Loaded,
}

/// Simulates the scenario `text` (from `origin`), with `seed` (0 ..= 2^63 - 1) instead of
/// the scenario's when given, keeping the trace: what `ringsync sim` runs.
#[pyfunction]
#[pyo3(signature = (text, origin, seed=None))]
fn simulate(
    py: Python<'_>,
    text: String,
    origin: String,
    seed: Option<Bound<'_, PyAny>>,
) -> PyResult<SimRun> {
    let seed = seed
        .map(|s| whole("seed", &s, 0, MAX_SEED, SEED_RANGE))
        .transpose()?;
    crate::interruptible(py, move |stop| {
        let loaded = ringsync::parse(&text, &origin)?;
        let mut scenario = loaded.scenario.clone();
        if let Some(seed) = seed {
            scenario.seed = seed;
        }
        let opts = SimOptions {
            trace: true,
            stop: Some(stop.clone()),
            ..SimOptions::default()
        };
        let result = ringsync::simulate(&scenario, &opts)?;
        Ok(SimRun {
            scenario,
            hash: loaded.hash,
            result,
            rt: None,
            loaded,
        })
    })
}

impl SimRun {
    /// summary.json's content: the real-time run's when it is one, else the simulator's.
    fn summary_value(&self) -> serde_json::Value {
        match &self.rt {
            Some((v, _)) => v.clone(),
            None => summary_json(&self.scenario, self.hash, &self.result),
        }
    }
}

/// Runs the scenario `text` in real time (`ringsync rt`: the master and a
/// process-internal slave per axis exchanging real frames on their own threads) over
/// `transport` ("udp" on loopback, no privileges needed; "veth", a ring of network
/// namespaces, as root) with `stamps` ("phy" or "software"), and the simulator's
/// predictions from `prediction_seeds` seeds (0: none). Ctrl-C (KeyboardInterrupt) ends the
/// run early; it is raised when the run has stopped and cleaned up.
#[pyfunction]
#[pyo3(signature = (text, origin, prediction_seeds=None, transport="udp", stamps="phy"))]
fn rt(
    py: Python<'_>,
    text: String,
    origin: String,
    prediction_seeds: Option<Bound<'_, PyAny>>,
    transport: &str,
    stamps: &str,
) -> PyResult<SimRun> {
    let prediction_seeds = match prediction_seeds {
        Some(n) => whole("prediction_seeds", &n, 0, MAX_PREDICTION_SEEDS, "")?,
        None => 8,
    };
    let transport = match transport {
        "udp" => ringsync::TransportKind::Udp,
        "veth" => ringsync::TransportKind::Veth,
        other => {
            return Err(ScenarioError::new_err(format!(
                "unknown transport {other:?}: use \"udp\" or \"veth\""
            )));
        }
    };
    let stamps: ringsync::Stamps = stamps.parse().map_err(ScenarioError::new_err)?;
    if stamps == ringsync::Stamps::Kernel {
        return Err(ScenarioError::new_err(
            "stamps 'kernel' are for a ring of node processes (ringsync rt --processes): use phy or software",
        ));
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let worker = std::thread::Builder::new()
        .name("ringsync-rt".into())
        .spawn(move || {
            catch_unwind(AssertUnwindSafe(|| -> ringsync::Result<SimRun> {
                let loaded = ringsync::parse(&text, &origin)?;
                let opts = ringsync::RtOptions {
                    transport,
                    stamps,
                    trace: true,
                    ..ringsync::RtOptions::default()
                };
                let r = ringsync::run_rt(&loaded.scenario, &opts, &flag, Vec::new())?;
                let prediction = if prediction_seeds > 0 && !r.interrupted {
                    Some(ringsync::predict_rt(&r, prediction_seeds)?)
                } else {
                    None
                };
                let summary =
                    ringsync::rt::rt_summary(&r, loaded.hash, r.transport.name(), prediction);
                let text = ringsync::rt::rt_text(&r, prediction);
                Ok(SimRun {
                    scenario: r.scenario,
                    hash: loaded.hash,
                    result: r.run,
                    rt: Some((summary, text)),
                    loaded,
                })
            }))
        })
        .map_err(|e| crate::RunError::new_err(format!("cannot start the real-time run: {e}")))?;
    // Wait without the GIL, looking for Ctrl-C every 50 ms.
    let mut interrupted = None;
    while !worker.is_finished() {
        py.detach(|| std::thread::sleep(std::time::Duration::from_millis(50)));
        if interrupted.is_none()
            && let Err(e) = py.check_signals()
        {
            stop.store(true, Ordering::Relaxed);
            interrupted = Some(e);
        }
    }
    let done = py.detach(|| worker.join());
    if let Some(e) = interrupted {
        return Err(e);
    }
    match done {
        Ok(Ok(r)) => r.map_err(crate::to_py),
        Ok(Err(panic)) | Err(panic) => Err(crate::panicked(panic.as_ref())),
    }
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
        let mut e = Vec::new();
        t.e_into(0..t.len(), &mut e);
        for (name, col) in [
            ("x_d", &t.x_d),
            ("x", &t.x),
            ("e", &e),
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

    /// A part program's run (`None` for other trajectories): `axes` (the machine axes'
    /// letters), `time` (cycles,) [s], `actual` and `desired` (cycles × machine axes) [mm],
    /// `contour_error` (cycles,) [mm], `metrics` (contour_rmse, contour_max, contour_mean
    /// [mm], cycles, program_duration_s, complete) and `circles` (one dict per ISO 230-4
    /// circular test, as summary.json's, with its `angle` [rad] and `deviation` [mm]
    /// profile as arrays).
    fn path<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(p) = &self.result.path else {
            return Ok(None);
        };
        let tr = &p.trace;
        let m = tr.axes.len().max(1);
        let d = PyDict::new(py);
        d.set_item(
            "axes",
            tr.axes.iter().map(|c| c.to_string()).collect::<Vec<_>>(),
        )?;
        d.set_item("time", PyArray1::from_slice(py, &tr.t))?;
        d.set_item("actual", grid(py, &tr.actual, m)?)?;
        d.set_item("desired", grid(py, &tr.desired, m)?)?;
        d.set_item("contour_error", PyArray1::from_slice(py, &tr.contour))?;
        let metrics = PyDict::new(py);
        metrics.set_item("contour_rmse", p.rmse)?;
        metrics.set_item("contour_max", p.max)?;
        metrics.set_item("contour_mean", p.mean)?;
        metrics.set_item("cycles", p.cycles)?;
        metrics.set_item("program_duration_s", p.program_duration)?;
        metrics.set_item("complete", p.complete)?;
        d.set_item("metrics", metrics)?;
        let circles = pyo3::types::PyList::empty(py);
        for c in &p.circles {
            let v = ringsync::layers::report::path::circular_json(c);
            let cd = json_to_py(py, &v)?;
            let (angle, dev): (Vec<f64>, Vec<f64>) = c.profile.iter().copied().unzip();
            cd.set_item("angle", PyArray1::from_slice(py, &angle))?;
            cd.set_item("deviation", PyArray1::from_slice(py, &dev))?;
            circles.append(cd)?;
        }
        d.set_item("circles", circles)?;
        Ok(Some(d))
    }

    /// summary.json's text, exactly as `ringsync sim` (or `ringsync rt`) writes it.
    fn summary_json(&self) -> PyResult<String> {
        let v = self.summary_value();
        let text = serde_json::to_string_pretty(&v)
            .map_err(|e| crate::RunError::new_err(format!("cannot format JSON: {e}")))?;
        Ok(format!("{text}\n"))
    }

    /// summary.json's content as a dict.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.summary_value())
    }

    /// Whether this is a real-time run (`ringsync.rt`).
    #[getter]
    fn realtime(&self) -> bool {
        self.rt.is_some()
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
        match &self.rt {
            Some((_, text)) => text.clone(),
            None => ringsync::sim_text(&self.scenario, &self.result),
        }
    }

    /// Writes the CLI's files into `dir` (replaced as a whole, as `ringsync sim --out`
    /// replaces it): scenario.toml, summary.json, trace.csv (path.csv for a part program),
    /// the figures, report.html; for a real-time run what `ringsync rt --out` writes:
    /// scenario.toml, summary.json and trace.csv. An empty path is a `ScenarioError`.
    fn save(&self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        if dir.as_os_str().is_empty() {
            return Err(ScenarioError::new_err(
                "directory = '' is empty: give Run.save the path of a new, empty or earlier results directory, e.g. 'out/run'",
            ));
        }
        guard(py, || {
            // Named so that the library's messages read "the save directory DIR is not
            // empty …: the run replaces the save directory as a whole …".
            let mut out = OutDir::create("the save directory", &dir)?;
            // The scenario as run, as `ringsync sim --out` keeps it (`identify` reads it).
            ringsync::identify::write_scenario(&out, &self.loaded, Some(self.scenario.seed))?;
            if let Some((summary, _)) = &self.rt {
                out.write(
                    "summary.json",
                    format!("{}\n", serde_json::to_string_pretty(summary)?),
                )?;
                out.write_with("trace.csv", |w| write_trace_csv(&self.result, w))?;
                return out.commit();
            }
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

/// What [`check`] hands back: `ringsync check --json`'s object, its text, whether stable,
/// the discrete-time check's closed-loop matrix (states × states, `None` when the check
/// does not model the loop) and the cycle time T_cyc [s].
type Checked<'py> = (
    Bound<'py, PyAny>,
    String,
    bool,
    Option<Bound<'py, PyAny>>,
    f64,
);

/// Checks the scenario `text` as `ringsync check --json` does, the paper's conditions at
/// `points` instants (1 ..= [`MAX_POINTS`], default 4001): (report, text, stable, loop
/// matrix, T_cyc [s]); the matrix is the one whose eigenvalues give the report's spectral
/// radius (9 states per axis, see `ringsync_control::stability::discrete_loop`).
#[pyfunction]
#[pyo3(signature = (text, origin, points=None))]
fn check<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    points: Option<Bound<'py, PyAny>>,
) -> PyResult<Checked<'py>> {
    let points = match points {
        Some(p) => whole(
            "points",
            &p,
            1,
            MAX_POINTS,
            " (instants of the motion, as ringsync check --points)",
        )?,
        None => 4001,
    };
    let points = usize::try_from(points)
        .map_err(|_| ScenarioError::new_err(format!("points = {points} is too many here")))?;
    let (json, text, stable, matrix, t_cyc) = guard(py, move || {
        let s = ringsync::parse(&text, &origin)?.scenario;
        let r = ringsync::check(&s, points)?;
        let states = r.discrete.map_or(0, |d| d.states);
        Ok((
            check_json(&r),
            check_text(&r),
            r.verdict() == Verdict::Stable,
            r.discrete_matrix.map(|m| (m, states)),
            s.ring.cycle.secs(),
        ))
    })?;
    let matrix = match matrix {
        Some((m, n)) => Some(PyArray1::from_vec(py, m).reshape([n, n])?.into_any()),
        None => None,
    };
    Ok((json_to_py(py, &json)?, text, stable, matrix, t_cyc))
}

/// The cycle plan (eq. 1-2) of the scenario `text`'s ring, as `ringsync plan --json`
/// prints it (integer ns; with `events`, the frame-by-frame timeline too), checked against
/// the scenario's plan kind.
#[pyfunction]
#[pyo3(signature = (text, origin, events=false))]
fn plan<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    events: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let json = guard(py, move || {
        let s = ringsync::parse(&text, &origin)?.scenario;
        let p = ringsync::plan_of(&s)?;
        Ok(plan_json(&p, s.ring.plan, events))
    })?;
    json_to_py(py, &json)
}

/// The scenario's part program planned on its machine without a ring, as
/// `ringsync program --json` prints it: duration [s], length [mm], blends, stops, blocks,
/// each axis's peak v, a, j at the cycle against its limits, what bounds the feed; and
/// `feed` = (time [s], path speed [mm/s]) at `points` instants over the program.
#[pyfunction]
#[pyo3(signature = (text, origin, points=1000))]
fn program<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    points: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let (json, t, v) = guard(py, move || {
        let s = ringsync::parse(&text, &origin)?.scenario;
        let p = ringsync::plan_program(&s)?;
        let view = p.view();
        let n = points.clamp(2, 1_000_000);
        let dt = p.path.duration() / (n - 1) as f64;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let v: Vec<f64> = t.iter().map(|&x| p.path.at(x).speed).collect();
        Ok((ringsync::layers::report::path::program_json(&view), t, v))
    })?;
    let d = json_to_py(py, &json)?;
    d.set_item(
        "feed",
        (PyArray1::from_slice(py, &t), PyArray1::from_slice(py, &v)),
    )?;
    Ok(d)
}

/// The paper's Table 1 reproduced on the scenario `text` over `seeds` seeds (1 ..=
/// 10 000: the scenario's, +1, …), as `ringsync reproduce --seeds` runs it: one dict per
/// (seed, plan, controller), seeds outermost, with `seed`, `plan`, `controller`,
/// `track_rmse`, `sync_rmse` [rad] and `group_stop` (bool).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn reproduce<'py>(
    py: Python<'py>,
    text: String,
    origin: String,
    seeds: Bound<'py, PyAny>,
) -> PyResult<(Vec<Bound<'py, PyDict>>, Bound<'py, PyAny>)> {
    let max = ringsync::reproduce::MAX_SEEDS;
    let seeds = whole("seeds", &seeds, 1, u64::from(max), " (seeds per case)")?;
    let seeds = u32::try_from(seeds).unwrap_or(max);
    let rows = crate::interruptible(py, move |stop| {
        let s = ringsync::parse(&text, &origin)?.scenario;
        let opts = ringsync::ReproOptions {
            seeds,
            stop: Some(stop.clone()),
            ..Default::default()
        };
        let r = ringsync::reproduce_with(&s, &opts)?;
        let summary =
            ringsync::layers::report::repro::repro_json(&s.name, &r.rows, r.bench.as_ref());
        let mut rows = Vec::new();
        for (k, &seed) in r
            .rows
            .first()
            .map_or(&[][..], |x| &x.seeds[..])
            .iter()
            .enumerate()
        {
            for (row, stops) in r.rows.iter().zip(&r.stops) {
                rows.push((
                    seed,
                    row.plan.to_string(),
                    row.controller.to_string(),
                    row.track_rmse[k],
                    row.sync_rmse[k],
                    stops.iter().any(|(s, _)| *s == seed),
                ));
            }
        }
        Ok((rows, summary))
    })?;
    let (rows, summary) = rows;
    let summary = json_to_py(py, &summary)?;
    let rows = rows
        .into_iter()
        .map(|(seed, plan, controller, track, sync, stop)| {
            let d = PyDict::new(py);
            d.set_item("seed", seed)?;
            d.set_item("plan", plan)?;
            d.set_item("controller", controller)?;
            d.set_item("track_rmse", track)?;
            d.set_item("sync_rmse", sync)?;
            d.set_item("group_stop", stop)?;
            Ok(d)
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok((rows, summary))
}

/// Registers the simulation functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SimRun>()?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(program, m)?)?;
    m.add_function(wrap_pyfunction!(reproduce, m)?)?;
    m.add_function(wrap_pyfunction!(rt, m)?)?;
    Ok(())
}
