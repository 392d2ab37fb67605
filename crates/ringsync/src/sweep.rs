//! Parameter sweeps: the Cartesian product of values of any scenario keys, several seeds
//! each (no key: the scenario alone over its seeds). A [`Case`] is plain data (its scenario as TOML text) and [`run_case`] a pure
//! function of it, so a case can be sent to another process or machine and run there;
//! [`run_cases`] runs them on threads here. [`aggregate`] takes means over the seeds.
//!
//! ```
//! use ringsync::sweep::{SweepAxis, aggregate, cases, run_cases};
//! let base = ringsync::parse("duration = \"100ms\"\n", "short")?;
//! let axes: Vec<SweepAxis> = vec!["control.estimator=hold,paper".parse()?];
//! let cs = cases(&base, &axes, 2, false)?;
//! assert_eq!(cs.len(), 4); // 2 values × 2 seeds
//! // A case travels as text: JSON here, for a remote worker.
//! let wire = serde_json::to_string(&cs[0]).unwrap();
//! let back: ringsync::sweep::Case = serde_json::from_str(&wire).unwrap();
//! assert_eq!(ringsync::run_case(&back)?, ringsync::run_case(&cs[0])?);
//! let results = run_cases(&cs, 2, &|_, _| {});
//! let results: Vec<_> = results.into_iter().collect::<Result<_, _>>()?;
//! let means = aggregate(&cs, &results);
//! assert_eq!((means.len(), means[0].runs), (2, 2));
//! # Ok::<(), ringsync::Error>(())
//! ```

use std::fmt::Write as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde::{Deserialize, Serialize};

use ringsync_model::scenario::{ECHO_CHARS, Scenario, ScenarioError, clip, toml_message};
use ringsync_proto::{CyclePlan, Duration, PlanKind};

use crate::error::{Error, Result};
use crate::load::Loaded;
use crate::output::OutDir;
pub use ringsync_sim::Stop;

/// Seeds per case by default, in `sweep`, `reproduce` and Python alike: enough for a
/// standard deviation worth reading.
pub const DEFAULT_SEEDS: u32 = crate::reproduce::DEFAULT_SEEDS;

/// Most seeds per case, in `sweep`, `reproduce` and Python alike.
pub const MAX_SEEDS: u32 = crate::reproduce::MAX_SEEDS;

/// One swept key and its values, from `key=v1,v2,…`.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepAxis {
    /// Dotted scenario key, e.g. `faults.loss`.
    pub key: String,
    /// The values as written (TOML values; bare words are strings).
    pub values: Vec<String>,
}

impl std::str::FromStr for SweepAxis {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let (key, values) = s.split_once('=').ok_or_else(|| {
            Error::Input(format!(
                "'{s}' is not KEY=V1,V2,…: e.g. faults.loss=0,0.01,0.02"
            ))
        })?;
        let key = key.trim();
        if key.is_empty()
            || !key
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "_.[]".contains(c))
        {
            return Err(Error::Input(format!(
                "'{key}' is not a scenario key like ring.slaves"
            )));
        }
        one_line(key, values)?;
        let values: Vec<String> = split_values(values)
            .into_iter()
            .map(|v| v.trim().to_string())
            .collect();
        if values.iter().all(|v| v.is_empty()) {
            return Err(Error::Input(format!("'{s}' gives no values")));
        }
        if values.iter().any(|v| v.is_empty()) {
            return Err(Error::Input(format!(
                "'{s}' has an empty value between commas: expected KEY=V1,V2,…"
            )));
        }
        if let Some((_, v)) = values
            .iter()
            .enumerate()
            .find(|(i, v)| values[..*i].contains(v))
        {
            return Err(Error::Input(format!(
                "'{s}' gives {key} the value {v} twice: each value is one case, run over every seed"
            )));
        }
        Ok(SweepAxis {
            key: key.to_string(),
            values,
        })
    }
}

/// `v1,v2,…` split at the commas between values: not inside brackets (an array such as
/// `[1,2]` or an inline table) or quotes (a string holding a comma).
///
/// ```
/// # use ringsync::sweep::SweepAxis;
/// let a: SweepAxis = "control.kp=[1, 2],[3,4],\"a,b\",5".parse().unwrap();
/// assert_eq!(a.values, ["[1, 2]", "[3,4]", "\"a,b\"", "5"]);
/// ```
fn split_values(s: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let (mut depth, mut quote, mut start) = (0i32, None::<char>, 0);
    let mut escaped = false;
    for (i, c) in s.char_indices() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                ',' if depth <= 0 => {
                    out.push(&s[start..i]);
                    start = i + 1;
                }
                _ => {}
            },
        }
    }
    out.push(&s[start..]);
    out
}

/// Refuses a value of `key` with a line break or another control character: a value is
/// one TOML value on one line (the rest of a second line would be dropped, or read as
/// another key).
pub(crate) fn one_line(key: &str, value: &str) -> Result<()> {
    if let Some(c) = value.chars().find(|c| c.is_control()) {
        return Err(Error::Input(format!(
            "the value of {key} holds the control character {}: a value is one line",
            c.escape_default()
        )));
    }
    Ok(())
}

/// Parses `v`, the value of `key`, as a TOML value; a bare word is taken as a string (so is
/// anything that is not exactly one value). An integer beyond TOML's is refused.
fn toml_value(key: &str, v: &str) -> Result<toml::Value> {
    if let Ok(n) = v.replace('_', "").parse::<i128>()
        && i64::try_from(n).is_err()
    {
        return Err(Error::Input(format!(
            "{key} = {v} is beyond the integers a scenario holds (-2^63 … 2^63 - 1)"
        )));
    }
    Ok(toml::from_str::<toml::Table>(&format!("x = {v}"))
        .ok()
        .filter(|t| t.len() == 1)
        .and_then(|mut t| t.remove("x"))
        .unwrap_or_else(|| toml::Value::String(v.to_string())))
}

