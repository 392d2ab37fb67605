//! Outputs of a simulation run: `summary.json`, `trace.csv`, and the reproduction table.

use std::fmt::Write as _;

use ringsync_proto::node::StopReason;
use ringsync_sim::RunResult;
use ringsync_sim::run::ASSUMPTIONS;
use ringsync_sim::scenario::Scenario;
use serde_json::{Value, json};

fn stop_json(stop: &Option<(f64, StopReason)>) -> Value {
    match stop {
        None => Value::Null,
        Some((t, r)) => {
            let (reason, axis, error) = match *r {
                StopReason::FollowingError { axis, error } => {
                    ("following-error", axis, Some(error))
                }
                StopReason::AxisFault { axis } => ("axis-fault", axis, None),
                StopReason::NoResponse { axis } => ("no-response", axis, None),
            };
            json!({ "time_s": t, "reason": reason, "axis": axis + 1, "error_rad": error })
        }
    }
}

/// `summary.json` of one run. Deterministic: no wall time, no paths.
pub fn summary_json(s: &Scenario, hash: u64, r: &RunResult) -> Value {
    let m = &r.summary;
    let axes: Vec<Value> = m
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| {
            json!({
                "axis": i + 1,
                "rms_e": a.rms_e, "max_e": a.max_e, "rms_eps": a.rms_eps, "max_eps": a.max_eps,
                "rms_u": a.rms_u, "peak_u": a.peak_u, "saturations": a.saturations,
                "clock_error_max_ns": r.clock_error_max_ns[i], "clock_error_rms_ns": r.clock_error_rms_ns[i],
            })
        })
        .collect();
    let slaves: Vec<Value> = r
        .slaves
        .iter()
        .enumerate()
        .map(|(i, c)| json!({"slave": i + 1, "syncs": c.syncs, "commands": c.commands, "bad_frames": c.bad_frames, "duplicates": c.duplicates}))
        .collect();
    let mc = &r.master;
    json!({
        "scenario": s.name,
        "scenario_hash": format!("{hash:016x}"),
        "seed": s.seed,
        "plan": s.ring.plan.name(),
        "controller": s.control.law.name(),
        "estimator": s.control.estimator.name(),
        "cycles": r.cycles,
        "t_cyc_s": s.ring.cycle.secs(),
        "track_rmse": m.track_rmse,
        "sync_rmse": m.sync_rmse,
        "axes": axes,
        "frames": {
            "sent_by_master": mc.frames_sent,
            "lost_on_links": r.links.lost,
            "corrupted_on_links": r.links.corrupted,
            "lumped_lost": mc.lumped_lost,
            "samples_missing": mc.samples_missing,
            "slices_failed": mc.slices_failed,
            "retries": mc.retries,
            "retries_ok": mc.retries_ok,
            "commands_lost": mc.commands_lost,
            "bad_frames_at_master": mc.bad_frames,
        },
        "slaves": slaves,
        "clock_error_max_ns": r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        "faults": {
            "watchdog": r.watchdog.iter().map(|(s, t)| json!({"slave": s, "time_s": t})).collect::<Vec<_>>(),
            "group_stop": stop_json(&r.group_stop),
        },
        "assumptions": ASSUMPTIONS,
    })
}

/// `trace.csv`: one row per cycle and axis.
pub fn trace_csv(r: &RunResult) -> String {
    let mut o = String::with_capacity(r.trace.len() * 120);
    o.push_str(
        "t_s,axis,x_d_rad,x_rad,e_rad,eps_rad,u_v,sample_time_s,apply_time_s,clock_error_ns\n",
    );
    for row in &r.trace {
        let _ = writeln!(
            o,
            "{:.6},{},{:.9},{:.9},{:.9},{:.9},{:.6},{:.9},{:.9},{:.0}",
            row.t,
            row.axis,
            row.x_d,
            row.x,
            row.e,
            row.eps,
            row.u,
            row.sample_time,
            row.apply_time,
            row.clock_error_ns
        );
    }
    o
}

/// The paper's Table 1 (rad): (Track-RMSE this paper, ref. [3]; Sync-RMSE this paper, ref. [3]).
pub const PAPER_TABLE_1: [(&str, [f64; 4]); 2] = [
    ("standard PD", [0.23267, 0.25715, 0.0039154, 0.0059015]),
    ("sync controller", [0.18341, 0.20427, 0.0019863, 0.0032035]),
];

/// One row of the reproduction.
#[derive(Debug, Clone)]
pub struct ReproRow {
    /// `p2p-lumped` or `lumped-only`.
    pub plan: &'static str,
    /// `pd`, `sync` or `ring-coupled`.
    pub controller: &'static str,
    /// Track-RMSE [rad].
    pub track_rmse: f64,
    /// Sync-RMSE [rad].
    pub sync_rmse: f64,
}

fn find(rows: &[ReproRow], plan: &str, ctl: &str) -> Option<(f64, f64)> {
    rows.iter()
        .find(|r| r.plan == plan && r.controller == ctl)
        .map(|r| (r.track_rmse, r.sync_rmse))
}

/// The paper's Table 1 beside ours, as Markdown.
pub fn repro_table(rows: &[ReproRow]) -> String {
    let mut o = String::new();
    let f = |v: Option<(f64, f64)>, which: usize, digits: usize| match v {
        Some(p) => format!("{:.*}", digits, if which == 0 { p.0 } else { p.1 }),
        None => "not simulated".into(),
    };
    let _ = writeln!(
        o,
        "| | Track-RMSE, paper | Track-RMSE, ringsync | Sync-RMSE, paper | Sync-RMSE, ringsync |"
    );
    let _ = writeln!(o, "|---|---:|---:|---:|---:|");
    let ours = [
        find(rows, "p2p-lumped", "pd"),
        find(rows, "p2p-lumped", "sync"),
    ];
    for (k, (name, p)) in PAPER_TABLE_1.iter().enumerate() {
        let _ = writeln!(
            o,
            "| {name} | {} | {} | {} | {} |",
            p[0],
            f(ours[k], 0, 5),
            p[2],
            f(ours[k], 1, 7)
        );
    }
    let red = |a: f64, b: f64| format!("{:.3} %", (1.0 - b / a) * 100.0);
    let (ot, os) = match (ours[0], ours[1]) {
        (Some(pd), Some(sy)) => (red(pd.0, sy.0), red(pd.1, sy.1)),
        _ => ("–".into(), "–".into()),
    };
    let _ = writeln!(o, "| reduction | 21.171 % | {ot} | 49.270 % | {os} |");
    if let Some(rc) = find(rows, "p2p-lumped", "ring-coupled") {
        let _ = writeln!(
            o,
            "| ring-coupled (not in the paper) | – | {:.5} | – | {:.7} |",
            rc.0, rc.1
        );
    }
    let _ = writeln!(
        o,
        "\nPaper's ref. [3] column (lumped-only plan, another test bench): PD {} / {}, sync {} / {} (Track / Sync-RMSE, rad). \
         The lumped-only plan is not simulated yet.",
        PAPER_TABLE_1[0].1[1], PAPER_TABLE_1[0].1[3], PAPER_TABLE_1[1].1[1], PAPER_TABLE_1[1].1[3]
    );
    o
}

/// `summary.json` of `reproduce`: one object per row.
pub fn repro_json(rows: &[ReproRow]) -> Value {
    Value::Array(
        rows.iter()
            .map(|r| json!({"plan": r.plan, "controller": r.controller, "track_rmse": r.track_rmse, "sync_rmse": r.sync_rmse}))
            .collect(),
    )
}
