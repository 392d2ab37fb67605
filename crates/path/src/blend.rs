//! Corner blending: a program's moves become the pieces of the path the machine follows.
//! Where two moves meet with a jump in tangent or curvature (a corner, or a line running
//! tangentially into an arc), both are cut back by the same arc length d and a quintic
//! joins the cut points, meeting each neighbour in point, tangent and curvature (G2). d is
//! the largest that keeps every point of the blend within 90 % of `path_tolerance` of the
//! programmed moves, and takes at most half of either move, so that two blends never
//! overlap. What cannot be blended stops the path: a tolerance of 0 (exact stop, as G61),
//! a reversal (tangents more than 179° apart), a dwell. Runs of short lines, whose blends
//! meet with no line left between them, are smoothed where they meet
//! (a least-squares fit of the meeting points; see `smooth_chains`).

use crate::geometry::{Curve, Frame, Quintic, golden_max};
use crate::program::{Move, MoveKind};
use crate::vec3::Vec3;

/// Corners sharper than this \[rad\] (179°) are not blended: the path stops there.
pub const MAX_BLEND_ANGLE: f64 = 179.0 * std::f64::consts::PI / 180.0;

/// A blend may take at most this share of a move's length at either end.
pub const MAX_SHARE: f64 = 0.5;

/// The blend keeps within this share of the path tolerance (the rest is the margin for
/// what its samples do not see).
pub const TOLERANCE_SHARE: f64 = 0.9;

/// Pieces shorter than this \[mm\] are dropped.
pub const MIN_PIECE: f64 = 1e-9;

/// Points of a blend at which its deviation from the program is measured.
const DEVIATION_SAMPLES: u32 = 32;

/// How a piece joins the one before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    /// Continuously in point, tangent and curvature: the feed runs on.
    Smooth,
    /// At rest (the first piece, an unblended corner, a reversal).
    Stop,
    /// At rest after a dwell of this long \[s\].
    Dwell(f64),
}

/// One piece of the path: part of a programmed move, or a corner blend.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// Its geometry.
    pub curve: Curve,
    /// Programmed feed \[mm/s\] (∞ for a rapid; a blend: the lower of its two moves').
    pub feed: f64,
    /// The programmed move it lies on (index into the program's moves); for a blend, the
    /// move before the corner.
    pub mv: u32,
    /// How it joins the piece before.
    pub start: Start,
}

/// A program's path: its pieces, and a dwell after the last one.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Blended {
    /// The pieces in order.
    pub pieces: Vec<Piece>,
    /// Dwell after the last piece (or the whole program's, without motion) \[s\].
    pub end_dwell: f64,
    /// Corners blended.
    pub blends: usize,
    /// Junctions where the path stops (not counting the start).
    pub stops: usize,
}

/// The move being carried forward: what is left of it, and how long it was.
struct Pending {
    curve: Curve,
    original: Curve,
    feed: f64,
    mv: u32,
    start: Start,
}

