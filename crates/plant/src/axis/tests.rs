use super::*;

fn axis(b: f64, tc: f64, sign: SignModel) -> TorqueAxis {
    // Reference axis 1: J = 4.96e-4 kg·m², K_a = 0.0318 N·m/V.
    TorqueAxis::new(
        4.96e-4,
        0.0318,
        Friction {
            viscous: b,
            coulomb: tc,
            sign,
        },
        10.0,
    )
    .expect("axis")
}

/// J ẍ = K_a·u − b·ẋ from rest: x(t) = (F/b)·(t − (1 − e^{−at})/a), v(t) = (F/b)(1 − e^{−at}),
/// a = b/J, F = K_a·u. Written out here independently of the stepping code.
#[test]
fn torque_axis_matches_closed_form_step_response() {
    let (j, ka, b, u) = (4.96e-4, 0.0318, 1e-3, 2.0);
    let ax = axis(b, 0.0, SignModel::Exact);
    let (a, f) = (b / j, ka * u);
    let (mut x, mut v) = (0.0, 0.0);
    for k in 1..=400 {
        ax.step(&mut x, &mut v, u, 1e-3);
        let t = k as f64 * 1e-3;
        let xe = f / b * (t - (1.0 - (-a * t).exp()) / a);
        let ve = f / b * (1.0 - (-a * t).exp());
        assert!(
            (x - xe).abs() <= 1e-12 * xe.abs().max(1.0),
            "t={t}: {x} vs {xe}"
        );
        assert!(
            (v - ve).abs() <= 1e-12 * ve.abs().max(1.0),
            "t={t}: {v} vs {ve}"
        );
    }
    // One long step equals many short ones (exact discretisation).
    let (mut x1, mut v1) = (0.0, 0.0);
    ax.step(&mut x1, &mut v1, u, 0.4);
    assert!((x1 - x).abs() < 1e-12 && (v1 - v).abs() < 1e-12);
}

#[test]
fn no_friction_is_a_double_integrator() {
    let ax = axis(0.0, 0.0, SignModel::Exact);
    let (mut x, mut v) = (1.0, 2.0);
    ax.step(&mut x, &mut v, 1.0, 0.5);
    let acc = 0.0318 / 4.96e-4;
    assert!((v - (2.0 + acc * 0.5)).abs() < 1e-12);
    assert!((x - (1.0 + 2.0 * 0.5 + acc * 0.125)).abs() < 1e-12);
}

#[test]
fn saturation_clips_the_command() {
    let ax = axis(1e-5, 0.0, SignModel::Exact);
    let run = |u| {
        let (mut x, mut v) = (0.0, 0.0);
        ax.step(&mut x, &mut v, u, 0.01);
        (x, v)
    };
    assert_eq!(run(100.0), run(10.0));
    assert_eq!(run(-1e9), run(-10.0));
}

/// Coasting against Coulomb friction (b = 0): v = v0 − (T_c/J)·t until it stops at
/// t* = v0·J/T_c, x* = v0²·J/(2·T_c); then it sticks (no command).
#[test]
fn coulomb_friction_stops_and_sticks() {
    let (j, tc, v0) = (4.96e-4, 0.00636, 1.0);
    let ax = axis(0.0, tc, SignModel::Exact);
    let (mut x, mut v) = (0.0, v0);
    ax.step(&mut x, &mut v, 0.0, 1.0);
    assert_eq!(v, 0.0);
    assert!((x - v0 * v0 * j / (2.0 * tc)).abs() < 1e-12, "{x}");
    // A command whose torque stays under T_c does not move it.
    let weak = 0.9 * tc / 0.0318;
    ax.step(&mut x, &mut v, weak, 1.0);
    assert_eq!(v, 0.0);
    assert!((x - v0 * v0 * j / (2.0 * tc)).abs() < 1e-12);
}

/// A strong reverse command: decelerate with (drive − T_c), cross zero at t1, then
/// accelerate the other way with (drive + T_c).
#[test]
fn coulomb_friction_reversal_is_piecewise_exact() {
    let (j, ka, tc) = (4.96e-4, 0.0318, 0.00636);
    let ax = axis(0.0, tc, SignModel::Exact);
    let u = -5.0;
    let drive = ka * u; // −0.159 N·m, far beyond T_c
    let (mut x, mut v) = (0.0, 2.0);
    ax.step(&mut x, &mut v, u, 0.1);
    let a1 = (drive - tc) / j;
    let t1 = -2.0 / a1;
    let x1 = 2.0 * t1 + 0.5 * a1 * t1 * t1;
    let a2 = (drive + tc) / j;
    let t2 = 0.1 - t1;
    assert!((v - a2 * t2).abs() < 1e-9, "{v}");
    assert!((x - (x1 + 0.5 * a2 * t2 * t2)).abs() < 1e-9, "{x}");
}

/// With v_s small against the motion, the smooth model follows the exact one.
#[test]
fn smooth_sign_approaches_exact_sign() {
    let exact = axis(1e-5, 0.00636, SignModel::Exact);
    let smooth = axis(1e-5, 0.00636, SignModel::Smooth { v_s: 1e-3 });
    let (mut xe, mut ve, mut xs, mut vs) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..200 {
        let u = 3.0 * (k as f64 * 0.05).sin();
        exact.step(&mut xe, &mut ve, u, 1e-3);
        smooth.step(&mut xs, &mut vs, u, 1e-3);
    }
    assert!((xe - xs).abs() < 2e-3 * xe.abs().max(1.0), "{xe} vs {xs}");
    assert!((ve - vs).abs() < 1e-2 * ve.abs().max(1.0), "{ve} vs {vs}");
}

