//! `ringsync sim`, `ringsync reproduce` and `ringsync sweep`.

use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::time::Instant as WallClock;

use clap::Args;
use ringsync::{Loaded, OutDir, SimOptions};

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
    /// Seed for every random draw, instead of the scenario's (0 … 2^63 − 1).
    #[arg(long, value_parser = clap::value_parser!(u64).range(..=ringsync::sweep::MAX_SEED))]
    seed: Option<u64>,
    /// Set a scenario key, e.g. `control.law=pd` or `faults.loss=0.01` (repeatable;
    /// the dotted keys of `sweep --set`, one value each).
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = key_value)]
    set: Vec<(String, String)>,
    /// Also write every frame the nodes send, with its simulated send time, as pcapng.
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
    /// What to write, comma-separated: summary (summary.json), trace (trace.csv), parquet
    /// (trace.parquet: the trace's exact values, for pandas or polars), figures (*.svg),
    /// report (report.html), or all (every one but parquet: `all,parquet` adds it).
    /// `--outputs summary` keeps no trace. The run's scenario.toml is always written.
    #[arg(long, value_name = "LIST", default_value = "all", value_parser = outputs)]
    outputs: ringsync::Outputs,
    #[cfg(feature = "scope")]
    #[command(flatten)]
    scope: crate::scope_opt::SimScopeArgs,
}

pub(crate) fn key_value(kv: &str) -> Result<(String, String), String> {
    ringsync::key_value(kv).map_err(|e| e.to_string())
}

fn outputs(list: &str) -> Result<ringsync::Outputs, String> {
    list.parse().map_err(|e: ringsync::Error| e.to_string())
}

/// The results directory for `--out`, which must not hold the scenario file: it is replaced.
/// From here on Ctrl-C, SIGTERM and SIGHUP raise the stop flag
/// (`ringsync::layers::runtime::stop_flag_or_twice_exit`), which the command looks at: an
/// interrupted command ends cleanly and removes the directory it was writing beside `--out`;
/// a second signal ends the process at once. (`rt` and `node` put back the flag-only handler
/// before their ring exists: a second signal must not skip removing it.)
pub(crate) fn out_dir(out: &Path, scenario: &Loaded) -> Result<OutDir, CliError> {
    ringsync::layers::runtime::stop_flag_or_twice_exit();
    let dir = OutDir::create("--out", out)?;
    if !scenario.is_builtin() {
        dir.keep_out(Path::new(&scenario.origin))?;
    }
    Ok(dir)
}

/// Parses `--jobs`: 1 ..= [`ringsync::sweep::MAX_JOBS`] threads.
fn jobs(s: &str) -> Result<usize, String> {
    let max = ringsync::sweep::MAX_JOBS;
    match s.parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        Ok(_) => Err(format!("at least 1 thread, at most {max}")),
        Err(e) => Err(format!("{e}; expected a number of threads, 1 ..= {max}")),
    }
}

/// Runs `ringsync sim`: exit status 3 when the run ends in a group stop.
pub(crate) fn sim(args: &SimArgs) -> Result<Outcome, CliError> {
    let file = ringsync::load(&args.scenario)?;
    let loaded = ringsync::with_values(&file, &args.set)?;
    let mut dir = out_dir(&args.out, &file)?;
    let mut s = loaded.scenario.clone();
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    let wall = WallClock::now();
    // Ctrl-C, SIGTERM, SIGHUP: the run ends at its next cycle and nothing is written.
    let stop = ringsync::layers::runtime::stop_flag_or_twice_exit();
    let opts = SimOptions {
        trace: args.outputs.needs_trace(),
        capture: args.pcap.is_some(),
        stop: Some(ringsync::Stop::Static(stop)),
        ..SimOptions::default()
    };
    // A progress line on a terminal once the run has taken more than a second.
    let tty = std::io::stderr().is_terminal();
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
    #[cfg(feature = "scope")]
    let (scope, observers) = {
        let (scope, observers) = crate::scope_opt::start(
            args.scope.scope,
            &s,
            ringsync_scope::Source::Replay {
                speed: args.scope.speed,
            },
            "sim",
        )?;
        scope.wait_for_client(args.scope.scope_wait, "sim");
        (scope, observers)
    };
    #[cfg(not(feature = "scope"))]
    let observers = Vec::new();
    let r = ringsync::simulate_with(&s, &opts, observers, &mut progress);
    if shown {
        eprintln!();
    }
    let r = r.map_err(interrupted_nothing_written)?;
    #[cfg(feature = "scope")]
    scope.finish(&s, loaded.hash, &r);
    let elapsed = wall.elapsed();
    ringsync::write_sim(
        &mut dir,
        &s,
        loaded.hash,
        &r,
        args.pcap.as_deref(),
        args.outputs,
    )?;
    ringsync::identify::write_scenario(&dir, &loaded, args.seed)?;
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        return Err(CliError::Failure(
            "interrupted while writing the results; nothing written".into(),
        ));
    }
    dir.commit()?;
    // Every file the run wrote: the outputs asked for, a program's path table, the capture.
    let mut files = args.outputs.files();
    if args.outputs.trace && r.path.is_some() {
        files += ", path.csv";
    }
    if let Some(p) = &args.pcap {
        files += &format!("; the capture {}", p.display());
    }
    out(&format!(
        "{}  wrote {}: {} in {:.1} ms\n",
        ringsync::sim_text(&s, &r),
        args.out.display(),
        files,
        elapsed.as_secs_f64() * 1e3
    ))?;
    Ok(Outcome::flagged_if(r.group_stop.is_some()))
}

