//! Motion message estimators (eq. 11-13) and the per-axis history of error samples they
//! read.
//!
//! An estimator extrapolates the latest sample e_j[m] of axis j forward by D cycles:
//! `e' = e_j[m] + D·v̂_j`, with v̂_j the change per cycle estimated from the history:
//!
//! | kind | v̂ | exact for |
//! |---|---|---|
//! | [`EstimatorKind::Hold`] | 0 | constants |
//! | [`EstimatorKind::Linear`] | e[m] − e[m−1] | straight lines |
//! | [`EstimatorKind::Paper`] | 13/8·e[m] − 19/8·e[m−1] + 7/8·e[m−2] − 1/8·e[m−3] (eq. 12) | the slope of quadratics |
//!
//! The paper's weights give the exact derivative at t_m of any quadratic in time; for a cubic
//! c₃·t³ (t in cycles) they are off by −(5/4)·c₃ (tested). The
//! extrapolation e[m] + D·v̂ is linear in D, so a quadratic's value D cycles ahead is missed
//! by c₂·D². Until four samples exist, the paper's estimator uses the exact-for-quadratics
//! three-point slope (3·e[m] − 4·e[m−1] + e[m−2])/2, then the linear one, then holds.

use crate::error::ControlError;

/// Samples kept per axis.
pub const DEPTH: usize = 4;

/// Which estimator (docs/system.md, "The motion message estimator"); every result names the one in use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EstimatorKind {
    /// Hold the latest sample (no compensation).
    Hold,
    /// Linear extrapolation from the last two samples.
    Linear,
    /// The paper's four-sample estimator (eq. 12-13).
    Paper,
}

impl EstimatorKind {
    /// The name used in options, scenarios and outputs.
    pub fn name(self) -> &'static str {
        match self {
            EstimatorKind::Hold => "hold",
            EstimatorKind::Linear => "linear",
            EstimatorKind::Paper => "paper",
        }
    }

    /// Estimated change per cycle from `h` (newest first) of which `count` are valid.
    #[inline]
    pub fn slope(self, h: &[f64; DEPTH], count: usize) -> f64 {
        match (self, count) {
            (EstimatorKind::Hold, _) | (_, 0 | 1) => 0.0,
            (EstimatorKind::Linear, _) | (EstimatorKind::Paper, 2) => h[0] - h[1],
            (EstimatorKind::Paper, 3) => 0.5 * (3.0 * h[0] - 4.0 * h[1] + h[2]),
            (EstimatorKind::Paper, _) => (13.0 * h[0] - 19.0 * h[1] + 7.0 * h[2] - h[3]) * 0.125,
        }
    }

    /// e' = h[0] + d·v̂: the latest sample extrapolated by `d` cycles (eq. 13).
    #[inline]
    pub fn estimate(self, h: &[f64; DEPTH], count: usize, d: f64) -> f64 {
        h[0] + d * self.slope(h, count)
    }
}

impl core::str::FromStr for EstimatorKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "hold" | "none" => Ok(EstimatorKind::Hold),
            "linear" => Ok(EstimatorKind::Linear),
            "paper" => Ok(EstimatorKind::Paper),
            other => Err(format!(
                "unknown estimator '{other}': expected hold, linear or paper"
            )),
        }
    }
}

/// The last [`DEPTH`] error samples e and ė of every axis, newest first, with the sampling
/// instant of the newest. One sample per cycle is assumed (spacing T_cyc).
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorHistory {
    /// Position errors e [rad], newest first.
    pub e: Vec<[f64; DEPTH]>,
    /// Velocity errors ė [rad/s], newest first.
    pub de: Vec<[f64; DEPTH]>,
    /// Sampling instant of the newest sample [s].
    pub t: Vec<f64>,
    /// Valid samples per axis (≤ DEPTH).
    pub count: Vec<usize>,
}

