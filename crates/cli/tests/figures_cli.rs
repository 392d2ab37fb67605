//! The figures say what they show: a sweep's chart as Python draws it (categories, markers,
//! error bars of the sample sd, a log axis for doubling values, the legend whole), Fig. 4
//! and 5 pairs on one scale, the clock errors after acquisition, and the assumptions of
//! the plan a run used. (Looked at in headless Chromium at 1400 px: docs/simulator.md,
//! "The figures".)

mod common;

use common::{ringsync, scratch};

fn p(path: &std::path::Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Every `<text>` of an SVG: (x, y, content).
fn texts(svg: &str) -> Vec<(f64, f64, String)> {
    svg.split("<text ")
        .skip(1)
        .map(|chunk| {
            let attr = |name: &str| {
                chunk
                    .split(&format!(" {name}=\""))
                    .nth(1)
                    .or_else(|| chunk.strip_prefix(&format!("{name}=\"")))
                    .and_then(|r| r.split('"').next())
                    .and_then(|v| v.parse::<f64>().ok())
                    .unwrap_or(f64::NAN)
            };
            let body = chunk
                .split_once('>')
                .map_or("", |(_, b)| b.split("</text>").next().unwrap_or(""));
            (attr("x"), attr("y"), body.trim().to_string())
        })
        .collect()
}

fn sweep(d: &std::path::Path, name: &str, sets: &[&str], seeds: &str) -> String {
    let out = d.join(name);
    let mut args = vec!["sweep", "paper-2015", "--seeds", seeds, "--out", p(&out)];
    for s in sets {
        args.extend(["--set", s]);
    }
    args.extend(["--set", "duration=\"0.3s\""]);
    let o = ringsync(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read_to_string(out.join("sweep.svg")).expect("sweep.svg")
}

#[test]
fn a_sweep_chart_draws_what_python_draws() {
    let d = scratch("figures", "sweep");
    // A key of words: its values are the x axis's categories.
    let svg = sweep(
        &d,
        "plan",
        &["ring.plan=p2p-lumped,lumped-only", "control.law=pd,sync"],
        "3",
    );
    let t = texts(&svg);
    let has = |s: &str| t.iter().any(|(_, _, c)| c == s);
    assert!(has("p2p-lumped") && has("lumped-only"), "categories: {t:?}");
    let legend = |s: &str| {
        t.iter()
            .any(|(_, _, c)| c == &format!("{s}, duration=&quot;0.3s&quot;"))
    };
    assert!(
        legend("control.law=pd") && legend("control.law=sync"),
        "the legend whole: {t:?}"
    );
    assert!(
        t.iter()
            .any(|(_, _, c)| c == "paper-2015: mean ± sample sd (n − 1) over 3 seeds"),
        "{t:?}"
    );
    // Markers (4 points and 2 legend entries) and error bars (a vertical line with caps).
    assert!(svg.matches("<circle").count() >= 6, "markers");
    assert!(
        svg.matches("<polyline").count() >= 2 + 4,
        "lines and error bars"
    );
    // Doubling values: a log axis, so 2, 4, 8, 16 stand equally apart.
    let svg = sweep(
        &d,
        "slaves",
        &["ring.slaves=2,4,8,16", "control.law=sync"],
        "1",
    );
    let t = texts(&svg);
    let x_of = |s: &str| {
        t.iter()
            .find(|(_, _, c)| c == s)
            .map(|(x, _, _)| *x)
            .unwrap_or_else(|| panic!("no tick {s}: {t:?}"))
    };
    let (a, b, c, e) = (x_of("2"), x_of("4"), x_of("8"), x_of("16"));
    assert!(
        ((b - a) - (c - b)).abs() <= 2.0 && ((c - b) - (e - c)).abs() <= 2.0,
        "{a} {b} {c} {e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn paired_figures_share_a_scale_and_clock_errors_start_after_acquisition() {
    let d = scratch("figures", "repro");
    let o = ringsync(&["reproduce", "--seeds", "1", "--out", p(&d.join("r"))]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ticks = |name: &str| {
        let svg = std::fs::read_to_string(d.join("r").join(name)).expect(name);
        // The y axis's tick labels: right-aligned texts left of the plot.
        let mut v: Vec<String> = svg
            .split("<text ")
            .filter(|c| c.contains("text-anchor=\"end\""))
            .filter_map(|c| {
                c.split_once('>')
                    .map(|(_, b)| b.split("</text>").next().unwrap_or("").trim().to_string())
            })
            .collect();
        v.sort();
        v
    };
    for (a, b) in [
        (
            "fig4-position-errors-pd.svg",
            "fig4-position-errors-sync.svg",
        ),
        ("fig5-sync-errors-pd.svg", "fig5-sync-errors-sync.svg"),
    ] {
        assert_eq!(ticks(a), ticks(b), "{a} and {b} on one scale");
    }
    let out = d.join("sim");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "duration=\"0.5s\"",
        "--out",
        p(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let svg = std::fs::read_to_string(out.join("clock-errors.svg")).expect("clock");
    let t = texts(&svg);
    assert!(
        t.iter()
            .any(|(_, _, c)| c.contains("from t = ") && c.contains("acquisition before")),
        "{t:?}"
    );
    // The nanoseconds after lock, not the microseconds of the acquisition.
    let ys: Vec<f64> = t
        .iter()
        .filter_map(|(_, _, c)| c.parse::<f64>().ok())
        .collect();
    let top = ys.iter().fold(0.0f64, |m, y| m.max(y.abs()));
    assert!(top < 200.0, "y ticks up to {top} ns: {ys:?}");
    // A run on the proposed plan lists its plan's assumption and not the other's.
    let summary = std::fs::read_to_string(out.join("summary.json")).expect("summary");
    assert!(
        summary.contains("p2p-lumped plan: the master runs the law"),
        "{summary}"
    );
    assert!(
        !summary.contains("lumped-only plan: each slave"),
        "{summary}"
    );
    let lo = d.join("lo");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "ring.plan=lumped-only",
        "--set",
        "duration=\"0.2s\"",
        "--outputs",
        "summary",
        "--out",
        p(&lo),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = std::fs::read_to_string(lo.join("summary.json")).expect("summary");
    assert!(
        summary.contains("lumped-only plan: each slave") && !summary.contains("p2p-lumped plan:")
    );
    let _ = std::fs::remove_dir_all(&d);
}
