//! `ringsync sim` and `ringsync reproduce` end to end.

use std::path::PathBuf;
mod common;

use common::ringsync;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ringsync-sim-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn short_scenario() -> PathBuf {
    let d = dir("scenario");
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
fn reproduce_writes_the_table_and_rows() {
    let d = dir("repro");
    let o = ringsync(&["reproduce", "--out", d.to_str().expect("p")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).expect("utf-8");
    assert!(
        text.contains("0.23267") && text.contains("49.270 %"),
        "{text}"
    );
    let rows: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("summary.json")).expect("read"))
            .expect("json");
    let rows = rows.as_array().expect("array");
    let get = |ctl: &str| {
        rows.iter()
            .find(|r| r["controller"] == ctl && r["plan"] == "p2p-lumped")
            .map(|r| {
                (
                    r["track_rmse"].as_f64().expect("t"),
                    r["sync_rmse"].as_f64().expect("s"),
                )
            })
            .expect("row")
    };
    let (pd, sync) = (get("pd"), get("sync"));
    get("ring-coupled");
    assert_eq!(rows.len(), 6, "three controllers on both plans");
    assert!(
        rows.iter()
            .any(|r| r["plan"] == "lumped-only" && r["controller"] == "sync")
    );
    // The acceptance of the paper's result: the sync controller lowers both errors.
    assert!(sync.0 < pd.0 && sync.1 < pd.1, "pd {pd:?} sync {sync:?}");
    assert!(
        std::fs::read_to_string(d.join("table.md"))
            .expect("table")
            .contains("| reduction |")
    );
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

#[test]
fn pcap_holds_every_frame_sent() {
    let d = dir("pcap");
    std::fs::create_dir_all(&d).expect("dir");
    let sc = d.join("five.toml");
    std::fs::write(&sc, "duration = \"5ms\"\n").expect("write");
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
    // Walk the blocks and count the packets: per cycle 5 lumped hops (master and 4 slaves),
    // 4 commands and 4 responses.
    let (mut at, mut packets) = (0usize, 0usize);
    while at < b.len() {
        let kind = u32::from_le_bytes(b[at..at + 4].try_into().expect("4"));
        let len = u32::from_le_bytes(b[at + 4..at + 8].try_into().expect("4")) as usize;
        packets += usize::from(kind == 6);
        at += len;
    }
    assert_eq!(at, b.len());
    assert_eq!(packets, 5 * 13);
}
