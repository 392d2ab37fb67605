//! Motion message estimators (eq. 11-13) and the per-axis history of error samples they
//! read.
//!
//! An estimator extrapolates the latest sample e_j\[m\] of axis j forward by D cycles:
//! `e' = e_j[m] + D·v̂_j`, with v̂_j the change per cycle estimated from the history:
//!
//! | kind | v̂ | exact for |
//! |---|---|---|
//! | [`Hold`] | 0 | constants |
//! | [`Linear`] | e\[m\] − e[m−1] | straight lines |
//! | [`Paper`] | 13/8·e\[m\] − 19/8·e[m−1] + 7/8·e[m−2] − 1/8·e[m−3] (eq. 12) | the slope of quadratics |
//!
//! The paper's weights give the exact derivative at t_m of any quadratic in time; for a cubic
//! c₃·t³ (t in cycles) they are off by −(5/4)·c₃ (tested). The
//! extrapolation e\[m\] + D·v̂ is linear in D, so a quadratic's value D cycles ahead is missed
//! by c₂·D². Until four samples exist, the paper's estimator uses the exact-for-quadratics
//! three-point slope (3·e\[m\] − 4·e[m−1] + e[m−2])/2, then the linear one, then holds.
//!
//! **The estimator slot.** A law owns its estimator as a `Box<dyn` [`Estimator`]`>`, so an
//! estimator may keep state of its own (a Kalman filter, a least-squares fit over a longer
//! window): [`Controller::update`](crate::Controller::update) tells it each time a sample
//! enters the history ([`Estimator::observe`]), and the law asks it for slopes while it
//! computes ([`Estimator::slope`]). The three kinds above keep no state: they read the
//! history alone. [`EstimatorKind`] names them (in scenarios and outputs) and builds them.
//! Each one declares whether its slope is a fixed linear function of the samples in the
//! history ([`Estimator::is_linear_in_history`]): the discrete-time stability check
//! ([`crate::stability::discrete_check`]) assumes it and refuses a law whose estimator
//! says otherwise.

use crate::error::ControlError;

/// Samples kept per axis.
pub const DEPTH: usize = 4;

/// One of an axis's two error signals in the history.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Signal {
    /// The position error e \[rad\].
    Position,
    /// The velocity error ė [rad/s].
    Velocity,
}

/// A motion message estimator (eq. 11-13): the change per cycle of one error signal of one
/// axis at its newest sample, from which a law extrapolates the sample by D_jk (eq. 13).
///
/// It may keep state: [`Estimator::observe`] is called for every sample that enters the
/// history, in order, before the law computes. It must not allocate in `observe` or `slope`
/// and should cost O(1) per call, so that a law stays O(n) per cycle.
pub trait Estimator: Send + std::fmt::Debug {
    /// The name used in outputs, e.g. `paper`.
    fn name(&self) -> &'static str;

    /// Whether [`Estimator::slope`] is a fixed linear function of the [`DEPTH`] samples the
    /// history holds for that axis and signal (the same weights every cycle once the history
    /// is full, no state of its own). The discrete-time stability check builds the loop from
    /// the history alone and refuses a law whose estimator returns `false`. A Kalman filter
    /// is linear but carries state beyond the history: it must return `false`.
    fn is_linear_in_history(&self) -> bool;

    /// A sample of `axis` has just entered `history` (it is `history.e[axis][0]` and
    /// `history.de[axis][0]`, taken at `history.t[axis]`). `history.count[axis] == 1` means
    /// the axis's history started afresh. The default keeps no state and does nothing.
    fn observe(&mut self, history: &ErrorHistory, axis: usize) {
        let _ = (history, axis);
    }

    /// Estimated change per cycle v̂ of `signal` of `axis` at its newest sample [rad or
    /// rad/s per cycle].
    fn slope(&self, history: &ErrorHistory, axis: usize, signal: Signal) -> f64;

    /// e' = e\[m\] + d·v̂: the newest sample of `signal` of `axis` extrapolated by `d` cycles
    /// (eq. 13).
    #[inline]
    fn estimate(&self, history: &ErrorHistory, axis: usize, signal: Signal, d: f64) -> f64 {
        history.samples(axis, signal)[0] + d * self.slope(history, axis, signal)
    }
}

/// Holds the latest sample: v̂ = 0 (no compensation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Hold;

/// Linear extrapolation from the last two samples: v̂ = e\[m\] − e[m−1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Linear;

/// The paper's four-sample estimator (eq. 12-13), with the shorter fallbacks while the
/// history fills.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Paper;

impl Hold {
    /// v̂ from `h` (newest first) of which `count` are valid: always 0.
    #[inline]
    pub fn slope_of(_h: &[f64; DEPTH], _count: usize) -> f64 {
        0.0
    }
}

impl Linear {
    /// v̂ from `h` (newest first) of which `count` are valid: e\[m\] − e[m−1], 0 with fewer
    /// than two samples.
    #[inline]
    pub fn slope_of(h: &[f64; DEPTH], count: usize) -> f64 {
        if count < 2 { 0.0 } else { h[0] - h[1] }
    }
}

impl Paper {
    /// v̂ from `h` (newest first) of which `count` are valid (eq. 12), with the fallbacks.
    #[inline]
    pub fn slope_of(h: &[f64; DEPTH], count: usize) -> f64 {
        match count {
            0 | 1 => 0.0,
            2 => h[0] - h[1],
            3 => 0.5 * (3.0 * h[0] - 4.0 * h[1] + h[2]),
            _ => (13.0 * h[0] - 19.0 * h[1] + 7.0 * h[2] - h[3]) * 0.125,
        }
    }
}