/// Blends the corners of `moves` within `tolerance` \[mm\] (0: no blending, the path
/// stops at every corner).
///
/// ```
/// use ringsync_path::{blend::{blend, Start}, program::interpret};
/// let p = interpret("G1 X10 F600\nY10\n", [true, true, false]).unwrap();
/// let b = blend(&p.moves, 0.01);
/// assert_eq!((b.pieces.len(), b.blends, b.stops), (3, 1, 0));
/// assert_eq!(b.pieces[1].start, Start::Smooth);
/// assert_eq!(blend(&p.moves, 0.0).stops, 1);
/// ```
pub fn blend(moves: &[Move], tolerance: f64) -> Blended {
    let mut out = Blended::default();
    let mut pending: Option<Pending> = None;
    let mut next_start = Start::Stop;
    for (i, m) in moves.iter().enumerate() {
        let curve = match &m.kind {
            MoveKind::Dwell(d) => {
                if let Some(p) = pending.take() {
                    push(&mut out, p);
                }
                next_start = match next_start {
                    Start::Dwell(e) => Start::Dwell(e + d),
                    _ => Start::Dwell(*d),
                };
                continue;
            }
            MoveKind::Line(l) => Curve::Line(*l),
            MoveKind::Arc(h) => Curve::Arc(*h),
        };
        if curve.len() < MIN_PIECE {
            continue;
        }
        let mv = i as u32;
        let Some(mut prev) = pending.take() else {
            pending = Some(Pending {
                original: curve.clone(),
                curve,
                feed: m.feed,
                mv,
                start: next_start,
            });
            next_start = Start::Stop;
            continue;
        };
        let a = prev.curve.frame(prev.curve.len());
        let b = curve.frame(0.0);
        if is_g2(&a, &b) {
            push(&mut out, prev);
            pending = Some(Pending {
                original: curve.clone(),
                curve,
                feed: m.feed,
                mv,
                start: Start::Smooth,
            });
            continue;
        }
        let angle = a.t.dot(b.t).clamp(-1.0, 1.0).acos();
        let corner = if tolerance > 0.0 && angle <= MAX_BLEND_ANGLE {
            corner_blend(&prev, &curve, tolerance)
        } else {
            None
        };
        match corner {
            Some((d1, d, q)) => {
                let keep = prev.curve.len() - d1;
                prev.curve = prev.curve.sub(0.0, keep);
                let feed = prev.feed.min(m.feed);
                let before = prev.mv;
                push(&mut out, prev);
                out.pieces.push(Piece {
                    curve: Curve::Blend(Box::new(q)),
                    feed,
                    mv: before,
                    start: Start::Smooth,
                });
                out.blends += 1;
                pending = Some(Pending {
                    curve: curve.sub(d, curve.len()),
                    original: curve,
                    feed: m.feed,
                    mv,
                    start: Start::Smooth,
                });
            }
            None => {
                push(&mut out, prev);
                out.stops += 1;
                pending = Some(Pending {
                    original: curve.clone(),
                    curve,
                    feed: m.feed,
                    mv,
                    start: Start::Stop,
                });
            }
        }
    }
    if let Some(p) = pending.take() {
        push(&mut out, p);
    }
    if let Start::Dwell(d) = next_start {
        out.end_dwell = d;
    }
    smooth_chains(&mut out, moves, tolerance);
    out
}

/// The curve a programmed move is (`None` for a dwell).
fn move_curve(m: &Move) -> Option<Curve> {
    match &m.kind {
        MoveKind::Line(l) => Some(Curve::Line(*l)),
        MoveKind::Arc(h) => Some(Curve::Arc(*h)),
        MoveKind::Dwell(_) => None,
    }
}

/// Meeting points on each side that the circle through a meeting point spans (of a run of
/// short lines: what smooths their coordinates' rounding).
pub const SMOOTHING_SPAN: usize = 4;

