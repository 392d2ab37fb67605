use ringsync_plant::{AxisModel, Friction, IndependentAxes, TorqueAxis};

use super::*;
use crate::Controller;
use crate::estimator::EstimatorKind;
use crate::law::{Feedback, Pd, SyncController, SyncParams, VelocitySource};
use crate::trajectory::{Cosine, State};

const DELAYS: [f64; 4] = [130e-6, 145e-6, 160e-6, 175e-6];

/// The reference axes (docs/system.md, "The reference scenario") without Coulomb friction.
fn reference_axes() -> Vec<AxisModel> {
    ringsync_plant::reference::axes(None).expect("axes")
}

fn linear(axes: &[AxisModel]) -> Vec<(f64, f64)> {
    axes.iter().map(|a| a.linear_part()).collect()
}

fn sync_law(kd: f64) -> SyncController {
    SyncController::new(Gains::uniform(4, 3.182, kd, 0.75), SyncParams::reference()).expect("sync")
}

#[test]
fn reference_loops_are_stable() {
    let axes = linear(&reference_axes());
    let pd = Pd::new(Gains::uniform(4, 3.182, 1.591, 0.0), false).expect("pd");
    let r = discrete_check(&pd, &axes, 1e-3, &DELAYS).expect("check");
    assert!(r.is_stable(), "PD ρ = {}", r.spectral_radius);
    assert_eq!(r.states, 36);
    let r = discrete_check(&sync_law(1.591), &axes, 1e-3, &DELAYS).expect("check");
    assert!(r.is_stable(), "sync ρ = {}", r.spectral_radius);
}

#[test]
fn a_gain_pushed_far_too_high_is_flagged() {
    let axes = linear(&reference_axes());
    // K_D × 100: the derivative loop alone has a pole near −10⁴ rad/s, far past what a 1 ms
    // sampled loop can hold.
    let pd = Pd::new(Gains::uniform(4, 3.182, 159.1, 0.0), false).expect("pd");
    let r = discrete_check(&pd, &axes, 1e-3, &DELAYS).expect("check");
    assert!(!r.is_stable(), "ρ = {}", r.spectral_radius);
    let r = discrete_check(&sync_law(159.1), &axes, 1e-3, &DELAYS).expect("check");
    assert!(!r.is_stable(), "ρ = {}", r.spectral_radius);
}

/// The spectral radius predicts how fast the real loop decays: run the Controller on the
/// stepped plant from an offset and compare the decay rate per cycle.
#[test]
#[allow(clippy::needless_range_loop)] // one index over several per-axis arrays
fn spectral_radius_matches_simulated_decay() {
    let models = reference_axes();
    let axes = linear(&models);
    let law = SyncController::new(
        Gains::uniform(4, 3.182, 1.591, 0.75),
        SyncParams {
            estimator: EstimatorKind::Paper,
            ..SyncParams::reference()
        },
    )
    .expect("law");
    let rho = discrete_check(&law, &axes, 1e-3, &DELAYS)
        .expect("check")
        .spectral_radius;
    let mut plant = IndependentAxes::new(models.clone());
    for i in 0..4 {
        plant.set_state(i, 0.05 * (i as f64 + 1.0), 0.0);
    }
    let mut ctl = Controller::new(law, VelocitySource::Reported);
    let mut fb = Feedback::new(4);
    let mut input = ControlInput::new(4, 1e-3);
    let mut out = ControlOutput::new(4);
    let mut u_prev = [0.0; 4];
    let mut norms = Vec::new();
    for m in 0..3000 {
        let t = m as f64 * 1e-3;
        for i in 0..4 {
            fb.position[i] = ringsync_plant::Plant::position(&plant, i);
            fb.velocity[i] = ringsync_plant::Plant::velocity(&plant, i);
            fb.sample_time[i] = t;
            fb.desired[i] = State::default();
            input.apply_time[i] = t + DELAYS[i];
        }
        norms.push((0..4).map(|i| fb.position[i].powi(2)).sum::<f64>().sqrt());
        ctl.update(&fb, &input, &mut out).expect("update");
        for (i, model) in models.iter().enumerate() {
            let (mut x, mut v) = (
                ringsync_plant::Plant::position(&plant, i),
                ringsync_plant::Plant::velocity(&plant, i),
            );
            model.step(&mut x, &mut v, u_prev[i], DELAYS[i]);
            model.step(&mut x, &mut v, out.u_raw[i], 1e-3 - DELAYS[i]);
            plant.set_state(i, x, v);
        }
        u_prev.copy_from_slice(&out.u_raw);
    }
    let (a, b) = (norms[1500], norms[2999]);
    let rate = (b / a).powf(1.0 / 1499.0);
    assert!((rate - rho).abs() < 2e-4, "simulated {rate} vs ρ {rho}");
}

#[test]
fn bad_inputs_are_errors() {
    let axes = linear(&reference_axes());
    let pd = Pd::new(Gains::uniform(4, 3.182, 1.591, 0.0), false).expect("pd");
    let e = discrete_check(&pd, &axes, 1e-3, &[2e-3; 4]).expect_err("delay > T");
    assert!(e.to_string().contains("delays[0]"), "{e}");
    assert!(discrete_check(&pd, &axes[..3], 1e-3, &DELAYS).is_err());
    assert!(discrete_check(&pd, &axes, 0.0, &DELAYS).is_err());
}

