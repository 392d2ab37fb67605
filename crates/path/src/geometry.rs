//! The curves a path is made of, each parametrised by its arc length s ∈ [0, len] \[mm\]:
//! straight lines, circular and helical arcs (evaluated exactly), and the quintic corner
//! blends. Each gives its point, unit tangent, curvature vector and the curvature
//! vector's derivative at any s (the [`Frame`] that turns path speed, acceleration and jerk
//! into axis setpoints), and lines and arcs the shortest distance from a point.

use std::f64::consts::TAU;

use crate::vec3::Vec3;

/// The local geometry of a curve at one arc length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// The point \[mm\].
    pub p: Vec3,
    /// Unit tangent dp/ds.
    pub t: Vec3,
    /// Curvature vector dt/ds = κ·N \[1/mm\].
    pub k: Vec3,
    /// Its derivative dk/ds \[1/mm²\].
    pub dk: Vec3,
}

impl Frame {
    /// The axis velocity, acceleration and jerk when the path moves through this point
    /// at speed `v` \[mm/s\], tangential acceleration `a` \[mm/s²\] and jerk `j` \[mm/s³\]:
    /// ṗ = t·v, p̈ = t·a + k·v², p⃛ = t·j + 3·k·v·a + k′·v³.
    pub fn motion(&self, v: f64, a: f64, j: f64) -> [Vec3; 3] {
        [
            self.t * v,
            self.t * a + self.k * (v * v),
            self.t * j + self.k * (3.0 * v * a) + self.dk * (v * v * v),
        ]
    }
}

/// A straight line from `p0` along the unit direction `dir` for `len` \[mm\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Start point \[mm\].
    pub p0: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// Length \[mm\].
    pub len: f64,
}

impl Line {
    /// The line from `a` to `b` (`None` when they coincide).
    pub fn between(a: Vec3, b: Vec3) -> Option<Line> {
        let d = b - a;
        let len = d.norm();
        (len > 0.0).then(|| Line {
            p0: a,
            dir: d * (1.0 / len),
            len,
        })
    }

    /// The point at arc length `s`.
    pub fn point(&self, s: f64) -> Vec3 {
        self.p0 + self.dir * s
    }

    /// The part from arc length `a` to `b`.
    pub fn sub(&self, a: f64, b: f64) -> Line {
        Line {
            p0: self.point(a),
            dir: self.dir,
            len: b - a,
        }
    }

    /// The shortest distance from `q` to the line segment \[mm\].
    pub fn distance(&self, q: Vec3) -> f64 {
        let s = (q - self.p0).dot(self.dir).clamp(0.0, self.len);
        (q - self.point(s)).norm()
    }
}

/// A circular arc (rise 0) or a helix: centre `c` (at the start's height along the
/// normal), in the plane spanned by the unit vectors `e1`, `e2` with normal n = e1 × e2;
/// angle φ from `phi0` over `sweep` \[rad\] (positive: counter-clockwise seen from +n),
/// rising `rise` \[mm\] along n over the whole arc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Helix {
    /// Centre, at the start's height along the normal \[mm\].
    pub c: Vec3,
    /// First in-plane axis (φ = 0).
    pub e1: Vec3,
    /// Second in-plane axis (φ = π/2).
    pub e2: Vec3,
    /// Radius \[mm\].
    pub r: f64,
    /// Start angle \[rad\].
    pub phi0: f64,
    /// Signed sweep \[rad\]: > 0 counter-clockwise about n.
    pub sweep: f64,
    /// Travel along the normal over the arc \[mm\].
    pub rise: f64,
    /// Arc length √((r·sweep)² + rise²) \[mm\].
    pub len: f64,
}

impl Helix {
    /// The arc of radius `r` about `c` from angle `phi0` over `sweep`, rising `rise`.
    pub fn new(c: Vec3, e1: Vec3, e2: Vec3, r: f64, phi0: f64, sweep: f64, rise: f64) -> Helix {
        Helix {
            c,
            e1,
            e2,
            r,
            phi0,
            sweep,
            rise,
            len: (r * sweep).hypot(rise),
        }
    }

    /// The normal n = e1 × e2.
    pub fn normal(&self) -> Vec3 {
        self.e1.cross(self.e2)
    }

