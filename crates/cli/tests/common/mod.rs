//! Shared by the CLI tests: run the `ringsync` binary as a user would.

use std::process::{Command, Output};

/// Runs `ringsync ARGS` without backtraces and returns its output.
pub fn ringsync(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ringsync"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("run ringsync")
}

/// A scratch path in the temporary directory, `ringsync-TAG-test-PID` (then `-NAME` when
/// `name` is not empty). The first call in a test process removes what earlier runs of
/// these tests left there whose process is gone: a run keeps its outputs for a look after
/// a failure, and the next run clears them, so they do not pile up.
#[allow(dead_code)] // not every test binary that shares this module makes scratch paths
pub fn scratch(tag: &str, name: &str) -> std::path::PathBuf {
    static SWEEP: std::sync::Once = std::sync::Once::new();
    let tmp = std::env::temp_dir();
    let prefix = format!("ringsync-{tag}-test-");
    SWEEP.call_once(|| {
        let Ok(entries) = std::fs::read_dir(&tmp) else {
            return;
        };
        for e in entries.flatten() {
            let file = e.file_name();
            let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
                continue;
            };
            let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
            if let Some(pid) = pid
                && pid != std::process::id()
                && !std::path::Path::new(&format!("/proc/{pid}")).exists()
            {
                let _ = std::fs::remove_dir_all(e.path());
                let _ = std::fs::remove_file(e.path());
            }
        }
    });
    let mut leaf = format!("{prefix}{}", std::process::id());
    if !name.is_empty() {
        leaf = format!("{leaf}-{name}");
    }
    tmp.join(leaf)
}
