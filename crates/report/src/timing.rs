//! The cycle as a timing diagram like the paper's Fig. 1: one lane for the master and one per
//! slave, each frame a bar where a node sends (upper half) or receives (lower half) it, the
//! phases shaded and labelled.
//!
//! Three cycles can be drawn, each from the planner's own figures:
//!
//! - the proposed plan (p2p-lumped) on the whole ring: [`CyclePlan::timeline`], the
//!   event-level timeline the simulator reproduces;
//! - the lumped-only plan of ref. \[3\]: its lumped frame(s) round the ring, then T_rest and
//!   idle (`CyclePlan::lumped_only`);
//! - the proposed plan with one link broken: the master's two ports each send a copy of the
//!   lumped frame(s) and the commands of their side ([`BrokenRing`]).
//!
//! Bars of every frame carry `class="frame lumped"`, `"frame command"` or
//! `"frame response"`, and the mark of a broken link `class="broken-link"`.

use ringsync_proto::plan::{BrokenRing, FrameRef, Node, PhaseKind};
use ringsync_proto::{CyclePlan, PlanKind};

use crate::svg::{Svg, nice_step};

/// Most slaves a timing diagram draws (one lane each).
pub const MAX_SVG_SLAVES: u32 = 64;

const WIDTH: f64 = 1100.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 20.0;
const IDLE_W: f64 = 120.0;
/// Top of the lanes below the title, without subtitle lines.
const TOP: f64 = 64.0;
/// Height of a subtitle line.
const SUB: f64 = 16.0;
const LANE: f64 = 28.0;
const BROKEN: &str = "#d62728";

fn colour(f: FrameRef) -> &'static str {
    match f {
        FrameRef::Lumped(_) => "#4e79a7",
        FrameRef::Command(_) => "#f28e2b",
        FrameRef::Response(_) => "#59a14f",
    }
}

fn class(f: FrameRef) -> &'static str {
    match f {
        FrameRef::Lumped(_) => "frame lumped",
        FrameRef::Command(_) => "frame command",
        FrameRef::Response(_) => "frame response",
    }
}

fn frame_name(f: FrameRef) -> String {
    match f {
        FrameRef::Lumped(j) => format!("lumped frame {}", j + 1),
        FrameRef::Command(i) => format!("command to slave {i}"),
        FrameRef::Response(i) => format!("response of slave {i}"),
    }
}

/// A lane of the diagram: the master (one lane on the whole ring, one per port on a broken
/// ring) or a slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lane {
    Master,
    PortA,
    PortB,
    Slave(u32),
}

impl Lane {
    /// Its row, 0 at the top; port B (node n + 1) below slave n.
    fn row(self, n: u32) -> u32 {
        match self {
            Lane::Master | Lane::PortA => 0,
            Lane::Slave(i) => i,
            Lane::PortB => n + 1,
        }
    }

    /// The label left of the lane.
    fn label(self) -> String {
        match self {
            Lane::Master => "master".into(),
            Lane::PortA => "master (A)".into(),
            Lane::PortB => "master (B)".into(),
            Lane::Slave(i) => format!("slave {i}"),
        }
    }

    /// The node in hover titles.
    fn name(self) -> String {
        match self {
            Lane::Master => "master".into(),
            Lane::PortA => "master (port A)".into(),
            Lane::PortB => "master (port B)".into(),
            Lane::Slave(i) => format!("slave {i}"),
        }
    }
}

/// One frame on one lane: sent (upper half) or received (lower half), first to last bit.
#[derive(Debug, Clone, Copy)]
struct Bar {
    lane: Lane,
    frame: FrameRef,
    sends: bool,
    start: i64,
    end: i64,
    /// The node only relays the frame (a lumped frame on a broken ring's unprocessed leg).
    relay: bool,
}

/// A phase band [ns from the cycle start].
#[derive(Debug, Clone, Copy)]
struct Band {
    kind: PhaseKind,
    start: i64,
    end: i64,
    /// A slice of a slave reached from port B.
    side_b: bool,
}

