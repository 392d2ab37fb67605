//! Identifying a run's axes (`ringsync identify RUN_DIR --out FILE.toml`): H = J/K_a,
//! C = b/K_a and F = T_c/K_a of every torque axis from the run's `trace.csv`, by least
//! squares on the axis model ([`ringsync_control::identify`]), and the run's scenario with
//! them as feed-forward gains (K_H, K_C, K_F).

use std::path::Path;

use ringsync_control::identify::{AxisIdentification, AxisRecord, identify_axis};
use ringsync_plant::AxisModel;

use crate::error::{Error, Result};
use crate::load::Loaded;

/// The file a run directory keeps its scenario in ([`write_scenario`]).
pub const SCENARIO_FILE: &str = "scenario.toml";

/// How [`SCENARIO_FILE`] starts (a comment naming where the scenario came from): it marks a
/// directory as a run's results, which the next run into it may replace.
pub const SCENARIO_HEADER: &str = "# The scenario of this run, from ";

/// One axis identified, beside the scenario's own values.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifiedAxis {
    /// Axis, 1-based.
    pub axis: usize,
    /// The estimates.
    pub id: AxisIdentification,
    /// The scenario's (H, C, F) of this axis (the simulated plant's) [V·s²/rad, V·s/rad, V].
    pub scenario: (f64, f64, f64),
}

/// The disturbance observer's bandwidth `identify` writes by default \[Hz\]
/// (`control.dob_bandwidth`). Feed-forward alone is only as good as the model is equal on
/// every axis: on `paper-2015` with the identified gains, per-axis errors alternating ±1 %,
/// ±3 %, ±10 % between the axes give the sync law Sync-RMSE 0.32×, 0.96×, 3.2× standard
/// PD's; with this observer 0.010×, 0.026×, 0.084× (±30 %: 0.25×), for +4 % peak command
/// and a Track-RMSE of 0.0014 rad against 0.0002 rad with an exact model
/// (docs/experiments.md, section 6).
pub const DOB_BANDWIDTH_HZ: f64 = 20.0;

/// The per-axis model error (relative, alternating between axes) above which feed-forward
/// without an observer leaves the sync law's Sync-RMSE above standard PD's: 3.1 % measured
/// on `paper-2015` (see [`DOB_BANDWIDTH_HZ`]); a fit whose 95 % intervals are wider than
/// this is warned about.
pub const FEED_FORWARD_BREAK_EVEN: f64 = 0.03;

/// A run identified: every axis, and the scenario it ran.
#[derive(Debug, Clone)]
pub struct Identification {
    /// The run's scenario (from its `scenario.toml`).
    pub run: Loaded,
    /// Every axis, in order.
    pub axes: Vec<IdentifiedAxis>,
}

/// Writes `scenario.toml` into `dir`: the scenario file a run ran, `seed` set when the run
/// was given another than the file's (`ringsync identify` reads it; `ringsync rt` applies
/// its options, such as `--cycle`, on top, and its summary.json names them).
pub fn write_scenario(dir: &crate::OutDir, run: &Loaded, seed: Option<u64>) -> Result<()> {
    let text = match seed {
        Some(seed) if seed != run.scenario.seed => {
            crate::with_values(run, &[("seed".into(), seed.to_string())])?.text
        }
        _ => run.text.clone(),
    };
    // A scenario file that named nothing ran under its file's name: the copy says so (a
    // top-level key, before any table).
    let named = toml::from_str::<toml::Table>(&text).is_ok_and(|t| t.contains_key("name"));
    let text = if named {
        text
    } else {
        format!(
            "name = \"{}\"  # the scenario file's name\n{text}",
            run.scenario.name.escape_default()
        )
    };
    dir.write(
        SCENARIO_FILE,
        format!("{SCENARIO_HEADER}{}.\n{text}", run.origin.escape_default()),
    )
}

/// Largest `scenario.toml` or `summary.json` of a run read \[bytes\] (a run's summary grows
/// with its axes: about 1 MB for 1 024).
const MAX_RUN_FILE: u64 = 64 << 20;

