//! Simulating a scenario: the deterministic co-simulator (same scenario and seed, identical
//! results), its results written as a directory of files, and a one-paragraph summary.

use std::path::Path;

use ringsync_model::observer::Observer;
use ringsync_model::{RunResult, Scenario};
use ringsync_report::sim::{run_figures, run_html, summary_json, write_trace_csv};
pub use ringsync_sim::RunOptions as SimOptions;

use crate::error::Result;
use crate::output::OutDir;

/// Simulates `s`.
///
/// ```
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(200);
/// let r = ringsync::simulate(&s, &ringsync::SimOptions { trace: true, ..Default::default() })?;
/// assert_eq!(r.cycles, 200);
/// assert!(r.group_stop.is_none());
/// // The trace in columns: one group of n rows per cycle the master computed.
/// assert_eq!(r.trace.len(), r.trace.t.len() * 4);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn simulate(s: &Scenario, opts: &SimOptions) -> Result<RunResult> {
    simulate_with(s, opts, Vec::new(), &mut |_, _| {})
}

/// [`simulate`], `observers` told every cycle, law run, applied command and fault step as
/// the run goes, `progress(cycles done, cycles in all)` called every 100 cycles.
///
/// ```
/// use ringsync::{Observer, AxisProbe};
/// /// Counts the cycles and keeps the largest |e| seen on axis 1 [rad].
/// #[derive(Default)]
/// struct Peak(std::sync::Arc<std::sync::Mutex<(u64, f64)>>);
/// impl Observer for Peak {
///     fn cycle(&mut self, _k: i64, _t: f64, axes: &[AxisProbe]) {
///         let mut p = self.0.lock().unwrap();
///         p.0 += 1;
///         p.1 = p.1.max((axes[0].x_d - axes[0].x).abs());
///     }
/// }
/// let peak = Peak::default();
/// let seen = peak.0.clone();
/// let mut s = ringsync::load("paper-2015")?.scenario;
/// s.duration.0 = ringsync::Duration::from_ms(100);
/// let r = ringsync::simulate_with(&s, &Default::default(), vec![Box::new(peak)], &mut |_, _| {})?;
/// let (cycles, max_e) = *seen.lock().unwrap();
/// assert_eq!(cycles as i64, r.cycles); // every cycle start
/// assert!(max_e > 0.0 && max_e <= r.summary.axes[0].max_e + 1e-12);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn simulate_with(
    s: &Scenario,
    opts: &SimOptions,
    observers: Vec<Box<dyn Observer>>,
    progress: &mut dyn FnMut(i64, i64),
) -> Result<RunResult> {
    let spec = s.build()?;
    Ok(ringsync_sim::simulate(
        &spec,
        opts.clone(),
        observers,
        progress,
    )?)
}

/// Which files [`write_sim`] writes (`ringsync sim --outputs`): any of `summary`
/// (summary.json), `trace` (trace.csv), `figures` (the `*.svg`), `report` (report.html, which
/// holds the figures). Parsed from a comma-separated list; `all` is every one.
///
/// ```
/// let o: ringsync::Outputs = "summary".parse()?;
/// assert!(o.summary && !o.needs_trace());
/// assert_eq!("all".parse::<ringsync::Outputs>()?, ringsync::Outputs::ALL);
/// assert!("summary,plots".parse::<ringsync::Outputs>().is_err());
/// # Ok::<(), ringsync::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outputs {
    /// summary.json: the metrics, counters, faults and assumptions.
    pub summary: bool,
    /// trace.csv: one row per cycle and axis.
    pub trace: bool,
    /// The figures, one `*.svg` each.
    pub figures: bool,
    /// report.html, with the figures inline.
    pub report: bool,
    /// trace.parquet: the trace's exact values as Parquet ([`ringsync_report::columnar`]);
    /// not among [`Outputs::ALL`], asked for by name.
    pub parquet: bool,
}

impl Outputs {
    /// Every output (the default).
    pub const ALL: Outputs = Outputs {
        summary: true,
        trace: true,
        figures: true,
        report: true,
        parquet: false,
    };
    /// The names in `--outputs`, in the order files are written.
    pub const NAMES: [&'static str; 5] = ["summary", "trace", "parquet", "figures", "report"];

    /// Whether the run must keep its trace (for trace.csv, the figures or the report).
    pub fn needs_trace(self) -> bool {
        self.trace || self.parquet || self.figures || self.report
    }

    /// The files these outputs write, for messages: `summary.json, trace.csv, …`.
    pub fn files(self) -> String {
        let f = [
            (self.summary, "summary.json"),
            (self.trace, "trace.csv"),
            (self.parquet, "trace.parquet"),
            (self.figures, "the figures (*.svg)"),
            (self.report, "report.html"),
        ];
        let v: Vec<&str> = f.iter().filter(|(on, _)| *on).map(|(_, n)| *n).collect();
        v.join(", ")
    }
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs::ALL
    }
}