/// Refuses a grid that gives a key twice, or a key and a key inside it (`control` and
/// `control.alpha`): the later would overwrite the earlier and the rows be mislabelled.
/// `seed` is no sweep key unless `seed_key` (a single run's `--set seed=S`): each case runs
/// over the seeds from the scenario's own.
fn check_grid(axes: &[SweepAxis], seed_key: bool) -> Result<()> {
    for (i, a) in axes.iter().enumerate() {
        if !seed_key && a.key == "seed" {
            return Err(Error::Input(
                "seed is not a key to sweep: each case runs over `seeds` seeds from the scenario's own seed (set that in the scenario)".into(),
            ));
        }
        for b in &axes[..i] {
            let inside = |x: &str, y: &str| {
                x.strip_prefix(y)
                    .is_some_and(|r| r.starts_with('.') || r.starts_with('['))
            };
            if a.key == b.key {
                return Err(Error::Input(format!(
                    "{} is given twice: give each key once, with all its values",
                    a.key
                )));
            }
            if inside(&a.key, &b.key) || inside(&b.key, &a.key) {
                return Err(Error::Input(format!(
                    "{} and {} overlap: one would overwrite the other",
                    b.key, a.key
                )));
            }
        }
    }
    Ok(())
}

/// The most threads a sweep runs on (one run is single-threaded: more would only wait).
pub const MAX_JOBS: usize = 4096;

/// The largest seed a scenario holds (TOML integers are signed 64-bit).
pub const MAX_SEED: u64 = i64::MAX as u64;

/// Sets `key` (dotted; `axis.KEY` sets KEY in every `[[axis]]` table, `axis[i].KEY` in the
/// i-th, 0-based) to `value` in a scenario's TOML table.
fn set(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ScenarioError> {
    let parts: Vec<&str> = key.split('.').collect();
    set_in(table, &parts, key, &value)
}

fn set_in(
    t: &mut toml::Table,
    parts: &[&str],
    key: &str,
    value: &toml::Value,
) -> Result<(), ScenarioError> {
    let bad = |allowed: String| ScenarioError::OutOfRange {
        key: key.to_string(),
        value: clip(&value.to_string(), ECHO_CHARS).into_owned(),
        allowed,
    };
    let Some((p, rest)) = parts.split_first() else {
        return Err(bad("a key".into()));
    };
    let (name, index) = match p.split_once('[') {
        Some((n, i)) => {
            let i = i
                .strip_suffix(']')
                .and_then(|i| i.parse::<usize>().ok())
                .ok_or_else(|| bad(format!("{p}: an index is a whole number, e.g. axis[0]")))?;
            (n, Some(i))
        }
        None => (*p, None),
    };
    if rest.is_empty() {
        if index.is_some() {
            return Err(bad(format!("a key after {p}, e.g. {p}.encoder_bits")));
        }
        t.insert(name.to_string(), value.clone());
        return Ok(());
    }
    if !t.contains_key(name) {
        // The axes a file leaves out are the reference scenario's: set them explicitly.
        let default = (name == "axis")
            .then(|| ringsync_model::builtin("paper-2015"))
            .flatten()
            .and_then(|text| toml::from_str::<toml::Table>(text).ok())
            .and_then(|mut r| r.remove("axis"))
            .unwrap_or_else(|| toml::Value::Table(toml::Table::new()));
        t.insert(name.to_string(), default);
    }
    match (t.get_mut(name), index) {
        (Some(toml::Value::Table(inner)), None) => set_in(inner, rest, key, value),
        (Some(toml::Value::Array(items)), index) => {
            let n = items.len();
            let chosen: Vec<&mut toml::Value> = match index {
                Some(i) => items.get_mut(i).map(|v| vec![v]).ok_or_else(|| {
                    bad(format!("{name}[0] to {name}[{}]: {n} tables", n.max(1) - 1))
                })?,
                None => items.iter_mut().collect(),
            };
            for item in chosen {
                let inner = item
                    .as_table_mut()
                    .ok_or_else(|| bad(format!("a key inside a table; {name} holds no tables")))?;
                set_in(inner, rest, key, value)?;
            }
            Ok(())
        }
        _ => Err(bad(format!("a key inside a table; {p} is not a table"))),
    }
}

/// The (key, value) pairs that name one case of a sweep.
pub type Labels = Vec<(String, String)>;

/// One case of a sweep: plain data, all a worker needs to run it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Case {
    /// (key, value) for every swept key, as written.
    pub labels: Labels,
    /// The seed.
    pub seed: u64,
    /// The case's scenario as TOML text: the base with the swept values, the seed and (with
    /// `auto_cycle`) the cycle set.
    pub scenario: String,
}

impl Case {
    /// The case's scenario, validated.
    pub fn scenario(&self) -> Result<Scenario> {
        Ok(Scenario::from_toml(&self.scenario, &self.name())?)
    }

    /// The case's name: its labels and seed, e.g. `faults.loss=0.01 seed=2`.
    pub fn name(&self) -> String {
        let mut n: Vec<String> = self
            .labels
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        n.push(format!("seed={}", self.seed));
        n.join(" ")
    }
}