/// The error of work that was interrupted before it had anything to write.
fn interrupted_nothing_written(e: ringsync::Error) -> CliError {
    match e {
        ringsync::Error::Interrupted(m) => CliError::Failure(format!("{m}; nothing written")),
        e => e.into(),
    }
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
    /// Seeds per case (the scenario's seed, +1, …): the tables give mean ± standard
    /// deviation and range over them.
    #[arg(long, default_value_t = ringsync::reproduce::DEFAULT_SEEDS,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(ringsync::reproduce::MAX_SEEDS)))]
    seeds: u32,
    /// Parallel simulations (default: the number of CPUs).
    #[arg(long, value_parser = jobs)]
    jobs: Option<usize>,
}

/// Runs `ringsync reproduce`: exit status 3 when any case ends in a group stop.
pub(crate) fn reproduce(args: &ReproduceArgs) -> Result<Outcome, CliError> {
    let loaded = ringsync::load(&args.scenario)?;
    let base = &loaded.scenario;
    let dir = out_dir(&args.out, &loaded)?;
    let wall = WallClock::now();
    let tty = std::io::stderr().is_terminal();
    let progress = |done: usize, total: usize| {
        if tty {
            eprint!("\r  run {done}/{total}");
        }
    };
    let opts = ringsync::ReproOptions {
        seeds: args.seeds,
        jobs: args.jobs.unwrap_or_else(ringsync::sweep::default_jobs),
        progress: &progress,
        // Ctrl-C, SIGTERM, SIGHUP: no run starts after it, and nothing is written.
        stop: Some(ringsync::Stop::Static(
            ringsync::layers::runtime::stop_flag_or_twice_exit(),
        )),
    };
    let r = ringsync::reproduce_with(base, &opts);
    if tty {
        eprintln!();
    }
    let r = r.map_err(interrupted_nothing_written)?;
    ringsync::write_reproduction(&dir, &r)?;
    if ringsync::layers::runtime::stop_flag_or_twice_exit()
        .load(std::sync::atomic::Ordering::Relaxed)
    {
        return Err(CliError::Failure(
            "interrupted while writing the results; nothing written".into(),
        ));
    }
    dir.commit()?;
    let stopped = r.stopped();
    out(&format!(
        "Scenario {} ({} axes, {} s, estimator {}), Table 1 [rad] over {} seed{} per case:\n\n{}\nAssumptions of the scenario: scenarios/{}.toml; of the simulator: summary.json of `ringsync sim`.\nWrote {}/summary.json, table.md, report.html and the figures (fig*.svg) in {:.1} ms.\n",
        base.name,
        base.axes_count(),
        base.duration.secs(),
        base.control.estimator.name(),
        args.seeds,
        if args.seeds == 1 { "" } else { "s" },
        r.table(),
        base.name,
        args.out.display(),
        wall.elapsed().as_secs_f64() * 1e3
    ))?;
    if !stopped.is_empty() {
        out(&format!("GROUP STOP in {}\n", stopped.join(", ")))?;
    }
    Ok(Outcome::flagged_if(!stopped.is_empty()))
}

/// Options of `ringsync sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// Scenario file or built-in name: the base of every case.
    scenario: String,
    /// A key and its values, e.g. `faults.loss=0,0.01,0.02`; several give their product;
    /// none: the scenario alone, over its seeds. Commas inside brackets or quotes belong to
    /// the value: `control.kp=[1,2],[3,4]` is two cases.
    #[arg(long = "set", value_name = "KEY=V1,V2,…")]
    set: Vec<ringsync::sweep::SweepAxis>,
    /// Seeds per case (the scenario's seed, +1, …), as in `reproduce` and Python; means and
    /// sample standard deviations are over them.
    #[arg(long, default_value_t = ringsync::sweep::DEFAULT_SEEDS,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(ringsync::sweep::MAX_SEEDS)))]
    seeds: u32,
    /// Give each case whose cycle is too short for its ring the shortest cycle that holds it (+10 %).
    #[arg(long)]
    auto_cycle: bool,
    /// Directory for sweep.csv, means.csv and sweep.svg; replaced as a whole when the sweep
    /// ends (created if missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Parallel simulations (default: the number of CPUs).
    #[arg(long, value_parser = jobs)]
    jobs: Option<usize>,
}

