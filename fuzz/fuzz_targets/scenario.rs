//! Any text as a scenario file. Whatever `Scenario::from_toml` accepts must then build, plan,
//! pass through the stability check without a panic, and run a few cycles in the simulator
//! (shortened so that an execution stays fast): "what `scenario validate` accepts they run".
//! Errors are fine at each step but the build; a panic anywhere is a finding.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ringsync_model::Scenario;
use ringsync_proto::Duration;

/// Most cycles simulated per input, and most axes for which a run is tried.
const CYCLES: i64 = 12;
const AXES: usize = 16;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(mut s) = Scenario::from_toml(text, "fuzz") else {
        return;
    };
    // Every message is one line.
    let spec = match s.build() {
        Ok(spec) => spec,
        Err(e) => panic!("a validated scenario does not build: {e}"),
    };
    let _ = ringsync_model::check::check(&s, 64);
    if spec.axes() > AXES {
        return;
    }
    let t_cyc = s.ring.cycle.0.as_ns();
    if s.duration.0.as_ns() > CYCLES * t_cyc {
        s.duration.0 = Duration::from_ns(CYCLES * t_cyc);
        if s.validate().is_err() {
            return;
        }
    }
    let _ = ringsync_sim::run(&s, ringsync_sim::RunOptions::default());
});
