//! What every command shares: clap's whole message on bad usage, status 2; help and version
//! with status 0 and the exit statuses in `--help`.

mod common;

use common::ringsync;

/// Runs `ringsync ARGS`, expects status 2 and returns standard error.
fn usage_error(args: &[&str]) -> String {
    let o = ringsync(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?}: wrote to stdout");
    assert!(
        err.trim_end()
            .ends_with("For more information, try '--help'."),
        "{args:?}: {err}"
    );
    err
}

#[test]
fn clap_messages_survive_whole() {
    let err = usage_error(&["sim", "paper-2015"]);
    assert!(
        err.contains("the following required arguments were not provided")
            && err.contains("--out <DIR>"),
        "{err}"
    );
    assert!(
        err.contains("Usage: ringsync sim --out <DIR> <SCENARIO>"),
        "{err}"
    );
    let err = usage_error(&["plan", "--slave", "3"]);
    assert!(
        err.contains("unexpected argument '--slave'") && err.contains("'--slaves'"),
        "{err}"
    );
    let err = usage_error(&["rt", "paper-2015", "--transport", "foo", "--out", "/tmp/x"]);
    assert!(
        err.contains("invalid value 'foo'") && err.contains("[possible values: udp, veth]"),
        "{err}"
    );
    let err = usage_error(&["nosuchcommand"]);
    assert!(
        err.contains("unrecognized subcommand 'nosuchcommand'"),
        "{err}"
    );
    // A huge value is echoed cut, not whole.
    let long = "x".repeat(100_000);
    let err = usage_error(&["plan", "--cycle", &long]);
    assert!(
        err.len() < 2_000 && err.contains('…'),
        "{} bytes",
        err.len()
    );
}

#[test]
fn help_and_version_exit_0_and_help_names_the_exit_statuses() {
    let o = ringsync(&["--help"]);
    assert_eq!(o.status.code(), Some(0));
    let help = String::from_utf8_lossy(&o.stdout);
    for line in [
        "Exit status:",
        "  0  success",
        "  1  a runtime or I/O error",
        "  2  bad usage or input",
        "  3  the work finished and its results are written",
        "--out DIR is replaced as a whole",
    ] {
        assert!(help.contains(line), "{line:?} not in\n{help}");
    }
    let o = ringsync(&["--version"]);
    assert_eq!(o.status.code(), Some(0));
    let version = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(version.starts_with("ringsync "));
    // The commit it was built from (issue 41): the checkout's HEAD, as git names it.
    let head = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into());
    assert!(version.contains(&format!("({head})")), "{version}");
    assert_eq!(ringsync(&["sim", "--help"]).status.code(), Some(0));
}

