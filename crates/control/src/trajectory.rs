//! Desired motion x^d(t) with ẋ^d and ẍ^d (docs/system.md, "The reference scenario"): the cosine command, a
//! trapezoidal ("T-type") point-to-point profile and a sequence of such moves. Each axis has
//! its own trajectory. Units: rad, rad/s, rad/s², s.

use std::f64::consts::TAU;

use crate::error::{ControlError, check};

/// Desired position, velocity and acceleration at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Position x^d \[rad\].
    pub x: f64,
    /// Velocity ẋ^d [rad/s].
    pub v: f64,
    /// Acceleration ẍ^d [rad/s²].
    pub a: f64,
}

/// A desired motion of one axis.
pub trait Trajectory {
    /// The desired state at time `t` \[s\]; before the start the initial position at rest.
    fn at(&self, t: f64) -> State;
    /// When the motion ends \[s\] (∞ for a periodic command).
    fn end_time(&self) -> f64;
}

/// x^d(t) = x0 + A·(1 − cos(2πt/P)): the reference scenario's command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cosine {
    /// Amplitude A \[rad\].
    pub amplitude: f64,
    /// Period P \[s\].
    pub period: f64,
    /// Initial position x0 \[rad\].
    pub start: f64,
}

impl Cosine {
    /// A checked cosine command.
    pub fn new(amplitude: f64, period: f64, start: f64) -> Result<Self, ControlError> {
        check(
            "amplitude",
            amplitude,
            f64::MIN,
            false,
            "a finite angle in rad",
        )?;
        check("period", period, 0.0, true, "> 0 s")?;
        check("start", start, f64::MIN, false, "a finite angle in rad")?;
        Ok(Cosine {
            amplitude,
            period,
            start,
        })
    }

    /// The cosine whose peak speed is `v_peak` [rad/s]: A = v_peak·P/(2π)
    /// (the reference: 15.12 rad/s, P = 2 s).
    pub fn with_peak_speed(v_peak: f64, period: f64) -> Result<Self, ControlError> {
        check("v_peak", v_peak, 0.0, true, "> 0 rad/s")?;
        check("period", period, 0.0, true, "> 0 s")?;
        Cosine::new(v_peak * period / TAU, period, 0.0)
    }
}

impl Trajectory for Cosine {
    fn at(&self, t: f64) -> State {
        if t < 0.0 {
            return State {
                x: self.start,
                v: 0.0,
                a: 0.0,
            };
        }
        let w = TAU / self.period;
        let (s, c) = (w * t).sin_cos();
        State {
            x: self.start + self.amplitude * (1.0 - c),
            v: self.amplitude * w * s,
            a: self.amplitude * w * w * c,
        }
    }
    fn end_time(&self) -> f64 {
        f64::INFINITY
    }
}

/// A trapezoidal velocity profile from `start` over `distance`: accelerate at a_max, cruise
/// at v_max, decelerate at a_max. When the distance is too short to reach v_max
/// (|distance| < v_max²/a_max) the profile is triangular with peak √(|distance|·a_max).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    /// Start position \[rad\].
    pub start: f64,
    /// Signed distance \[rad\].
    pub distance: f64,
    /// Start time \[s\].
    pub t0: f64,
    /// Acceleration limit a_max [rad/s²].
    pub a_max: f64,
    /// Peak speed reached, ≤ v_max [rad/s].
    pub v_peak: f64,
    /// Duration of the acceleration (and of the deceleration) phase \[s\].
    pub t_acc: f64,
    /// Duration of the cruise phase \[s\] (0 when triangular).
    pub t_cruise: f64,
}

impl Trapezoid {
    /// Plans a move; v_max and a_max must be > 0.
    pub fn new(
        start: f64,
        distance: f64,
        v_max: f64,
        a_max: f64,
        t0: f64,
    ) -> Result<Self, ControlError> {
        check("start", start, f64::MIN, false, "a finite angle in rad")?;
        check(
            "distance",
            distance,
            f64::MIN,
            false,
            "a finite angle in rad",
        )?;
        check("v_max", v_max, 0.0, true, "> 0 rad/s")?;
        check("a_max", a_max, 0.0, true, "> 0 rad/s²")?;
        check("t0", t0, f64::MIN, false, "a finite time in s")?;
        let d = distance.abs();
        let (v_peak, t_acc, t_cruise) = if d * a_max <= v_max * v_max {
            let vp = (d * a_max).sqrt();
            (vp, vp / a_max, 0.0)
        } else {
            (v_max, v_max / a_max, d / v_max - v_max / a_max)
        };
        Ok(Trapezoid {
            start,
            distance,
            t0,
            a_max,
            v_peak,
            t_acc,
            t_cruise,
        })
    }

