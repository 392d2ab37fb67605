//! The simulator's prediction for a scenario, to set beside a real-time run of it.

use ringsync_model::{Scenario, Spec};
use ringsync_proto::Duration;
use ringsync_proto::PlanKind;

use crate::run::{RunError, RunOptions, simulate};

/// The simulator's prediction for a scenario: means over several seeds, because one run's
/// Sync-RMSE moves by about ±10 % with the seed (encoder quantisation) and a real-time run
/// is one more draw of that noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimPrediction {
    /// Seeds run: the scenario's seed and the next ones.
    pub seeds: u64,
    /// Mean Track-RMSE \[rad\].
    pub track_rmse: f64,
    /// Mean Sync-RMSE \[rad\].
    pub sync_rmse: f64,
    /// Smallest and largest Sync-RMSE over the seeds \[rad\].
    pub sync_rmse_range: (f64, f64),
}

/// Simulates `s` with `seeds` seeds from its own (the runtime's prediction: the scenario
/// as run, after its overrides).
pub fn predict(s: &Scenario, seeds: u64) -> Result<SimPrediction, RunError> {
    predict_spec(&s.build()?, seeds)
}

/// [`predict`] for a built ring (a runtime's measured one, for instance:
/// `ringsync_rt::schedule::measured_ring`).
pub fn predict_spec(spec: &Spec, seeds: u64) -> Result<SimPrediction, RunError> {
    let seeds = seeds.max(1);
    let (mut track, mut sync, mut lo, mut hi) = (0.0, 0.0, f64::INFINITY, 0.0f64);
    for k in 0..seeds {
        let mut sk = spec.clone();
        sk.scenario.seed = spec.scenario.seed.wrapping_add(k);
        let r = simulate(&sk, RunOptions::default(), Vec::new(), &mut |_, _| {})?;
        track += r.summary.track_rmse;
        sync += r.summary.sync_rmse;
        lo = lo.min(r.summary.sync_rmse);
        hi = hi.max(r.summary.sync_rmse);
    }
    Ok(SimPrediction {
        seeds,
        track_rmse: track / seeds as f64,
        sync_rmse: sync / seeds as f64,
        sync_rmse_range: (lo, hi),
    })
}

/// Cycles of the warm-up [`with_settled_arrivals`] runs (or the whole run, if shorter).
pub const SETTLE_CYCLES: i64 = 300;

/// `spec` with the law told when each axis's commands take effect on this ring: the
/// median, over a warm-up of [`SETTLE_CYCLES`] simulated cycles (the scenario's seed), of
/// each command's effect after its cycle start. The runtime does the same with its own
/// warm-up; a ring built from the runtime's measurements ([`predict_spec`] of
/// `ringsync_rt::schedule::measured_ring`) carries the arrivals the runtime's loop gave,
/// which the simulated ring's hops need not reproduce to the µs, and a law that times its
/// feed-forward for the wrong instant is a few µrad off at one encoder count. P2P plans
/// only (the lumped-only plan's law runs in the slaves); an axis whose commands never
/// took effect in the warm-up keeps its arrival.
pub fn with_settled_arrivals(spec: &Spec) -> Result<Spec, RunError> {
    let mut out = spec.clone();
    if spec.scenario.ring.plan != PlanKind::P2pLumped {
        return Ok(out);
    }
    let t_cyc = spec.scenario.ring.cycle.0.as_ns().max(1);
    let mut warm = spec.clone();
    let cycles = (spec.scenario.duration.0.as_ns() / t_cyc).min(SETTLE_CYCLES);
    warm.scenario.duration.0 = Duration::from_ns(cycles * t_cyc);
    let opts = RunOptions {
        trace: true,
        ..RunOptions::default()
    };
    let r = simulate(&warm, opts, Vec::new(), &mut |_, _| {})?;
    let n = r.trace.axes;
    for (axis, arrival) in out.master.command_arrival.iter_mut().enumerate().take(n) {
        let mut after: Vec<i64> = r
            .trace
            .t
            .iter()
            .enumerate()
            .filter_map(|(g, &t)| {
                let a = *r.trace.apply_time.get(g * n + axis)?;
                a.is_finite().then(|| ((a - t) * 1e9).round() as i64)
            })
            .filter(|&d| d >= 0 && d < t_cyc)
            .collect();
        if after.is_empty() {
            continue;
        }
        after.sort_unstable();
        *arrival = Duration::from_ns(after[after.len() / 2]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A law told the wrong arrivals is told, after the warm-up, when its commands take
    /// effect on the simulated ring: the plan's arrivals, to the timestamp resolution and
    /// the clocks' drift.
    #[test]
    fn settled_arrivals_are_where_the_commands_take_effect() {
        let spec = Scenario::default().build().expect("spec");
        let planned = spec.master.command_arrival.clone();
        let mut wrong = spec.clone();
        wrong.master.command_arrival.fill(Duration::from_ns(0));
        let settled = with_settled_arrivals(&wrong).expect("warm-up");
        assert_eq!(settled.master.command_arrival.len(), planned.len());
        for (s, p) in settled.master.command_arrival.iter().zip(&planned) {
            assert!((s.as_ns() - p.as_ns()).abs() < 100, "{s:?} against {p:?}");
        }
    }
}