/// Longest line of a trace.csv read \[bytes\] (a row is about 150).
const MAX_TRACE_LINE: usize = 64 << 10;

fn read(dir: &Path, name: &str) -> Result<String> {
    let p = dir.join(name);
    ringsync_model::bounded::read_text(&p, MAX_RUN_FILE, "a run's file").map_err(|e| {
        Error::Input(format!(
            "{}: {e}; expected a run directory written by `ringsync sim` or `ringsync rt` (with {name})",
            p.display()
        ))
    })
}

/// Refuses an `out` for the identified scenario that is one of the run's own files in
/// `dir` (writing it would replace that file).
pub fn check_out(dir: &Path, out: &Path) -> Result<()> {
    let Ok(target) = std::fs::canonicalize(out) else {
        return Ok(()); // not there yet: none of the run's files
    };
    for name in [SCENARIO_FILE, "summary.json", "trace.csv"] {
        if std::fs::canonicalize(dir.join(name)).is_ok_and(|p| p == target) {
            return Err(Error::Input(format!(
                "--out {} is the run's own {name}: write the identified scenario elsewhere",
                out.display()
            )));
        }
    }
    Ok(())
}

/// Identifies every axis of the run in `dir` (its `scenario.toml`, `trace.csv` and
/// `summary.json`). Refused, naming the reason: a run that stopped, a plant that is not
/// independent torque axes, an axis the run does not excite enough.
///
/// ```no_run
/// let id = ringsync::identify::identify_run(std::path::Path::new("out/pd"))?;
/// for a in &id.axes {
///     println!("axis {}: H = {:.5} V·s²/rad", a.axis, a.id.h.value);
/// }
/// std::fs::write(
///     "id.toml",
///     ringsync::identify::identified_toml(&id, ringsync::identify::DOB_BANDWIDTH_HZ)?,
/// )?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn identify_run(dir: &Path) -> Result<Identification> {
    let text = read(dir, SCENARIO_FILE)?;
    let run = crate::parse(&text, &dir.join(SCENARIO_FILE).display().to_string())?;
    let s = &run.scenario;
    let summary: serde_json::Value = serde_json::from_str(&read(dir, "summary.json")?)
        .map_err(|e| Error::Input(format!("{}/summary.json: {e}", dir.display())))?;
    if let Some(t) = summary["faults"]["group_stop"]["time_s"].as_f64() {
        return Err(Error::Input(format!(
            "{}: the run ended in a group stop at {t} s; identify from a run that did not stop",
            dir.display()
        )));
    }
    if s.plant.arm().is_some() {
        return Err(Error::Input(
            "identify fits independent torque axes; this run's plant is the two-link arm"
                .to_string(),
        ));
    }
    let models = s
        .axis_models()
        .map_err(|(i, e)| Error::Input(format!("axis[{i}]: {e}")))?;
    let n = models.len();
    let Some(cycles) = summary["cycles"].as_u64() else {
        return Err(Error::Input(format!(
            "{}/summary.json holds no `cycles`: expected a run's summary.json from `ringsync sim` or `ringsync rt`",
            dir.display()
        )));
    };
    let trace = Trace::read(&dir.join("trace.csv"), n)?;
    if trace.t.len() as u64 != cycles {
        return Err(Error::Input(format!(
            "{}/trace.csv: {} cycles, where summary.json says {cycles}: a trace cut short or of another run",
            dir.display(),
            trace.t.len()
        )));
    }
    let mut axes = Vec::with_capacity(n);
    for (i, m) in models.iter().enumerate() {
        let AxisModel::Torque(ax) = m else {
            return Err(Error::Input(format!(
                "axis {}: identify fits torque-mode axes; this one is velocity-mode",
                i + 1
            )));
        };
        let spec = s
            .axis_spec(i)
            .ok_or_else(|| Error::Input("no [[axis]] table".into()))?;
        let resolution = std::f64::consts::TAU / 2f64.powi(spec.encoder_bits as i32);
        let col = &trace.axes[i];
        let id = identify_axis(&AxisRecord {
            t: &trace.t,
            x: &col.x,
            u: &col.u,
            apply_time: &col.apply_time,
            resolution,
            u_max: ax.u_max,
        })
        .map_err(|e| Error::Input(format!("axis {}: {e}", i + 1)))?;
        let kt = ax.torque_constant;
        axes.push(IdentifiedAxis {
            axis: i + 1,
            id,
            scenario: (
                ax.inertia / kt,
                ax.friction.viscous / kt,
                ax.friction.coulomb / kt,
            ),
        });
    }
    Ok(Identification { run, axes })
}

