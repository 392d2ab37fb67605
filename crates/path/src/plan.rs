//! The feed along the path: look-ahead over the whole program and a jerk-limited (S-curve)
//! profile of the path speed that keeps every machine axis within its velocity,
//! acceleration and jerk limits at every instant.
//!
//! How (docs/programs.md, "The planner"):
//!
//! 1. **Bounds per piece.** For each piece and machine axis i, the largest |tᵢ|, |κᵢ| and
//!    |κ′ᵢ| over the piece (the unit tangent, the curvature vector and its derivative along
//!    the arc length; exact for lines and arcs, from 65 samples plus 5 % for blends).
//! 2. **Blocks.** Neighbouring pieces that join smoothly are merged into one block while
//!    the merge costs less time than the speed change it saves (tiny segments of CAM
//!    output become one block); a block's bounds are its pieces' largest.
//! 3. **Limits per block.** The path speed V, tangential acceleration A and jerk J under
//!    which axis i's velocity tᵢ·v, acceleration tᵢ·a + κᵢ·v² and jerk
//!    tᵢ·j + 3κᵢ·v·a + κ′ᵢ·v³ stay within vᵢ, aᵢ, jᵢ (the triangle inequality on the
//!    bounds): V is the feed, or vᵢ/|tᵢ|, or the speed at which the centripetal
//!    acceleration takes half of aᵢ or κ′ᵢ·V³ a quarter of jᵢ; A leaves room for the
//!    centripetal part and keeps 3κᵢ·V·A within a quarter of jᵢ; J takes the rest.
//! 4. **Look-ahead.** The path stops at its ends, at dwells and at unblended corners; at
//!    every other junction it may pass at the lower of its blocks' V. A backward and a
//!    forward pass lower each junction's speed to what the block after it can still brake
//!    from, and the block before it can reach (the shortest jerk-limited speed change with
//!    zero acceleration at both ends, in closed form).
//! 5. **Profiles.** Each block's path speed goes from its entry speed to its exit speed,
//!    with zero tangential acceleration at both ends, time-optimally under V, A, J: the 1-D
//!    state-to-state problem Ruckig solves (`rsruckig`). Its up to seven constant-jerk
//!    phases are kept, each with its absolute start time and arc length.

use rsruckig::prelude::*;

use crate::blend::{Blended, Start, blend};
use crate::geometry::{Curve, Frame, Helix, Quintic, golden_max};
use crate::program::{Move, MoveKind, Program, Source};
use crate::vec3::Vec3;

/// A machine axis's limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest speed \[mm/s\].
    pub v_max: f64,
    /// Largest acceleration \[mm/s²\].
    pub a_max: f64,
    /// Largest jerk \[mm/s³\].
    pub j_max: f64,
}

/// What the planner knows of the machine: the limits of its axes X, Y, Z (`None`: no such
/// axis) and the path tolerance for blending.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// Limits of X, Y and Z.
    pub axes: [Option<Limits>; 3],
    /// How far the path may leave the programmed corners \[mm\] (0: stop at each).
    pub tolerance: f64,
}

impl Machine {
    /// Which of X, Y, Z the machine has.
    pub fn present(&self) -> [bool; 3] {
        self.axes.map(|a| a.is_some())
    }
}

/// Share of an axis's acceleration the centripetal part κ·v² may take at a block's V.
pub const CENTRIPETAL_SHARE: f64 = 0.5;
/// Share of an axis's jerk κ′·v³ may take at a block's V.
pub const CURVATURE_JERK_SHARE: f64 = 0.25;
/// Share of an axis's jerk 3κ·v·a may take at a block's V and A.
pub const COUPLING_JERK_SHARE: f64 = 0.25;
/// Longest program planned \[s\]: a day (a slower one is most likely a feed in the wrong
/// unit, and sampling it at a cycle would not end).
pub const MAX_PROGRAM_SECONDS: f64 = 86_400.0;
/// Margin on a blend's sampled bounds.
const BLEND_MARGIN: f64 = 1.05;
/// Samples of a blend for its bounds.
const BLEND_SAMPLES: u32 = 64;

/// What set a block's speed limit V.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    /// The programmed feed.
    Feed,
    /// Axis i's velocity limit (0 = X).
    Velocity(usize),
    /// Axis i's acceleration, through the path's curvature.
    Centripetal(usize),
    /// Axis i's jerk, through the curvature's change along the path.
    CurvatureJerk(usize),
}