    /// Whether the profile never reaches v_max (no cruise phase).
    pub fn is_triangular(&self) -> bool {
        self.t_cruise == 0.0
    }

    /// Duration of the whole move \[s\].
    pub fn duration(&self) -> f64 {
        2.0 * self.t_acc + self.t_cruise
    }
}

impl Trajectory for Trapezoid {
    fn at(&self, t: f64) -> State {
        let s = self.distance.signum();
        let (a, vp, ta, tc) = (self.a_max, self.v_peak, self.t_acc, self.t_cruise);
        let tau = t - self.t0;
        let (x, v, acc) = if tau <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if tau < ta {
            (0.5 * a * tau * tau, a * tau, a)
        } else if tau < ta + tc {
            (0.5 * a * ta * ta + vp * (tau - ta), vp, 0.0)
        } else if tau < 2.0 * ta + tc {
            let td = tau - ta - tc;
            (
                0.5 * a * ta * ta + vp * tc + vp * td - 0.5 * a * td * td,
                vp - a * td,
                -a,
            )
        } else {
            return State {
                x: self.start + self.distance,
                v: 0.0,
                a: 0.0,
            };
        };
        State {
            x: self.start + s * x,
            v: s * v,
            a: s * acc,
        }
    }
    fn end_time(&self) -> f64 {
        self.t0 + self.duration()
    }
}

/// Point-to-point moves one after the other, each from where the last one ended, with a
/// dwell after each.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    moves: Vec<Trapezoid>,
    start: f64,
}

impl Sequence {
    /// Moves from `start` through `targets` (position \[rad\], dwell after arriving \[s\]) with
    /// the same limits, beginning at `t0` \[s\].
    pub fn new(
        start: f64,
        targets: &[(f64, f64)],
        v_max: f64,
        a_max: f64,
        t0: f64,
    ) -> Result<Self, ControlError> {
        let mut moves = Vec::with_capacity(targets.len());
        let (mut pos, mut t) = (start, t0);
        for (k, &(target, dwell)) in targets.iter().enumerate() {
            check(&format!("targets[{k}].dwell"), dwell, 0.0, false, ">= 0 s")?;
            let m = Trapezoid::new(pos, target - pos, v_max, a_max, t)?;
            t = m.end_time() + dwell;
            pos = target;
            moves.push(m);
        }
        Ok(Sequence { moves, start })
    }

    /// The moves.
    pub fn moves(&self) -> &[Trapezoid] {
        &self.moves
    }
}

impl Trajectory for Sequence {
    fn at(&self, t: f64) -> State {
        // The last move that has started (moves are in time order).
        let k = self.moves.partition_point(|m| m.t0 <= t);
        match k {
            0 => State {
                x: self.start,
                v: 0.0,
                a: 0.0,
            },
            k => self.moves[k - 1].at(t),
        }
    }
    fn end_time(&self) -> f64 {
        self.moves.last().map_or(0.0, |m| m.end_time())
    }
}

/// One drive's share of a planned part program (docs/programs.md): the path's machine
/// coordinate `coord` (0 = X, 1 = Y, 2 = Z) through the drive's transmission, x^d =
/// p_coord(t)·`rad_per_mm`.
#[derive(Debug, Clone)]
pub struct PathAxis {
    /// The planned path, shared by every drive of the machine.
    pub path: std::sync::Arc<ringsync_path::PlannedPath>,
    /// Which machine coordinate the drive moves.
    pub coord: usize,
    /// Transmission [rad/mm]: 2π over the lead, negative for a reversed drive.
    pub rad_per_mm: f64,
}

impl PartialEq for PathAxis {
    /// The same plan (not merely an equal one), coordinate and transmission.
    fn eq(&self, o: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.path, &o.path)
            && self.coord == o.coord
            && self.rad_per_mm.to_bits() == o.rad_per_mm.to_bits()
    }
}

impl Trajectory for PathAxis {
    fn at(&self, t: f64) -> State {
        let p = self.path.at(t);
        let k = self.rad_per_mm;
        State {
            x: p.p[self.coord] * k,
            v: p.v[self.coord] * k,
            a: p.a[self.coord] * k,
        }
    }
    fn end_time(&self) -> f64 {
        self.path.duration()
    }
}

