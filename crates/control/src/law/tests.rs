use nalgebra::DMatrix;
use proptest::prelude::*;

use super::*;
use crate::coupling::Coupling;
use crate::estimator::{DEPTH, EstimatorKind, Signal};

/// A random cycle: history, inputs and gains for n axes.
#[derive(Debug, Clone)]
struct Case {
    hist: ErrorHistory,
    input: ControlInput,
    gains: Gains,
    params: SyncParams,
}

fn case() -> impl Strategy<Value = Case> {
    (2usize..10).prop_flat_map(|n| {
        (
            prop::collection::vec(
                (
                    prop::array::uniform4(-1.0f64..1.0),
                    prop::array::uniform4(-5.0f64..5.0),
                    1usize..=DEPTH,
                    -0.003f64..0.0,
                ),
                n,
            ),
            prop::collection::vec(
                (
                    0.0f64..0.002,
                    -2.0f64..2.0,
                    -20.0f64..20.0,
                    -100.0f64..100.0,
                ),
                n,
            ),
            prop::collection::vec(
                (
                    0.1f64..10.0,
                    0.1f64..5.0,
                    0.0f64..2.0,
                    -0.1f64..0.1,
                    -0.5f64..0.5,
                ),
                n,
            ),
            (
                0.0f64..3.0,
                0.0f64..0.01,
                0.0f64..0.1,
                prop_oneof![
                    Just(EstimatorKind::Hold),
                    Just(EstimatorKind::Linear),
                    Just(EstimatorKind::Paper)
                ],
                any::<bool>(),
                prop_oneof![
                    Just(Sign::Exact),
                    (0.01f64..1.0).prop_map(Sign::BoundaryLayer)
                ],
                100.0f64..5000.0,
            ),
        )
            .prop_map(
                move |(h, inp, g, (alpha, dh, dc, estimator, own, sign, t0))| {
                    let mut hist = ErrorHistory::new(n);
                    let mut input = ControlInput::new(n, 1e-3);
                    let mut gains = Gains::uniform(n, 1.0, 1.0, 0.0);
                    for i in 0..n {
                        hist.e[i] = h[i].0;
                        hist.de[i] = h[i].1;
                        hist.count[i] = h[i].2;
                        hist.t[i] = t0 + h[i].3;
                        input.apply_time[i] = t0 + inp[i].0;
                        input.desired[i] = State {
                            x: inp[i].1,
                            v: inp[i].2,
                            a: inp[i].3,
                        };
                        gains.kp[i] = g[i].0;
                        gains.kd[i] = g[i].1;
                        gains.ke[i] = g[i].2;
                        gains.kh[i] = g[i].3;
                        gains.kc[i] = g[i].4;
                        gains.u_max[i] = 1e6;
                    }
                    let params = SyncParams {
                        alpha,
                        delta_h: dh,
                        delta_c: dc,
                        sign,
                        estimator,
                        extrapolate_own: own,
                    };
                    Case {
                        hist,
                        input,
                        gains,
                        params,
                    }
                },
            )
    })
}

