//! A coupled plant: the planar two-link arm (no gravity), H(q)q̈ + C(q, q̇)q̇ + F q̇ = τ.
//!
//! M(q) = [[p1 + 2·p3·cos q2, p2 + p3·cos q2], [p2 + p3·cos q2, p2]], with h = −p3·sin q2,
//! C(q, q̇) = [[h·q̇2, h·(q̇1 + q̇2)], [−h·q̇1, 0]], F = diag(f1, f2). With this C,
//! Ṁ − 2C is skew-symmetric (tested).

use crate::error::{PlantError, check};
use crate::integrate::rk4;
use crate::{Dynamics, Plant, saturate};

/// Parameters of the two-link arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmParams {
    /// p1 [kg·m²].
    pub p1: f64,
    /// p2 [kg·m²].
    pub p2: f64,
    /// p3 [kg·m²].
    pub p3: f64,
    /// Viscous friction of joint 1, f1 [N·m·s/rad].
    pub f1: f64,
    /// Viscous friction of joint 2, f2 [N·m·s/rad].
    pub f2: f64,
    /// Torque per volt of each joint's drive, K_a,1 and K_a,2 [N·m/V]: τ_i = K_a,i·sat(u_i).
    pub torque_constant: [f64; 2],
    /// Command range of each joint's drive, ±u_max,i \[V\].
    pub u_max: [f64; 2],
    /// Largest RK4 step \[s\].
    pub max_step: f64,
}

impl Default for ArmParams {
    /// The arm of the control issue: p = (3.473, 0.196, 0.242) kg·m², f = (5.3, 1.1) N·m·s,
    /// with drives of 10 N·m/V and ±10 V on both joints.
    fn default() -> Self {
        ArmParams {
            p1: 3.473,
            p2: 0.196,
            p3: 0.242,
            f1: 5.3,
            f2: 1.1,
            torque_constant: [10.0; 2],
            u_max: [10.0; 2],
            max_step: 1e-4,
        }
    }
}

impl ArmParams {
    /// M(q) [kg·m²], row-major, at joint-2 angle `q2` \[rad\] (the arm's inertia depends on
    /// q2 only).
    pub fn mass_matrix(&self, q2: f64) -> [f64; 4] {
        let c = q2.cos();
        [
            self.p1 + 2.0 * self.p3 * c,
            self.p2 + self.p3 * c,
            self.p2 + self.p3 * c,
            self.p2,
        ]
    }

