use super::*;
use crate::check::{Check, check_setpoints};
use crate::corpus;
use crate::program::interpret;

fn machine(tol: f64) -> Machine {
    let l = Limits {
        v_max: 100.0,
        a_max: 1000.0,
        j_max: 20000.0,
    };
    Machine {
        axes: [Some(l), Some(l), Some(Limits { v_max: 50.0, ..l })],
        tolerance: tol,
    }
}

/// The shortest distance of a jerk-limited speed change with zero acceleration at both
/// ends, d = (v0 + v1)/2 · T.
fn change_distance(v0: f64, v1: f64, a: f64, j: f64) -> f64 {
    0.5 * (v0 + v1) * change_time(v0, v1, a, j)
}

/// `reach` inverts the distance of the shortest speed change, in both of its regimes.
#[test]
fn reach_inverts_the_shortest_change() {
    for &(v0, len, a, j) in &[
        (0.0, 0.001, 1000.0, 20000.0),
        (0.0, 10.0, 1000.0, 20000.0),
        (35.0, 0.2, 1000.0, 20000.0),
        (35.0, 50.0, 500.0, 1e5),
        (1e-3, 1e-6, 10.0, 1e6),
        (80.0, 1e-4, 1000.0, 20000.0),
    ] {
        let v1 = reach(v0, len, a, j);
        assert!(v1 >= v0);
        let d = change_distance(v0, v1, a, j);
        // v1 − v0 loses digits to rounding when the change is tiny beside v0.
        let tol = 1e-9 + 1e-15 * v1 / (v1 - v0);
        assert!(
            (d - len).abs() <= tol * len,
            "{v0} {len} {a} {j}: {v1} covers {d}"
        );
    }
}

/// A long single-axis move from rest to rest reaches V and A: its duration is the
/// closed form L/V + V/A + A/J, and it ends exactly where it was programmed.
#[test]
fn a_long_line_has_the_closed_form_duration() {
    let m = machine(0.01);
    let p = interpret("G1 X200 F6000\n", m.present()).expect("valid");
    let path = plan(&p, &m).expect("plans");
    let (v, a, j) = (100.0, 1000.0, 20000.0);
    let want = 200.0 / v + v / a + a / j;
    assert!(
        (path.duration() - want).abs() < 1e-9,
        "{} {want}",
        path.duration()
    );
    let end = path.at(path.duration());
    assert!((end.p - Vec3::new(200.0, 0.0, 0.0)).norm() < 1e-9);
    let mid = path.at(path.duration() / 2.0);
    assert!((mid.speed - 100.0).abs() < 1e-9 && mid.accel.abs() < 1e-9);
}

/// A circle is run at the speed its curvature allows: the centripetal acceleration v²/R
/// within half of a_max, v³/R² within a quarter of j_max.
#[test]
fn a_circle_runs_at_its_curvature_limit() {
    let m = machine(0.01);
    // R = 2 mm at 6000 mm/min: v²/R would be 5000 mm/s².
    let p = interpret("G1 X2 F6000\nG3 I-2\n", m.present()).expect("valid");
    let path = plan(&p, &m).expect("plans");
    let arc = path
        .blocks()
        .iter()
        .find(|b| {
            matches!(
                b.binding,
                Binding::Centripetal(_) | Binding::CurvatureJerk(_)
            )
        })
        .expect("a block bound by the curvature");
    let v = arc.v_max;
    assert!(v * v / 2.0 <= 0.5 * 1000.0 * (1.0 + 1e-12), "{v}");
    assert!(v.powi(3) / 4.0 <= 0.25 * 20000.0 * (1.0 + 1e-12), "{v}");
}