/// RK4 on the smooth model converges at 4th order to a fine reference.
#[test]
fn smooth_model_rk4_accuracy() {
    let run = |max_step: f64| {
        let mut a = axis(1e-5, 0.00636, SignModel::Smooth { v_s: 1e-2 });
        a.max_step = max_step;
        let (mut x, mut v) = (0.0, 0.0);
        a.step(&mut x, &mut v, 1.0, 0.02);
        x
    };
    let reference = run(1e-7);
    let (e1, e2) = ((run(2e-4) - reference).abs(), (run(1e-4) - reference).abs());
    // Measured: x = 0.01029 rad, error 6.6e-8 at 200 µs, 4.0e-9 at 100 µs (ratio 16.5).
    assert!(e1 < 1e-5 * reference.abs(), "{e1}");
    let ratio = e1 / e2;
    assert!(
        (12.0..20.0).contains(&ratio),
        "{e1} / {e2} = {ratio}: not 4th order"
    );
}

#[test]
fn velocity_axis_settles_at_gain_times_command() {
    let ax = VelocityAxis::new(2.0, 0.005, 10.0).expect("axis");
    let (mut x, mut v) = (0.0, 0.0);
    ax.step(&mut x, &mut v, 1.5, 0.1);
    assert!((v - 3.0).abs() < 1e-6);
    // After one time constant: 1 − e^{−1} of the way.
    let (mut x, mut v) = (0.0, 0.0);
    ax.step(&mut x, &mut v, 1.0, 0.005);
    assert!((v - 2.0 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
}

/// The discretisation with delay equals stepping the axis: previous command for τ, the new
/// one for T − τ.
#[test]
fn discretisation_with_delay_matches_stepping() {
    let ax = axis(2e-5, 0.0, SignModel::Exact);
    let (a, g) = ax.linear().expect("linear");
    let (t, tau) = (1e-3, 175e-6);
    let d = Discretised::new(a, g, t, tau).expect("discretise");
    let (x0, v0, u_prev, u) = (0.3, -1.2, 2.0, -4.0);
    let (mut x, mut v) = (x0, v0);
    ax.step(&mut x, &mut v, u_prev, tau);
    ax.step(&mut x, &mut v, u, t - tau);
    let xd = d.phi[0][0] * x0 + d.phi[0][1] * v0 + d.gamma1[0] * u_prev + d.gamma0[0] * u;
    let vd = d.phi[1][0] * x0 + d.phi[1][1] * v0 + d.gamma1[1] * u_prev + d.gamma0[1] * u;
    assert!(
        (x - xd).abs() < 1e-13 && (v - vd).abs() < 1e-12,
        "{x} {xd} {v} {vd}"
    );
    assert!(Discretised::new(a, g, t, 2e-3).is_none());
}

#[test]
fn bad_parameters_are_named() {
    let name = |r: Result<TorqueAxis, PlantError>| match r {
        Err(PlantError::InvalidParameter { name, .. }) => name,
        other => panic!("{other:?}"),
    };
    let f = Friction::viscous(0.0);
    assert_eq!(name(TorqueAxis::new(-1.0, 0.03, f, 10.0)), "inertia");
    assert_eq!(name(TorqueAxis::new(f64::NAN, 0.03, f, 10.0)), "inertia");
    assert_eq!(name(TorqueAxis::new(1e-4, 0.0, f, 10.0)), "torque_constant");
    assert_eq!(
        name(TorqueAxis::new(1e-4, 0.03, Friction::viscous(-1.0), 10.0)),
        "viscous_friction"
    );
    let smooth = Friction {
        viscous: 0.0,
        coulomb: 0.01,
        sign: SignModel::Smooth { v_s: 0.0 },
    };
    assert_eq!(
        name(TorqueAxis::new(1e-4, 0.03, smooth, 10.0)),
        "coulomb_velocity_scale"
    );
    assert_eq!(name(TorqueAxis::new(1e-4, 0.03, f, f64::INFINITY)), "u_max");
    let mut p = IndependentAxes::new(vec![AxisModel::Torque(
        TorqueAxis::new(1e-4, 0.03, f, 10.0).expect("ok"),
    )]);
    assert!(matches!(
        p.advance(&[1.0, 2.0], 1e-3),
        Err(PlantError::LengthMismatch { .. })
    ));
}

/// The window's mean velocity is what two positions w apart give, stepping the axis
/// forward over the window with the command held: for a damped axis, an undamped one (the
/// series branch) and several windows.
#[test]
fn window_velocity_is_the_difference_of_two_positions() {
    for (a, g) in [(2.5, 64.0), (0.0, 60.0), (1e-6, 40.0), (80.0, 10.0)] {
        let ax = TorqueAxis::new(1.0 / g, 1.0, Friction::viscous(a / g), 1e9).expect("axis");
        for w in [1e-6, 125e-6, 900e-6] {
            let [cv, cu] = Discretised::window_velocity(a, g, w).expect("window");
            let (v0, u) = (1.7, -3.2);
            let (mut x, mut v) = (0.4, v0);
            ax.step(&mut x, &mut v, u, w);
            let mean = (x - 0.4) / w;
            let got = cv * v + cu * u;
            assert!(
                (got - mean).abs() < 1e-9 * (1.0 + mean.abs()),
                "a {a} w {w}: {got} vs {mean}"
            );
        }
    }
    assert!(Discretised::window_velocity(1.0, 1.0, 0.0).is_none());
}
