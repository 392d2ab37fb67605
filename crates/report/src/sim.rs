//! Outputs of a simulation run: `summary.json`, `trace.csv`, and the reproduction table.

use std::fmt::Write as _;

use ringsync_model::RunResult;
use ringsync_model::result::assumptions;
use ringsync_model::scenario::Scenario;
use ringsync_proto::node::{Rejections, StopReason};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
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
                StopReason::NoFeedback { axis } => ("no-feedback", axis, None),
                StopReason::CommandMismatch { axis, .. } => ("command-mismatch", axis, None),
                StopReason::SyncTrip { axis, error } => ("sync-error-trip", axis, Some(error)),
                StopReason::FollowingTrip { axis, error } => {
                    ("following-error-trip", axis, Some(error))
                }
                StopReason::RingSplit { axis, .. } => ("ring-split", axis, None),
            };
            if let StopReason::RingSplit { axis, last } = *r {
                let isolated: Vec<usize> = (axis + 1..=last + 1).collect();
                return json!({ "time_s": t, "reason": "ring-split", "axis": axis + 1,
                    "error_rad": Value::Null, "isolated_slaves": isolated });
            }
            json!({ "time_s": t, "reason": reason, "axis": axis + 1, "error_rad": error })
        }
    }
}

/// A group stop's reason in words, axes counted from 1 as everywhere in the outputs.
pub fn stop_reason_text(r: &StopReason) -> String {
    match *r {
        StopReason::SyncTrip { axis, error } => format!(
            "sync error trip on axis {} (ε = {error:+.5} rad beyond the monitor's trip limit)",
            axis + 1
        ),
        StopReason::FollowingTrip { axis, error } => format!(
            "following error trip on axis {} (e = {error:+.5} rad beyond the monitor's trip limit)",
            axis + 1
        ),
        StopReason::RingSplit { axis, last } if axis == last => format!(
            "ring split: slave {} is cut off from both of the master's ports",
            axis + 1
        ),
        StopReason::RingSplit { axis, last } => format!(
            "ring split: slaves {}..{} are cut off from both of the master's ports",
            axis + 1,
            last + 1
        ),
        StopReason::FollowingError { axis, error } => format!(
            "following error on axis {} (e = {error:+.5} rad beyond faults.following_error_limit)",
            axis + 1
        ),
        StopReason::CommandMismatch {
            axis,
            sent,
            applied,
        } => format!(
            "command mismatch on axis {} (sent {sent:+.4} V, the slave applied {applied:+.4} V)",
            axis + 1
        ),
        StopReason::AxisFault { axis }
        | StopReason::NoResponse { axis }
        | StopReason::NoFeedback { axis } => format!("{} on axis {}", r.name(), axis + 1),
    }
}

/// A line per change of the ring the master found, for the run's text: when, in which
/// cycle, what the ring became and the cycles it cost.
pub fn ring_lines(r: &RunResult) -> Vec<String> {
    r.ring_changes
        .iter()
        .map(|c| {
            let what = match c.to {
                ringsync_proto::node::RingState::Whole => "whole again".to_string(),
                to => to.describe(),
            };
            let lost = match c.cycles_lost {
                1 => ", 1 cycle lost".to_string(),
                0 => String::new(),
                k => format!(", {k} cycles lost"),
            };
            format!("{what} at {:.3} s (cycle {}{lost})", c.t, c.k)
        })
        .collect()
}

/// The `ring` key of summary.json: every change of the ring the master found (a link
/// broke, healed, or the break moved), with the cycles each cost; `None` (no key) on a
/// ring that never changed and had no break scheduled.
pub fn ring_json(s: &Scenario, r: &RunResult) -> Option<Value> {
    if r.ring_changes.is_empty() && s.faults.break_link.is_empty() {
        return None;
    }
    let link = |st: &ringsync_proto::node::RingState| match st {
        ringsync_proto::node::RingState::Whole => Value::Null,
        ringsync_proto::node::RingState::Broken { link } => json!(link),
    };
    let changes: Vec<Value> = r
        .ring_changes
        .iter()
        .map(|c| {
            let event = match (c.from, c.to) {
                (_, ringsync_proto::node::RingState::Whole) => "healed",
                (ringsync_proto::node::RingState::Whole, _) => "broken",
                _ => "moved",
            };
            json!({
                "time_s": c.t, "cycle": c.k, "event": event,
                "from": c.from.describe(), "to": c.to.describe(),
                "broken_link": link(&c.to), "cycles_lost": c.cycles_lost,
            })
        })
        .collect();
    let end = r
        .ring_changes
        .last()
        .map_or("whole".to_string(), |c| c.to.describe());
    Some(json!({
        "scheduled": s.faults.break_link.iter().map(|b| b.to_string()).collect::<Vec<_>>(),
        "changes": changes,
        "at_end": end,
        "breaks_found": r.master.ring_breaks,
        "heals_found": r.master.ring_heals,
    }))
}

