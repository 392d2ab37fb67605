//! Plants for ringsync: what the axes do with the commands (docs/system.md, "Plant and controller" and "The reference scenario").
//!
//! - [`TorqueAxis`]: a voltage-commanded torque-mode drive, J ẍ = K_a·sat(u) − b·ẋ − T_c·sgn(ẋ).
//! - [`VelocityAxis`]: a drive that closes its own velocity loop (first-order lag).
//! - [`TwoLinkArm`]: a coupled plant H(x)ẍ + C(x, ẋ)ẋ = τ (planar arm, no gravity).
//! - [`Encoder`]: quantisation to counts and velocity by encoder difference.
//!
//! Every plant advances over an interval with its commands held ([`Plant::advance`]). Linear
//! parts are stepped by exact discretisation; the rest by RK4 with a maximum step
//! ([`integrate`]). Units: positions in rad, velocities in rad/s, commands in V, time in s.

mod arm;
mod axis;
mod encoder;
mod error;
pub mod integrate;
pub mod reference;
pub mod rounding;

pub use arm::{ArmParams, TwoLinkArm};
pub use axis::{
    AxisModel, Discretised, Friction, IndependentAxes, SignModel, TorqueAxis, VelocityAxis,
};
pub use encoder::Encoder;
pub use error::PlantError;

/// A multi-axis plant: state, and how it evolves under held commands.
pub trait Plant {
    /// Number of axes.
    fn axes(&self) -> usize;
    /// Position of axis `i` \[rad\].
    fn position(&self, i: usize) -> f64;
    /// Velocity of axis `i` [rad/s].
    fn velocity(&self, i: usize) -> f64;
    /// Advances the state by `dt` \[s\] with the commands `u` \[V\] held; `u.len()` must equal
    /// [`Plant::axes`].
    fn advance(&mut self, u: &[f64], dt: f64) -> Result<(), PlantError>;
}

/// Dynamics in the theory's form H(x)ẍ + C(x, ẋ)ẋ = τ (eq. 8), in the controller's units
/// (τ in V: H in V·s²/rad, C in V·s/rad; docs/system.md, "Plant and controller"), for the stability checks.
pub trait Dynamics {
    /// Number of axes n.
    fn dof(&self) -> usize;
    /// H(x), row-major n×n, written into `h`.
    fn inertia(&self, x: &[f64], h: &mut [f64]);
    /// C(x, ẋ), row-major n×n, written into `c`.
    fn coriolis(&self, x: &[f64], v: &[f64], c: &mut [f64]);
    /// Ḣ(x, ẋ), row-major n×n, written into `hd`.
    fn inertia_rate(&self, x: &[f64], v: &[f64], hd: &mut [f64]);
}

/// Clips `u` to ±`limit`; returns the clipped value and whether it was clipped.
pub fn saturate(u: f64, limit: f64) -> (f64, bool) {
    if u > limit {
        (limit, true)
    } else if u < -limit {
        (-limit, true)
    } else {
        (u, false)
    }
}