/// Runs `ringsync ARGS`, expects status 2 with one `ringsync: error:` line and returns it.
fn input_error(args: &[&str]) -> String {
    let o = ringsync(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    assert!(err.starts_with("ringsync: error: "), "{args:?}: {err}");
    err
}

/// Inputs that used to pass silently or fail late: each refused at once, named.
#[test]
fn bad_inputs_are_refused_before_anything_runs() {
    let d = common::scratch("usage", "bad-inputs");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    let out = d.join("out");
    let out = out.to_str().expect("p");
    // A key twice, keys that overlap, seed as a key: the rows would be mislabelled.
    let err = input_error(&[
        "sweep",
        "paper-2015",
        "--set",
        "faults.loss=0,0.1",
        "--set",
        "faults.loss=0.2",
        "--out",
        out,
    ]);
    assert!(err.contains("faults.loss is given twice"), "{err}");
    let err = input_error(&[
        "sweep",
        "paper-2015",
        "--set",
        "control={}",
        "--set",
        "control.alpha=0.1",
        "--out",
        out,
    ]);
    assert!(err.contains("control and control.alpha overlap"), "{err}");
    let err = input_error(&["sweep", "paper-2015", "--set", "seed=1,2", "--out", out]);
    assert!(err.contains("seed is not a key to sweep"), "{err}");
    // Empty or repeated values, a value of two lines, --jobs 0: clap's own message.
    for (set, says) in [
        ("faults.loss=0,,0.1", "an empty value between commas"),
        ("faults.loss=0,0", "the value 0 twice"),
    ] {
        let o = ringsync(&["sweep", "paper-2015", "--set", set, "--out", out]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set}: {err}");
        assert!(err.contains(says), "{set}: {err}");
    }
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--set",
        "control.kp=2\ncontrol.kd=9",
        "--out",
        out,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("a value is one line"));
    let o = ringsync(&["sweep", "paper-2015", "--jobs", "0", "--out", out]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("at least 1 thread"));
    let o = ringsync(&[
        "sim",
        "paper-2015",
        "--seed",
        "9223372036854775808",
        "--out",
        out,
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = input_error(&[
        "sim",
        "paper-2015",
        "--set",
        "seed=9223372036854775808",
        "--out",
        out,
    ]);
    assert!(
        err.contains("beyond the integers a scenario holds"),
        "{err}"
    );
    // More gains than axes.
    let err = input_error(&[
        "sim",
        "paper-2015",
        "--set",
        "control.kp=[1,2,3,4,5]",
        "--out",
        out,
    ]);
    assert!(
        err.contains("control.kp = [1, 2, 3, 4, 5]") && err.contains("at most 4"),
        "{err}"
    );
    // An --out below a file.
    let file = d.join("file");
    std::fs::write(&file, "mine").expect("write");
    let below = file.join("x");
    let err = input_error(&["sim", "paper-2015", "--out", below.to_str().expect("p")]);
    assert!(err.contains("file is a file, not a directory"), "{err}");
    assert_eq!(std::fs::read_to_string(&file).expect("kept"), "mine");
    // Real-time options that cannot hold or never act (UDP: refused before any socket).
    for (args, says) in [
        (&["--spin", "5ms"][..], "--spin"),
        (&["--cpu", "100000"][..], "--cpu 100000"),
        (
            &["--kill-slave", "2", "--kill-at", "10s"][..],
            "--kill-at 10 s is not inside the run",
        ),
        (
            &[
                "--flap-link",
                "1-2",
                "--flap-at",
                "0.1s",
                "--flap-for",
                "0s",
            ][..],
            "--flap-for",
        ),
    ] {
        let mut a = vec![
            "rt",
            "paper-2015",
            "--transport",
            "udp",
            "--duration",
            "0.2s",
            "--out",
            out,
        ];
        a.extend_from_slice(args);
        let err = input_error(&a);
        assert!(err.contains(says), "{args:?}: {err}");
    }
    assert!(!std::path::Path::new(out).exists(), "nothing was written");
    let _ = std::fs::remove_dir_all(&d);
}

/// A results directory the tool wrote is its own, whatever `--outputs` left out of it; a
/// single file written through a link keeps the link, and a device stays a device.
#[test]
fn outputs_go_where_they_belong() {
    let d = common::scratch("usage", "outputs");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("dir");
    let out = d.join("run");
    for _ in 0..2 {
        let o = ringsync(&[
            "sim",
            "paper-2015",
            "--set",
            "duration=\"50ms\"",
            "--outputs",
            "parquet",
            "--out",
            out.to_str().expect("p"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    std::os::unix::fs::symlink("cycle.svg", d.join("link.svg")).expect("link");
    let o = ringsync(&["plan", "--svg", d.join("link.svg").to_str().expect("p")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::symlink_metadata(d.join("link.svg"))
            .expect("link")
            .file_type()
            .is_symlink()
    );
    assert!(
        std::fs::read_to_string(d.join("cycle.svg"))
            .expect("svg")
            .contains("<svg")
    );
    let o = ringsync(&["plan", "--svg", "/dev/null"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    use std::os::unix::fs::FileTypeExt;
    assert!(
        std::fs::metadata("/dev/null")
            .expect("null")
            .file_type()
            .is_char_device()
    );
    let _ = std::fs::remove_dir_all(&d);
}