    /// The smallest eigenvalue of S·M(q)·S over every configuration q, S = diag(`scale`)
    /// [kg·m² times the scale's unit squared]; ≤ 0 when M is not positive definite.
    /// S = (1, 1) gives the smallest inertia of any motion [kg·m²]; S = K_a^(−1/2) the
    /// smallest of H = M/K_a as the drives see it [V·s²/rad]. M is affine in cos q2 and the
    /// smallest eigenvalue of a symmetric matrix is concave in it, so the minimum lies at
    /// cos q2 = ±1.
    pub fn min_inertia(&self, scale: [f64; 2]) -> f64 {
        [0.0, std::f64::consts::PI]
            .iter()
            .map(|&q2| {
                let m = self.mass_matrix(q2);
                let (a, b, d) = (
                    m[0] * scale[0] * scale[0],
                    m[1] * scale[0] * scale[1],
                    m[3] * scale[1] * scale[1],
                );
                0.5 * (a + d) - (0.25 * (a - d) * (a - d) + b * b).sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The largest eigenvalue of M(q) over every configuration q [kg·m²] (convex in cos q2:
    /// the maximum lies at cos q2 = ±1).
    pub fn max_inertia(&self) -> f64 {
        [0.0, std::f64::consts::PI]
            .iter()
            .map(|&q2| {
                let m = self.mass_matrix(q2);
                let (a, b, d) = (m[0], m[1], m[3]);
                0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt()
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// The two-link arm with its state.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoLinkArm {
    /// Parameters.
    pub params: ArmParams,
    q: [f64; 2],
    qd: [f64; 2],
}

impl TwoLinkArm {
    /// A checked arm at rest at q = 0. M must be positive definite: p2 > 0 and
    /// p1·p2 − p2² − p3² > 0 (its smallest determinant, at cos q2 = ±1).
    pub fn new(params: ArmParams) -> Result<Self, PlantError> {
        let p = &params;
        check("p1", p.p1, 0.0, true, "> 0 kg·m²")?;
        check("p2", p.p2, 0.0, true, "> 0 kg·m²")?;
        check("p3", p.p3, 0.0, false, ">= 0 kg·m²")?;
        check("f1", p.f1, 0.0, false, ">= 0 N·m·s/rad")?;
        check("f2", p.f2, 0.0, false, ">= 0 N·m·s/rad")?;
        for j in 0..2 {
            check(
                "torque_constant",
                p.torque_constant[j],
                0.0,
                true,
                "> 0 N·m/V",
            )?;
            check("u_max", p.u_max[j], 0.0, true, "> 0 V")?;
        }
        check("max_step", p.max_step, 0.0, true, "> 0 s")?;
        let det_min = p.p1 * p.p2 - p.p2 * p.p2 - p.p3 * p.p3;
        if det_min.is_nan() || det_min <= 0.0 {
            return Err(PlantError::InvalidParameter {
                name: "p3",
                value: p.p3,
                expected: "p1·p2 − p2² − p3² > 0 (inertia matrix positive definite)",
            });
        }
        Ok(TwoLinkArm {
            params,
            q: [0.0; 2],
            qd: [0.0; 2],
        })
    }

    /// Sets the joint state [rad, rad/s].
    pub fn set_state(&mut self, q: [f64; 2], qd: [f64; 2]) {
        self.q = q;
        self.qd = qd;
    }

    /// M(q) [kg·m²], row-major.
    pub fn mass_matrix(&self, q2: f64) -> [f64; 4] {
        self.params.mass_matrix(q2)
    }

    /// The Coriolis/centripetal matrix C(q, q̇) [kg·m²/s], row-major (no friction).
    pub fn coriolis_matrix(&self, q2: f64, qd: [f64; 2]) -> [f64; 4] {
        let h = -self.params.p3 * q2.sin();
        [h * qd[1], h * (qd[0] + qd[1]), -h * qd[0], 0.0]
    }

    /// Ṁ(q, q̇) [kg·m²/s], row-major.
    pub fn mass_matrix_rate(&self, q2: f64, qd2: f64) -> [f64; 4] {
        let s = -self.params.p3 * q2.sin() * qd2;
        [2.0 * s, s, s, 0.0]
    }

    /// Joint accelerations for state (q, q̇) and joint torques τ [N·m].
    pub fn acceleration(&self, q: [f64; 2], qd: [f64; 2], tau: [f64; 2]) -> [f64; 2] {
        let m = self.mass_matrix(q[1]);
        let c = self.coriolis_matrix(q[1], qd);
        let p = &self.params;
        let r0 = tau[0] - c[0] * qd[0] - c[1] * qd[1] - p.f1 * qd[0];
        let r1 = tau[1] - c[2] * qd[0] - c[3] * qd[1] - p.f2 * qd[1];
        let det = m[0] * m[3] - m[1] * m[2];
        [(m[3] * r0 - m[1] * r1) / det, (m[0] * r1 - m[2] * r0) / det]
    }

    /// Joint torques τ = M(q)q̈ + C(q, q̇)q̇ + F·q̇ [N·m] that give the accelerations `qdd`
    /// [rad/s²] in state (q \[rad\], q̇ [rad/s]): the inverse of [`TwoLinkArm::acceleration`].
    pub fn inverse_dynamics(&self, q: [f64; 2], qd: [f64; 2], qdd: [f64; 2]) -> [f64; 2] {
        let m = self.mass_matrix(q[1]);
        let c = self.coriolis_matrix(q[1], qd);
        let p = &self.params;
        [
            m[0] * qdd[0] + m[1] * qdd[1] + c[0] * qd[0] + c[1] * qd[1] + p.f1 * qd[0],
            m[2] * qdd[0] + m[3] * qdd[1] + c[2] * qd[0] + c[3] * qd[1] + p.f2 * qd[1],
        ]
    }

    /// Advances both joints together by `dt` \[s\] with the commands `u` \[V\] held: each
    /// clipped to its drive's ±u_max,i and turned into τ_i = K_a,i·sat(u_i), then RK4 in
    /// steps of at most `max_step`.
    pub fn advance_held(&mut self, u: [f64; 2], dt: f64) {
        let p = self.params;
        let tau = [
            p.torque_constant[0] * saturate(u[0], p.u_max[0]).0,
            p.torque_constant[1] * saturate(u[1], p.u_max[1]).0,
        ];
        let mut y = [self.q[0], self.q[1], self.qd[0], self.qd[1]];
        let mut scratch = [0.0; 20];
        let arm = &*self;
        rk4(&mut y, dt, p.max_step, &mut scratch, |y, d| {
            let a = arm.acceleration([y[0], y[1]], [y[2], y[3]], tau);
            d[0] = y[2];
            d[1] = y[3];
            d[2] = a[0];
            d[3] = a[1];
        });
        self.q = [y[0], y[1]];
        self.qd = [y[2], y[3]];
    }

    /// K_a⁻¹·`m` (row i divided by joint i's torque constant), written into `out`.
    fn per_volt(&self, m: [f64; 4], out: &mut [f64]) {
        for (k, (o, v)) in out.iter_mut().zip(m).enumerate() {
            *o = v / self.params.torque_constant[k / 2];
        }
    }

    /// Kinetic energy ½·q̇ᵀM q̇ \[J\].
    pub fn kinetic_energy(&self) -> f64 {
        let m = self.mass_matrix(self.q[1]);
        let qd = self.qd;
        0.5 * (qd[0] * (m[0] * qd[0] + m[1] * qd[1]) + qd[1] * (m[2] * qd[0] + m[3] * qd[1]))
    }
}

impl Plant for TwoLinkArm {
    fn axes(&self) -> usize {
        2
    }
    fn position(&self, i: usize) -> f64 {
        self.q[i]
    }
    fn velocity(&self, i: usize) -> f64 {
        self.qd[i]
    }
    fn advance(&mut self, u: &[f64], dt: f64) -> Result<(), PlantError> {
        if u.len() != 2 {
            return Err(PlantError::LengthMismatch {
                what: "commands",
                expected: 2,
                got: u.len(),
            });
        }
        self.advance_held([u[0], u[1]], dt);
        Ok(())
    }
}

/// In the controller's units: H = K_a⁻¹·M, C = K_a⁻¹·(C_coriolis + F) (viscous friction is
/// part of the velocity term of eq. 8), Ḣ = K_a⁻¹·Ṁ, with K_a = diag(K_a,1, K_a,2): row i is
/// divided by joint i's torque constant. H is symmetric, as the theory's form needs, only
/// when both torque constants are equal.
impl Dynamics for TwoLinkArm {
    fn dof(&self) -> usize {
        2
    }
    fn inertia(&self, x: &[f64], h: &mut [f64]) {
        let m = self.mass_matrix(x[1]);
        self.per_volt(m, h);
    }
    fn coriolis(&self, x: &[f64], v: &[f64], c: &mut [f64]) {
        let mut m = self.coriolis_matrix(x[1], [v[0], v[1]]);
        m[0] += self.params.f1;
        m[3] += self.params.f2;
        self.per_volt(m, c);
    }
    fn inertia_rate(&self, x: &[f64], v: &[f64], hd: &mut [f64]) {
        let m = self.mass_matrix_rate(x[1], v[1]);
        self.per_volt(m, hd);
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// Ṁ − 2C is skew-symmetric for every state.
        #[test]
        fn mdot_minus_2c_is_skew(q2 in -10.0f64..10.0, qd1 in -20.0f64..20.0, qd2 in -20.0f64..20.0) {
            let arm = TwoLinkArm::new(ArmParams::default()).expect("arm");
            let md = arm.mass_matrix_rate(q2, qd2);
            let c = arm.coriolis_matrix(q2, [qd1, qd2]);
            let n = [md[0] - 2.0 * c[0], md[1] - 2.0 * c[1], md[2] - 2.0 * c[2], md[3] - 2.0 * c[3]];
            prop_assert!(n[0].abs() < 1e-12 && n[3].abs() < 1e-12);
            prop_assert!((n[1] + n[2]).abs() < 1e-12);
        }

        /// M(q) is symmetric positive definite.
        #[test]
        fn mass_matrix_is_spd(q2 in -10.0f64..10.0) {
            let arm = TwoLinkArm::new(ArmParams::default()).expect("arm");
            let m = arm.mass_matrix(q2);
            prop_assert_eq!(m[1], m[2]);
            prop_assert!(m[0] > 0.0 && m[0] * m[3] - m[1] * m[2] > 0.0);
        }

        /// The inverse dynamics undo the forward dynamics in any state.
        #[test]
        fn inverse_dynamics_inverts_acceleration(
            q1 in -10.0f64..10.0, q2 in -10.0f64..10.0,
            qd1 in -20.0f64..20.0, qd2 in -20.0f64..20.0,
            a1 in -100.0f64..100.0, a2 in -100.0f64..100.0,
        ) {
            let arm = TwoLinkArm::new(ArmParams::default()).expect("arm");
            let tau = arm.inverse_dynamics([q1, q2], [qd1, qd2], [a1, a2]);
            let a = arm.acceleration([q1, q2], [qd1, qd2], tau);
            prop_assert!((a[0] - a1).abs() < 1e-9 * (1.0 + a1.abs()), "{a:?}");
            prop_assert!((a[1] - a2).abs() < 1e-9 * (1.0 + a2.abs()), "{a:?}");
        }
    }

    /// The smallest and largest inertia over all configurations bound the eigenvalues of
    /// M(q) on a fine grid of q2, and a grid point comes within 1e-6 of each.
    #[test]
    fn inertia_extremes_bound_every_configuration() {
        let p = ArmParams {
            p1: 0.15,
            p2: 0.02,
            p3: 0.03,
            ..ArmParams::default()
        };
        let scale = [1.0 / 2.0f64.sqrt(), 1.0 / 0.5f64.sqrt()];
        let (lo, lo_scaled, hi) = (
            p.min_inertia([1.0; 2]),
            p.min_inertia(scale),
            p.max_inertia(),
        );
        let (mut grid_lo, mut grid_lo_scaled, mut grid_hi) = (f64::INFINITY, f64::INFINITY, 0.0f64);
        for k in 0..=20_000 {
            let q2 = -4.0 + 8.0 * k as f64 / 20_000.0;
            let m = p.mass_matrix(q2);
            let eig = |a: f64, b: f64, d: f64| {
                let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
                (0.5 * (a + d) - r, 0.5 * (a + d) + r)
            };
            let (l, h) = eig(m[0], m[1], m[3]);
            let (ls, _) = eig(
                m[0] * scale[0] * scale[0],
                m[1] * scale[0] * scale[1],
                m[3] * scale[1] * scale[1],
            );
            grid_lo = grid_lo.min(l);
            grid_hi = grid_hi.max(h);
            grid_lo_scaled = grid_lo_scaled.min(ls);
        }
        assert!(
            lo > 0.0 && lo <= grid_lo && grid_lo - lo < 1e-6,
            "{lo} {grid_lo}"
        );
        assert!(hi >= grid_hi && hi - grid_hi < 1e-6, "{hi} {grid_hi}");
        assert!(
            lo_scaled <= grid_lo_scaled && grid_lo_scaled - lo_scaled < 1e-6,
            "{lo_scaled} {grid_lo_scaled}"
        );
        // Not positive definite: p3² > p1·p2 − p2².
        assert!(ArmParams { p3: 0.06, ..p }.min_inertia([1.0; 2]) < 0.0);
    }

    /// Each joint's drive has its own torque constant and range: from rest at q = 0 a short
    /// step accelerates the arm as M⁻¹·(K_a,1·sat(u_1), K_a,2·sat(u_2)), and a command beyond
    /// joint 2's range acts as its limit.
    #[test]
    fn each_joint_has_its_own_drive() {
        let p = ArmParams {
            torque_constant: [2.0, 0.5],
            u_max: [10.0, 4.0],
            ..ArmParams::default()
        };
        let arm = TwoLinkArm::new(p).expect("arm");
        let dt = 1e-6;
        let step = |u: [f64; 2]| {
            let mut a = arm.clone();
            a.advance_held(u, dt);
            [a.velocity(0) / dt, a.velocity(1) / dt]
        };
        let got = step([3.0, 9.0]);
        let want = arm.acceleration([0.0; 2], [0.0; 2], [2.0 * 3.0, 0.5 * 4.0]);
        for j in 0..2 {
            assert!(
                (got[j] - want[j]).abs() < 1e-4 * want[j].abs(),
                "{got:?} vs {want:?}"
            );
        }
        assert_eq!(step([3.0, 9.0]), step([3.0, 4.0]));
        assert_ne!(step([3.0, 3.9]), step([3.0, 4.0]));
    }

    /// Without friction and torque the kinetic energy is conserved.
    #[test]
    fn free_motion_conserves_energy() {
        let mut arm = TwoLinkArm::new(ArmParams {
            f1: 0.0,
            f2: 0.0,
            ..ArmParams::default()
        })
        .expect("arm");
        arm.set_state([0.1, 0.7], [2.0, -3.0]);
        let e0 = arm.kinetic_energy();
        for _ in 0..1000 {
            arm.advance(&[0.0, 0.0], 1e-3).expect("advance");
        }
        assert!(
            (arm.kinetic_energy() - e0).abs() < 1e-9 * e0,
            "{} vs {e0}",
            arm.kinetic_energy()
        );
        assert!(arm.position(1) != 0.7, "the arm moved");
    }

    /// Energy balance: ΔKE = ∫ q̇ᵀτ dt − ∫ q̇ᵀF q̇ dt (the Coriolis terms do no work).
    #[test]
    fn energy_balance_with_torque_and_friction() {
        let p = ArmParams::default();
        let mut arm = TwoLinkArm::new(p).expect("arm");
        arm.set_state([0.0, 0.3], [0.5, -0.5]);
        let e0 = arm.kinetic_energy();
        let u = [0.4, -0.2];
        let tau = [p.torque_constant[0] * u[0], p.torque_constant[1] * u[1]];
        let power = |a: &TwoLinkArm| {
            let v = [a.velocity(0), a.velocity(1)];
            v[0] * tau[0] + v[1] * tau[1] - p.f1 * v[0] * v[0] - p.f2 * v[1] * v[1]
        };
        let dt = 1e-4;
        let mut work = 0.0;
        let mut p0 = power(&arm);
        for _ in 0..5000 {
            arm.advance(&u, dt).expect("advance");
            let p1 = power(&arm);
            work += 0.5 * (p0 + p1) * dt;
            p0 = p1;
        }
        let de = arm.kinetic_energy() - e0;
        assert!(
            (de - work).abs() < 1e-4 * work.abs().max(1e-3),
            "ΔKE {de} vs work {work}"
        );
    }

    #[test]
    fn bad_arm_is_named() {
        let e = TwoLinkArm::new(ArmParams {
            p3: 1.0,
            ..ArmParams::default()
        })
        .expect_err("not SPD");
        assert!(e.to_string().contains("p3"), "{e}");
        assert!(
            TwoLinkArm::new(ArmParams {
                p1: -1.0,
                ..ArmParams::default()
            })
            .is_err()
        );
    }
}