impl Identification {
    /// How well the fit knows each axis's feed-forward on the run's own motion: the 95 %
    /// interval of H·|ẍ^d| + C·|ẋ^d| + F at the motion's peaks, relative to its value
    /// (H_ci·A + C_ci·V + F_ci) / (H·A + C·V + F), the widest over the axes, with its axis.
    /// The model error the fit itself can see; unmodelled dynamics add to it.
    pub fn model_uncertainty(&self) -> (f64, usize) {
        let s = &self.run.scenario;
        let peaks: Vec<(f64, f64)> = match s.trajectories() {
            Ok(traj) => {
                let g = ringsync_control::GroupTrajectories::new(traj);
                let dur = s.duration.secs();
                let steps = 2000;
                (0..g.len())
                    .map(|i| {
                        (0..=steps).fold((0.0f64, 0.0f64), |(a, v), k| {
                            let d = g.at(i, dur * k as f64 / steps as f64);
                            (a.max(d.a.abs()), v.max(d.v.abs()))
                        })
                    })
                    .collect()
            }
            Err(_) => Vec::new(),
        };
        let mut worst = (0.0, 0);
        for (k, a) in self.axes.iter().enumerate() {
            let (acc, vel) = peaks.get(k).copied().unwrap_or((1.0, 1.0));
            let (h, c, f) = (a.id.h, a.id.c, a.id.f);
            let ff = h.value.abs() * acc + c.value.abs() * vel + f.value.abs();
            let ci = h.ci95 * acc + c.ci95 * vel + f.ci95;
            let rel = if ff > 0.0 { ci / ff } else { f64::INFINITY };
            if rel > worst.0 || rel.is_nan() {
                worst = (rel, a.axis);
            }
        }
        worst
    }

    /// A warning when the fit's intervals are wider than [`FEED_FORWARD_BREAK_EVEN`]: what
    /// feed-forward alone would then do, and whether the written scenario's observer
    /// (`dob_hz`, 0 for none) holds it.
    pub fn warning(&self, dob_hz: f64) -> Option<String> {
        let (rel, axis) = self.model_uncertainty();
        if rel <= FEED_FORWARD_BREAK_EVEN {
            return None;
        }
        let rel = if rel.is_finite() {
            format!("±{:.1} %", rel * 100.0)
        } else {
            "unbounded".to_string()
        };
        Some(format!(
            "warning: the feed-forward of axis {axis} (H·ẍ + C·ẋ + F at the motion's peaks) is known to {rel} (95 %): per-axis model errors above about {:.0} % make feed-forward alone worse than standard PD on Sync-RMSE; {}",
            FEED_FORWARD_BREAK_EVEN * 100.0,
            if dob_hz > 0.0 {
                format!(
                    "the written scenario's disturbance observer ({dob_hz} Hz) holds errors of ±30 % to a quarter of PD's Sync-RMSE"
                )
            } else {
                "consider a disturbance observer (--dob-bandwidth, default 20 Hz), which holds errors of ±30 % to a quarter of PD's Sync-RMSE".to_string()
            }
        ))
    }

    /// The estimates beside the scenario's values, as a Markdown table.
    pub fn text(&self) -> String {
        let rows: Vec<_> = self
            .axes
            .iter()
            .map(|a| (a.axis, a.id, a.scenario))
            .collect();
        let mut t = ringsync_report::identify::identify_text(&rows);
        for c in measurement_choices(&self.run.scenario) {
            t.push_str(&format!("The written scenario also sets {}\n", c.why));
        }
        t
    }
}