/// What a case gives: the metrics (eq. 26-27) and the counters a sweep compares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseResult {
    /// Track-RMSE \[rad\].
    pub track_rmse: f64,
    /// Sync-RMSE \[rad\].
    pub sync_rmse: f64,
    /// Lumped frames the master lost.
    pub lumped_lost: u64,
    /// Commands the master sent again.
    pub retries: u64,
    /// Commands never acknowledged in their cycle.
    pub commands_lost: u64,
    /// Largest slave clock error over the second half of the run \[ns\].
    pub clock_error_max_ns: f64,
    /// When the group stopped \[s\], if it did.
    pub group_stop_s: Option<f64>,
    /// Why the group stopped, if it did: the name `summary.json` gives it
    /// (`faults.group_stop.reason`: `following-error`, `axis-fault`, `no-response`,
    /// `no-feedback`, `command-mismatch`); see [`stop_reason`].
    #[serde(default)]
    pub group_stop_reason: Option<String>,
    /// Largest |command| over the run and the axes \[V\] (the effort a law spends).
    #[serde(default)]
    pub peak_u: f64,
    /// The most cycles any axis's drive was held at its limit ±u_max (summary.json's
    /// per-axis `saturations`): gains that drive the axes bang-bang show here.
    #[serde(default)]
    pub saturated_cycles: u64,
    /// A part program's RMS contour error \[mm\] (docs/programs.md); `None` for other
    /// trajectories.
    #[serde(default)]
    pub contour_rmse: Option<f64>,
    /// A part program's largest contour error \[mm\].
    #[serde(default)]
    pub contour_max: Option<f64>,
}

/// The name of a group stop's reason in outputs, as `summary.json` writes it
/// (`faults.group_stop.reason`) and a sweep's [`CaseResult::group_stop_reason`] holds it.
///
/// ```
/// use ringsync::layers::proto::node::StopReason;
/// assert_eq!(ringsync::sweep::stop_reason(&StopReason::NoResponse { axis: 1 }), "no-response");
/// ```
pub fn stop_reason(r: &ringsync_proto::node::StopReason) -> String {
    r.name().replace(' ', "-")
}

/// Every case: each combination of values, `seeds` seeds each (the scenario's seed, +1, …).
/// With `auto_cycle`, a case whose cycle is too short for its ring gets the shortest cycle
/// that holds it, plus 10 %, rounded up to 100 µs. Every case is validated here: the error
/// names the case and its bad key.
///
/// A key given twice, two keys one inside the other, or `seed` as a key are refused.
pub fn cases(base: &Loaded, axes: &[SweepAxis], seeds: u32, auto_cycle: bool) -> Result<Vec<Case>> {
    check_grid(axes, false)?;
    make_cases(base, axes, seeds, auto_cycle)
}

/// [`cases`] for `--set` values of a single run (`seed` may be set).
pub(crate) fn set_cases(base: &Loaded, axes: &[SweepAxis]) -> Result<Vec<Case>> {
    check_grid(axes, true)?;
    make_cases(base, axes, 1, false)
}

/// A case's scenario is text without a file: a part program named relative to the base
/// scenario's file (or, set by the case, to the working directory) is named by its
/// absolute path in it, so that the case finds it wherever it runs on this machine.
fn anchor_program(t: &mut toml::Table, dir: Option<&std::path::Path>) {
    let Some(toml::Value::Table(tr)) = t.get_mut("trajectory") else {
        return;
    };
    let Some(toml::Value::String(p)) = tr.get("program") else {
        return;
    };
    let given = std::path::Path::new(p);
    if given.is_absolute() {
        return;
    }
    let found = dir
        .map(|d| d.join(given))
        .into_iter()
        .chain(std::env::current_dir().ok().map(|c| c.join(given)))
        .find(|c| c.is_file())
        .and_then(|c| std::fs::canonicalize(c).ok());
    if let Some(abs) = found.and_then(|a| a.to_str().map(str::to_string)) {
        tr.insert("program".into(), toml::Value::String(abs));
    }
}

