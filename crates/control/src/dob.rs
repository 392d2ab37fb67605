//! A disturbance observer per axis (not in the paper): what the axis needs beyond the
//! command, estimated from its samples through the nominal model, filtered, and added to
//! the next command (docs/control.md, "Disturbance observer").
//!
//! With the nominal model H_n·ẍ + C_n·ẋ = u + d (H_n = K_H, C_n = K_C, the feed-forward
//! gains, e.g. from `ringsync identify`), the disturbance d lumps Coulomb friction, the
//! model's error and loads. At each sample k the observer integrates the model over the two
//! cycles before it, as the identification does (the weight T − |s| around t_{k−1}):
//!
//! ```text
//! A = x_k − 2·x_{k−1} + x_{k−2}      V = T·(x_k − x_{k−2})/2      Y = ∫ (T − |s|)·u(t_{k−1}+s) ds
//! d_k = (H_n·A + C_n·V − Y) / T²     d̂_k = d̂_{k−1} + γ·(d_k − d̂_{k−1}),  γ = 1 − exp(−2π·f_Q·T)
//! ```
//!
//! Y is exact: the commands are piecewise constant from their application times. The
//! first-order filter Q (bandwidth f_Q) keeps the encoder's quantisation, divided by T² in
//! d_k, out of the command. The command becomes u_law − d̂_k (then clipped to the drive's
//! range): what the disturbance takes, the command adds. The check models it with three more states per axis
//! ([`crate::stability::discrete_loop_with`]).

use crate::error::{ControlError, check, check_len};
use crate::identify::weighted_input;

/// The observer's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct DobParams {
    /// Bandwidth f_Q of the filter \[Hz\], > 0.
    pub bandwidth_hz: f64,
    /// Nominal H_n = J/K_a per axis [V·s²/rad], > 0.
    pub h: Vec<f64>,
    /// Nominal C_n = b/K_a per axis [V·s/rad].
    pub c: Vec<f64>,
    /// Drive range ±u_max per axis \[V\] (the command is clipped after d̂ is taken off).
    pub u_max: Vec<f64>,
}

impl DobParams {
    /// The filter's gain γ for cycle `t_cyc` \[s\].
    pub fn gain(&self, t_cyc: f64) -> f64 {
        1.0 - (-std::f64::consts::TAU * self.bandwidth_hz * t_cyc).exp()
    }

    /// The weights of (u_{k−3}, u_{k−2}, u_{k−1}) in Y when every command takes effect
    /// `delay` \[s\] after its cycle's sample, 0 ≤ delay ≤ T.
    pub fn input_weights(t_cyc: f64, delay: f64) -> [f64; 3] {
        let w = |s: f64| t_cyc * s - s * s.abs() / 2.0;
        [
            w(-t_cyc + delay) - w(-t_cyc),
            w(delay) - w(-t_cyc + delay),
            w(t_cyc) - w(delay),
        ]
    }
}

/// One axis's observer state.
#[derive(Debug, Clone)]
struct AxisState {
    /// The last three samples (t [s], x [rad]), newest first.
    x: [(f64, f64); 3],
    /// Samples held (up to 3).
    count: usize,
    /// The last four commands (from [s], u [V]), oldest first.
    steps: [(f64, f64); 4],
    /// d̂ [V].
    d: f64,
}

impl Default for AxisState {
    fn default() -> Self {
        AxisState {
            x: [(0.0, 0.0); 3],
            count: 0,
            // 0 V since ever, until the first command.
            steps: [(f64::NEG_INFINITY, 0.0); 4],
            d: 0.0,
        }
    }
}

/// The disturbance observers of n axes.
#[derive(Debug, Clone)]
pub struct DisturbanceObserver {
    params: DobParams,
    axes: Vec<AxisState>,
}

