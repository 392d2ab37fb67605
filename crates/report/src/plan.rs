//! The cycle plan as a readable budget table and as one JSON object.

use std::fmt::Write as _;

use ringsync_proto::plan::ASSUMPTIONS;
use ringsync_proto::{CyclePlan, Duration, PlanKind, max_slaves};
use serde_json::{Value, json};

/// Rows of T_slot(i) shown one by one; longer rings collapse the middle into one row.
const SLOT_ROWS: usize = 16;

fn us(d: Duration) -> String {
    let sign = if d.is_negative() { "-" } else { "" };
    let a = d.as_ns().unsigned_abs();
    format!("{sign}{}.{:03}", a / 1_000, a % 1_000)
}

fn share(d: Duration, t_cyc: Duration) -> String {
    format!("{:.2} %", d.as_ns() as f64 * 100.0 / t_cyc.as_ns() as f64)
}

fn bit_rate(bps: u64) -> String {
    match bps {
        b if b % 1_000_000_000 == 0 => format!("{} Gbit/s", b / 1_000_000_000),
        b if b % 1_000_000 == 0 => format!("{} Mbit/s", b / 1_000_000),
        b if b % 1_000 == 0 => format!("{} kbit/s", b / 1_000),
        b => format!("{b} bit/s"),
    }
}

/// Largest ring that fits the plan's T_cyc with the plan's other parameters.
fn largest(p: &CyclePlan, kind: PlanKind) -> u32 {
    max_slaves(&p.params, kind).unwrap_or(0)
}

/// The budget table: every term in µs (ns resolution) with its share of T_cyc, the other
/// plan for comparison, and the assumptions. For the proposed plan the terms are those of
/// eq. 1-2, followed by the event-level figures.
pub fn plan_table(p: &CyclePlan, kind: PlanKind) -> String {
    match kind {
        PlanKind::P2pLumped => p2p_table(p),
        PlanKind::LumpedOnly => lumped_only_table(p),
    }
}

fn row(o: &mut String, t_cyc: Duration, term: &str, what: &str, d: Duration) {
    let _ = writeln!(
        o,
        "  {:<24} {:<40} {:>12} {:>9}",
        term,
        what,
        us(d),
        share(d, t_cyc)
    );
}

fn assumptions(o: &mut String) {
    let _ = writeln!(o, "\nAssumptions not in the paper:");
    for a in ASSUMPTIONS {
        let _ = writeln!(o, "  - {a}");
    }
}

fn header(o: &mut String, p: &CyclePlan, plan: &str) {
    let n = p.slaves();
    let _ = writeln!(
        o,
        "Cycle plan: {n} slave{}, {}, T_cyc = {} µs, {plan}",
        if n == 1 { "" } else { "s" },
        bit_rate(p.params.bit_rate_bps),
        us(p.params.t_cyc)
    );
    let _ = writeln!(
        o,
        "hop latency L = {} µs (PHY tx {} + cable {} + PHY rx {}), residence T_t = {} µs, response delay T_ti = {} µs\n",
        us(p.hop),
        us(p.link.phy_tx),
        us(p.link.cable),
        us(p.link.phy_rx),
        us(p.params.residence),
        us(p.params.response_delay)
    );
    let _ = writeln!(
        o,
        "  {:<24} {:<40} {:>12} {:>9}",
        "term", "what", "time [µs]", "share"
    );
}

fn lumped_what(bytes: &[usize]) -> String {
    if bytes.len() == 1 {
        format!("lumped frame on the wire, {} B", bytes[0])
    } else {
        format!("{} lumped frames back to back", bytes.len())
    }
}

fn lumped_only_table(p: &CyclePlan) -> String {
    let n = p.slaves();
    let t_cyc = p.params.t_cyc;
    let mut o = String::new();
    header(
        &mut o,
        p,
        "lumped-only plan of ref. [3] (one lumped frame, controllers in the slaves)",
    );
    let lo = &p.lumped_only;
    row(
        &mut o,
        t_cyc,
        "T_lmf",
        &lumped_what(&lo.lumped.frame_bytes),
        lo.lumped.t_lmf,
    );
    row(
        &mut o,
        t_cyc,
        "D_ms(n)",
        &format!("master → slave {n}, first bit"),
        p.d_ms,
    );
    row(
        &mut o,
        t_cyc,
        "D_snm",
        &format!("slave {n} → master, first bit"),
        p.d_snm,
    );
    row(
        &mut o,
        t_cyc,
        "T_rest",
        "reserve: the master computes",
        p.params.t_rest,
    );
    row(&mut o, t_cyc, "T_idle", "idle", lo.t_idle);
    row(&mut o, t_cyc, "= T_cyc", "", t_cyc);
    let _ = writeln!(
        o,
        "\nShortest cycle for {n} slaves: {} µs (lumped-only); the proposed plan needs {} µs by eq. 1, {} µs at event level.",
        us(lo.min_t_cyc),
        us(p.min_t_cyc),
        us(p.event.min_t_cyc)
    );
    let _ = writeln!(
        o,
        "Largest ring for T_cyc = {} µs: {} slaves (lumped-only), {} slaves (proposed plan).",
        us(t_cyc),
        largest(p, PlanKind::LumpedOnly),
        largest(p, PlanKind::P2pLumped)
    );
    assumptions(&mut o);
    o
}