/// A local least-squares fit (Savitzky-Golay) through `pts`, each coordinate a quadratic in
/// the chord length from the middle point: at the middle, the fitted point, its unit
/// tangent and its curvature vector \[1/mm\]. `pts` has an odd number (≥ 3) of points.
fn fit_at(pts: &[Vec3]) -> (Vec3, Vec3, Vec3) {
    let mid = pts.len() / 2;
    // Chord length from the middle, signed.
    let mut s = vec![0.0; pts.len()];
    for k in (0..mid).rev() {
        s[k] = s[k + 1] - (pts[k + 1] - pts[k]).norm();
    }
    for k in mid + 1..pts.len() {
        s[k] = s[k - 1] + (pts[k] - pts[k - 1]).norm();
    }
    // Normal equations of a + b·s + c·s² (3 × 3), by Cramer's rule.
    let (mut m0, mut m1, mut m2, mut m3, mut m4) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut r0, mut r1, mut r2) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    for (p, &x) in pts.iter().zip(&s) {
        let q = *p - pts[mid];
        m0 += 1.0;
        m1 += x;
        m2 += x * x;
        m3 += x * x * x;
        m4 += x * x * x * x;
        r0 += q;
        r1 += q * x;
        r2 += q * (x * x);
    }
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let m = [[m0, m1, m2], [m1, m2, m3], [m2, m3, m4]];
    let d = det3(m);
    let chord = (pts[pts.len() - 1] - pts[0]).unit();
    if d.abs() <= 1e-300 {
        return (pts[mid], chord, Vec3::ZERO);
    }
    let mut coef = [Vec3::ZERO; 3];
    for axis in 0..3 {
        let rhs = [r0[axis], r1[axis], r2[axis]];
        for (k, c) in coef.iter_mut().enumerate() {
            let mut a = m;
            for (row, v) in a.iter_mut().zip(rhs) {
                row[k] = v;
            }
            c[axis] = det3(a) / d;
        }
    }
    let (p, v, acc) = (pts[mid] + coef[0], coef[1], coef[2] * 2.0);
    let speed = v.norm();
    if speed <= 0.0 {
        return (pts[mid], chord, Vec3::ZERO);
    }
    let t = v * (1.0 / speed);
    let k = (acc - t * t.dot(acc)) * (1.0 / (speed * speed));
    (p, t, k)
}

/// Runs of short lines (CAM output of a curve) whose blends meet with no line left between
/// them. Made corner by corner, each blend meets the next on a line with the line's
/// direction and curvature 0, so along the run the curvature falls to 0 and rises again at
/// every segment, and its rate of change, which costs jerk, bounds the feed; and the
/// coordinates' rounding (10⁻⁴ mm on a 0.1 mm segment) makes every corner's turn noisy.
/// Here each meeting point takes the place, tangent and curvature of a least-squares fit
/// through it and the meeting points [`SMOOTHING_SPAN`] either side, and the blends are made
/// again between those: along the run the curvature then changes as the program's curve
/// does, the rounding smoothed away (the meeting points move by about the rounding, far
/// inside the tolerance, which every blend is checked against again). A blend that would leave the tolerance goes back to its
/// neighbours' own directions and curvature 0 at its ends (and those neighbours with it).
fn smooth_chains(out: &mut Blended, moves: &[Move], tolerance: f64) {
    let pieces = &mut out.pieces;
    let n = pieces.len();
    // Meeting points: i such that pieces i and i + 1 are blends joined smoothly on a line.
    let meets: Vec<bool> = (0..n.saturating_sub(1))
        .map(|i| {
            matches!(pieces[i].curve, Curve::Blend(_))
                && matches!(pieces[i + 1].curve, Curve::Blend(_))
                && pieces[i + 1].start == Start::Smooth
                && matches!(
                    moves.get(pieces[i + 1].mv as usize).map(|m| &m.kind),
                    Some(MoveKind::Line(_))
                )
        })
        .collect();
    if !meets.iter().any(|m| *m) {
        return;
    }
    let end_point = |i: usize| pieces[i].curve.frame(pieces[i].curve.len()).p;
    // Each meeting point's new frame: (point, tangent, curvature).
    let mut frame_at: Vec<Option<(Vec3, Vec3, Vec3)>> = vec![None; meets.len()];
    for i in 0..meets.len() {
        if !meets[i] {
            continue;
        }
        let left = (1..=SMOOTHING_SPAN)
            .take_while(|&k| i >= k && meets[i - k])
            .count();
        let right = (1..=SMOOTHING_SPAN)
            .take_while(|&k| i + k < meets.len() && meets[i + k])
            .count();
        let m = left.min(right);
        if m == 0 {
            continue;
        }
        let pts: Vec<Vec3> = (i - m..=i + m).map(end_point).collect();
        frame_at[i] = Some(fit_at(&pts));
    }
    // The corner each blend replaces: its move and the next move with a length.
    let corner = |i: usize| -> Option<(Curve, Curve)> {
        let mv = pieces[i].mv as usize;
        let a = move_curve(moves.get(mv)?)?;
        let b = moves[mv + 1..]
            .iter()
            .filter_map(move_curve)
            .find(|c| c.len() >= MIN_PIECE)?;
        Some((a, b))
    };
    let target = TOLERANCE_SHARE * tolerance;
    let mut made: Vec<Option<Quintic>> = vec![None; n];
    loop {
        let mut changed = false;
        for i in 0..n {
            let Curve::Blend(q) = &pieces[i].curve else {
                continue;
            };
            let before = i.checked_sub(1).and_then(|j| frame_at[j]);
            let after = frame_at.get(i).copied().flatten();
            if before.is_none() && after.is_none() {
                made[i] = None;
                continue;
            }
            let (f0, f1) = (q.frame_at_param(0.0), q.frame_at_param(1.0));
            let (p0, t0, k0) = before.unwrap_or((f0.p, f0.t, f0.k));
            let (p1, t1, k1) = after.unwrap_or((f1.p, f1.t, f1.k));
            // Between two fitted frames the chord is the arc's length to second order;
            // next to a corner the corner's tangent magnitude stays.
            let lambda = if before.is_some() && after.is_some() {
                (p1 - p0).norm()
            } else {
                q.c[1].norm()
            };
            let c = Quintic::coefficients(
                p0,
                t0 * lambda,
                k0 * (lambda * lambda),
                p1,
                t1 * lambda,
                k1 * (lambda * lambda),
            );
            let ok = corner(i).is_some_and(|(a, b)| deviation(&c, &a, &b) <= target);
            if ok {
                made[i] = Some(Quintic::from_coefficients(c));
            } else {
                // Back to the segments' own frames where this blend meets its neighbours.
                if i > 0 && frame_at[i - 1].take().is_some() {
                    changed = true;
                }
                if i < frame_at.len() && frame_at[i].take().is_some() {
                    changed = true;
                }
                made[i] = None;
            }
        }
        if !changed {
            break;
        }
    }
    for (p, m) in pieces.iter_mut().zip(made) {
        if let Some(q) = m {
            p.curve = Curve::Blend(Box::new(q));
        }
    }
}