/// Eq. 14 term by term, O(n²), with (I + αT)⁻¹ from an explicit matrix inverse.
fn naive_sync(c: &Case) -> Vec<f64> {
    let (h, inp, g, p) = (&c.hist, &c.input, &c.gains, &c.params);
    let n = h.axes();
    let t = inp.t_cyc;
    let est = p.estimator;
    let kk = 1.0 / (n - 1) as f64;
    let m = DMatrix::from_fn(
        n,
        n,
        |i, j| if i == j { 1.0 + p.alpha } else { -p.alpha * kk },
    );
    let inv = m.try_inverse().expect("I + αT is invertible");
    let w = DMatrix::from_fn(n, 1, |i, _| g.ke[i] * h.de[i][0]);
    let inv_term = inv * w;
    let na = inp.desired.iter().map(|d| d.a * d.a).sum::<f64>().sqrt();
    let nv = inp.desired.iter().map(|d| d.v * d.v).sum::<f64>().sqrt();
    let kn = p.delta_h * na + p.delta_c * nv;
    (0..n)
        .map(|k| {
            let mut others_e = 0.0;
            let mut others_de = 0.0;
            for j in (0..n).filter(|&j| j != k) {
                let d = (inp.apply_time[k] - h.t[j]) / t;
                others_e += est.estimate(&h.e[j], h.count[j], d);
                others_de += est.estimate(&h.de[j], h.count[j], d);
            }
            let d_own = (inp.apply_time[k] - h.t[k]) / t;
            let (own_e, own_de) = if p.extrapolate_own {
                (
                    est.estimate(&h.e[k], h.count[k], d_own),
                    est.estimate(&h.de[k], h.count[k], d_own),
                )
            } else {
                (h.e[k][0], h.de[k][0])
            };
            let big_e = (1.0 + p.alpha) * own_e - p.alpha * kk * others_e;
            let big_de = (1.0 + p.alpha) * own_de - p.alpha * kk * others_de;
            let sgn = match p.sign {
                _ if kn == 0.0 => 0.0,
                Sign::Exact => {
                    if big_de > 0.0 {
                        1.0
                    } else if big_de < 0.0 {
                        -1.0
                    } else {
                        0.0
                    }
                }
                Sign::BoundaryLayer(phi) => (big_de / phi).clamp(-1.0, 1.0),
            };
            let d = &inp.desired[k];
            g.kh[k] * d.a
                + g.kc[k] * d.v
                + g.kp[k] * big_e
                + g.kd[k] * big_de
                + inv_term[(k, 0)]
                + kn * sgn
        })
        .collect()
}

proptest! {
    /// The O(n) implementation equals eq. 14 written out term by term.
    #[test]
    fn sync_controller_matches_naive_eq14(c in case()) {
        let law = SyncController::new(c.gains.clone(), c.params).expect("law");
        let mut out = ControlOutput::new(c.hist.axes());
        law.compute(&c.hist, &c.input, &mut out).expect("compute");
        let want = naive_sync(&c);
        for (got, want) in out.u_raw.iter().zip(&want) {
            prop_assert!((got - want).abs() <= 1e-9 * (1.0 + want.abs()), "{got} vs {want}");
        }
    }
}

/// With the Hold estimator the sync law is eq. 9: K_P·E + K_D·Ė + (I + αT)⁻¹·K_E·ė with
/// E = (I + αT)·e.
#[test]
fn hold_estimator_gives_eq9() {
    let n = 4;
    let mut hist = ErrorHistory::new(n);
    let e = [0.1, -0.2, 0.05, 0.3];
    let de = [1.0, 0.5, -0.7, 0.0];
    for i in 0..n {
        hist.push(i, e[i], de[i], 1.0).expect("push");
    }
    let mut input = ControlInput::new(n, 1e-3);
    input.apply_time = vec![1.00013, 1.000145, 1.00016, 1.000175];
    let gains = Gains::uniform(n, 3.182, 1.591, 0.75);
    let params = SyncParams {
        estimator: EstimatorKind::Hold,
        ..SyncParams::reference()
    };
    let law = SyncController::new(gains, params).expect("law");
    let mut out = ControlOutput::new(n);
    law.compute(&hist, &input, &mut out).expect("compute");
    let c = Coupling::new(n, 0.5).expect("coupling");
    let (mut big_e, mut big_de, mut inv) = ([0.0; 4], [0.0; 4], [0.0; 4]);
    c.coupled(&e, &mut big_e).expect("E");
    c.coupled(&de, &mut big_de).expect("Ė");
    c.inverse(&de.map(|x| 0.75 * x), &mut inv).expect("inverse");
    for k in 0..n {
        let want = 3.182 * big_e[k] + 1.591 * big_de[k] + inv[k];
        assert!((out.u[k] - want).abs() < 1e-12, "{} vs {want}", out.u[k]);
    }
}

/// With α = 0 and K_E = 0 the sync law is standard PD.
#[test]
fn sync_without_coupling_is_pd() {
    let n = 3;
    let mut hist = ErrorHistory::new(n);
    for i in 0..n {
        hist.push(i, 0.1 * i as f64, -0.3, 0.0).expect("push");
    }
    let input = ControlInput::new(n, 1e-3);
    let gains = Gains::uniform(n, 2.0, 0.5, 0.0);
    let sync = SyncController::new(
        gains.clone(),
        SyncParams {
            alpha: 0.0,
            ..SyncParams::reference()
        },
    )
    .expect("sync");
    let pd = Pd::new(gains, false).expect("pd");
    let (mut a, mut b) = (ControlOutput::new(n), ControlOutput::new(n));
    sync.compute(&hist, &input, &mut a).expect("sync");
    pd.compute(&hist, &input, &mut b).expect("pd");
    assert_eq!(a.u, b.u);
    assert!((b.u[2] - (2.0 * 0.2 + 0.5 * -0.3)).abs() < 1e-15);
}

