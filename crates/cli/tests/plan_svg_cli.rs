//! `ringsync plan --svg`: the timing diagram shows the cycle the options ask for (the plan
//! of `--plan`, the ring with `--break-link`'s link broken), read back from the SVG as text.

mod common;

use common::{ringsync, scratch};

/// A frame bar of the diagram: its attributes and its hover title. Bars are the rects with a
/// title that names a frame (phase bands and the legend have none of these).
struct Bar {
    attrs: String,
    title: String,
}

fn bars(svg: &str) -> Vec<Bar> {
    svg.split("<rect ")
        .skip(1)
        .filter_map(|r| {
            let (attrs, rest) = r.split_once('>')?;
            let title = rest.strip_prefix("<title>")?.split_once("</title>")?.0;
            let frame = ["lumped frame", "command to slave", "response of slave"];
            frame.iter().any(|f| title.contains(f)).then(|| Bar {
                attrs: attrs.to_string(),
                title: title.to_string(),
            })
        })
        .collect()
}

fn count(bars: &[Bar], pred: impl Fn(&Bar) -> bool) -> usize {
    bars.iter().filter(|b| pred(b)).count()
}

/// The text of the SVG's `<text>` elements, in order.
fn texts(svg: &str) -> Vec<(f64, String)> {
    svg.split("<text ")
        .skip(1)
        .filter_map(|t| {
            let (attrs, rest) = t.split_once('>')?;
            let y = attrs
                .split("y=\"")
                .nth(1)?
                .split('"')
                .next()?
                .parse()
                .ok()?;
            Some((y, rest.split_once("</text>")?.0.to_string()))
        })
        .collect()
}

