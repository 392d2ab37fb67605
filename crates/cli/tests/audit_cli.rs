//! Inputs an audit of the less-used commands found mishandled (2026-11-27): each is now one
//! line and exit status 2, without running out of memory, hanging, or overwriting a run.

mod common;

use std::path::Path;

use common::ringsync;

/// Runs `ringsync ARGS`, asserting exit status 2 and a stderr line containing `says`.
fn refused(args: &[&str], says: &str) {
    let o = ringsync(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
}

fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// A run directory and what `identify` makes of it edited: a trace that is /dev/zero (it
/// read it whole: the machine's memory), a trace cut at a row's end (it fitted half the
/// run), an `--out` that is the run's own trace (it replaced it).
#[test]
fn identify_refuses_endless_short_and_own_files() {
    let d = common::scratch("audit", "identify");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    let run = d.join("run");
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "duration=\"1s\"",
        "--out",
        p(&run),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let trace = run.join("trace.csv");
    let text = std::fs::read_to_string(&trace).expect("trace");
    let out = d.join("id.toml");
    refused(
        &["identify", p(&run), "--out", p(&trace)],
        "is the run's own trace.csv",
    );
    assert_eq!(std::fs::read_to_string(&trace).expect("trace"), text);
    // A position that is not a number, a summary that is not a run's.
    let head: Vec<&str> = text.lines().next().expect("header").split(',').collect();
    let cx = head.iter().position(|&h| h == "x_rad").expect("x_rad");
    let mut rows: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<&str> = rows[5].split(',').collect();
    cells[cx] = "nan";
    rows[5] = cells.join(",");
    std::fs::write(&trace, rows.join("\n") + "\n").expect("write");
    refused(
        &["identify", p(&run), "--out", p(&out)],
        "row 6, column x_rad: NaN, where a run that did not stop has a finite number",
    );
    std::fs::write(&trace, &text).expect("write");
    let summary = run.join("summary.json");
    let kept = std::fs::read_to_string(&summary).expect("summary");
    std::fs::write(&summary, "{}").expect("write");
    refused(
        &["identify", p(&run), "--out", p(&out)],
        "holds no `cycles`",
    );
    std::fs::write(&summary, kept).expect("write");
    // Half the rows, cut where a cycle ends (4 axes a cycle).
    let lines: Vec<&str> = text.lines().collect();
    let half = 1 + (lines.len() - 1) / 2 / 4 * 4;
    std::fs::write(&trace, lines[..half].join("\n") + "\n").expect("write");
    refused(
        &["identify", p(&run), "--out", p(&out)],
        "cycles, where summary.json says 1000",
    );
    std::fs::remove_file(&trace).expect("remove");
    std::os::unix::fs::symlink("/dev/zero", &trace).expect("link");
    refused(
        &["identify", p(&run), "--out", p(&out)],
        "a line longer than 65536 bytes",
    );
    std::fs::remove_file(&trace).expect("remove");
    std::fs::remove_file(run.join("summary.json")).expect("remove");
    std::os::unix::fs::symlink("/dev/zero", run.join("summary.json")).expect("link");
    refused(
        &["identify", p(&run), "--out", p(&out)],
        "not a regular file",
    );
    assert!(!out.exists());
}

/// Gains beyond double precision made `check` run for ever (now refused, as every gain
/// beyond 10¹² is: a law's commands could overflow to NaN); `plan --events` on a long
/// ring, and node plans that are /dev/zero, took all the memory; a link break after the
/// run's end was accepted and never happened.
#[test]
fn what_would_hang_or_exhaust_memory_is_refused() {
    let d = common::scratch("audit", "check");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    let huge = d.join("huge.toml");
    std::fs::write(&huge, "[control]\nkp = 1.5e308\n").expect("write");
    refused(
        &["check", p(&huge)],
        "control.kp (axis 1) = 1.5e308 is out of range: allowed > 0 ..= 1e12 V/rad",
    );
    refused(
        &[
            "plan", "--slaves", "300", "--cycle", "10s", "--json", "--events",
        ],
        "at most 256 slaves",
    );
    let rec = d.join("m.json");
    refused(
        &["node", "master", "--plan", "/dev/zero", "--out", p(&rec)],
        "not a regular file, as a node plan must be",
    );
    refused(
        &[
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--duration",
            "1s",
            "--break-link",
            "2@5s",
            "--out",
            p(&d.join("rt")),
        ],
        "would never happen",
    );
}

/// A file target in a missing directory is refused before the work (they failed with
/// status 1 after it); `rt --cycle 0ns` names the cycle (it
/// blamed `--spin`).
#[test]
fn targets_and_cycles_are_checked_before_the_work() {
    let d = common::scratch("audit", "targets");
    let missing = d.join("no-such-dir");
    refused(
        &["plan", "--svg", p(&missing.join("x.svg"))],
        "its directory",
    );
    refused(
        &["identify", p(&d), "--out", p(&missing.join("id.toml"))],
        "its directory",
    );
    refused(
        &[
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--cycle",
            "0ns",
            "--out",
            p(&d.join("rt")),
        ],
        "--cycle 0 s: a cycle must last some time",
    );
}

/// A node started from a plan whose run has already begun was told its start-up phase "ran
/// past the run's start … give it more time" (exit 1); it is told the plan is stale.
/// `ringsync node plan paper-2015` for a 1 s run on loopback starting `start_in` from now,
/// written to `out`.
fn node_plan(start_in: &str, out: &str) -> std::process::Output {
    ringsync(&[
        "node",
        "plan",
        "paper-2015",
        "--links",
        "lo:lo,lo:lo,lo:lo,lo:lo,lo:lo",
        "--start-in",
        start_in,
        "--duration",
        "1s",
        "--out",
        out,
    ])
}

#[test]
fn a_node_plan_whose_run_has_begun_is_refused_as_stale() {
    let d = common::scratch("audit", "stale-plan");
    std::fs::create_dir_all(&d).expect("scratch directory");
    let plan = d.join("plan.json");
    let o = node_plan("1.5s", p(&plan));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::thread::sleep(std::time::Duration::from_millis(1_700));
    let rec = d.join("rec");
    for node in [&["master"][..], &["slave", "--index", "2"][..]] {
        let mut args = vec!["node"];
        args.extend_from_slice(node);
        args.extend(["--plan", p(&plan), "--out", p(&rec)]);
        refused(&args, "the run this node plan describes started");
    }
}

/// `node plan --out` writes as every single file ringsync writes: through a symbolic link
/// (the link stays), and onto a device without replacing it (as root it used to rename its
/// temporary over /dev/full, replacing the host's device node with a file).
#[test]
fn a_node_plan_goes_through_links_and_never_replaces_a_device() {
    use std::os::unix::fs::FileTypeExt as _;
    let d = common::scratch("audit", "node-plan-out");
    std::fs::create_dir_all(&d).expect("scratch directory");
    let target = d.join("real.json");
    let link = d.join("link.json");
    std::fs::write(&target, "old").expect("target");
    std::os::unix::fs::symlink(&target, &link).expect("symlink");
    let plan = |out: &str| node_plan("5s", out);
    let o = plan(p(&link));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::symlink_metadata(&link)
            .expect("link")
            .file_type()
            .is_symlink()
    );
    let written = std::fs::read_to_string(&target).expect("through the link");
    assert!(
        written.starts_with('{') && written.contains("\"scenario\""),
        "{written}"
    );
    // A device: written to (/dev/null takes it), never replaced by a file.
    let o = plan("/dev/null");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = std::fs::metadata("/dev/null").expect("/dev/null");
    assert!(
        meta.file_type().is_char_device(),
        "/dev/null is still a device"
    );
    let o = plan("/dev/full");
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        std::fs::metadata("/dev/full")
            .expect("/dev/full")
            .file_type()
            .is_char_device(),
        "/dev/full is still a device"
    );
    let _ = std::fs::remove_dir_all(&d);
}