#[test]
fn pd_feed_forward_and_saturation() {
    let mut hist = ErrorHistory::new(2);
    hist.push(0, 1.0, 0.0, 0.0).expect("push");
    hist.push(1, 10.0, 0.0, 0.0).expect("push");
    let mut input = ControlInput::new(2, 1e-3);
    input.desired[0] = State {
        x: 0.0,
        v: 2.0,
        a: 4.0,
    };
    let mut gains = Gains::uniform(2, 3.0, 1.0, 0.0);
    gains.kh = vec![0.5; 2];
    gains.kc = vec![0.25; 2];
    let mut out = ControlOutput::new(2);
    Pd::new(gains.clone(), true)
        .expect("pd")
        .compute(&hist, &input, &mut out)
        .expect("compute");
    assert!((out.u[0] - (3.0 + 0.5 * 4.0 + 0.25 * 2.0)).abs() < 1e-15);
    assert_eq!(
        (out.u[1], out.u_raw[1], out.saturated[1]),
        (10.0, 30.0, true)
    );
    Pd::new(gains, false)
        .expect("pd")
        .compute(&hist, &input, &mut out)
        .expect("compute");
    assert_eq!(out.u[0], 3.0);
}

#[test]
fn ring_law_with_hold_is_the_laplacian() {
    let n = 5;
    let mut hist = ErrorHistory::new(n);
    let e = [0.3, -0.1, 0.2, 0.0, 0.4];
    for (i, &ei) in e.iter().enumerate() {
        hist.push(i, ei, 0.0, 0.0).expect("push");
    }
    let law =
        RingCoupled::new(Gains::uniform(n, 2.0, 1.0, 0.0), 0.5, EstimatorKind::Hold).expect("ring");
    let mut out = ControlOutput::new(n);
    law.compute(&hist, &ControlInput::new(n, 1e-3), &mut out)
        .expect("compute");
    let mut big = [0.0; 5];
    crate::coupling::ring_coupled(&e, 0.5, &mut big).expect("ring");
    for (u, b) in out.u.iter().zip(big) {
        assert!((u - 2.0 * b).abs() < 1e-15);
    }
}

#[test]
fn controller_builds_errors_from_feedback() {
    let n = 2;
    let law = Pd::new(Gains::uniform(n, 1.0, 1.0, 0.0), false).expect("pd");
    let mut c = Controller::new(law, VelocitySource::Differenced);
    let mut fb = Feedback::new(n);
    let input = ControlInput::new(n, 1e-3);
    let mut out = ControlOutput::new(n);
    // Axis 0 lags a ramp x^d = 2t by 0.01 + 0.5·t: e grows at 0.5 rad/s.
    for m in 0..5 {
        let t = m as f64 * 1e-3;
        fb.sample_time = vec![t; n];
        fb.desired[0] = State {
            x: 2.0 * t,
            v: 2.0,
            a: 0.0,
        };
        fb.position[0] = 2.0 * t - 0.01 - 0.5 * t;
        c.update(&fb, &input, &mut out).expect("update");
    }
    assert!((c.history.e[0][0] - (0.01 + 0.5 * 4e-3)).abs() < 1e-15);
    assert!((c.history.de[0][0] - 0.5).abs() < 1e-9);
    // A stale sample is not pushed again.
    fb.fresh[0] = false;
    c.update(&fb, &input, &mut out).expect("update");
    assert_eq!(c.history.count[0], 4);
    assert!((c.history.e[0][1] - (0.01 + 0.5 * 3e-3)).abs() < 1e-15);
    // The same sample delivered again as fresh (same sampling instant) is not taken
    // either: the history and the commands stay as they were.
    fb.fresh[0] = true;
    let (before, u) = (c.history.clone(), out.u.clone());
    c.update(&fb, &input, &mut out).expect("update");
    assert_eq!(c.history, before);
    assert_eq!(out.u, u);
    // Nor is an older one.
    fb.sample_time[0] -= 1e-3;
    c.update(&fb, &input, &mut out).expect("update");
    assert_eq!(c.history, before);
}

