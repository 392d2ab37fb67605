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
/// stepped plant from an offset and compare the decay rate per cycle, for every source of ė.
#[test]
fn spectral_radius_matches_simulated_decay() {
    let obs = VelocitySource::Observer(crate::law::ErrorObserver {
        bandwidth_hz: 100.0,
    });
    for velocity in [VelocitySource::Reported, VelocitySource::Differenced, obs] {
        decay_matches(Measurement {
            velocity,
            ..Measurement::default()
        });
    }
    // With the disturbance observer on the axes' own model.
    let axes = linear(&reference_axes());
    let dob = crate::dob::DobParams {
        bandwidth_hz: 20.0,
        h: axes.iter().map(|(_, g)| 1.0 / g).collect(),
        c: axes.iter().map(|(a, g)| a / g).collect(),
        u_max: vec![10.0; 4],
    };
    decay_matches(Measurement {
        dob: Some(dob),
        ..Measurement::default()
    });
}

/// Axis `model` from state (x, ẋ) `s` over one cycle `t_cyc` [s]: the old command
/// `u.0` [V] until `at` [s], then the new one `u.1`.
fn one_cycle(model: &AxisModel, s: (f64, f64), u: (f64, f64), at: f64, t_cyc: f64) -> (f64, f64) {
    let (mut x, mut v) = s;
    model.step(&mut x, &mut v, u.0, at);
    model.step(&mut x, &mut v, u.1, t_cyc - at);
    (x, v)
}

#[allow(clippy::needless_range_loop)] // one index over several per-axis arrays
fn decay_matches(meas: Measurement) {
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
    let rho = discrete_loop_with(&law, &axes, 1e-3, &DELAYS, &meas)
        .expect("check")
        .report
        .spectral_radius;
    let mut plant = IndependentAxes::new(models.clone());
    for i in 0..4 {
        plant.set_state(i, 0.05 * (i as f64 + 1.0), 0.0);
    }
    let mut ctl = Controller::new(law, meas.velocity);
    if let Some(p) = &meas.dob {
        let dob = crate::dob::DisturbanceObserver::new(p.clone()).expect("dob");
        ctl = ctl.with_dob(dob).expect("with dob");
    }
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
            let s = (
                ringsync_plant::Plant::position(&plant, i),
                ringsync_plant::Plant::velocity(&plant, i),
            );
            let (x, v) = one_cycle(model, s, (u_prev[i], out.u_raw[i]), DELAYS[i], 1e-3);
            plant.set_state(i, x, v);
        }
        u_prev.copy_from_slice(&out.u_raw);
    }
    let (a, b) = (norms[1500], norms[2999]);
    let rate = (b / a).powf(1.0 / 1499.0);
    assert!(
        (rate - rho).abs() < 2e-4,
        "{meas:?}: simulated {rate} vs ρ {rho}"
    );
}