impl Binding {
    /// Short name in tables: `feed`, `v X`, `a X (curvature)`, `j X (curvature)`.
    pub fn label(&self) -> String {
        let l = |i: usize| crate::program::AXIS_LETTERS[i.min(2)];
        match self {
            Binding::Feed => "feed".into(),
            Binding::Velocity(i) => format!("v {}", l(*i)),
            Binding::Centripetal(i) => format!("a {} (curvature)", l(*i)),
            Binding::CurvatureJerk(i) => format!("j {} (curvature)", l(*i)),
        }
    }
}

/// A stretch of path with one speed profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// Where it starts along the path \[mm\].
    pub s0: f64,
    /// Its length \[mm\].
    pub len: f64,
    /// When it starts \[s\] (after any dwell before it).
    pub t0: f64,
    /// How long it takes \[s\].
    pub duration: f64,
    /// Speed limit V \[mm/s\].
    pub v_max: f64,
    /// Tangential acceleration limit A \[mm/s²\].
    pub a_max: f64,
    /// Tangential jerk limit J \[mm/s³\].
    pub j_max: f64,
    /// What set V.
    pub binding: Binding,
    /// Path speed on entry \[mm/s\].
    pub v_in: f64,
    /// Path speed on exit \[mm/s\].
    pub v_out: f64,
    /// Highest path speed reached \[mm/s\].
    pub v_peak: f64,
    /// The program line of its first piece.
    pub src: Source,
}

/// One constant-jerk phase of the path speed's profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phase {
    /// Start time \[s\].
    pub t0: f64,
    /// Arc length at its start \[mm\].
    pub s0: f64,
    /// Path speed at its start \[mm/s\].
    pub v0: f64,
    /// Tangential acceleration at its start \[mm/s²\].
    pub a0: f64,
    /// Its jerk \[mm/s³\].
    pub j: f64,
}

/// A piece of the planned path at its place along it.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// Its geometry.
    pub curve: Curve,
    /// Arc length at its start \[mm\].
    pub s0: f64,
    /// The programmed move it lies on (for a blend, the move before the corner).
    pub mv: u32,
}

/// The planned path at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathState {
    /// Arc length travelled \[mm\].
    pub s: f64,
    /// Path speed \[mm/s\].
    pub speed: f64,
    /// Tangential acceleration \[mm/s²\].
    pub accel: f64,
    /// Tangential jerk \[mm/s³\].
    pub jerk: f64,
    /// Position \[mm\].
    pub p: Vec3,
    /// Velocity \[mm/s\].
    pub v: Vec3,
    /// Acceleration \[mm/s²\].
    pub a: Vec3,
    /// Jerk \[mm/s³\].
    pub j: Vec3,
    /// Index of the piece (see [`PlannedPath::pieces`]).
    pub piece: usize,
}

/// A program that cannot be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{at}: {message}")]
pub struct PlanError {
    /// The program line it concerns.
    pub at: Source,
    /// What went wrong.
    pub message: String,
}

/// A program planned for a machine: the path and its feed, to be evaluated at any
/// instant.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPath {
    moves: Vec<Move>,
    pieces: Vec<Placed>,
    phases: Vec<Phase>,
    blocks: Vec<Block>,
    duration: f64,
    length: f64,
    start: Vec3,
    end: Vec3,
    blends: usize,
    stops: usize,
    tolerance: f64,
}

/// Axis bounds of a stretch of path: the largest |tᵢ|, |κᵢ| \[1/mm\], |κ′ᵢ| \[1/mm²\].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Bounds {
    t: [f64; 3],
    k: [f64; 3],
    dk: [f64; 3],
}

impl Bounds {
    fn max(self, o: Bounds) -> Bounds {
        let m = |a: [f64; 3], b: [f64; 3]| [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])];
        Bounds {
            t: m(self.t, o.t),
            k: m(self.k, o.k),
            dk: m(self.dk, o.dk),
        }
    }

    fn of(c: &Curve) -> Bounds {
        match c {
            Curve::Line(l) => Bounds {
                t: l.dir.abs().0,
                ..Bounds::default()
            },
            Curve::Arc(h) => helix_bounds(h),
            Curve::Blend(q) => blend_bounds(q),
        }
    }
}

