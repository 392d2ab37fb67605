//! `ringsync plan` end to end: the binary as a user runs it.

mod common;

use std::process::Output;

use common::ringsync;

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).expect("utf-8")
}

/// The value in µs of the first table row whose first column is `term`, in ns.
fn table_ns(table: &str, term: &str) -> i64 {
    let line = table
        .lines()
        .find(|l| l.trim_start().starts_with(term) && l.trim_start()[term.len()..].starts_with(' '))
        .unwrap_or_else(|| panic!("no row {term} in\n{table}"));
    let cols: Vec<&str> = line.split_whitespace().collect();
    // ... time [µs], share value, "%"
    let us = cols[cols.len() - 3];
    let (int, frac) = us.split_once('.').expect("µs with decimals");
    let sign = if int.starts_with('-') { -1 } else { 1 };
    sign * (int.trim_start_matches('-').parse::<i64>().expect("int") * 1000
        + frac.parse::<i64>().expect("frac"))
}

#[test]
fn json_matches_the_table() {
    for args in [
        &["plan", "--slaves", "4"][..],
        &[
            "plan",
            "--slaves",
            "7",
            "--cycle",
            "700us",
            "--bit-rate",
            "1G",
        ],
    ] {
        let table = ringsync(args);
        assert!(
            table.status.success(),
            "{}",
            String::from_utf8_lossy(&table.stderr)
        );
        let table = stdout(&table);
        let mut json_args = args.to_vec();
        json_args.push("--json");
        let json = ringsync(&json_args);
        assert!(json.status.success());
        let v: serde_json::Value = serde_json::from_str(&stdout(&json)).expect("valid JSON");
        let n = v["n"].as_u64().expect("n") as usize;
        for (term, key) in [
            ("T_lmf", "t_lmf_ns"),
            ("D_ms(n)", "d_ms_ns"),
            ("D_snm", "d_snm_ns"),
            ("T_rest", "t_rest_ns"),
            ("= T_syn", "t_syn_ns"),
            ("T_idle", "t_idle_ns"),
            ("= T_cyc", "t_cyc_ns"),
        ] {
            assert_eq!(
                table_ns(&table, term),
                v[key].as_i64().expect(key),
                "{term} vs {key}"
            );
        }
        let slots = v["slot_ns"].as_array().expect("slot_ns");
        assert_eq!(slots.len(), n);
        let mut sum = v["t_syn_ns"].as_i64().expect("syn") + v["t_idle_ns"].as_i64().expect("idle");
        for (i, s) in slots.iter().enumerate() {
            assert_eq!(
                table_ns(&table, &format!("T_slot({})", i + 1)),
                s.as_i64().expect("slot")
            );
            sum += s.as_i64().expect("slot");
        }
        let reserve =
            v["reserve_slices"].as_i64().expect("k") * v["reserve_slice_ns"].as_i64().expect("r");
        assert_eq!(
            table_ns(
                &table,
                &format!("reserve {}×T_slot({n})", v["reserve_slices"])
            ),
            reserve
        );
        // Eq. 1 from the JSON parts.
        assert_eq!(sum + reserve, v["t_cyc_ns"].as_i64().expect("cyc"));
        for key in [
            "link_bps",
            "lumped_frame_bytes",
            "command_frame_bytes",
            "response_frame_bytes",
            "t_cmf_ns",
            "min_t_cyc_ns",
            "max_n_for_t_cyc",
        ] {
            assert!(v[key].is_u64(), "{key} missing or not an integer");
        }
        assert!(table.contains(&format!("{} slaves.", v["max_n_for_t_cyc"])));
    }
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    for (args, needle) in [
        (
            &["plan", "--slaves", "0"][..],
            "--slaves 0 is out of range: allowed 1..=65535",
        ),
        (&["plan", "--slaves", "-2"], "--slaves -2 is out of range"),
        (
            &["plan", "--bit-rate", "0"],
            "--bit-rate 0 bit/s is out of range",
        ),
        (
            &["plan", "--bit-rate", "-100M"],
            "--bit-rate '-100M' is negative",
        ),
        (&["plan", "--cycle", "150us"], "short by 74.690 µs"),
        (
            &["plan", "--cycle", "0s"],
            "--cycle 0.000 µs is out of range",
        ),
        (&["plan", "--cycle", "1000"], "has no unit"),
        (
            &["plan", "--residence", "-1us"],
            "--residence -1.000 µs is out of range",
        ),
        (
            &[
                "plan",
                "--slaves",
                "100",
                "--cycle",
                "1s",
                "--svg",
                "/tmp/never.svg",
            ],
            "--svg draws at most 64 slaves",
        ),
    ] {
        let o = ringsync(args);
        let err = String::from_utf8(o.stderr).expect("utf-8");
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        // One line of ours, or clap's whole message for a value its parser refused.
        let clap = err.starts_with("error: ")
            && err
                .trim_end()
                .ends_with("For more information, try '--help'.");
        assert!(
            err.lines().count() == 1 || clap,
            "{args:?}: not one line: {err}"
        );
        assert!(
            err.lines().next().is_some_and(|l| l.contains(needle)),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(o.stdout.is_empty(), "{args:?}: wrote to stdout on error");
    }
}

#[test]
fn svg_timing_diagram_is_written() {
    let dir = std::env::temp_dir().join(format!("ringsync-plan-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("cycle.svg");
    let o = ringsync(&[
        "plan",
        "--slaves",
        "4",
        "--svg",
        path.to_str().expect("path"),
    ]);
    assert!(o.status.success());
    let svg = std::fs::read_to_string(&path).expect("svg written");
    assert!(svg.starts_with("<?xml") && svg.trim_end().ends_with("</svg>"));
    for lane in [
        "master",
        "slave 1",
        "slave 4",
        "sync",
        "T_rest",
        "idle",
        "response of slave 3",
    ] {
        assert!(svg.contains(lane), "no {lane} in the diagram");
    }
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn events_give_the_timeline() {
    let o = ringsync(&["plan", "--json", "--events"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("json");
    let passages = v["timeline"]["passages"].as_array().expect("passages");
    // Lumped frame: master + 4 slaves + master; commands: 1 + 2 + 3 + 4 targets and
    // forwarders plus the master; responses: (4 − i) forwarders + origin + master.
    assert_eq!(passages.len(), 6 + (2 + 3 + 4 + 5) + (5 + 4 + 3 + 2));
}

#[test]
fn lumped_only_plan_checks_its_own_cycle() {
    let args = [
        "plan",
        "--slaves",
        "100",
        "--lumped-only-slot-bytes",
        "8",
        "--t-rest",
        "0us",
    ];
    // 100 slaves do not fit 1 ms with P2P slices ...
    let o = ringsync(&args);
    assert_eq!(o.status.code(), Some(2));
    // ... but the lumped-only plan needs 199.63 µs (docs/planner.md, EtherCAT comparison).
    let mut lo = args.to_vec();
    lo.extend(["--plan", "lumped-only", "--json"]);
    let o = ringsync(&lo);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("json");
    assert_eq!(v["plan"], "lumped-only");
    assert_eq!(v["lumped_only"]["min_t_cyc_ns"], 199_630);
    assert_eq!(v["lumped_only"]["t_idle_ns"], 1_000_000 - 199_630);
    let table = stdout(&ringsync(&lo[..lo.len() - 1]));
    assert!(table.contains("lumped-only plan of ref. [3]"));
    assert_eq!(table_ns(&table, "T_idle"), 1_000_000 - 199_630);
}

/// `--break-link J`: the broken ring's cycle, in the table and in the JSON, and a link
/// outside the ring refused with the range and exit code 2.
#[test]
fn break_link_plans_the_broken_ring() {
    let o = ringsync(&["plan", "--break-link", "3"]);
    assert!(o.status.success(), "{o:?}");
    let text = stdout(&o);
    assert!(
        text.contains("With link 3 broken (port A reaches slaves 1..2, port B slaves 3..4):"),
        "{text}"
    );
    let o = ringsync(&["plan", "--break-link", "1", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    let b = &v["broken_ring"];
    assert_eq!(b["side_a"], 0);
    assert_eq!(b["side_b"], 4);
    // Port A dead: every slave from port B, the copy stamped for its longer path (Δ > 0).
    assert!(b["stamp_shift"].as_i64().expect("ns") > 0, "{b}");
    assert!(b["lumped_back_a"].is_null());
    let o = ringsync(&["plan", "--break-link", "6"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8(o.stderr).expect("utf-8");
    assert!(
        err.contains("--break-link 6 is not a link of this ring: allowed 1..=5"),
        "{err}"
    );
}
