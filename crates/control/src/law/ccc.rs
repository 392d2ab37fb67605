//! Cross-coupled contour control (Koren 1980; variable gains for curved paths, Koren & Lo
//! 1991): on top of each axis's PD, ring axes 1 and 2 (the machine's X and Y) are pushed
//! together along the path's normal by the estimated contour error, the distance of the
//! tool from the path rather than from its due point on it (docs/control.md,
//! "Cross-coupled contour control"):
//!
//! ```text
//! t = ẋ^d/|ẋ^d|, n = (−t_y, t_x), κ = (ẋ^d_x·ẍ^d_y − ẋ^d_y·ẍ^d_x)/|ẋ^d|³   (at the command's application time)
//! ε   = n·e + (κ/2)·(t·e)²          (the contour error: 0 for a tool on the path's osculating circle)
//! ε̇  ≈ n·ė
//! u_k = K_H,k·ẍ^d_k + K_C,k·ẋ^d_k + K_P,k·e_k + K_D,k·ė_k + n_k·(K_CP,k·ε + K_CD,k·ε̇)   (k = 1, 2)
//! u_k = K_H,k·ẍ^d_k + K_C,k·ẋ^d_k + K_P,k·e_k + K_D,k·ė_k                              (k > 2)
//! ```
//!
//! with e = x^d − x per axis (e of axes 1 and 2 in the same unit, so their drives must move
//! the tool equally per radian: equal leads). The (κ/2)·(t·e)² term is Koren and Lo's
//! variable gain: a tool that lags along a circle stays on it, and its tracking error then
//! has a normal part −e_t²/(2R) that is no contour error. Where the path stands still
//! (|ẋ^d| below 1 µrad/s) the direction is undefined and only the PD acts.

use super::registry::{LawEntry, ParamSpec};
use super::{ControlInput, ControlLaw, ControlOutput, Gains};
use crate::error::{ControlError, check, check_len};
use crate::estimator::ErrorHistory;

/// Speed of the desired path below which it has no direction \[rad/s\].
const STILL: f64 = 1e-6;

/// The registry's entry: `ccc`, PD with the feed-forward, plus the contour coupling of axes
/// 1 and 2 with gains `kcp`, `kcd` (one per axis; only axes 1 and 2 use theirs).
pub const ENTRY: LawEntry = LawEntry {
    name: "ccc",
    description: "cross-coupled contour control (Koren 1980, variable gains of Koren & Lo 1991): PD per axis, and ring axes 1 and 2 (X, Y) pushed along the path's normal by the contour error estimated from the path's local direction and curvature",
    min_axes: 2,
    params: &[
        ParamSpec {
            key: "kcp",
            doc: "contour gain K_CP on the estimated contour error ε (axes 1 and 2)",
            unit: "V/rad",
            default: 300.0,
            min: 0.0,
            max: f64::INFINITY,
        },
        ParamSpec {
            key: "kcd",
            doc: "contour gain K_CD on its rate ε̇ ≈ n·ė (axes 1 and 2)",
            unit: "V·s/rad",
            default: 3.0,
            min: 0.0,
            max: f64::INFINITY,
        },
    ],
    make: |p| {
        Ok(Box::new(ContourCoupled::new(
            p.gains.clone(),
            p.values(ENTRY.name, "kcp")?.to_vec(),
            p.values(ENTRY.name, "kcd")?.to_vec(),
        )?))
    },
};

/// The cross-coupled contour controller.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourCoupled {
    gains: Gains,
    kcp: Vec<f64>,
    kcd: Vec<f64>,
}

/// A direction or vector in the XY plane of axes 1 and 2.
pub type Planar = (f64, f64);

/// The path's local frame at one instant: unit tangent, left normal and signed curvature
/// \[1/rad\] of the XY motion with velocity `v` and acceleration `a`; `None` where it stands
/// still (or a figure is not finite).
pub fn local_frame(v: Planar, a: Planar) -> Option<(Planar, Planar, f64)> {
    let speed = v.0.hypot(v.1);
    if speed.is_nan() || speed <= STILL {
        return None;
    }
    let t = (v.0 / speed, v.1 / speed);
    let kappa = (v.0 * a.1 - v.1 * a.0) / (speed * speed * speed);
    Some((t, (-t.1, t.0), kappa))
}

/// The estimated contour error of tracking error `e` (x^d − x) in the frame (t, n, κ):
/// n·e + (κ/2)·(t·e)², positive when the tool lies on the right of the path (outside a
/// left turn).
pub fn contour_error(e: Planar, t: Planar, n: Planar, kappa: f64) -> f64 {
    let et = t.0 * e.0 + t.1 * e.1;
    n.0 * e.0 + n.1 * e.1 + 0.5 * kappa * et * et
}

impl ContourCoupled {
    /// A checked controller: n ≥ 2, one K_CP [V/rad] and one K_CD [V·s/rad] per axis, each
    /// ≥ 0 (axes beyond the second do not use theirs).
    pub fn new(gains: Gains, kcp: Vec<f64>, kcd: Vec<f64>) -> Result<Self, ControlError> {
        gains.validate()?;
        let n = gains.axes();
        if n < 2 {
            return Err(ControlError::TooFewAxes {
                what: "cross-coupled contour control",
                n,
                min: 2,
            });
        }
        check_len("kcp", n, kcp.len())?;
        check_len("kcd", n, kcd.len())?;
        for i in 0..n {
            check(&format!("kcp[{i}]"), kcp[i], 0.0, false, ">= 0 V/rad")?;
            check(&format!("kcd[{i}]"), kcd[i], 0.0, false, ">= 0 V·s/rad")?;
        }
        Ok(ContourCoupled { gains, kcp, kcd })
    }
}

