//! `ringsync sim` and `ringsync reproduce` end to end.

use std::path::{Path, PathBuf};
mod common;

use common::ringsync;

fn dir(name: &str) -> PathBuf {
    let d = common::scratch("sim", name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// The short scenario, in a directory of its own per call: tests run in parallel, and one
/// that removed a shared directory while another read from it made that one fail ("no such
/// file").
fn short_scenario() -> PathBuf {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let d = dir(&format!("scenario-{k}"));
    std::fs::create_dir_all(&d).expect("dir");
    let p = d.join("short.toml");
    std::fs::write(
        &p,
        "duration = \"300ms\"\n[faults]\nloss = 0.01\n[ring]\njitter = \"20ns\"\n",
    )
    .expect("write");
    p
}

#[test]
fn sim_outputs_are_byte_identical_for_one_seed() {
    let sc = short_scenario();
    let (a, b, c) = (dir("a"), dir("b"), dir("c"));
    for (d, seed) in [(&a, "7"), (&b, "7"), (&c, "8")] {
        let o = ringsync(&[
            "sim",
            sc.to_str().expect("p"),
            "--out",
            d.to_str().expect("p"),
            "--seed",
            seed,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for f in [
        "summary.json",
        "trace.csv",
        "report.html",
        "position-errors.svg",
        "sync-errors.svg",
        "clock-errors.svg",
    ] {
        let (x, y, z) = (
            std::fs::read(a.join(f)).expect("a"),
            std::fs::read(b.join(f)).expect("b"),
            std::fs::read(c.join(f)).expect("c"),
        );
        assert_eq!(x, y, "{f} differs between two runs with one seed");
        assert_ne!(x, z, "{f} identical for another seed");
    }
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("summary.json")).expect("read"))
            .expect("json");
    for key in [
        "scenario",
        "scenario_hash",
        "seed",
        "plan",
        "controller",
        "estimator",
        "track_rmse",
        "sync_rmse",
        "axes",
        "frames",
        "faults",
    ] {
        assert!(!v[key].is_null(), "summary.json lacks {key}");
    }
    assert_eq!(v["seed"], 7);
    let trace = std::fs::read_to_string(a.join("trace.csv")).expect("trace");
    // Header plus 300 cycles × 4 axes.
    assert_eq!(trace.lines().count(), 1 + 300 * 4);
}

#[test]
fn reproduce_writes_the_table_and_rows_over_seeds() {
    let d = dir("repro");
    let o = ringsync(&["reproduce", "--out", d.to_str().expect("p")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).expect("utf-8");
    assert!(
        text.contains("0.23267") && text.contains("49.270 %") && text.contains("over 8 seeds"),
        "{text}"
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("summary.json")).expect("read"))
            .expect("json");
    assert_eq!(summary["schema_version"], 2, "{summary}");
    assert!(summary["ringsync_version"].is_string());
    // A verdict on both of the paper's claims, each with our figure beside the paper's.
    let claims = summary["claims"].as_array().expect("claims");
    for (claim, metric, paper) in [
        ("controller", "Sync-RMSE", 49.270),
        ("controller", "Track-RMSE", 21.171),
        ("plan", "Sync-RMSE", 37.996),
    ] {
        let c = claims
            .iter()
            .find(|c| c["claim"] == claim && c["metric"] == metric)
            .unwrap_or_else(|| panic!("claim {claim} {metric}: {summary}"));
        assert!(
            (c["paper_percent"].as_f64().expect("paper") - paper).abs() < 1e-3,
            "{c}"
        );
        assert!(
            c["ours_percent"]["mean"].is_f64() && c["verdict"].is_string(),
            "{c}"
        );
    }
    assert!(
        text.contains("Claim 1, the controller (Sync-RMSE)")
            && text.contains("Claim 2, the plan (Sync-RMSE, sync controller)"),
        "{text}"
    );
    assert!(
        summary["bench"]["pd_ratio"].as_f64().expect("bench") > 1.0,
        "{summary}"
    );
    let rows = summary["cases"].as_array().expect("cases");
    let get = |ctl: &str| {
        rows.iter()
            .find(|r| r["controller"] == ctl && r["plan"] == "p2p-lumped")
            .expect("row")
    };
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().expect(k);
    let (pd, sync) = (get("pd"), get("sync"));
    get("ring-coupled");
    assert_eq!(rows.len(), 6, "three controllers on both plans");
    assert!(
        rows.iter()
            .any(|r| r["plan"] == "lumped-only" && r["controller"] == "sync")
    );
    for r in rows {
        // The default: 8 seeds per case, the means and spreads from every seed's value.
        assert_eq!(r["seeds"], 8, "{r}");
        let per: Vec<f64> = r["sync_rmse_per_seed"]
            .as_array()
            .expect("per seed")
            .iter()
            .map(|v| v.as_f64().expect("f64"))
            .collect();
        assert_eq!(per.len(), 8);
        let mean = per.iter().sum::<f64>() / 8.0;
        assert!((f(r, "sync_rmse") - mean).abs() <= 1e-15 * mean, "{r}");
        // The sample standard deviation (n − 1) and the range of exactly these values.
        let sd = (per.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 7.0).sqrt();
        assert!(
            (f(r, "sync_rmse_sd") - sd).abs() <= 1e-12 * sd,
            "{r}: sd {sd}"
        );
        assert!(f(r, "track_rmse_sd") > 0.0, "{r}");
        let lo = per.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = per.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(
            (f(r, "sync_rmse_min"), f(r, "sync_rmse_max")),
            (lo, hi),
            "{r}"
        );
    }
    // The acceptance of the paper's result: the sync controller lowers both errors, in
    // the mean and in every seed.
    assert!(f(sync, "track_rmse") < f(pd, "track_rmse"));
    assert!(
        f(sync, "sync_rmse_max") < f(pd, "sync_rmse_min"),
        "pd {pd} sync {sync}"
    );
    let table = std::fs::read_to_string(d.join("table.md")).expect("table");
    assert!(
        table.contains(
            "| Sync-RMSE, sync controller vs standard PD, proposed (P2P + lumped) | 49.270 % |"
        ) && table.contains("Verdict:")
            && table.contains("the paper's sync controller lowers it by 49.270 %"),
        "{table}"
    );
    let html = std::fs::read_to_string(d.join("report.html")).expect("html");
    assert!(
        html.contains("<li>Claim 1, the controller (Sync-RMSE)")
            && html.contains("<li>Claim 2, the plan")
            && html.contains("seeds 1–8"),
        "{html}"
    );
}

/// Each seed's runs are the same whichever thread ran them: the reproduction's files do
/// not depend on `--jobs`; fewer seeds, fewer values; 0 seeds is bad input.
#[test]
fn reproduce_is_the_same_on_one_thread_or_two() {
    let d = dir("repro-jobs");
    let (a, b) = (d.join("a"), d.join("b"));
    for (out, jobs) in [(&a, "1"), (&b, "2")] {
        let o = ringsync(&[
            "reproduce",
            "--seeds",
            "3",
            "--jobs",
            jobs,
            "--out",
            out.to_str().expect("p"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for f in ["summary.json", "table.md", "report.html"] {
        assert_eq!(
            std::fs::read(a.join(f)).expect("a"),
            std::fs::read(b.join(f)).expect("b"),
            "{f}"
        );
    }
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("summary.json")).expect("read"))
            .expect("json");
    assert_eq!(
        summary["cases"][0]["seed_values"],
        serde_json::json!([1, 2, 3])
    );
    let o = ringsync(&["reproduce", "--seeds", "0", "--out", a.to_str().expect("p")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--seeds"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// `sim --set KEY=VALUE` runs the scenario with the keys set, as a sweep's case would;
/// a bad key, value or form is one line and exit 2, and nothing is written.
#[test]
fn sim_set_changes_keys_like_a_sweep_case() {
    let d = dir("sim-set");
    let out = d.join("pd");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "control.law=pd",
        "--set",
        "duration=\"0.3s\"",
        "--outputs",
        "summary",
        "--out",
        out.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).expect("read"))
            .expect("json");
    assert_eq!(v["controller"], "pd", "{v}");
    assert_eq!(v["cycles"], 300, "{v}");
    // The same case through `sweep --set` gives the same Track-RMSE.
    let sw = d.join("sweep");
    let o = ringsync(&[
        "sweep",
        "paper-2015",
        "--set",
        "control.law=pd",
        "--set",
        "duration=\"0.3s\"",
        "--out",
        sw.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(sw.join("sweep.csv")).expect("csv");
    let track = v["track_rmse"].as_f64().expect("track");
    assert!(
        csv.contains(&format!(",{track:.9},")),
        "{track} not in {csv}"
    );
    for (set, says) in [
        ("control.law=nonesuch", "control.law"),
        ("control.alpha=-1", "control.alpha"),
        ("no such key=1", "scenario key"),
        // Not KEY=VALUE: clap's whole message (what was wrong, and --help), still exit 2.
        ("control.alpha", "expected KEY=VALUE"),
    ] {
        let bad = d.join("bad");
        let o = ringsync(&[
            "sim",
            "paper-2015",
            "--set",
            set,
            "--out",
            bad.to_str().expect("p"),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set}: {err}");
        if set.contains('=') {
            assert_eq!(err.lines().count(), 1, "{set}: {err}");
        }
        assert!(err.contains(says), "{set}: {err}");
        assert!(!bad.exists(), "{set}: wrote {}", bad.display());
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_runs_are_one_line_and_exit_2() {
    let d = dir("bad");
    for args in [
        vec!["sim", "no-such-scenario", "--out", d.to_str().expect("p")],
        vec![
            "reproduce",
            "--scenario",
            "no-such-scenario",
            "--out",
            d.to_str().expect("p"),
        ],
    ] {
        let o = ringsync(&args);
        let err = String::from_utf8(o.stderr).expect("utf-8");
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    let sc = d.join("lo.toml");
    std::fs::create_dir_all(&d).expect("dir");
    std::fs::write(
        &sc,
        "[ring]\nplan = \"lumped-only\"\nslaves = 60\ncycle = \"2ms\"\n",
    )
    .expect("write");
    let o = ringsync(&[
        "sim",
        sc.to_str().expect("p"),
        "--out",
        d.to_str().expect("p"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("at most 46 slaves"));
}

#[test]
fn sweep_writes_rows_means_and_a_figure() {
    let d = dir("sweep");
    let sc = short_scenario();
    let o = ringsync(&[
        "sweep",
        sc.to_str().expect("p"),
        "--set",
        "control.law=pd,sync",
        "--set",
        "faults.loss=0,0.02",
        "--seeds",
        "2",
        "--out",
        d.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = std::fs::read_to_string(d.join("sweep.csv")).expect("sweep.csv");
    assert_eq!(rows.lines().count(), 1 + 2 * 2 * 2);
    assert!(rows.starts_with("control.law,faults.loss,seed,track_rmse,sync_rmse"));
    let means = std::fs::read_to_string(d.join("means.csv")).expect("means.csv");
    assert_eq!(means.lines().count(), 1 + 4);
    assert!(
        std::fs::read_to_string(d.join("sweep.svg"))
            .expect("svg")
            .contains("<polyline")
    );
    let o = ringsync(&[
        "sweep",
        sc.to_str().expect("p"),
        "--set",
        "faults.lost=0.1",
        "--out",
        d.to_str().expect("p"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(String::from_utf8_lossy(&o.stderr).lines().count(), 1);
}

/// sweep.csv's last columns: the largest command and the most cycles an axis's drive was
/// held at its limit, 0 at the reference gains and most of the run at gains far too high.
#[test]
fn sweep_rows_count_the_cycles_at_the_drives_limit() {
    let d = dir("sweep-saturated");
    let sc = short_scenario();
    let o = ringsync(&[
        "sweep",
        sc.to_str().expect("p"),
        "--set",
        "control.kp=340,1e8",
        "--out",
        d.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = std::fs::read_to_string(d.join("sweep.csv")).expect("sweep.csv");
    let mut lines = rows.lines();
    assert!(
        lines
            .next()
            .is_some_and(|h| h.ends_with(",group_stop_s,peak_u_v,saturated_cycles")),
        "{rows}"
    );
    let last = |line: &str| -> (f64, u64) {
        let f: Vec<&str> = line.split(',').collect();
        let n = f.len();
        (
            f[n - 2].parse().expect("peak_u_v"),
            f[n - 1].parse().expect("saturated_cycles"),
        )
    };
    let (low, high): (Vec<_>, Vec<_>) = lines.partition(|l| l.starts_with("340,"));
    assert!(!low.is_empty() && !high.is_empty(), "{rows}");
    for l in low {
        let (peak, sat) = last(l);
        assert!(peak < 10.0 && sat == 0, "{l}");
    }
    for l in high {
        let (peak, sat) = last(l);
        assert!(peak == 10.0 && sat > 100, "{l}");
    }
}

/// A sweep with no key runs the scenario alone over its seeds: no key columns, one row of
/// means over them, each seed's Sync-RMSE what `sim --seed` gives, and a figure per seed.
#[test]
fn a_sweep_without_keys_runs_the_scenario_over_its_seeds() {
    let d = dir("sweep-seeds");
    let sc = short_scenario();
    let o = ringsync(&[
        "sweep",
        sc.to_str().expect("p"),
        "--seeds",
        "3",
        "--out",
        d.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.starts_with("| runs | Track-RMSE"), "{stdout}");
    let rows = std::fs::read_to_string(d.join("sweep.csv")).expect("sweep.csv");
    let lines: Vec<&str> = rows.lines().collect();
    assert_eq!(lines.len(), 1 + 3);
    assert!(
        lines[0].starts_with("seed,track_rmse,sync_rmse,"),
        "{}",
        lines[0]
    );
    let field = |line: &str, i: usize| -> f64 {
        line.split(',')
            .nth(i)
            .expect("field")
            .parse()
            .expect("number")
    };
    // The scenario's seed (1 by default), then +1, +2.
    let seeds: Vec<f64> = lines[1..].iter().map(|l| field(l, 0)).collect();
    assert_eq!(seeds, [1.0, 2.0, 3.0]);
    let sync: Vec<f64> = lines[1..].iter().map(|l| field(l, 2)).collect();
    assert!(sync[0] != sync[1] && sync[1] != sync[2], "{sync:?}");
    let means = std::fs::read_to_string(d.join("means.csv")).expect("means.csv");
    let m: Vec<&str> = means.lines().collect();
    assert_eq!(m.len(), 2);
    assert!(
        m[0].starts_with("runs,track_rmse_mean,sync_rmse_mean,"),
        "{}",
        m[0]
    );
    assert_eq!(field(m[1], 0), 3.0);
    let mean = sync.iter().sum::<f64>() / 3.0;
    assert!((field(m[1], 2) - mean).abs() < 2e-9, "{} vs {mean}", m[1]);
    // Seed 2's row is the single run with seed 2.
    let one = d.join("seed2");
    let o = ringsync(&[
        "sim",
        sc.to_str().expect("p"),
        "--seed",
        "2",
        "--outputs",
        "summary",
        "--out",
        one.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(one.join("summary.json")).expect("read"))
            .expect("json");
    let single = v["sync_rmse"].as_f64().expect("sync_rmse");
    assert!((single - sync[1]).abs() < 1e-9, "{single} vs {}", sync[1]);
    let svg = std::fs::read_to_string(d.join("sweep.svg")).expect("svg");
    assert!(
        svg.contains("<polyline") && svg.contains("Sync-RMSE of each of"),
        "{svg}"
    );
}

#[test]
fn pcap_holds_every_frame_sent() {
    let d = dir("pcap");
    let sc = dir("pcap-scenario").join("five.toml");
    std::fs::create_dir_all(sc.parent().expect("dir")).expect("dir");
    std::fs::write(&sc, "duration = \"5ms\"\n").expect("write");
    // Inside --out: written with the results, kept when --out is replaced.
    let pcap = d.join("run.pcapng");
    let o = ringsync(&[
        "sim",
        sc.to_str().expect("p"),
        "--out",
        d.to_str().expect("p"),
        "--pcap",
        pcap.to_str().expect("p"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let b = std::fs::read(&pcap).expect("pcap");
    assert_eq!(
        &b[0..4],
        &0x0A0D_0D0Au32.to_le_bytes(),
        "section header block"
    );
    // Walk the blocks and count the packets: per cycle every hop, as `rt --pcap` records
    // them: 5 lumped hops (master and 4 slaves), 4 commands with the 0 + 1 + 2 + 3 relays of
    // the slaves before their targets, 4 responses with the 3 + 2 + 1 + 0 relays of the
    // slaves behind their sources.
    let (mut at, mut packets) = (0usize, 0usize);
    while at < b.len() {
        let kind = u32::from_le_bytes(b[at..at + 4].try_into().expect("4"));
        let len = u32::from_le_bytes(b[at + 4..at + 8].try_into().expect("4")) as usize;
        packets += usize::from(kind == 6);
        at += len;
    }
    assert_eq!(at, b.len());
    assert_eq!(packets, 5 * 25);
}

fn files(d: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .expect("read dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn out_is_replaced_as_a_whole_or_left_untouched() {
    let base = dir("atomic");
    let out = base.join("run");
    std::fs::create_dir_all(&out).expect("dir");
    std::fs::write(out.join("summary.json"), "old summary").expect("old");
    std::fs::write(out.join("old-figure.svg"), "old figure").expect("old");
    let sc = short_scenario();
    let (sc, out_arg) = (sc.to_str().expect("p"), out.to_str().expect("p"));
    // A run that fails after simulating (its pcap cannot be written) leaves the old results.
    let o = ringsync(&[
        "sim",
        sc,
        "--out",
        out_arg,
        "--pcap",
        "/nonexistent-dir/x.pcapng",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot write /nonexistent-dir/x.pcapng"),
        "{err}"
    );
    assert_eq!(files(&out), ["old-figure.svg", "summary.json"]);
    assert_eq!(
        std::fs::read_to_string(out.join("summary.json")).expect("read"),
        "old summary"
    );
    assert_eq!(
        files(&base),
        ["run"],
        "no temporary directory left beside --out"
    );
    // So does a bad scenario.
    let o = ringsync(&["sim", "no-such-scenario", "--out", out_arg]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(files(&out), ["old-figure.svg", "summary.json"]);
    // A run that succeeds replaces the directory: the old figure is gone.
    let o = ringsync(&["sim", sc, "--out", out_arg]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let now = files(&out);
    assert!(!now.contains(&"old-figure.svg".to_string()), "{now:?}");
    assert!(now.contains(&"trace.csv".to_string()), "{now:?}");
    assert_ne!(
        std::fs::read_to_string(out.join("summary.json")).expect("read"),
        "old summary"
    );
    assert_eq!(files(&base), ["run"]);
    // A directory that holds something else is not replaced, nor is the scenario's own.
    let mine = base.join("mine");
    std::fs::create_dir_all(&mine).expect("dir");
    std::fs::write(mine.join("notes.txt"), "mine").expect("write");
    let o = ringsync(&["sim", sc, "--out", mine.to_str().expect("p")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("holds no ringsync results"), "{err}");
    assert_eq!(files(&mine), ["notes.txt"]);
    let inside = out.join("my.toml");
    std::fs::copy(sc, &inside).expect("copy");
    let o = ringsync(&["sim", inside.to_str().expect("p"), "--out", out_arg]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("is inside the results directory"), "{err}");
    assert!(inside.exists());
    // An --out that cannot be created fails at once, with one line.
    let o = ringsync(&[
        "sweep",
        sc,
        "--set",
        "faults.loss=0",
        "--out",
        "/proc/ringsync/x",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_group_stop_exits_3_with_its_results_written() {
    let d = dir("stop");
    std::fs::create_dir_all(&d).expect("dir");
    let sc = d.join("stop.toml");
    std::fs::write(
        &sc,
        "duration = \"300ms\"\n[faults]\nfollowing_error_limit = 0.001\n",
    )
    .expect("write");
    let sc = sc.to_str().expect("p");
    let out = d.join("sim");
    let o = ringsync(&["sim", sc, "--out", out.to_str().expect("p")]);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = String::from_utf8_lossy(&o.stdout);
    let stop = text
        .lines()
        .find(|l| l.contains("GROUP STOP at"))
        .expect("the stop is told");
    // In words, axes counted from 1: not the reason's debug form.
    assert!(
        stop.contains("following error on axis ") && !stop.contains('{'),
        "{stop}"
    );
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).expect("written"))
            .expect("json");
    assert!(!v["faults"]["group_stop"].is_null());
    // A sweep exits 3 when any case stopped, and only then.
    let sw = d.join("sweep");
    for (limits, status) in [("0.001,1.0", 3), ("1.0", 0)] {
        let set = format!("faults.following_error_limit={limits}");
        let o = ringsync(&["sweep", sc, "--set", &set, "--out", sw.to_str().expect("p")]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(status), "{limits}: {err}");
        assert!(sw.join("sweep.csv").exists());
    }
    let o = ringsync(&[
        "reproduce",
        "--scenario",
        sc,
        "--out",
        d.join("repro").to_str().expect("p"),
    ]);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(d.join("repro").join("table.md").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn pd_with_feed_forward_is_named_pd_ff() {
    let d = dir("pdff");
    std::fs::create_dir_all(&d).expect("dir");
    for (text, name) in [
        ("[control]\nlaw = \"pd\"\n", "pd"),
        ("[control]\nlaw = \"pd\"\nkc = 0.05\n", "pd+ff"),
    ] {
        let sc = d.join("pd.toml");
        std::fs::write(&sc, format!("duration = \"50ms\"\n{text}")).expect("write");
        let out = d.join("out");
        let o = ringsync(&[
            "sim",
            sc.to_str().expect("p"),
            "--out",
            out.to_str().expect("p"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            stdout.contains(&format!(", {name} controller,")),
            "{stdout}"
        );
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("summary.json")).expect("read"))
                .expect("json");
        assert_eq!(v["controller"], name);
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `--outputs` writes the named files only, each byte-identical to the full run's; an unknown
/// name is a usage error that names it.
#[test]
fn outputs_selects_the_files_written() {
    let sc = short_scenario();
    let full = dir("outputs-full");
    let run = |d: &PathBuf, outputs: &str| {
        ringsync(&[
            "sim",
            sc.to_str().expect("p"),
            "--out",
            d.to_str().expect("p"),
            "--outputs",
            outputs,
        ])
    };
    assert!(run(&full, "all").status.success());
    let listed = |d: &PathBuf| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .expect("dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    for (outputs, want) in [
        // scenario.toml, the run's scenario, comes with every selection.
        ("summary", vec!["scenario.toml", "summary.json"]),
        (
            "trace,report",
            vec!["report.html", "scenario.toml", "trace.csv"],
        ),
    ] {
        let d = dir(&format!("outputs-{}", outputs.replace(',', "-")));
        let o = run(&d, outputs);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(listed(&d), want, "{outputs}");
        for f in want {
            assert_eq!(
                std::fs::read(d.join(f)).expect("read"),
                std::fs::read(full.join(f)).expect("read"),
                "{outputs}: {f}"
            );
        }
    }
    // trace.parquet only when named: beside all the others, unchanged; the same bytes
    // from the same run (no time of writing in it); a Parquet file by its magic.
    let pq: Vec<Vec<u8>> = ["outputs-parquet-1", "outputs-parquet-2"]
        .iter()
        .map(|name| {
            let d = dir(name);
            let o = run(&d, "all,parquet");
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let mut want = listed(&full);
            want.push("trace.parquet".into());
            want.sort();
            assert_eq!(listed(&d), want);
            for f in listed(&full) {
                assert_eq!(
                    std::fs::read(d.join(&f)).expect("read"),
                    std::fs::read(full.join(&f)).expect("read"),
                    "all,parquet: {f}"
                );
            }
            std::fs::read(d.join("trace.parquet")).expect("trace.parquet")
        })
        .collect();
    assert!(pq[0].starts_with(b"PAR1") && pq[0].ends_with(b"PAR1"));
    assert_eq!(pq[0], pq[1], "trace.parquet is reproducible");
    let o = run(&dir("outputs-bad"), "summary,plots");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("unknown output 'plots'"), "{err}");
    assert!(err.contains("parquet"), "the names it lists: {err}");
}

/// `ringsync sim paper-2015` for 1 s with `faults.break_link = value`, summary only: the
/// process's output and its summary.json.
fn sim_broken(name: &str, value: &str) -> (std::process::Output, serde_json::Value) {
    let d = dir(name);
    let set = format!("faults.break_link={value}");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "duration=\"1s\"",
        "--set",
        &set,
        "--outputs",
        "summary",
        "--out",
        d.to_str().expect("utf-8"),
    ]);
    let v = serde_json::from_slice(&std::fs::read(d.join("summary.json")).expect("summary"))
        .expect("JSON");
    let _ = std::fs::remove_dir_all(&d);
    (o, v)
}

/// A broken link in `sim --set`: the run goes on (exit 0), and summary.json names the link,
/// when the master found it and the cycles it cost; two breaks stop the group (exit 3)
/// and name the slaves cut off.
#[test]
fn a_broken_link_is_reported_in_the_summary() {
    let (o, v) = sim_broken("broken", "\"2@500ms..800ms\"");
    assert_eq!(o.status.code(), Some(0), "{o:?}");
    let ring = &v["ring"];
    assert_eq!(ring["scheduled"][0], "2@0.5s..0.8s");
    assert_eq!(ring["changes"][0]["event"], "broken");
    assert_eq!(ring["changes"][0]["broken_link"], 2);
    assert_eq!(ring["changes"][0]["cycle"], 500);
    assert!(ring["changes"][0]["cycles_lost"].as_u64().expect("count") <= 1);
    assert_eq!(ring["changes"][1]["event"], "healed");
    assert_eq!(ring["at_end"], "whole");
    // And in the run's lines.
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("  ring: link 2 broken at 0.500 s (cycle 500"),
        "{text}"
    );
    assert!(
        text.contains("  ring: whole again at 0.800 s (cycle 800)"),
        "{text}"
    );
    let (o, v) = sim_broken("split", "[\"2@300ms\",\"4@600ms\"]");
    assert_eq!(o.status.code(), Some(3), "{o:?}");
    let stop = &v["faults"]["group_stop"];
    assert_eq!(stop["reason"], "ring-split");
    assert_eq!(stop["isolated_slaves"], serde_json::json!([2, 3]));
}

/// Starts `ringsync ARGS` with every signal at its default (a suite run in a background job
/// ignores SIGINT) and sends it SIGINT, as Ctrl-C does, once the directory it writes beside
/// `out` exists (the command takes the signal as a request from then on); returns its exit
/// status and stderr, and how long it took to end after the signal.
fn interrupt(args: &[&str], out: &Path) -> (Option<i32>, String, std::time::Duration) {
    let mut child = std::process::Command::new("env")
        .arg("--default-signal")
        .arg(env!("CARGO_BIN_EXE_ringsync"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start ringsync");
    let pid = child.id();
    let name = out.file_name().and_then(|n| n.to_str()).expect("name");
    let tmp = out.with_file_name(format!(".{name}.tmp-{pid}"));
    let started = std::time::Instant::now();
    while !tmp.exists() {
        if let Ok(Some(status)) = child.try_wait() {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = std::io::Read::read_to_string(&mut e, &mut err);
            }
            panic!("ringsync {args:?} ended before its results directory existed: {status}, {err}");
        }
        assert!(
            started.elapsed() < std::time::Duration::from_secs(120),
            "{} never appeared",
            tmp.display()
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    // Some runs of a sweep finish first (on a busy host perhaps none: both are checked).
    std::thread::sleep(std::time::Duration::from_millis(500));
    let sent = std::process::Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .expect("kill");
    assert!(sent.success());
    let signalled = std::time::Instant::now();
    let o = child.wait_with_output().expect("wait");
    let took = signalled.elapsed();
    assert!(!tmp.exists(), "{} left behind", tmp.display());
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        took,
    )
}

/// Ctrl-C: a sweep starts no case after it and writes the runs that finished (exit 1, the
/// count named); a simulation ends at its next cycle and writes nothing (exit 1), also
/// while it waits for a page of its scope; none leaves anything beside `--out`.
#[test]
fn ctrl_c_keeps_a_sweeps_finished_runs_and_a_sim_writes_nothing() {
    let d = dir("interrupted");
    std::fs::create_dir_all(&d).expect("dir");
    let p = |p: &Path| p.to_str().expect("utf-8 path").to_string();
    let out = d.join("sweep");
    let (code, err, _) = interrupt(
        &[
            "sweep",
            "paper-2015",
            "--set",
            "control.alpha=0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0",
            "--seeds",
            "1000",
            "--jobs",
            "1",
            "--out",
            &p(&out),
        ],
        &out,
    );
    assert_eq!(code, Some(1), "{err}");
    if out.exists() {
        let rows = std::fs::read_to_string(out.join("sweep.csv")).expect("sweep.csv");
        let finished = rows.lines().count() - 1;
        assert!((1..10_000).contains(&finished), "{finished} rows");
        assert!(
            err.contains(&format!(
                "interrupted: {finished} of 10000 runs finished and are written ({} not run;",
                10_000 - finished
            )),
            "{err}"
        );
        let means = std::fs::read_to_string(out.join("means.csv")).expect("means.csv");
        assert!(means.lines().count() >= 2, "{means}");
    } else {
        assert!(
            err.contains("interrupted before any run finished; nothing written"),
            "{err}"
        );
    }
    let out = d.join("sim");
    let (code, err, _) = interrupt(
        &[
            "sim",
            "paper-2015",
            "--set",
            "duration=\"3600s\"",
            "--out",
            &p(&out),
        ],
        &out,
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("ringsync: error: interrupted at cycle "),
        "{err}"
    );
    assert!(err.contains(" of 3600000; nothing written"), "{err}");
    assert!(!out.exists());
    // Waiting for a page to open the scope: Ctrl-C ends the wait (two minutes) at once.
    let out = d.join("scope");
    let (code, err, took) = interrupt(
        &[
            "sim",
            "paper-2015",
            "--scope",
            "127.0.0.1:0",
            "--scope-wait",
            "120s",
            "--out",
            &p(&out),
        ],
        &out,
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("interrupted at cycle 0 of 4000"), "{err}");
    assert!(took < std::time::Duration::from_secs(60), "{took:?}");
}

/// Ctrl-C twice: a command stuck where it does not look at the stop flag (here opening a
/// `--pcap` FIFO that nobody reads, after the run) ends at the second signal, as it would
/// have without a handler; the first only asks.
#[test]
fn a_second_ctrl_c_ends_a_stuck_command() {
    use std::os::unix::process::ExitStatusExt as _;
    let d = dir("twice");
    std::fs::create_dir_all(&d).expect("dir");
    let fifo = d.join("capture.pcapng");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(made.success());
    let out = d.join("run");
    let mut child = std::process::Command::new("env")
        .arg("--default-signal")
        .arg(env!("CARGO_BIN_EXE_ringsync"))
        .args(["sim", "paper-2015", "--set", "duration=\"0.2s\""])
        .arg("--pcap")
        .arg(&fifo)
        .arg("--out")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start ringsync");
    let pid = child.id();
    // Until it waits for a reader of the FIFO (the kernel names where it sleeps).
    let wchan = format!("/proc/{pid}/wchan");
    let started = std::time::Instant::now();
    while std::fs::read_to_string(&wchan).unwrap_or_default() != "wait_for_partner" {
        assert!(
            child.try_wait().expect("wait").is_none(),
            "ended before it opened the FIFO"
        );
        assert!(
            started.elapsed() < std::time::Duration::from_secs(120),
            "never opened the FIFO"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let int = |pid: u32| {
        let sent = std::process::Command::new("kill")
            .args(["-INT", &pid.to_string()])
            .status()
            .expect("kill");
        assert!(sent.success());
    };
    int(pid);
    std::thread::sleep(std::time::Duration::from_millis(500));
    assert!(
        child.try_wait().expect("wait").is_none(),
        "the first Ctrl-C only asks"
    );
    int(pid);
    let signalled = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if signalled.elapsed() > std::time::Duration::from_secs(60) {
            let _ = child.kill();
            panic!("still running 60 s after the second Ctrl-C");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    assert_eq!(status.signal(), Some(2), "{status}");
}