impl std::str::FromStr for Outputs {
    type Err = crate::Error;
    fn from_str(list: &str) -> Result<Self> {
        let mut o = Outputs {
            summary: false,
            trace: false,
            figures: false,
            report: false,
            parquet: false,
        };
        for name in list.split(',').map(str::trim) {
            match name {
                "summary" => o.summary = true,
                "trace" => o.trace = true,
                "figures" => o.figures = true,
                "report" => o.report = true,
                "parquet" => o.parquet = true,
                "all" => {
                    o = Outputs {
                        parquet: o.parquet,
                        ..Outputs::ALL
                    }
                }
                other => {
                    return Err(crate::Error::Input(format!(
                        "unknown output '{}' in '{}': expected a comma-separated list of {}, or all (every one but parquet)",
                        ringsync_model::scenario::clip(other, 40),
                        ringsync_model::scenario::clip(list, 120),
                        Outputs::NAMES.join(", ")
                    )));
                }
            }
        }
        Ok(o)
    }
}

/// Writes a run's results into `dir`: those of `outputs` among `summary.json`, `trace.csv`
/// (when the run kept its trace), the figures (`*.svg`) and `report.html`; the frames it
/// captured as pcapng to `pcap` when given. `s` is the scenario as run, `hash` its text's
/// hash.
pub fn write_sim(
    dir: &mut OutDir,
    s: &Scenario,
    hash: u64,
    r: &RunResult,
    pcap: Option<&Path>,
    outputs: Outputs,
) -> Result<()> {
    if let Some(p) = pcap {
        dir.write_file(
            p,
            ringsync_report::pcap::pcapng(
                &r.captured,
                s.axes_count(),
                &ringsync_report::pcap::CaptureInfo::simulated(s, hash),
            ),
        )?;
    }
    if outputs.summary {
        let summary = serde_json::to_string_pretty(&summary_json(s, hash, r))?;
        dir.write("summary.json", format!("{summary}\n"))?;
    }
    if outputs.trace {
        dir.write_with("trace.csv", |w| write_trace_csv(r, w))?;
    }
    if outputs.trace
        && let Some(p) = &r.path
    {
        dir.write_with("path.csv", |w| ringsync_report::path::write_path_csv(p, w))?;
    }
    if outputs.parquet {
        dir.write_with("trace.parquet", |w| {
            ringsync_report::columnar::write_trace_parquet(r, w)
        })?;
    }
    if !(outputs.figures || outputs.report) {
        return Ok(());
    }
    // The cycle of the run's plan (the broken ring's is drawn by `ringsync plan
    // --break-link`: a run's break comes and goes).
    let timing = ringsync_proto::CyclePlan::new(&s.ring_params())
        .ok()
        .and_then(|p| ringsync_report::timing_svg(&p, s.ring.plan, None));
    let figures = run_figures(timing, r);
    if outputs.figures {
        for (name, svg) in &figures {
            dir.write(name, svg)?;
        }
    }
    if outputs.report {
        dir.write("report.html", run_html(s, hash, r, &figures))?;
    }
    Ok(())
}

/// A few lines on a run: cycles, controller, the two metrics (eq. 26-27), frames, clock
/// error, the group stop if any.
pub fn sim_text(s: &Scenario, r: &RunResult) -> String {
    let mut text = format!(
        "{}: {} cycles of {} axes, {} controller, estimator {}\n  Track-RMSE {:.6} rad, Sync-RMSE {:.7} rad\n  frames: {} sent by the master, {} lost, {} retried; clock error ≤ {:.0} ns\n  {}\n",
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
            Some((t, reason)) => format!(
                "GROUP STOP at {t:.3} s: {}",
                ringsync_report::sim::stop_reason_text(&reason)
            ),
            None => "no group stop".to_string(),
        },
    );
    if let Some(l) = ringsync_report::sim::start_up_line(r) {
        text += &format!("  start-up: {l}\n");
    }
    if let Some(p) = &r.path {
        for l in ringsync_report::path::path_lines(p) {
            text += &format!("  {l}\n");
        }
    }
    text += &monitor_text(s, r);
    text += &ring_text(r);
    text += &saturation_text(r);
    text
}

/// A line when a drive spent cycles pinned at its limit (a command clipped to ±u_max):
/// how many axes, and the one most often (empty when none did).
pub fn saturation_text(r: &RunResult) -> String {
    let axes = &r.summary.axes;
    let hit = axes.iter().filter(|a| a.saturations > 0).count();
    let Some((i, most)) = axes
        .iter()
        .enumerate()
        .max_by_key(|(i, a)| (a.saturations, std::cmp::Reverse(*i)))
        .filter(|(_, a)| a.saturations > 0)
    else {
        return String::new();
    };
    format!(
        "  saturated: {hit} of {} axes held at the drive's limit; most, axis {}: {} of {} cycles ({:.1} %)\n",
        axes.len(),
        i + 1,
        most.saturations,
        r.cycles,
        100.0 * most.saturations as f64 / r.cycles.max(1) as f64
    )
}

/// The ring's changes (a link broken, healed, the break moved), a line each; empty on a
/// ring that never changed.
pub fn ring_text(r: &RunResult) -> String {
    ringsync_report::sim::ring_lines(r)
        .iter()
        .map(|l| format!("  ring: {l}\n"))
        .collect()
}

/// The monitors' warnings and trips, a line each (empty when no monitor is set; at most
/// 10 events, then a count).
pub fn monitor_text(s: &Scenario, r: &RunResult) -> String {
    let Some(lines) = ringsync_report::sim::monitor_lines(s, r) else {
        return String::new();
    };
    let total = lines.len();
    let mut out: String = lines
        .iter()
        .take(12)
        .map(|l| format!("  monitor: {l}\n"))
        .collect();
    if total > 12 {
        out += &format!("  monitor: … {} more in summary.json\n", total - 12);
    }
    out
}
