//! 02: simulate the reference scenario with standard PD and with the paper's sync
//! controller, watch a run as it goes with an observer, and write one run's results.
//!
//! ```sh
//! cargo run --release -p ringsync --example 02_simulate
//! ```

use std::sync::{Arc, Mutex};

use ringsync::{AxisProbe, Duration, Observer, SimOptions};

/// Keeps the largest spread between the axes' position errors seen at a cycle start [rad]:
/// what the sync controller exists to keep small.
struct Spread(Arc<Mutex<f64>>);

impl Observer for Spread {
    fn cycle(&mut self, _k: i64, _t: f64, axes: &[AxisProbe]) {
        let e = axes.iter().map(|a| a.x_d - a.x);
        let (lo, hi) = e.fold((f64::MAX, f64::MIN), |(l, h), e| (l.min(e), h.max(e)));
        if let Ok(mut m) = self.0.lock() {
            *m = m.max(hi - lo);
        }
    }
}

fn main() -> Result<(), ringsync::Error> {
    let mut rows = Vec::new();
    for law in ["pd", "sync"] {
        // The reference scenario (every key defaults to paper-2015), 1 s, with this law.
        let text = format!("duration = \"1s\"\n[control]\nlaw = \"{law}\"\n");
        let s = ringsync::parse(&text, law)?.scenario;
        let spread = Arc::new(Mutex::new(0.0));
        let r = ringsync::simulate_with(
            &s,
            &SimOptions::default(),
            vec![Box::new(Spread(spread.clone()))],
            &mut |_, _| {},
        )?;
        let worst = *spread
            .lock()
            .map_err(|_| ringsync::Error::Failed("lock".into()))?;
        println!(
            "{law:>4}: Track-RMSE {:.5} rad, Sync-RMSE {:.7} rad, largest spread of e {:.5} rad",
            r.summary.track_rmse, r.summary.sync_rmse, worst
        );
        rows.push(r.summary.sync_rmse);
    }
    // The paper's claim, on this run: the sync controller synchronises the axes better.
    assert!(rows[1] < rows[0], "sync {} vs pd {}", rows[1], rows[0]);

    // One run's results, written atomically into a directory.
    let mut s = ringsync::load("paper-2015")?.scenario;
    s.duration.0 = Duration::from_ms(500);
    let out = std::env::temp_dir().join(format!("ringsync-02-{}", std::process::id()));
    let r = ringsync::simulate(
        &s,
        &SimOptions {
            trace: true,
            ..Default::default()
        },
    )?;
    let mut dir = ringsync::OutDir::create("out", &out)?;
    ringsync::write_sim(&mut dir, &s, 0, &r, None, ringsync::Outputs::ALL)?;
    dir.commit()?;
    println!("wrote {}", out.join("summary.json").display());
    // The trace in columns: e of axis 1 at every computed cycle.
    let n = r.trace.axes;
    let e1: Vec<f64> = (0..r.trace.len())
        .step_by(n)
        .map(|row| r.trace.e(row))
        .collect();
    println!(
        "axis 1: {} samples of e, last {:.6} rad",
        e1.len(),
        e1[e1.len() - 1]
    );
    std::fs::remove_dir_all(&out).map_err(|e| ringsync::Error::io("cleaning up", e))?;
    Ok(())
}