/// A missed sample leaves no gap in the history: the missing cycle is interpolated, so the
/// estimators keep seeing one sample per cycle.
#[test]
fn missed_samples_are_interpolated() {
    let law = Pd::new(Gains::uniform(1, 1.0, 1.0, 0.0), false).expect("pd");
    let mut c = Controller::new(law, VelocitySource::Reported);
    let mut fb = Feedback::new(1);
    let input = ControlInput::new(1, 1e-3);
    let mut out = ControlOutput::new(1);
    // e = 0.5·m (x^d = 0, x = −0.5·m) sampled at m·1 ms, with cycle 3 missing.
    for m in [0usize, 1, 2, 4] {
        fb.sample_time[0] = m as f64 * 1e-3;
        fb.position[0] = -0.5 * m as f64;
        c.update(&fb, &input, &mut out).expect("update");
    }
    assert_eq!(c.history.e[0], [2.0, 1.5, 1.0, 0.5]);
    assert!((c.history.t[0] - 4e-3).abs() < 1e-15);
    // A gap longer than the history starts it afresh.
    fb.sample_time[0] = 10e-3;
    c.update(&fb, &input, &mut out).expect("update");
    assert_eq!(c.history.count[0], 1);
}

/// With differenced velocity the ė a law runs on adds up, cycle by cycle, to the change of
/// the error, across missed cycles and a sample delivered twice as well: a gap leaves no
/// velocity noise behind in the D term.
#[test]
fn differenced_velocity_adds_up_across_gaps() {
    let t_cyc = 1e-3;
    let law = Pd::new(Gains::uniform(1, 1.0, 1.0, 0.0), false).expect("pd");
    let mut c = Controller::new(law, VelocitySource::Differenced);
    let mut fb = Feedback::new(1);
    let input = ControlInput::new(1, t_cyc);
    let mut out = ControlOutput::new(1);
    // e = 0.5 rad/s · t plus quantisation-like noise of up to ±3 µrad; cycles 5, 9-10
    // and 20 bring no new sample, cycle 14 brings cycle 13's again, and from cycle 21 on
    // every cycle brings the one before's (the samples lag the law by a cycle).
    let e_at = |m: usize| 0.5 * m as f64 * t_cyc + 3e-6 * ((m * 7919 % 13) as f64 / 6.0 - 1.0);
    let (mut sum, mut first, mut last) = (0.0, None, 0.0);
    for m in 0..30usize {
        let taken = match m {
            5 | 9 | 10 | 20 => None,
            14 => Some(13),
            21.. => Some(m - 1),
            _ => Some(m),
        };
        match taken {
            Some(k) => {
                fb.fresh[0] = true;
                fb.sample_time[0] = k as f64 * t_cyc;
                fb.position[0] = -e_at(k);
                first.get_or_insert(e_at(k));
                last = e_at(k);
            }
            None => fb.fresh[0] = false,
        }
        c.update(&fb, &input, &mut out).expect("update");
        // The ė the law ran on this cycle, held for one cycle.
        if m > 0 {
            sum += c.history.de[0][0] * t_cyc;
        }
        // PD with K_P = K_D = 1 and no feed-forward: the command is e + ė of that sample.
        let (e, de) = (c.history.e[0][0], c.history.de[0][0]);
        assert!((out.u[0] - (e + de)).abs() < 1e-12, "cycle {m}");
    }
    let change = last - first.expect("a sample");
    assert!(
        (sum - change).abs() < 1e-15,
        "Σ ė·T = {sum:e}, e changed by {change:e}"
    );
}