impl ControlLaw for ContourCoupled {
    fn name(&self) -> &'static str {
        ENTRY.name
    }
    fn axes(&self) -> usize {
        self.gains.axes()
    }
    #[inline]
    fn evaluate(&self, h: &ErrorHistory, input: &ControlInput, out: &mut ControlOutput) {
        let g = &self.gains;
        let (dx, dy) = (&input.desired[0], &input.desired[1]);
        let frame = local_frame((dx.v, dy.v), (dx.a, dy.a));
        let (eps, deps, normal) = match frame {
            Some((t, n, kappa)) => {
                let e = (h.e[0][0], h.e[1][0]);
                let de = (h.de[0][0], h.de[1][0]);
                (
                    contour_error(e, t, n, kappa),
                    n.0 * de.0 + n.1 * de.1,
                    [n.0, n.1],
                )
            }
            None => (0.0, 0.0, [0.0, 0.0]),
        };
        for k in 0..self.axes() {
            let mut raw = g.feed_forward(k, &input.desired[k])
                + g.kp[k] * h.e[k][0]
                + g.kd[k] * h.de[k][0];
            if let Some(nk) = normal.get(k) {
                raw += nk * (self.kcp[k] * eps + self.kcd[k] * deps);
            }
            out.set(k, raw, g.u_max[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::ControlInput;
    use crate::trajectory::State;

    /// A ccw circle of radius R at angular speed ω, at angle θ.
    fn circle(r: f64, w: f64, th: f64) -> ((f64, f64), (f64, f64), (f64, f64)) {
        let p = (r * th.cos(), r * th.sin());
        let v = (-r * w * th.sin(), r * w * th.cos());
        let a = (-r * w * w * th.cos(), -r * w * w * th.sin());
        (p, v, a)
    }

    #[test]
    fn the_frame_of_a_circle_and_the_contour_error_of_a_tool_on_it() {
        let (r, w, th) = (50.0, 2.0, 0.7);
        let (pd, v, a) = circle(r, w, th);
        let (t, n, kappa) = local_frame(v, a).expect("moving");
        assert!((kappa - 1.0 / r).abs() < 1e-12, "{kappa}");
        // The left normal of a ccw circle points to its centre.
        assert!((n.0 + th.cos()).abs() < 1e-12 && (n.1 + th.sin()).abs() < 1e-12);
        // A tool lagging 0.02 rad along the circle is on it: its tracking error is 1 mm,
        // its normal part −R(1 − cos 0.02) = −0.01 mm, its contour error (to third order)
        // none.
        let (p, _, _) = circle(r, w, th - 0.02);
        let e = (pd.0 - p.0, pd.1 - p.1);
        assert!((n.0 * e.0 + n.1 * e.1 + 0.01).abs() < 1e-4);
        assert!(contour_error(e, t, n, kappa).abs() < 1e-6, "{}", contour_error(e, t, n, kappa));
        // A tool 0.05 off outward (x = x^d + 0.05·r̂, e = −0.05·r̂): ε = +0.05.
        let e = (-0.05 * th.cos(), -0.05 * th.sin());
        assert!((contour_error(e, t, n, kappa) - 0.05).abs() < 1e-12);
        assert!(local_frame((0.0, 0.0), (1.0, 0.0)).is_none(), "no direction at rest");
    }

    #[test]
    fn axes_1_and_2_are_pushed_along_the_normal_the_rest_is_pd() {
        let n = 3;
        let gains = Gains::uniform(n, 3.0, 0.5, 0.0);
        let law = ContourCoupled::new(gains, vec![100.0; n], vec![0.0; n]).expect("law");
        let mut h = ErrorHistory::new(n);
        let mut input = ControlInput::new(n, 1e-3);
        let mut out = ControlOutput::new(n);
        // Moving along +x: t = (1, 0), n = (0, 1); errors 0.01 on axis 2 (normal), 0.02 on 1.
        input.desired[0] = State { x: 0.0, v: 5.0, a: 0.0 };
        input.desired[1] = State::default();
        for (i, e) in [0.02, 0.01, 0.03].into_iter().enumerate() {
            h.push(i, e, 0.0, 0.0).expect("push");
        }
        law.compute(&h, &input, &mut out).expect("compute");
        assert!((out.u[0] - 3.0 * 0.02).abs() < 1e-12, "no normal part on X: {:?}", out.u);
        assert!((out.u[1] - (3.0 * 0.01 + 100.0 * 0.01)).abs() < 1e-12, "{:?}", out.u);
        assert!((out.u[2] - 3.0 * 0.03).abs() < 1e-12, "axis 3 is PD: {:?}", out.u);
        // At rest: PD alone.
        input.desired[0].v = 0.0;
        law.compute(&h, &input, &mut out).expect("compute");
        assert!((out.u[1] - 3.0 * 0.01).abs() < 1e-12, "{:?}", out.u);
    }
}