/// What the diagram shows, in ns from the cycle start.
struct Diagram {
    title: String,
    /// Below the title: the ring (whole or which link broken), shortest cycle, idle; then
    /// what else the plan needs said.
    subtitle: Vec<String>,
    lanes: Vec<Lane>,
    bars: Vec<Bar>,
    bands: Vec<Band>,
    /// Label of the [`PhaseKind::Sync`] band and of its group.
    sync_label: &'static str,
    sync_group: &'static str,
    p2p_group: &'static str,
    /// Frames the legend lists.
    legend: Vec<(&'static str, FrameRef)>,
    /// The broken link j: between rows j − 1 and j.
    broken_link: Option<u32>,
    t_cyc: i64,
}

fn us(ns: i64) -> String {
    let sign = if ns < 0 { "-" } else { "" };
    let a = ns.unsigned_abs();
    format!("{sign}{}.{:03}", a / 1_000, a % 1_000)
}

fn idle_text(t_idle: i64) -> String {
    if t_idle < 0 {
        format!(
            "T_idle = {} µs: the plan does not fit this cycle",
            us(t_idle)
        )
    } else {
        format!("T_idle = {} µs", us(t_idle))
    }
}

/// Follows frames along paths of lanes, as the planner does: every hop takes L (first bit
/// out to first bit in, `plan.hop`) and every node between sender and receiver forwards
/// after its residence T_t (`plan.params.residence`).
struct Router {
    hop: i64,
    residence: i64,
    bars: Vec<Bar>,
}

impl Router {
    fn new(plan: &CyclePlan) -> Self {
        Router {
            hop: plan.hop.as_ns(),
            residence: plan.params.residence.as_ns(),
            bars: Vec::new(),
        }
    }

