//! The cycle as a timing diagram like the paper's Fig. 1: one lane for the master and one per
//! slave, each frame a bar where a node sends (upper half) or receives (lower half) it, the
//! phases shaded and labelled.

use ringsync_proto::CyclePlan;
use ringsync_proto::plan::{FrameRef, Node, PhaseKind};

use crate::svg::{Svg, nice_step};

/// Most slaves a timing diagram draws (one lane each).
pub const MAX_SVG_SLAVES: u32 = 64;

const WIDTH: f64 = 1100.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 20.0;
const IDLE_W: f64 = 120.0;
const TOP: f64 = 64.0;
const LANE: f64 = 28.0;

fn colour(f: FrameRef) -> &'static str {
    match f {
        FrameRef::Lumped(_) => "#4e79a7",
        FrameRef::Command(_) => "#f28e2b",
        FrameRef::Response(_) => "#59a14f",
    }
}

fn frame_name(f: FrameRef) -> String {
    match f {
        FrameRef::Lumped(j) => format!("lumped frame {}", j + 1),
        FrameRef::Command(i) => format!("command to slave {i}"),
        FrameRef::Response(i) => format!("response of slave {i}"),
    }
}

fn node_name(n: Node) -> String {
    match n {
        Node::Master => "master".into(),
        Node::Slave(i) => format!("slave {i}"),
    }
}

fn us(ns: i64) -> String {
    format!("{}.{:03}", ns / 1_000, (ns % 1_000).abs())
}

