//! Closes the loop on the reference scenario's four torque-mode axes (docs/system.md, "The reference scenario")
//! with standard PD and with the paper's sync controller, and prints Track-RMSE and
//! Sync-RMSE (eq. 26-27) of both as one JSON object.
//!
//! ```sh
//! cargo run --release --example closed_loop
//! ```
//!
//! Setup: cosine command (peak 15.12 rad/s, P = 2 s) on every axis for 4 s; one sample per
//! 1 ms cycle at the cycle start; the command of axis i takes effect 130, 145, 160, 175 µs
//! after the sample; exact position and velocity feedback (no quantisation), no estimator
//! (hold); K_P = 3.182 V/rad, K_D = 1.591 V·s/rad on every axis; the sync controller adds
//! α = 0.5, K_E = 0.75 V·s/rad. No network: this isolates the control law.

use ringsync_control::{
    ControlInput, ControlLaw, ControlOutput, Controller, Cosine, EstimatorKind, Feedback, Gains,
    Metrics, Pd, Summary, SyncController, SyncParams, Trajectory, VelocitySource,
};
use ringsync_plant::{Plant, SignModel};

const T_CYC: f64 = 1e-3;
const CYCLES: usize = 4000;
const DELAYS: [f64; 4] = [130e-6, 145e-6, 160e-6, 175e-6];

fn run<L: ControlLaw>(law: L) -> Result<Summary, Box<dyn std::error::Error>> {
    let models = ringsync_plant::reference::axes(Some(SignModel::Smooth { v_s: 1e-3 }))?;
    let mut plant = ringsync_plant::IndependentAxes::new(models.clone());
    let command = Cosine::with_peak_speed(15.12, 2.0)?;
    let mut ctl = Controller::new(law, VelocitySource::Reported);
    let mut fb = Feedback::new(4);
    let mut input = ControlInput::new(4, T_CYC);
    let mut out = ControlOutput::new(4);
    let mut metrics = Metrics::new(4);
    let mut u_held = [0.0; 4];
    let mut e = [0.0; 4];
    for m in 0..CYCLES {
        let t = m as f64 * T_CYC;
        let desired = command.at(t);
        for i in 0..4 {
            fb.position[i] = plant.position(i);
            fb.velocity[i] = plant.velocity(i);
            fb.sample_time[i] = t;
            fb.desired[i] = desired;
            e[i] = desired.x - fb.position[i];
            input.apply_time[i] = t + DELAYS[i];
            input.desired[i] = command.at(t + DELAYS[i]);
        }
        ctl.update(&fb, &input, &mut out)?;
        metrics.push(&e, &out.u, &out.saturated)?;
        // The previous command holds until this one takes effect.
        for (i, model) in models.iter().enumerate() {
            let (mut x, mut v) = (plant.position(i), plant.velocity(i));
            model.step(&mut x, &mut v, u_held[i], DELAYS[i]);
            model.step(&mut x, &mut v, out.u[i], T_CYC - DELAYS[i]);
            plant.set_state(i, x, v);
        }
        u_held.copy_from_slice(&out.u);
    }
    Ok(metrics.summary())
}

/// The metrics of standard PD and of the sync controller on the reference axes.
pub fn results() -> Result<(Summary, Summary), Box<dyn std::error::Error>> {
    let pd = run(Pd::new(Gains::uniform(4, 3.182, 1.591, 0.0), false)?)?;
    let params = SyncParams {
        alpha: 0.5,
        estimator: EstimatorKind::Hold,
        ..SyncParams::reference()
    };
    let sync = run(SyncController::new(
        Gains::uniform(4, 3.182, 1.591, 0.75),
        params,
    )?)?;
    Ok((pd, sync))
}

#[allow(dead_code)] // also compiled into a test, which calls results() only
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (pd, sync) = results()?;
    let json = serde_json::json!({
        "pd": { "track_rmse": pd.track_rmse, "sync_rmse": pd.sync_rmse },
        "sync": { "track_rmse": sync.track_rmse, "sync_rmse": sync.sync_rmse },
    });
    println!("{json}");
    Ok(())
}