    /// The point at angle `phi` (rising with the angle travelled from `phi0`).
    fn at_angle(&self, phi: f64) -> Vec3 {
        let (s, c) = phi.sin_cos();
        let h = if self.sweep == 0.0 {
            0.0
        } else {
            self.rise * (phi - self.phi0) / self.sweep
        };
        self.c + self.e1 * (self.r * c) + self.e2 * (self.r * s) + self.normal() * h
    }

    /// The frame at arc length `s`.
    pub fn frame(&self, s: f64) -> Frame {
        let u = if self.len > 0.0 { s / self.len } else { 0.0 };
        let k = self.sweep / self.len; // dφ/ds
        let h = self.rise / self.len; // d(height)/ds
        let phi = self.phi0 + self.sweep * u;
        let (sn, cs) = phi.sin_cos();
        let n = self.normal();
        let radial = self.e1 * cs + self.e2 * sn;
        let along = self.e2 * cs - self.e1 * sn;
        Frame {
            p: self.c + radial * self.r + n * (self.rise * u),
            t: along * (self.r * k) + n * h,
            k: radial * (-self.r * k * k),
            dk: along * (-self.r * k * k * k),
        }
    }

    /// The part from arc length `a` to `b`.
    pub fn sub(&self, a: f64, b: f64) -> Helix {
        let (ua, ub) = (a / self.len, b / self.len);
        let n = self.normal();
        Helix::new(
            self.c + n * (self.rise * ua),
            self.e1,
            self.e2,
            self.r,
            self.phi0 + self.sweep * ua,
            self.sweep * (ub - ua),
            self.rise * (ub - ua),
        )
    }

    /// The shortest distance from `q` to the arc \[mm\].
    pub fn distance(&self, q: Vec3) -> f64 {
        let d = q - self.c;
        let n = self.normal();
        let (x, y) = (d.dot(self.e1), d.dot(self.e2));
        let end = self.phi0 + self.sweep;
        let (lo, hi) = if self.sweep >= 0.0 {
            (self.phi0, end)
        } else {
            (end, self.phi0)
        };
        let ends = (q - self.at_angle(self.phi0))
            .norm()
            .min((q - self.at_angle(end)).norm());
        if x == 0.0 && y == 0.0 {
            // On the axis: every point of the arc at a height h is r·√(1 + …) away.
            let hq = d.dot(n);
            let h = hq.clamp(self.rise.min(0.0), self.rise.max(0.0));
            return ends.min(self.r.hypot(hq - h));
        }
        let phi_q = y.atan2(x);
        // Every angle lo ≤ φ ≤ hi at which q's direction is met, refined (for a helix)
        // by Newton's method on |p(φ) − q|².
        let first = phi_q + TAU * ((lo - phi_q) / TAU).ceil();
        let mut best = ends;
        let mut phi = first;
        while phi <= hi {
            let mut f = phi;
            if self.rise != 0.0 {
                let dh = self.rise / self.sweep; // height per radian
                for _ in 0..8 {
                    let (s, c) = f.sin_cos();
                    let p = self.at_angle(f) - q;
                    let dp = self.e2 * (self.r * c) - self.e1 * (self.r * s) + n * dh;
                    let ddp = (self.e1 * c + self.e2 * s) * (-self.r);
                    let g = p.dot(dp);
                    let gg = dp.dot(dp) + p.dot(ddp);
                    if gg <= 0.0 {
                        break;
                    }
                    f = (f - g / gg).clamp(lo, hi);
                }
            }
            best = best.min((q - self.at_angle(f)).norm());
            phi += TAU;
        }
        best
    }
}

/// The largest value of `f` between `lo` and `hi` by a golden-section search of `iters`
/// steps (for a function with one peak there, as near a sampled maximum).
pub(crate) fn golden_max(f: impl Fn(f64) -> f64, lo: f64, hi: f64, iters: u32) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (lo, hi);
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..iters {
        if f1 > f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    f1.max(f2)
}

/// Gauss-Legendre nodes and weights on \[−1, 1\], 8 points (the positive half).
const GL_X: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];
const GL_W: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

/// A quintic polynomial curve r(u) = Σ cₖ·uᵏ, u ∈ \[0, 1\], reparametrised by arc length: a
/// corner blend that meets its neighbours in point, tangent and curvature (G2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quintic {
    /// Coefficients c₀ … c₅ \[mm\].
    pub c: [Vec3; 6],
    /// Arc length \[mm\].
    pub len: f64,
    /// Arc length from 0 to u = i/[`QUINTIC_PANELS`], i = 0 … 8 \[mm\].
    knots: [f64; QUINTIC_PANELS + 1],
}