    /// Sends `frame` from `origin` (first bit out at `t0`, `dur` long) through `path`, each
    /// node with whether it only relays the frame; returns when its last bit reaches the
    /// last node.
    fn route(
        &mut self,
        frame: FrameRef,
        origin: Lane,
        (t0, dur): (i64, i64),
        path: &[(Lane, bool)],
    ) -> i64 {
        let bar = |lane, sends, start: i64, relay| Bar {
            lane,
            frame,
            sends,
            start,
            end: start + dur,
            relay,
        };
        self.bars.push(bar(origin, true, t0, false));
        let mut tx = t0;
        let mut last_end = t0 + dur;
        for (k, &(lane, relay)) in path.iter().enumerate() {
            let rx = tx + self.hop;
            last_end = rx + dur;
            if k + 1 < path.len() {
                tx = rx + self.residence;
                self.bars.push(bar(lane, true, tx, relay));
            }
            self.bars.push(bar(lane, false, rx, relay));
        }
        last_end
    }
}

fn slaves(range: impl Iterator<Item = u32>, relay: bool) -> Vec<(Lane, bool)> {
    range.map(|i| (Lane::Slave(i), relay)).collect()
}

fn head(plan: &CyclePlan, what: &str) -> String {
    format!(
        "One cycle of {what}: {} slaves, {} Mbit/s, T_cyc = {} µs",
        plan.slaves(),
        plan.params.bit_rate_bps as f64 / 1e6,
        us(plan.params.t_cyc.as_ns())
    )
}

/// The sync phase up to `back` and T_rest from there to `rest_end`, the bands every plan's
/// cycle starts with.
fn sync_and_rest(back: i64, rest_end: i64) -> Vec<Band> {
    vec![
        Band {
            kind: PhaseKind::Sync,
            start: 0,
            end: back,
            side_b: false,
        },
        Band {
            kind: PhaseKind::Rest,
            start: back,
            end: rest_end,
            side_b: false,
        },
    ]
}

fn idle_band(bands: &mut Vec<Band>, end: i64, t_cyc: i64) {
    if t_cyc > end {
        bands.push(Band {
            kind: PhaseKind::Idle,
            start: end,
            end: t_cyc,
            side_b: false,
        });
    }
}

/// The proposed plan on the whole ring: the planner's event-level timeline.
fn proposed(plan: &CyclePlan) -> Diagram {
    let n = plan.slaves();
    let tl = plan.timeline();
    let lane = |node: Node| match node {
        Node::Master => Lane::Master,
        Node::Slave(i) => Lane::Slave(i),
    };
    let mut bars = Vec::with_capacity(tl.passages.len() * 2);
    for p in &tl.passages {
        for (span, sends) in [(p.tx, true), (p.rx, false)] {
            if let Some(sp) = span {
                bars.push(Bar {
                    lane: lane(p.node),
                    frame: p.frame,
                    sends,
                    start: sp.start.as_ns(),
                    end: sp.end.as_ns(),
                    relay: false,
                });
            }
        }
    }
    let bands = tl
        .phases
        .iter()
        .map(|ph| Band {
            kind: ph.kind,
            start: ph.start.as_ns(),
            end: ph.end.as_ns(),
            side_b: false,
        })
        .collect();
    Diagram {
        title: format!(
            "{} (event level, physical ring path)",
            head(plan, "the proposed plan (p2p-lumped)")
        ),
        subtitle: vec![format!(
            "Whole ring, no link broken. Shortest cycle {} µs, {} (event level).",
            us(plan.event.min_t_cyc.as_ns()),
            idle_text(plan.event.t_idle.as_ns())
        )],
        lanes: std::iter::once(Lane::Master)
            .chain((1..=n).map(Lane::Slave))
            .collect(),
        bars,
        bands,
        sync_label: "sync",
        sync_group: "clock-sync phase",
        p2p_group: "point-to-point phase (slices, reserve)",
        legend: vec![
            ("lumped frame", FrameRef::Lumped(0)),
            ("command frame", FrameRef::Command(1)),
            ("response frame", FrameRef::Response(1)),
        ],
        broken_link: None,
        t_cyc: plan.params.t_cyc.as_ns(),
    }
}

/// The lumped-only plan of ref. \[3\]: `plan.lumped_only`'s frames (`lumped.frame_time`,
/// sent `lumped.frame_offset` apart with the link's gap) go master → slaves 1..n → master,
/// a hop `plan.hop` and a residence `plan.params.residence` at a time, so that the last one
/// is back at T_lmf + D_ms(n) + D_snm; then T_rest, and `lumped_only.t_idle`
/// (`lumped_only.min_t_cyc` = T_lmf + D_ms(n) + D_snm + T_rest).
fn lumped_only(plan: &CyclePlan) -> Diagram {
    let n = plan.slaves();
    let lo = &plan.lumped_only;
    let gap = plan.link.gap();
    let mut r = Router::new(plan);
    let mut path = slaves(1..=n, false);
    path.push((Lane::Master, false));
    let mut back = 0;
    for (k, &dur) in lo.lumped.frame_time.iter().enumerate() {
        let t0 = lo.lumped.frame_offset(k, gap).as_ns();
        back = r.route(
            FrameRef::Lumped(k as u32),
            Lane::Master,
            (t0, dur.as_ns()),
            &path,
        );
    }
    let rest_end = back + plan.params.t_rest.as_ns();
    let t_cyc = plan.params.t_cyc.as_ns();
    let mut bands = sync_and_rest(back, rest_end);
    idle_band(&mut bands, rest_end, t_cyc);
    let frames = lo.lumped.frame_bytes.len();
    let sizes: Vec<String> = lo
        .lumped
        .frame_bytes
        .iter()
        .map(|b| b.to_string())
        .collect();
    Diagram {
        title: head(plan, "the lumped-only plan (ref. [3])"),
        subtitle: vec![
            format!(
                "Whole ring, no link broken. Shortest cycle {} µs, {}.",
                us(lo.min_t_cyc.as_ns()),
                idle_text(lo.t_idle.as_ns())
            ),
            format!(
                "{} ({} B) {} round the ring{}; each slave computes its command as {} passes; no point-to-point phase.",
                if frames == 1 {
                    "One lumped frame".to_string()
                } else {
                    format!("{frames} lumped frames")
                },
                sizes.join(" + "),
                if frames == 1 { "goes" } else { "go" },
                if frames == 1 { "" } else { " back to back" },
                if frames == 1 {
                    "it"
                } else {
                    "the frame holding its slot"
                },
            ),
        ],
        lanes: std::iter::once(Lane::Master)
            .chain((1..=n).map(Lane::Slave))
            .collect(),
        bars: r.bars,
        bands,
        sync_label: "lumped",
        sync_group: "lumped phase (slaves read and write on the fly)",
        p2p_group: "",
        legend: vec![("lumped frame", FrameRef::Lumped(0))],
        broken_link: None,
        t_cyc,
    }
}

/// The proposed plan with link `br.link` broken. The paths are those of
/// `crates/proto/src/plan/broken.rs` (docs/planner.md, "A broken link"), walked a hop
/// (`plan.hop`) and a residence (`plan.params.residence`) at a time; the times they give are
/// the [`BrokenRing`]'s: the copy on port B leaves at `b_delay`, the lumped frames reach the
/// slaves at `lumped_at` and are back at `lumped_back_a` / `lumped_back_b`, the P2P phase
/// starts at `p2p_start`, each slave's slice is its side's `slice_a` / `slice_b` (its
/// command arrives at `command_arrival`), the reserve slices are `slice` long, and the
/// cycle ends at `min_t_cyc` + `t_idle`.
fn broken_ring(plan: &CyclePlan, br: &BrokenRing) -> Diagram {
    let n = plan.slaves();
    let (j, a) = (br.link, br.side_a);
    let gap = plan.link.gap();
    let mut r = Router::new(plan);
    let lumped = &plan.lumped;
    // Port A's copy: processed by slaves 1..a, turned back by slave a, relayed back to A.
    if a > 0 {
        let mut path = slaves(1..=a, false);
        path.extend(slaves((1..a).rev(), true));
        path.push((Lane::PortA, false));
        for (k, &dur) in lumped.frame_time.iter().enumerate() {
            let t0 = lumped.frame_offset(k, gap).as_ns();
            r.route(
                FrameRef::Lumped(k as u32),
                Lane::PortA,
                (t0, dur.as_ns()),
                &path,
            );
        }
    }
    // Port B's copy: relayed by slaves n..j+1, turned back by slave j, processed by j..n.
    if br.side_b > 0 {
        let mut path = slaves((j + 1..=n).rev(), true);
        path.extend(slaves(j..=n, false));
        path.push((Lane::PortB, false));
        for (k, &dur) in lumped.frame_time.iter().enumerate() {
            let t0 = (br.b_delay + lumped.frame_offset(k, gap)).as_ns();
            r.route(
                FrameRef::Lumped(k as u32),
                Lane::PortB,
                (t0, dur.as_ns()),
                &path,
            );
        }
    }
    let back = br
        .lumped_back_a
        .into_iter()
        .chain(br.lumped_back_b)
        .max()
        .map_or(0, |d| d.as_ns());
    let p2p = br.p2p_start.as_ns();
    let mut bands = sync_and_rest(back, p2p);
    let (t_cmf, t_rmf) = (plan.t_cmf.as_ns(), plan.t_rmf.as_ns());
    let t_ti = plan.params.response_delay.as_ns();
    let mut start = p2p;
    for s in 1..=n {
        let (port, cmd, resp, slice) = if s < j {
            // Out through 1..s; the response on through s+1..a, back through a−1..1.
            let mut resp = slaves(s + 1..=a, false);
            resp.extend(slaves((1..a).rev(), false));
            (Lane::PortA, slaves(1..=s, false), resp, br.slice_a)
        } else {
            // Relayed by n..j+1, turned back by j, on through j..s; the response on to B.
            let mut cmd = slaves((j + 1..=n).rev(), false);
            cmd.extend(slaves(j..=s, false));
            (Lane::PortB, cmd, slaves(s + 1..=n, false), br.slice_b)
        };
        let mut resp = resp;
        resp.push((port, false));
        let cmd_end = r.route(FrameRef::Command(s), port, (start, t_cmf), &cmd);
        r.route(
            FrameRef::Response(s),
            Lane::Slave(s),
            (cmd_end + t_ti, t_rmf),
            &resp,
        );
        let end = start + slice.unwrap_or(br.slice).as_ns();
        bands.push(Band {
            kind: PhaseKind::Slice(s),
            start,
            end,
            side_b: s >= j,
        });
        start = end;
    }
    for k in 1..=plan.reserve_slices {
        let end = start + br.slice.as_ns();
        bands.push(Band {
            kind: PhaseKind::Reserve(k),
            start,
            end,
            side_b: false,
        });
        start = end;
    }
    let t_cyc = plan.params.t_cyc.as_ns();
    idle_band(&mut bands, start, t_cyc);
    let node = |k: u32| match k {
        0 => "the master's port A".to_string(),
        k if k == n + 1 => "the master's port B".to_string(),
        k => format!("slave {k}"),
    };
    let side = |from: u32, count: u32, slice: Option<ringsync_proto::Duration>| match slice {
        None => "no slave".to_string(),
        Some(d) => format!(
            "{} (slices of {} µs)",
            match count {
                1 => format!("slave {from}"),
                _ => format!("slaves {from}..{}", from + count - 1),
            },
            us(d.as_ns())
        ),
    };
    Diagram {
        title: format!(
            "{} (event level)",
            head(
                plan,
                &format!("the proposed plan (p2p-lumped) with link {j} broken")
            )
        ),
        subtitle: vec![
            format!(
                "Link {j} broken, between {} and {}. Shortest cycle {} µs, {} (event level).",
                node(j - 1),
                node(j),
                us(br.min_t_cyc.as_ns()),
                idle_text(br.t_idle.as_ns())
            ),
            format!(
                "Port A reaches {}, port B {}; each port sends its copy of the lumped frame and the commands of its side.",
                side(1, a, br.slice_a),
                side(a + 1, br.side_b, br.slice_b),
            ),
        ],
        lanes: std::iter::once(Lane::PortA)
            .chain((1..=n).map(Lane::Slave))
            .chain(std::iter::once(Lane::PortB))
            .collect(),
        bars: r.bars,
        bands,
        sync_label: "sync",
        sync_group: "clock-sync phase (a copy from each port)",
        p2p_group: "point-to-point phase (slices of side A, then B; reserve)",
        legend: vec![
            ("lumped frame", FrameRef::Lumped(0)),
            ("command frame", FrameRef::Command(1)),
            ("response frame", FrameRef::Response(1)),
        ],
        broken_link: Some(j),
        t_cyc,
    }
}

/// Draws one cycle as an SVG document: the cycle of the plan `kind` on the whole ring, or,
/// with `broken` (a [`BrokenRing`] of this plan, [`CyclePlan::broken`]), the proposed plan's
/// cycle with that link broken. `None` when the ring has more than [`MAX_SVG_SLAVES`]
/// slaves, or when `broken` is given with the lumped-only plan (the broken ring is planned
/// for the proposed plan only) or does not belong to this ring.
pub fn timing_svg(plan: &CyclePlan, kind: PlanKind, broken: Option<&BrokenRing>) -> Option<String> {
    let n = plan.slaves();
    if n > MAX_SVG_SLAVES {
        return None;
    }
    let d = match (kind, broken) {
        (PlanKind::P2pLumped, None) => proposed(plan),
        (PlanKind::LumpedOnly, None) => lumped_only(plan),
        (PlanKind::P2pLumped, Some(br)) if br.side_a + br.side_b == n => broken_ring(plan, br),
        (_, Some(_)) => return None,
    };
    Some(draw(&d))
}

fn draw(d: &Diagram) -> String {
    let n = d
        .lanes
        .iter()
        .filter(|l| matches!(l, Lane::Slave(_)))
        .count() as u32;
    let busy = d
        .bands
        .iter()
        .filter(|b| b.kind != PhaseKind::Idle)
        .map(|b| b.end)
        .max()
        .unwrap_or(0)
        .max(1) as f64;
    let idle = d.bands.iter().find(|b| b.kind == PhaseKind::Idle);
    let plot_w = WIDTH - LEFT - RIGHT - if idle.is_some() { IDLE_W } else { 0.0 };
    let x = |ns: i64| LEFT + ns as f64 / busy * plot_w;
    let lanes = d.lanes.len() as f64;
    let top = TOP + SUB * d.subtitle.len() as f64;
    let bottom = top + lanes * LANE;
    let height = bottom + 78.0;
    let lane_y = |lane: Lane| top + f64::from(lane.row(n)) * LANE;
    let mut s = Svg::new(WIDTH, height);
    s.text(
        LEFT,
        18.0,
        &d.title,
        "start",
        r#"font-size="13" font-weight="bold""#,
    );
    let sub_style = if d.broken_link.is_some() {
        format!(r#"fill="{BROKEN}""#)
    } else {
        r##"fill="#333""##.to_string()
    };
    for (k, line) in d.subtitle.iter().enumerate() {
        s.text(LEFT, 36.0 + SUB * k as f64, line, "start", &sub_style);
    }
    // Phases: shaded bands with labels above the lanes.
    for (k, ph) in d.bands.iter().enumerate() {
        if ph.kind == PhaseKind::Idle {
            continue;
        }
        let (x0, x1) = (x(ph.start), x(ph.end));
        let fill = match ph.kind {
            PhaseKind::Sync => "#dbe6f1",
            PhaseKind::Rest => "#eeeeee",
            PhaseKind::Slice(_) if ph.side_b && k % 2 == 0 => "#e3f2ef",
            PhaseKind::Slice(_) if ph.side_b => "#cfe8e3",
            PhaseKind::Slice(_) if k % 2 == 0 => "#fdf0e2",
            PhaseKind::Slice(_) => "#fae3cb",
            _ => "#f3e8f4",
        };
        let label = match ph.kind {
            PhaseKind::Sync => d.sync_label.to_string(),
            PhaseKind::Rest => "T_rest".to_string(),
            PhaseKind::Slice(i) => format!("{i}"),
            PhaseKind::Reserve(_) => "res".to_string(),
            PhaseKind::Idle => String::new(),
        };
        let side = match (ph.kind, d.broken_link) {
            (PhaseKind::Slice(_), Some(_)) if ph.side_b => " (side B)",
            (PhaseKind::Slice(_), Some(_)) => " (side A)",
            _ => "",
        };
        let title = format!("{label}{side}: {} – {} µs", us(ph.start), us(ph.end));
        s.rect(
            x0,
            top - 6.0,
            x1 - x0,
            bottom - top + 6.0,
            &format!(r##"fill="{fill}" stroke="white""##),
            Some(&title),
        );
        if x1 - x0 >= 7.0 * label.chars().count() as f64 {
            s.text(
                (x0 + x1) / 2.0,
                top - 10.0,
                &label,
                "middle",
                r##"fill="#333""##,
            );
        }
    }
    // Group labels over the phase labels.
    let p2p = d
        .bands
        .iter()
        .find(|b| b.kind == PhaseKind::Slice(1))
        .map(|b| b.start);
    let sync_end = d
        .bands
        .iter()
        .find(|b| b.kind == PhaseKind::Sync)
        .map_or(0, |b| b.end);
    // Centred over the phase, but not out of the figure on the left.
    let half = 3.2 * d.sync_group.chars().count() as f64;
    s.text(
        x(sync_end / 2).max(4.0 + half),
        top - 26.0,
        d.sync_group,
        "middle",
        r#"font-style="italic""#,
    );
    if let Some(p) = p2p {
        s.text(
            x((p + busy as i64) / 2),
            top - 26.0,
            d.p2p_group,
            "middle",
            r#"font-style="italic""#,
        );
    }
    // Lanes.
    for &lane in &d.lanes {
        let y = lane_y(lane);
        s.line(
            LEFT,
            y + LANE,
            WIDTH - RIGHT,
            y + LANE,
            r##"stroke="#cccccc""##,
        );
        s.text(LEFT - 8.0, y + LANE / 2.0 + 4.0, &lane.label(), "end", "");
    }
    // The broken link: between the lanes of nodes j − 1 and j, a red cross in the label
    // column and a dashed red line across.
    if let Some(j) = d.broken_link {
        let y = top + f64::from(j) * LANE;
        s.line(
            LEFT,
            y,
            LEFT + plot_w,
            y,
            &format!(
                r#"class="broken-link" stroke="{BROKEN}" stroke-width="1.5" stroke-dasharray="6 4""#
            ),
        );
        cross(&mut s, LEFT - 40.0, y);
    }
    // Frames: sends in the upper half of a lane, receptions in the lower half.
    for b in &d.bars {
        let y = lane_y(b.lane);
        let c = colour(b.frame);
        let (dy, op, verb) = if b.sends {
            (5.0, "1", "sends")
        } else {
            (15.0, "0.55", "receives")
        };
        let relay = if b.relay {
            " (relays it unprocessed)"
        } else {
            ""
        };
        let title = format!(
            "{} {verb} {}: {} – {} µs{relay}",
            b.lane.name(),
            frame_name(b.frame),
            us(b.start),
            us(b.end)
        );
        s.rect(
            x(b.start),
            y + dy,
            x(b.end) - x(b.start),
            9.0,
            &format!(
                r#"class="{}" fill="{c}" fill-opacity="{op}""#,
                class(b.frame)
            ),
            Some(&title),
        );
    }
    // Idle, drawn after an axis break.
    if let Some(idle) = idle {
        let x0 = LEFT + plot_w + 14.0;
        let x1 = WIDTH - RIGHT;
        s.rect(
            x0,
            top - 6.0,
            x1 - x0,
            bottom - top + 6.0,
            r##"fill="#f7f7f7" stroke="#dddddd""##,
            None,
        );
        s.text(
            (x0 + x1) / 2.0,
            top - 10.0,
            "idle",
            "middle",
            r##"fill="#333""##,
        );
        s.text(
            (x0 + x1) / 2.0,
            (top + bottom) / 2.0,
            &format!("{} µs", us(idle.end - idle.start)),
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
        s.text(x1, bottom + 16.0, &us(d.t_cyc), "end", "");
    }
    // A cycle too short for the plan: where it ends.
    if idle.is_none() && (d.t_cyc as f64) < busy {
        let xc = x(d.t_cyc);
        s.line(
            xc,
            top - 6.0,
            xc,
            bottom,
            &format!(r#"stroke="{BROKEN}" stroke-width="1.5""#),
        );
        s.text(
            xc - 3.0,
            bottom - 4.0,
            "T_cyc",
            "end",
            &format!(r#"fill="{BROKEN}""#),
        );
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
    let mut legend: Vec<(&str, &str, &str)> = d
        .legend
        .iter()
        .map(|&(label, f)| (label, colour(f), "1"))
        .collect();
    legend.push((
        "upper bar: node sends, lower (pale): node receives",
        "#999999",
        "0.55",
    ));
    for (label, c, op) in legend {
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
    if let Some(j) = d.broken_link {
        cross(&mut s, lx + 7.0, ly - 4.5);
        s.text(
            lx + 18.0,
            ly,
            &format!("link {j} broken"),
            "start",
            &format!(r#"fill="{BROKEN}""#),
        );
    }
    s.finish()
}

/// A red cross centred on (`x`, `y`).
fn cross(s: &mut Svg, x: f64, y: f64) {
    let style = format!(r#"class="broken-link" stroke="{BROKEN}" stroke-width="2.5""#);
    let r = 5.0;
    s.line(x - r, y - r, x + r, y + r, &style);
    s.line(x - r, y + r, x + r, y - r, &style);
}

#[cfg(test)]
mod tests {
    use super::*;
    use ringsync_proto::RingParams;

    fn plan(slaves: u32) -> CyclePlan {
        CyclePlan::new(&RingParams {
            slaves,
            t_cyc: ringsync_proto::Duration::from_ms(10),
            ..RingParams::default()
        })
        .expect("plan")
    }

    fn bar(d: &Diagram, lane: Lane, frame: FrameRef, sends: bool, relay: bool) -> Vec<&Bar> {
        d.bars
            .iter()
            .filter(|b| b.lane == lane && b.frame == frame && b.sends == sends && b.relay == relay)
            .collect()
    }

    /// The lumped-only bars end where the planner's figures say: the last frame back at
    /// T_lmf + D_ms(n) + D_snm, T_rest after it the shortest cycle.
    #[test]
    fn lumped_only_bars_follow_the_planners_figures() {
        for slaves in [1, 4, 50, 64] {
            let p = plan(slaves);
            let lo = &p.lumped_only;
            let d = lumped_only(&p);
            let frames = lo.lumped.frame_time.len();
            assert_eq!(d.bars.len(), frames * (2 * slaves as usize + 2));
            let last = FrameRef::Lumped(frames as u32 - 1);
            let back = bar(&d, Lane::Master, last, false, false)[0].end;
            assert_eq!(back, (lo.lumped.t_lmf + p.d_ms + p.d_snm).as_ns());
            let rest = d
                .bands
                .iter()
                .find(|b| b.kind == PhaseKind::Rest)
                .expect("rest");
            assert_eq!(rest.end, lo.min_t_cyc.as_ns());
            for (i, &dc) in p.d_c.iter().enumerate() {
                let rx = bar(
                    &d,
                    Lane::Slave(i as u32 + 1),
                    FrameRef::Lumped(0),
                    false,
                    false,
                );
                assert_eq!(rx[0].start, dc.as_ns());
            }
            assert!(
                d.bars
                    .iter()
                    .all(|b| matches!(b.frame, FrameRef::Lumped(_)))
            );
        }
    }

    /// The broken ring's bars land on the [`BrokenRing`]'s own figures for every link.
    #[test]
    fn broken_ring_bars_follow_the_planners_figures() {
        for slaves in [1u32, 2, 4, 7] {
            let p = plan(slaves);
            for j in 1..=slaves + 1 {
                let br = p.broken(j).expect("link");
                let d = broken_ring(&p, &br);
                for s in 1..=slaves {
                    // The pass that processes the lumped frame, first frame of the train.
                    let rx = bar(&d, Lane::Slave(s), FrameRef::Lumped(0), false, false);
                    assert_eq!(rx.len(), 1, "n {slaves} j {j} s {s}");
                    assert_eq!(rx[0].start, br.lumped_at[s as usize - 1].as_ns());
                    // The last reception: a command of side B may pass its slave twice.
                    let cmd = bar(&d, Lane::Slave(s), FrameRef::Command(s), false, false);
                    assert_eq!(
                        cmd[cmd.len() - 1].end,
                        br.command_arrival[s as usize - 1].as_ns()
                    );
                    let port = if s < j { Lane::PortA } else { Lane::PortB };
                    let resp = bar(&d, port, FrameRef::Response(s), false, false)[0];
                    let slice = d
                        .bands
                        .iter()
                        .find(|b| b.kind == PhaseKind::Slice(s))
                        .expect("slice");
                    assert_eq!(resp.end + p.event.turnaround.as_ns(), slice.end);
                }
                let last = FrameRef::Lumped(p.lumped.frame_time.len() as u32 - 1);
                for (port, back) in [
                    (Lane::PortA, br.lumped_back_a),
                    (Lane::PortB, br.lumped_back_b),
                ] {
                    let got = bar(&d, port, last, false, false).first().map(|b| b.end);
                    assert_eq!(got, back.map(|b| b.as_ns()), "n {slaves} j {j}");
                }
                let busy = d.bands.iter().filter(|b| b.kind != PhaseKind::Idle);
                assert_eq!(busy.map(|b| b.end).max(), Some(br.min_t_cyc.as_ns()));
            }
        }
    }

    #[test]
    fn each_diagram_names_its_plan_and_the_break() {
        let p = plan(4);
        let p2p = timing_svg(&p, PlanKind::P2pLumped, None).expect("svg");
        assert!(p2p.contains("proposed plan (p2p-lumped)") && p2p.contains("no link broken"));
        let lo = timing_svg(&p, PlanKind::LumpedOnly, None).expect("svg");
        assert!(lo.contains("lumped-only plan") && !lo.contains("class=\"frame command\""));
        let br = p.broken(3).expect("link");
        let b = timing_svg(&p, PlanKind::P2pLumped, Some(&br)).expect("svg");
        assert!(b.contains("with link 3 broken") && b.contains("class=\"broken-link\""));
        assert!(timing_svg(&p, PlanKind::LumpedOnly, Some(&br)).is_none());
        assert!(timing_svg(&plan(3), PlanKind::P2pLumped, Some(&br)).is_none());
        assert_eq!(us(-500), "-0.500");
    }
}