impl DisturbanceObserver {
    /// Checked observers, one per axis of `params`.
    pub fn new(params: DobParams) -> Result<Self, ControlError> {
        let n = params.h.len();
        check_len("dob.c", n, params.c.len())?;
        check_len("dob.u_max", n, params.u_max.len())?;
        check("dob_bandwidth", params.bandwidth_hz, 0.0, true, "> 0 Hz")?;
        for i in 0..n {
            check(
                &format!("kh[{i}]"),
                params.h[i],
                0.0,
                true,
                "> 0 V·s²/rad: the disturbance observer inverts the nominal model K_H",
            )?;
            check(
                &format!("kc[{i}]"),
                params.c[i],
                f64::MIN,
                false,
                "a finite gain in V·s/rad",
            )?;
        }
        Ok(DisturbanceObserver {
            axes: vec![AxisState::default(); n],
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &DobParams {
        &self.params
    }

    /// The estimate d̂ of axis `i` \[V\].
    pub fn estimate(&self, i: usize) -> f64 {
        self.axes[i].d
    }

    /// A sample of axis `i`: position `x` \[rad\] at `t` \[s\]. With three samples one cycle
    /// apart, d̂ moves towards the new d_k; a gap starts the samples afresh.
    pub fn sample(&mut self, i: usize, x: f64, t: f64, t_cyc: f64) {
        let a = &mut self.axes[i];
        if a.count > 0 && ((t - a.x[0].0) / t_cyc - 1.0).abs() > 0.5 {
            a.count = 0;
        }
        a.x = [(t, x), a.x[0], a.x[1]];
        a.count = (a.count + 1).min(3);
        if a.count < 3 {
            return;
        }
        let (h, c) = (self.params.h[i], self.params.c[i]);
        let (xk, x1, x2) = (a.x[0].1, a.x[1].1, a.x[2].1);
        let acc = xk - 2.0 * x1 + x2;
        let vel = t_cyc * (xk - x2) / 2.0;
        let y = weighted_input(&a.steps, a.x[1].0, t_cyc);
        let d = (h * acc + c * vel - y) / (t_cyc * t_cyc);
        a.d += self.params.gain(t_cyc) * (d - a.d);
    }

    /// Takes d̂ off the law's commands in `out` (clipped again to the drive's range) and
    /// records them as applied at `apply_time` \[s\].
    pub fn compensate(&mut self, out: &mut crate::law::ControlOutput, apply_time: &[f64]) {
        for (i, &at) in apply_time.iter().enumerate().take(self.axes.len()) {
            let raw = out.u_raw[i] - self.axes[i].d;
            out.set(i, raw, self.params.u_max[i]);
            self.applied(i, at, out.u[i]);
        }
    }

    /// The command `u` \[V\] axis `i` applies from `at` \[s\] on (after clipping).
    pub fn applied(&mut self, i: usize, at: f64, u: f64) {
        let s = &mut self.axes[i].steps;
        if at.is_finite() && at >= s[3].0 {
            *s = [s[1], s[2], s[3], (at, u)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis H·ẍ = u − F (a constant load F) at rest under u = F: the model expects an
    /// acceleration it does not see, so d̂ → −F (and u_law − d̂ adds F back). An axis that
    /// accelerates exactly as the model says has nothing to estimate.
    #[test]
    fn the_estimate_is_what_the_model_does_not_explain() {
        let t_cyc = 1e-3;
        let p = DobParams {
            bandwidth_hz: 20.0,
            h: vec![0.02],
            c: vec![0.0],
            u_max: vec![10.0],
        };
        // An axis at rest under a constant 0.3 V: the model says it should accelerate at
        // 0.3/0.02 rad/s², it does not: a disturbance of −0.3 V holds it.
        let mut o = DisturbanceObserver::new(p.clone()).expect("dob");
        for k in 0..2000 {
            let t = k as f64 * t_cyc;
            o.applied(0, t + 1e-4, 0.3);
            o.sample(0, 0.0, t, t_cyc);
        }
        assert!((o.estimate(0) + 0.3).abs() < 1e-9, "{}", o.estimate(0));
        // The axis accelerating exactly as H·ẍ = u: nothing to estimate.
        let mut o = DisturbanceObserver::new(p).expect("dob");
        let a = 0.3 / 0.02;
        for k in 0..2000 {
            let t = k as f64 * t_cyc;
            o.applied(0, t - 1.0, 0.3);
            o.sample(0, 0.5 * a * t * t, t, t_cyc);
        }
        assert!(o.estimate(0).abs() < 1e-9, "{}", o.estimate(0));
    }

    #[test]
    fn the_weights_sum_to_the_window() {
        for d in [0.0, 1.3e-4, 1e-3] {
            let w = DobParams::input_weights(1e-3, d);
            assert!((w.iter().sum::<f64>() - 1e-6).abs() < 1e-18, "{w:?}");
        }
        let bad = DobParams {
            bandwidth_hz: 10.0,
            h: vec![0.0],
            c: vec![0.0],
            u_max: vec![10.0],
        };
        let e = DisturbanceObserver::new(bad).expect_err("H_n = 0");
        assert!(e.to_string().contains("kh[0]"), "{e}");
    }
}