/// `summary.json` of one run, with `ringsync_version` and `schema_version` (1) first. Deterministic:
/// no wall time, no paths.
pub fn summary_json(s: &Scenario, hash: u64, r: &RunResult) -> Value {
    serde_json::to_value(run_summary(s, hash, r)).unwrap_or(Value::Null)
}

/// Version of the schema of a run's summary.json ([`RunSummary`]; docs/schemas/).
pub const SUMMARY_SCHEMA_VERSION: u32 = 1;

/// One axis in summary.json.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct AxisSummary {
    /// Axis, 1-based.
    pub axis: usize,
    /// RMS of its position error e \[rad\].
    pub rms_e: f64,
    /// Largest |e| \[rad\].
    pub max_e: f64,
    /// RMS of its sync error ε \[rad\].
    pub rms_eps: f64,
    /// Largest |ε| \[rad\].
    pub max_eps: f64,
    /// RMS of its command u \[V\].
    pub rms_u: f64,
    /// Largest |u| \[V\].
    pub peak_u: f64,
    /// Cycles its drive was held at ±u_max.
    pub saturations: u64,
    /// Largest residual clock error of its slave after the first half of the run \[ns\].
    pub clock_error_max_ns: f64,
    /// RMS of that clock error \[ns\].
    pub clock_error_rms_ns: f64,
}

/// The frames of a run, as the master and the links count them.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct FramesSummary {
    /// Frames the master sent.
    pub sent_by_master: u64,
    /// Frames lost on the links.
    pub lost_on_links: u64,
    /// Frames corrupted on the links.
    pub corrupted_on_links: u64,
    /// Lumped frames that did not come back.
    pub lumped_lost: u64,
    /// Samples missing from lumped frames.
    pub samples_missing: u64,
    /// Samples that were last cycle's again.
    pub samples_stale: u64,
    /// P2P slices without a valid response.
    pub slices_failed: u64,
    /// Commands sent again in a reserve slice.
    pub retries: u64,
    /// Retries answered.
    pub retries_ok: u64,
    /// Commands never acknowledged.
    pub commands_lost: u64,
    /// Responses whose echoed command differs from the one sent.
    pub command_mismatches: u64,
}

/// One slave's counters.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct SlaveSummary {
    /// Slave, 1-based.
    pub slave: usize,
    /// Clock syncs taken.
    pub syncs: u64,
    /// Commands applied.
    pub commands: u64,
    /// Frames refused.
    pub rejected: u64,
    /// Retries answered as repeats.
    pub retries_answered: u64,
    /// Times its clock relocked.
    pub clock_relocks: u64,
    /// Times its clock acquisition started again.
    pub clock_acquisitions_restarted: u64,
}

/// The group stop of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GroupStop {
    /// When \[s\].
    pub time_s: f64,
    /// Why: `following-error`, `axis-fault`, `no-response`, `no-feedback`,
    /// `command-mismatch`, `sync-error-trip`, `following-error-trip`, `ring-split`.
    pub reason: String,
    /// The axis, 1-based.
    pub axis: usize,
    /// The error that tripped it \[rad\], where one did.
    pub error_rad: Option<f64>,
    /// A split ring's slaves cut off, 1-based.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub isolated_slaves: Option<Vec<usize>>,
}

/// A slave's watchdog expiry.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct WatchdogEvent {
    /// Slave, 1-based.
    pub slave: usize,
    /// When \[s\].
    pub time_s: f64,
}

/// A step of a fault reaction.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct FaultStepSummary {
    /// When \[s\].
    pub time_s: f64,
    /// Axis, 1-based.
    pub axis: usize,
    /// What happened.
    pub step: String,
    /// Why, in words.
    pub detail: String,
}

