//! `ringsync sim` and `ringsync reproduce`.

use std::path::{Path, PathBuf};
use std::time::Instant as WallClock;

use anyhow::Context as _;
use clap::Args;
use ringsync_model::law::{pd, ring, sync};
use ringsync_model::scenario::Scenario;
use ringsync_report::sim::{
    ReproRow, repro_figures, repro_html, repro_json, repro_table, summary_json, trace_csv,
};
use ringsync_sim::run::{RunError, RunOptions, run};

use crate::output::OutDir;
use crate::scenario_cmd::usage;
use crate::{CliError, Outcome, out};

/// Options of `ringsync sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// Scenario file or built-in name (see `ringsync scenario list`).
    scenario: String,
    /// Directory for summary.json, trace.csv, report.html and the figures; replaced as a
    /// whole when the run ends (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Seed for every random draw, instead of the scenario's.
    #[arg(long)]
    seed: Option<u64>,
    /// Also write every frame the nodes send, with its simulated send time, as pcapng.
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
}

fn run_error(e: RunError) -> CliError {
    match e {
        RunError::Scenario(e) => usage(e),
        RunError::Unsupported(m) => CliError::Usage(m),
    }
}

/// The results directory for `--out`, which must not hold the scenario file: it is replaced.
pub(crate) fn out_dir(out: &Path, scenario: &str) -> Result<OutDir, CliError> {
    let dir = OutDir::create("--out", out)?;
    if ringsync_model::builtin(scenario).is_none() {
        dir.keep_out(Path::new(scenario))?;
    }
    Ok(dir)
}

/// Runs `ringsync sim`: exit status 3 when the run ends in a group stop.
pub(crate) fn sim(args: &SimArgs) -> Result<Outcome, CliError> {
    let (mut s, hash) = Scenario::load_with_hash(&args.scenario).map_err(usage)?;
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    let mut dir = out_dir(&args.out, &args.scenario)?;
    let wall = WallClock::now();
    let opts = RunOptions {
        trace: true,
        capture: args.pcap.is_some(),
        ..RunOptions::default()
    };
    // A progress line on a terminal once the run has taken more than a second.
    let tty = {
        use std::io::IsTerminal as _;
        std::io::stderr().is_terminal()
    };
    let mut shown = false;
    let cycle_s = s.ring.cycle.secs();
    let mut progress = |done: i64, total: i64| {
        if tty && wall.elapsed().as_secs_f64() > 1.0 {
            shown = true;
            eprint!(
                "\r  simulated {:.1} s of {:.1} s ({:.0} %)",
                done as f64 * cycle_s,
                total as f64 * cycle_s,
                100.0 * done as f64 / total.max(1) as f64
            );
        }
    };
    let r = ringsync_sim::run_with_progress(&s, opts, &mut progress).map_err(run_error)?;
    if shown {
        eprintln!();
    }
    let elapsed = wall.elapsed();
    if let Some(p) = &args.pcap {
        dir.write_file(
            p,
            ringsync_report::pcap::pcapng(&r.captured, s.axes_count()),
        )?;
    }
    let summary = summary_json(&s, hash, &r);
    let text = serde_json::to_string_pretty(&summary).context("cannot format JSON")?;
    dir.write("summary.json", format!("{text}\n"))?;
    dir.write("trace.csv", trace_csv(&r))?;
    let timing = match s.ring.plan {
        ringsync_proto::PlanKind::P2pLumped => ringsync_proto::CyclePlan::new(&s.ring_params())
            .ok()
            .and_then(|p| ringsync_report::timing_svg(&p)),
        ringsync_proto::PlanKind::LumpedOnly => None,
    };
    let figures = ringsync_report::sim::run_figures(timing, &r);
    for (name, svg) in &figures {
        dir.write(name, svg)?;
    }
    dir.write(
        "report.html",
        ringsync_report::sim::run_html(&s, hash, &r, &figures),
    )?;
    dir.commit()?;
    out(&format!(
        "{}: {} cycles of {} axes, {} controller, estimator {}\n  Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad\n  frames: {} sent by the master, {} lost, {} retried; clock error ≤ {:.0} ns\n  {}\n  wrote {}/summary.json, trace.csv, report.html and the figures (*.svg) in {:.1} ms\n",
        s.name,
        r.cycles,
        s.axes_count(),
        s.law_name(),
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
    ))?;
    Ok(Outcome::flagged_if(r.group_stop.is_some()))
}

/// Options of `ringsync reproduce`.
#[derive(Args, Debug)]
pub struct ReproduceArgs {
    /// Directory for summary.json, table.md, report.html and the figures; replaced as a
    /// whole when the run ends (created if missing).
    #[arg(long, value_name = "DIR", default_value = "out/reproduce")]
    out: PathBuf,
    /// Scenario to reproduce (default: the built-in paper-2015).
    #[arg(long, default_value = "paper-2015")]
    scenario: String,
}