/// A blend's bounds: sampled, each curvature component's largest sample refined by a
/// golden-section search between its neighbours (a sharp corner's blend turns within a
/// few samples), plus [`BLEND_MARGIN`].
fn blend_bounds(q: &Quintic) -> Bounds {
    let n = BLEND_SAMPLES as usize;
    let frames: Vec<Frame> = (0..=n)
        .map(|i| q.frame_at_param(i as f64 / n as f64))
        .collect();
    let mut b = Bounds::default();
    for f in &frames {
        b = b.max(Bounds {
            t: f.t.abs().0,
            k: f.k.abs().0,
            dk: f.dk.abs().0,
        });
    }
    // (component of k or dk, axis): refine where the largest sample stands out from its
    // neighbours.
    for which in 0..2 {
        for axis in 0..3 {
            let get = |f: &Frame| {
                if which == 0 {
                    f.k[axis].abs()
                } else {
                    f.dk[axis].abs()
                }
            };
            let (i, top) = frames
                .iter()
                .map(get)
                .enumerate()
                .fold((0, 0.0), |m, (i, x)| if x > m.1 { (i, x) } else { m });
            if top == 0.0 {
                continue;
            }
            let side = |j: usize| frames.get(j).map_or(0.0, get);
            let near = side(i.wrapping_sub(1)).max(side(i + 1));
            if near >= 0.99 * top {
                continue;
            }
            let f = |u: f64| get(&q.frame_at_param(u));
            let w = 1.0 / n as f64;
            let (lo, hi) = ((i as f64 * w - w).max(0.0), (i as f64 * w + w).min(1.0));
            let best = top.max(golden_max(f, lo, hi, 30));
            if which == 0 {
                b.k[axis] = best;
            } else {
                b.dk[axis] = best;
            }
        }
    }
    let m = |v: [f64; 3]| v.map(|x| x * BLEND_MARGIN);
    Bounds {
        t: b.t.map(|x| (x * BLEND_MARGIN).min(1.0)),
        k: m(b.k),
        dk: m(b.dk),
    }
}

/// The largest |c1·cos φ + c2·sin φ| for φ between `phi0` and `phi0 + sweep`.
fn max_harmonic(c1: f64, c2: f64, phi0: f64, sweep: f64) -> f64 {
    let amp = c1.hypot(c2);
    if amp == 0.0 {
        return 0.0;
    }
    let psi = c2.atan2(c1);
    let (lo, hi) = if sweep >= 0.0 {
        (phi0, phi0 + sweep)
    } else {
        (phi0 + sweep, phi0)
    };
    // |cos(φ − ψ)| is 1 where φ − ψ is a multiple of π.
    let first = ((lo - psi) / std::f64::consts::PI).ceil();
    if psi + first * std::f64::consts::PI <= hi {
        return amp;
    }
    amp * (lo - psi).cos().abs().max((hi - psi).cos().abs())
}

fn helix_bounds(h: &Helix) -> Bounds {
    let n = h.normal();
    let kphi = if h.len > 0.0 { h.sweep / h.len } else { 0.0 };
    let rise = if h.len > 0.0 { h.rise / h.len } else { 0.0 };
    let mut b = Bounds::default();
    for i in 0..3 {
        let (al, be) = (h.e1[i], h.e2[i]);
        // along = e2·cos φ − e1·sin φ, radial = e1·cos φ + e2·sin φ.
        let along = max_harmonic(be, -al, h.phi0, h.sweep);
        let radial = max_harmonic(al, be, h.phi0, h.sweep);
        b.t[i] = (h.r * kphi.abs() * along + (n[i] * rise).abs()).min(1.0);
        b.k[i] = h.r * kphi * kphi * radial;
        b.dk[i] = h.r * kphi.abs().powi(3) * along;
    }
    b
}

