//! `ringsync scenario` and `ringsync check` end to end.

mod common;

use common::ringsync;

fn temp_file(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("ringsync-scenario-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
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
            "unknown variant `pid`",
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
    let p = temp_file("unstable.toml", "[control]\nkd = 159.1\n");
    let o = ringsync(&[
        "check",
        p.to_str().expect("path"),
        "--json",
        "--points",
        "11",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["discrete"]["stable"], false);
}
