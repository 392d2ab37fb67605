//! Standard PD, the paper's baseline: u = K_P·e + K_D·ė, each axis on its own latest sample,
//! with optional feed-forward K_H·ẍ^d + K_C·ẋ^d.

use super::registry::LawEntry;
use super::{ControlInput, ControlLaw, ControlOutput, Gains};
use crate::error::ControlError;
use crate::estimator::ErrorHistory;

/// The registry's entry: `pd`, no parameters of its own; feed-forward when the scenario sets
/// K_H or K_C.
pub const ENTRY: LawEntry = LawEntry {
    name: "pd",
    description: "standard PD, the paper's baseline: u = K_P·e + K_D·ė on each axis's own latest sample (named pd+ff with K_H·ẍ^d + K_C·ẋ^d)",
    min_axes: 1,
    params: &[],
    make: |p| Ok(Box::new(Pd::new(p.gains.clone(), p.feed_forward)?)),
};

/// The standard PD controller.
#[derive(Debug, Clone, PartialEq)]
pub struct Pd {
    gains: Gains,
    feed_forward: bool,
}

impl Pd {
    /// A checked PD law; with `feed_forward` the K_H, K_C and K_F terms are added.
    pub fn new(gains: Gains, feed_forward: bool) -> Result<Self, ControlError> {
        gains.validate()?;
        Ok(Pd {
            gains,
            feed_forward,
        })
    }
}

impl ControlLaw for Pd {
    /// `pd`, or `pd+ff` with the feed-forward on.
    fn name(&self) -> &'static str {
        if self.feed_forward { "pd+ff" } else { "pd" }
    }
    fn axes(&self) -> usize {
        self.gains.axes()
    }
    #[inline]
    fn evaluate(&self, h: &ErrorHistory, input: &ControlInput, out: &mut ControlOutput) {
        let n = self.axes();
        let g = &self.gains;
        for i in 0..n {
            let ff = if self.feed_forward {
                g.feed_forward(i, &input.desired[i])
            } else {
                0.0
            };
            let raw = ff + g.kp[i] * h.e[i][0] + g.kd[i] * h.de[i][0];
            out.set(i, raw, g.u_max[i]);
        }
    }
}