/// Any of the built-in trajectories.
#[derive(Debug, Clone, PartialEq)]
pub enum AxisTrajectory {
    /// The cosine command.
    Cosine(Cosine),
    /// One trapezoidal move.
    Trapezoid(Trapezoid),
    /// A sequence of moves.
    Sequence(Sequence),
    /// A drive's share of a part program.
    Path(PathAxis),
}

impl Trajectory for AxisTrajectory {
    fn at(&self, t: f64) -> State {
        match self {
            AxisTrajectory::Cosine(c) => c.at(t),
            AxisTrajectory::Trapezoid(c) => c.at(t),
            AxisTrajectory::Sequence(c) => c.at(t),
            AxisTrajectory::Path(c) => c.at(t),
        }
    }
    fn end_time(&self) -> f64 {
        match self {
            AxisTrajectory::Cosine(c) => c.end_time(),
            AxisTrajectory::Trapezoid(c) => c.end_time(),
            AxisTrajectory::Sequence(c) => c.end_time(),
            AxisTrajectory::Path(c) => c.end_time(),
        }
    }
}

/// The trajectories of a group's axes, each evaluated once per instant asked: axes whose
/// trajectories are equal (the reference scenario's four follow one cosine) share one
/// evaluation while they are asked for the same instant, as a master is at a cycle's start
/// and at its sampling instant, and a lumped-only slave for every axis at once. Results are
/// [`Trajectory::at`]'s to the bit.
#[derive(Debug, Clone)]
pub struct GroupTrajectories {
    each: Vec<AxisTrajectory>,
    /// For each axis, the first axis with an equal trajectory.
    first: Vec<usize>,
    /// Each first axis's last instant asked [s, as bits] and the state then.
    last_t: Vec<std::cell::Cell<u64>>,
    last: Vec<std::cell::Cell<State>>,
}

impl GroupTrajectories {
    /// The group of `each` (one trajectory per axis).
    pub fn new(each: Vec<AxisTrajectory>) -> Self {
        let first = (0..each.len())
            .map(|i| each[..i].iter().position(|t| *t == each[i]).unwrap_or(i))
            .collect();
        let last_t = vec![std::cell::Cell::new(0.0f64.to_bits()); each.len()];
        let last = each
            .iter()
            .map(|t| std::cell::Cell::new(t.at(0.0)))
            .collect();
        GroupTrajectories {
            each,
            first,
            last_t,
            last,
        }
    }

    /// How many axes.
    pub fn len(&self) -> usize {
        self.each.len()
    }

    /// Whether the group has no axis.
    pub fn is_empty(&self) -> bool {
        self.each.is_empty()
    }

