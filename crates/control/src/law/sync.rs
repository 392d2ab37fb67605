//! The paper's position-synchronisation controller, eq. 9 (no delay) and eq. 14 (with the
//! motion message estimator):
//!
//! ```text
//! u_k = K_H,k·ẍ^d_k + K_C,k·ẋ^d_k + K_P,k·E'_k + K_D,k·Ė'_k + [(I + αT)⁻¹·K_E·ė]_k + K_N·sgn(Ė'_k)
//! E'_k = (1 + α)·e_k − (α/(n−1))·Σ_{j≠k} e'_jk,   e'_jk = e_j[m] + (D_jk/T_cyc)·v̂_j
//! K_N  = Δ_H·‖ẍ^d‖ + Δ_C·‖ẋ^d‖
//! ```
//!
//! D_jk = (application time of axis k's command) − (sampling instant of axis j's latest
//! sample), known from the timestamps. Ė'_k is built the same way from ė. The own term uses
//! the latest own sample as is unless `extrapolate_own` is set. With the `Hold` estimator,
//! or all delays zero, this is eq. 9 on the latest samples.
//!
//! O(n): D_jk = a_k − s_j is affine in a_k, so Σ_{j≠k} e'_jk = (S_e − e_k) + a_k·(S_v − v̂_k)
//! − (S_sv − s_k·v̂_k) (times in cycles, relative to the first axis's sample) from three sums
//! over all axes.

use super::registry::LawEntry;
use super::{ControlInput, ControlLaw, ControlOutput, Gains};
use crate::coupling::Coupling;
use crate::error::{ControlError, check};
use crate::estimator::{ErrorHistory, Estimator, EstimatorKind, Signal};

/// The registry's entry: `sync`, from K_P, K_D, K_E, K_H, K_C and the coupling's parameters;
/// no parameters of its own.
pub const ENTRY: LawEntry = LawEntry {
    name: "sync",
    description: "the paper's position-synchronisation controller (eq. 9, 14): each axis coupled to the mean of all others through E' = (I + αT)e with the motion message estimator",
    min_axes: 2,
    params: &[],
    make: |p| Ok(Box::new(SyncController::new(p.gains.clone(), p.sync)?)),
};

/// How the robust term's sgn(Ė') is evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sign {
    /// The discontinuous sign (chatters in discrete time).
    Exact,
    /// The boundary layer sat(Ė'/φ), φ > 0 [rad/s].
    BoundaryLayer(f64),
}

/// Parameters of the sync controller besides the per-axis gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyncParams {
    /// Coupling weight α ≥ 0.
    pub alpha: f64,
    /// Δ_H of K_N [V·s²/rad], ≥ 0 (the reference: 0).
    pub delta_h: f64,
    /// Δ_C of K_N [V·s/rad], ≥ 0 (the reference: 0).
    pub delta_c: f64,
    /// sgn or its boundary layer.
    pub sign: Sign,
    /// The motion message estimator (built-in kinds; [`SyncController::with_estimator`]
    /// takes any other).
    pub estimator: EstimatorKind,
    /// Extrapolate the own axis's sample too (the paper uses it as is).
    pub extrapolate_own: bool,
}

impl SyncParams {
    /// The reference scenario's: α = 0.5, K_N = 0, the paper's estimator.
    pub fn reference() -> Self {
        SyncParams {
            alpha: 0.5,
            delta_h: 0.0,
            delta_c: 0.0,
            sign: Sign::BoundaryLayer(0.01),
            estimator: EstimatorKind::Paper,
            extrapolate_own: false,
        }
    }
}

/// The position-synchronisation controller (eq. 9 and 14).
#[derive(Debug)]
pub struct SyncController {
    gains: Gains,
    params: SyncParams,
    estimator: Box<dyn Estimator>,
    /// P = p_diag·I and Q = q_off·(1·1ᵀ − I) of I + αT.
    p_diag: f64,
    q_off: f64,
    /// 1 / (1 + α·n/(n−1)).
    inv_den: f64,
    /// 1 / n.
    inv_n: f64,
}

impl SyncController {
    /// A checked controller: n ≥ 2 axes, α ≥ 0, K_E ≥ 0, Δ_H, Δ_C ≥ 0, φ > 0, with the
    /// built-in estimator `params.estimator`.
    pub fn new(gains: Gains, params: SyncParams) -> Result<Self, ControlError> {
        Self::with_estimator(gains, params, params.estimator.build())
    }

