//! Reproducing the paper's Table 1: standard PD, the sync controller and the ring-coupled
//! baseline on the proposed plan (P2P + lumped) and on the lumped-only plan of ref. \[3\],
//! each over several seeds (means, spreads and ranges beside the paper's single
//! measurement, and a verdict), the runs in parallel.

use ringsync_model::law::{pd, ring, sync};
use ringsync_model::{RunResult, Scenario};
use ringsync_proto::{CyclePlan, PlanKind};
use ringsync_report::repro::{ReproRow, repro_figures, repro_html, repro_json, repro_table};

use crate::error::{Error, Result};
use crate::output::OutDir;

/// A reproduction: one row per (plan, controller) with every seed's RMSEs, and the runs
/// of the first seed behind them.
#[derive(Debug, Clone)]
pub struct Reproduction {
    /// The base scenario.
    pub scenario: Scenario,
    /// Track-RMSE and Sync-RMSE per plan and controller, per seed.
    pub rows: Vec<ReproRow>,
    /// The first seed's runs in the rows' order (with traces for the figures' cases:
    /// standard PD and the sync controller on the proposed plan).
    pub runs: Vec<RunResult>,
    /// Why a case's run stopped, per row: `(seed, reason)` of every run that ended in a
    /// group stop.
    pub stops: Vec<Vec<(u64, String)>>,
}

/// The controllers of the reproduction by their registry names, in the table's order: the
/// paper's two and the literature's ring-coupled baseline.
const LAWS: [&str; 3] = [pd::ENTRY.name, sync::ENTRY.name, ring::ENTRY.name];

/// Seeds per case by default: enough for a standard deviation worth reading, 48 runs in all.
pub const DEFAULT_SEEDS: u32 = 8;

/// Most seeds per case [`reproduce_with`] takes.
pub const MAX_SEEDS: u32 = 10_000;

/// How to run a reproduction.
pub struct ReproOptions<'a> {
    /// Seeds per case: the scenario's seed, +1, … (1 to [`MAX_SEEDS`]).
    pub seeds: u32,
    /// Parallel runs (threads).
    pub jobs: usize,
    /// Called after each run with (runs done, runs in all).
    pub progress: &'a (dyn Fn(usize, usize) + Sync),
    /// The caller's stop flag (Ctrl-C): once it rises no run starts, those running end at
    /// their next cycle, and the reproduction is an [`crate::Error::Interrupted`].
    pub stop: Option<crate::Stop>,
}

impl Default for ReproOptions<'_> {
    fn default() -> Self {
        ReproOptions {
            seeds: DEFAULT_SEEDS,
            jobs: crate::sweep::default_jobs(),
            progress: &|_, _| {},
            stop: None,
        }
    }
}

/// One run of the reproduction: a case (plan, law) and a seed.
struct Job {
    row: usize,
    scenario: Scenario,
    trace: bool,
}

/// [`reproduce_with`] with the default options: [`DEFAULT_SEEDS`] seeds per case, on
/// every CPU.
///
/// ```
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(300);
/// let r = ringsync::reproduce(&s)?;
/// assert_eq!(r.rows.len(), 6);
/// assert!(r.rows.iter().all(|row| row.seeds.len() == 8));
/// assert!(r.table().contains("| proposed (P2P + lumped) | standard PD | 0.23267 |"));
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn reproduce(base: &Scenario) -> Result<Reproduction> {
    reproduce_with(base, &ReproOptions::default())
}