#[test]
fn bad_configurations_are_named() {
    let name = |e: ControlError| match e {
        ControlError::InvalidParameter { name, .. } => name,
        other => panic!("{other:?}"),
    };
    assert!(matches!(
        SyncController::new(Gains::uniform(1, 1.0, 1.0, 1.0), SyncParams::reference()),
        Err(ControlError::TooFewAxes { n: 1, min: 2, .. })
    ));
    assert!(matches!(
        RingCoupled::new(Gains::uniform(1, 1.0, 1.0, 1.0), 0.5, EstimatorKind::Hold),
        Err(ControlError::TooFewAxes { .. })
    ));
    let mut g = Gains::uniform(3, 1.0, 1.0, 1.0);
    g.kp[2] = f64::NAN;
    assert_eq!(name(Pd::new(g, false).expect_err("nan")), "kp[2]");
    let mut g = Gains::uniform(3, 1.0, 1.0, 1.0);
    g.kd[1] = -1.0;
    assert_eq!(name(Pd::new(g, false).expect_err("neg")), "kd[1]");
    let bad = SyncParams {
        sign: Sign::BoundaryLayer(0.0),
        ..SyncParams::reference()
    };
    assert_eq!(
        name(SyncController::new(Gains::uniform(3, 1.0, 1.0, 1.0), bad).expect_err("phi")),
        "boundary_layer"
    );
    let bad = SyncParams {
        alpha: -1.0,
        ..SyncParams::reference()
    };
    assert_eq!(
        name(SyncController::new(Gains::uniform(3, 1.0, 1.0, 1.0), bad).expect_err("alpha")),
        "alpha"
    );
    let mut g = Gains::uniform(3, 1.0, 1.0, 1.0);
    g.ke.pop();
    assert!(matches!(
        Pd::new(g, false),
        Err(ControlError::LengthMismatch { what: "ke", .. })
    ));
    // Mismatched input at compute time is an error, not a panic.
    let law = Pd::new(Gains::uniform(3, 1.0, 1.0, 1.0), false).expect("pd");
    let r = law.compute(
        &ErrorHistory::new(3),
        &ControlInput::new(2, 1e-3),
        &mut ControlOutput::new(3),
    );
    assert!(matches!(r, Err(ControlError::LengthMismatch { .. })));
}

/// The estimator slot holds state: the controller tells a law's estimator of every sample
/// it pushes (interpolated ones too), and the law's command uses the estimator's slope.
#[test]
fn a_stateful_estimator_is_told_of_every_sample() {
    use crate::estimator::Smoothing;
    let n = 3;
    let law = RingCoupled::with_estimator(
        Gains::uniform(n, 2.0, 1.0, 0.0),
        0.5,
        Box::new(Smoothing::new(n, 0.5)),
    )
    .expect("ring");
    let mut c = Controller::new(law, VelocitySource::Reported);
    let mut fb = Feedback::new(n);
    let mut input = ControlInput::new(n, 1e-3);
    let mut out = ControlOutput::new(n);
    // Axis 0: e = 0.1·m (x^d = 0, x = −0.1·m) sampled at m·1 ms with cycle 2 missing
    // (on every axis); axes 1 and 2 stay at e = 0.
    for m in [0usize, 1, 3] {
        let t = m as f64 * 1e-3;
        fb.sample_time = vec![t; n];
        fb.position[0] = -0.1 * m as f64;
        input.apply_time = vec![t + 0.5e-3; n];
        c.update(&fb, &input, &mut out).expect("update");
    }
    let est = c.law.estimator().expect("owned");
    assert_eq!(est.name(), "smoothing");
    // Three samples each, and one interpolated (cycle 2).
    let h = &c.history;
    assert_eq!(h.count, vec![4, 4, 4]);
    // Axis 0's smoothed slope, β = 0.5 on differences of 0.1: 0 after the first sample,
    // then 0.05, 0.075 (the interpolated sample) and 0.0875: four observations.
    let v = est.slope(h, 0, Signal::Position);
    assert!((v - 0.0875).abs() < 1e-15, "{v}");
    // Axis 1's neighbours are 0 (slope 0.0875, 0.5 cycles ahead) and 2 (all zero):
    // u_1 = K_P·(e_1 + α·(2·e_1 − e'_0 − e'_2)) with e_1 = 0 and no velocity errors.
    let e0 = 0.3 + 0.5 * 0.0875;
    let want = 2.0 * (0.5 * -e0);
    assert!((out.u[1] - want).abs() < 1e-15, "{} vs {want}", out.u[1]);
}

