//! The reference scenario's axes (docs/system.md, "The reference scenario", the project's reconstruction of the
//! paper's test bench): voltage-commanded torque-mode drives, ±10 V = ± rated torque, on
//! Yaskawa SGM7J-01A, -02A, -04A, -08A motors with loads.

use crate::axis::{AxisModel, Friction, SignModel, TorqueAxis};
use crate::error::PlantError;

/// Rated torque of the four motors [N·m] (0.318 is the SGM7J-01A's, not 1/π).
#[allow(clippy::approx_constant)]
pub const RATED_TORQUE: [f64; 4] = [0.318, 0.637, 1.27, 2.39];
/// Total inertia over torque constant, J/K_a [s²·V/rad]: J = (4.96, 10.26, 20.07, 39.20)·10⁻⁴ kg·m².
pub const J_OVER_KA: [f64; 4] = [0.0156, 0.0161, 0.0158, 0.0164];
/// Viscous friction b [N·m·s/rad].
pub const VISCOUS: [f64; 4] = [1e-5, 2e-5, 4e-5, 8e-5];
/// Coulomb friction as a fraction of rated torque.
pub const COULOMB_FRACTION: f64 = 0.02;
/// Drive range ±u_max \[V\].
pub const U_MAX: f64 = 10.0;

/// The four reference axes. With `coulomb` = `None` they have viscous friction only (the
/// linear axes of the discrete-time stability check); otherwise Coulomb friction of 2 % of
/// rated torque with the given sign model (docs/system.md, "The reference scenario": smoothed, tanh(ẋ / 1 mrad/s)).
pub fn axes(coulomb: Option<SignModel>) -> Result<Vec<AxisModel>, PlantError> {
    (0..4)
        .map(|i| {
            let ka = RATED_TORQUE[i] / U_MAX;
            let friction = match coulomb {
                None => Friction::viscous(VISCOUS[i]),
                Some(sign) => Friction {
                    viscous: VISCOUS[i],
                    coulomb: COULOMB_FRACTION * RATED_TORQUE[i],
                    sign,
                },
            };
            TorqueAxis::new(J_OVER_KA[i] * ka, ka, friction, U_MAX).map(AxisModel::Torque)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inertias_match_the_spec() {
        // docs/system.md, "The reference scenario": J ≈ (4.96, 10.26, 20.07, 39.20)·10⁻⁴ kg·m².
        let want = [4.96e-4, 10.26e-4, 20.07e-4, 39.20e-4];
        for (m, w) in axes(None).expect("axes").iter().zip(want) {
            let AxisModel::Torque(a) = m else {
                panic!("torque axis")
            };
            assert!((a.inertia - w).abs() < 0.005e-4, "{} vs {w}", a.inertia);
        }
    }
}