/// Before the start the path rests at its start, after the end at its end; the phases
/// are continuous in arc length and speed.
#[test]
fn phases_are_continuous() {
    let m = machine(0.05);
    let p = interpret(
        "G1 X10 Y3 F3000\nG2 X20 Y3 R6\nG4 P0.2\nG0 Z5\nG1 X0 Y0 Z0 F1200\n",
        m.present(),
    )
    .expect("valid");
    let path = plan(&p, &m).expect("plans");
    assert_eq!(path.at(-1.0).p, Vec3::ZERO);
    let ph = path.phases();
    for w in ph.windows(2) {
        let tau = w[1].t0 - w[0].t0;
        let p = &w[0];
        let s = p.s0 + tau * (p.v0 + tau * (0.5 * p.a0 + tau * p.j / 6.0));
        let v = p.v0 + tau * (p.a0 + 0.5 * tau * p.j);
        assert!((s - w[1].s0).abs() < 1e-7, "{s} {}", w[1].s0);
        assert!((v - w[1].v0).abs() < 1e-6, "{v} {}", w[1].v0);
    }
    // The dwell holds the path still for 0.2 s.
    let dwell = path
        .blocks()
        .windows(2)
        .map(|b| b[1].t0 - (b[0].t0 + b[0].duration))
        .fold(0.0, f64::max);
    assert!((dwell - 0.2).abs() < 1e-12, "{dwell}");
}

/// The acceptance corpus: 1 000 generated programs (lines, arcs and helices in every
/// plane, rapids, dwells, feeds from slow to beyond the axes' limits, tolerances from 0 to
/// 0.5 mm). Sampled every 1 ms, the setpoints keep every axis within 0.1 % of its limits
/// (finite differences of the sampled positions), stay within the tolerance of the
/// program, and end at the program's end.
#[test]
fn a_thousand_generated_programs_keep_their_limits() {
    let mut worst = Check::default();
    for seed in 0..1000u64 {
        let (text, tol) = corpus::program(seed);
        let m = Machine {
            tolerance: tol,
            ..corpus::machine(seed)
        };
        let p =
            interpret(&text, m.present()).unwrap_or_else(|e| panic!("seed {seed}: {e}\n{text}"));
        let path = plan(&p, &m).unwrap_or_else(|e| panic!("seed {seed}: {e}\n{text}"));
        let c = check_setpoints(&path, &m, 1e-3);
        assert!(c.limit_ratio <= 1.001, "seed {seed}: {c:?}\n{text}");
        assert!(
            c.path_deviation <= tol + 1e-9,
            "seed {seed}: {} mm off the program (tolerance {tol})\n{text}",
            c.path_deviation
        );
        assert!(
            (path.at(path.duration()).p - p.end).norm() < 1e-6,
            "seed {seed}: ends elsewhere"
        );
        worst = worst.worse(c);
    }
    eprintln!("worst over the corpus: {worst:?}");
}

/// A feed far too slow (0.0001 mm/min) would take months: refused, naming its line.
#[test]
fn a_program_longer_than_a_day_is_refused() {
    let m = machine(0.01);
    let p = interpret("G1 X1 F600\nG1 X10 F0.0001\n", m.present()).expect("valid");
    let e = plan(&p, &m).expect_err("months");
    assert_eq!(e.at.line, 2, "{e}");
    assert!(e.message.contains("more than 86400 s"), "{e}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 400, ..Default::default() })]
    /// Whatever the text, interpreting it and planning what interprets end in a program or
    /// an error, never a panic; a plan's duration and positions are finite.
    #[test]
    fn any_text_is_a_program_or_an_error(
        lines in proptest::collection::vec(
            proptest::string::string_regex(
                "(N[0-9]{1,3} )?(G[0-3]|G4|G1[7-9]|G2[01]|G9[01]|G90\\.1|G91\\.1|G94|M2|M30|G[0-9]{1,2}|M[0-9]|T1|S100|#1)?( [XYZIJKRFP]-?[0-9]{0,4}(\\.[0-9]{0,4})?){0,5}( \\(c\\)| ;c)?"
            ).expect("regex"),
            0..12,
        ),
        tol in 0.0f64..0.5,
    ) {
        let text = lines.join("\n");
        let m = machine(tol);
        if let Ok(p) = interpret(&text, m.present())
            && let Ok(path) = plan(&p, &m)
        {
            proptest::prop_assert!(path.duration().is_finite() && path.duration() >= 0.0);
            for k in 0..=20 {
                let st = path.at(path.duration() * f64::from(k) / 20.0);
                proptest::prop_assert!(st.p.is_finite() && st.speed.is_finite(), "{text}");
            }
        }
    }
}
