//! `ringsync latency` as a user runs it: a short probe writes its figures; bad options give
//! one line and exit status 2.

mod common;

use common::ringsync;

#[test]
fn a_short_probe_reports_every_cycle() {
    let o = ringsync(&["latency", "--duration", "300ms", "--cycle", "1ms"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.starts_with("host latency over 300 cycles of 1000 µs"),
        "{stdout}"
    );
    assert!(stdout.contains("stalls per cycle p50"), "{stdout}");
    // --json prints the figures instead of the text, as plan --json and check --json do.
    let o = ringsync(&["latency", "--duration", "300ms", "--cycle", "1ms", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_slice(&o.stdout).expect("stdout is one JSON object");
    assert_eq!(v["schema_version"], 1);
    assert_eq!(v["cycles"], 300);
    assert_eq!(v["lateness_us"]["count"], 300);
    assert_eq!(v["stalls_us"]["count"], 300);
    let over = v["cycles_stalled_at_least_us"].as_array().expect("array");
    assert_eq!(over[0]["us"], 50.0);
    assert_eq!(over[0]["cycles"], v["cycles_stalled"]);
    // The real-time settings it applied (or the warnings), then the busy-wait.
    let rt = v["realtime"].as_array().expect("array");
    assert!(
        rt.last()
            .and_then(|l| l.as_str())
            .is_some_and(|l| l.contains("busy-wait"))
    );
}

#[test]
fn bad_options_are_one_line_and_status_2() {
    for (args, needle) in [
        (vec!["latency", "--cycle", "1us"], "--cycle"),
        (vec!["latency", "--busy", "2ms"], "--busy"),
        (vec!["latency", "--duration", "0s"], "--duration"),
    ] {
        let o = ringsync(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
    // Values the parser refuses: clap's whole message, its first line naming the option.
    for (args, needle) in [
        (vec!["latency", "--duration=-1s"], "--duration"),
        (vec!["latency", "--priority", "120"], "--priority"),
    ] {
        let o = ringsync(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        let first = stderr.lines().next().unwrap_or_default();
        assert!(first.contains(needle), "{args:?}: {stderr}");
        assert!(
            stderr
                .trim_end()
                .ends_with("For more information, try '--help'.")
        );
    }
}
