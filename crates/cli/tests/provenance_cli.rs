//! What the outputs say about themselves and how uniform the CLI is: versions in every JSON
//! output, CSV a CSV reader reads back, the same seeds default everywhere, shell
//! completions and man pages from the clap definitions.

mod common;

use common::{ringsync, scratch};

fn p(path: &std::path::Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Every JSON output starts with the tool's version and its schema's.
#[test]
fn json_outputs_name_their_version_and_schema() {
    let d = scratch("prov", "json");
    let sim = d.join("sim");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "duration=\"0.2s\"",
        "--outputs",
        "summary",
        "--out",
        p(&sim),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(sim.join("summary.json")).expect("summary");
    let version = env!("CARGO_PKG_VERSION");
    assert!(
        text.starts_with(&format!(
            "{{\n  \"ringsync_version\": \"{version}\",\n  \"schema_version\": 1,"
        )),
        "{}",
        &text[..200.min(text.len())]
    );
    for args in [
        vec!["plan", "--json"],
        vec!["check", "paper-2015", "--json"],
        vec!["program", "circle-xy", "--json"],
    ] {
        let o = ringsync(&args);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
        assert_eq!(v["ringsync_version"], version, "{args:?}");
        assert_eq!(v["schema_version"], 1, "{args:?}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `sweep --set` keeps an array whole, the CSV files quote what holds a comma (a CSV reader
/// gets every field back), and a sweep runs 8 seeds per case unless told otherwise, as
/// `reproduce` and Python do.
#[test]
fn sweep_values_with_commas_survive_and_seeds_default_to_eight() {
    let d = scratch("prov", "sweep");
    let out = d.join("sw");
    let o = ringsync(&[
        "sweep",
        "paper-2015",
        "--set",
        "duration=\"0.1s\"",
        "--set",
        "control.kp=[3.0,3.182,3.2,3.3],3.182",
        "--out",
        p(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut rd = csv::Reader::from_path(out.join("means.csv")).expect("means.csv");
    let header: Vec<String> = rd
        .headers()
        .expect("header")
        .iter()
        .map(String::from)
        .collect();
    assert_eq!(header[..3], ["duration", "control.kp", "runs"]);
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.expect("row")).collect();
    assert_eq!(rows.len(), 2, "two values of control.kp: {rows:?}");
    assert_eq!(&rows[0][1], "[3.0,3.182,3.2,3.3]");
    assert_eq!(&rows[1][1], "3.182");
    assert!(
        rows.iter().all(|r| &r[2] == "8"),
        "8 seeds per case: {rows:?}"
    );
    let raw = std::fs::read_to_string(out.join("sweep.csv")).expect("sweep.csv");
    assert!(raw.contains("\"[3.0,3.182,3.2,3.3]\""), "quoted: {raw}");
    let n = csv::Reader::from_path(out.join("sweep.csv"))
        .expect("sweep.csv")
        .records()
        .count();
    assert_eq!(n, 16);
    let _ = std::fs::remove_dir_all(&d);
}

/// Completions for every shell clap_complete knows, and man pages for every command.
#[test]
fn completions_and_man_pages_come_from_the_definitions() {
    let o = ringsync(&["completions", "bash"]);
    let script = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(
        script.contains("_ringsync()")
            && script.contains("reproduce")
            && script.contains("--auto-cycle"),
        "{script}"
    );
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        let o = ringsync(&["completions", shell]);
        assert!(o.status.success() && o.stdout.len() > 1000, "{shell}");
    }
    let o = ringsync(&["completions", "tcsh"]);
    assert_eq!(o.status.code(), Some(2));
    let d = scratch("prov", "man");
    let o = ringsync(&["man", "--out", p(&d)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let top = std::fs::read_to_string(d.join("ringsync.1")).expect("ringsync.1");
    assert!(
        top.contains(".TH ringsync 1") && top.contains("reproduce"),
        "{top}"
    );
    let sweep = std::fs::read_to_string(d.join("ringsync-sweep.1")).expect("sweep page");
    assert!(
        sweep.contains("\\-\\-seeds") && sweep.contains("8"),
        "{sweep}"
    );
    assert!(d.join("ringsync-scenario-show.1").exists());
    let _ = std::fs::remove_dir_all(&d);
}
