//! The coupled two-link arm on the simulated ring: the built-in `arm-2link`
//! (`scenarios/arm-2link.toml`), two slaves driving the arm's two joints.

use ringsync_control::Trajectory;
use ringsync_plant::{AxisModel, Friction, Plant, TorqueAxis, TwoLinkArm};

use super::tests::run_traced;
use super::*;

/// The built-in arm scenario with the law named `law` (the file's own is "sync").
fn arm_scenario(law: &str, seed: u64) -> Scenario {
    let text = ringsync_model::builtin("arm-2link").expect("built in");
    let with_law = text.replace("law = \"sync\"", &format!("law = \"{law}\""));
    assert!(
        law == "sync" || with_law != text,
        "the law is set in the file"
    );
    let mut s = Scenario::from_toml(&with_law, "arm-2link").expect("valid");
    s.seed = seed;
    s
}

/// The bound on PD's tracking error, from the arm's own inverse dynamics. With
/// u_i = K_P,i·e_i + K_D,i·ė_i and e = x^d − q, the arm's equation gives the error dynamics
///
///   M(q)·ë + (F + K_a·K_D)·ė + K_a·K_P·e = M(q)·ẍ^d + C(q, q̇)·q̇ + F·ẋ^d ≈ τ_ff(t),
///
/// τ_ff the torque that moves the arm exactly along x^d (inverse dynamics at q = x^d; the
/// difference is second order in e). Frozen at any M in the arm's range, with stiffness
/// S = K_a·K_P and damping D = F + K_a·K_D diagonal: for a unit vector v,
/// |vᴴ(S − ω²M + jωD)v|² = (s − ω²m)² + ω²d² ≥ s² at every ω when d² ≥ 2·m·s, so the
/// loop's gain from τ_ff to e is at most 1/min_i S_i at every frequency. Its L2 gain is
/// bounded alike, so over the run (zero initial error)
///
///   Track-RMSE ≤ RMS‖τ_ff‖ / min_i S_i,  given min_i D_i² ≥ 2·λ_max(M)·max_i S_i.
///
/// Not modelled: the variation of M along the motion (slow: q2 changes at ≤ 3 rad/s against
/// the loop's poles at 4 to 300 rad/s), the 1 ms sampling and the sample-to-actuation delay
/// of about 0.12 ms (0.6 ms of lag in all, 0.2 rad of phase at the fastest pole). Returns
/// (bound [rad], the damping condition's two sides).
fn pd_tracking_bound(s: &Scenario) -> (f64, (f64, f64)) {
    let p = s.arm_params().expect("the arm");
    let arm = TwoLinkArm::new(p).expect("arm");
    let g = s.gains();
    let f = [p.f1, p.f2];
    let stiff: Vec<f64> = (0..2).map(|i| p.torque_constant[i] * g.kp[i]).collect();
    let damp: Vec<f64> = (0..2)
        .map(|i| p.torque_constant[i] * g.kd[i] + f[i])
        .collect();
    let (s_min, s_max) = (stiff[0].min(stiff[1]), stiff[0].max(stiff[1]));
    let d_min = damp[0].min(damp[1]);
    let traj = s.trajectories().expect("trajectories");
    let t_cyc = s.ring.cycle.secs();
    let cycles = (s.duration.secs() / t_cyc).round() as usize;
    let sum: f64 = (0..cycles)
        .map(|k| {
            let t = k as f64 * t_cyc;
            let (d1, d2) = (traj[0].at(t), traj[1].at(t));
            let tau = arm.inverse_dynamics([d1.x, d2.x], [d1.v, d2.v], [d1.a, d2.a]);
            tau[0] * tau[0] + tau[1] * tau[1]
        })
        .sum();
    let bound = (sum / cycles as f64).sqrt() / s_min;
    (bound, (d_min * d_min, 2.0 * p.max_inertia() * s_max))
}

/// Standard PD on the arm: no group stop, and Track-RMSE under the bound derived from the
/// arm's inverse dynamics ([`pd_tracking_bound`]). The sync controller of the file runs the
/// arm too, and keeps the joints closer together than PD (lower Sync-RMSE).
#[test]
fn the_arm_tracks_within_its_derived_bound() {
    let s = arm_scenario("pd", 1);
    let (bound, (d2, two_ms)) = pd_tracking_bound(&s);
    assert!(
        d2 >= two_ms,
        "the bound needs D² ≥ 2·λ_max(M)·S: {d2} < {two_ms}"
    );
    let pd = run_traced(&s);
    assert!(
        pd.group_stop.is_none() && pd.watchdog.is_empty(),
        "{:?}",
        pd.faults
    );
    assert_eq!(pd.cycles, 4000);
    let track = pd.summary.track_rmse;
    assert!(
        track < bound,
        "PD Track-RMSE {track} rad over the bound {bound} rad"
    );
    let sync = run_traced(&arm_scenario("sync", 1));
    assert!(
        sync.group_stop.is_none() && sync.watchdog.is_empty(),
        "{:?}",
        sync.faults
    );
    assert!(
        sync.summary.sync_rmse < pd.summary.sync_rmse,
        "sync {} vs PD {}",
        sync.summary.sync_rmse,
        pd.summary.sync_rmse
    );
    eprintln!(
        "arm-2link seed 1: PD Track-RMSE {track:.6} rad (bound {bound:.6}), Sync-RMSE {:.6}; sync Track-RMSE {:.6}, Sync-RMSE {:.6}",
        pd.summary.sync_rmse, sync.summary.track_rmse, sync.summary.sync_rmse
    );
}

