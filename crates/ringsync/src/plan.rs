//! The cycle-time planner (eq. 1-2): how fast a ring of n axes can cycle and where the time
//! goes, for given link figures or for a scenario's ring.

use ringsync_model::Scenario;
use ringsync_proto::{CyclePlan, PlanKind, RingParams};

use crate::error::Result;

/// The plan of a ring with these figures, checked to fit its cycle with the plan `kind`.
/// The error names the [`RingParams`] field that is out of range, or how much the cycle
/// is short.
///
/// ```
/// use ringsync::{PlanKind, RingParams};
/// let p = ringsync::plan(&RingParams::default(), PlanKind::P2pLumped)?;
/// // The reference ring (4 axes, 100 Mbit/s) needs far less than its 1 ms cycle.
/// assert!(p.min_t_cyc.as_ns() < 1_000_000);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn plan(params: &RingParams, kind: PlanKind) -> Result<CyclePlan> {
    let plan = CyclePlan::new(params)?;
    plan.check_fits_for(kind)?;
    Ok(plan)
}

/// The plan of a scenario's ring (its plan kind).
pub fn plan_of(s: &Scenario) -> Result<CyclePlan> {
    plan(&s.ring_params(), s.ring.plan)
}