fn make_cases(
    base: &Loaded,
    axes: &[SweepAxis],
    seeds: u32,
    auto_cycle: bool,
) -> Result<Vec<Case>> {
    let origin = &base.origin;
    let table: toml::Table = toml::from_str(&base.text).map_err(|e| ScenarioError::Syntax {
        origin: clip(origin, ECHO_CHARS).into_owned(),
        message: toml_message(e.message()),
    })?;
    let mut combos: Vec<Labels> = vec![Vec::new()];
    for a in axes {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                a.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((a.key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    let mut out = Vec::new();
    for labels in combos {
        let mut t = table.clone();
        for (k, v) in &labels {
            set(&mut t, k, toml_value(k, v)?)?;
        }
        anchor_program(&mut t, base.scenario.dir.as_deref());
        // A file that named nothing ran under its own name: its cases keep it.
        if !t.contains_key("name") && base.scenario.dir.is_some() {
            t.insert(
                "name".into(),
                toml::Value::String(base.scenario.name.clone()),
            );
        }
        let with = || {
            let l: Vec<String> = labels.iter().map(|(k, v)| format!("{k}={v}")).collect();
            clip(&format!("{origin} with {}", l.join(" ")), 2 * ECHO_CHARS).into_owned()
        };
        let s = Scenario::deserialize(toml::Value::Table(t.clone())).map_err(|e| {
            ScenarioError::Syntax {
                origin: with(),
                message: toml_message(e.message()),
            }
        })?;
        if auto_cycle && let Some(cycle) = cycle_that_holds(&s) {
            set(
                &mut t,
                "ring.cycle",
                toml::Value::String(format!("{}ns", cycle.as_ns())),
            )?;
        }
        let s = Scenario::deserialize(toml::Value::Table(t.clone())).map_err(|e| {
            ScenarioError::Syntax {
                origin: with(),
                message: toml_message(e.message()),
            }
        })?;
        s.validate().map_err(|e| ScenarioError::Syntax {
            origin: with(),
            message: e.to_string(),
        })?;
        let last = s.seed.saturating_add(u64::from(seeds.max(1)) - 1);
        let last = i64::try_from(last).map_err(|_| {
            Error::Input(format!(
                "{}: the seeds {} … {last} go beyond {MAX_SEED}, the largest seed a scenario holds",
                with(),
                s.seed
            ))
        })?;
        for seed in s.seed..=last as u64 {
            let mut tk = t.clone();
            tk.insert("seed".into(), toml::Value::Integer(seed as i64));
            let scenario = toml::to_string(&tk)
                .map_err(|e| Error::Failed(format!("cannot write the case {}: {e}", with())))?;
            out.push(Case {
                labels: labels.clone(),
                seed,
                scenario,
            });
        }
    }
    Ok(out)
}

/// The shortest cycle that holds `s`'s ring plus 10 %, rounded up to 100 µs, when its own
/// is too short.
fn cycle_that_holds(s: &Scenario) -> Option<Duration> {
    let mut p = s.ring_params();
    p.t_cyc = Duration::from_ms(10_000);
    let plan = CyclePlan::new(&p).ok()?;
    let need = match s.ring.plan {
        PlanKind::P2pLumped => plan.min_t_cyc.max(plan.event.min_t_cyc),
        PlanKind::LumpedOnly => plan.lumped_only.min_t_cyc,
    };
    (need > s.ring.cycle.0).then(|| {
        let ns = need.as_ns() + need.as_ns() / 10;
        Duration::from_ns((ns / 100_000 + 1) * 100_000)
    })
}

/// Runs one case: a pure function of the case (same case, same result, wherever it runs).
pub fn run_case(case: &Case) -> Result<CaseResult> {
    run_case_until(case, None)
}

/// [`run_case`], ended early (an [`Error::Interrupted`]) when `stop` rises.
pub fn run_case_until(case: &Case, stop: Option<&Stop>) -> Result<CaseResult> {
    let s = case.scenario()?;
    let opts = crate::SimOptions {
        stop: stop.cloned(),
        ..Default::default()
    };
    let r = crate::simulate(&s, &opts)?;
    Ok(CaseResult {
        track_rmse: r.summary.track_rmse,
        sync_rmse: r.summary.sync_rmse,
        lumped_lost: r.master.lumped_lost,
        retries: r.master.retries,
        commands_lost: r.master.commands_lost,
        clock_error_max_ns: r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        group_stop_s: r.group_stop.map(|(t, _)| t),
        group_stop_reason: r.group_stop.map(|(_, why)| stop_reason(&why)),
        peak_u: r.summary.axes.iter().map(|a| a.peak_u).fold(0.0, f64::max),
        saturated_cycles: r
            .summary
            .axes
            .iter()
            .map(|a| a.saturations)
            .max()
            .unwrap_or(0),
        contour_rmse: r.path.as_ref().map(|p| p.rmse),
        contour_max: r.path.as_ref().map(|p| p.max),
    })
}

/// The default number of parallel cases: the CPUs this process may use.
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Runs every case on `jobs` threads (one single-threaded simulation per case); results in
/// case order. `progress(done, total)` is called after each case.
pub fn run_cases(
    cases: &[Case],
    jobs: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<Result<CaseResult>> {
    par_map(cases, jobs, run_case, progress, None)
}

/// [`run_cases`] until `stop` rises (Ctrl-C): no case starts after it, the cases running
/// end at their next cycle; every case that did not finish is an [`Error::Interrupted`]
/// ([`Sweep::finished`] keeps the others).
pub fn run_cases_until(
    cases: &[Case],
    jobs: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
    stop: &Stop,
) -> Vec<Result<CaseResult>> {
    par_map(
        cases,
        jobs,
        |c| run_case_until(c, Some(stop)),
        progress,
        Some(stop),
    )
}

/// `f` on every item, on `jobs` threads taking the next item as they finish one; results in
/// item order. `progress(done, total)` is called after each item. A thread that panics
/// leaves its item's result as an error. Once `stop` rises no item starts: those left are
/// [`Error::Interrupted`].
pub(crate) fn par_map<T: Sync, R: Send>(
    items: &[T],
    jobs: usize,
    f: impl Fn(&T) -> Result<R> + Sync,
    progress: &(dyn Fn(usize, usize) + Sync),
    stop: Option<&Stop>,
) -> Vec<Result<R>> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<R>>>> = items.iter().map(|_| Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..jobs.max(1).min(items.len().max(1)) {
            scope.spawn(|| {
                loop {
                    if stop.is_some_and(Stop::raised) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= items.len() {
                        break;
                    }
                    let r = f(&items[i]);
                    if let Ok(mut slot) = slots[i].lock() {
                        *slot = Some(r);
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, items.len());
                }
            });
        }
    });
    let stopped = stop.is_some_and(Stop::raised);
    slots
        .into_iter()
        .map(|slot| {
            slot.into_inner().ok().flatten().unwrap_or_else(|| {
                Err(if stopped {
                    Error::Interrupted("not run: interrupted".into())
                } else {
                    Error::Failed("a case was not run".into())
                })
            })
        })
        .collect()
}

/// The means over the seeds of one combination of values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Mean {
    /// The combination.
    pub labels: Labels,
    /// Cases (seeds) in the mean.
    pub runs: usize,
    /// Mean Track-RMSE \[rad\].
    pub track_rmse: f64,
    /// Mean Sync-RMSE \[rad\].
    pub sync_rmse: f64,
    /// Sample standard deviation (n − 1) of Sync-RMSE over the seeds; 0 for one seed \[rad\].
    pub sync_rmse_std: f64,
    /// Mean over the seeds of the peak |command| \[V\].
    pub peak_u: f64,
    /// Mean RMS contour error of a part program \[mm\] (`None` for other trajectories).
    pub contour_rmse: Option<f64>,
    /// Its sample standard deviation (n − 1) over the seeds \[mm\].
    pub contour_rmse_std: Option<f64>,
}

/// The sample standard deviation (n − 1 in the denominator) of `values` about their mean
/// `mean`; 0 for fewer than two values. The one estimator of every "± sd" ringsync writes.
///
/// ```
/// let sd = ringsync::sweep::sample_sd([1.0, 2.0, 3.0].into_iter(), 2.0);
/// assert_eq!(sd, 1.0);
/// assert_eq!(ringsync::sweep::sample_sd([5.0].into_iter(), 5.0), 0.0);
/// ```
pub fn sample_sd(values: impl Iterator<Item = f64> + Clone, mean: f64) -> f64 {
    let n = values.clone().count();
    if n < 2 {
        return 0.0;
    }
    (values.map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
}

/// Means over the seeds, per combination of values, in the cases' order.
pub fn aggregate(cases: &[Case], results: &[CaseResult]) -> Vec<Mean> {
    // Per combination: (Track-RMSE, Sync-RMSE, peak |u|, contour RMSE) of each seed.
    type Seeds = Vec<(f64, f64, f64, Option<f64>)>;
    let mut groups: Vec<(Labels, Seeds)> = Vec::new();
    for (c, r) in cases.iter().zip(results) {
        let x = (r.track_rmse, r.sync_rmse, r.peak_u, r.contour_rmse);
        match groups.last_mut() {
            Some((l, v)) if *l == c.labels => v.push(x),
            _ => groups.push((c.labels.clone(), vec![x])),
        }
    }
    groups
        .into_iter()
        .map(|(labels, v)| {
            let n = v.len() as f64;
            let track = v.iter().map(|x| x.0).sum::<f64>() / n;
            let sync = v.iter().map(|x| x.1).sum::<f64>() / n;
            let sd = sample_sd(v.iter().map(|x| x.1), sync);
            let contour: Option<Vec<f64>> = v.iter().map(|x| x.3).collect();
            let (contour_rmse, contour_rmse_std) = match contour {
                Some(c) if !c.is_empty() => {
                    let m = c.iter().sum::<f64>() / n;
                    (Some(m), Some(sample_sd(c.iter().copied(), m)))
                }
                _ => (None, None),
            };
            Mean {
                contour_rmse,
                contour_rmse_std,
                labels,
                runs: v.len(),
                track_rmse: track,
                sync_rmse: sync,
                sync_rmse_std: sd,
                peak_u: v.iter().map(|x| x.2).sum::<f64>() / n,
            }
        })
        .collect()
}

/// A finished sweep.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The swept keys, in order.
    pub keys: Vec<String>,
    /// The base scenario's name or path.
    pub origin: String,
    /// Seeds per combination.
    pub seeds: u32,
    /// Every case.
    pub cases: Vec<Case>,
    /// Their results, in the same order.
    pub results: Vec<CaseResult>,
    /// Means over the seeds.
    pub means: Vec<Mean>,
}

impl Sweep {
    /// The cases of an interrupted sweep ([`run_cases_until`]) that finished, as a sweep of
    /// their own (means over the seeds that finished), and how many did not: the first case
    /// that failed otherwise is the error, as in [`Sweep::new`].
    pub fn finished(
        base: &Loaded,
        axes: &[SweepAxis],
        seeds: u32,
        cases: Vec<Case>,
        results: Vec<Result<CaseResult>>,
    ) -> Result<(Sweep, usize)> {
        let (kept, left): (Vec<_>, Vec<_>) = cases
            .into_iter()
            .zip(results)
            .partition(|(_, r)| !matches!(r, Err(Error::Interrupted(_))));
        let (cases, results) = kept.into_iter().unzip();
        Ok((Sweep::new(base, axes, seeds, cases, results)?, left.len()))
    }

    /// Collects the results of [`run_cases`]: the first failed case is the error, named.
    pub fn new(
        base: &Loaded,
        axes: &[SweepAxis],
        seeds: u32,
        cases: Vec<Case>,
        results: Vec<Result<CaseResult>>,
    ) -> Result<Sweep> {
        let results = cases
            .iter()
            .zip(results)
            .map(|(c, r)| {
                r.map_err(|e| match e {
                    Error::Scenario(e) => Error::Input(format!("case {}: {e}", c.name())),
                    other => other,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Sweep {
            keys: axes.iter().map(|a| a.key.clone()).collect(),
            origin: base.origin.clone(),
            seeds,
            means: aggregate(&cases, &results),
            cases,
            results,
        })
    }

    /// Cases that ended in a group stop.
    pub fn stopped(&self) -> usize {
        self.results
            .iter()
            .filter(|r| r.group_stop_s.is_some())
            .count()
    }

    /// The means as a Markdown table (no key columns for a sweep over seeds alone).
    pub fn table(&self) -> String {
        let mut table = format!(
            "| {}runs | Track-RMSE [rad] | Sync-RMSE [rad] (± sample sd over seeds) | peak \\|u\\| [V] |\n|{}---:|---:|---:|---:|\n",
            self.keys
                .iter()
                .map(|k| format!("{k} | "))
                .collect::<String>(),
            "---|".repeat(self.keys.len())
        );
        for m in &self.means {
            let vals: String = m.labels.iter().map(|(_, v)| format!("{v} | ")).collect();
            let _ = writeln!(
                table,
                "| {}{} | {:.5} | {:.7} ± {:.7} | {:.3} |",
                vals, m.runs, m.track_rmse, m.sync_rmse, m.sync_rmse_std, m.peak_u
            );
        }
        table
    }
}

/// Writes a sweep into `dir`: `sweep.csv` (one row per case), `means.csv` (one row per
/// combination; `sync_rmse_std` is the sample standard deviation, n − 1) and `sweep.svg`
/// (mean Sync-RMSE against the first key, one line per value of the others; with no key,
/// each seed's Sync-RMSE). The CSV files go through the `csv` writer: a value with a comma
/// or a quote (an array, a file name) is quoted.
pub fn write_sweep(dir: &OutDir, sw: &Sweep) -> Result<()> {
    // A part program's sweep gains the contour error's columns [mm].
    let contour = sw.results.iter().any(|r| r.contour_rmse.is_some());
    let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.9}"));
    let header = |cols: &[&str], extra: &[&str]| -> Vec<String> {
        let mut h: Vec<String> = sw.keys.clone();
        h.extend(cols.iter().map(|c| c.to_string()));
        if contour {
            h.extend(extra.iter().map(|c| c.to_string()));
        }
        h
    };
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header(
        &[
            "seed",
            "track_rmse",
            "sync_rmse",
            "lumped_lost",
            "retries",
            "commands_lost",
            "clock_error_max_ns",
            "group_stop_s",
            "peak_u_v",
            "saturated_cycles",
        ],
        &["contour_rmse_mm", "contour_max_mm"],
    ))
    .map_err(csv_failed)?;
    for (c, r) in sw.cases.iter().zip(&sw.results) {
        let mut rec: Vec<String> = c.labels.iter().map(|(_, v)| v.clone()).collect();
        rec.extend([
            c.seed.to_string(),
            format!("{:.9}", r.track_rmse),
            format!("{:.9}", r.sync_rmse),
            r.lumped_lost.to_string(),
            r.retries.to_string(),
            r.commands_lost.to_string(),
            format!("{:.0}", r.clock_error_max_ns),
            r.group_stop_s.map_or(String::new(), |t| format!("{t:.4}")),
            format!("{:.6}", r.peak_u),
            r.saturated_cycles.to_string(),
        ]);
        if contour {
            rec.extend([opt(r.contour_rmse), opt(r.contour_max)]);
        }
        w.write_record(&rec).map_err(csv_failed)?;
    }
    dir.write("sweep.csv", csv_bytes(w)?)?;
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header(
        &[
            "runs",
            "track_rmse_mean",
            "sync_rmse_mean",
            "sync_rmse_std",
            "peak_u_mean_v",
        ],
        &["contour_rmse_mean_mm", "contour_rmse_std_mm"],
    ))
    .map_err(csv_failed)?;
    for m in &sw.means {
        let mut rec: Vec<String> = m.labels.iter().map(|(_, v)| v.clone()).collect();
        rec.extend([
            m.runs.to_string(),
            format!("{:.9}", m.track_rmse),
            format!("{:.9}", m.sync_rmse),
            format!("{:.9}", m.sync_rmse_std),
            format!("{:.6}", m.peak_u),
        ]);
        if contour {
            rec.extend([opt(m.contour_rmse), opt(m.contour_rmse_std)]);
        }
        w.write_record(&rec).map_err(csv_failed)?;
    }
    dir.write("means.csv", csv_bytes(w)?)?;
    dir.write("sweep.svg", sweep_svg(sw))?;
    Ok(())
}

/// The bytes a CSV writer over memory holds.
fn csv_bytes(w: csv::Writer<Vec<u8>>) -> Result<Vec<u8>> {
    w.into_inner()
        .map_err(|e| Error::Failed(format!("sweep CSV: {e}")))
}

fn csv_failed(e: csv::Error) -> Error {
    Error::Failed(format!("sweep CSV: {e}"))
}

/// Mean Sync-RMSE against the first key with ± one sample standard deviation (n − 1) over
/// the seeds as error bars, one line with markers per combination of the other keys (as
/// Python's `Sweep.plot()` draws it): a key whose values are not all numbers is drawn as
/// categories, a numeric key whose values double from one to the next (ring sizes) and span
/// a factor of 8 or more on a log axis. With no key, each seed's Sync-RMSE and their mean.
fn sweep_svg(sw: &Sweep) -> String {
    use ringsync_report::plot::{Chart, PALETTE, Series, chart};
    let Some(first) = sw.keys.first() else {
        let points = sw
            .cases
            .iter()
            .zip(&sw.results)
            .map(|(c, r)| (c.seed as f64, r.sync_rmse))
            .collect();
        let series = [Series {
            name: "Sync-RMSE".into(),
            colour: PALETTE[0],
            points,
            extent: None,
            errors: Vec::new(),
        }];
        let mean = sw.means.first().map_or(f64::NAN, |m| m.sync_rmse);
        return chart(
            &format!("{}: Sync-RMSE of each of {}", sw.origin, seeds_run(sw)),
            "seed",
            "Sync-RMSE [rad]",
            &series,
            &Chart {
                markers: true,
                hline: Some((mean, format!("mean {mean:.6}"))),
                ..Chart::default()
            },
        );
    };
    // The first key's values in the sweep's order, and whether they are all numbers.
    let mut xs: Vec<&str> = Vec::new();
    for m in &sw.means {
        if !xs.contains(&m.labels[0].1.as_str()) {
            xs.push(&m.labels[0].1);
        }
    }
    let numbers: Option<Vec<f64>> = xs.iter().map(|v| v.parse::<f64>().ok()).collect();
    let numbers = numbers.filter(|v| v.iter().all(|x| x.is_finite()));
    let x_of = |label: &str| {
        let k = xs.iter().position(|v| *v == label).unwrap_or(0);
        numbers.as_ref().map_or(k as f64, |n| n[k])
    };
    // Per line (the other keys' values): its name, (x, mean) points and sample sds.
    type Line = (String, Vec<(f64, f64)>, Vec<f64>);
    let mut groups: Vec<Line> = Vec::new();
    for m in &sw.means {
        let name = m.labels[1..]
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(", ");
        let p = (x_of(&m.labels[0].1), m.sync_rmse);
        match groups.iter_mut().find(|(n, _, _)| *n == name) {
            Some((_, pts, sd)) => {
                pts.push(p);
                sd.push(m.sync_rmse_std);
            }
            None => groups.push((name, vec![p], vec![m.sync_rmse_std])),
        }
    }
    let series: Vec<Series<'_>> = groups
        .into_iter()
        .enumerate()
        .map(|(i, (name, points, errors))| Series {
            name: if name.is_empty() {
                "Sync-RMSE".into()
            } else {
                name
            },
            colour: PALETTE[i % PALETTE.len()],
            points,
            extent: None,
            errors,
        })
        .collect();
    let x_log = numbers.as_ref().is_some_and(|n| {
        let (lo, hi) = n
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), &x| (l.min(x), h.max(x)));
        lo > 0.0 && hi / lo >= 8.0
    });
    chart(
        &format!(
            "{}: mean ± sample sd (n − 1) over {}",
            sw.origin,
            seeds_run(sw)
        ),
        first,
        "Sync-RMSE [rad]",
        &series,
        &Chart {
            x_log,
            markers: true,
            x_categories: numbers
                .is_none()
                .then(|| xs.iter().map(|v| v.trim_matches('"').to_string()).collect()),
            ..Chart::default()
        },
    )
}