    /// Axis `axis`'s desired state at `t` \[s\].
    pub fn at(&self, axis: usize, t: f64) -> State {
        let j = self.first[axis];
        let key = t.to_bits();
        if self.last_t[j].get() == key {
            return self.last[j].get();
        }
        let s = self.each[j].at(t);
        self.last_t[j].set(key);
        self.last[j].set(s);
        s
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// A group shares evaluations between equal trajectories and gives each axis what its
    /// own trajectory gives, whatever the order of the instants asked.
    #[test]
    fn a_group_gives_each_axis_its_own_trajectory() {
        let a = AxisTrajectory::Cosine(Cosine::with_peak_speed(15.12, 2.0).expect("cosine"));
        let b = AxisTrajectory::Cosine(Cosine::new(0.3, 1.5, 0.1).expect("cosine"));
        let each = vec![a.clone(), b.clone(), a.clone(), b.clone(), a.clone()];
        let g = GroupTrajectories::new(each.clone());
        assert_eq!(g.first, [0, 1, 0, 1, 0]);
        for t in [0.0, 0.25, 0.25, -1.0, 0.1, 0.25, 0.7, 0.7] {
            for axis in [4, 0, 3, 1, 2, 2] {
                assert_eq!(g.at(axis, t), each[axis].at(t), "axis {axis} at {t}");
            }
        }
    }

    #[test]
    fn reference_cosine() {
        let c = Cosine::with_peak_speed(15.12, 2.0).expect("cosine");
        assert!((c.amplitude - 15.12 * 2.0 / TAU).abs() < 1e-12);
        // Peak speed at t = P/4, turning point at P/2, back home at P.
        assert!((c.at(0.5).v - 15.12).abs() < 1e-12);
        assert!((c.at(1.0).x - 2.0 * c.amplitude).abs() < 1e-12);
        assert!(c.at(2.0).x.abs() < 1e-12);
        // v and a are the derivatives of x (central differences).
        for t in [0.1, 0.7, 1.3] {
            let h = 1e-6;
            let dx = (c.at(t + h).x - c.at(t - h).x) / (2.0 * h);
            let dv = (c.at(t + h).v - c.at(t - h).v) / (2.0 * h);
            assert!((dx - c.at(t).v).abs() < 1e-6 && (dv - c.at(t).a).abs() < 1e-5);
        }
    }

    #[test]
    fn trapezoid_limits_and_end() {
        let m = Trapezoid::new(1.0, 10.0, 15.12, 50.0, 0.5).expect("move");
        assert!(!m.is_triangular());
        // t_acc = 15.12/50, cruise = 10/15.12 − 15.12/50.
        assert!((m.t_acc - 0.3024).abs() < 1e-12);
        assert!((m.duration() - (2.0 * 0.3024 + 10.0 / 15.12 - 0.3024)).abs() < 1e-12);
        assert_eq!(
            m.at(0.0),
            State {
                x: 1.0,
                v: 0.0,
                a: 0.0
            }
        );
        assert_eq!(
            m.at(m.end_time() + 1.0),
            State {
                x: 11.0,
                v: 0.0,
                a: 0.0
            }
        );
        assert!((m.at(0.5 + m.t_acc + 0.1).v - 15.12).abs() < 1e-12);
    }

    #[test]
    fn short_move_is_triangular() {
        // 1 rad with v_max 15.12 and a_max 50: v_max²/a_max = 4.57 rad > 1 rad.
        let m = Trapezoid::new(0.0, -1.0, 15.12, 50.0, 0.0).expect("move");
        assert!(m.is_triangular());
        assert!((m.v_peak - 50f64.sqrt()).abs() < 1e-12);
        let mid = m.at(m.t_acc);
        assert!((mid.x + 0.5).abs() < 1e-12 && (mid.v + m.v_peak).abs() < 1e-12);
        assert!((m.at(10.0).x + 1.0).abs() < 1e-15);
    }

    #[test]
    fn sequence_chains_moves() {
        let s = Sequence::new(0.0, &[(2.0, 0.1), (-1.0, 0.0)], 5.0, 20.0, 0.0).expect("seq");
        let m = s.moves();
        assert!((m[1].t0 - (m[0].end_time() + 0.1)).abs() < 1e-12);
        assert!((s.at(m[0].end_time() + 0.05).x - 2.0).abs() < 1e-12);
        assert!((s.at(s.end_time() + 1.0).x + 1.0).abs() < 1e-12);
        assert_eq!(s.at(-1.0).x, 0.0);
    }

    #[test]
    fn bad_parameters_are_named() {
        let name = |e: ControlError| match e {
            ControlError::InvalidParameter { name, .. } => name,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            name(Trapezoid::new(0.0, 1.0, 1.0, 0.0, 0.0).expect_err("a_max")),
            "a_max"
        );
        assert_eq!(
            name(Trapezoid::new(0.0, 1.0, f64::NAN, 1.0, 0.0).expect_err("v")),
            "v_max"
        );
        assert_eq!(
            name(Cosine::new(1.0, -2.0, 0.0).expect_err("period")),
            "period"
        );
        assert_eq!(
            name(Sequence::new(0.0, &[(1.0, -1.0)], 1.0, 1.0, 0.0).expect_err("dwell")),
            "targets[0].dwell"
        );
    }

    proptest! {
        /// Continuity of position and velocity, speed and acceleration within limits, and
        /// arrival at the target, for any move.
        #[test]
        fn trapezoid_is_continuous_and_limited(
            d in -50.0f64..50.0, v_max in 0.1f64..30.0, a_max in 0.1f64..500.0
        ) {
            let m = Trapezoid::new(0.0, d, v_max, a_max, 0.0).expect("move");
            let n = 2000;
            let dt = m.duration() / n as f64;
            let mut prev = m.at(0.0);
            for k in 1..=n + 5 {
                let s = m.at(k as f64 * dt);
                prop_assert!(s.v.abs() <= v_max * (1.0 + 1e-12));
                prop_assert!(s.a.abs() <= a_max * (1.0 + 1e-12));
                // Bounded change per step: |Δx| ≤ v_max·dt, |Δv| ≤ a_max·dt.
                prop_assert!((s.x - prev.x).abs() <= v_max * dt * (1.0 + 1e-9) + 1e-12);
                prop_assert!((s.v - prev.v).abs() <= a_max * dt * (1.0 + 1e-9) + 1e-12);
                prev = s;
            }
            prop_assert!((prev.x - d).abs() < 1e-9 * d.abs().max(1.0));
            prop_assert_eq!(prev.v, 0.0);
        }
    }
}