    /// A checked controller with any estimator, which the law then owns (`params.estimator`
    /// is not used).
    pub fn with_estimator(
        gains: Gains,
        params: SyncParams,
        estimator: Box<dyn Estimator>,
    ) -> Result<Self, ControlError> {
        gains.validate()?;
        let coupling = Coupling::new(gains.axes(), params.alpha)?;
        check("delta_h", params.delta_h, 0.0, false, ">= 0 V·s²/rad")?;
        check("delta_c", params.delta_c, 0.0, false, ">= 0 V·s/rad")?;
        if let Sign::BoundaryLayer(phi) = params.sign {
            check("boundary_layer", phi, 0.0, true, "> 0 rad/s")?;
        }
        let (p_diag, q_off) = coupling.split();
        Ok(SyncController {
            inv_n: 1.0 / gains.axes() as f64,
            gains,
            params,
            estimator,
            p_diag,
            q_off,
            inv_den: 1.0 / coupling.denominator(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &SyncParams {
        &self.params
    }
}

impl ControlLaw for SyncController {
    fn name(&self) -> &'static str {
        "sync"
    }
    fn axes(&self) -> usize {
        self.gains.axes()
    }
    fn estimator(&self) -> Option<&dyn Estimator> {
        Some(self.estimator.as_ref())
    }
    fn estimator_mut(&mut self) -> Option<&mut dyn Estimator> {
        Some(self.estimator.as_mut())
    }
    #[inline]
    fn evaluate(&self, h: &ErrorHistory, input: &ControlInput, out: &mut ControlOutput) {
        let n = self.axes();
        let g = &self.gains;
        let p = &self.params;
        let est = self.estimator.as_ref();
        let inv_t = 1.0 / input.t_cyc;
        let t_ref = h.t[0];
        // Pass 1: sums over all axes.
        let (mut se, mut sv, mut ssv) = (0.0, 0.0, 0.0);
        let (mut sde, mut sw, mut ssw) = (0.0, 0.0, 0.0);
        let mut ske = 0.0;
        for j in 0..n {
            let s = (h.t[j] - t_ref) * inv_t;
            let v = est.slope(h, j, Signal::Position);
            let w = est.slope(h, j, Signal::Velocity);
            out.work[j] = [v, w, s];
            se += h.e[j][0];
            sv += v;
            ssv += s * v;
            sde += h.de[j][0];
            sw += w;
            ssw += s * w;
            ske += g.ke[j] * h.de[j][0];
        }
        let mean_ke = ske * self.inv_n;
        // K_N = Δ_H·‖ẍ^d‖ + Δ_C·‖ẋ^d‖, only when the robust term is on.
        let kn = if p.delta_h == 0.0 && p.delta_c == 0.0 {
            0.0
        } else {
            let (a2, v2) = input
                .desired
                .iter()
                .fold((0.0, 0.0), |(a2, v2), d| (a2 + d.a * d.a, v2 + d.v * d.v));
            p.delta_h * a2.sqrt() + p.delta_c * v2.sqrt()
        };
        let (p_diag, q_off, inv_den) = (self.p_diag, self.q_off, self.inv_den);
        // Pass 2: each axis's command.
        for k in 0..n {
            let [v, w, s] = out.work[k];
            let f = (input.apply_time[k] - t_ref) * inv_t;
            let (e0, de0) = (h.e[k][0], h.de[k][0]);
            let others_e = (se - e0) + f * (sv - v) - (ssv - s * v);
            let others_de = (sde - de0) + f * (sw - w) - (ssw - s * w);
            let (own_e, own_de) = if p.extrapolate_own {
                (e0 + (f - s) * v, de0 + (f - s) * w)
            } else {
                (e0, de0)
            };
            // E' = P·e − Q·e' (eq. 14): (1+α)·own − α/(n−1)·Σ_{j≠k} e'_jk.
            let big_e = p_diag * own_e - q_off * others_e;
            let big_de = p_diag * own_de - q_off * others_de;
            let inv = mean_ke + (g.ke[k] * de0 - mean_ke) * inv_den;
            let sgn = match p.sign {
                _ if kn == 0.0 => 0.0,
                Sign::Exact if big_de == 0.0 => 0.0,
                Sign::Exact => big_de.signum(),
                Sign::BoundaryLayer(phi) => (big_de / phi).clamp(-1.0, 1.0),
            };
            let raw = g.feed_forward(k, &input.desired[k])
                + g.kp[k] * big_e
                + g.kd[k] * big_de
                + inv
                + kn * sgn;
            out.set(k, raw, g.u_max[k]);
        }
    }
}