/// Runs the reproduction on `base` (its plan and law replaced case by case), each case
/// once per seed (`base.seed`, +1, …), `opts.jobs` runs at a time.
///
/// ```
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(300);
/// let opts = ringsync::ReproOptions { seeds: 2, ..Default::default() };
/// let r = ringsync::reproduce_with(&s, &opts)?;
/// assert_eq!(r.rows[0].seeds, vec![s.seed, s.seed + 1]);
/// let sd = r.rows[0].track().sd;
/// assert!(sd > 0.0, "two seeds draw other clocks: {sd}");
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn reproduce_with(base: &Scenario, opts: &ReproOptions<'_>) -> Result<Reproduction> {
    if !(1..=MAX_SEEDS).contains(&opts.seeds) {
        return Err(Error::Input(format!(
            "seeds = {}: expected 1 to {MAX_SEEDS} seeds per case",
            opts.seeds
        )));
    }
    let combos: Vec<(PlanKind, &'static str)> = [PlanKind::P2pLumped, PlanKind::LumpedOnly]
        .iter()
        .flat_map(|&p| LAWS.iter().map(move |&l| (p, l)))
        .collect();
    let seeds: Vec<u64> = (0..u64::from(opts.seeds))
        .map(|k| base.seed.wrapping_add(k))
        .collect();
    let mut jobs = Vec::with_capacity(combos.len() * seeds.len());
    for (row, &(plan, law)) in combos.iter().enumerate() {
        let mut s = base.clone();
        s.control.law = law.to_string();
        // The base's own law parameters belong to its law: keep those this one takes.
        let entry = ringsync_model::law::registry::find(law);
        s.control
            .params
            .retain(|k, _| entry.is_some_and(|e| e.param(k).is_some()));
        s.ring.plan = plan;
        for (k, &seed) in seeds.iter().enumerate() {
            let mut s = s.clone();
            s.seed = seed;
            jobs.push(Job {
                row,
                scenario: s,
                // The figures show the first seed's PD and sync runs on the proposed plan.
                trace: k == 0 && plan == PlanKind::P2pLumped && law != ring::ENTRY.name,
            });
        }
    }
    let results = crate::sweep::par_map(
        &jobs,
        opts.jobs,
        |j| {
            let o = crate::SimOptions {
                trace: j.trace,
                stop: opts.stop.clone(),
                ..Default::default()
            };
            crate::simulate(&j.scenario, &o)
        },
        opts.progress,
        opts.stop.as_ref(),
    );
    let mut rows: Vec<ReproRow> = combos
        .iter()
        .map(|&(plan, law)| ReproRow {
            plan: plan.name(),
            controller: law,
            seeds: seeds.clone(),
            track_rmse: Vec::with_capacity(seeds.len()),
            sync_rmse: Vec::with_capacity(seeds.len()),
        })
        .collect();
    let mut runs = Vec::with_capacity(combos.len());
    let mut stops = vec![Vec::new(); combos.len()];
    for (j, r) in jobs.iter().zip(results) {
        let r = r?;
        let row = &mut rows[j.row];
        row.track_rmse.push(r.summary.track_rmse);
        row.sync_rmse.push(r.summary.sync_rmse);
        if let Some((_, why)) = &r.group_stop {
            stops[j.row].push((j.scenario.seed, crate::sweep::stop_reason(why)));
        }
        if j.scenario.seed == seeds[0] {
            runs.push(r);
        }
    }
    Ok(Reproduction {
        scenario: base.clone(),
        rows,
        runs,
        stops,
    })
}

impl Reproduction {
    /// The paper's Table 1 beside ours, as Markdown.
    pub fn table(&self) -> String {
        repro_table(&self.rows)
    }

    /// The verdict in plain sentences (also at the end of [`Reproduction::table`]).
    pub fn verdict(&self) -> Vec<String> {
        ringsync_report::repro::verdict(&self.rows)
    }

    /// The cases with a run that ended in a group stop, e.g. `sync on p2p-lumped (seeds 3,
    /// 5: following-error)`.
    pub fn stopped(&self) -> Vec<String> {
        self.rows
            .iter()
            .zip(&self.stops)
            .filter(|(_, s)| !s.is_empty())
            .map(|(row, s)| {
                let seeds: Vec<String> = s.iter().map(|(k, _)| k.to_string()).collect();
                let mut why: Vec<&str> = s.iter().map(|(_, w)| w.as_str()).collect();
                why.dedup();
                format!(
                    "{} on {} (seed{} {}: {})",
                    row.controller,
                    row.plan,
                    if seeds.len() == 1 { "" } else { "s" },
                    seeds.join(", "),
                    why.join(", ")
                )
            })
            .collect()
    }
}

/// Writes a reproduction into `dir`: `summary.json` (a row per case with means, spreads
/// and every seed's values), `table.md` (the tables and the verdict), `report.html` and the
/// paper's figures (`fig*.svg`, the first seed's runs).
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
