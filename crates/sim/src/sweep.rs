//! Parameter sweeps: the Cartesian product of values of any scenario keys, several seeds
//! each, run in parallel (one single-threaded simulation per case).

use std::sync::atomic::{AtomicUsize, Ordering};

use serde::Deserialize;

use ringsync_model::RunResult;

use crate::run::{RunOptions, run};
use ringsync_model::scenario::{Dur, ECHO_CHARS, Scenario, ScenarioError, clip, clip_middle};

/// One swept key and its values, from `key=v1,v2,…`.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepAxis {
    /// Dotted scenario key, e.g. `faults.loss`.
    pub key: String,
    /// The values as written (TOML values; bare words are strings).
    pub values: Vec<String>,
}

impl std::str::FromStr for SweepAxis {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (key, values) = s
            .split_once('=')
            .ok_or_else(|| format!("'{s}' is not KEY=V1,V2,…: e.g. faults.loss=0,0.01,0.02"))?;
        let key = key.trim();
        if key.is_empty()
            || !key
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
        {
            return Err(format!("'{key}' is not a scenario key like ring.slaves"));
        }
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if values.is_empty() {
            return Err(format!("'{s}' gives no values"));
        }
        Ok(SweepAxis {
            key: key.to_string(),
            values,
        })
    }
}

/// One case of a sweep.
#[derive(Debug, Clone)]
pub struct Case {
    /// (key, value) for every swept key.
    pub labels: Vec<(String, String)>,
    /// The seed.
    pub seed: u64,
    /// The scenario to run.
    pub scenario: Scenario,
}

/// Parses `v` as a TOML value; a bare word is taken as a string.
fn toml_value(v: &str) -> toml::Value {
    toml::from_str::<toml::Table>(&format!("x = {v}"))
        .ok()
        .and_then(|mut t| t.remove("x"))
        .unwrap_or_else(|| toml::Value::String(v.to_string()))
}

fn set(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ScenarioError> {
    let mut parts: Vec<&str> = key.split('.').collect();
    let last = parts.pop().unwrap_or(key);
    let mut t = table;
    for p in parts {
        let entry = t
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = entry
            .as_table_mut()
            .ok_or_else(|| ScenarioError::OutOfRange {
                key: key.to_string(),
                value: "?".into(),
                allowed: format!("a key inside a table; {p} is not a table"),
            })?;
    }
    t.insert(last.to_string(), value);
    Ok(())
}

/// Every case: each combination of values, `seeds` seeds each (the scenario's seed, +1, …).
/// With `auto_cycle`, a case whose cycle is too short for its ring gets the shortest cycle
/// that holds it, plus 10 %, rounded up to 100 µs.
pub fn cases(
    base_text: &str,
    origin: &str,
    axes: &[SweepAxis],
    seeds: u32,
    auto_cycle: bool,
) -> Result<Vec<Case>, ScenarioError> {
    let base: toml::Table = toml::from_str(base_text).map_err(|e| ScenarioError::Syntax {
        origin: clip(origin, ECHO_CHARS).into_owned(),
        message: clip_middle(e.message().trim(), 2 * ECHO_CHARS).replace('\n', " "),
    })?;
    let mut combos: Vec<Vec<(String, String)>> = vec![Vec::new()];
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
        let mut t = base.clone();
        for (k, v) in &labels {
            set(&mut t, k, toml_value(v))?;
        }
        let mut s =
            Scenario::deserialize(toml::Value::Table(t)).map_err(|e| ScenarioError::Syntax {
                origin: clip(
                    &format!(
                        "{origin} with {}",
                        labels
                            .iter()
                            .map(|(k, v)| format!("{k}={v}"))
                            .collect::<Vec<_>>()
                            .join(" ")
                    ),
                    2 * ECHO_CHARS,
                )
                .into_owned(),
                message: clip_middle(e.message().trim(), 2 * ECHO_CHARS).replace('\n', " "),
            })?;
        if auto_cycle {
            let mut p = s.ring_params();
            p.t_cyc = ringsync_proto::Duration::from_ms(10_000);
            if let Ok(plan) = ringsync_proto::CyclePlan::new(&p) {
                let need = match s.ring.plan {
                    ringsync_proto::PlanKind::P2pLumped => plan.min_t_cyc.max(plan.event.min_t_cyc),
                    ringsync_proto::PlanKind::LumpedOnly => plan.lumped_only.min_t_cyc,
                };
                if need > s.ring.cycle.0 {
                    let ns = need.as_ns() + need.as_ns() / 10;
                    s.ring.cycle = Dur(ringsync_proto::Duration::from_ns(
                        (ns / 100_000 + 1) * 100_000,
                    ));
                }
            }
        }
        s.validate()?;
        for k in 0..u64::from(seeds.max(1)) {
            let mut sc = s.clone();
            sc.seed = s.seed.wrapping_add(k);
            out.push(Case {
                labels: labels.clone(),
                seed: sc.seed,
                scenario: sc,
            });
        }
    }
    Ok(out)
}

