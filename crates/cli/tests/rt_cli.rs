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

/// Sends `signal` to a veth run once it runs: the run ends cleanly, exit status 1, its
/// namespaces and links removed, its partial results written and marked interrupted.
fn a_signal_ends_a_veth_run_cleanly(signal: &str) {
    let dir = std::env::temp_dir().join(format!(
        "ringsync-rt-{}-{}",
        signal.to_lowercase(),
        std::process::id()
    ));
    let out = dir.to_str().expect("utf-8 path");
    // With every signal at its default: a suite started under nohup (SIGHUP ignored, which
    // the run rightly keeps ignoring) or in a background job (SIGINT ignored) still tests
    // what a terminal's run gets. `env` execs ringsync, so the pid is the run's.
    let mut cmd = Command::new("env");
    cmd.args([
        "--default-signal",
        env!("CARGO_BIN_EXE_ringsync"),
        "rt",
        "paper-2015",
        "--transport",
        "veth",
        "--in-process",
        "--duration",
        "30s",
        "--no-sim-prediction",
        "--out",
        out,
    ]);
    let (mut child, seen) = start_until(cmd, "running paper-2015");
    let pid = child.id();
    assert_eq!(
        namespaces_of(pid).len(),
        5,
        "the run has its 5 namespaces while it runs: {seen:?}"
    );
    std::thread::sleep(Duration::from_millis(500));
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .expect("kill");
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
    // It reports the cycles it ran (about half a second's), not the 30 s it planned.
    let v: serde_json::Value = serde_json::from_str(&summary).expect("json");
    let (ran, planned) = (v["cycles"].as_i64(), v["cycles_planned"].as_i64());
    assert_eq!(planned, Some(30_000), "{summary}");
    assert!(
        ran.is_some_and(|c| (100..5_000).contains(&c)),
        "cycles {ran:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ctrl_c_ends_a_veth_run_cleanly_and_removes_its_namespaces() {
    // SIGINT, as Ctrl-C sends it.
    a_signal_ends_a_veth_run_cleanly("INT");
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
        "--in-process",
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
        (
            [&base[..], &["--break-link", "9@1s"]].concat(),
            "faults.break_link = 9@1s is out of range",
        ),
        (
            [&base[..], &["--break-link", "2@x"]].concat(),
            "'2@x' is not a link break",
        ),
        (
            [&base[..], &["--stamps", "kernel"]].concat(),
            "--stamps kernel is for a ring of node processes",
        ),
        (
            [&base[..], &["--processes", "--stamps", "phy"]].concat(),
            "a ring of node processes stamps kernel or software",
        ),
        (
            vec![
                "rt",
                "paper-2015",
                "--transport",
                "veth",
                "--stamps",
                "phy",
                "--out",
                "/tmp/x",
            ],
            "needs the one loop that sees the master's sends (--in-process)",
        ),
        (
            [&base[..], &["--processes", "--in-process"]].concat(),
            "cannot be used with",
        ),
        (
            [&base[..], &["--stamps", "ptp"]].concat(),
            "use phy, software or kernel",
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

#[test]
fn rt_checks_out_before_the_run_and_exits_3_on_a_group_stop() {
    // An --out that cannot be created fails before the ring is built.
    let t = Instant::now();
    let o = ringsync(&[
        "rt",
        "paper-2015",
        "--transport",
        "udp",
        "--out",
        "/proc/ringsync/x",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("cannot create"), "{err}");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    // A slave taken out stops the group: results written, status 3.
    let dir = std::env::temp_dir().join(format!("ringsync-rt-stop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let dir_arg = dir.to_str().expect("utf-8 path");
    let udp = |extra: &[&str]| {
        let base = [
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--no-sim-prediction",
        ];
        ringsync(&[&base[..], extra, &["--out", dir_arg]].concat())
    };
    let o = udp(&[
        "--duration",
        "1s",
        "--watchdog-cycles",
        "20",
        "--kill-slave",
        "2",
        "--kill-at",
        "300ms",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("GROUP STOP"), "{stdout}");
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("summary written");
    assert!(summary.contains("\"group_stop\": {"), "{summary}");
    // A run that fails while writing (its pcap cannot be written) leaves the previous
    // results as they were, not half of its own.
    let o = udp(&["--duration", "200ms", "--pcap", "/nonexistent-dir/x.pcapng"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot write /nonexistent-dir/x.pcapng"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("summary.json")).expect("summary kept"),
        summary
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `ringsync ARGS`, to start.
fn ringsync_with(args: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_ringsync"));
    cmd.args(args);
    cmd
}

/// Starts `cmd` and reads its standard error until a line contains `until`: the child (its
/// standard output piped) and the lines read.
fn start_until(mut cmd: Command, until: &str) -> (std::process::Child, Vec<String>) {
    let mut child = cmd
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
    a_signal_ends_a_veth_run_cleanly("HUP");
}

#[test]
fn an_ordinary_users_limits_give_one_warning_each_and_the_run_completes() {
    // An ordinary user's limits: 8 MiB of lockable memory, no real-time priority. As root
    // the capabilities would override them, so they are dropped (CAP_IPC_LOCK,
    // CAP_SYS_NICE). Before: in the release build mlockall succeeded, and an allocation
    // past 8 MiB aborted the run ("memory allocation of … bytes failed"); the debug build,
    // larger at start, warned "cannot lock memory (Cannot allocate memory)", naming no limit.
    let dir = std::env::temp_dir().join(format!("ringsync-rt-user-{}", std::process::id()));
    let mut cmd = Command::new("prlimit");
    cmd.args(["--memlock=8388608", "--rtprio=0"]);
    let root = std::fs::read_to_string("/proc/self/status")
        .is_ok_and(|s| s.lines().any(|l| l.starts_with("Uid:\t0\t")));
    if root {
        cmd.args([
            "setpriv",
            "--inh-caps=-all",
            "--bounding-set=-ipc_lock,-sys_nice",
        ]);
    }
    let out = cmd
        .arg(env!("CARGO_BIN_EXE_ringsync"))
        // The scenario's 4 s: its recorder alone outgrows 8 MiB.
        .args([
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--no-sim-prediction",
        ])
        .args(["--watchdog-cycles", "20", "--out"])
        .arg(&dir)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run prlimit (util-linux)");
    let err = String::from_utf8_lossy(&out.stderr);
    // 0: done; 3: the host cut the run (a group stop), which is still a completed run.
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "{}: {err}",
        out.status
    );
    let count = |what: &str| err.lines().filter(|l| l.contains(what)).count();
    assert_eq!(
        count("warning: not locking memory: RLIMIT_MEMLOCK is 8 MiB"),
        1,
        "{err}"
    );
    assert_eq!(count("warning: cannot use SCHED_FIFO"), 1, "{err}");
    assert_eq!(count("memory locked"), 0, "{err}");
    assert!(err.contains("ulimit -l unlimited"), "{err}");
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    assert!(summary.contains("\"cycles\""), "{summary}");
    // trace.csv went to its file as the run went (the run's memory does not grow with
    // it), whole: a header, then the 4 axes' rows of every cycle the master computed.
    let v: serde_json::Value = serde_json::from_str(&summary).expect("json");
    assert_eq!(v["streamed"]["trace"], true, "{summary}");
    assert_eq!(v["streamed"]["trace_rows_dropped"], 0, "{summary}");
    let cycles = v["cycles"].as_i64().expect("cycles");
    let trace = std::fs::read_to_string(dir.join("trace.csv")).expect("trace.csv");
    let rows = trace.lines().count() as i64 - 1;
    assert!(
        trace.starts_with("t_s,axis,"),
        "{}",
        &trace[..80.min(trace.len())]
    );
    assert_eq!(rows % 4, 0, "{rows} rows");
    assert!(
        (cycles - 2..=cycles).contains(&(rows / 4)),
        "{rows} rows, {cycles} cycles"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn two_concurrent_runs_do_not_pin_the_same_cpu() {
    // Two probes at once (normal scheduler, nothing locked: the CPU claim is what is
    // tested). Other engineers' runs may hold CPUs too; whatever they hold, the two never
    // share one, and the second names the first when it cannot have a CPU of its own.
    let args = [
        "latency",
        "--duration",
        "3s",
        "--priority",
        "0",
        "--no-mlock",
    ];
    let (mut first, a) = start_until(ringsync_with(&args), "busy-wait");
    let (mut second, b) = start_until(ringsync_with(&args), "busy-wait");
    let pinned = |lines: &[String]| {
        lines.iter().find_map(|l| {
            l.strip_prefix("ringsync latency: pinned to CPU ")?
                .split(|c: char| !c.is_ascii_digit())
                .next()?
                .parse::<usize>()
                .ok()
        })
    };
    let (pa, pb) = (pinned(&a), pinned(&b));
    assert!(pa.is_none() || pa != pb, "{a:?} {b:?}");
    // Unpinned only when every CPU is held, and then the second names the first.
    let all_taken = |lines: &[String]| {
        lines
            .iter()
            .find(|l| l.contains("warning: every CPU is taken by another ringsync run"))
            .cloned()
    };
    assert!(pa.is_some() || all_taken(&a).is_some(), "{a:?}");
    if pb.is_none() {
        let w = all_taken(&b).unwrap_or_else(|| panic!("{b:?}"));
        if pa.is_some() {
            assert!(w.contains(&format!("PID {}", first.id())), "{w}");
        }
    }
    assert!(first.wait().expect("wait").success());
    assert!(second.wait().expect("wait").success());
}

#[test]
fn a_run_started_with_nohup_keeps_running_through_sighup() {
    // `nohup` starts a run with SIGHUP ignored, so that it outlives its terminal: the
    // handler must not undo that. Ctrl-C still ends it.
    let dir = std::env::temp_dir().join(format!("ringsync-rt-nohup-{}", std::process::id()));
    let mut nohup = Command::new("nohup");
    nohup
        .arg(env!("CARGO_BIN_EXE_ringsync"))
        .args([
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--duration",
            "30s",
        ])
        .args([
            "--no-sim-prediction",
            "--no-pin",
            "--priority",
            "0",
            "--out",
        ])
        .arg(&dir);
    let (mut child, _) = start_until(nohup, "running paper-2015");
    let pid = child.id().to_string();
    let signal = |sig: &str| {
        let sent = Command::new("kill")
            .args([sig, &pid])
            .status()
            .expect("kill");
        assert!(sent.success(), "kill {sig}");
    };
    signal("-HUP");
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().expect("try_wait").is_none(),
        "a run under nohup ended on SIGHUP"
    );
    signal("-INT");
    let status = child.wait().expect("wait");
    assert_eq!(status.code(), Some(1), "{status}");
    let summary = std::fs::read_to_string(dir.join("summary.json")).expect("partial summary");
    assert!(summary.contains("\"interrupted\": true"));
    // It reports the cycles it ran (about half a second's), not the 30 s it planned.
    let v: serde_json::Value = serde_json::from_str(&summary).expect("json");
    let (ran, planned) = (v["cycles"].as_i64(), v["cycles_planned"].as_i64());
    assert_eq!(planned, Some(30_000), "{summary}");
    assert!(
        ran.is_some_and(|c| (100..5_000).contains(&c)),
        "cycles {ran:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