proptest! {
    /// Adjacent cross-coupling with K_X = α·K_P and K_XD = α·K_D is the ring-coupled law
    /// E = (I + αL)·e (the same neighbours through the same estimator).
    #[test]
    fn adjacent_with_alpha_gains_is_ring_coupled(c in case()) {
        let (g, a) = (&c.gains, c.params.alpha);
        let kx = g.kp.iter().map(|k| a * k).collect();
        let kxd = g.kd.iter().map(|k| a * k).collect();
        let adj = adjacent::AdjacentCoupled::new(g.clone(), kx, kxd, c.params.estimator)
            .expect("adjacent");
        let ring = RingCoupled::new(g.clone(), a, c.params.estimator).expect("ring");
        let n = c.hist.axes();
        let (mut got, mut want) = (ControlOutput::new(n), ControlOutput::new(n));
        adj.compute(&c.hist, &c.input, &mut got).expect("compute");
        ring.compute(&c.hist, &c.input, &mut want).expect("compute");
        for (x, y) in got.u_raw.iter().zip(&want.u_raw) {
            prop_assert!((x - y).abs() <= 1e-9 * (1.0 + y.abs()), "{x} vs {y}");
        }
    }

    /// Without coupling gains it is standard PD with feed-forward, whatever the neighbours do.
    #[test]
    fn adjacent_without_coupling_is_pd(c in case()) {
        let n = c.hist.axes();
        let adj = adjacent::AdjacentCoupled::new(
            c.gains.clone(), vec![0.0; n], vec![0.0; n], c.params.estimator,
        ).expect("adjacent");
        let pd = Pd::new(c.gains.clone(), true).expect("pd");
        let (mut got, mut want) = (ControlOutput::new(n), ControlOutput::new(n));
        adj.compute(&c.hist, &c.input, &mut got).expect("compute");
        pd.compute(&c.hist, &c.input, &mut want).expect("compute");
        prop_assert_eq!(got.u_raw, want.u_raw);
    }
}

/// Adjacent cross-coupling term by term on three axes with the Hold estimator: axis k sees
/// K_P·e_k + K_D·ė_k + K_X,k·(2e_k − e_{k−1} − e_{k+1}) + K_XD,k·(2ė_k − ė_{k−1} − ė_{k+1}).
#[test]
fn adjacent_term_by_term() {
    let n = 3;
    let mut hist = ErrorHistory::new(n);
    let e = [0.1, -0.2, 0.4];
    let de = [1.0, 0.5, -0.5];
    for i in 0..n {
        hist.push(i, e[i], de[i], 1.0).expect("push");
    }
    let mut input = ControlInput::new(n, 1e-3);
    input.apply_time = vec![1.0001; n];
    let gains = Gains::uniform(n, 2.0, 1.0, 0.0);
    let (kx, kxd) = (vec![1.0, 0.0, 3.0], vec![0.5, 2.0, 0.0]);
    let law = adjacent::AdjacentCoupled::new(gains, kx, kxd, EstimatorKind::Hold).expect("law");
    let mut out = ControlOutput::new(n);
    law.compute(&hist, &input, &mut out).expect("compute");
    // Axis 0: 0.2 + 1.0 + 1·(0.2 + 0.2 − 0.4) + 0.5·(2 − 0.5 + 0.5) = 1.2 + 0 + 1.0
    // Axis 1: −0.4 + 0.5 + 0 + 2·(1 − 1 + 0.5) = 1.1
    // Axis 2: 0.8 − 0.5 + 3·(0.8 + 0.2 − 0.1) + 0 = 3.0
    let want = [2.2, 1.1, 3.0];
    for (got, want) in out.u_raw.iter().zip(want) {
        assert!((got - want).abs() < 1e-12, "{:?} vs {want:?}", out.u_raw);
    }
    assert_eq!(law.name(), "adjacent");
}

/// Every registered law builds from its defaults on the axes it needs, under its own name;
/// names are unique; the catalogue lists each law and each parameter.
#[test]
fn every_registered_law_builds_from_its_defaults() {
    let mut seen = std::collections::BTreeSet::new();
    let text = registry::catalogue();
    for e in LAWS {
        assert!(seen.insert(e.name), "{} twice", e.name);
        assert!(registry::find(e.name).is_some());
        assert!(text.contains(e.name), "{text}");
        let n = e.min_axes.max(2);
        let p = LawParams::new(
            Gains::uniform(n, 3.0, 1.5, 0.5),
            false,
            SyncParams::reference(),
        );
        let law = e
            .build(&p)
            .unwrap_or_else(|err| panic!("{}: {err}", e.name));
        assert_eq!(law.name(), e.name);
        assert_eq!(law.axes(), n);
        for s in e.params {
            assert!(s.allows(s.default), "{}.{} default", e.name, s.key);
            assert!(
                text.contains(&format!("{} = {}", s.key, s.default)),
                "{text}"
            );
        }
    }
    assert!(registry::find("pid").is_none());
    assert_eq!(
        registry::unknown_law("pid"),
        "unknown control law 'pid': expected one of pd, sync, ring-coupled, adjacent, ccc"
    );
}