/// The seeds behind each mean, for a figure's title: "8 seeds", or for an interrupted sweep
/// "3 to 7 of 8 seeds (interrupted)".
fn seeds_run(sw: &Sweep) -> String {
    let runs = sw.means.iter().map(|m| m.runs);
    let (lo, hi) = (runs.clone().min().unwrap_or(0), runs.max().unwrap_or(0));
    let plural = if sw.seeds == 1 { "" } else { "s" };
    match (lo, hi) {
        (lo, hi) if lo == hi && hi == sw.seeds as usize => format!("{hi} seed{plural}"),
        (lo, hi) if lo == hi => format!("{hi} of {} seed{plural} (interrupted)", sw.seeds),
        (lo, hi) => format!("{lo} to {hi} of {} seed{plural} (interrupted)", sw.seeds),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> Loaded {
        crate::load("paper-2015").expect("builtin")
    }

    #[test]
    fn parses_axes() {
        let a: SweepAxis = "faults.loss=0, 0.01,0.02".parse().expect("axis");
        assert_eq!(a.key, "faults.loss");
        assert_eq!(a.values, vec!["0", "0.01", "0.02"]);
        assert!("faults.loss".parse::<SweepAxis>().is_err());
        assert!("=1".parse::<SweepAxis>().is_err());
        assert!("a b=1".parse::<SweepAxis>().is_err());
    }

    #[test]
    fn cartesian_product_with_seeds() {
        let axes: Vec<SweepAxis> = ["control.estimator=hold,paper", "faults.loss=0,0.02"]
            .iter()
            .map(|s| s.parse().expect("axis"))
            .collect();
        let c = cases(&base(), &axes, 2, false).expect("cases");
        assert_eq!(c.len(), 2 * 2 * 2);
        assert_eq!(
            c[0].labels,
            vec![
                ("control.estimator".into(), "hold".into()),
                ("faults.loss".into(), "0".into())
            ]
        );
        assert_eq!((c[0].seed, c[1].seed), (1, 2));
        let s7 = c[7].scenario().expect("valid");
        assert_eq!(s7.faults.loss, 0.02);
        assert_eq!(s7.control.estimator, ringsync_control::EstimatorKind::Paper);
        assert_eq!(s7.seed, 2);
        assert_eq!(
            c[7].name(),
            "control.estimator=paper faults.loss=0.02 seed=2"
        );
        // The text holds everything else of the base.
        let mut want = base().scenario;
        want.seed = 2;
        want.faults.loss = 0.02;
        assert_eq!(s7, want);
    }

    #[test]
    fn bad_keys_and_values_are_errors() {
        let bad = |s: &str| {
            cases(&base(), &[s.parse().expect("axis")], 1, false)
                .expect_err("bad")
                .to_string()
        };
        assert!(bad("faults.lost=0.1").contains("lost"));
        assert!(bad("faults.loss=2").contains("faults.loss = 2"));
        assert!(bad("ring.slaves=64").contains("ring.cycle"));
        // With auto_cycle the ring gets a cycle that holds it.
        let c = cases(&base(), &["ring.slaves=64".parse().expect("axis")], 1, true).expect("auto");
        let s = c[0].scenario().expect("valid");
        assert!(s.ring.cycle.0 > Duration::from_ms(8));
        assert_eq!(s.ring.cycle.0.as_ns() % 100_000, 0);
    }

    /// `axis.KEY` sets every `[[axis]]` table (those of the reference scenario when a file
    /// has none), `axis[i].KEY` one of them; a bad index is named.
    #[test]
    fn axis_keys_set_every_axis_or_one() {
        let one = |text: &str, key: &str| {
            let base = crate::parse(text, "t").expect("text");
            cases(&base, &[key.parse().expect("axis")], 1, false)
                .map(|c| c[0].scenario().expect("valid"))
        };
        let all = one("duration = \"1s\"\n", "axis.encoder_bits=28").expect("every axis");
        assert_eq!(all.axis.len(), 4, "the reference axes, made explicit");
        assert!(all.axis.iter().all(|a| a.encoder_bits == 28));
        assert_eq!(all.axis[3].j_over_ka, 0.0164, "the rest as the reference's");
        let second = one(&base().text, "axis[1].j_over_ka=0.02").expect("axis 1");
        let j: Vec<f64> = second.axis.iter().map(|a| a.j_over_ka).collect();
        assert_eq!(j, [0.0156, 0.02, 0.0158, 0.0164]);
        let e = one(&base().text, "axis[9].j_over_ka=0.02").expect_err("no axis 9");
        assert!(
            e.to_string().starts_with(
                "axis[9].j_over_ka = 0.02 is out of range: allowed axis[0] to axis[3]"
            ),
            "{e}"
        );
        let e = one(&base().text, "axis[x].j_over_ka=0.02").expect_err("not an index");
        assert!(e.to_string().contains("whole number"), "{e}");
        let e = one(&base().text, "axis.encoder_bits=1").expect_err("range");
        assert!(e.to_string().contains("encoder_bits"), "{e}");
    }

    /// A stop flag raised during a sweep: no case starts after it, the finished ones are
    /// kept (their means over the seeds that finished), the rest counted; raised before,
    /// nothing runs.
    #[test]
    fn an_interrupted_sweep_keeps_what_finished() {
        let short = crate::parse("duration = \"100ms\"\n", "t").expect("text");
        let axes = ["control.alpha=0.2,0.4".parse().expect("axis")];
        let c = cases(&short, &axes, 5, false).expect("cases");
        let stop = Stop::new();
        let r = run_cases_until(
            &c,
            1,
            &|done, _| {
                if done == 3 {
                    stop.raise();
                }
            },
            &stop,
        );
        assert!(r[..3].iter().all(Result::is_ok));
        assert!(
            r[3..]
                .iter()
                .all(|r| matches!(r, Err(Error::Interrupted(_))))
        );
        let (sw, not_run) = Sweep::finished(&short, &axes, 5, c.clone(), r).expect("sweep");
        assert_eq!((sw.results.len(), not_run), (3, 7));
        assert_eq!(sw.means.len(), 1, "only alpha = 0.2 ran");
        assert_eq!(sw.means[0].runs, 3);
        assert_eq!(sw.results[0], run_case(&c[0]).expect("run"));
        assert!(
            sweep_svg(&sw).contains("over 3 of 5 seeds (interrupted)"),
            "the figure says which seeds its means are over"
        );
        let r = run_cases_until(&c, 2, &|_, _| {}, &stop);
        let (sw, not_run) = Sweep::finished(&short, &axes, 5, c, r).expect("sweep");
        assert_eq!((sw.results.len(), not_run), (0, 10));
    }

    #[test]
    fn runs_in_parallel_in_order() {
        let short = crate::parse("duration = \"100ms\"\n", "t").expect("text");
        let c = cases(
            &short,
            &["control.law=pd,sync".parse().expect("axis")],
            1,
            false,
        )
        .expect("cases");
        let r = run_cases(&c, 2, &|_, _| {});
        assert_eq!(r.len(), 2);
        let (pd, sync) = (r[0].as_ref().expect("pd"), r[1].as_ref().expect("sync"));
        let solo = run_case(&c[1]).expect("run");
        assert_eq!(*sync, solo);
        assert_ne!(pd, sync);
    }

    #[test]
    fn a_stopped_case_names_its_reason_as_summary_json_does() {
        let base = crate::parse(
            "duration = \"300ms\"\n[faults]\nsilent_slave = 2\nsilent_from = \"100ms\"\n",
            "t",
        )
        .expect("text");
        let c = cases(&base, &[], 1, false).expect("cases");
        let r = run_case(&c[0]).expect("run");
        let s = c[0].scenario().expect("valid");
        let full = crate::simulate(&s, &crate::SimOptions::default()).expect("run");
        let json = ringsync_report::sim::summary_json(&s, 0, &full);
        assert!(r.group_stop_reason.is_some(), "{r:?}");
        assert_eq!(
            r.group_stop_reason.as_deref(),
            json["faults"]["group_stop"]["reason"].as_str()
        );
    }

    #[test]
    fn means_over_seeds() {
        let c = |v: &str, seed| Case {
            labels: vec![("k".into(), v.into())],
            seed,
            scenario: String::new(),
        };
        let r = |sync| CaseResult {
            track_rmse: 1.0,
            sync_rmse: sync,
            lumped_lost: 0,
            retries: 0,
            commands_lost: 0,
            clock_error_max_ns: 0.0,
            group_stop_s: None,
            peak_u: 0.0,
            saturated_cycles: 0,
            group_stop_reason: None,
            contour_rmse: None,
            contour_max: None,
        };
        let m = aggregate(
            &[c("a", 1), c("a", 2), c("b", 1)],
            &[r(1.0), r(3.0), r(5.0)],
        );
        assert_eq!(m.len(), 2);
        // The sample standard deviation: √(((1−2)² + (3−2)²)/(2 − 1)) = √2, not the
        // population's 1.
        assert_eq!(
            (m[0].runs, m[0].sync_rmse, m[0].sync_rmse_std),
            (2, 2.0, std::f64::consts::SQRT_2)
        );
        assert_eq!(
            (m[1].runs, m[1].sync_rmse, m[1].sync_rmse_std),
            (1, 5.0, 0.0)
        );
    }
}