/// Where ė comes from changes the loop: with K_D = 30 V·s/rad, PD on the slave's velocity
/// is stable, on differenced samples it is not (the simulator then drives the axes in a
/// ±10 V limit cycle, which `ringsync sim` shows); the observer's two states per axis are
/// in the matrix.
#[test]
fn the_velocity_source_is_part_of_the_loop() {
    let axes = linear(&reference_axes());
    let pd = Pd::new(Gains::uniform(4, 3.182, 30.0, 0.0), false).expect("pd");
    let rho = |velocity| {
        let m = Measurement {
            velocity,
            ..Measurement::default()
        };
        discrete_loop_with(&pd, &axes, 1e-3, &DELAYS, &m)
            .expect("check")
            .report
    };
    assert!(rho(VelocitySource::Reported).is_stable());
    let diff = rho(VelocitySource::Differenced);
    assert!(diff.spectral_radius > 1.05, "{diff:?}");
    let obs = VelocitySource::Observer(crate::law::ErrorObserver {
        bandwidth_hz: 100.0,
    });
    let m = Measurement {
        velocity: obs,
        ..Measurement::default()
    };
    let l = discrete_loop_with(&pd, &axes, 1e-3, &DELAYS, &m).expect("check");
    assert_eq!((l.states_per_axis, l.report.states), (11, 44));
    assert_eq!(l.matrix.nrows(), 44);
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

/// The frame passes of a lumped-only ring of four: slave i takes the frame about 13 µs
/// after the cycle start, 1.3 µs later per hop.
const PASSES: [f64; 4] = [13.1e-6, 14.4e-6, 15.7e-6, 17.0e-6];

/// The lumped-only loop's spectral radius predicts how fast a ring of slaves, each running
/// its own controller on its own view (this cycle's samples of the slaves up to itself,
/// last cycle's of those after it), decays from an offset: for the sync law on the
/// reported and the differenced velocity, and for PD.
#[test]
fn lumped_only_radius_matches_simulated_decay() {
    let sync = || {
        SyncController::new(
            Gains::uniform(4, 3.182, 1.591, 0.75),
            SyncParams {
                estimator: EstimatorKind::Paper,
                ..SyncParams::reference()
            },
        )
        .expect("law")
    };
    for velocity in [VelocitySource::Reported, VelocitySource::Differenced] {
        lumped_only_decay_matches(&sync, velocity);
    }
    let pd = || Pd::new(Gains::uniform(4, 3.182, 1.591, 0.0), false).expect("pd");
    lumped_only_decay_matches(&pd, VelocitySource::Reported);
}

#[allow(clippy::needless_range_loop)] // one index over several per-axis arrays
fn lumped_only_decay_matches<L: ControlLaw>(make: &dyn Fn() -> L, velocity: VelocitySource) {
    let models = reference_axes();
    let axes = linear(&models);
    let t_cyc = 1e-3;
    let m = Measurement {
        velocity,
        ..Measurement::default()
    };
    let l = lumped_only_loop(&make(), &axes, t_cyc, &PASSES, &m).expect("check");
    assert_eq!((l.states_per_axis, l.report.states), (11, 44));
    let rho = l.report.spectral_radius;
    let mut slaves: Vec<Controller<L>> =
        (0..4).map(|_| Controller::new(make(), velocity)).collect();
    let mut x: Vec<(f64, f64)> = (0..4).map(|i| (0.05 * (i as f64 + 1.0), 0.0)).collect();
    // Each axis's sample of the cycle before: what the frame still holds downstream.
    let mut before = x.clone();
    let mut fb = Feedback::new(4);
    let mut input = ControlInput::new(4, t_cyc);
    let mut out = ControlOutput::new(4);
    let mut u_prev = [0.0; 4];
    let mut norms = Vec::new();
    for m in 0..3000 {
        let t = m as f64 * t_cyc;
        norms.push(x.iter().map(|s| s.0 * s.0).sum::<f64>().sqrt());
        let mut u = [0.0; 4];
        for i in 0..4 {
            for j in 0..4 {
                let (s, ts) = if j <= i || m == 0 {
                    (x[j], t)
                } else {
                    (before[j], t - t_cyc)
                };
                fb.position[j] = s.0;
                fb.velocity[j] = s.1;
                fb.sample_time[j] = ts;
                fb.desired[j] = State::default();
                // New to slave i either way: a sample it had not seen.
                fb.fresh[j] = !(m == 0 && j > i && i > 0);
            }
            input.apply_time.fill(t + PASSES[i]);
            slaves[i].update(&fb, &input, &mut out).expect("update");
            u[i] = out.u_raw[i];
        }
        before.clone_from(&x);
        for (i, model) in models.iter().enumerate() {
            x[i] = one_cycle(model, x[i], (u_prev[i], u[i]), PASSES[i], t_cyc);
        }
        u_prev = u;
    }
    let (a, b) = (norms[1500], norms[2999]);
    let rate = (b / a).powf(1.0 / 1499.0);
    assert!(
        (rate - rho).abs() < 2e-4,
        "{velocity:?}: simulated {rate} vs ρ {rho}"
    );
}

/// With one slave there is nothing downstream: the lumped-only loop is the proposed plan's
/// with the pass as the delay (two more states, e[k−4] and ė[k−4], that nothing reads).
/// PD reads each axis's own error alone, fresh at its own slave: the same loop on four
/// axes too. The sync law couples the axes, and the stale view changes its loop.
#[test]
fn lumped_only_differs_from_the_proposed_plan_only_downstream() {
    let one = linear(&reference_axes()[..1]);
    let law = Pd::new(Gains::uniform(1, 3.182, 30.0, 0.0), false).expect("pd");
    for v in [VelocitySource::Reported, VelocitySource::Differenced] {
        let m = Measurement {
            velocity: v,
            ..Measurement::default()
        };
        let lo = lumped_only_loop(&law, &one, 1e-3, &PASSES[..1], &m).expect("lumped-only");
        let p2p = discrete_loop_with(&law, &one, 1e-3, &PASSES[..1], &m).expect("p2p");
        let (a, b) = (lo.report.spectral_radius, p2p.report.spectral_radius);
        assert!((a - b).abs() < 1e-9, "{v:?}: {a} vs {b}");
    }
    let axes = linear(&reference_axes());
    let radii = |law: &dyn ControlLaw| {
        let lo = lumped_only_loop(law, &axes, 1e-3, &PASSES, &Measurement::default())
            .expect("lumped-only");
        assert_eq!(lo.state_names, LUMPED_ONLY_STATE_NAMES);
        let p2p = discrete_check(law, &axes, 1e-3, &PASSES).expect("p2p");
        (lo.report.spectral_radius, p2p.spectral_radius)
    };
    for kd in [1.591, 30.0, 40.0] {
        let pd = Pd::new(Gains::uniform(4, 3.182, kd, 0.0), false).expect("pd");
        let (lo, p2p) = radii(&pd);
        assert!((lo - p2p).abs() < 1e-12, "PD, K_D {kd}: {lo} vs {p2p}");
    }
    // K_D = 20: both unstable, the stale view much more so (ρ 1.47 against 1.11).
    let (lo, p2p) = radii(&sync_law(20.0));
    assert!(lo > p2p + 0.3 && p2p > 1.0, "{lo} vs {p2p}");
    let law = sync_law(1.591);
    let obs = VelocitySource::Observer(crate::law::ErrorObserver {
        bandwidth_hz: 100.0,
    });
    assert!(matches!(
        lumped_only_loop(
            &law,
            &axes,
            1e-3,
            &PASSES,
            &Measurement {
                velocity: obs,
                ..Measurement::default()
            }
        ),
        Err(ControlError::NotApplicable { .. })
    ));
}

/// The spectral radius is found for every gain: a loop with large gains once failed the
/// Schur decomposition's convergence (K_D = 60, 80.3455, 120 V·s/rad with the sync law on
/// the reference delays); such a loop is balanced first. The radius grows smoothly with K_D.
#[test]
fn every_gain_gets_a_spectral_radius() {
    let axes = linear(&reference_axes());
    let delays = [122.34e-6, 141.72e-6, 161.10e-6, 180.48e-6];
    let mut last: Option<(f64, f64, f64)> = None;
    for step in 0..=320 {
        let kd = 1.591 + step as f64 * 0.5;
        let law = sync_law(kd);
        let p2p = discrete_check(&law, &axes, 1e-3, &delays)
            .expect("p2p")
            .spectral_radius;
        let lo = lumped_only_loop(&law, &axes, 1e-3, &PASSES, &Measurement::default())
            .expect("lumped-only")
            .report
            .spectral_radius;
        if let Some((k0, a, b)) = last {
            assert!(
                (p2p - a).abs() < 0.1 && (lo - b).abs() < 0.1,
                "K_D {k0} → {kd}: {a} → {p2p}, {b} → {lo}"
            );
        }
        last = Some((kd, p2p, lo));
    }
    for kd in [60.0, 80.3455, 120.0] {
        let law = sync_law(kd);
        assert!(
            discrete_check(&law, &axes, 1e-3, &delays).is_ok(),
            "K_D {kd}"
        );
    }
}

/// One cycle of the loop matrix is one cycle of the controllers on the stepped axes, to
/// rounding, where the drives report their mean velocity over a window: four `Controller`s
/// (one per slave, each on its view: the lumped-only plan) or one (the proposed plan), the
/// axes stepped forward through the command's switch and the window's start, the velocity
/// reported as the difference of the two positions. The sync law near the lumped-only
/// plan's edge, where the window matters.
#[test]
#[allow(clippy::needless_range_loop)] // one index over several per-axis arrays
fn one_step_of_the_matrix_is_one_cycle_of_the_controllers() {
    let models = reference_axes();
    let axes = linear(&models);
    let t_cyc = 1e-3;
    let w = 125e-6;
    let meas = Measurement {
        velocity_window: vec![w; 4],
        ..Measurement::default()
    };
    let law = || sync_law(12.0);
    for lumped in [true, false] {
        let delays = if lumped { PASSES } else { DELAYS };
        let l = if lumped {
            lumped_only_loop(&law(), &axes, t_cyc, &delays, &meas).expect("lumped-only")
        } else {
            discrete_loop_with(&law(), &axes, t_cyc, &delays, &meas).expect("p2p")
        };
        let per = l.states_per_axis;
        let slaves = if lumped { 4 } else { 1 };
        let mut ctl: Vec<_> = (0..slaves)
            .map(|_| Controller::new(law(), VelocitySource::Reported))
            .collect();
        // Per cycle at its sample: (x, ẋ, reported ẋ) per axis, and the command held.
        type Sample = (Vec<(f64, f64, f64)>, [f64; 4]);
        let mut rec: Vec<Sample> = Vec::new();
        let mut s: Vec<(f64, f64)> = (0..4).map(|i| (1e-3 * (i as f64 + 1.0), 0.0)).collect();
        let mut vrep: Vec<f64> = vec![0.0; 4];
        let mut u_prev = [0.0; 4];
        let (mut fb, mut input, mut out) = (
            Feedback::new(4),
            ControlInput::new(4, t_cyc),
            ControlOutput::new(4),
        );
        for m in 0..60 {
            let t = m as f64 * t_cyc;
            rec.push(((0..4).map(|i| (s[i].0, s[i].1, vrep[i])).collect(), u_prev));
            let mut u = [0.0; 4];
            for (k, c) in ctl.iter_mut().enumerate() {
                for j in 0..4 {
                    let stale = lumped && j > k && m > 0;
                    let (x, _, v) = if stale { rec[m - 1].0[j] } else { rec[m].0[j] };
                    fb.position[j] = x;
                    fb.velocity[j] = v;
                    fb.sample_time[j] = if stale { t - t_cyc } else { t };
                    fb.desired[j] = State::default();
                    fb.fresh[j] = true;
                    input.apply_time[j] = t + if lumped { delays[k] } else { delays[j] };
                }
                c.update(&fb, &input, &mut out).expect("update");
                if lumped {
                    u[k] = out.u_raw[k];
                } else {
                    u = [out.u_raw[0], out.u_raw[1], out.u_raw[2], out.u_raw[3]];
                }
            }
            for (i, model) in models.iter().enumerate() {
                let (mut x, mut v) = s[i];
                model.step(&mut x, &mut v, u_prev[i], delays[i]);
                model.step(&mut x, &mut v, u[i], t_cyc - delays[i] - w);
                let back = x;
                model.step(&mut x, &mut v, u[i], w);
                s[i] = (x, v);
                vrep[i] = (x - back) / w;
            }
            u_prev = u;
        }
        let z = |m: usize| {
            let mut z = vec![0.0; 4 * per];
            for i in 0..4 {
                let b = i * per;
                let (x, v, _) = rec[m].0[i];
                z[b] = x;
                z[b + 1] = v;
                z[b + 2] = rec[m].1[i];
                let depth = (per - 3) / 2;
                for q in 1..=depth {
                    z[b + 2 + q] = -rec[m - q].0[i].0;
                    z[b + 2 + depth + q] = -rec[m - q].0[i].2;
                }
            }
            nalgebra::DVector::from_vec(z)
        };
        for m in [10, 30, 58] {
            let (pred, got) = (&l.matrix * z(m), z(m + 1));
            let err = (&pred - &got).abs().max();
            assert!(
                err < 1e-9 * got.abs().max(),
                "lumped {lumped}, cycle {m}: {err:e} of {:e}",
                got.abs().max()
            );
        }
    }
}