/// A law's own parameters are checked by the registry: unknown keys, wrong lengths and
/// values out of range are errors that name the key (and the axis).
#[test]
fn law_parameters_are_checked_by_key() {
    let e = registry::find("adjacent").expect("registered");
    let base = LawParams::new(
        Gains::uniform(3, 3.0, 1.5, 0.0),
        false,
        SyncParams::reference(),
    );
    let with = |key: &'static str, v: Vec<f64>| {
        let mut p = base.clone();
        p.set(key, v);
        e.build(&p).map(|_| ()).map_err(|err| err.to_string())
    };
    assert_eq!(with("kx", vec![0.0, 2.0, 5.0]), Ok(()));
    let err = with("kx", vec![1.0, -1.0, 1.0]).expect_err("negative");
    assert!(
        err.contains("params.kx[1]") && err.contains(">= 0 V/rad"),
        "{err}"
    );
    let err = with("kxd", vec![1.0]).expect_err("length");
    assert!(err.contains("3") && err.contains("1"), "{err}");
    let err = with("gain", vec![1.0; 3]).expect_err("unknown");
    assert!(err.contains("'gain'") && err.contains("kx, kxd"), "{err}");
    let pd = registry::find("pd").expect("registered");
    let mut p = base.clone();
    p.set("kx", vec![1.0; 3]);
    let err = pd.build(&p).map(|_| ()).expect_err("pd has none");
    assert!(err.to_string().contains("none"), "{err}");
}

/// The error observer tracks a ramp of e with no steady error in ė, and takes the
/// quantisation out where differencing divides it by the cycle.
#[test]
fn the_error_observer_tracks_ramps_and_smooths_quantisation() {
    let t_cyc = 1e-3;
    let obs = crate::law::ErrorObserver {
        bandwidth_hz: 100.0,
    };
    let g = obs.gains(t_cyc);
    assert!(g.0 > 0.0 && g.0 < 1.0 && g.1 > 0.0 && g.1 < g.0, "{g:?}");
    let mut s = (0.0, 0.0);
    for k in 1..=400 {
        s = crate::law::ErrorObserver::step(s, 0.3 * k as f64 * t_cyc, t_cyc, g);
    }
    assert!(
        (s.1 - 0.3).abs() < 1e-9,
        "ė̂ = {} on a ramp of 0.3 rad/s",
        s.1
    );
    // A slow sine quantised to 6 µrad: the observer's rate error is far below the
    // differences'.
    let q = 6e-6;
    let e = |k: usize| ((k as f64 * t_cyc * 3.0).sin() * 1e-3 / q).floor() * q;
    let truth = |k: usize| 3.0e-3 * (k as f64 * t_cyc * 3.0).cos();
    let (mut s, mut err_obs, mut err_diff) = ((e(0), 3.0e-3), 0.0_f64, 0.0_f64);
    for k in 1..2000 {
        s = crate::law::ErrorObserver::step(s, e(k), t_cyc, g);
        if k > 200 {
            err_obs = err_obs.max((s.1 - truth(k)).abs());
            err_diff = err_diff.max(((e(k) - e(k - 1)) / t_cyc - truth(k)).abs());
        }
    }
    assert!(
        err_obs < 0.25 * err_diff,
        "observer {err_obs}, differences {err_diff}"
    );
    // Through a Controller: the first sample starts from the reported velocity.
    let law = Pd::new(Gains::uniform(1, 1.0, 1.0, 0.0), false).expect("pd");
    let mut c = Controller::new(law, VelocitySource::Observer(obs));
    let mut fb = Feedback::new(1);
    fb.velocity[0] = -0.25;
    let mut out = ControlOutput::new(1);
    c.update(&fb, &ControlInput::new(1, t_cyc), &mut out)
        .expect("update");
    assert_eq!(c.history.de[0][0], 0.25);
}