/// For equal viscous terms C = c·I and Ḣ = 0, ‖α·T·(−C)‖ = α·c·n/(n−1).
#[test]
fn condition_one_bound_by_hand() {
    let c = 3e-4;
    let models: Vec<AxisModel> = (0..4)
        .map(|_| {
            AxisModel::Torque(
                TorqueAxis::new(1e-3, 0.1, Friction::viscous(c * 0.1), 10.0).expect("axis"),
            )
        })
        .collect();
    let plant = IndependentAxes::new(models);
    let traj = vec![Cosine::with_peak_speed(15.12, 2.0).expect("cos"); 4];
    let gains = Gains::uniform(4, 3.182, 1.591, 0.75);
    let r =
        continuous_conditions(&plant, &traj, &gains, (0.5, 0.0, 0.0), 4.0, 41).expect("conditions");
    assert!(
        (r.cond1_bound - 0.5 * c * 4.0 / 3.0).abs() < 1e-12,
        "{}",
        r.cond1_bound
    );
    assert!((r.cond1_margin - (0.75 - r.cond1_bound)).abs() < 1e-15);
    assert!(r.condition1_holds());
    // Δ_H = 0 with K_H = 0: ‖H‖ = J/K_a = 0.01 > 0, so condition 2 fails (as in the
    // reference scenario, where K_N = 0).
    assert!((r.cond2_h_norm - 0.01).abs() < 1e-12);
    assert!(!r.condition2_holds());
    let ok = continuous_conditions(&plant, &traj, &gains, (0.5, 0.02, 0.001), 4.0, 41)
        .expect("conditions");
    assert!(ok.condition2_holds());
}

/// On the two-link arm Ḣ and C change along the motion; the bound is largest where the
/// speed is.
#[test]
fn arm_conditions_along_a_trajectory() {
    let arm = ringsync_plant::TwoLinkArm::new(ringsync_plant::ArmParams::default()).expect("arm");
    let traj = vec![Cosine::with_peak_speed(2.0, 2.0).expect("cos"); 2];
    let gains = Gains::uniform(2, 3.182, 1.591, 0.75);
    let r =
        continuous_conditions(&arm, &traj, &gains, (0.5, 0.0, 0.0), 2.0, 201).expect("conditions");
    assert!(r.cond1_bound > 0.0 && r.cond1_bound.is_finite());
    let none =
        continuous_conditions(&arm, &traj, &gains, (0.0, 0.0, 0.0), 2.0, 201).expect("conditions");
    assert_eq!(none.cond1_bound, 0.0);
    assert!(continuous_conditions(&arm, &traj[..1], &gains, (0.5, 0.0, 0.0), 2.0, 10).is_err());
}

/// The check builds the loop from the history alone: a law whose estimator keeps state
/// beyond it is refused, naming the estimator, not given a radius that means nothing.
#[test]
fn an_estimator_with_state_is_refused() {
    use crate::estimator::Smoothing;
    let axes = linear(&reference_axes());
    let law = SyncController::with_estimator(
        Gains::uniform(4, 3.182, 1.591, 0.75),
        SyncParams::reference(),
        Box::new(Smoothing::new(4, 0.5)),
    )
    .expect("law");
    let e = discrete_check(&law, &axes, 1e-3, &DELAYS).expect_err("refused");
    assert!(matches!(e, ControlError::NotApplicable { .. }), "{e:?}");
    assert!(e.to_string().contains("estimator smoothing"), "{e}");
    // The same law with the paper's estimator is checked.
    assert!(discrete_check(&sync_law(1.591), &axes, 1e-3, &DELAYS).is_ok());
}

/// `discrete_loop` hands back the matrix `discrete_check` takes the spectral radius of, with
/// the bookkeeping rows in the documented order.
#[test]
fn the_loop_matrix_is_the_one_checked() {
    let axes = linear(&reference_axes());
    let law = sync_law(1.591);
    let l = discrete_loop(&law, &axes, 1e-3, &DELAYS).expect("loop");
    let r = discrete_check(&law, &axes, 1e-3, &DELAYS).expect("check");
    assert_eq!(l.report, r);
    assert_eq!(l.matrix.shape(), (36, 36));
    let m = &l.matrix;
    for i in 0..4 {
        let o = PER_AXIS * i;
        // e[k−1] = −x, ė[k−1] = −ẋ; the older samples shift down.
        assert_eq!(m[(o + 3, o)], -1.0);
        assert_eq!(m[(o + 6, o + 1)], -1.0);
        assert_eq!((m[(o + 4, o + 3)], m[(o + 5, o + 4)]), (1.0, 1.0));
        assert_eq!((m[(o + 7, o + 6)], m[(o + 8, o + 7)]), (1.0, 1.0));
    }
    // nalgebra's own eigenvalues of the matrix (its default tolerances): the same radius.
    let rho = m
        .clone()
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max);
    assert!((rho - r.spectral_radius).abs() <= 1e-9 * r.spectral_radius);
}