/// The run's scenario with the identified H, C, F as `control.kh`, `control.kc` and
/// `control.kf` (one value per axis; a negative F, which friction cannot be, becomes 0),
/// behind a header that gives every estimate with its interval. With `dob_hz` > 0 it adds a
/// disturbance observer of that bandwidth (`control.dob_bandwidth`), which cancels the
/// Coulomb friction itself, so `control.kf` is 0 ([`DOB_BANDWIDTH_HZ`] says why); an
/// observer the stability check cannot show stable on the scenario's ring is halved until
/// it can (down to 1 Hz), or left out, and the header says which.
pub fn identified_toml(id: &Identification, dob_hz: f64) -> Result<String> {
    if !(0.0..=1000.0).contains(&dob_hz) {
        return Err(Error::Input(format!(
            "--dob-bandwidth {dob_hz}: expected 0 (no observer) to 1000 Hz"
        )));
    }
    let mut hz = dob_hz;
    loop {
        let text = identified_toml_at(id, hz)?;
        if hz == 0.0 {
            return Ok(text);
        }
        let stable = crate::parse(&text, "identified scenario")
            .ok()
            .and_then(|l| crate::check(&l.scenario, 11).ok())
            .is_some_and(|r| r.verdict() == crate::Verdict::Stable);
        if stable {
            if hz == dob_hz {
                return Ok(text);
            }
            return Ok(format!(
                "# control.dob_bandwidth: {dob_hz} Hz is not shown stable on this ring by `ringsync check`; {hz} Hz is.\n{text}"
            ));
        }
        hz /= 2.0;
        if hz < 1.0 {
            let text = identified_toml_at(id, 0.0)?;
            return Ok(format!(
                "# control.dob_bandwidth: no observer from 1 to {dob_hz} Hz is shown stable on this ring by `ringsync check`: none written.\n{text}"
            ));
        }
    }
}

fn identified_toml_at(id: &Identification, dob_hz: f64) -> Result<String> {
    let mut table: toml::Table = toml::from_str(&id.run.text)
        .map_err(|e| Error::Failed(format!("the run's scenario: {e}")))?;
    let list = |f: &dyn Fn(&IdentifiedAxis) -> f64| {
        toml::Value::Array(id.axes.iter().map(|a| toml::Value::Float(f(a))).collect())
    };
    let control = table
        .entry("control")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .ok_or_else(|| Error::Failed("the run's scenario: control is not a table".into()))?;
    control.insert("kh".into(), list(&|a| a.id.h.value));
    control.insert("kc".into(), list(&|a| a.id.c.value));
    if dob_hz > 0.0 {
        control.insert("kf".into(), toml::Value::Float(0.0));
        control.insert("dob_bandwidth".into(), toml::Value::Float(dob_hz));
    } else {
        control.insert("kf".into(), list(&|a| a.id.f.value.max(0.0)));
    }
    let choices = measurement_choices(&id.run.scenario);
    for c in &choices {
        control.insert(c.key.into(), toml::Value::String(c.to.to_string()));
    }
    let body = toml::to_string(&table)
        .map_err(|e| Error::Failed(format!("cannot write the scenario: {e}")))?;
    let mut head = format!(
        "# Identified by `ringsync identify` from the run of {}: per axis H = J/K_a [V·s²/rad],\n\
         # C = b/K_a [V·s/rad] and F = T_c/K_a [V] (least squares on H·ẍ + C·ẋ + F·sgn(ẋ) = u,\n\
         # 95 % intervals), set as the feed-forward gains control.kh, control.kc and control.kf\n\
         # (every law adds K_H·ẍ^d + K_C·ẋ^d + K_F·sat(ẋ^d/kf_velocity)).\n",
        id.run.origin
    );
    for c in &choices {
        head.push_str(&format!("# {}\n", c.why));
    }
    if dob_hz > 0.0 {
        head.push_str(&format!(
            "# control.dob_bandwidth = {dob_hz} Hz with control.kf = 0: a disturbance observer through the\n\
             # identified H and C cancels what the model misses, the Coulomb friction included\n\
             # (feed-forward alone is only as good as the model is equal on every axis;\n\
             # `ringsync identify --dob-bandwidth 0` leaves it out and writes K_F = F).\n"
        ));
    }
    if let Some(w) = id.warning(dob_hz) {
        head.push_str(&format!("# {w}\n"));
    }
    for a in &id.axes {
        head.push_str(&format!(
            "#   axis {}: H = {:.6} ± {:.1e}, C = {:.3e} ± {:.1e}, F = {:.5} ± {:.1e}\n",
            a.axis, a.id.h.value, a.id.h.ci95, a.id.c.value, a.id.c.ci95, a.id.f.value, a.id.f.ci95
        ));
    }
    Ok(format!("{head}{body}"))
}

