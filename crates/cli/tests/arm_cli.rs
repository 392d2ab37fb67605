//! The coupled two-link arm (`[plant] kind = "two-link-arm"`) end to end: its scenario
//! errors, `check`'s verdict on it, and a run that names its assumptions.

mod common;

use common::ringsync;

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = common::scratch("arm", name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    d
}

const ARM: &str = "[ring]\nslaves = 2\n[plant]\nkind = \"two-link-arm\"\n";

#[test]
fn bad_arm_files_give_one_line_naming_the_key_and_exit_2() {
    let d = temp_dir("bad");
    for (name, text, want) in [
        (
            "four.toml",
            "[plant]\nkind = \"two-link-arm\"\n".to_string(),
            "ring.slaves = 4 is out of range: allowed 2 with plant.kind = \"two-link-arm\"",
        ),
        (
            "p3.toml",
            format!("{ARM}p3 = 0.2\n"),
            "plant.p3 = 0.2 is out of range: allowed 0 ..< 0.05099 kg·m²",
        ),
        (
            "friction.toml",
            format!("{ARM}friction = [0.1, 0.1, 0.1]\n"),
            "plant.friction = [0.1, 0.1, 0.1] is out of range: allowed a number or a list of 2 values",
        ),
        (
            "ka.toml",
            format!("{ARM}torque_constant = [2.0, -0.5]\n"),
            "plant.torque_constant (joint 2) = -0.5 is out of range: allowed > 0 N·m/V",
        ),
        (
            "key.toml",
            format!("{ARM}mass = 1.0\n"),
            "unknown field `mass`, expected one of `p1`, `p2`, `p3`, `friction`, `torque_constant`",
        ),
    ] {
        let p = d.join(name);
        std::fs::write(&p, text).expect("write");
        let path = p.to_str().expect("path");
        let out = d.join("out");
        for args in [
            vec!["scenario", "validate", path],
            vec!["check", path],
            vec!["sim", path, "--out", out.to_str().expect("path")],
        ] {
            let o = ringsync(&args);
            let err = String::from_utf8(o.stderr).expect("utf-8");
            assert_eq!(o.status.code(), Some(2), "{name} {args:?}: {err}");
            assert_eq!(err.lines().count(), 1, "{name}: {err}");
            assert!(err.contains(want), "{name}: {err}");
        }
    }
}

#[test]
fn check_does_not_vouch_for_the_arm() {
    let o = ringsync(&["check", "arm-2link", "--json", "--points", "11"]);
    assert_eq!(o.status.code(), Some(3), "not shown exits 3");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["verdict"], "not shown");
    assert!(v["discrete"].is_null() && v["conditions"].is_null(), "{v}");
    let why = v["not_modelled"].as_str().expect("a reason");
    assert!(why.contains("coupled two-link arm"), "{why}");
    let text = String::from_utf8(ringsync(&["check", "arm-2link"]).stdout).expect("utf-8");
    assert!(
        text.contains("Verdict: NOT SHOWN") && text.contains("two-link arm"),
        "{text}"
    );
}

#[test]
fn the_arm_is_built_in_and_its_run_names_its_assumptions() {
    let list = String::from_utf8(ringsync(&["scenario", "list"]).stdout).expect("utf-8");
    assert!(list.contains("arm-2link"), "{list}");
    let d = temp_dir("run");
    let shown = ringsync(&["scenario", "show", "arm-2link"]);
    let file = d.join("arm.toml");
    std::fs::write(&file, &shown.stdout).expect("write");
    let v = ringsync(&["scenario", "validate", file.to_str().expect("path")]);
    let said = String::from_utf8(v.stdout).expect("utf-8");
    assert!(said.contains("ok (arm-2link, 2 axes)"), "{said}");
    let assumptions = |scenario: &str, out: &str| {
        let out = d.join(out);
        let o = ringsync(&[
            "sim",
            scenario,
            "--out",
            out.to_str().expect("path"),
            "--seed",
            "2",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("summary.json")).expect("read"))
                .expect("json");
        let html = std::fs::read_to_string(out.join("report.html")).expect("html");
        let list: Vec<String> = v["assumptions"]
            .as_array()
            .expect("a list")
            .iter()
            .map(|a| a.as_str().expect("text").to_string())
            .collect();
        (list, html)
    };
    let (arm, html) = assumptions("arm-2link", "arm");
    let named = |l: &[String]| l.iter().any(|a| a.contains("no gravity"));
    assert!(named(&arm), "{arm:?}");
    assert!(html.contains("no gravity"));
    // The independent axes' run does not carry the arm's assumptions.
    let short = d.join("short.toml");
    std::fs::write(&short, "duration = \"100ms\"\n").expect("write");
    let (axes, _) = assumptions(short.to_str().expect("path"), "axes");
    assert!(!named(&axes) && axes.len() + 2 == arm.len(), "{axes:?}");
}
