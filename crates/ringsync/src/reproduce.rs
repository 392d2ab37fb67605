//! Reproducing the paper's Table 1: standard PD, the sync controller and the ring-coupled
//! baseline on the proposed plan (P2P + lumped) and on the lumped-only plan of ref. \[3\],
//! each over several seeds (means, spreads and ranges beside the paper's single
//! measurement, and a verdict), the runs in parallel.

use ringsync_model::law::{pd, ring, sync};
use ringsync_model::{RunResult, Scenario};
use ringsync_proto::{CyclePlan, PlanKind};
use ringsync_report::repro::{
    BENCH_SPREAD, BenchRows, ReproRow, repro_figures, repro_html, repro_json, repro_table,
};

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
    /// The bench experiment: standard PD and the sync controller on the lumped-only plan
    /// with the spread of the axes' J/K_a widened ([`bench_scenario`]); `None` when the
    /// axes' J/K_a are all equal (no spread to widen).
    pub bench: Option<BenchRows>,
}

/// `s` with each axis table's J/K_a moved `spread` times as far from the tables' mean:
/// the bench experiment of [`reproduce_with`] (docs/simulator.md, "The plan comparison");
/// `None` when every table has the same J/K_a.
///
/// ```
/// let s = ringsync::load("paper-2015")?.scenario;
/// let b = ringsync::reproduce::bench_scenario(&s, 2.0).expect("the axes differ");
/// let mean = |s: &ringsync::Scenario| s.axis.iter().map(|a| a.j_over_ka).sum::<f64>() / 4.0;
/// assert!((mean(&b) - mean(&s)).abs() < 1e-15);
/// assert!((b.axis[0].j_over_ka - mean(&s) - 2.0 * (s.axis[0].j_over_ka - mean(&s))).abs() < 1e-15);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn bench_scenario(s: &Scenario, spread: f64) -> Option<Scenario> {
    let j: Vec<f64> = s.axis.iter().map(|a| a.j_over_ka).collect();
    let (lo, hi) = j
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mean = j.iter().sum::<f64>() / j.len() as f64;
    let mut b = s.clone();
    for a in &mut b.axis {
        a.j_over_ka = mean + spread * (a.j_over_ka - mean);
        if a.j_over_ka.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
    }
    Some(b)
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
    // The bench experiment: PD and sync on the lumped-only plan of the widened bench, rows
    // after the table's.
    let bench = bench_scenario(base, BENCH_SPREAD);
    if let Some(b) = &bench {
        for (k, law) in [pd::ENTRY.name, sync::ENTRY.name].into_iter().enumerate() {
            let mut s = b.clone();
            s.control.law = law.to_string();
            let entry = ringsync_model::law::registry::find(law);
            s.control
                .params
                .retain(|k, _| entry.is_some_and(|e| e.param(k).is_some()));
            s.ring.plan = PlanKind::LumpedOnly;
            for &seed in &seeds {
                let mut s = s.clone();
                s.seed = seed;
                jobs.push(Job {
                    row: combos.len() + k,
                    scenario: s,
                    trace: false,
                });
            }
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
        .copied()
        .chain(bench.iter().flat_map(|_| {
            [
                (PlanKind::LumpedOnly, pd::ENTRY.name),
                (PlanKind::LumpedOnly, sync::ENTRY.name),
            ]
        }))
        .map(|(plan, law)| ReproRow {
            plan: plan.name(),
            controller: law,
            seeds: seeds.clone(),
            track_rmse: Vec::with_capacity(seeds.len()),
            sync_rmse: Vec::with_capacity(seeds.len()),
        })
        .collect();
    let mut runs = Vec::with_capacity(combos.len());
    let mut stops = vec![Vec::new(); rows.len()];
    for (j, r) in jobs.iter().zip(results) {
        let r = r?;
        let row = &mut rows[j.row];
        row.track_rmse.push(r.summary.track_rmse);
        row.sync_rmse.push(r.summary.sync_rmse);
        if let Some((_, why)) = &r.group_stop {
            stops[j.row].push((j.scenario.seed, crate::sweep::stop_reason(why)));
        }
        if j.scenario.seed == seeds[0] && j.row < combos.len() {
            runs.push(r);
        }
    }
    let bench = if rows.len() > combos.len() {
        let sync = rows.pop();
        let pd = rows.pop();
        pd.zip(sync).map(|(pd, sync)| BenchRows {
            spread: BENCH_SPREAD,
            pd,
            sync,
        })
    } else {
        None
    };
    Ok(Reproduction {
        scenario: base.clone(),
        rows,
        runs,
        stops,
        bench,
    })
}

impl Reproduction {
    /// The paper's Table 1 beside ours, as Markdown.
    pub fn table(&self) -> String {
        repro_table(&self.rows, self.bench.as_ref())
    }

    /// The paper's claims, each beside ours with a verdict.
    pub fn claims(&self) -> Vec<ringsync_report::repro::Claim> {
        ringsync_report::repro::claims(&self.rows, self.bench.as_ref())
    }

    /// The verdict in plain sentences (also at the end of [`Reproduction::table`]).
    pub fn verdict(&self) -> Vec<String> {
        ringsync_report::repro::verdict(&self.rows, self.bench.as_ref())
    }

    /// The cases with a run that ended in a group stop, e.g. `sync on p2p-lumped (seeds 3,
    /// 5: following-error)`.
    pub fn stopped(&self) -> Vec<String> {
        self.rows
            .iter()
            .chain(self.bench.iter().flat_map(|b| [&b.pd, &b.sync]))
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

/// Writes a reproduction into `dir`: `summary.json` (the paper's claims with ours and a
/// verdict each, a case per (plan, controller) with means, sample standard deviations,
/// ranges and every seed's values, the reductions, the bench experiment, provenance;
/// [`ringsync_report::repro::ReproSummary`]), `table.md` (the tables and the verdict), `report.html` and the
/// paper's figures (`fig*.svg`, the first seed's runs).
pub fn write_reproduction(dir: &OutDir, r: &Reproduction) -> Result<()> {
    let base = &r.scenario;
    let timing = CyclePlan::new(&base.ring_params())
        .ok()
        .and_then(|p| ringsync_report::timing_svg(&p, PlanKind::P2pLumped, None));
    let figures = repro_figures(timing, &r.runs[0], &r.runs[1]);
    for (name, svg) in &figures {
        dir.write(name, svg)?;
    }
    dir.write(
        "report.html",
        repro_html(base, &r.rows, r.bench.as_ref(), &figures),
    )?;
    let json = serde_json::to_string_pretty(&repro_json(&base.name, &r.rows, r.bench.as_ref()))?;
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