/// A setting of `[control]` that a compensated scenario should have when the run's differs.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// The key in `[control]`.
    pub key: &'static str,
    /// The value written.
    pub to: &'static str,
    /// Why, one line: `control.KEY: "from" -> "to": reason`.
    pub why: String,
}

/// The measurement settings a compensated scenario should use, where the run's differ. With
/// the axes cancelled by the feed-forward, what is left of the errors is mostly the encoder's
/// quantisation, so:
///
/// - **velocity**: the slave's velocity over its short window (`axis.velocity_window`) has a
///   quantum of one count per window where the difference of successive samples has one
///   count per cycle: `differenced`;
/// - **estimator**: extrapolating noise amplifies it (the paper's weights, eq. 12, sum to 5
///   in magnitude): a cycle that runs on last cycle's samples (a lumped frame lost or late)
///   then leaves an offset the slow pole K_P/K_D removes only over about a second, where
///   holding the samples leaves none (docs/experiments.md, experiment 6): `hold`.
pub fn measurement_choices(s: &ringsync_model::Scenario) -> Vec<Choice> {
    use ringsync_control::EstimatorKind;
    use ringsync_model::scenario::VelocityKind;
    let mut out = Vec::new();
    let Some(a) = s.axis_spec(0) else {
        return out;
    };
    let (window, cycle) = (a.velocity_window.secs(), s.ring.cycle.secs());
    if s.control.velocity == VelocityKind::Reported && window < cycle {
        let count = std::f64::consts::TAU / 2f64.powi(a.encoder_bits as i32);
        out.push(Choice {
            key: "velocity",
            to: "differenced",
            why: format!(
                "control.velocity: \"reported\" -> \"differenced\": one encoder count is {:.4} rad/s over the slave's {:.0} µs window, {:.4} rad/s over the {:.0} µs cycle.",
                count / window,
                window * 1e6,
                count / cycle,
                cycle * 1e6
            ),
        });
    }
    if s.control.estimator != EstimatorKind::Hold {
        out.push(Choice {
            key: "estimator",
            to: "hold",
            why: format!(
                "control.estimator: \"{}\" -> \"hold\": with the axes cancelled the errors left are encoder noise, which extrapolation amplifies; a cycle run on last cycle's samples (a lumped frame lost or late) then leaves an offset that takes about a second to die out.",
                s.control.estimator.name()
            ),
        });
    }
    out
}

/// The columns of a trace.csv that identification reads, per axis.
#[derive(Default)]
struct Column {
    x: Vec<f64>,
    u: Vec<f64>,
    apply_time: Vec<f64>,
}

struct Trace {
    t: Vec<f64>,
    axes: Vec<Column>,
}

