//! Corner blending: a program's moves become the pieces of the path the machine follows.
//! Where two moves meet with a jump in tangent or curvature (a corner, or a line running
//! tangentially into an arc), both are cut back by the same arc length d and a quintic
//! joins the cut points, meeting each neighbour in point, tangent and curvature (G2). d is
//! the largest that keeps every point of the blend within 90 % of `path_tolerance` of the
//! programmed moves, and takes at most half of either move, so that two blends never
//! overlap. What cannot be blended stops the path: a tolerance of 0 (exact stop, as G61),
//! a reversal (tangents more than 179° apart), a dwell.

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
            Some((d, q)) => {
                let keep = prev.curve.len() - d;
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
    out
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
fn quintic(prev: &Curve, next: &Curve, d: f64) -> [Vec3; 6] {
    let fa = prev.frame(prev.len() - d);
    let fb = next.frame(d);
    // Tangent magnitude 1.25·(d + d): for two lines, the quintic Bézier with its middle
    // control points on the corner (curvature 0 at both ends, inside the corner's hull).
    let lambda = 2.5 * d;
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

/// The blend of the corner between `prev` (what is left of the move before) and `next`
/// within `tolerance`: (d, the quintic), or `None` when no cut back of at least
/// [`MIN_PIECE`] keeps within it.
fn corner_blend(prev: &Pending, next: &Curve, tolerance: f64) -> Option<(f64, Quintic)> {
    let d_max = (MAX_SHARE * prev.original.len())
        .min(prev.curve.len())
        .min(MAX_SHARE * next.len());
    let target = TOLERANCE_SHARE * tolerance;
    let mut d = d_max;
    for _ in 0..40 {
        if d < MIN_PIECE {
            return None;
        }
        let c = quintic(&prev.curve, next, d);
        let dev = deviation(&c, &prev.original, next);
        if dev <= target {
            return Some((d, Quintic::from_coefficients(c)));
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
}
