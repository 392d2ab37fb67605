//! `ringsync program` and a part program's `ringsync sim` end to end: the binary as a user
//! runs it (docs/programs.md).

mod common;

use common::{ringsync, scratch};

fn text(b: &[u8]) -> String {
    String::from_utf8(b.to_vec()).expect("utf-8")
}

/// The table, its JSON, the figure and the blocks' CSV agree, and the setpoints keep their
/// limits (exit status 0).
#[test]
fn program_prints_the_plan_as_text_json_svg_and_csv() {
    let dir = scratch("program", "plan");
    std::fs::create_dir_all(&dir).expect("scratch");
    let (svg, csv) = (dir.join("feed.svg"), dir.join("blocks.csv"));
    let o = ringsync(&[
        "program",
        "circle-xy",
        "--svg",
        svg.to_str().expect("utf-8"),
        "--csv",
        csv.to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let table = text(&o.stdout);
    assert!(
        table.starts_with("circle-xy: program circle-r50.ngc on 2 machine axes"),
        "{table}"
    );
    let j = ringsync(&["program", "circle-xy", "--json"]);
    assert_eq!(j.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&j.stdout).expect("JSON");
    let duration = v["duration_s"].as_f64().expect("duration_s");
    assert!(table.contains(&format!("{duration:.3} s")), "{table}");
    assert!(v["limit_ratio"].as_f64().expect("ratio") <= 1.001);
    assert_eq!(v["axes"][1]["axis"], "Y");
    assert!(std::fs::read_to_string(&svg).expect("svg").contains("<svg"));
    let blocks = std::fs::read_to_string(&csv).expect("csv");
    let rows = blocks.lines().count() - 1;
    assert_eq!(rows as u64, v["blocks"].as_u64().expect("blocks"));
    // Each block's duration adds up to the program's (no dwell in it).
    let sum: f64 = blocks
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .nth(5)
                .and_then(|d| d.parse::<f64>().ok())
                .expect("duration")
        })
        .sum();
    assert!((sum - duration).abs() < 1e-5, "{sum} {duration}");
}

/// A scenario without a program, a bad program, a missing file: one line, exit status 2.
#[test]
fn what_cannot_be_planned_is_a_usage_error() {
    let dir = scratch("program", "bad");
    std::fs::create_dir_all(&dir).expect("scratch");
    let o = ringsync(&["program", "paper-2015"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("not a part program"),
        "{}",
        text(&o.stderr)
    );
    let bad = dir.join("bad.ngc");
    std::fs::write(&bad, "G1 X10 F600\nG2 X20 Y0 R2\n").expect("program");
    let set = format!("trajectory.program=\"{}\"", bad.display());
    for cmd in ["program", "sim"] {
        let mut args = vec![cmd, "circle-xy", "--set", &set];
        let out = dir.join(format!("out-{cmd}"));
        if cmd == "sim" {
            args.extend(["--out", out.to_str().expect("utf-8")]);
        }
        let o = ringsync(&args);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {err}");
        assert!(
            err.contains(
                "bad.ngc: line 2, column 11: R2: a radius of 2.0000 mm cannot reach the end point"
            ),
            "{cmd}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!out.exists(), "nothing written");
    }
    let o = ringsync(&[
        "program",
        "circle-xy",
        "--set",
        "trajectory.program=\"missing.ngc\"",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("missing.ngc: no such file"),
        "{}",
        text(&o.stderr)
    );
}

/// `sim` of a program writes path.csv beside trace.csv, and summary.json's contour keys
/// are the run text's figures.
#[test]
fn sim_writes_path_csv_and_the_contour_error() {
    let dir = scratch("program", "sim");
    let out = dir.join("run");
    let o = ringsync(&[
        "sim",
        "circle-xy",
        "--set",
        "duration=\"4s\"",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let path = std::fs::read_to_string(out.join("path.csv")).expect("path.csv");
    assert!(
        path.starts_with("time_s,X,X_d,Y,Y_d,contour_error\n"),
        "{}",
        &path[..80]
    );
    assert_eq!(path.lines().count(), 4001);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("summary"))
            .expect("JSON");
    let rmse = s["contour_rmse"].as_f64().expect("contour_rmse");
    assert!(
        text(&o.stdout).contains(&format!("contour error: RMS {:.2} µm", rmse * 1e3)),
        "{}",
        text(&o.stdout)
    );
    assert_eq!(s["program"]["complete"], false);
    // The line that lists what was written names path.csv (and a capture, issue 41).
    let stdout = text(&o.stdout);
    let wrote = stdout
        .lines()
        .find(|l| l.contains("wrote"))
        .expect("a wrote line");
    assert!(wrote.contains("path.csv"), "{wrote}");
    let pcap = dir.join("run.pcapng");
    let o = ringsync(&[
        "sim",
        "circle-xy",
        "--set",
        "duration=\"0.1s\"",
        "--outputs",
        "summary",
        "--pcap",
        pcap.to_str().expect("utf-8"),
        "--out",
        dir.join("run2").to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let wrote = stdout
        .lines()
        .find(|l| l.contains("wrote"))
        .expect("a wrote line");
    assert!(
        wrote.contains("the capture") && wrote.contains("run.pcapng"),
        "{wrote}"
    );
    assert!(
        !wrote.contains("path.csv"),
        "no trace, no path table: {wrote}"
    );
    assert!(
        s["assumptions"]
            .as_array()
            .expect("assumptions")
            .iter()
            .any(|a| a.as_str().is_some_and(|a| a.starts_with("part program:")))
    );
}