impl Trace {
    /// Reads `trace.csv` of a run of `n` axes: one row per cycle and axis, axes in order.
    fn read(path: &Path, n: usize) -> Result<Trace> {
        let bad = |what: String| Error::Input(format!("{}: {what}", path.display()));
        let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
        let mut rd = csv::Reader::from_reader(ringsync_model::bounded::LineLimit::new(
            file,
            MAX_TRACE_LINE,
        ));
        let head = rd.headers().map_err(|e| bad(e.to_string()))?.clone();
        let col = |name: &str| {
            head.iter()
                .position(|h| h == name)
                .ok_or_else(|| bad(format!("no column {name}")))
        };
        let (ct, ca, cx, cu, cap) = (
            col("t_s")?,
            col("axis")?,
            col("x_rad")?,
            col("u_v")?,
            col("apply_time_s")?,
        );
        let mut tr = Trace {
            t: Vec::new(),
            axes: (0..n).map(|_| Column::default()).collect(),
        };
        for (k, rec) in rd.records().enumerate() {
            let rec = rec.map_err(|e| bad(e.to_string()))?;
            let num = |c: usize| -> Result<f64> {
                let v = rec.get(c).unwrap_or("");
                v.parse::<f64>()
                    .map_err(|_| bad(format!("row {}: '{v}' is not a number", k + 2)))
            };
            // Time, position and command are finite in a run that did not stop (the
            // application time may be unknown).
            let finite = |c: usize| -> Result<f64> {
                let x = num(c)?;
                if x.is_finite() {
                    Ok(x)
                } else {
                    Err(bad(format!(
                        "row {}, column {}: {x}, where a run that did not stop has a finite number",
                        k + 2,
                        &head[c]
                    )))
                }
            };
            let axis = num(ca)?;
            if axis != (k % n + 1) as f64 {
                return Err(bad(format!(
                    "row {}: axis {axis}, expected {} (rows of {n} axes in order)",
                    k + 2,
                    k % n + 1
                )));
            }
            let a = &mut tr.axes[k % n];
            if k % n == 0 {
                tr.t.push(finite(ct)?);
            }
            a.x.push(finite(cx)?);
            a.u.push(finite(cu)?);
            a.apply_time.push(num(cap)?);
        }
        if tr.axes.iter().any(|a| a.x.len() != tr.t.len()) {
            return Err(bad("the last cycle has fewer rows than axes".into()));
        }
        Ok(tr)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ringsync_control::identify::{AxisIdentification, Estimate};

    fn identification(h_ci: f64) -> Identification {
        let est = |value, ci95| Estimate { value, ci95 };
        let axes = (1..=4)
            .map(|axis| IdentifiedAxis {
                axis,
                id: AxisIdentification {
                    h: est(0.016, h_ci),
                    c: est(3e-4, 1e-4),
                    f: est(0.2, 1e-4),
                    windows: 95,
                    half_window: 0.02,
                    v_min: 0.3,
                    residual_v: 2e-4,
                },
                scenario: (0.016, 3e-4, 0.2),
            })
            .collect();
        Identification {
            run: crate::load("paper-2015").expect("built-in"),
            axes,
        }
    }

    /// The warning follows the feed-forward's own interval on the run's motion: the cosine
    /// of paper-2015 peaks at 15.12 rad/s and 47.5 rad/s², where H·ẍ = 0.76 V dominates.
    #[test]
    fn a_feed_forward_known_worse_than_the_break_even_is_warned_about() {
        let good = identification(1.6e-5);
        let (rel, _) = good.model_uncertainty();
        // (1.6e-5·47.5 + 1e-4·15.12 + 1e-4) / (0.016·47.5 + 3e-4·15.12 + 0.2) = 0.24 %.
        assert!((rel - 0.0024).abs() < 2e-4, "{rel}");
        assert_eq!(good.warning(20.0), None);
        let poor = identification(1e-3);
        let (rel, axis) = poor.model_uncertainty();
        assert!(rel > FEED_FORWARD_BREAK_EVEN && axis == 1, "{rel}");
        let w = poor.warning(20.0).expect("a warning");
        assert!(
            w.contains("known to ±5.") && w.contains("observer (20 Hz) holds"),
            "{w}"
        );
        let w = poor.warning(0.0).expect("a warning");
        assert!(w.contains("consider a disturbance observer"), "{w}");
    }
}