/// Runs `ringsync reproduce`: exit status 3 when any case ends in a group stop.
pub(crate) fn reproduce(args: &ReproduceArgs) -> Result<Outcome, CliError> {
    let base = Scenario::load(&args.scenario).map_err(usage)?;
    let dir = out_dir(&args.out, &args.scenario)?;
    let wall = WallClock::now();
    // Table 1's two controllers and the literature baseline, by their registry names.
    let laws = [pd::ENTRY.name, sync::ENTRY.name, ring::ENTRY.name];
    let plans = [
        ringsync_proto::PlanKind::P2pLumped,
        ringsync_proto::PlanKind::LumpedOnly,
    ];
    let combos: Vec<(ringsync_proto::PlanKind, &str)> = plans
        .iter()
        .flat_map(|&p| laws.iter().map(move |&l| (p, l)))
        .collect();
    // One single-threaded simulation per case, the cases in parallel.
    let results: Vec<Result<(ReproRow, ringsync_model::RunResult), CliError>> =
        std::thread::scope(|scope| {
            let handles: Vec<_> = combos
                .iter()
                .map(|&(plan, law)| {
                    let mut s = base.clone();
                    s.control.law = law.to_string();
                    s.ring.plan = plan;
                    let figures =
                        plan == ringsync_proto::PlanKind::P2pLumped && law != ring::ENTRY.name;
                    scope.spawn(move || {
                        let r = run(
                            &s,
                            RunOptions {
                                trace: figures,
                                ..RunOptions::default()
                            },
                        )
                        .map_err(run_error)?;
                        let row = ReproRow {
                            plan: s.ring.plan.name(),
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
        dir.write(name, svg)?;
    }
    dir.write("report.html", repro_html(&base, &rows, &figures))?;
    let json = serde_json::to_string_pretty(&repro_json(&rows)).context("cannot format JSON")?;
    dir.write("summary.json", format!("{json}\n"))?;
    dir.write(
        "table.md",
        format!(
            "# Table 1 of Huang et al. (2015) beside ringsync's `{}`\n\n{table}",
            base.name
        ),
    )?;
    dir.commit()?;
    let stopped: Vec<String> = done
        .iter()
        .filter(|(_, r)| r.group_stop.is_some())
        .map(|(row, _)| format!("{} on {}", row.controller, row.plan))
        .collect();
    out(&format!(
        "Scenario {} ({} axes, {} s, estimator {}), Table 1 [rad]:\n\n{table}\nAssumptions of the scenario: scenarios/{}.toml; of the simulator: summary.json of `ringsync sim`.\nWrote {}/summary.json, table.md, report.html and the figures (fig*.svg) in {:.1} ms.\n",
        base.name,
        base.axes_count(),
        base.duration.secs(),
        base.control.estimator.name(),
        base.name,
        args.out.display(),
        wall.elapsed().as_secs_f64() * 1e3
    ))?;
    if !stopped.is_empty() {
        out(&format!("GROUP STOP in {}\n", stopped.join(", ")))?;
    }
    Ok(Outcome::flagged_if(!stopped.is_empty()))
}

/// The (key, value) pairs that name one case of a sweep.
type Labels = Vec<(String, String)>;

/// Options of `ringsync sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Scenario file or built-in name: the base of every case.
    scenario: String,
    /// A key and its values, e.g. `faults.loss=0,0.01,0.02`; several give their product.
    #[arg(long = "set", value_name = "KEY=V1,V2,…", required = true)]
    set: Vec<ringsync_sim::sweep::SweepAxis>,
    /// Seeds per case (the scenario's seed, +1, …); means are over them.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    seeds: u32,
    /// Give each case whose cycle is too short for its ring the shortest cycle that holds it (+10 %).
    #[arg(long)]
    auto_cycle: bool,
    /// Directory for sweep.csv, means.csv and sweep.svg; replaced as a whole when the sweep
    /// ends (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Parallel simulations (default: the number of CPUs).
    #[arg(long)]
    jobs: Option<usize>,
}

/// Runs `ringsync sweep`: exit status 3 when any case ends in a group stop.
pub(crate) fn sweep(args: &SweepArgs) -> Result<Outcome, CliError> {
    use std::fmt::Write as _;
    use std::io::IsTerminal as _;
    let text = Scenario::text(&args.scenario).map_err(usage)?;
    let cases = ringsync_sim::sweep::cases(
        &text,
        &args.scenario,
        &args.set,
        args.seeds,
        args.auto_cycle,
    )
    .map_err(usage)?;
    let dir = out_dir(&args.out, &args.scenario)?;
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let tty = std::io::stderr().is_terminal();
    let wall = WallClock::now();
    let results = ringsync_sim::sweep::run_all(&cases, jobs, &|done, total| {
        if tty {
            eprint!("\r  case {done}/{total}");
        }
    });
    if tty {
        eprintln!();
    }
    let keys: Vec<&str> = args.set.iter().map(|a| a.key.as_str()).collect();
    let mut csv = format!(
        "{},seed,track_rmse,sync_rmse,lumped_lost,retries,commands_lost,clock_error_max_ns,group_stop_s\n",
        keys.join(",")
    );
    for (c, r) in cases.iter().zip(&results) {
        let vals: Vec<&str> = c.labels.iter().map(|(_, v)| v.as_str()).collect();
        match r {
            Ok(r) => {
                let _ = writeln!(
                    csv,
                    "{},{},{:.9},{:.9},{},{},{},{:.0},{}",
                    vals.join(","),
                    c.seed,
                    r.summary.track_rmse,
                    r.summary.sync_rmse,
                    r.master.lumped_lost,
                    r.master.retries,
                    r.master.commands_lost,
                    r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
                    r.group_stop
                        .map_or(String::new(), |(t, _)| format!("{t:.4}"))
                );
            }
            Err(e) => return Err(CliError::Usage(format!("case {}: {e}", vals.join(" ")))),
        }
    }
    dir.write("sweep.csv", &csv)?;
    // Means over seeds, per combination, in order.
    let mut means: Vec<(Labels, Vec<(f64, f64)>)> = Vec::new();
    for (c, r) in cases.iter().zip(&results) {
        if let Ok(r) = r {
            match means.last_mut() {
                Some((l, v)) if *l == c.labels => {
                    v.push((r.summary.track_rmse, r.summary.sync_rmse))
                }
                _ => means.push((
                    c.labels.clone(),
                    vec![(r.summary.track_rmse, r.summary.sync_rmse)],
                )),
            }
        }
    }
    let mut mcsv = format!(
        "{},runs,track_rmse_mean,sync_rmse_mean,sync_rmse_std\n",
        keys.join(",")
    );
    let mut table = format!(
        "| {} | runs | Track-RMSE [rad] | Sync-RMSE [rad] (± std over seeds) |\n|{}---:|---:|---:|\n",
        keys.join(" | "),
        "---|".repeat(keys.len())
    );
    for (labels, v) in &means {
        let n = v.len() as f64;
        let mt = v.iter().map(|x| x.0).sum::<f64>() / n;
        let ms = v.iter().map(|x| x.1).sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x.1 - ms).powi(2)).sum::<f64>() / n).sqrt();
        let vals: Vec<&str> = labels.iter().map(|(_, v)| v.as_str()).collect();
        let _ = writeln!(
            mcsv,
            "{},{},{:.9},{:.9},{:.9}",
            vals.join(","),
            v.len(),
            mt,
            ms,
            sd
        );
        let _ = writeln!(
            table,
            "| {} | {} | {:.5} | {:.7} ± {:.7} |",
            vals.join(" | "),
            v.len(),
            mt,
            ms,
            sd
        );
    }
    dir.write("means.csv", &mcsv)?;
    // Figure: mean Sync-RMSE against the first key, one line per value of the others.
    let mut groups: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (k, (labels, v)) in means.iter().enumerate() {
        let name = labels[1..]
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(", ");
        let x = labels[0].1.parse::<f64>().unwrap_or(k as f64);
        let ms = v.iter().map(|x| x.1).sum::<f64>() / v.len() as f64;
        match groups.iter_mut().find(|(n, _)| *n == name) {
            Some((_, pts)) => pts.push((x, ms)),
            None => groups.push((name, vec![(x, ms)])),
        }
    }
    let series: Vec<ringsync_report::plot::Series<'_>> = groups
        .into_iter()
        .enumerate()
        .map(|(i, (name, points))| ringsync_report::plot::Series {
            name: if name.is_empty() {
                "Sync-RMSE".into()
            } else {
                name
            },
            colour: ringsync_report::plot::PALETTE[i % ringsync_report::plot::PALETTE.len()],
            points,
        })
        .collect();
    let svg = ringsync_report::plot::line_chart(
        &format!(
            "Sync-RMSE against {} ({}, mean of {} seed{})",
            keys[0],
            args.scenario,
            args.seeds,
            if args.seeds == 1 { "" } else { "s" }
        ),
        keys[0],
        "Sync-RMSE [rad]",
        &series,
    );
    dir.write("sweep.svg", &svg)?;
    dir.commit()?;
    let stopped = results
        .iter()
        .filter(|r| r.as_ref().is_ok_and(|r| r.group_stop.is_some()))
        .count();
    out(&format!(
        "{table}\n{} runs on {jobs} threads in {:.2} s; wrote {}/sweep.csv, means.csv and sweep.svg\n{}",
        cases.len(),
        wall.elapsed().as_secs_f64(),
        args.out.display(),
        if stopped > 0 {
            format!("GROUP STOP in {stopped} of the runs (group_stop_s in sweep.csv)\n")
        } else {
            String::new()
        }
    ))?;
    Ok(Outcome::flagged_if(stopped > 0))
}