/// Panels of a quintic's arc-length table: the length to any u is a table entry plus one
/// 8-point Gauss-Legendre rule over part of a panel, accurate to rounding, so that the
/// path speed along a blend is the planned one to rounding (a coarser rule shows as a
/// step in speed where a blend meets its neighbour).
pub const QUINTIC_PANELS: usize = 8;

impl Quintic {
    /// The quintic Hermite curve with r(0) = p0, r′(0) = v0, r″(0) = a0, r(1) = p1,
    /// r′(1) = v1, r″(1) = a1.
    pub fn hermite(p0: Vec3, v0: Vec3, a0: Vec3, p1: Vec3, v1: Vec3, a1: Vec3) -> Quintic {
        Quintic::from_coefficients(Quintic::coefficients(p0, v0, a0, p1, v1, a1))
    }

    /// The coefficients c₀ … c₅ of [`Quintic::hermite`]'s curve (without measuring it).
    pub fn coefficients(p0: Vec3, v0: Vec3, a0: Vec3, p1: Vec3, v1: Vec3, a1: Vec3) -> [Vec3; 6] {
        let d = p1 - p0;
        [
            p0,
            v0,
            a0 * 0.5,
            d * 10.0 - v0 * 6.0 - v1 * 4.0 - (a0 * 3.0 - a1) * 0.5,
            d * -15.0 + v0 * 8.0 + v1 * 7.0 + (a0 * 3.0 - a1 * 2.0) * 0.5,
            d * 6.0 - v0 * 3.0 - v1 * 3.0 - (a0 - a1) * 0.5,
        ]
    }

    /// The curve of coefficients `c`, measured.
    pub fn from_coefficients(c: [Vec3; 6]) -> Quintic {
        let mut q = Quintic {
            c,
            len: 0.0,
            knots: [0.0; QUINTIC_PANELS + 1],
        };
        let w = 1.0 / QUINTIC_PANELS as f64;
        for i in 0..QUINTIC_PANELS {
            q.knots[i + 1] = q.knots[i] + q.gauss(i as f64 * w, (i + 1) as f64 * w);
        }
        q.len = q.knots[QUINTIC_PANELS];
        q
    }

    /// The point r(u) of the curve of coefficients `c`.
    pub fn point_of(c: &[Vec3; 6], u: f64) -> Vec3 {
        c[0] + (c[1] + (c[2] + (c[3] + (c[4] + c[5] * u) * u) * u) * u) * u
    }

    /// r(u) and its first three derivatives.
    pub fn derivs(&self, u: f64) -> [Vec3; 4] {
        let c = &self.c;
        let p = c[0] + (c[1] + (c[2] + (c[3] + (c[4] + c[5] * u) * u) * u) * u) * u;
        let d1 = c[1] + (c[2] * 2.0 + (c[3] * 3.0 + (c[4] * 4.0 + c[5] * (5.0 * u)) * u) * u) * u;
        let d2 = c[2] * 2.0 + (c[3] * 6.0 + (c[4] * 12.0 + c[5] * (20.0 * u)) * u) * u;
        let d3 = c[3] * 6.0 + (c[4] * 24.0 + c[5] * (60.0 * u)) * u;
        [p, d1, d2, d3]
    }

    /// |r′(u)| \[mm\].
    fn speed(&self, u: f64) -> f64 {
        let c = &self.c;
        (c[1] + (c[2] * 2.0 + (c[3] * 3.0 + (c[4] * 4.0 + c[5] * (5.0 * u)) * u) * u) * u).norm()
    }

    /// ∫ |r′| from `a` to `b` by the 8-point Gauss-Legendre rule.
    fn gauss(&self, a: f64, b: f64) -> f64 {
        let (mid, h) = (0.5 * (a + b), 0.5 * (b - a));
        let mut sum = 0.0;
        for (x, w) in GL_X.iter().zip(GL_W) {
            sum += w * (self.speed(mid - h * x) + self.speed(mid + h * x));
        }
        sum * h
    }

    /// Arc length from 0 to `u` \[mm\]: the table to the panel `u` is in, and the
    /// Gauss-Legendre rule over the rest.
    pub fn length_to(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        let i = ((u * QUINTIC_PANELS as f64) as usize).min(QUINTIC_PANELS - 1);
        let a = i as f64 / QUINTIC_PANELS as f64;
        self.knots[i] + self.gauss(a, u)
    }