impl ErrorHistory {
    /// An empty history for `n` axes.
    pub fn new(n: usize) -> Self {
        ErrorHistory {
            e: vec![[0.0; DEPTH]; n],
            de: vec![[0.0; DEPTH]; n],
            t: vec![0.0; n],
            count: vec![0; n],
        }
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.e.len()
    }

    /// Adds a sample of axis `i` taken at `t` [s].
    #[inline]
    pub fn push(&mut self, i: usize, e: f64, de: f64, t: f64) -> Result<(), ControlError> {
        if i >= self.axes() {
            return Err(ControlError::AxisOutOfRange {
                axis: i,
                n: self.axes(),
            });
        }
        let (h, dh) = (self.e[i], self.de[i]);
        self.e[i] = [e, h[0], h[1], h[2]];
        self.de[i] = [de, dh[0], dh[1], dh[2]];
        self.t[i] = t;
        self.count[i] = (self.count[i] + 1).min(DEPTH);
        Ok(())
    }

    /// Forgets every sample.
    pub fn clear(&mut self) {
        self.count.fill(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of f at t = 0, −1, −2, −3 (cycles), newest first.
    fn samples(f: impl Fn(f64) -> f64) -> [f64; DEPTH] {
        [f(0.0), f(-1.0), f(-2.0), f(-3.0)]
    }

    #[test]
    fn paper_slope_is_exact_for_quadratics() {
        let (c0, c1, c2) = (0.3, -1.7, 2.9);
        let h = samples(|t| c0 + c1 * t + c2 * t * t);
        let v = EstimatorKind::Paper.slope(&h, 4);
        assert!((v - c1).abs() < 1e-12, "{v}");
        // Its extrapolation misses the quadratic by c2·D² (linear in D).
        let d = 0.175;
        let est = EstimatorKind::Paper.estimate(&h, 4, d);
        let truth = c0 + c1 * d + c2 * d * d;
        assert!((truth - est - c2 * d * d).abs() < 1e-12);
        // The linear estimator is not exact for the slope of a quadratic.
        assert!((EstimatorKind::Linear.slope(&h, 4) - c1).abs() > 1.0);
    }

    #[test]
    fn paper_slope_error_on_a_cubic() {
        // t³ has slope 0 at t = 0; the weights give (−19·(−1) + 7·(−8) − (−27))/8 = −10/8.
        let c3 = 0.4;
        let h = samples(|t| c3 * t * t * t);
        assert!((EstimatorKind::Paper.slope(&h, 4) - (-1.25 * c3)).abs() < 1e-12);
    }

    #[test]
    fn fallbacks_with_short_history() {
        let h = samples(|t| 1.0 + 2.0 * t + 3.0 * t * t);
        assert_eq!(EstimatorKind::Paper.slope(&h, 1), 0.0);
        assert_eq!(EstimatorKind::Paper.slope(&h, 2), h[0] - h[1]);
        // Three points: exact for the quadratic too.
        assert!((EstimatorKind::Paper.slope(&h, 3) - 2.0).abs() < 1e-12);
        assert_eq!(EstimatorKind::Hold.estimate(&h, 4, 5.0), h[0]);
        assert!((EstimatorKind::Linear.estimate(&h, 4, 1.0) - (2.0 * h[0] - h[1])).abs() < 1e-12);
    }

    #[test]
    fn history_keeps_newest_first() {
        let mut hist = ErrorHistory::new(2);
        for k in 0..6 {
            hist.push(1, k as f64, -(k as f64), k as f64 * 1e-3)
                .expect("push");
        }
        assert_eq!(hist.e[1], [5.0, 4.0, 3.0, 2.0]);
        assert_eq!(hist.de[1], [-5.0, -4.0, -3.0, -2.0]);
        assert_eq!(hist.count, vec![0, 4]);
        assert!(hist.push(2, 0.0, 0.0, 0.0).is_err());
        assert_eq!("paper".parse::<EstimatorKind>(), Ok(EstimatorKind::Paper));
        assert!("kalman".parse::<EstimatorKind>().is_err());
    }
}
