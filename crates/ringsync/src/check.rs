//! The stability check of a scenario's loop: the discrete-time spectral radius of the
//! sampled closed loop with each axis's delay, and the paper's continuous-time conditions
//! (docs/system.md, "Stability").

use ringsync_model::Scenario;
pub use ringsync_model::check::{CheckReport, Verdict};

use crate::error::Result;

/// Checks `s` with the paper's conditions evaluated at `points` instants of its motion.
///
/// ```
/// let s = ringsync::load("paper-2015")?.scenario;
/// let r = ringsync::check(&s, 101)?;
/// assert_eq!(r.verdict(), ringsync::Verdict::Stable);
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn check(s: &Scenario, points: usize) -> Result<CheckReport> {
    Ok(ringsync_model::check::check(s, points)?)
}