/// Runs `ringsync sweep`: exit status 3 when any case ends in a group stop.
pub(crate) fn sweep(args: &SweepArgs) -> Result<Outcome, CliError> {
    use ringsync::sweep::{Sweep, cases, run_cases_until, write_sweep};
    let base = ringsync::load(&args.scenario)?;
    let cases = cases(&base, &args.set, args.seeds, args.auto_cycle)?;
    let dir = out_dir(&args.out, &base)?;
    let jobs = args.jobs.unwrap_or_else(ringsync::sweep::default_jobs);
    let tty = std::io::stderr().is_terminal();
    let wall = WallClock::now();
    // Ctrl-C, SIGTERM, SIGHUP: no case starts after it; the runs that finished are written.
    let stop = ringsync::Stop::Static(ringsync::layers::runtime::stop_flag_or_twice_exit());
    let results = run_cases_until(
        &cases,
        jobs,
        &|done, total| {
            if tty {
                eprint!("\r  case {done}/{total}");
            }
        },
        &stop,
    );
    if tty {
        eprintln!();
    }
    let planned = cases.len();
    let (sw, not_run) = Sweep::finished(&base, &args.set, args.seeds, cases, results)?;
    if sw.results.is_empty() {
        return Err(CliError::Failure(
            "interrupted before any run finished; nothing written".into(),
        ));
    }
    write_sweep(&dir, &sw)?;
    dir.commit()?;
    let stopped = sw.stopped();
    let n = sw.results.len();
    out(&format!(
        "{}\n{n} runs on {jobs} threads in {:.2} s; wrote {}/sweep.csv, means.csv and sweep.svg\n{}",
        sw.table(),
        wall.elapsed().as_secs_f64(),
        args.out.display(),
        if stopped > 0 {
            format!("GROUP STOP in {stopped} of the runs (group_stop_s in sweep.csv)\n")
        } else {
            String::new()
        }
    ))?;
    if not_run > 0 {
        return Err(CliError::Failure(format!(
            "interrupted: {n} of {planned} runs finished and are written ({not_run} not run; the means are over the seeds that finished)"
        )));
    }
    Ok(Outcome::flagged_if(stopped > 0))
}

/// Options of `ringsync identify`.
#[derive(Args, Debug)]
pub struct IdentifyArgs {
    /// A run directory written by `ringsync sim` or `ringsync rt` (scenario.toml,
    /// summary.json, trace.csv).
    run: PathBuf,
    /// Where to write the run's scenario with the identified feed-forward (control.kh, kc,
    /// kf); written beside and renamed into place.
    #[arg(long, value_name = "FILE.toml")]
    out: PathBuf,
    /// Bandwidth of the disturbance observer the written scenario adds [Hz] (0: none, and
    /// K_F = F instead): it holds the compensation when the model is not equally right on
    /// every axis (docs/experiments.md, section 6).
    #[arg(long, value_name = "HZ", default_value_t = ringsync::identify::DOB_BANDWIDTH_HZ)]
    dob_bandwidth: f64,
}

/// Runs `ringsync identify`: the table of estimates, and the scenario with them.
pub(crate) fn identify(args: &IdentifyArgs) -> Result<Outcome, CliError> {
    ringsync::identify::check_out(&args.run, &args.out)?;
    ringsync::output::writable(&args.out)?;
    let id = ringsync::identify::identify_run(&args.run)?;
    let text = ringsync::identify::identified_toml(&id, args.dob_bandwidth)?;
    ringsync::output::write_file(&args.out, &text)?;
    let dob = text
        .lines()
        .find_map(|l| l.strip_prefix("dob_bandwidth = "))
        .map(str::to_string);
    let written_hz = dob.as_deref().and_then(|d| d.parse().ok()).unwrap_or(0.0);
    if let Some(w) = id.warning(written_hz) {
        eprintln!("ringsync: {w}");
    }
    out(&format!(
        "{}\nWrote {}: the run's scenario with K_H = H, K_C = C per axis, {}.\n",
        id.text(),
        args.out.display(),
        match dob {
            Some(hz) if hz != "0.0" => format!(
                "and a disturbance observer of {hz} Hz in place of K_F (--dob-bandwidth 0: K_F = F instead)"
            ),
            _ => "K_F = F".to_string(),
        }
    ))
}