    /// The parameter u at arc length `s` (Newton's method on the arc length).
    pub fn param(&self, s: f64) -> f64 {
        if s <= 0.0 {
            return 0.0;
        }
        if s >= self.len {
            return 1.0;
        }
        // The panel holding s, and a linear guess within it.
        let i = (self.knots.partition_point(|&k| k <= s).max(1) - 1).min(QUINTIC_PANELS - 1);
        let (k0, k1) = (self.knots[i], self.knots[i + 1]);
        let w = 1.0 / QUINTIC_PANELS as f64;
        let mut u = (i as f64 + if k1 > k0 { (s - k0) / (k1 - k0) } else { 0.0 }) * w;
        for _ in 0..30 {
            let f = self.length_to(u) - s;
            if f.abs() <= 1e-14 * self.len {
                break;
            }
            u = (u - f / self.speed(u)).clamp(0.0, 1.0);
        }
        u
    }

    /// The frame at parameter `u`.
    pub fn frame_at_param(&self, u: f64) -> Frame {
        let [p, a, b, c] = self.derivs(u);
        let sigma = a.norm();
        let t = a * (1.0 / sigma);
        let g = t.dot(b);
        let k = (b - t * g) * (1.0 / (sigma * sigma));
        let dk_du = (c - k * (sigma * g) - t * (sigma * k.dot(b) + t.dot(c)))
            * (1.0 / (sigma * sigma))
            - k * (2.0 * g / sigma);
        Frame {
            p,
            t,
            k,
            dk: dk_du * (1.0 / sigma),
        }
    }

    /// The frame at arc length `s`.
    pub fn frame(&self, s: f64) -> Frame {
        self.frame_at_param(self.param(s))
    }
}

/// One piece of a path.
#[derive(Debug, Clone, PartialEq)]
pub enum Curve {
    /// A straight line.
    Line(Line),
    /// A circular or helical arc.
    Arc(Helix),
    /// A corner blend (boxed: it is the largest).
    Blend(Box<Quintic>),
}

impl Curve {
    /// Arc length \[mm\].
    pub fn len(&self) -> f64 {
        match self {
            Curve::Line(l) => l.len,
            Curve::Arc(h) => h.len,
            Curve::Blend(q) => q.len,
        }
    }

    /// Whether the curve has no length.
    pub fn is_empty(&self) -> bool {
        self.len() <= 0.0
    }

    /// The frame at arc length `s` (clamped into \[0, len\]).
    pub fn frame(&self, s: f64) -> Frame {
        let s = s.clamp(0.0, self.len());
        match self {
            Curve::Line(l) => Frame {
                p: l.point(s),
                t: l.dir,
                k: Vec3::ZERO,
                dk: Vec3::ZERO,
            },
            Curve::Arc(h) => h.frame(s),
            Curve::Blend(q) => q.frame(s),
        }
    }

