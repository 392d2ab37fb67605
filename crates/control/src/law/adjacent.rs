//! Adjacent cross-coupling, the fixed-gain form used for multi-motor synchronisation: each
//! axis is held against its two ring neighbours' errors through coupling gains of its own,
//! independent of its tracking gains (docs/control.md, "Adjacent cross-coupling"):
//!
//! ```text
//! ε_k = e_k − e'_{k+1}                     (synchronisation error to the next axis)
//! u_k = K_H,k·ẍ^d_k + K_C,k·ẋ^d_k + K_P,k·e_k + K_D,k·ė_k
//!       + K_X,k·(ε_k − ε_{k−1}) + K_XD,k·(ε̇_k − ε̇_{k−1})
//! ε_k − ε_{k−1} = 2·e_k − e'_{k−1} − e'_{k+1}
//! ```
//!
//! (indices modulo n). The synchronisation errors are those of Sun (2003), "Position
//! synchronization of multiple motion axes with adaptive coupling control", Automatica 39;
//! this is their fixed-gain PD form, not that paper's adaptive law. The neighbours' samples
//! e'_j are extrapolated to axis k's application time by the motion message estimator, as
//! in the sync and ring-coupled laws. With K_X = α·K_P and K_XD = α·K_D it is the
//! ring-coupled law (tested); with K_X = K_XD = 0 it is standard PD with feed-forward.

use super::registry::{LawEntry, ParamSpec};
use super::{ControlInput, ControlLaw, ControlOutput, Gains, ring_neighbours};
use crate::error::{ControlError, check, check_len};
use crate::estimator::{ErrorHistory, Estimator, EstimatorKind};

/// The registry's entry: `adjacent`, from K_P, K_D, K_H, K_C, the estimator and its own
/// coupling gains `kx` and `kxd`, one per axis.
pub const ENTRY: LawEntry = LawEntry {
    name: "adjacent",
    description: "adjacent cross-coupling: each axis against its two ring neighbours' errors with its own gains K_X, K_XD (the synchronisation errors of Sun 2003, fixed gains), the neighbours through the estimator",
    min_axes: 2,
    params: &[
        ParamSpec {
            key: "kx",
            doc: "coupling gain K_X on ε_k − ε_{k−1} = 2·e_k − e_{k−1} − e_{k+1}",
            unit: "V/rad",
            default: 1.591,
            min: 0.0,
            max: f64::INFINITY,
        },
        ParamSpec {
            key: "kxd",
            doc: "coupling gain K_XD on the same combination of ė",
            unit: "V·s/rad",
            default: 0.7955,
            min: 0.0,
            max: f64::INFINITY,
        },
    ],
    make: |p| {
        Ok(Box::new(AdjacentCoupled::new(
            p.gains.clone(),
            p.values(ENTRY.name, "kx")?.to_vec(),
            p.values(ENTRY.name, "kxd")?.to_vec(),
            p.sync.estimator,
        )?))
    },
};

/// The adjacent cross-coupling controller.
#[derive(Debug)]
pub struct AdjacentCoupled {
    gains: Gains,
    kx: Vec<f64>,
    kxd: Vec<f64>,
    estimator: Box<dyn Estimator>,
}

impl AdjacentCoupled {
    /// A checked controller: n ≥ 2, one K_X [V/rad] and one K_XD [V·s/rad] per axis, each
    /// ≥ 0, with a built-in estimator.
    pub fn new(
        gains: Gains,
        kx: Vec<f64>,
        kxd: Vec<f64>,
        estimator: EstimatorKind,
    ) -> Result<Self, ControlError> {
        Self::with_estimator(gains, kx, kxd, estimator.build())
    }

    /// A checked controller with any estimator (which the law then owns; it may keep state:
    /// [`Estimator::observe`]).
    pub fn with_estimator(
        gains: Gains,
        kx: Vec<f64>,
        kxd: Vec<f64>,
        estimator: Box<dyn Estimator>,
    ) -> Result<Self, ControlError> {
        gains.validate()?;
        let n = gains.axes();
        if n < 2 {
            return Err(ControlError::TooFewAxes {
                what: "adjacent cross-coupling",
                n,
                min: 2,
            });
        }
        check_len("kx", n, kx.len())?;
        check_len("kxd", n, kxd.len())?;
        for i in 0..n {
            check(&format!("kx[{i}]"), kx[i], 0.0, false, ">= 0 V/rad")?;
            check(&format!("kxd[{i}]"), kxd[i], 0.0, false, ">= 0 V·s/rad")?;
        }
        Ok(AdjacentCoupled {
            gains,
            kx,
            kxd,
            estimator,
        })
    }
}

impl ControlLaw for AdjacentCoupled {
    fn name(&self) -> &'static str {
        ENTRY.name
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
        for k in 0..n {
            let [(pe, pde), (ne, nde)] = ring_neighbours(self.estimator.as_ref(), h, input, k);
            let (e0, de0) = (h.e[k][0], h.de[k][0]);
            let sync = 2.0 * e0 - pe - ne;
            let dsync = 2.0 * de0 - pde - nde;
            let raw = g.feed_forward(k, &input.desired[k])
                + g.kp[k] * e0
                + g.kd[k] * de0
                + self.kx[k] * sync
                + self.kxd[k] * dsync;
            out.set(k, raw, g.u_max[k]);
        }
    }
}
