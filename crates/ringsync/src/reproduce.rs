//! Reproducing the paper's Table 1: standard PD, the sync controller and the ring-coupled
//! baseline on the proposed plan (P2P + lumped) and on the lumped-only plan of ref. [3],
//! one simulation per case, the cases in parallel.

use ringsync_model::law::{pd, ring, sync};
use ringsync_model::{RunResult, Scenario};
use ringsync_proto::{CyclePlan, PlanKind};
use ringsync_report::sim::{ReproRow, repro_figures, repro_html, repro_json, repro_table};

use crate::error::{Error, Result};
use crate::output::OutDir;

/// A reproduction: one row per (plan, controller), and the runs behind them.
#[derive(Debug, Clone)]
pub struct Reproduction {
    /// The base scenario.
    pub scenario: Scenario,
    /// Track-RMSE and Sync-RMSE per plan and controller.
    pub rows: Vec<ReproRow>,
    /// The runs in the rows' order (with traces for the figures' cases: standard PD and the
    /// sync controller on the proposed plan).
    pub runs: Vec<RunResult>,
}

/// The controllers of the reproduction by their registry names, in the table's order: the
/// paper's two and the literature's ring-coupled baseline.
const LAWS: [&str; 3] = [pd::ENTRY.name, sync::ENTRY.name, ring::ENTRY.name];

/// Runs the reproduction on `base` (its plan and law replaced case by case), on as many
/// threads as cases.
///
/// ```
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(300);
/// let r = ringsync::reproduce(&s)?;
/// assert_eq!(r.rows.len(), 6);
/// assert!(r.table().contains("| standard PD |"));
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn reproduce(base: &Scenario) -> Result<Reproduction> {
    let combos: Vec<(PlanKind, &str)> = [PlanKind::P2pLumped, PlanKind::LumpedOnly]
        .iter()
        .flat_map(|&p| LAWS.iter().map(move |&l| (p, l)))
        .collect();
    let done: Vec<Result<(ReproRow, RunResult)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = combos
            .iter()
            .map(|&(plan, law)| {
                let mut s = base.clone();
                s.control.law = law.to_string();
                // The base's own law parameters belong to its law: keep those this one takes.
                let entry = ringsync_model::law::registry::find(law);
                s.control
                    .params
                    .retain(|k, _| entry.is_some_and(|e| e.param(k).is_some()));
                s.ring.plan = plan;
                let trace = plan == PlanKind::P2pLumped && law != ring::ENTRY.name;
                scope.spawn(move || {
                    let opts = crate::SimOptions {
                        trace,
                        ..Default::default()
                    };
                    let r = crate::simulate(&s, &opts)?;
                    let row = ReproRow {
                        plan: plan.name(),
                        controller: law,
                        track_rmse: r.summary.track_rmse,
                        sync_rmse: r.summary.sync_rmse,
                    };
                    Ok((row, r))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(Error::Failed("a simulation thread panicked".into())))
            })
            .collect()
    });
    let (rows, runs) = done
        .into_iter()
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    Ok(Reproduction {
        scenario: base.clone(),
        rows,
        runs,
    })
}

impl Reproduction {
    /// The paper's Table 1 beside ours, as Markdown.
    pub fn table(&self) -> String {
        repro_table(&self.rows)
    }

    /// The cases that ended in a group stop, e.g. `sync on p2p-lumped`.
    pub fn stopped(&self) -> Vec<String> {
        self.rows
            .iter()
            .zip(&self.runs)
            .filter(|(_, r)| r.group_stop.is_some())
            .map(|(row, _)| format!("{} on {}", row.controller, row.plan))
            .collect()
    }
}

/// Writes a reproduction into `dir`: `summary.json`, `table.md`, `report.html` and the
/// paper's figures (`fig*.svg`).
pub fn write_reproduction(dir: &OutDir, r: &Reproduction) -> Result<()> {
    let base = &r.scenario;
    let timing = CyclePlan::new(&base.ring_params())
        .ok()
        .and_then(|p| ringsync_report::timing_svg(&p));
    let figures = repro_figures(timing, &r.runs[0], &r.runs[1]);
    for (name, svg) in &figures {
        dir.write(name, svg)?;
    }
    dir.write("report.html", repro_html(base, &r.rows, &figures))?;
    let json = serde_json::to_string_pretty(&repro_json(&r.rows))?;
    dir.write("summary.json", format!("{json}\n"))?;
    dir.write(
        "table.md",
        format!(
            "# Table 1 of Huang et al. (2015) beside ringsync's `{}`\n\n{}",
            base.name,
            r.table()
        ),
    )?;
    Ok(())
}