macro_rules! stateless_estimator {
    ($t:ty, $name:literal) => {
        impl Estimator for $t {
            fn name(&self) -> &'static str {
                $name
            }
            fn is_linear_in_history(&self) -> bool {
                true
            }
            #[inline]
            fn slope(&self, history: &ErrorHistory, axis: usize, signal: Signal) -> f64 {
                <$t>::slope_of(history.samples(axis, signal), history.count[axis])
            }
        }
    };
}

stateless_estimator!(Hold, "hold");
stateless_estimator!(Linear, "linear");
stateless_estimator!(Paper, "paper");

/// Which built-in estimator (docs/system.md, "The motion message estimator"); every result
/// names the one in use. [`EstimatorKind::build`] makes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EstimatorKind {
    /// Hold the latest sample (no compensation): [`Hold`].
    Hold,
    /// Linear extrapolation from the last two samples: [`Linear`].
    Linear,
    /// The paper's four-sample estimator (eq. 12-13): [`Paper`].
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

    /// The estimator, for a law to own (allocates once, at construction).
    pub fn build(self) -> Box<dyn Estimator> {
        match self {
            EstimatorKind::Hold => Box::new(Hold),
            EstimatorKind::Linear => Box::new(Linear),
            EstimatorKind::Paper => Box::new(Paper),
        }
    }

    /// Estimated change per cycle from `h` (newest first) of which `count` are valid.
    #[inline]
    pub fn slope(self, h: &[f64; DEPTH], count: usize) -> f64 {
        match self {
            EstimatorKind::Hold => Hold::slope_of(h, count),
            EstimatorKind::Linear => Linear::slope_of(h, count),
            EstimatorKind::Paper => Paper::slope_of(h, count),
        }
    }

    /// e' = h\[0\] + d·v̂: the latest sample extrapolated by `d` cycles (eq. 13).
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
    /// Position errors e \[rad\], newest first.
    pub e: Vec<[f64; DEPTH]>,
    /// Velocity errors ė [rad/s], newest first.
    pub de: Vec<[f64; DEPTH]>,
    /// Sampling instant of the newest sample \[s\].
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

    /// The samples of `signal` of `axis`, newest first (only `count[axis]` are valid).
    #[inline]
    pub fn samples(&self, axis: usize, signal: Signal) -> &[f64; DEPTH] {
        match signal {
            Signal::Position => &self.e[axis],
            Signal::Velocity => &self.de[axis],
        }
    }

    /// Adds a sample of axis `i` taken at `t` \[s\].
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

/// A stateful estimator for tests: v̂ is an exponentially smoothed difference of successive
/// samples, updated in [`Estimator::observe`], so it is not linear in the history.
#[cfg(test)]
#[derive(Debug)]
pub(crate) struct Smoothing {
    /// Smoothing factor β in (0, 1].
    pub beta: f64,
    /// Per axis: the smoothed slope of e and of ė.
    pub state: Vec<[f64; 2]>,
    /// Samples observed per axis.
    pub observed: Vec<usize>,
}

#[cfg(test)]
impl Smoothing {
    pub(crate) fn new(n: usize, beta: f64) -> Self {
        Smoothing {
            beta,
            state: vec![[0.0; 2]; n],
            observed: vec![0; n],
        }
    }
}

#[cfg(test)]
impl Estimator for Smoothing {
    fn name(&self) -> &'static str {
        "smoothing"
    }
    fn is_linear_in_history(&self) -> bool {
        false
    }
    fn observe(&mut self, h: &ErrorHistory, axis: usize) {
        self.observed[axis] += 1;
        for (k, sig) in [Signal::Position, Signal::Velocity].into_iter().enumerate() {
            let s = h.samples(axis, sig);
            self.state[axis][k] = if h.count[axis] < 2 {
                0.0
            } else {
                self.state[axis][k] + self.beta * ((s[0] - s[1]) - self.state[axis][k])
            };
        }
    }
    fn slope(&self, _h: &ErrorHistory, axis: usize, signal: Signal) -> f64 {
        self.state[axis][signal as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimator objects compute what the kinds' pure functions do, for every history
    /// length and both signals, and say that they are linear in the history.
    #[test]
    fn the_built_in_estimators_are_the_kinds() {
        let mut hist = ErrorHistory::new(1);
        for m in 0..5 {
            let t = m as f64;
            hist.push(0, 0.3 * t * t - t, 2.0 - 0.7 * t, t * 1e-3)
                .expect("push");
            for kind in [
                EstimatorKind::Hold,
                EstimatorKind::Linear,
                EstimatorKind::Paper,
            ] {
                let est = kind.build();
                assert_eq!(est.name(), kind.name());
                assert!(est.is_linear_in_history());
                for (sig, h) in [
                    (Signal::Position, hist.e[0]),
                    (Signal::Velocity, hist.de[0]),
                ] {
                    assert_eq!(est.slope(&hist, 0, sig), kind.slope(&h, hist.count[0]));
                    assert_eq!(
                        est.estimate(&hist, 0, sig, 0.4),
                        kind.estimate(&h, hist.count[0], 0.4)
                    );
                }
            }
        }
    }

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
