//! `ringsync rt` as a user runs it: Ctrl-C and failures remove every namespace and link the
//! run created; bad options give one line and exit status 2.

mod common;

use std::io::{BufRead as _, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::ringsync;

fn namespaces_of(pid: u32) -> Vec<String> {
    let out = Command::new("ip")
        .args(["netns", "list"])
        .output()
        .expect("ip netns list (iproute2 is needed for the veth transport)");
    let prefix = format!("ringsync-{pid}-");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|n| n.starts_with(&prefix))
        .map(str::to_string)
        .collect()
}

#[test]
fn ctrl_c_ends_a_veth_run_cleanly_and_removes_its_namespaces() {
    let dir = std::env::temp_dir().join(format!("ringsync-rt-cli-{}", std::process::id()));
    let mut child = Command::new(env!("CARGO_BIN_EXE_ringsync"))
        .args([
            "rt",
            "paper-2015",
            "--transport",
            "veth",
            "--duration",
            "30s",
        ])
        .args(["--no-sim-prediction", "--out"])
        .arg(&dir)
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("start ringsync rt");
    let pid = child.id();
    let stderr = child.stderr.take().expect("stderr");
    let mut lines = BufReader::new(stderr).lines();
    let t = Instant::now();
    let mut seen = Vec::new();
    loop {
        let line = lines
            .next()
            .unwrap_or_else(|| panic!("ringsync rt ended before running: {seen:?}"))
            .expect("read stderr");
        seen.push(line.clone());
        if line.contains("running paper-2015") {
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "{seen:?}");
    }
    assert_eq!(
        namespaces_of(pid).len(),
        5,
        "the run has its 5 namespaces while it runs"
    );
    std::thread::sleep(Duration::from_millis(500));
    // SIGINT, as Ctrl-C sends it.
    let killed = Command::new("sh")
        .args(["-c", &format!("kill -INT {pid}")])
        .status()
        .expect("kill -INT");
    assert!(killed.success());
    let status = child.wait().expect("wait");
    assert_eq!(status.code(), Some(1), "an interrupted run exits 1");
    assert!(namespaces_of(pid).is_empty(), "{:?}", namespaces_of(pid));
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("partial summary");
    assert!(summary.contains("\"interrupted\": true"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_that_fails_after_building_the_ring_removes_it() {
    // A 300 µs cycle (the planner's wire figures fit it) cannot hold the measured ring: the run fails after the namespaces and
    // links exist, and must remove them.
    let dir = std::env::temp_dir().join(format!("ringsync-rt-fail-{}", std::process::id()));
    let out = ringsync(&[
        "rt",
        "paper-2015",
        "--transport",
        "veth",
        "--cycle",
        "300us",
        "--out",
        dir.to_str().expect("utf-8 path"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("the measured ring needs"), "{err}");
    assert!(err.contains("creating 5 network namespaces"), "{err}");
    // The child is gone; nothing of it may remain.
    let left: Vec<String> = Command::new("ip")
        .args(["netns", "list"])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).to_string())
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with("ringsync-"))
        .filter(|l| {
            l.split('-')
                .nth(1)
                .and_then(|p| p.parse::<u32>().ok())
                .is_some_and(|p| !std::path::Path::new(&format!("/proc/{p}")).exists())
        })
        .map(str::to_string)
        .collect();
    assert!(left.is_empty(), "{left:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_rt_options_give_one_line_and_exit_2() {
    let base = ["rt", "paper-2015", "--transport", "udp", "--out", "/tmp/x"];
    for (args, says) in [
        (
            vec!["rt", "no-such", "--transport", "udp", "--out", "/tmp/x"],
            "no-such",
        ),
        (
            vec!["rt", "paper-2015", "--transport", "tcp", "--out", "/tmp/x"],
            "tcp",
        ),
        (
            [&base[..], &["--kill-slave", "9", "--kill-at", "1s"]].concat(),
            "--kill-slave 9",
        ),
        ([&base[..], &["--cycle", "fast"]].concat(), "fast"),
        (
            [&base[..], &["--watchdog-cycles", "0"]].concat(),
            "faults.watchdog_cycles = 0",
        ),
        (
            [&base[..], &["--sample-lead", "2ms"]].concat(),
            "clock.sample_lead",
        ),
    ] {
        let out = ringsync(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(
            err.lines().filter(|l| l.contains("error")).count(),
            1,
            "{args:?}: {err}"
        );
    }
}

/// Starts `ringsync ARGS` and reads its standard error until a line contains `until`:
/// the child (its standard output piped) and the lines read.
fn start_until(args: &[&str], until: &str) -> (std::process::Child, Vec<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ringsync"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("start ringsync");
    let stderr = child.stderr.take().expect("stderr");
    let mut lines = BufReader::new(stderr).lines();
    let t = Instant::now();
    let mut seen = Vec::new();
    while !seen.last().is_some_and(|l: &String| l.contains(until)) {
        let line = lines
            .next()
            .unwrap_or_else(|| panic!("ringsync ended before {until:?}: {seen:?}"))
            .expect("read stderr");
        seen.push(line);
        assert!(t.elapsed() < Duration::from_secs(60), "{seen:?}");
    }
    // Keep draining, so that the child never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    (child, seen)
}

#[test]
fn sighup_ends_a_veth_run_cleanly_and_removes_its_namespaces() {
    // SIGHUP is what a run gets when its terminal closes: it must end as on Ctrl-C.
    let dir = std::env::temp_dir().join(format!("ringsync-rt-hup-{}", std::process::id()));
    let out = dir.to_str().expect("utf-8 path");
    let (mut child, seen) = start_until(
        &[
            "rt",
            "paper-2015",
            "--transport",
            "veth",
            "--duration",
            "30s",
            "--no-sim-prediction",
            "--out",
            out,
        ],
        "running paper-2015",
    );
    let pid = child.id();
    assert_eq!(namespaces_of(pid).len(), 5, "{seen:?}");
    std::thread::sleep(Duration::from_millis(500));
    let sent = Command::new("kill")
        .args(["-HUP", &pid.to_string()])
        .status()
        .expect("kill -HUP");
    assert!(sent.success());
    let status = child.wait().expect("wait");
    assert_eq!(
        status.code(),
        Some(1),
        "an interrupted run exits 1: {status}"
    );
    assert!(namespaces_of(pid).is_empty(), "{:?}", namespaces_of(pid));
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("partial summary");
    assert!(summary.contains("\"interrupted\": true"));
    let _ = std::fs::remove_dir_all(&dir);
}