/// Runs every case on `threads` threads; results in case order. `progress` is called with
/// (done, total) after each case.
pub fn run_all(
    cases: &[Case],
    threads: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Vec<Result<RunResult, String>> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let mut results: Vec<Option<Result<RunResult, String>>> =
        (0..cases.len()).map(|_| None).collect();
    let slots: Vec<std::sync::Mutex<Option<Result<RunResult, String>>>> = (0..cases.len())
        .map(|_| std::sync::Mutex::new(None))
        .collect();
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1).min(cases.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= cases.len() {
                        break;
                    }
                    let r =
                        run(&cases[i].scenario, RunOptions::default()).map_err(|e| e.to_string());
                    if let Ok(mut slot) = slots[i].lock() {
                        *slot = Some(r);
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, cases.len());
                }
            });
        }
    });
    for (r, slot) in results.iter_mut().zip(slots) {
        *r = slot.into_inner().ok().flatten();
    }
    results
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err("not run".into())))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let text = crate::builtin("paper-2015").expect("builtin");
        let axes: Vec<SweepAxis> = ["control.estimator=hold,paper", "faults.loss=0,0.02"]
            .iter()
            .map(|s| s.parse().expect("axis"))
            .collect();
        let c = cases(text, "paper-2015", &axes, 2, false).expect("cases");
        assert_eq!(c.len(), 2 * 2 * 2);
        assert_eq!(
            c[0].labels,
            vec![
                ("control.estimator".into(), "hold".into()),
                ("faults.loss".into(), "0".into())
            ]
        );
        assert_eq!((c[0].seed, c[1].seed), (1, 2));
        assert_eq!(c[7].scenario.faults.loss, 0.02);
        assert_eq!(
            c[7].scenario.control.estimator,
            ringsync_control::EstimatorKind::Paper
        );
    }

    #[test]
    fn bad_keys_and_values_are_errors() {
        let text = crate::builtin("paper-2015").expect("builtin");
        let bad = |s: &str| {
            cases(text, "p", &[s.parse().expect("axis")], 1, false)
                .expect_err("bad")
                .to_string()
        };
        assert!(bad("faults.lost=0.1").contains("lost"));
        assert!(bad("faults.loss=2").contains("faults.loss = 2"));
        assert!(bad("ring.slaves=64").contains("ring.cycle"));
        // With --auto-cycle the ring gets a cycle that holds it.
        let c = cases(
            text,
            "p",
            &["ring.slaves=64".parse().expect("axis")],
            1,
            true,
        )
        .expect("auto");
        assert!(c[0].scenario.ring.cycle.0 > ringsync_proto::Duration::from_ms(8));
    }

    #[test]
    fn runs_in_parallel_in_order() {
        let text = "duration = \"100ms\"\n";
        let c = cases(
            text,
            "t",
            &["control.law=pd,sync".parse().expect("axis")],
            1,
            false,
        )
        .expect("cases");
        let r = run_all(&c, 2, &|_, _| {});
        assert_eq!(r.len(), 2);
        let (pd, sync) = (r[0].as_ref().expect("pd"), r[1].as_ref().expect("sync"));
        let solo = run(&c[1].scenario, RunOptions::default()).expect("run");
        assert_eq!(sync.summary, solo.summary);
        assert_ne!(pd.summary, sync.summary);
    }
}