fn p2p_table(p: &CyclePlan) -> String {
    let n = p.slaves() as usize;
    let t_cyc = p.params.t_cyc;
    let max_n = largest(p, PlanKind::P2pLumped);
    let mut o = String::new();
    header(
        &mut o,
        p,
        "proposed plan (lumped frame + point-to-point slices, eq. 1-2)",
    );
    let row = |o: &mut String, term: &str, what: &str, d: Duration| row(o, t_cyc, term, what, d);
    row(
        &mut o,
        "T_lmf",
        &lumped_what(&p.lumped.frame_bytes),
        p.t_lmf,
    );
    row(
        &mut o,
        "D_ms(n)",
        &format!("master → slave {n}, first bit"),
        p.d_ms,
    );
    row(
        &mut o,
        "D_snm",
        &format!("slave {n} → master, first bit"),
        p.d_snm,
    );
    row(
        &mut o,
        "T_rest",
        "reserve: the master computes",
        p.params.t_rest,
    );
    row(&mut o, "= T_syn", "sync phase (eq. 2)", p.t_syn);
    let slot_row = |o: &mut String, i: usize| {
        let _ = writeln!(
            o,
            "  {:<24} {:<40} {:>12} {:>9}",
            format!("T_slot({})", i + 1),
            format!("T_cmf + 2·D_ci + T_ti, D_ci = {}", us(p.d_c[i])),
            us(p.slot[i]),
            share(p.slot[i], t_cyc)
        );
    };
    if n <= SLOT_ROWS {
        (0..n).for_each(|i| slot_row(&mut o, i));
    } else {
        (0..3).for_each(|i| slot_row(&mut o, i));
        let mid: Duration = p.slot[3..n - 2].iter().copied().sum();
        row(
            &mut o,
            &format!("Σ T_slot(4..{})", n - 2),
            "slices 4 to n−2, summed",
            mid,
        );
        (n - 2..n).for_each(|i| slot_row(&mut o, i));
    }
    let reserve = p.reserve_slice * i64::from(p.reserve_slices);
    row(
        &mut o,
        &format!("reserve {}×T_slot({n})", p.reserve_slices),
        "⌊n/4⌋ + 1 slices for retries",
        reserve,
    );
    row(&mut o, "T_idle", "idle", p.t_idle);
    row(&mut o, "= T_cyc", "eq. 1", t_cyc);
    let _ = writeln!(
        o,
        "\n  T_cmf = {} µs (command frame {} B), T_rmf = {} µs (response frame {} B)",
        us(p.t_cmf),
        p.command_frame_bytes,
        us(p.t_rmf),
        p.response_frame_bytes
    );
    let _ = writeln!(
        o,
        "\nEvent level (physical ring path: each response travels on through slaves i+1..n):"
    );
    row(
        &mut o,
        "slice (each)",
        "command out → whole response back",
        p.event.slot[0],
    );
    if p.event.turnaround > Duration::ZERO {
        row(
            &mut o,
            "  of which turnaround",
            "master waits for the inter-frame gap",
            p.event.turnaround,
        );
    }
    row(
        &mut o,
        &format!("reserve {}×slice", p.reserve_slices),
        "⌊n/4⌋ + 1 slices for retries",
        p.event.reserve_slice * i64::from(p.reserve_slices),
    );
    row(&mut o, "idle", "", p.event.t_idle);
    let _ = writeln!(
        o,
        "\nShortest cycle for {n} slaves: {} µs by eq. 1, {} µs at event level.",
        us(p.min_t_cyc),
        us(p.event.min_t_cyc)
    );
    let _ = writeln!(
        o,
        "Largest ring for T_cyc = {} µs: {max_n} slaves.",
        us(t_cyc)
    );
    let _ = writeln!(
        o,
        "Lumped-only plan of ref. [3] on this ring: {} frame{} of {} B, T_lmf = {} µs, shortest cycle {} µs.",
        p.lumped_only.lumped.frame_bytes.len(),
        if p.lumped_only.lumped.frame_bytes.len() == 1 {
            ""
        } else {
            "s"
        },
        p.lumped_only.lumped.frame_bytes[0],
        us(p.lumped_only.lumped.t_lmf),
        us(p.lumped_only.min_t_cyc)
    );
    assumptions(&mut o);
    o
}