/// Adds what is left of a move (nothing when a blend took it all; the next piece then
/// starts where it would have).
fn push(out: &mut Blended, p: Pending) {
    if p.curve.len() >= MIN_PIECE {
        out.pieces.push(Piece {
            curve: p.curve,
            feed: p.feed,
            mv: p.mv,
            start: p.start,
        });
    }
}

/// Whether two frames meet in tangent and curvature (to rounding).
fn is_g2(a: &Frame, b: &Frame) -> bool {
    let scale = 1.0 + a.k.norm().max(b.k.norm());
    (a.t - b.t).norm() <= 1e-9 && (a.k - b.k).norm() <= 1e-9 * scale
}

/// The quintic joining `a` (the end of the piece before the corner) and `b` (the start of
/// the one after), cut back by `d` each.
fn quintic(prev: &Curve, next: &Curve, d1: f64, d2: f64) -> [Vec3; 6] {
    let fa = prev.frame(prev.len() - d1);
    let fb = next.frame(d2);
    // Tangent magnitude 1.25·(d1 + d2): for two lines cut back equally, the quintic Bézier
    // with its middle control points on the corner (curvature 0 at both ends, inside the
    // corner's hull).
    let lambda = 1.25 * (d1 + d2);
    Quintic::coefficients(
        fa.p,
        fa.t * lambda,
        fa.k * (lambda * lambda),
        fb.p,
        fb.t * lambda,
        fb.k * (lambda * lambda),
    )
}