/// What the simulator moved is the coupled arm: replaying the commands each drive applied
/// (the trace's u as the wire carries it, f32, from its apply time) on the plant crate's
/// `TwoLinkArm` gives the trace's positions at every cycle start, to within RK4's
/// step-partition differences (the simulator splits the intervals at every event; about
/// 10⁻¹³ rad here, so 10⁻⁹ rad leaves room and still catches commands applied 1 µs off,
/// which shift the motion by 1 µs: up to 3·10⁻⁶ rad at 3 rad/s). The same commands
/// on independent axes with the arm's diagonal inertia at q2 = 0 (J1 = p1 + 2·p3,
/// J2 = p2), drives and friction give another motion: in the arm, joint 1's acceleration
/// pushes joint 2 through M21 = p2 + p3·cos q2 (up to 0.05 kg·m² against its own 0.02) and
/// back, which the independent axes lack.
#[test]
fn the_simulated_arm_is_the_coupled_plant() {
    let s = arm_scenario("sync", 3);
    let r = run_traced(&s);
    assert!(r.group_stop.is_none());
    let p = s.arm_params().expect("the arm");
    // Command changes (true ns, joint, volts applied), in time order.
    let mut changes: Vec<(i64, usize, f64)> = r
        .trace
        .rows()
        .filter(|row| row.apply_time.is_finite())
        .map(|row| {
            let at = (row.apply_time * 1e9).round() as i64;
            (at, row.axis - 1, f64::from(row.u as f32))
        })
        .collect();
    changes.sort_by_key(|c| c.0);
    assert_eq!(changes.len(), 2 * 4000, "every command applied");
    let mut arm = TwoLinkArm::new(p).expect("arm");
    let indep: Vec<AxisModel> = [(p.p1 + 2.0 * p.p3, p.f1), (p.p2, p.f2)]
        .iter()
        .enumerate()
        .map(|(i, &(j, f))| {
            let a = TorqueAxis::new(j, p.torque_constant[i], Friction::viscous(f), p.u_max[i]);
            AxisModel::Torque(a.expect("axis"))
        })
        .collect();
    let (mut x, mut v) = ([0.0; 2], [0.0; 2]);
    let (mut u, mut t) = ([0.0; 2], 0i64);
    let (mut arm_err, mut indep_diff) = (0.0f64, [0.0f64; 2]);
    let mut next = changes.iter().peekable();
    let mut step = |to: i64, u: [f64; 2], t: &mut i64, arm: &mut TwoLinkArm, x: &mut [f64; 2]| {
        let dt = (to - *t) as f64 * 1e-9;
        if dt > 0.0 {
            arm.advance_held(u, dt);
            for i in 0..2 {
                indep[i].step(&mut x[i], &mut v[i], u[i], dt);
            }
            *t = to;
        }
    };
    for (row_group, chunk) in r.trace.x.chunks(2).enumerate() {
        let t_k = (r.trace.t[row_group] * 1e9).round() as i64;
        while let Some(&&(at, joint, volts)) = next.peek() {
            if at > t_k {
                break;
            }
            step(at, u, &mut t, &mut arm, &mut x);
            u[joint] = volts;
            next.next();
        }
        step(t_k, u, &mut t, &mut arm, &mut x);
        for i in 0..2 {
            arm_err = arm_err.max((arm.position(i) - chunk[i]).abs());
            indep_diff[i] = indep_diff[i].max((x[i] - chunk[i]).abs());
        }
    }
    assert!(arm_err < 1e-9, "replay on the arm off by {arm_err} rad");
    for (i, d) in indep_diff.iter().enumerate() {
        assert!(
            *d > 1e-2,
            "joint {}: independent axes within {d} rad of the arm",
            i + 1
        );
    }
    eprintln!(
        "arm-2link seed 3: replay on the arm within {arm_err:.3e} rad; independent axes off by up to {:.3} and {:.3} rad",
        indep_diff[0], indep_diff[1]
    );
}

/// Same seed, same trace and summary; another seed draws other clocks.
#[test]
fn the_arm_run_is_deterministic() {
    let s = arm_scenario("sync", 7);
    let (a, b) = (run_traced(&s), run_traced(&s));
    assert_eq!(a.trace, b.trace);
    assert_eq!(a.summary, b.summary);
    assert_eq!(a.master, b.master);
    let c = run_traced(&arm_scenario("sync", 8));
    assert_ne!(a.trace, c.trace, "another seed draws other clocks");
}