/// `ringsync plan ARGS --svg FILE`: the SVG written.
fn svg(name: &str, args: &[&str]) -> String {
    let dir = scratch("plan-svg", name);
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("cycle.svg");
    let mut all = vec!["plan"];
    all.extend_from_slice(args);
    all.extend(["--svg", path.to_str().expect("path")]);
    let o = ringsync(&all);
    assert!(
        o.status.success(),
        "{all:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let s = std::fs::read_to_string(&path).expect("svg written");
    assert!(s.starts_with("<?xml") && s.trim_end().ends_with("</svg>"));
    std::fs::remove_dir_all(&dir).expect("cleanup");
    s
}

/// `ringsync plan ARGS --json`.
fn json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["plan"];
    all.extend_from_slice(args);
    all.push("--json");
    let o = ringsync(&all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("json")
}

/// ns as the diagram prints µs.
fn us(ns: i64) -> String {
    format!("{}.{:03}", ns / 1_000, ns % 1_000)
}

#[test]
fn the_proposed_plan_on_the_whole_ring_keeps_its_diagram() {
    for n in [4u32, 7] {
        let ns = n.to_string();
        let s = svg(&format!("p2p-{n}"), &["--slaves", &ns]);
        let t = texts(&s);
        assert!(t[0].1.contains("proposed plan (p2p-lumped)"), "{}", t[0].1);
        assert!(
            t[1].1.contains("no link broken") && t[1].1.contains("T_idle"),
            "{}",
            t[1].1
        );
        assert!(!s.contains("broken-link"));
        // Lanes: the master and every slave.
        for lane in
            std::iter::once("master".to_string()).chain((1..=n).map(|i| format!("slave {i}")))
        {
            assert!(t.iter().any(|(_, x)| *x == lane), "no lane {lane}");
        }
        let b = bars(&s);
        let n = n as usize;
        // One lumped frame: sent by the master, received and forwarded by every slave,
        // received by the master.
        assert_eq!(count(&b, |b| b.title.contains("lumped frame")), 2 * n + 2);
        assert_eq!(count(&b, |b| b.title.contains("lumped frame 2")), 0);
        // n slices: each command sent once by the master, each response once by its slave.
        for i in 1..=n {
            let cmd = format!("master sends command to slave {i}:");
            assert_eq!(count(&b, |b| b.title.starts_with(&cmd)), 1, "{cmd}");
            let resp = format!("slave {i} sends response of slave {i}:");
            assert_eq!(count(&b, |b| b.title.starts_with(&resp)), 1, "{resp}");
            assert!(t.iter().any(|(_, x)| *x == i.to_string()), "no slice {i}");
        }
        // Command i passes slaves 1..i, response i slaves i+1..n: n(n+1) bars each.
        assert_eq!(
            count(&b, |b| b.title.contains("command to slave")),
            n * (n + 1)
        );
        assert_eq!(
            count(&b, |b| b.title.contains("response of slave")),
            n * (n + 1)
        );
    }
}

#[test]
fn lumped_only_draws_its_own_cycle() {
    let p2p = svg("lo-p2p", &[]);
    for n in [4u32, 50] {
        let ns = n.to_string();
        let s = svg(
            &format!("lo-{n}"),
            &["--plan", "lumped-only", "--slaves", &ns],
        );
        if n == 4 {
            assert_ne!(s, p2p, "the lumped-only diagram is the proposed plan's");
        }
        let t = texts(&s);
        assert!(t[0].1.contains("lumped-only plan"), "{}", t[0].1);
        assert!(!t[0].1.contains("proposed plan"), "{}", t[0].1);
        assert!(t[1].1.contains("no link broken"), "{}", t[1].1);
        let v = json(&["--plan", "lumped-only", "--slaves", &ns]);
        let lo = &v["lumped_only"];
        // The subtitle gives the plan's own cycle and idle time.
        let min = us(lo["min_t_cyc_ns"].as_i64().expect("min"));
        let idle = us(lo["t_idle_ns"].as_i64().expect("idle"));
        assert!(
            t[1].1.contains(&min) && t[1].1.contains(&idle),
            "{}",
            t[1].1
        );
        let b = bars(&s);
        // No point-to-point phase: no command or response bars, by title or by class.
        assert_eq!(count(&b, |b| b.title.contains("command to slave")), 0);
        assert_eq!(count(&b, |b| b.title.contains("response of slave")), 0);
        assert!(!s.contains("frame command") && !s.contains("frame response"));
        assert!(!s.contains("#f28e2b") && !s.contains("#59a14f"));
        // Each lumped frame: master sends, every slave receives and forwards, master receives.
        let frames = lo["lumped_frames"].as_u64().expect("frames") as usize;
        assert_eq!(frames, if n == 4 { 1 } else { 2 });
        let n = n as usize;
        assert_eq!(b.len(), frames * (2 * n + 2));
        assert_eq!(
            count(&b, |b| b.attrs.contains(r#"class="frame lumped""#)),
            b.len()
        );
        for f in 1..=frames {
            let sent = format!("master sends lumped frame {f}:");
            assert_eq!(count(&b, |b| b.title.starts_with(&sent)), 1, "{sent}");
        }
        // The last frame back at the master: T_lmf + D_ms(n) + D_snm.
        let back = lo["t_lmf_ns"].as_i64().expect("t_lmf")
            + v["d_ms_ns"].as_i64().expect("d_ms")
            + v["d_snm_ns"].as_i64().expect("d_snm");
        let rx = format!("master receives lumped frame {frames}: ");
        let got = b.iter().find(|b| b.title.starts_with(&rx)).expect("back");
        assert!(
            got.title.ends_with(&format!(" – {} µs", us(back))),
            "{}",
            got.title
        );
    }
}

#[test]
fn a_broken_link_draws_the_broken_ring() {
    let s = svg("broken-3", &["--break-link", "3"]);
    let t = texts(&s);
    assert!(
        t[0].1.contains("proposed plan (p2p-lumped)") && t[0].1.contains("link 3 broken"),
        "{}",
        t[0].1
    );
    assert!(
        t[1].1
            .contains("Link 3 broken, between slave 2 and slave 3"),
        "{}",
        t[1].1
    );
    let v = json(&["--break-link", "3"]);
    let br = &v["broken_ring"];
    let ns = |k: &str| br[k].as_i64().unwrap_or_else(|| panic!("{k}"));
    assert!(t[1].1.contains(&us(ns("min_t_cyc"))) && t[1].1.contains(&us(ns("t_idle"))));
    // Both ports have a lane, and the mark of the break lies between slave 2's and slave 3's.
    let y = |lane: &str| {
        t.iter()
            .find(|(_, x)| x == lane)
            .unwrap_or_else(|| panic!("no lane {lane}"))
            .0
    };
    assert!(y("master (A)") < y("slave 1") && y("slave 4") < y("master (B)"));
    let mark = s
        .lines()
        .find(|l| l.starts_with("<line") && l.contains(r#"class="broken-link""#))
        .expect("the broken link is marked");
    let y1: f64 = mark
        .split("y1=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .and_then(|v| v.parse().ok())
        .expect("y1");
    assert!(y("slave 2") < y1 && y1 < y("slave 3"), "mark at {y1}");
    let b = bars(&s);
    // A copy of the lumped frame from each port, back when the planner says.
    for (port, back) in [("A", "lumped_back_a"), ("B", "lumped_back_b")] {
        let sent = format!("master (port {port}) sends lumped frame 1:");
        assert_eq!(count(&b, |b| b.title.starts_with(&sent)), 1, "{sent}");
        let rx = format!("master (port {port}) receives lumped frame 1: ");
        let got = b.iter().find(|b| b.title.starts_with(&rx)).expect("back");
        assert!(
            got.title.ends_with(&format!(" – {} µs", us(ns(back)))),
            "{}",
            got.title
        );
    }
    // Each side's commands from its own port, arriving when the planner says.
    let arrival = br["command_arrival"].as_array().expect("arrivals");
    for s in 1..=4 {
        let port = if s < 3 { "A" } else { "B" };
        let cmd = format!("master (port {port}) sends command to slave {s}:");
        assert_eq!(count(&b, |b| b.title.starts_with(&cmd)), 1, "{cmd}");
        let rx = format!("slave {s} receives command to slave {s}: ");
        let at = us(arrival[s - 1].as_i64().expect("ns"));
        assert!(
            b.iter()
                .any(|b| b.title.starts_with(&rx) && b.title.ends_with(&format!(" – {at} µs"))),
            "command {s} not at {at}"
        );
        let resp = format!("master (port {port}) receives response of slave {s}:");
        assert_eq!(count(&b, |b| b.title.starts_with(&resp)), 1, "{resp}");
    }
    // The whole ring's diagram has no port lanes and no mark.
    let whole = svg("broken-none", &[]);
    assert!(!whole.contains("master (B)") && !whole.contains("broken-link"));
}

#[test]
fn a_break_at_the_master_leaves_one_port_alone() {
    // Link 1: port A reaches no slave; every frame goes out on port B.
    let s = svg("broken-1", &["--break-link", "1", "--slaves", "3"]);
    let b = bars(&s);
    assert_eq!(
        count(&b, |b| b.title.starts_with("master (port A) sends")),
        0
    );
    assert_eq!(
        count(&b, |b| b.title.starts_with("master (port B) sends command")),
        3
    );
    assert!(
        texts(&s)[1]
            .1
            .contains("between the master's port A and slave 1")
    );
}