/// The largest distance from the blend to the two programmed moves it replaces \[mm\]:
/// sampled, then the largest sample's neighbourhood searched (where the nearer move
/// changes, the distance has a kink that samples straddle).
fn deviation(c: &[Vec3; 6], a: &Curve, b: &Curve) -> f64 {
    let dev = |u: f64| {
        let p = Quintic::point_of(c, u);
        a.distance(p).min(b.distance(p))
    };
    let n = f64::from(DEVIATION_SAMPLES);
    let (mut best, mut at) = (0.0, 0.0);
    for i in 1..DEVIATION_SAMPLES {
        let u = f64::from(i) / n;
        let d = dev(u);
        if d > best {
            (best, at) = (d, u);
        }
    }
    // The largest value between the neighbouring samples.
    let (lo, hi) = ((at - 1.0 / n).max(0.0), (at + 1.0 / n).min(1.0));
    best.max(golden_max(dev, lo, hi, 24))
}

/// What is left of a move shorter than this share of it is taken into the blend before it
/// rather than kept as a sliver of line (which would bring the curvature back to 0 between
/// two blends).
pub const SLIVER_SHARE: f64 = 0.05;

/// The blend of the corner between `prev` (what is left of the move before) and `next`
/// within `tolerance`: (the cut back into `prev`, into `next`, the quintic), or `None` when
/// no cut back of at least [`MIN_PIECE`] keeps within it. The cuts are equal, but that
/// the one into `prev` takes all of it when less than [`SLIVER_SHARE`] would be left.
fn corner_blend(prev: &Pending, next: &Curve, tolerance: f64) -> Option<(f64, f64, Quintic)> {
    let d_max = (MAX_SHARE * prev.original.len())
        .min(prev.curve.len())
        .min(MAX_SHARE * next.len());
    let target = TOLERANCE_SHARE * tolerance;
    let mut d = d_max;
    for _ in 0..40 {
        if d < MIN_PIECE {
            return None;
        }
        let left = prev.curve.len() - d;
        let d1 = if left < SLIVER_SHARE * prev.original.len() {
            prev.curve.len()
        } else {
            d
        };
        let c = quintic(&prev.curve, next, d1, d);
        let dev = deviation(&c, &prev.original, next);
        if dev <= target {
            return Some((d1, d, Quintic::from_coefficients(c)));
        }
        // A corner's deviation grows as d, a curvature jump's as d²: aim a little inside.
        d *= (0.97 * target / dev).clamp(0.05, 0.97);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::interpret;

    const XYZ: [bool; 3] = [true, true, true];

    /// The pieces join in point, tangent and curvature wherever they start smoothly, and
    /// every blend stays within the tolerance of the moves it replaces.
    #[test]
    fn blends_are_g2_and_within_tolerance() {
        let text = "G1 X10 F600\nY10\nG3 X0 Y20 R10\nG2 X-10 Y10 I0 J-10\nG1 X-10 Y0 Z3\nX0 Y0\nG4 P0.5\nG1 X5\nX0\n";
        let p = interpret(text, XYZ).expect("valid");
        for tol in [0.001, 0.01, 0.5] {
            let b = blend(&p.moves, tol);
            assert!(b.blends >= 4, "{tol}: {} blends", b.blends);
            for w in b.pieces.windows(2) {
                let (a, c) = (w[0].curve.frame(w[0].curve.len()), w[1].curve.frame(0.0));
                match w[1].start {
                    Start::Smooth => {
                        assert!((a.p - c.p).norm() < 1e-9, "{tol}: {:?} {:?}", a.p, c.p);
                        assert!((a.t - c.t).norm() < 1e-7);
                        assert!((a.k - c.k).norm() < 1e-6 * (1.0 + a.k.norm()));
                    }
                    _ => assert!((a.p - c.p).norm() < 1e-9),
                }
            }
            for pc in &b.pieces {
                if let Curve::Blend(q) = &pc.curve {
                    for i in 0..=200 {
                        let pt = q.derivs(f64::from(i) / 200.0)[0];
                        let d = p
                            .moves
                            .iter()
                            .filter_map(|m| match &m.kind {
                                MoveKind::Line(l) => Some(l.distance(pt)),
                                MoveKind::Arc(h) => Some(h.distance(pt)),
                                MoveKind::Dwell(_) => None,
                            })
                            .fold(f64::INFINITY, f64::min);
                        assert!(d <= tol, "{tol}: a blend point {d} mm off the program");
                    }
                }
            }
            // The dwell and the reversal stop the path.
            assert!(b.pieces.iter().any(|p| p.start == Start::Dwell(0.5)));
            assert!(b.stops >= 1, "the reversal X5 → X0");
        }
    }

    /// A full circle entered along a tangent line: the curvature jumps, so it is blended.
    #[test]
    fn curvature_jumps_are_blended_and_collinear_lines_are_not() {
        let p = interpret("G1 X50 F600\nG3 I-50\nG1 X60\nX70\n", XYZ).expect("valid");
        let b = blend(&p.moves, 0.01);
        assert_eq!(
            b.blends, 2,
            "line → arc and arc → line; the collinear lines join as they are"
        );
        assert_eq!(b.stops, 0);
        let total: f64 = b.pieces.iter().map(|p| p.curve.len()).sum();
        let programmed: f64 = p.moves.iter().map(Move::len).sum();
        assert!(
            total < programmed && total > programmed - 1.0,
            "{total} {programmed}"
        );
    }

    /// A circle of R = 5 mm written as 0.1 mm lines rounded to 10⁻⁴ mm (as CAM writes
    /// it): along the run the blends' curvature stays near 1/R and changes slowly, the
    /// rounding smoothed away, every blend within the tolerance and G2 at its ends.
    #[test]
    fn a_run_of_short_lines_becomes_a_smooth_curve() {
        use std::fmt::Write as _;
        let r = 5.0;
        let n = 300; // 0.1 mm steps
        let mut text = String::from("G1 X5 Y0 F3000\n");
        for k in 1..=n {
            let a = f64::from(k) * 0.1 / r;
            let _ = writeln!(text, "X{:.4} Y{:.4}", r * a.cos(), r * a.sin());
        }
        let p = interpret(&text, XYZ).expect("valid");
        let b = blend(&p.moves, 0.01);
        let (mut kmin, mut kmax, mut dkmax) = (f64::INFINITY, 0.0f64, 0.0f64);
        // The middle of the run (away from its ends, where it meets the lead-in line).
        for pc in &b.pieces[60..b.pieces.len() - 60] {
            let Curve::Blend(q) = &pc.curve else {
                panic!("a line left in the run: {:?}", pc.curve);
            };
            for i in 0..=16 {
                let f = q.frame_at_param(f64::from(i) / 16.0);
                kmin = kmin.min(f.k.norm());
                kmax = kmax.max(f.k.norm());
                dkmax = dkmax.max(f.dk.norm());
            }
        }
        assert!(
            kmin > 0.9 / r && kmax < 1.1 / r,
            "curvature {kmin} .. {kmax}, 1/R = {}",
            1.0 / r
        );
        // Corner by corner (without the smoothing) the curvature fell to 0 at every
        // segment and peaked at 0.66 /mm between: |dκ/ds| of tens /mm². Here 0.69 is what
        // the rounding leaves (10⁻⁴ mm on 0.1 mm).
        assert!(dkmax < 1.0, "|dκ/ds| up to {dkmax} /mm²");
        for w in b.pieces.windows(2) {
            let (a, c) = (w[0].curve.frame(w[0].curve.len()), w[1].curve.frame(0.0));
            assert!((a.p - c.p).norm() < 1e-9 && (a.t - c.t).norm() < 1e-7);
            assert!((a.k - c.k).norm() < 1e-6 * (1.0 + a.k.norm()));
        }
    }
}
