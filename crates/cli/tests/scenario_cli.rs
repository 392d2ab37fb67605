//! `ringsync scenario` and `ringsync check` end to end.

mod common;

use common::ringsync;

fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = common::scratch("scenario", "");
    std::fs::create_dir_all(&dir).expect("dir");
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// `ringsync check FILE --json --points 401` on a scenario file `name` holding `text`.
fn check_json(name: &str, text: &str) -> (std::process::Output, serde_json::Value) {
    let p = temp_file(name, text);
    let o = ringsync(&[
        "check",
        p.to_str().expect("path"),
        "--json",
        "--points",
        "401",
    ]);
    let v = serde_json::from_slice(&o.stdout).expect("json");
    (o, v)
}

#[test]
fn show_prints_a_file_that_loads_back() {
    let o = ringsync(&["scenario", "show", "paper-2015"]);
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).expect("utf-8");
    assert!(text.starts_with("# Scenario paper-2015"));
    let p = temp_file("shown.toml", &text);
    let o = ringsync(&["scenario", "validate", p.to_str().expect("path")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = ringsync(&["scenario", "list"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("paper-2015"));
}

#[test]
fn bad_scenarios_give_one_line_and_exit_2() {
    for (name, text, needle) in [
        ("syntax.toml", "[ring\nslaves = 4\n", "line 1"),
        (
            "unknown.toml",
            "[ring]\nslavez = 4\n",
            "unknown field `slavez`",
        ),
        (
            "range.toml",
            "[faults]\nloss = 7\n",
            "faults.loss = 7 is out of range",
        ),
        (
            "single.toml",
            "[ring]\nslaves = 1\n",
            "coupling needs two axes",
        ),
        (
            "law.toml",
            "[control]\nlaw = \"pid\"\n",
            "unknown control law 'pid': expected one of pd, sync, ring-coupled, adjacent",
        ),
    ] {
        let p = temp_file(name, text);
        for cmd in [&["check"][..], &["scenario", "validate"]] {
            let mut args = cmd.to_vec();
            args.push(p.to_str().expect("path"));
            let o = ringsync(&args);
            let err = String::from_utf8(o.stderr).expect("utf-8");
            assert_eq!(o.status.code(), Some(2), "{name}: {err}");
            assert_eq!(err.lines().count(), 1, "{name}: {err}");
            assert!(err.contains(needle), "{name}: {err}");
            assert!(o.stdout.is_empty());
        }
    }
    let o = ringsync(&["check", "no-such-scenario"]);
    assert_eq!(o.status.code(), Some(2));
    let o = ringsync(&["scenario", "show", "nope"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn check_reports_the_reference_as_stable() {
    let o = ringsync(&["check", "paper-2015", "--json", "--points", "101"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["discrete"]["stable"], true);
    assert_eq!(
        v["delays_ns"],
        serde_json::json!([122_340, 141_720, 161_100, 180_480])
    );
    assert_eq!(v["conditions"]["cond1_holds"], true);
    assert_eq!(v["conditions"]["cond2_holds"], false);
    let (o, v) = check_json("unstable.toml", "[control]\nkd = 159.1\n");
    assert_eq!(v["discrete"]["stable"], false);
    assert_eq!(v["verdict"], "unstable");
    assert_eq!(o.status.code(), Some(3), "an unstable loop exits 3");
}

/// Every command that takes a scenario: (arguments before the scenario, after it).
fn every_command(out: &str) -> Vec<(Vec<&str>, Vec<&str>)> {
    vec![
        (vec!["scenario", "validate"], vec![]),
        (vec!["check"], vec![]),
        (vec!["sim"], vec!["--out", out]),
        (vec!["sweep"], vec!["--set", "faults.loss=0", "--out", out]),
        (
            vec!["rt"],
            vec!["--transport", "udp", "--no-sim-prediction", "--out", out],
        ),
        (vec!["reproduce", "--out", out, "--scenario"], vec![]),
    ]
}

#[test]
fn every_command_rejects_what_validate_rejects_with_the_same_line() {
    let out = std::env::temp_dir().join(format!("ringsync-never-{}", std::process::id()));
    let out_arg = out.to_str().expect("path");
    for (name, text, says) in [
        (
            "no-axes.toml",
            "axis = []\n",
            "axis = [] is out of range: allowed at least one [[axis]] table",
        ),
        (
            "one-bit.toml",
            "[[axis]]\nencoder_bits = 1\n",
            "axis[0].encoder_bits = 1 is out of range: allowed 2 ..= 28",
        ),
        (
            "thirty-bits.toml",
            "[[axis]]\nencoder_bits = 30\n",
            "axis[0].encoder_bits = 30 is out of range: allowed 2 ..= 28 for this trajectory: velocities up to 30.2 rad/s (2 × the peak speed",
        ),
        (
            "lumped-60.toml",
            "[ring]\nplan = \"lumped-only\"\nslaves = 60\ncycle = \"2ms\"\n",
            "ring.slaves = 60 is out of range: allowed 1 ..= 46",
        ),
    ] {
        let p = temp_file(name, text);
        let p = p.to_str().expect("path");
        for (before, after) in every_command(out_arg) {
            let args = [&before[..], &[p], &after[..]].concat();
            let o = ringsync(&args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
            assert!(err.contains(says), "{args:?}: {err}");
            assert!(!out.exists(), "{args:?} created --out");
        }
    }
}

#[test]
fn huge_and_endless_files_are_refused_fast_and_errors_stay_short() {
    let big = temp_file("big.toml", &format!("# {}\n", "x".repeat(2 << 20)));
    for path in ["/dev/zero", big.to_str().expect("path")] {
        let t = std::time::Instant::now();
        let o = ringsync(&["scenario", "validate", path]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{path}: {err}");
        assert!(
            err.trim_end()
                .ends_with("larger than 1 MiB (1048576 bytes), the limit for a scenario file"),
            "{path}: {err}"
        );
        assert!(t.elapsed() < std::time::Duration::from_secs(5));
    }
    // A syntax error on a 1 MB line echoes a cut line.
    let long = temp_file(
        "long.toml",
        &format!("[ring]\nslaves = \"{}\"\n", "a".repeat(1_000_000)),
    );
    let o = ringsync(&["sim", long.to_str().expect("path"), "--out", "/tmp/never"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1);
    assert!(
        err.len() < 1_000 && err.contains('…'),
        "{} bytes: {err}",
        err.len()
    );
    assert!(err.trim_end().ends_with("expected u32"), "{err}");
}

#[test]
fn check_exits_3_unless_it_can_vouch_for_the_loop() {
    for (name, text, status, verdict) in [
        ("reference.toml", "", 0, "Verdict: stable"),
        (
            "thin-layer.toml",
            "[control]\ndelta_c = 1.0\nboundary_layer = 0.01\n",
            3,
            "Verdict: UNSTABLE",
        ),
        (
            "exact-sign.toml",
            "[control]\ndelta_c = 0.1\nboundary_layer = 0.0\n",
            3,
            "Verdict: NOT SHOWN: the check cannot vouch for stability with K_N != 0",
        ),
        (
            "lumped-only.toml",
            "[ring]\nplan = \"lumped-only\"\n",
            0,
            "Verdict: stable",
        ),
        // K_D = 17: past the lumped-only plan's edge (15.6), inside the proposed plan's (28.5).
        (
            "p2p-warm.toml",
            "[control]\nkd = 17.0\n",
            0,
            "Verdict: stable",
        ),
        (
            "lumped-only-hot.toml",
            "[ring]\nplan = \"lumped-only\"\n[control]\nkd = 17.0\n",
            3,
            "Verdict: UNSTABLE",
        ),
        (
            "lumped-only-observer.toml",
            "[ring]\nplan = \"lumped-only\"\n[control]\nvelocity = \"observer\"\n",
            3,
            "Verdict: NOT SHOWN: the discrete-time check does not model the slaves' own error or disturbance observers on the lumped-only plan",
        ),
    ] {
        let p = temp_file(name, text);
        let o = ringsync(&["check", p.to_str().expect("path"), "--points", "401"]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(status), "{name}: {text}");
        assert!(text.contains(verdict), "{name}: {text}");
    }
    let (o, v) = check_json(
        "thin-json.toml",
        "[control]\ndelta_c = 1.0\nboundary_layer = 0.01\n",
    );
    assert_eq!(o.status.code(), Some(3));
    assert_eq!(v["verdict"], "unstable");
    let extra = v["robust_term"]["extra_kd"].as_f64().expect("extra_kd");
    assert!((extra - 3024.0).abs() < 1e-6, "{extra}");
    assert!(v["discrete"]["spectral_radius"].as_f64().expect("rho") > 1.0);
    // The lumped-only plan's loop names its own states; the proposed plan's its nine.
    let (o, v) = check_json("lo-json.toml", "[ring]\nplan = \"lumped-only\"\n");
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(v["plan"], "lumped-only");
    assert_eq!(v["discrete"]["states"], 44);
    assert_eq!(v["discrete"]["state_names"][6], "e4");
    let (_, v) = check_json("p2p-json.toml", "");
    assert_eq!(v["plan"], "p2p-lumped");
    assert_eq!(
        v["discrete"]["state_names"].as_array().map(Vec::len),
        Some(9)
    );
}

#[test]
fn scenario_laws_lists_the_registry_with_parameters() {
    let o = ringsync(&["scenario", "laws"]);
    assert_eq!(o.status.code(), Some(0));
    let text = String::from_utf8(o.stdout).expect("utf-8");
    for name in ["pd", "sync", "ring-coupled", "adjacent"] {
        assert!(
            text.lines().any(|l| l.starts_with(&format!("{name} "))),
            "{text}"
        );
    }
    assert!(
        text.contains("kx = 1.591 V/rad (allowed >= 0 V/rad)"),
        "{text}"
    );
}

/// `check --set` checks the scenario with the key set, as `sim --set` runs it (issue 41:
/// `check` took no `--set`): too much damping for the sampled loop is unstable, exit 3.
#[test]
fn check_takes_set_as_sim_does() {
    let o = ringsync(&["check", "paper-2015"]);
    assert_eq!(o.status.code(), Some(0));
    let o = ringsync(&["check", "paper-2015", "--set", "control.kd=30"]);
    assert_eq!(o.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&o.stdout).contains("UNSTABLE"));
    let o = ringsync(&["check", "paper-2015", "--set", "control.alpha=-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("control.alpha"));
}
