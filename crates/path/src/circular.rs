//! The circular test of ISO 230-4 (its Annex E: from the machine's own feedback) on the
//! samples taken while the path ran a programmed full circle: the mean radius against the
//! programmed one, the radial deviation F about the programmed centre (its least and largest
//! value), and the circular deviation G, the radial width of the band about the
//! least-squares circle's centre that holds every sample.

use crate::geometry::Helix;

/// A programmed full circle the test is run on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// The programmed move (index into the program's moves).
    pub mv: usize,
    /// The two coordinates of its plane (0 = X, 1 = Y, 2 = Z), in the plane's order (G17:
    /// X, Y).
    pub plane: [usize; 2],
    /// Programmed centre in those coordinates \[mm\].
    pub centre: [f64; 2],
    /// Programmed radius \[mm\].
    pub radius: f64,
    /// Counter-clockwise (G3) or clockwise (G2), seen from the plane's normal.
    pub ccw: bool,
}

impl Circle {
    /// The circle of a move, when it is a full turn (or more) in a plane, without rise.
    pub fn of(mv: usize, h: &Helix) -> Option<Circle> {
        if h.rise != 0.0 || h.sweep.abs() < std::f64::consts::TAU * (1.0 - 1e-9) {
            return None;
        }
        let axis = |e: crate::vec3::Vec3| (0..3).find(|&i| e[i].abs() == 1.0);
        let (a, b) = (axis(h.e1)?, axis(h.e2)?);
        Some(Circle {
            mv,
            plane: [a, b],
            centre: [h.c[a], h.c[b]],
            radius: h.r,
            ccw: h.sweep > 0.0,
        })
    }
}

/// What the test found.
#[derive(Debug, Clone, PartialEq)]
pub struct CircularTest {
    /// The circle.
    pub circle: Circle,
    /// Samples on it.
    pub samples: usize,
    /// Mean distance of the samples from the programmed centre \[mm\].
    pub mean_radius: f64,
    /// Least radial deviation F_min = min(r − R) about the programmed centre \[mm\].
    pub radial_min: f64,
    /// Largest radial deviation F_max = max(r − R) \[mm\].
    pub radial_max: f64,
    /// Circular deviation G: max − min of the radius about the least-squares centre \[mm\].
    pub circular_deviation: f64,
    /// The least-squares circle's centre \[mm\].
    pub lsq_centre: [f64; 2],
    /// The least-squares circle's radius \[mm\].
    pub lsq_radius: f64,
    /// (angle about the programmed centre \[rad\], r − R \[mm\]) at up to 720 samples
    /// evenly spread through the run, for a polar plot.
    pub profile: Vec<(f64, f64)>,
}

/// The test on `points` (coordinates of the circle's plane \[mm\]); `None` with fewer than
/// 3 points or a degenerate fit.
pub fn circular_test(circle: Circle, points: &[[f64; 2]]) -> Option<CircularTest> {
    if points.len() < 3 {
        return None;
    }
    let [cx, cy] = circle.centre;
    let r = |p: &[f64; 2], c: [f64; 2]| (p[0] - c[0]).hypot(p[1] - c[1]);
    let n = points.len() as f64;
    let radii: Vec<f64> = points.iter().map(|p| r(p, circle.centre)).collect();
    let mean_radius = radii.iter().sum::<f64>() / n;
    let (lo, hi) = radii
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
    // Least squares (Kåsa): x² + y² + D·x + E·y + F = 0 in coordinates about the programmed
    // centre (well conditioned), normal equations by Cramer's rule.
    let (mut sxx, mut sxy, mut syy, mut sx, mut sy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut sxz, mut syz, mut sz) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = (p[0] - cx, p[1] - cy);
        let z = x * x + y * y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sx += x;
        sy += y;
        sxz += x * z;
        syz += y * z;
        sz += z;
    }
    let m = [[sxx, sxy, sx], [sxy, syy, sy], [sx, sy, n]];
    let rhs = [-sxz, -syz, -sz];
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-300 || !d.is_finite() {
        return None;
    }
    let col = |k: usize| {
        let mut a = m;
        for (row, v) in a.iter_mut().zip(rhs) {
            row[k] = v;
        }
        det(a) / d
    };
    let (dd, ee, ff) = (col(0), col(1), col(2));
    let lsq_centre = [cx - dd / 2.0, cy - ee / 2.0];
    let lsq_radius = (dd * dd / 4.0 + ee * ee / 4.0 - ff).max(0.0).sqrt();
    let (glo, ghi) = points
        .iter()
        .map(|p| r(p, lsq_centre))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(x), h.max(x))
        });
    let step = points.len().div_ceil(720).max(1);
    let profile = points
        .iter()
        .zip(&radii)
        .step_by(step)
        .map(|(p, rr)| ((p[1] - cy).atan2(p[0] - cx), rr - circle.radius))
        .collect();
    Some(CircularTest {
        circle,
        samples: points.len(),
        mean_radius,
        radial_min: lo - circle.radius,
        radial_max: hi - circle.radius,
        circular_deviation: ghi - glo,
        lsq_centre,
        lsq_radius,
        profile,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ellipse of half-axes R + d and R − d about a centre moved by (u, v): the mean
    /// radius is R (to second order), F spans ±d plus the offset's share, and the
    /// least-squares centre finds the offset.
    #[test]
    fn an_offset_ellipse_is_measured() {
        let c = Circle {
            mv: 0,
            plane: [0, 1],
            centre: [10.0, -5.0],
            radius: 50.0,
            ccw: true,
        };
        let (d, u, v) = (0.01, 0.002, -0.003);
        let pts: Vec<[f64; 2]> = (0..3600)
            .map(|k| {
                let th = f64::from(k) * std::f64::consts::TAU / 3600.0;
                // Major axis at 45°.
                let rr = 50.0 + d * (2.0 * (th - std::f64::consts::FRAC_PI_4)).cos();
                [10.0 + u + rr * th.cos(), -5.0 + v + rr * th.sin()]
            })
            .collect();
        let t = circular_test(c, &pts).expect("test");
        assert!(
            (t.lsq_centre[0] - 10.002).abs() < 1e-6,
            "{:?}",
            t.lsq_centre
        );
        assert!((t.lsq_centre[1] + 5.003).abs() < 1e-6, "{:?}", t.lsq_centre);
        assert!((t.lsq_radius - 50.0).abs() < 1e-6);
        assert!(
            (t.circular_deviation - 2.0 * d).abs() < 1e-6,
            "{}",
            t.circular_deviation
        );
        assert!((t.mean_radius - 50.0).abs() < 1e-5);
        assert!(t.radial_max > d && t.radial_min < -d);
        assert_eq!(t.profile.len(), 720);
    }
}