/// A block's limits: (V, A, J, what set V).
fn limits(b: &Bounds, feed: f64, m: &Machine) -> (f64, f64, f64, Binding) {
    let mut v = feed;
    let mut binding = Binding::Feed;
    let mut lower = |c: f64, why: Binding| {
        if c < v {
            v = c;
            binding = why;
        }
    };
    for (i, l) in m.axes.iter().enumerate() {
        let Some(l) = l else { continue };
        if b.t[i] > 0.0 {
            lower(l.v_max / b.t[i], Binding::Velocity(i));
        }
        if b.k[i] > 0.0 {
            lower(
                (CENTRIPETAL_SHARE * l.a_max / b.k[i]).sqrt(),
                Binding::Centripetal(i),
            );
        }
        if b.dk[i] > 0.0 {
            lower(
                (CURVATURE_JERK_SHARE * l.j_max / b.dk[i]).cbrt(),
                Binding::CurvatureJerk(i),
            );
        }
    }
    let mut a = f64::INFINITY;
    for (i, l) in m.axes.iter().enumerate() {
        let Some(l) = l else { continue };
        if b.t[i] > 0.0 {
            a = a.min((l.a_max - b.k[i] * v * v) / b.t[i]);
        }
        if b.k[i] > 0.0 && v > 0.0 {
            a = a.min(COUPLING_JERK_SHARE * l.j_max / (3.0 * b.k[i] * v));
        }
    }
    let mut j = f64::INFINITY;
    for (i, l) in m.axes.iter().enumerate() {
        let Some(l) = l else { continue };
        if b.t[i] > 0.0 {
            j = j.min((l.j_max - 3.0 * b.k[i] * v * a - b.dk[i] * v * v * v) / b.t[i]);
        }
    }
    (v, a, j, binding)
}

/// The time a jerk-limited change of path speed from `v0` to `v1` takes with zero
/// acceleration at both ends \[s\].
fn change_time(v0: f64, v1: f64, a: f64, j: f64) -> f64 {
    let dv = (v1 - v0).abs();
    if dv * j <= a * a {
        2.0 * (dv / j).sqrt()
    } else {
        dv / a + a / j
    }
}

/// The highest speed reachable from `v0` within `len` under `a`, `j`, starting and ending
/// with zero acceleration: the closed form of the shortest S-curve, d = (v0 + v1)/2 · T.
pub fn reach(v0: f64, len: f64, a: f64, j: f64) -> f64 {
    if len <= 0.0 {
        return v0;
    }
    // With the whole change inside the jerk phases (Δv ≤ a²/j): x = √Δv solves
    // x³ + 2·v0·x − len·√j = 0.
    let dv_star = a * a / j;
    let d_star = (2.0 * v0 + dv_star) * a / j;
    let dv = if len <= d_star {
        let (p, q) = (2.0 * v0, -len * j.sqrt());
        let disc = (q * q / 4.0 + p * p * p / 27.0).sqrt();
        let mut x = (-q / 2.0 + disc).cbrt() + (-q / 2.0 - disc).cbrt();
        // Newton polishes what cancellation in Cardano's formula lost.
        for _ in 0..3 {
            let f = x * x * x + p * x + q;
            let df = 3.0 * x * x + p;
            if df > 0.0 {
                x -= f / df;
            }
        }
        (x * x).min(dv_star)
    } else {
        // (2·v0 + Δv)·(Δv/a + a/j) = 2·len, a quadratic in Δv.
        let qa = 1.0 / a;
        let qb = 2.0 * v0 / a + a / j;
        let qc = 2.0 * v0 * a / j - 2.0 * len;
        2.0 * -qc / (qb + (qb * qb - 4.0 * qa * qc).sqrt())
    };
    v0 + dv.max(0.0)
}

/// Plans `program` for `machine`.
///
/// ```
/// use ringsync_path::{interpret, plan::{Limits, Machine, plan}};
/// let l = Limits { v_max: 100.0, a_max: 1000.0, j_max: 20000.0 };
/// let m = Machine { axes: [Some(l), Some(l), None], tolerance: 0.01 };
/// let p = interpret("G1 X10 F6000\nY10\n", m.present()).unwrap();
/// let path = plan(&p, &m).unwrap();
/// // Two 10 mm legs and a corner blended within 0.01 mm, taken at about 1 mm/s.
/// assert!(path.duration() > 0.5 && path.duration() < 0.8, "{}", path.duration());
/// let end = path.at(path.duration() + 1.0);
/// assert!((end.p.0[0] - 10.0).abs() < 1e-9 && (end.p.0[1] - 10.0).abs() < 1e-9);
/// assert_eq!(end.speed, 0.0);
/// ```
pub fn plan(program: &Program, machine: &Machine) -> Result<PlannedPath, PlanError> {
    for (i, l) in machine.axes.iter().enumerate() {
        if let Some(l) = l
            && !([l.v_max, l.a_max, l.j_max]
                .iter()
                .all(|x| x.is_finite() && *x > 0.0))
        {
            return Err(PlanError {
                at: Source::default(),
                message: format!(
                    "axis {}: v_max, a_max and j_max must be finite and > 0",
                    crate::program::AXIS_LETTERS[i]
                ),
            });
        }
    }
    let b = blend(&program.moves, machine.tolerance);
    Planner::new(program, machine).run(b)
}

