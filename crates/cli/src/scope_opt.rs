//! `--scope ADDR` of `ringsync rt` and `ringsync sim` (the live web scope, docs/scope.md),
//! built with the CLI's `scope` feature (on by default).

use std::net::SocketAddr;

use clap::Args;
use ringsync::layers::report::sim::summary_json;
use ringsync::{Observer, RunResult, Scenario};
use ringsync_scope::{Scope, Source};
use serde_json::{Value, json};

use crate::CliError;
use crate::rt_cmd::duration;

/// The scope's options of `ringsync rt`.
#[derive(Args, Debug, Default)]
pub struct RtScopeArgs {
    /// Serve the live scope while the ring runs: a page at http://ADDR/ and its WebSocket
    /// stream at ws://ADDR/ws (e.g. 127.0.0.1:8080; port 0 picks a free one).
    #[arg(long, value_name = "ADDR")]
    pub scope: Option<SocketAddr>,
    /// Measure what the scope costs the loop: feed the pages in alternate periods of this
    /// length only, and print the cycle-start lateness of the fed and the idle periods
    /// (with --scope; docs/runtime.md, "With the scope attached").
    #[arg(long, value_name = "PERIOD", requires = "scope", value_parser = duration)]
    pub scope_ab: Option<ringsync::Duration>,
}

/// The scope's options of `ringsync sim`.
#[derive(Args, Debug, Default)]
pub struct SimScopeArgs {
    /// Replay the run on the live scope: a page at http://ADDR/ and its WebSocket stream at
    /// ws://ADDR/ws (e.g. 127.0.0.1:8080; port 0 picks a free one). The replay starts when
    /// the first page connects (or after --scope-wait) and runs at --speed.
    #[arg(long, value_name = "ADDR")]
    pub scope: Option<SocketAddr>,
    /// Replay at this multiple of real speed (with --scope).
    #[arg(long, value_name = "X", default_value_t = 1.0, requires = "scope",
          value_parser = speed)]
    pub speed: f64,
    /// Longest wait for a first page before the replay starts anyway (with --scope).
    #[arg(long, value_name = "DURATION", default_value = "60s", requires = "scope",
          value_parser = duration)]
    pub scope_wait: ringsync::Duration,
}

fn speed(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if !(x.is_finite() && (0.01..=1000.0).contains(&x)) {
        return Err(format!("{s} is out of range (0.01 to 1000)"));
    }
    Ok(x)
}

/// A scope started for a run, or none.
pub struct Running {
    scope: Option<Scope>,
    /// The alternating measurement's report (`--scope-ab`), when asked for.
    ab: Option<std::sync::mpsc::Receiver<ringsync_scope::ab::AbReport>>,
}

/// Starts the scope at `addr` (if given) for `s`, from `source`; returns it and the
/// observers to add to the run.
pub fn start(
    addr: Option<SocketAddr>,
    s: &Scenario,
    source: Source,
    what: &str,
) -> Result<(Running, Vec<Box<dyn Observer>>), CliError> {
    start_ab(addr, None, s, source, what)
}

/// [`start`], feeding the pages in alternate periods of `ab` only when given (the first
/// feeds; see `ringsync_scope::ab`).
pub fn start_ab(
    addr: Option<SocketAddr>,
    ab: Option<ringsync::Duration>,
    s: &Scenario,
    source: Source,
    what: &str,
) -> Result<(Running, Vec<Box<dyn Observer>>), CliError> {
    let Some(addr) = addr else {
        return Ok((
            Running {
                scope: None,
                ab: None,
            },
            Vec::new(),
        ));
    };
    let (scope, observer) =
        Scope::start(addr, s, source).map_err(|e| CliError::Failure(e.to_string()))?;
    eprintln!("ringsync {what}: scope at http://{}/", scope.addr());
    let (observer, ab) = match ab {
        Some(period) => {
            let cycles = (period.as_ns() / s.ring.cycle.0.as_ns().max(1)).max(1);
            eprintln!(
                "ringsync {what}: the scope feeds its pages in alternate periods of {cycles} cycles"
            );
            let (o, rx) = observer.alternate(cycles);
            (o, Some(rx))
        }
        None => (observer, None),
    };
    Ok((
        Running {
            scope: Some(scope),
            ab,
        },
        vec![Box::new(observer) as Box<dyn Observer>],
    ))
}

impl Running {
    /// Waits up to `wait` for a first page (a replay starts when someone watches).
    pub fn wait_for_client(&self, wait: ringsync::Duration, what: &str) {
        if let Some(s) = &self.scope {
            eprintln!(
                "ringsync {what}: the replay starts when a page connects (up to {} s)",
                wait.as_ns() as f64 * 1e-9
            );
            let w = std::time::Duration::from_nanos(u64::try_from(wait.as_ns()).unwrap_or(0));
            // In slices, so that Ctrl-C (the stop flag, raised from `out_dir` on) ends the
            // wait at once; the run then sees the flag at its first cycle.
            let stop = ringsync::layers::runtime::stop_flag_or_twice_exit();
            let end = std::time::Instant::now() + w;
            let slice = std::time::Duration::from_millis(100);
            loop {
                if stop.load(std::sync::atomic::Ordering::Relaxed) {
                    return;
                }
                let left = end.saturating_duration_since(std::time::Instant::now());
                if s.wait_for_client(left.min(slice)) {
                    break;
                }
                if left <= slice {
                    eprintln!("ringsync {what}: no page connected; replaying anyway");
                    break;
                }
            }
        }
    }

    /// The run ended: its result to the pages, then the server stops (after up to 2 s for
    /// the pages to read the rest).
    pub fn finish(self, s: &Scenario, hash: u64, r: &RunResult) {
        // The observer went with the run: its alternating measurement is in.
        if let Some(report) = self.ab.as_ref().and_then(|rx| rx.try_recv().ok()) {
            eprintln!("{}", report.text());
        }
        if let Some(scope) = self.scope {
            scope.finish(end_json(s, hash, r), std::time::Duration::from_secs(2));
        }
    }
}

fn end_json(s: &Scenario, hash: u64, r: &RunResult) -> Value {
    let v = summary_json(s, hash, r);
    json!({
        "cycles": v["cycles"],
        "track_rmse": v["track_rmse"],
        "sync_rmse": v["sync_rmse"],
        "group_stop": v["faults"]["group_stop"],
        "monitor": v.get("monitor").cloned().unwrap_or(Value::Null),
    })
}