/// What went wrong in a run and what the nodes did about it.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct FaultsSummary {
    /// Watchdog expiries.
    pub watchdog: Vec<WatchdogEvent>,
    /// The group stop, if any.
    pub group_stop: Option<GroupStop>,
    /// What a slave that loses its master does: `brake` or `torque-off`.
    pub safe_state: String,
    /// Every step of the fault reactions.
    pub steps: Vec<FaultStepSummary>,
    /// The node or link that failed, in words, if one did.
    pub failed: Option<String>,
    /// The slave that failed, 1-based, if one did.
    pub failed_slave: Option<usize>,
}

/// Counts by name, written as one JSON object in their order (the reasons' order of
/// `ringsync_proto::node::Reject`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Counts(pub Vec<(String, u64)>);

impl Serialize for Counts {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap as _;
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

impl JsonSchema for Counts {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Counts".into()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        <std::collections::BTreeMap<String, u64>>::json_schema(generator)
    }
}

/// Frames refused by the nodes.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct RejectedSummary {
    /// All of them.
    pub total: u64,
    /// Per reason, every reason listed.
    pub by_reason: Counts,
    /// The master's, per reason.
    pub master: Counts,
    /// Each slave's, per reason, then `slave` (1-based).
    pub slaves: Vec<Counts>,
}

/// A run's summary.json (`sim`; `rt` adds its own keys): schema version
/// [`SUMMARY_SCHEMA_VERSION`]. Deterministic: no wall time, no paths.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct RunSummary {
    /// The version of ringsync that wrote it.
    pub ringsync_version: String,
    /// The version of this schema.
    pub schema_version: u32,
    /// The scenario's name.
    pub scenario: String,
    /// FNV-1a 64-bit hash of the scenario's text, hexadecimal.
    pub scenario_hash: String,
    /// The seed of every random draw.
    pub seed: u64,
    /// `p2p-lumped` or `lumped-only`.
    pub plan: String,
    /// The law as run (`pd`, `pd+ff`, `sync`, …).
    pub controller: String,
    /// `hold`, `linear` or `paper`.
    pub estimator: String,
    /// Cycles run.
    pub cycles: i64,
    /// T_cyc \[s\].
    pub t_cyc_s: f64,
    /// Track-RMSE (eq. 26) \[rad\].
    pub track_rmse: f64,
    /// Sync-RMSE (eq. 27) \[rad\].
    pub sync_rmse: f64,
    /// Per axis.
    pub axes: Vec<AxisSummary>,
    /// The frames.
    pub frames: FramesSummary,
    /// Frames refused.
    pub rejected: RejectedSummary,
    /// Per slave.
    pub slaves: Vec<SlaveSummary>,
    /// Largest residual clock error of any slave \[ns\].
    pub clock_error_max_ns: f64,
    /// Faults and reactions.
    pub faults: FaultsSummary,
    /// What the run assumes that the paper does not state.
    pub assumptions: Vec<String>,
    /// The sync and following monitors: their limits, counts and first trip (when on).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub monitor: Option<Value>,
    /// Every change of the ring the master found (when the ring changed or a break was
    /// scheduled).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ring: Option<Value>,
    /// What the nodes' start-up phase measured (measured path delays).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_up: Option<Value>,
    /// A part program's RMS contour error \[mm\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contour_rmse: Option<f64>,
    /// Its largest contour error \[mm\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contour_max: Option<f64>,
    /// Its mean contour error \[mm\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contour_mean: Option<f64>,
    /// The program: its file, duration, the circular tests (docs/programs.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub program: Option<Value>,
}

fn stop_summary(stop: &Option<(f64, StopReason)>) -> Option<GroupStop> {
    serde_json::from_value(stop_json(stop)).ok()
}

fn by_reason(r: &Rejections) -> Counts {
    Counts(
        r.iter()
            .map(|(why, n)| (why.name().to_string(), n))
            .collect(),
    )
}

