//! Any text as a part program (docs/programs.md): the interpreter either gives canonical
//! moves or one error naming a line and column; what it accepts the planner either plans or
//! refuses with an error; a plan's duration is finite and the path is finite wherever it is
//! evaluated. A panic anywhere is a finding.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ringsync_path::interpret;
use ringsync_path::plan::{Limits, Machine, plan};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let l = Limits {
        v_max: 100.0,
        a_max: 500.0,
        j_max: 10_000.0,
    };
    let m = Machine {
        axes: [Some(l), Some(l), Some(l)],
        tolerance: 0.01,
    };
    let p = match interpret(text, m.present()) {
        Ok(p) => p,
        Err(e) => {
            assert!(e.at.line >= 1 && e.at.col >= 1, "{e}");
            assert!(!e.message.contains('\n'), "one line: {e}");
            return;
        }
    };
    // Keep an execution short: at most a few hundred moves.
    if p.moves.len() > 300 {
        return;
    }
    let Ok(path) = plan(&p, &m) else {
        return;
    };
    assert!(path.duration().is_finite() && path.duration() >= 0.0);
    for k in 0..=32 {
        let st = path.at(path.duration() * f64::from(k) / 32.0);
        assert!(st.p.is_finite() && st.v.is_finite() && st.a.is_finite() && st.j.is_finite());
    }
});
