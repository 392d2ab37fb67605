//! `ringsync sim` and `ringsync reproduce`.

use std::path::{Path, PathBuf};
use std::time::Instant as WallClock;

use anyhow::Context as _;
use clap::Args;
use ringsync_report::sim::{
    ReproRow, repro_figures, repro_html, repro_json, repro_table, summary_json, trace_csv,
};
use ringsync_sim::run::{RunError, RunOptions, run};
use ringsync_sim::scenario::{LawKind, Scenario};

use crate::scenario_cmd::usage;
use crate::{CliError, out};

/// Options of `ringsync sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// Scenario file or built-in name (see `ringsync scenario list`).
    scenario: String,
    /// Directory for summary.json and trace.csv (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Seed for every random draw, instead of the scenario's.
    #[arg(long)]
    seed: Option<u64>,
}

fn run_error(e: RunError) -> CliError {
    match e {
        RunError::Scenario(e) => usage(e),
        RunError::Unsupported(m) => CliError::Usage(m),
    }
}

fn write(dir: &Path, name: &str, text: &str) -> Result<(), CliError> {
    let p = dir.join(name);
    std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))?;
    Ok(())
}

fn create(dir: &Path) -> Result<(), CliError> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(())
}

pub(crate) fn sim(args: &SimArgs) -> Result<(), CliError> {
    let (mut s, hash) = Scenario::load_with_hash(&args.scenario).map_err(usage)?;
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    create(&args.out)?;
    let wall = WallClock::now();
    let r = run(
        &s,
        RunOptions {
            trace: true,
            ..RunOptions::default()
        },
    )
    .map_err(run_error)?;
    let elapsed = wall.elapsed();
    let summary = summary_json(&s, hash, &r);
    let text = serde_json::to_string_pretty(&summary).context("cannot format JSON")?;
    write(&args.out, "summary.json", &format!("{text}\n"))?;
    write(&args.out, "trace.csv", &trace_csv(&r))?;
    out(&format!(
        "{}: {} cycles of {} axes, {} controller, estimator {}\n  Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad\n  frames: {} sent by the master, {} lost, {} retried; clock error ≤ {:.0} ns\n  {}\n  wrote {}/summary.json and trace.csv in {:.1} ms\n",
        s.name,
        r.cycles,
        s.axes_count(),
        s.control.law.name(),
        s.control.estimator.name(),
        r.summary.track_rmse,
        r.summary.sync_rmse,
        r.master.frames_sent,
        r.links.lost,
        r.master.retries,
        r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        match r.group_stop {
            Some((t, reason)) => format!("GROUP STOP at {t:.3} s: {reason:?}"),
            None => "no group stop".to_string(),
        },
        args.out.display(),
        elapsed.as_secs_f64() * 1e3
    ))
}

/// Options of `ringsync reproduce`.
#[derive(Args, Debug)]
pub struct ReproduceArgs {
    /// Directory for summary.json and table.md (created if missing).
    #[arg(long, value_name = "DIR", default_value = "out/reproduce")]
    out: PathBuf,
    /// Scenario to reproduce (default: the built-in paper-2015).
    #[arg(long, default_value = "paper-2015")]
    scenario: String,
}

pub(crate) fn reproduce(args: &ReproduceArgs) -> Result<(), CliError> {
    let base = Scenario::load(&args.scenario).map_err(usage)?;
    create(&args.out)?;
    let wall = WallClock::now();
    let laws = [LawKind::Pd, LawKind::Sync, LawKind::RingCoupled];
    // One single-threaded simulation per case, the cases in parallel.
    let results: Vec<Result<(ReproRow, ringsync_sim::RunResult), CliError>> =
        std::thread::scope(|scope| {
            let handles: Vec<_> = laws
                .iter()
                .map(|&law| {
                    let mut s = base.clone();
                    s.control.law = law;
                    scope.spawn(move || {
                        let r = run(
                            &s,
                            RunOptions {
                                trace: law != LawKind::RingCoupled,
                                ..RunOptions::default()
                            },
                        )
                        .map_err(run_error)?;
                        let row = ReproRow {
                            plan: s.ring.plan.name(),
                            controller: law.name(),
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
                    h.join().unwrap_or_else(|_| {
                        Err(CliError::Failure(anyhow::anyhow!(
                            "a simulation thread panicked"
                        )))
                    })
                })
                .collect()
        });
    let done = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let rows: Vec<ReproRow> = done.iter().map(|(row, _)| row.clone()).collect();
    let table = repro_table(&rows);
    let plan = ringsync_proto::CyclePlan::new(&base.ring_params()).ok();
    let timing = plan.as_ref().and_then(ringsync_report::timing_svg);
    let figures = repro_figures(timing, &done[0].1, &done[1].1);
    for (name, svg) in &figures {
        write(&args.out, name, svg)?;
    }
    write(
        &args.out,
        "report.html",
        &repro_html(&base, &rows, &figures),
    )?;
    let json = serde_json::to_string_pretty(&repro_json(&rows)).context("cannot format JSON")?;
    write(&args.out, "summary.json", &format!("{json}\n"))?;
    write(
        &args.out,
        "table.md",
        &format!(
            "# Table 1 of Huang et al. (2015) beside ringsync's `{}`\n\n{table}",
            base.name
        ),
    )?;
    out(&format!(
        "Scenario {} ({} axes, {} s, estimator {}), Table 1 [rad]:\n\n{table}\nAssumptions of the scenario: scenarios/{}.toml; of the simulator: summary.json of `ringsync sim`.\nWrote {}/summary.json, table.md, report.html and the figures (fig*.svg) in {:.1} ms.\n",
        base.name,
        base.axes_count(),
        base.duration.secs(),
        base.control.estimator.name(),
        base.name,
        args.out.display(),
        wall.elapsed().as_secs_f64() * 1e3
    ))
}
