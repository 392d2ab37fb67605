//! A ring-coupled cross-coupled controller in the style of Sun et al. (2007), the
//! literature baseline: each axis is coupled to its two ring neighbours only,
//!
//! ```text
//! E_k = e_k + α·(2·e_k − e'_{k−1} − e'_{k+1}),   i.e. E = (I + αL)·e with the ring Laplacian L
//! u_k = K_H,k·ẍ^d_k + K_C,k·ẋ^d_k + K_P,k·E_k + K_D,k·Ė_k
//! ```
//!
//! (indices modulo n; Ė likewise from ė). The neighbours' samples are extrapolated to this
//! axis's application time by the same estimator as the sync controller. This is the
//! adjacent-coupling structure of Sun's ring approach as commonly restated; the original
//! paper's exact law was not available to check it against.

use super::registry::LawEntry;
use super::{ControlInput, ControlLaw, ControlOutput, Gains, ring_neighbours};
use crate::error::{ControlError, check_gain};
use crate::estimator::{ErrorHistory, Estimator, EstimatorKind};

/// The registry's entry: `ring-coupled`, from K_P, K_D, K_H, K_C, α and the estimator; no
/// parameters of its own.
pub const ENTRY: LawEntry = LawEntry {
    name: "ring-coupled",
    description: "ring-coupled baseline in the style of Sun et al. (2007): E = (I + αL)e with the ring Laplacian L, the neighbours through the estimator",
    min_axes: 2,
    params: &[],
    make: |p| {
        Ok(Box::new(RingCoupled::new(
            p.gains.clone(),
            p.sync.alpha,
            p.sync.estimator,
        )?))
    },
};

/// The ring-coupled controller.
#[derive(Debug)]
pub struct RingCoupled {
    gains: Gains,
    alpha: f64,
    estimator: Box<dyn Estimator>,
}

impl RingCoupled {
    /// A checked controller: n ≥ 2, α ≥ 0, with a built-in estimator.
    pub fn new(gains: Gains, alpha: f64, estimator: EstimatorKind) -> Result<Self, ControlError> {
        Self::with_estimator(gains, alpha, estimator.build())
    }

    /// A checked controller with any estimator (which the law then owns).
    pub fn with_estimator(
        gains: Gains,
        alpha: f64,
        estimator: Box<dyn Estimator>,
    ) -> Result<Self, ControlError> {
        gains.validate()?;
        if gains.axes() < 2 {
            return Err(ControlError::TooFewAxes {
                what: "ring coupling",
                n: gains.axes(),
                min: 2,
            });
        }
        check_gain("alpha", alpha, 0.0, false, ">= 0 ..= 1e12 (dimensionless)")?;
        Ok(RingCoupled {
            gains,
            alpha,
            estimator,
        })
    }
}

impl ControlLaw for RingCoupled {
    fn name(&self) -> &'static str {
        "ring-coupled"
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
        let a = self.alpha;
        for k in 0..n {
            let [(pe, pde), (ne, nde)] = ring_neighbours(self.estimator.as_ref(), h, input, k);
            let (e0, de0) = (h.e[k][0], h.de[k][0]);
            let big_e = e0 + a * (2.0 * e0 - pe - ne);
            let big_de = de0 + a * (2.0 * de0 - pde - nde);
            let raw = g.feed_forward(k, &input.desired[k]) + g.kp[k] * big_e + g.kd[k] * big_de;
            out.set(k, raw, g.u_max[k]);
        }
    }
}
