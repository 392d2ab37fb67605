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