/// A run's summary.json as its type.
pub fn run_summary(s: &Scenario, hash: u64, r: &RunResult) -> RunSummary {
    let m = &r.summary;
    let mc = &r.master;
    let total = r
        .slaves
        .iter()
        .fold(r.master.rejected, |acc, c| acc.plus(&c.rejected));
    let mut summary = RunSummary {
        ringsync_version: crate::provenance::RINGSYNC_VERSION.into(),
        schema_version: SUMMARY_SCHEMA_VERSION,
        scenario: s.name.clone(),
        scenario_hash: format!("{hash:016x}"),
        seed: s.seed,
        plan: s.ring.plan.name().into(),
        controller: s.law_name().to_string(),
        estimator: s.control.estimator.name().into(),
        cycles: r.cycles,
        t_cyc_s: s.ring.cycle.secs(),
        track_rmse: m.track_rmse,
        sync_rmse: m.sync_rmse,
        axes: m
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| AxisSummary {
                axis: i + 1,
                rms_e: a.rms_e,
                max_e: a.max_e,
                rms_eps: a.rms_eps,
                max_eps: a.max_eps,
                rms_u: a.rms_u,
                peak_u: a.peak_u,
                saturations: a.saturations,
                clock_error_max_ns: r.clock_error_max_ns[i],
                clock_error_rms_ns: r.clock_error_rms_ns[i],
            })
            .collect(),
        frames: FramesSummary {
            sent_by_master: mc.frames_sent,
            lost_on_links: r.links.lost,
            corrupted_on_links: r.links.corrupted,
            lumped_lost: mc.lumped_lost,
            samples_missing: mc.samples_missing,
            samples_stale: mc.samples_stale,
            slices_failed: mc.slices_failed,
            retries: mc.retries,
            retries_ok: mc.retries_ok,
            commands_lost: mc.commands_lost,
            command_mismatches: mc.command_mismatches,
        },
        rejected: RejectedSummary {
            total: total.total(),
            by_reason: by_reason(&total),
            master: by_reason(&r.master.rejected),
            slaves: r
                .slaves
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let mut m = by_reason(&c.rejected);
                    m.0.push(("slave".into(), i as u64 + 1));
                    m
                })
                .collect(),
        },
        slaves: r
            .slaves
            .iter()
            .enumerate()
            .map(|(i, c)| SlaveSummary {
                slave: i + 1,
                syncs: c.syncs,
                commands: c.commands,
                rejected: c.rejected.total(),
                retries_answered: c.duplicates,
                clock_relocks: c.relocks,
                clock_acquisitions_restarted: c.acquisitions_restarted,
            })
            .collect(),
        clock_error_max_ns: r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        faults: FaultsSummary {
            watchdog: r
                .watchdog
                .iter()
                .map(|&(slave, time_s)| WatchdogEvent { slave, time_s })
                .collect(),
            group_stop: stop_summary(&r.group_stop),
            safe_state: s.faults.safe_state.name().into(),
            steps: r
                .faults
                .iter()
                .map(|f| FaultStepSummary {
                    time_s: f.t,
                    axis: f.axis,
                    step: f.step.name().into(),
                    detail: f.step.detail(),
                })
                .collect(),
            failed: r.ring_break.map(|b| b.describe()),
            failed_slave: r.ring_break.and_then(|b| b.slave()),
        },
        assumptions: assumptions(s).into_iter().map(String::from).collect(),
        monitor: monitor_json(s, r),
        ring: ring_json(s, r),
        start_up: start_up_json(r),
        contour_rmse: None,
        contour_max: None,
        contour_mean: None,
        program: None,
    };
    if let (Some(p), ringsync_model::scenario::TrajectorySpec::Program { program }) =
        (&r.path, &s.trajectory)
    {
        summary.contour_rmse = Some(p.rmse);
        summary.contour_max = Some(p.max);
        summary.contour_mean = Some(p.mean);
        summary.program = crate::path::path_json(program, p)
            .into_iter()
            .find(|(k, _)| *k == "program")
            .map(|(_, v)| v);
    }
    summary
}

/// The `start_up` key of summary.json: what the nodes' start-up phase measured (one link,
/// each residence and path delay, the round trips), the delay each slave took, and the
/// planner's path delays beside them; `None` (no key) when the path delays were the plan's.
pub fn start_up_json(r: &RunResult) -> Option<Value> {
    let c = r.start_up.as_ref()?;
    let m = &c.measured;
    let ns = |v: &[ringsync_proto::Duration]| v.iter().map(|d| d.as_ns()).collect::<Vec<_>>();
    let mut rtt = ns(&m.round_trips);
    rtt.sort_unstable();
    let at = |q: f64| {
        let i = ((rtt.len().saturating_sub(1)) as f64 * q).round() as usize;
        rtt.get(i).copied()
    };
    Some(json!({
        "path_delays": "measured",
        "probes": m.probes,
        "probes_back": m.probes_back,
        "probes_complete": m.complete,
        "closing_frames": m.closing_sent,
        "link_ns": m.link.as_ns(),
        "residence_ns": ns(&m.residence),
        "path_delay_ns": ns(&m.path),
        "taken_by_slaves_ns": c.taken.iter().map(|d| d.map(|d| d.as_ns())).collect::<Vec<_>>(),
        "planned_path_delay_ns": ns(&c.planned),
        "measured_minus_planned_ns": m.path.iter().zip(&c.planned).map(|(a, b)| a.as_ns() - b.as_ns()).collect::<Vec<_>>(),
        "timestamp_resolution_ns": c.resolution.as_ns(),
        "round_trip_ns": {"min": at(0.0), "p50": at(0.5), "p99": at(0.99), "max": at(1.0)},
        "rejected_by_slaves": c.slaves_rejected,
        "took_ms": c.took.as_ns() as f64 * 1e-6,
        "assumption": "every link of the ring has the same delay",
    }))
}