/// A block being built.
struct Open {
    first: usize,
    s0: f64,
    len: f64,
    bounds: Bounds,
    feed: f64,
    v: f64,
    a: f64,
    j: f64,
    binding: Binding,
    start: Start,
    /// Σ len/V of its pieces, each at its own V \[s\]: what the merge cost is measured
    /// from.
    ideal: f64,
}

struct Planner<'p> {
    program: &'p Program,
    machine: &'p Machine,
}

impl<'p> Planner<'p> {
    fn new(program: &'p Program, machine: &'p Machine) -> Self {
        Planner { program, machine }
    }

    fn src(&self, mv: u32) -> Source {
        self.program
            .moves
            .get(mv as usize)
            .map_or(Source::default(), |m| m.src)
    }

    fn run(self, b: Blended) -> Result<PlannedPath, PlanError> {
        let Blended {
            pieces,
            end_dwell,
            blends,
            stops,
        } = b;
        // Place the pieces along the path; make the blocks.
        let mut placed = Vec::with_capacity(pieces.len());
        let mut opens: Vec<Open> = Vec::new();
        let mut s = 0.0;
        for (idx, pc) in pieces.into_iter().enumerate() {
            let len = pc.curve.len();
            let bounds = Bounds::of(&pc.curve);
            let (v, a, j, binding) = limits(&bounds, pc.feed, self.machine);
            if !(v > 0.0 && a > 0.0 && j > 0.0 && v.is_finite() && a.is_finite() && j.is_finite()) {
                return Err(PlanError {
                    at: self.src(pc.mv),
                    message: format!(
                        "no feasible speed on this move (v {v:.3e} mm/s, a {a:.3e} mm/s², j {j:.3e} mm/s³): its curvature is too tight for the machine's limits"
                    ),
                });
            }
            let merged = match opens.last_mut() {
                Some(o) if pc.start == Start::Smooth => {
                    let mb = o.bounds.max(bounds);
                    let mf = o.feed.min(pc.feed);
                    let (mv, ma, mj, mbind) = limits(&mb, mf, self.machine);
                    // Time lost cruising every piece of the block at the merged V rather than
                    // at its own, plus the longer speed changes of the lower A and J.
                    let loss = (o.len + len) / mv - (o.ideal + len / v)
                        + ((mv / ma + ma / mj) - (o.v / o.a + o.a / o.j).max(v / a + a / j))
                            .max(0.0);
                    let trans = change_time(o.v, v, o.a.min(a), o.j.min(j));
                    if mv > 0.0 && ma > 0.0 && mj > 0.0 && loss <= trans {
                        o.len += len;
                        o.ideal += len / v;
                        o.bounds = mb;
                        o.feed = mf;
                        (o.v, o.a, o.j, o.binding) = (mv, ma, mj, mbind);
                        true
                    } else {
                        false
                    }
                }
                _ => false,
            };
            if !merged {
                opens.push(Open {
                    first: idx,
                    s0: s,
                    len,
                    bounds,
                    feed: pc.feed,
                    v,
                    a,
                    j,
                    binding,
                    start: pc.start,
                    ideal: len / v,
                });
            }
            placed.push(Placed {
                curve: pc.curve,
                s0: s,
                mv: pc.mv,
            });
            s += len;
        }
        let length = s;
        // Junction speeds: w[k] on entry to block k, w[m] at the end.
        let m = opens.len();
        let mut w = vec![0.0; m + 1];
        for k in 1..m {
            w[k] = match opens[k].start {
                Start::Smooth => opens[k - 1].v.min(opens[k].v),
                _ => 0.0,
            };
        }
        // Lengths a hair shorter in the passes: rounding never makes a block too short.
        let shrink = |len: f64| len * (1.0 - 1e-9);
        for k in (0..m).rev() {
            let o = &opens[k];
            w[k] = w[k].min(reach(w[k + 1], shrink(o.len), o.a, o.j)).min(o.v);
        }
        for k in 0..m {
            let o = &opens[k];
            w[k + 1] = w[k + 1].min(reach(w[k], shrink(o.len), o.a, o.j)).min(o.v);
        }
        // Profiles.
        let mut otg = Ruckig::<1, ThrowErrorHandler>::new(None, 1e-3);
        let mut input = InputParameter::<1>::new(None);
        let mut traj = Trajectory::<1>::new(None);
        input.min_velocity = Some(DataArrayOrVec::Stack([0.0]));
        let mut phases = Vec::with_capacity(4 * m + 2);
        let mut blocks = Vec::with_capacity(m);
        let mut t = 0.0;
        for (k, o) in opens.iter().enumerate() {
            let src = self.src(placed[o.first].mv);
            if let Start::Dwell(d) = o.start {
                phases.push(Phase {
                    t0: t,
                    s0: o.s0,
                    v0: 0.0,
                    a0: 0.0,
                    j: 0.0,
                });
                t += d;
            }
            let (v_in, v_out) = (w[k], w[k + 1]);
            input.current_position[0] = 0.0;
            input.current_velocity[0] = v_in;
            input.current_acceleration[0] = 0.0;
            input.target_position[0] = o.len;
            input.target_velocity[0] = v_out;
            input.target_acceleration[0] = 0.0;
            input.max_velocity[0] = o.v;
            input.max_acceleration[0] = o.a;
            input.max_jerk[0] = o.j;
            otg.calculate(&input, &mut traj).map_err(|e| PlanError {
                at: src,
                message: format!(
                    "the feed profile of {:.6} mm from {v_in:.6} to {v_out:.6} mm/s (V {:.6} mm/s, A {:.6} mm/s², J {:.6} mm/s³) failed: {e}",
                    o.len, o.v, o.a, o.j
                ),
            })?;
            let pr = &traj.get_profiles()[0][0];
            let t_block = t;
            let mut v_peak = v_in.max(v_out);
            for ph in 0..7 {
                if pr.t[ph] > 0.0 {
                    phases.push(Phase {
                        t0: t,
                        s0: o.s0 + pr.p[ph],
                        v0: pr.v[ph],
                        a0: pr.a[ph],
                        j: pr.j[ph],
                    });
                    t += pr.t[ph];
                    v_peak = v_peak.max(pr.v[ph + 1]);
                }
            }
            blocks.push(Block {
                s0: o.s0,
                len: o.len,
                t0: t_block,
                duration: t - t_block,
                v_max: o.v,
                a_max: o.a,
                j_max: o.j,
                binding: o.binding,
                v_in,
                v_out,
                v_peak,
                src,
            });
        }
        if t + end_dwell > MAX_PROGRAM_SECONDS {
            let slowest = blocks
                .iter()
                .max_by(|a, b| a.duration.total_cmp(&b.duration))
                .map_or(Source::default(), |b| b.src);
            return Err(PlanError {
                at: slowest,
                message: format!(
                    "the program takes {:.0} s as planned, more than {MAX_PROGRAM_SECONDS:.0} s (a day); its slowest stretch starts here: is its feed in mm (or inches) per minute?",
                    t + end_dwell
                ),
            });
        }
        // At rest at the end (and through a final dwell).
        phases.push(Phase {
            t0: t,
            s0: length,
            v0: 0.0,
            a0: 0.0,
            j: 0.0,
        });
        t += end_dwell;
        let start = placed
            .first()
            .map_or(self.program.end, |p| p.curve.frame(0.0).p);
        let end = placed
            .last()
            .map_or(self.program.end, |p| p.curve.frame(p.curve.len()).p);
        Ok(PlannedPath {
            moves: self.program.moves.clone(),
            pieces: placed,
            phases,
            blocks,
            duration: t,
            length,
            start,
            end,
            blends,
            stops,
            tolerance: self.machine.tolerance,
        })
    }
}

