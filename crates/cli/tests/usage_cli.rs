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
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("ringsync "));
    assert_eq!(ringsync(&["sim", "--help"]).status.code(), Some(0));
}
