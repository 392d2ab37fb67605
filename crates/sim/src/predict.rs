//! The simulator's prediction for a scenario, to set beside a real-time run of it.

use ringsync_model::{Scenario, Spec};

use crate::run::{RunError, RunOptions, simulate};

/// The simulator's prediction for a scenario: means over several seeds, because one run's
/// Sync-RMSE moves by about ±10 % with the seed (encoder quantisation) and a real-time run
/// is one more draw of that noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimPrediction {
    /// Seeds run: the scenario's seed and the next ones.
    pub seeds: u64,
    /// Mean Track-RMSE [rad].
    pub track_rmse: f64,
    /// Mean Sync-RMSE [rad].
    pub sync_rmse: f64,
    /// Smallest and largest Sync-RMSE over the seeds [rad].
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