impl PlannedPath {
    /// How long the program takes \[s\], dwells included.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The path's length \[mm\] (after blending).
    pub fn length(&self) -> f64 {
        self.length
    }

    /// The program's canonical moves.
    pub fn moves(&self) -> &[Move] {
        &self.moves
    }

    /// The pieces of the path in order.
    pub fn pieces(&self) -> &[Placed] {
        &self.pieces
    }

    /// The blocks, each with its limits and speeds.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    /// The constant-jerk phases of the path speed.
    pub fn phases(&self) -> &[Phase] {
        &self.phases
    }

    /// Corners blended.
    pub fn blends(&self) -> usize {
        self.blends
    }

    /// Junctions where the path stops (unblended corners, reversals, dwells).
    pub fn stops(&self) -> usize {
        self.stops
    }

    /// The path tolerance it was planned with \[mm\].
    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// Where the path starts and ends \[mm\].
    pub fn ends(&self) -> (Vec3, Vec3) {
        (self.start, self.end)
    }

    /// (s, speed, acceleration, jerk) of the path at time `t` \[s\].
    fn feed_at(&self, t: f64) -> (f64, f64, f64, f64) {
        if t <= 0.0 || self.phases.is_empty() {
            return (0.0, 0.0, 0.0, 0.0);
        }
        let i = self.phases.partition_point(|p| p.t0 <= t).max(1) - 1;
        let p = &self.phases[i];
        let tau = t - p.t0;
        let s = p.s0 + tau * (p.v0 + tau * (0.5 * p.a0 + tau * p.j / 6.0));
        let v = p.v0 + tau * (p.a0 + 0.5 * tau * p.j);
        let a = p.a0 + tau * p.j;
        if i + 1 == self.phases.len() {
            // The last phase is the rest at the end.
            return (self.length, 0.0, 0.0, 0.0);
        }
        (s.clamp(0.0, self.length), v.max(0.0), a, p.j)
    }

