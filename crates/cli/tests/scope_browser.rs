//! The live scope in a real browser: a headless Chromium opens the page while `ringsync sim
//! --scope` replays a run, and the page's own counters (attributes of `<body>`) show that
//! frames arrived in sequence and the plots show all of them; the screenshot is kept in the
//! target directory (`target/tmp/scope-sim.png`).
//!
//! Chromium must be installed (Debian: `apt-get install --no-install-recommends chromium`;
//! `.ci/run` installs it): the test fails, with that message, when it is not. No tool
//! downloads a browser.
#![cfg(feature = "scope")]

use std::io::{BufRead as _, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Waits up to `limit` for `child`; kills it after that.
fn wait(child: &mut Child, limit: Duration, what: &str) -> std::process::ExitStatus {
    let end = Instant::now() + limit;
    loop {
        if let Some(s) = child.try_wait().expect("wait") {
            return s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            panic!("{what} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `<body data-NAME="…">` of the dumped DOM, as a number.
fn counter(dom: &str, name: &str) -> i64 {
    let key = format!("data-{name}=\"");
    let at = dom
        .find(&key)
        .unwrap_or_else(|| panic!("no {key} in the page: {}", &dom[..dom.len().min(400)]));
    let rest = &dom[at + key.len()..];
    rest[..rest.find('"').expect("closing quote")]
        .parse()
        .unwrap_or_else(|e| panic!("data-{name}: {e}"))
}

/// Fails, saying how to install it, when Debian's chromium is missing.
fn need_chromium() {
    match Command::new("chromium").arg("--version").output() {
        Ok(o) if o.status.success() => {}
        other => panic!(
            "chromium is not installed ({other:?}): the scope's browser test needs it. Install \
             Debian's package: `apt-get install -y --no-install-recommends chromium` (.ci/run does); \
             never a browser a tool downloads"
        ),
    }
}

/// Runs `ringsync sim SCENARIO ARGS --scope 127.0.0.1:0 --speed 8 --out OUT`, opens its
/// page in headless chromium (a screenshot to `shot`) and returns the page's DOM once
/// chromium's virtual time ran out, the run's exit status and its stderr.
fn replay_in_chromium(
    dir: &std::path::Path,
    scenario: &str,
    args: &[&str],
    shot: &std::path::Path,
) -> (String, std::process::ExitStatus, Vec<String>) {
    let out = dir.join("out");
    let mut sim = Command::new(env!("CARGO_BIN_EXE_ringsync"))
        .args(["sim", scenario])
        .args(args)
        .args([
            "--scope",
            "127.0.0.1:0",
            "--speed",
            "8",
            "--scope-wait",
            "30s",
            "--out",
        ])
        .arg(&out)
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run ringsync sim --scope");
    let stderr = sim.stderr.take().expect("stderr");
    let mut lines = BufReader::new(stderr).lines();
    let url = loop {
        let line = lines
            .next()
            .expect("ringsync sim ended before it served the scope")
            .expect("stderr");
        if let Some(u) = line.split("scope at ").nth(1) {
            break u.trim().to_string();
        }
    };
    // The rest of its stderr, so it never blocks on a full pipe.
    let rest = std::thread::spawn(move || lines.map_while(Result::ok).collect::<Vec<_>>());
    let _ = std::fs::remove_file(shot);
    let profile = dir.join("chromium-profile");
    let chromium = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=20000",
            "--window-size=1400,1300",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg("--dump-dom")
        .arg(&url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromium");
    let dom = {
        let mut c = chromium;
        let mut stdout = c.stdout.take().expect("stdout");
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut stdout, &mut s);
            s
        });
        let status = wait(&mut c, Duration::from_secs(60), "chromium");
        assert!(status.success(), "chromium: {status}");
        reader.join().expect("chromium's output")
    };
    let status = wait(&mut sim, Duration::from_secs(60), "ringsync sim --scope");
    let said = rest.join().expect("stderr");
    (dom, status, said)
}

#[test]
fn chromium_sees_a_replay_arrive_and_the_plots_update() {
    need_chromium();
    let dir = std::env::temp_dir().join(format!("ringsync-scope-{}", std::process::id()));
    let shot: PathBuf = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("scope-sim.png");
    // The weak axis 4 (K_P 0.8 V/rad) trips the sync monitor at about 0.58 s.
    let (dom, status, said) = replay_in_chromium(
        &dir,
        "paper-2015",
        &[
            "--set",
            "duration=\"2s\"",
            "--set",
            "control.kp=[3.182,3.182,3.182,0.8]",
            "--set",
            "monitor.sync_warn=0.02",
            "--set",
            "monitor.sync_trip=0.03",
            // Link 2 breaks before the trip: the ring drawing marks it.
            "--set",
            "faults.break_link=\"2@300ms\"",
        ],
        &shot,
    );
    assert_eq!(
        status.code(),
        Some(3),
        "the weak axis stops the group: {said:?}"
    );
    // Frames arrived, in sequence, nothing dropped or skipped; the plots were redrawn.
    let frames = counter(&dom, "frames");
    assert!(frames >= 3, "{frames} frames");
    assert!(
        counter(&dom, "rows") >= 100,
        "rows {}",
        counter(&dom, "rows")
    );
    // The plots were drawn, and the last drawing holds every row that arrived. Updates
    // that arrive within 16 ms of a drawing share the next one, so how many drawings there
    // were depends on the machine's load (a busy CI host delivered a whole replay between
    // two), never more than the updates.
    let draws = counter(&dom, "draws");
    assert!(
        draws >= 1 && draws <= frames,
        "draws {draws}, frames {frames}"
    );
    assert_eq!(
        counter(&dom, "drawn"),
        counter(&dom, "rows"),
        "the last drawing shows every row"
    );
    assert_eq!(counter(&dom, "gaps"), 0);
    assert_eq!(counter(&dom, "drops"), 0);
    assert_eq!(counter(&dom, "skipped"), 0);
    assert_eq!(
        counter(&dom, "seq"),
        frames - 1,
        "seq starts at 0, +1 per update"
    );
    // The ring drawing has the master and 4 slaves; the monitor table a row per axis.
    assert_eq!(dom.matches("data-node=").count(), 5, "ring drawing");
    assert_eq!(dom.matches("data-axis=").count(), 4, "monitor table");
    // The broken link, drawn dashed, and its event.
    assert_eq!(dom.matches("data-broken=").count(), 1, "the broken link");
    assert!(
        dom.contains("ring: whole → link 2 broken"),
        "the ring's event"
    );
    // uPlot drew its canvases.
    assert!(dom.matches("class=\"uplot").count() >= 5, "uPlot charts");
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{} bytes",
        png.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A part program's replay: the page shows the XY panel and draws the path in it (the
/// paper's scenario has no panel: the hidden section is not drawn).
#[test]
fn chromium_draws_a_programs_path_in_the_xy_panel() {
    need_chromium();
    let dir = std::env::temp_dir().join(format!("ringsync-scope-xy-{}", std::process::id()));
    let shot: PathBuf = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("scope-xy.png");
    let run = || replay_in_chromium(&dir, "circle-xy", &["--set", "duration=\"2s\""], &shot);
    let (mut dom, mut status, mut said) = run();
    // Headless Chromium's virtual time runs ahead of the wall clock: on a loaded host the
    // page's time budget can run out before the replay's messages reach it (seen in full suite
    // runs on 2026-12-08, the panel missing). Twice more, then the assertions stand.
    for _ in 0..2 {
        if dom.contains("Path in XY [mm]") {
            break;
        }
        (dom, status, said) = run();
    }
    assert_eq!(status.code(), Some(0), "{said:?}");
    assert!(
        dom.contains("Path in XY [mm]"),
        "the panel's title: {}",
        &dom[..dom.len().min(3000)]
    );
    assert!(
        !dom.contains("id=\"s-xy\" style=\"display: none"),
        "the panel is shown"
    );
    let points: i64 = dom
        .split("id=\"xy\"")
        .nth(1)
        .and_then(|r| r.split("data-points=\"").nth(1))
        .and_then(|r| r.split('"').next())
        .and_then(|v| v.parse().ok())
        .expect("the XY canvas's data-points");
    assert!(points >= 100, "{points} points drawn");
    assert!(
        dom.contains("circle-r50.ngc: commanded"),
        "the panel's note"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--scope-ab`: the scope feeds in alternate periods and the run reports the lateness of
/// both kinds; every cycle whose lateness the ring reports is in one of them.
#[test]
fn scope_ab_sorts_every_cycle_into_fed_or_idle() {
    let out = std::env::temp_dir().join(format!("ringsync-scope-ab-{}", std::process::id()));
    let o = Command::new(env!("CARGO_BIN_EXE_ringsync"))
        .args([
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--duration",
            "2s",
            "--watchdog-cycles",
            "20",
            "--no-sim-prediction",
            "--scope",
            "127.0.0.1:0",
            "--scope-ab",
            "250ms",
            "--out",
        ])
        .arg(&out)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run ringsync rt --scope-ab");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        matches!(o.status.code(), Some(0) | Some(3)),
        "{:?}: {err}",
        o.status
    );
    assert!(err.contains("alternate periods of 250 cycles"), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("scope A/B"))
        .unwrap_or_else(|| panic!("no A/B line: {err}"));
    // "… fed P50/P99/P999 µs (N cycles), idle … µs (M cycles); …"
    let cycles: Vec<u64> = line
        .split(" cycles)")
        .filter_map(|part| part.rsplit('(').next())
        .filter_map(|n| n.trim().parse().ok())
        .collect();
    assert_eq!(cycles.len(), 2, "{line}");
    assert!(cycles[0] > 0 && cycles[1] > 0, "{line}");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).expect("summary.json"))
            .expect("JSON");
    let reported = summary["lateness_us"]["count"]
        .as_u64()
        .expect("lateness count");
    assert_eq!(cycles[0] + cycles[1], reported, "{line}");
    let _ = std::fs::remove_dir_all(&out);
}

/// Bad scope options are usage errors: one line naming the option, exit status 2.
#[test]
fn bad_scope_options_are_named() {
    let run = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_ringsync"))
            .args(args)
            .env("RUST_BACKTRACE", "0")
            .output()
            .expect("run ringsync");
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let out = std::env::temp_dir().join(format!("ringsync-scope-usage-{}", std::process::id()));
    let out = out.to_str().expect("utf-8");
    // (arguments after the command, what the message must name)
    let cases: [(&[&str], &[&str]); 5] = [
        (&["sim", "--scope", "localhost-8080"], &["--scope"]),
        (
            &["sim", "--scope", "127.0.0.1:0", "--speed", "0"],
            &["--speed", "out of range"],
        ),
        (&["sim", "--speed", "2"], &["--scope"]),
        (
            &["rt", "--transport", "udp", "--scope-ab", "1s"],
            &["--scope"],
        ),
        (
            &["rt", "--transport", "udp", "--scope", "1.2.3"],
            &["--scope"],
        ),
    ];
    for (args, says) in cases {
        let mut all = vec![args[0], "paper-2015", "--out", out];
        all.extend_from_slice(&args[1..]);
        let (code, err) = run(&all);
        assert_eq!(code, Some(2), "{all:?}: {err}");
        for s in says {
            assert!(err.contains(s), "{all:?}: {err}");
        }
    }
    assert!(!std::path::Path::new(out).exists());
}