fn ns_list(v: &[Duration]) -> Vec<i64> {
    v.iter().map(|d| d.as_ns()).collect()
}

/// `ringsync plan --json`, with `ringsync_version` and `schema_version` (1) first.
pub fn plan_json(p: &CyclePlan, kind: PlanKind, events: bool) -> Value {
    crate::provenance::stamp(plan_json_fields(p, kind, events), 1)
}

/// The plan as one JSON object in integer nanoseconds (keys documented in docs/planner.md).
/// Top-level terms are the proposed plan's; `lumped_only` holds the other plan's; `plan`
/// names the plan the cycle was checked against. With `events`, the frame-by-frame timeline
/// is included.
fn plan_json_fields(p: &CyclePlan, kind: PlanKind, events: bool) -> Value {
    let max_n = largest(p, PlanKind::P2pLumped);
    let mut v = json!({
        "plan": kind.name(),
        "n": p.slaves(),
        "t_cyc_ns": p.params.t_cyc.as_ns(),
        "link_bps": p.params.bit_rate_bps,
        "lumped_frame_bytes": p.lumped.frame_bytes[0],
        "lumped_frames": p.lumped.frame_bytes.len(),
        "lumped_frame_bytes_each": p.lumped.frame_bytes,
        "command_frame_bytes": p.command_frame_bytes,
        "response_frame_bytes": p.response_frame_bytes,
        "hop_ns": p.hop.as_ns(),
        "t_lmf_ns": p.t_lmf.as_ns(),
        "d_ms_ns": p.d_ms.as_ns(),
        "d_snm_ns": p.d_snm.as_ns(),
        "t_rest_ns": p.params.t_rest.as_ns(),
        "t_syn_ns": p.t_syn.as_ns(),
        "t_cmf_ns": p.t_cmf.as_ns(),
        "t_rmf_ns": p.t_rmf.as_ns(),
        "t_t_ns": p.params.residence.as_ns(),
        "t_ti_ns": p.params.response_delay.as_ns(),
        "d_c_ns": ns_list(&p.d_c),
        "slot_ns": ns_list(&p.slot),
        "reserve_slices": p.reserve_slices,
        "reserve_slice_ns": p.reserve_slice.as_ns(),
        "t_idle_ns": p.t_idle.as_ns(),
        "min_t_cyc_ns": p.min_t_cyc.as_ns(),
        "max_n_for_t_cyc": max_n,
        "event": {
            "p2p_start_ns": p.event.p2p_start.as_ns(),
            "turnaround_ns": p.event.turnaround.as_ns(),
            "slot_ns": ns_list(&p.event.slot),
            "reserve_slice_ns": p.event.reserve_slice.as_ns(),
            "t_idle_ns": p.event.t_idle.as_ns(),
            "min_t_cyc_ns": p.event.min_t_cyc.as_ns(),
        },
        "lumped_only": {
            "lumped_frame_bytes": p.lumped_only.lumped.frame_bytes[0],
            "lumped_frames": p.lumped_only.lumped.frame_bytes.len(),
            "t_lmf_ns": p.lumped_only.lumped.t_lmf.as_ns(),
            "min_t_cyc_ns": p.lumped_only.min_t_cyc.as_ns(),
            "t_idle_ns": p.lumped_only.t_idle.as_ns(),
            "max_n_for_t_cyc": largest(p, PlanKind::LumpedOnly),
        },
        "params": {
            "slaves": p.params.slaves,
            "bit_rate_bps": p.params.bit_rate_bps,
            "phy_rx_ns": p.params.phy_rx.as_ns(),
            "phy_tx_ns": p.params.phy_tx.as_ns(),
            "cable_m": p.params.cable_m,
            "propagation_ns_per_m": p.params.propagation_ns_per_m,
            "cable_ns": p.link.cable.as_ns(),
            "slot_bytes": p.params.slot_bytes,
            "lumped_only_slot_bytes": p.params.lumped_only_slot_bytes,
            "mtu": p.params.mtu,
        },
        "assumptions": ASSUMPTIONS,
    });
    if events {
        v["timeline"] = serde_json::to_value(p.timeline()).unwrap_or(Value::Null);
    }
    v
}