    /// The piece at arc length `s`.
    pub fn piece_at(&self, s: f64) -> usize {
        self.pieces.partition_point(|p| p.s0 <= s).max(1) - 1
    }

    /// The planned path at time `t` \[s\] (at rest at the start before 0, at the end
    /// after [`PlannedPath::duration`]).
    pub fn at(&self, t: f64) -> PathState {
        let (s, speed, accel, jerk) = self.feed_at(t);
        if self.pieces.is_empty() {
            return PathState {
                s: 0.0,
                speed: 0.0,
                accel: 0.0,
                jerk: 0.0,
                p: self.end,
                v: Vec3::ZERO,
                a: Vec3::ZERO,
                j: Vec3::ZERO,
                piece: 0,
            };
        }
        let i = self.piece_at(s);
        let pc = &self.pieces[i];
        let f: Frame = pc.curve.frame(s - pc.s0);
        let [v, a, j] = f.motion(speed, accel, jerk);
        PathState {
            s,
            speed,
            accel,
            jerk,
            p: f.p,
            v,
            a,
            j,
            piece: i,
        }
    }

    /// The programmed move that piece `i` lies on.
    pub fn move_of(&self, piece: usize) -> Option<&Move> {
        self.pieces
            .get(piece)
            .and_then(|p| self.moves.get(p.mv as usize))
    }

    /// Whether move `m` of the program is a curve (a line or an arc, not a dwell).
    fn geometry(&self, m: usize) -> Option<Curve> {
        match self.moves.get(m).map(|m| &m.kind) {
            Some(MoveKind::Line(l)) => Some(Curve::Line(*l)),
            Some(MoveKind::Arc(h)) => Some(Curve::Arc(*h)),
            _ => None,
        }
    }

    /// The contour error of the tool at `q` when the reference is at arc length `s_ref`
    /// \[mm\]: the shortest distance from `q` to the programmed moves (the program's
    /// geometry, not the blended path) near the reference: the moves within
    /// 2·|q − p_ref| + tolerance + 1 mm of programmed length either side of the
    /// reference's move.
    pub fn contour_error(&self, q: Vec3, s_ref: f64) -> f64 {
        if self.pieces.is_empty() {
            return (q - self.end).norm();
        }
        let i = self.piece_at(s_ref);
        let pc = &self.pieces[i];
        let p_ref = pc.curve.frame(s_ref - pc.s0).p;
        let window = 2.0 * (q - p_ref).norm() + self.tolerance + 1.0;
        let m0 = pc.mv as usize;
        let mut best = f64::INFINITY;
        if let Some(c) = self.geometry(m0) {
            best = c.distance(q);
        }
        // Blends lie between their move and the next: look at both.
        for dir in [-1i64, 1] {
            let mut travelled = 0.0;
            let mut m = m0 as i64;
            loop {
                m += dir;
                if m < 0 || m as usize >= self.moves.len() || travelled > window {
                    break;
                }
                if let Some(c) = self.geometry(m as usize) {
                    best = best.min(c.distance(q));
                    travelled += c.len();
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests;