/// Draws the cycle of `plan` as an SVG document; `None` when the ring has more than
/// [`MAX_SVG_SLAVES`] slaves.
pub fn timing_svg(plan: &CyclePlan) -> Option<String> {
    let n = plan.slaves();
    if n > MAX_SVG_SLAVES {
        return None;
    }
    let tl = plan.timeline();
    let busy = tl.busy_end().as_ns().max(1) as f64;
    let has_idle = tl.phase(PhaseKind::Idle).is_some();
    let plot_w = WIDTH - LEFT - RIGHT - if has_idle { IDLE_W } else { 0.0 };
    let x = |ns: i64| LEFT + ns as f64 / busy * plot_w;
    let lanes = n as f64 + 1.0;
    let bottom = TOP + lanes * LANE;
    let height = bottom + 78.0;
    let lane_y = |node: Node| {
        TOP + match node {
            Node::Master => 0.0,
            Node::Slave(i) => f64::from(i) * LANE,
        }
    };
    let mut s = Svg::new(WIDTH, height);
    s.text(
        LEFT,
        18.0,
        &format!(
            "One cycle of the proposed plan: {n} slaves, {} Mbit/s, T_cyc = {} µs (event level, physical ring path)",
            plan.params.bit_rate_bps as f64 / 1e6,
            us(plan.params.t_cyc.as_ns())
        ),
        "start",
        r#"font-size="13" font-weight="bold""#,
    );
    // Phases: shaded bands with labels above the lanes.
    for (k, ph) in tl.phases.iter().enumerate() {
        if ph.kind == PhaseKind::Idle {
            continue;
        }
        let (x0, x1) = (x(ph.start.as_ns()), x(ph.end.as_ns()));
        let fill = match ph.kind {
            PhaseKind::Sync => "#dbe6f1",
            PhaseKind::Rest => "#eeeeee",
            PhaseKind::Slice(_) if k % 2 == 0 => "#fdf0e2",
            PhaseKind::Slice(_) => "#fae3cb",
            _ => "#f3e8f4",
        };
        let label = match ph.kind {
            PhaseKind::Sync => "sync".to_string(),
            PhaseKind::Rest => "T_rest".to_string(),
            PhaseKind::Slice(i) => format!("{i}"),
            PhaseKind::Reserve(_) => "res".to_string(),
            PhaseKind::Idle => String::new(),
        };
        let title = format!(
            "{label}: {} – {} µs",
            us(ph.start.as_ns()),
            us(ph.end.as_ns())
        );
        s.rect(
            x0,
            TOP - 6.0,
            x1 - x0,
            bottom - TOP + 6.0,
            &format!(r##"fill="{fill}" stroke="white""##),
            Some(&title),
        );
        if x1 - x0 >= 7.0 * label.chars().count() as f64 {
            s.text(
                (x0 + x1) / 2.0,
                TOP - 10.0,
                &label,
                "middle",
                r##"fill="#333""##,
            );
        }
    }
    // Group labels over the phase labels.
    let p2p = tl.phase(PhaseKind::Slice(1)).map(|p| p.start.as_ns());
    let res_end = tl.busy_end().as_ns();
    let sync_end = tl
        .phase(PhaseKind::Sync)
        .map(|p| p.end.as_ns())
        .unwrap_or(0);
    s.text(
        x(sync_end / 2),
        TOP - 26.0,
        "clock-sync phase",
        "middle",
        r#"font-style="italic""#,
    );
    if let Some(p) = p2p {
        s.text(
            x((p + res_end) / 2),
            TOP - 26.0,
            "point-to-point phase (slices, reserve)",
            "middle",
            r#"font-style="italic""#,
        );
    }
    // Lanes.
    for lane in std::iter::once(Node::Master).chain((1..=n).map(Node::Slave)) {
        let y = lane_y(lane);
        s.line(
            LEFT,
            y + LANE,
            WIDTH - RIGHT,
            y + LANE,
            r##"stroke="#cccccc""##,
        );
        s.text(
            LEFT - 8.0,
            y + LANE / 2.0 + 4.0,
            &node_name(lane),
            "end",
            "",
        );
    }
    // Frames: sends in the upper half of a lane, receptions in the lower half.
    for p in &tl.passages {
        let y = lane_y(p.node);
        let c = colour(p.frame);
        for (span, dy, op, verb) in [(p.tx, 5.0, "1", "sends"), (p.rx, 15.0, "0.55", "receives")] {
            if let Some(sp) = span {
                let title = format!(
                    "{} {verb} {}: {} – {} µs",
                    node_name(p.node),
                    frame_name(p.frame),
                    us(sp.start.as_ns()),
                    us(sp.end.as_ns())
                );
                s.rect(
                    x(sp.start.as_ns()),
                    y + dy,
                    x(sp.end.as_ns()) - x(sp.start.as_ns()),
                    9.0,
                    &format!(r#"fill="{c}" fill-opacity="{op}""#),
                    Some(&title),
                );
            }
        }
    }
    // Idle, drawn after an axis break.
    if let Some(idle) = tl.phase(PhaseKind::Idle) {
        let x0 = LEFT + plot_w + 14.0;
        let x1 = WIDTH - RIGHT;
        s.rect(
            x0,
            TOP - 6.0,
            x1 - x0,
            bottom - TOP + 6.0,
            r##"fill="#f7f7f7" stroke="#dddddd""##,
            None,
        );
        s.text(
            (x0 + x1) / 2.0,
            TOP - 10.0,
            "idle",
            "middle",
            r##"fill="#333""##,
        );
        s.text(
            (x0 + x1) / 2.0,
            (TOP + bottom) / 2.0,
            &format!("{} µs", us((idle.end - idle.start).as_ns())),
            "middle",
            "",
        );
        let xb = LEFT + plot_w + 7.0;
        s.polyline(
            &[
                (xb - 4.0, bottom + 4.0),
                (xb, bottom - 4.0),
                (xb + 4.0, bottom + 4.0),
                (xb + 8.0, bottom - 4.0),
            ],
            r#"fill="none" stroke="black""#,
        );
        s.text(x1, bottom + 16.0, &us(plan.params.t_cyc.as_ns()), "end", "");
    }
    // Time axis [µs].
    let span_us = busy / 1_000.0;
    let step = nice_step(span_us, 10.0);
    s.line(LEFT, bottom, LEFT + plot_w, bottom, r#"stroke="black""#);
    let mut t = 0.0;
    while t <= span_us + 1e-9 {
        let xx = LEFT + t / span_us * plot_w;
        s.line(xx, bottom, xx, bottom + 4.0, r#"stroke="black""#);
        s.text(xx, bottom + 16.0, &format!("{t}"), "middle", "");
        t += step;
    }
    s.text(
        LEFT + plot_w / 2.0,
        bottom + 32.0,
        "time from cycle start [µs]",
        "middle",
        "",
    );
    // Legend.
    let ly = bottom + 52.0;
    let mut lx = LEFT;
    for (label, c, op) in [
        ("lumped frame", "#4e79a7", "1"),
        ("command frame", "#f28e2b", "1"),
        ("response frame", "#59a14f", "1"),
        (
            "upper bar: node sends, lower (pale): node receives",
            "#999999",
            "0.55",
        ),
    ] {
        s.rect(
            lx,
            ly - 9.0,
            14.0,
            9.0,
            &format!(r#"fill="{c}" fill-opacity="{op}""#),
            None,
        );
        s.text(lx + 18.0, ly, label, "start", "");
        lx += 30.0 + 6.5 * label.chars().count() as f64;
    }
    Some(s.finish())
}