    /// A box holding the curve: (lowest, highest) of each coordinate \[mm\] (a blend's
    /// from 33 samples, a hair wider).
    pub fn extent(&self) -> (Vec3, Vec3) {
        match self {
            Curve::Line(l) => {
                let (a, b) = (l.p0, l.point(l.len));
                (a.min(b), a.max(b))
            }
            Curve::Arc(h) => {
                let (a, b) = (h.frame(0.0).p, h.frame(h.len).p);
                let n = h.normal();
                let r = (h.e1.abs() + h.e2.abs()) * h.r;
                let c0 = h.c;
                let c1 = h.c + n * h.rise;
                (
                    a.min(b).min(c0 - r).min(c1 - r),
                    a.max(b).max(c0 + r).max(c1 + r),
                )
            }
            Curve::Blend(q) => {
                let mut lo = q.c[0];
                let mut hi = q.c[0];
                for i in 1..=32 {
                    let p = Quintic::point_of(&q.c, f64::from(i) / 32.0);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                let pad = Vec3::new(1e-3, 1e-3, 1e-3) * (1.0 + q.len);
                (lo - pad, hi + pad)
            }
        }
    }

    /// The part from arc length `a` to `b` (lines and arcs only; a blend is whole).
    pub fn sub(&self, a: f64, b: f64) -> Curve {
        match self {
            Curve::Line(l) => Curve::Line(l.sub(a, b)),
            Curve::Arc(h) => Curve::Arc(h.sub(a, b)),
            Curve::Blend(q) => Curve::Blend(q.clone()),
        }
    }

    /// The shortest distance from `q` \[mm\] (a blend: from its 65 sample points, an upper
    /// bound used only in tests).
    pub fn distance(&self, q: Vec3) -> f64 {
        match self {
            Curve::Line(l) => l.distance(q),
            Curve::Arc(h) => h.distance(q),
            Curve::Blend(b) => (0..=64)
                .map(|i| (b.derivs(f64::from(i) / 64.0)[0] - q).norm())
                .fold(f64::INFINITY, f64::min),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
        (a - b).norm() <= tol
    }

    /// A frame's tangent, curvature and its derivative are the derivatives of its point
    /// (central differences), for a helix and a quintic.
    #[test]
    fn frames_are_the_derivatives_of_the_point() {
        let h = Helix::new(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::axis(0),
            Vec3::axis(1),
            5.0,
            0.3,
            -4.0,
            2.5,
        );
        let q = Quintic::hermite(
            Vec3::ZERO,
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(2.0, 2.0, 1.0),
            Vec3::new(0.0, 3.0, 0.5),
            Vec3::new(-0.4, 0.0, 0.0),
        );
        for c in [Curve::Arc(h), Curve::Blend(Box::new(q))] {
            let len = c.len();
            for i in 1..10 {
                let s = len * f64::from(i) / 10.0;
                let e = 1e-4;
                let (f, a, b) = (c.frame(s), c.frame(s - e), c.frame(s + e));
                assert!(close(f.t, (b.p - a.p) * (0.5 / e), 1e-6), "{c:?} t at {s}");
                assert!((f.t.norm() - 1.0).abs() < 1e-9);
                assert!(close(f.k, (b.t - a.t) * (0.5 / e), 1e-6), "{c:?} k at {s}");
                assert!(
                    close(f.dk, (b.k - a.k) * (0.5 / e), 1e-5),
                    "{c:?} dk at {s}"
                );
            }
        }
    }

    /// The quintic meets its Hermite data, and its arc length is that of a dense chord sum.
    #[test]
    fn quintic_hermite_data_and_length() {
        let (p0, v0, a0) = (
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let (p1, v1, a1) = (
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(-1.0, 0.0, 0.0),
        );
        let q = Quintic::hermite(p0, v0, a0, p1, v1, a1);
        let [p, d1, d2, _] = q.derivs(0.0);
        assert!(close(p, p0, 1e-12) && close(d1, v0, 1e-12) && close(d2, a0, 1e-12));
        let [p, d1, d2, _] = q.derivs(1.0);
        assert!(close(p, p1, 1e-12) && close(d1, v1, 1e-12) && close(d2, a1, 1e-12));
        let n = 200_000;
        let chords: f64 = (0..n)
            .map(|i| {
                let (a, b) = (f64::from(i) / f64::from(n), f64::from(i + 1) / f64::from(n));
                (q.derivs(b)[0] - q.derivs(a)[0]).norm()
            })
            .sum();
        assert!((chords - q.len).abs() < 1e-9, "{chords} {}", q.len);
        for s in [0.1, 0.5, 1.3, q.len - 1e-3] {
            assert!((q.length_to(q.param(s)) - s).abs() < 1e-12);
        }
    }

    /// The distance to an arc against a dense sampling of it, from points all round.
    #[test]
    fn distance_to_arcs_and_helices() {
        for (sweep, rise) in [
            (2.0, 0.0),
            (-5.0, 0.0),
            (TAU, 0.0),
            (-9.0, 3.0),
            (1.0, -0.5),
        ] {
            let h = Helix::new(
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::axis(1),
                Vec3::axis(2),
                2.0,
                0.7,
                sweep,
                rise,
            );
            for i in 0..60 {
                let f = f64::from(i);
                let q = Vec3::new(
                    (f * 0.37).sin() * 1.5,
                    (f * 1.3).cos() * 3.0,
                    (f * 0.7).sin() * 2.5,
                );
                let dense = (0..=40_000)
                    .map(|k| (h.frame(h.len * f64::from(k) / 40_000.0).p - q).norm())
                    .fold(f64::INFINITY, f64::min);
                let d = h.distance(q);
                assert!(
                    d <= dense + 1e-9 && d >= dense - 1e-3,
                    "{sweep} {rise} {q:?}: {d} {dense}"
                );
            }
        }
    }
}