/// The start-up phase's line for the run's text; `None` when the path delays were the
/// plan's.
pub fn start_up_line(r: &RunResult) -> Option<String> {
    let c = r.start_up.as_ref()?;
    let m = &c.measured;
    let us = |v: &[ringsync_proto::Duration]| {
        v.iter()
            .map(|d| format!("{:.3}", d.as_us_f64()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let worst = m
        .path
        .iter()
        .zip(&c.planned)
        .map(|(a, b)| (a.as_ns() - b.as_ns()).abs())
        .max()
        .unwrap_or(0);
    let against = if worst <= c.resolution.as_ns() {
        format!("the planner's within {worst} ns")
    } else {
        format!("the planner's wire figures {} µs", us(&c.planned))
    };
    // Behind transparent relays (a ring of node processes with kernel stamps) the slaves'
    // clocks take their links alone: the relays put their residences in the stamps.
    let took: Vec<ringsync_proto::Duration> = c.taken.iter().flatten().copied().collect();
    let took = if took.len() == m.path.len() && took != m.path {
        format!(
            "; the slaves' clocks took their links alone, {} µs (transparent relays)",
            us(&took)
        )
    } else {
        String::new()
    };
    Some(format!(
        "path delays measured by the nodes ({} of {} probes back, every link taken equal): {} µs; {against}{took}",
        m.probes_back,
        m.probes,
        us(&m.path)
    ))
}

/// The `monitor` key of summary.json: the limits and every warning and trip (axes
/// 1-based), the first trip and its reaction; `None` (no key) when no limit is set.
pub fn monitor_json(s: &Scenario, r: &RunResult) -> Option<Value> {
    let set = s.monitor_settings();
    if !set.enabled() {
        return None;
    }
    let limits = |l: &ringsync_model::monitor::Limits| {
        json!({
            "warn_rad": l.warn, "trip_rad": l.trip,
            "filter_s": l.filter.as_ns() as f64 * 1e-9, "reaction": l.reaction.name(),
        })
    };
    let events: Vec<Value> = r
        .monitor
        .iter()
        .map(|e| {
            json!({
                "time_s": e.t, "axis": e.axis, "monitor": e.kind.monitor(), "level": e.kind.level(),
                "change": if e.raised { "raised" } else { "cleared" }, "value_rad": e.value,
            })
        })
        .collect();
    let count = |monitor: &str, level: &str| {
        r.monitor
            .iter()
            .filter(|e| e.raised && e.kind.monitor() == monitor && e.kind.level() == level)
            .count()
    };
    let first_trip = r
        .monitor
        .iter()
        .find(|e| e.raised && e.kind.level() == "trip");
    Some(json!({
        "sync": limits(&set.sync),
        "following": limits(&set.following),
        "sync_warnings": count("sync", "warning"),
        "sync_trips": count("sync", "trip"),
        "following_warnings": count("following", "warning"),
        "following_trips": count("following", "trip"),
        "first_trip": first_trip.map(|e| json!({
            "time_s": e.t, "axis": e.axis, "monitor": e.kind.monitor(), "value_rad": e.value,
            "reaction": if e.kind.monitor() == "sync" { set.sync.reaction.name() } else { set.following.reaction.name() },
        })),
        "events": events,
    }))
}

/// The monitors in words, one line each: the limits, then every warning and trip (axes
/// 1-based); `None` when no limit is set.
pub fn monitor_lines(s: &Scenario, r: &RunResult) -> Option<Vec<String>> {
    let set = s.monitor_settings();
    if !set.enabled() {
        return None;
    }
    let mut lines = Vec::new();
    for (name, l) in [
        ("sync error ε", &set.sync),
        ("following error", &set.following),
    ] {
        if !l.enabled() {
            lines.push(format!("{name} monitor: off"));
            continue;
        }
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| {
                    if *x > 0.0 {
                        format!("{x}")
                    } else {
                        "off".into()
                    }
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        lines.push(format!(
            "{name} monitor: warning at [{}] rad, trip at [{}] rad, filter {:.1} ms, reaction on trip {}",
            list(&l.warn),
            list(&l.trip),
            l.filter.as_ns() as f64 * 1e-6,
            l.reaction.name()
        ));
    }
    if r.monitor.is_empty() {
        lines.push("no warning, no trip: every axis stayed in sync".into());
    }
    for e in &r.monitor {
        lines.push(format!(
            "{:.4} s: axis {} {} {} {} ({:+.5} rad)",
            e.t,
            e.axis,
            e.kind.monitor(),
            e.kind.level(),
            if e.raised { "raised" } else { "cleared" },
            e.value
        ));
    }
    Some(lines)
}

/// `trace.csv`: one row per cycle and axis.
pub fn trace_csv(r: &RunResult) -> String {
    let mut o = Vec::with_capacity(r.trace.len() * 120);
    // Writing to a Vec cannot fail.
    let _ = write_trace_csv(r, &mut o);
    String::from_utf8(o).unwrap_or_default()
}

/// The header of trace.csv: the columns and their units.
pub const TRACE_CSV_HEADER: &str =
    "t_s,axis,x_d_rad,x_rad,e_rad,eps_rad,u_v,sample_time_s,apply_time_s,clock_error_ns\n";

/// Streams trace.csv to `w`, a row at a time through one line buffer (the trace is never
/// held whole as text), with the bytes of [`trace_csv`]: times and positions to 9 decimals
/// (t and u to 6), the clock error to whole ns ([`crate::fixed`]).
pub fn write_trace_csv(r: &RunResult, w: &mut impl std::io::Write) -> std::io::Result<()> {
    w.write_all(TRACE_CSV_HEADER.as_bytes())?;
    crate::fixed::write_lines(w, r.trace.rows(), |o, row| push_trace_row(o, &row))
}

/// Appends one line of trace.csv (with its newline) to `o`: the bytes [`write_trace_csv`]
/// writes for `row`, for a writer that streams the rows as a run makes them.
pub fn push_trace_row(o: &mut Vec<u8>, row: &ringsync_model::result::TraceRow) {
    use crate::fixed::{push_fixed, push_u64};
    push_fixed(o, row.t, 6);
    o.push(b',');
    push_u64(o, row.axis as u64);
    for (v, d) in [
        (row.x_d, 9),
        (row.x, 9),
        (row.e, 9),
        (row.eps, 9),
        (row.u, 6),
        (row.sample_time, 9),
        (row.apply_time, 9),
        (row.clock_error_ns, 0),
    ] {
        o.push(b',');
        push_fixed(o, v, d);
    }
    o.push(b'\n');
}

/// `s` escaped for HTML text.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Per-axis series of one trace column.
pub(crate) fn per_axis(
    r: &RunResult,
    f: fn(&ringsync_model::result::Trace, usize) -> f64,
) -> Vec<crate::plot::Series<'static>> {
    use crate::plot::PALETTE;
    (1..=r.summary.axes.len())
        .map(|a| {
            axis_series(&r.trace, a, f)
                .finish(format!("axis {a}"), PALETTE[(a - 1) % PALETTE.len()])
        })
        .collect()
}

/// Axis `a`'s (1-based) points (t, f(trace, row)), thinned as they are built: a long run's
/// column is never copied whole, and `f` reads the one column it plots. The trace holds one
/// group of n rows per cycle, so axis a's rows are every n-th, from a − 1.
pub(crate) fn axis_series(
    trace: &ringsync_model::result::Trace,
    a: usize,
    f: impl Fn(&ringsync_model::result::Trace, usize) -> f64,
) -> crate::plot::Thinning {
    let n = trace.axes.max(1);
    let rows = (a - 1..trace.len()).step_by(n);
    let mut t = crate::plot::Thinning::new(rows.len());
    for i in rows {
        t.push((trace.t[i / n], f(trace, i)));
    }
    t
}

/// The figures of one run (made with a trace): position errors, sync errors, commands and
/// clock errors per axis, and the cycle's timing diagram when given.
pub fn run_figures(timing: Option<String>, r: &RunResult) -> Vec<(String, String)> {
    use crate::plot::line_chart;
    let mut figs: Vec<(&'static str, String)> = Vec::new();
    if let Some(t) = timing {
        figs.push(("cycle.svg", t));
    }
    figs.push((
        "position-errors.svg",
        line_chart(
            "Position errors e = x^d − x",
            "t [s]",
            "e [rad]",
            &per_axis(r, |t, i| t.e(i)),
        ),
    ));
    figs.push((
        "sync-errors.svg",
        line_chart(
            "Synchronisation errors ε = Te",
            "t [s]",
            "ε [rad]",
            &per_axis(r, |t, i| t.eps[i]),
        ),
    ));
    figs.push((
        "commands.svg",
        line_chart("Commands", "t [s]", "u [V]", &per_axis(r, |t, i| t.u[i])),
    ));
    // The clocks' acquisition (microseconds off at t = 0) would flatten the nanoseconds
    // that follow into a line: the figure starts once every slave is within 1 µs for good.
    let tr = &r.trace;
    let n = tr.axes.max(1);
    let (mut settled, mut before) = (0.0, 0.0f64);
    for i in 0..tr.len() {
        let e = tr.clock_error_ns[i].abs();
        if e > 1000.0 {
            settled = tr.t.get(i / n + 1).copied().unwrap_or(settled);
            before = before.max(e);
        }
    }
    let end = tr.t.last().copied().unwrap_or(0.0);
    let (title, clock) = if settled > 0.0 && settled < end {
        let series = (1..=r.summary.axes.len())
            .map(|a| {
                let rows = (a - 1..tr.len())
                    .step_by(n)
                    .filter(|&i| tr.t[i / n] >= settled);
                let mut th = crate::plot::Thinning::new(rows.clone().count());
                for i in rows {
                    th.push((tr.t[i / n], tr.clock_error_ns[i]));
                }
                th.finish(
                    format!("axis {a}"),
                    crate::plot::PALETTE[(a - 1) % crate::plot::PALETTE.len()],
                )
            })
            .collect::<Vec<_>>();
        (
            format!(
                "Slave clock minus master clock at each cycle start, from t = {settled:.3} s (acquisition before: up to {before:.0} ns)"
            ),
            series,
        )
    } else {
        (
            "Slave clock minus master clock, at each cycle start".to_string(),
            per_axis(r, |t, i| t.clock_error_ns[i]),
        )
    };
    figs.push((
        "clock-errors.svg",
        line_chart(&title, "t [s]", "clock error [ns]", &clock),
    ));
    let mut figs: Vec<(String, String)> =
        figs.into_iter().map(|(n, s)| (n.to_string(), s)).collect();
    if let Some(p) = &r.path {
        figs.extend(crate::path::path_figures(p));
    }
    figs
}

/// One self-contained HTML page for one run.
pub fn run_html(s: &Scenario, hash: u64, r: &RunResult, figures: &[(String, String)]) -> String {
    let m = &r.summary;
    let mc = &r.master;
    let mut o = String::new();
    let _ = write!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>ringsync: {name}</title>\
<style>body{{font-family:DejaVu Sans,Verdana,sans-serif;max-width:980px;margin:2em auto;line-height:1.45;color:#222}}\
table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 10px;text-align:right}}\
th:first-child,td:first-child{{text-align:left}}figure svg{{max-width:100%;height:auto}}code{{background:#f4f4f4;padding:0 3px}}.note{{color:#555;font-size:90%}}</style></head><body>\n\
<h1>ringsync run: {name}</h1>\n<p>{desc}</p>\n<p>Scenario hash <code>{hash:016x}</code>, seed {seed}, plan <code>{plan}</code>, \
controller <code>{law}</code>, estimator <code>{est}</code>; {cycles} cycles of {cyc} ms, {n} axes.</p>\n\
<table><tr><th>metric</th><th>value</th></tr>\n<tr><td>Track-RMSE (eq. 26)</td><td>{track:.6} rad</td></tr>\n\
<tr><td>Sync-RMSE (eq. 27)</td><td>{sync:.7} rad</td></tr>\n<tr><td>frames sent by the master</td><td>{sent}</td></tr>\n\
<tr><td>frames lost / corrupted on links</td><td>{lost} / {corr}</td></tr>\n<tr><td>lumped frames lost</td><td>{llost}</td></tr>\n\
<tr><td>slices failed / retries / retries that succeeded</td><td>{sf} / {rt} / {rok}</td></tr>\n\
<tr><td>commands lost</td><td>{cl}</td></tr>\n<tr><td>largest residual clock error (second half)</td><td>{clk:.0} ns</td></tr>\n\
<tr><td>group stop</td><td>{stop}</td></tr>\n<tr><td>watchdog expiries</td><td>{wd}</td></tr></table>\n",
        name = esc(&s.name),
        desc = esc(&s.description),
        seed = s.seed,
        plan = s.ring.plan.name(),
        law = s.law_name(),
        est = s.control.estimator.name(),
        cycles = r.cycles,
        cyc = s.ring.cycle.secs() * 1e3,
        n = s.axes_count(),
        track = m.track_rmse,
        sync = m.sync_rmse,
        sent = mc.frames_sent,
        lost = r.links.lost,
        corr = r.links.corrupted,
        llost = mc.lumped_lost,
        sf = mc.slices_failed,
        rt = mc.retries,
        rok = mc.retries_ok,
        cl = mc.commands_lost,
        clk = r.clock_error_max_ns.iter().copied().fold(0.0, f64::max),
        stop = r
            .group_stop
            .map_or("none".to_string(), |(t, reason)| esc(&format!(
                "at {t:.3} s: {}",
                stop_reason_text(&reason)
            ))),
        wd = if r.watchdog.is_empty() {
            "none".to_string()
        } else {
            r.watchdog
                .iter()
                .map(|(sl, t)| format!("slave {sl} at {t:.3} s"))
                .collect::<Vec<_>>()
                .join(", ")
        },
    );
    o.push_str("<table><tr><th>axis</th><th>RMS e [rad]</th><th>max |e| [rad]</th><th>RMS ε [rad]</th><th>max |ε| [rad]</th><th>RMS u [V]</th><th>peak |u| [V]</th><th>saturated cycles</th></tr>\n");
    for (i, a) in m.axes.iter().enumerate() {
        let _ = writeln!(
            o,
            "<tr><td>{}</td><td>{:.6}</td><td>{:.6}</td><td>{:.7}</td><td>{:.7}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td></tr>",
            i + 1,
            a.rms_e,
            a.max_e,
            a.rms_eps,
            a.max_eps,
            a.rms_u,
            a.peak_u,
            a.saturations
        );
    }
    o.push_str("</table>\n");
    if let Some(p) = &r.path {
        let file = match &s.trajectory {
            ringsync_model::scenario::TrajectorySpec::Program { program } => program.as_str(),
            _ => "",
        };
        let _ = writeln!(
            o,
            "<h2>Part program</h2>\n<p>Program <code>{}</code>, {:.3} s as planned. The contour error is the distance from the tool (the encoders through the transmissions) to the programmed path's geometry, at every cycle start before any group stop.</p>\n<ul>",
            esc(file),
            p.program_duration
        );
        for l in crate::path::path_lines(p) {
            let _ = writeln!(o, "<li>{}</li>", esc(&l));
        }
        o.push_str("</ul>\n");
    }
    if let Some(lines) = monitor_lines(s, r) {
        o.push_str("<h2>Sync and following-error monitors</h2>\n<ul>\n");
        for l in lines {
            let _ = writeln!(o, "<li>{}</li>", esc(&l));
        }
        o.push_str("</ul>\n");
    }
    o.push_str("<h2>Figures</h2>\n");
    for (name, svg) in figures {
        let body = svg.split_once("?>\n").map_or(svg.as_str(), |(_, b)| b);
        let _ = writeln!(
            o,
            "<figure>{body}<figcaption class=\"note\">{name}</figcaption></figure>"
        );
    }
    o.push_str("<h2>Assumptions not in the paper</h2>\n<ul>\n");
    for a in assumptions(s)
        .iter()
        .chain(ringsync_proto::plan::ASSUMPTIONS)
    {
        let _ = writeln!(o, "<li>{}</li>", esc(a));
    }
    let _ = writeln!(
        o,
        "</ul>\n<p class=\"note\">Every parameter: <code>ringsync scenario show</code> for built-in scenarios, or the scenario file. \
Generated by ringsync; the same scenario and seed give the same page.</p>\n</body></html>"
    );
    o
}
