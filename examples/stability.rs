//! The stability analysis of docs/system.md, "Stability", on the reference axes: the discrete-time
//! spectral radius of each loop (PD, and the sync controller with each estimator) with the
//! 130-175 µs sample-to-actuation delays, and the paper's two conditions along the cosine
//! command.
//!
//! ```sh
//! cargo run --release --example stability
//! ```

use ringsync_control::stability::{continuous_conditions, discrete_check};
use ringsync_control::{ControlLaw, Cosine, EstimatorKind, Gains, Pd, SyncController, SyncParams};
use ringsync_plant::IndependentAxes;

const DELAYS: [f64; 4] = [130e-6, 145e-6, 160e-6, 175e-6];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The reference axes without Coulomb friction: the check linearises anyway.
    let models = ringsync_plant::reference::axes(None)?;
    let linear: Vec<(f64, f64)> = models.iter().map(|m| m.linear_part()).collect();
    println!(
        "Discrete-time check (T_cyc = 1 ms, delays 130/145/160/175 µs, Coulomb friction and saturation left out):"
    );
    let row = |name: &str, law: &dyn ControlLaw| -> Result<(), Box<dyn std::error::Error>> {
        let r = discrete_check(law, &linear, 1e-3, &DELAYS)?;
        let verdict = if r.is_stable() { "stable" } else { "UNSTABLE" };
        println!(
            "  {name:<28} spectral radius {:.6}  {verdict}",
            r.spectral_radius
        );
        Ok(())
    };
    row(
        "standard PD",
        &Pd::new(Gains::uniform(4, 3.182, 1.591, 0.0), false)?,
    )?;
    for est in [
        EstimatorKind::Hold,
        EstimatorKind::Linear,
        EstimatorKind::Paper,
    ] {
        let params = SyncParams {
            estimator: est,
            ..SyncParams::reference()
        };
        let law = SyncController::new(Gains::uniform(4, 3.182, 1.591, 0.75), params)?;
        row(&format!("sync, estimator {}", est.name()), &law)?;
    }
    row(
        "standard PD, K_D × 100",
        &Pd::new(Gains::uniform(4, 3.182, 159.1, 0.0), false)?,
    )?;

    let plant = IndependentAxes::new(models);
    let traj = vec![Cosine::with_peak_speed(15.12, 2.0)?; 4];
    let gains = Gains::uniform(4, 3.182, 1.591, 0.75);
    let r = continuous_conditions(&plant, &traj, &gains, (0.5, 0.0, 0.0), 4.0, 4001)?;
    println!("\nPaper's conditions along the cosine command (α = 0.5, K_E = 0.75, Δ_H = Δ_C = 0):");
    println!(
        "  condition 1: λ_min(K_E) = {:.4} vs max ‖αT(½Ḣ − C)‖ = {:.3e} V·s/rad: margin {:.4} ({})",
        r.lambda_min_ke,
        r.cond1_bound,
        r.cond1_margin,
        if r.condition1_holds() {
            "holds"
        } else {
            "fails"
        }
    );
    println!(
        "  condition 2: ‖K_H − H‖ = {:.4} V·s²/rad, ‖K_C − C‖ = {:.3e} V·s/rad against Δ_H = Δ_C = 0: {}",
        r.cond2_h_norm,
        r.cond2_c_norm,
        if r.condition2_holds() {
            "holds"
        } else {
            "fails (K_N = 0 in the reference scenario)"
        }
    );
    Ok(())
}
