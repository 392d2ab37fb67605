//! `[plant]`: what the axes are mechanically (docs/simulator.md, "The plant").
//!
//! - `kind = "independent"` (the default, also when the table is missing): every axis is the
//!   drive and mechanics of its own `[[axis]]` table, on its own (the paper's experiment).
//! - `kind = "two-link-arm"`: the ring's two axes are the joints of a planar two-link arm,
//!   M(q)q̈ + C(q, q̇)q̇ + F·q̇ = τ, τ_i = K_a,i·sat(u_i). Each joint keeps its `[[axis]]`
//!   table's drive range `u_max`, encoder (`encoder_bits`) and `velocity_window`; the
//!   tables' mechanical keys (`model`, `rated_torque`, `j_over_ka`, `viscous`, `coulomb_*`,
//!   `velocity_gain`, `time_constant`) are not used.

use ringsync_plant::ArmParams;
use serde::Deserialize;

use super::error::{ScenarioError, out_of_range};
use super::schema::{PerAxis, Scenario};

/// Largest RK4 step of the arm \[s\] (`ringsync_plant::ArmParams`'s default); smaller when the
/// friction is stiff against the inertia (see [`ArmSpec::params`]).
pub const ARM_MAX_STEP: f64 = 1e-4;

/// `[plant]`: independent axes, or the coupled two-link arm.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum PlantSpec {
    /// Every axis on its own, from its `[[axis]]` table (no keys of its own).
    Independent {},
    /// The planar two-link arm on a ring of two slaves.
    TwoLinkArm(ArmSpec),
}

impl Default for PlantSpec {
    fn default() -> Self {
        PlantSpec::Independent {}
    }
}

impl PlantSpec {
    /// The name in scenario files and outputs.
    pub fn name(&self) -> &'static str {
        match self {
            PlantSpec::Independent {} => "independent",
            PlantSpec::TwoLinkArm(_) => "two-link-arm",
        }
    }

    /// The arm's parameters, for `kind = "two-link-arm"`.
    pub fn arm(&self) -> Option<&ArmSpec> {
        match self {
            PlantSpec::Independent {} => None,
            PlantSpec::TwoLinkArm(a) => Some(a),
        }
    }
}

/// The keys of `[plant]` with `kind = "two-link-arm"`: the arm's inertia parameters (p1, p2,
/// p3), its viscous joint friction and its drives' torque constants. The defaults are a
/// small arm: links of about 0.25 m and 1-2 kg (docs/simulator.md, "The plant").
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmSpec {
    /// p1 = m1·l_c1² + m2·(l1² + l_c2²) + I1 + I2 [kg·m²], > p2.
    pub p1: f64,
    /// p2 = m2·l_c2² + I2 [kg·m²], > 0.
    pub p2: f64,
    /// p3 = m2·l1·l_c2 [kg·m²], ≥ 0 with p3² < p2·(p1 − p2) (M(q) positive definite).
    pub p3: f64,
    /// Viscous friction of each joint, f1 and f2 [N·m·s/rad], ≥ 0: one value for both
    /// joints or a list of two.
    pub friction: PerAxis,
    /// Torque per volt of each joint's drive, K_a,1 and K_a,2 [N·m/V], > 0: one value for
    /// both joints or a list of two.
    pub torque_constant: PerAxis,
}

impl Default for ArmSpec {
    fn default() -> Self {
        ArmSpec {
            p1: 0.15,
            p2: 0.02,
            p3: 0.03,
            friction: PerAxis::Each(vec![0.05, 0.02]),
            torque_constant: PerAxis::Each(vec![2.0, 0.5]),
        }
    }
}

/// Shortest RK4 step of the arm's integration \[s\]: 1 µs (1000 steps per 1 ms cycle).
pub const MIN_ARM_STEP: f64 = 1e-6;

/// A computed figure for an error message: rounded to 6 decimals, in exponent form (6
/// significant digits) when very small or large.
fn number(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:.5e}")
    } else {
        format!("{}", (x * 1e6).round() / 1e6)
    }
}

/// The values of a per-joint key: one number for both joints, or a list of two.
fn per_joint(key: &str, v: &PerAxis) -> Result<[f64; 2], ScenarioError> {
    match v {
        PerAxis::Each(list) if list.len() != 2 => Err(out_of_range(
            key,
            format!("{list:?}"),
            "a number or a list of 2 values (joint 1, joint 2)",
        )),
        v => Ok([v.get(0), v.get(1)]),
    }
}

impl ArmSpec {
    /// Checks every key; the error names the first bad one (`plant.<key>`).
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let finite_above = |key: &str, v: f64, min: f64, strict: bool, allowed: &str| {
            let ok = v.is_finite() && if strict { v > min } else { v >= min };
            if ok {
                Ok(())
            } else {
                Err(out_of_range(key, number(v), allowed))
            }
        };
        finite_above("plant.p2", self.p2, 0.0, true, "> 0 kg·m²")?;
        finite_above(
            "plant.p1",
            self.p1,
            self.p2,
            true,
            &format!(
                "> plant.p2 = {} kg·m² (M(q) positive definite needs p1 > p2)",
                self.p2
            ),
        )?;
        let p3_max = (self.p2 * (self.p1 - self.p2)).sqrt();
        if !(self.p3.is_finite() && self.p3 >= 0.0 && self.p3 < p3_max) {
            return Err(out_of_range(
                "plant.p3",
                self.p3,
                format!(
                    "0 ..< {} kg·m² with p1 = {:?}, p2 = {:?} (M(q) positive definite in every configuration needs p3² < p2·(p1 − p2))",
                    number(p3_max),
                    self.p1,
                    self.p2
                ),
            ));
        }
        for (j, f) in per_joint("plant.friction", &self.friction)?
            .into_iter()
            .enumerate()
        {
            let key = format!("plant.friction (joint {})", j + 1);
            finite_above(&key, f, 0.0, false, ">= 0 N·m·s/rad")?;
        }
        for (j, k) in per_joint("plant.torque_constant", &self.torque_constant)?
            .into_iter()
            .enumerate()
        {
            let key = format!("plant.torque_constant (joint {})", j + 1);
            finite_above(&key, k, 0.0, true, "> 0 N·m/V")?;
        }
        // The arm is integrated in RK4 steps of at most a tenth of its fastest friction time
        // constant (`params`): refuse what would take steps too short to finish.
        let f_max = self.friction.get(0).max(self.friction.get(1));
        if self.params([1.0; 2]).max_step < MIN_ARM_STEP {
            let inertia = self.params([1.0; 2]).min_inertia([1.0; 2]);
            return Err(out_of_range(
                "plant.friction",
                format!("{f_max:?}"),
                format!(
                    "at most {} N·m·s/rad with this arm (λ_min(M) = {} kg·m²): it is integrated in steps of a tenth of its fastest friction time constant λ_min(M)/f, which must stay at or above {} s",
                    number(0.1 * inertia / MIN_ARM_STEP),
                    number(inertia),
                    number(MIN_ARM_STEP)
                ),
            ));
        }
        Ok(())
    }

    /// The plant's parameters with the joints' drive ranges `u_max` \[V\] (from their
    /// `[[axis]]` tables). The RK4 step is [`ARM_MAX_STEP`], or a tenth of the fastest
    /// friction time constant λ_min(M)/max(f1, f2) when that is shorter. Call on a validated
    /// spec.
    pub fn params(&self, u_max: [f64; 2]) -> ArmParams {
        let f = [self.friction.get(0), self.friction.get(1)];
        let mut p = ArmParams {
            p1: self.p1,
            p2: self.p2,
            p3: self.p3,
            f1: f[0],
            f2: f[1],
            torque_constant: [self.torque_constant.get(0), self.torque_constant.get(1)],
            u_max,
            max_step: ARM_MAX_STEP,
        };
        let f_max = f[0].max(f[1]);
        if f_max > 0.0 {
            p.max_step = p.max_step.min(0.1 * p.min_inertia([1.0; 2]) / f_max);
        }
        p
    }

    /// The slaves' brake u_i = −K_b·v_i, updated once a cycle (docs/safety.md), on the arm:
    /// v ← (I − T·K_b·M⁻¹·K_a)·v (friction left out, it only damps), stable when
    /// T·K_b/λ_min(K_a^(−1/2)·M·K_a^(−1/2)) < 2 in every configuration.
    pub(crate) fn check_brake(&self, cycle_s: f64, k_b: f64) -> Result<(), ScenarioError> {
        let p = self.params([1.0; 2]);
        let scale = p.torque_constant.map(|k| 1.0 / k.sqrt());
        let factor = cycle_s * k_b / p.min_inertia(scale);
        if factor >= 2.0 {
            return Err(out_of_range(
                "faults.brake_gain",
                k_b,
                format!(
                    "a gain the slaves' brake (u = −K_b·v once a cycle) can use on the two-link arm: its loop factor is {}, it must stay under 2",
                    number(factor)
                ),
            ));
        }
        Ok(())
    }
}

impl Scenario {
    /// Checks `[plant]`: the arm's keys, and that it has its two axes (`ring.slaves = 2`).
    pub(crate) fn validate_plant(&self) -> Result<(), ScenarioError> {
        let Some(arm) = self.plant.arm() else {
            return Ok(());
        };
        if self.ring.slaves != 2 {
            return Err(out_of_range(
                "ring.slaves",
                self.ring.slaves,
                "2 with plant.kind = \"two-link-arm\" (the arm's two joints, one slave each)",
            ));
        }
        arm.validate()
    }

    /// The two-link arm's parameters with each joint's drive range from its `[[axis]]`
    /// table; `None` unless `plant.kind = "two-link-arm"`.
    pub fn arm_params(&self) -> Option<ArmParams> {
        let u_max = |i| self.axis_spec(i).map_or(f64::NAN, |a| a.u_max);
        self.plant.arm().map(|a| a.params([u_max(0), u_max(1)]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARM: &str = "[ring]\nslaves = 2\n[plant]\nkind = \"two-link-arm\"\n";

    fn err(text: &str) -> String {
        Scenario::from_toml(text, "arm.toml")
            .expect_err("should fail")
            .to_string()
    }

    #[test]
    fn independent_is_the_default() {
        let none = Scenario::from_toml("", "none").expect("valid");
        assert_eq!(none.plant, PlantSpec::Independent {});
        let named =
            Scenario::from_toml("[plant]\nkind = \"independent\"\n", "named").expect("valid");
        assert_eq!(named, none);
        assert!(named.arm_params().is_none());
    }

    /// A friction so large that the arm's integration step would fall under 1 µs is refused
    /// (it would take hours of RK4 steps per simulated second, or never end), naming the key
    /// and the largest allowed value; extreme values print in exponent form.
    #[test]
    fn a_friction_too_stiff_to_integrate_is_refused() {
        let e = err(&format!("{ARM}friction = 1e12\n"));
        assert!(
            e.starts_with("plant.friction = 1000000000000.0 is out of range: allowed at most 764.544723 N·m·s/rad"),
            "{e}"
        );
        let ok = Scenario::from_toml(&format!("{ARM}friction = 700.0\n"), "ok").expect("valid");
        assert!(ok.arm_params().expect("arm").max_step >= MIN_ARM_STEP);
        let e = err(&format!("{ARM}friction = [0.1]\n"));
        assert!(e.contains("a number or a list of 2 values"), "{e}");
        let e = err(&format!("{ARM}p2 = -1e-300\n"));
        assert!(
            e.starts_with("plant.p2 = -1.00000e-300 is out of range"),
            "{e}"
        );
    }

    #[test]
    fn the_arm_takes_its_keys_and_the_joints_drive_ranges() {
        let s = Scenario::from_toml(
            &format!(
                "{ARM}p1 = 0.2\nfriction = 0.1\ntorque_constant = [3.0, 1.0]\n[[axis]]\nu_max = 8.0\n[[axis]]\nu_max = 5.0\n"
            ),
            "arm",
        )
        .expect("valid");
        assert_eq!(s.plant.name(), "two-link-arm");
        let p = s.arm_params().expect("arm");
        assert_eq!((p.p1, p.p2, p.p3), (0.2, 0.02, 0.03));
        assert_eq!((p.f1, p.f2), (0.1, 0.1));
        assert_eq!(p.torque_constant, [3.0, 1.0]);
        assert_eq!(p.u_max, [8.0, 5.0]);
        // The step: 0.1 ms, or a tenth of λ_min(M)/f_max when shorter.
        assert!(p.max_step <= ARM_MAX_STEP);
        assert!((p.max_step - ARM_MAX_STEP.min(0.1 * p.min_inertia([1.0; 2]) / 0.1)).abs() < 1e-18);
        let stiff = Scenario::from_toml(&format!("{ARM}friction = 100.0\n"), "stiff")
            .expect("valid")
            .arm_params()
            .expect("arm");
        assert!(stiff.max_step < ARM_MAX_STEP, "{}", stiff.max_step);
        // The defaults are valid and a plant the plant crate accepts.
        ringsync_plant::TwoLinkArm::new(
            Scenario::from_toml(ARM, "arm")
                .expect("valid")
                .arm_params()
                .expect("arm"),
        )
        .expect("plant accepts");
    }

    #[test]
    fn the_arm_needs_exactly_two_slaves() {
        for n in [1, 3, 4] {
            let e = err(&format!(
                "[ring]\nslaves = {n}\n[control]\nlaw = \"pd\"\n[plant]\nkind = \"two-link-arm\"\n"
            ));
            assert_eq!(
                e,
                format!(
                    "ring.slaves = {n} is out of range: allowed 2 with plant.kind = \"two-link-arm\" (the arm's two joints, one slave each)"
                )
            );
        }
    }

    #[test]
    fn bad_arm_keys_are_named() {
        for (extra, want) in [
            (
                "p2 = 0.0\n",
                "plant.p2 = 0 is out of range: allowed > 0 kg·m²",
            ),
            (
                "p1 = 0.02\n",
                "plant.p1 = 0.02 is out of range: allowed > plant.p2 = 0.02 kg·m² (M(q) positive definite needs p1 > p2)",
            ),
            (
                "p3 = 0.06\n",
                "plant.p3 = 0.06 is out of range: allowed 0 ..< 0.05099 kg·m² with p1 = 0.15, p2 = 0.02 (M(q) positive definite in every configuration needs p3² < p2·(p1 − p2))",
            ),
            ("p3 = -0.01\n", "plant.p3 = -0.01 is out of range"),
            (
                "friction = [0.1, -0.2]\n",
                "plant.friction (joint 2) = -0.2 is out of range: allowed >= 0 N·m·s/rad",
            ),
            (
                "friction = [0.1, 0.2, 0.3]\n",
                "plant.friction = [0.1, 0.2, 0.3] is out of range: allowed a number or a list of 2 values (joint 1, joint 2)",
            ),
            (
                "torque_constant = 0.0\n",
                "plant.torque_constant (joint 1) = 0 is out of range: allowed > 0 N·m/V",
            ),
            (
                "torque_constant = []\n",
                "plant.torque_constant = [] is out of range",
            ),
            ("p1 = nan\n", "plant.p1 = NaN is out of range"),
        ] {
            let e = err(&format!("{ARM}{extra}"));
            assert!(e.starts_with(want), "{extra}: {e}");
        }
    }

    #[test]
    fn unknown_plant_keys_and_kinds_are_refused() {
        let e = err(&format!("{ARM}p4 = 1.0\n"));
        assert!(e.contains("unknown field `p4`"), "{e}");
        // The arm's keys do not belong to independent axes.
        let e = err("[plant]\nkind = \"independent\"\np1 = 0.2\n");
        assert!(e.contains("p1"), "{e}");
        let e = err("[plant]\nkind = \"three-link-arm\"\n");
        assert!(
            e.contains("three-link-arm") && e.contains("two-link-arm"),
            "{e}"
        );
        assert_eq!(e.lines().count(), 1, "{e}");
    }

    /// The slaves' brake on the arm: T·K_b/λ_min(K_a^(−1/2)·M·K_a^(−1/2)) < 2. For the
    /// default arm the smallest is at q2 = 0, of [[0.21/2, 0.05/√1], [0.05, 0.02/0.5]]:
    /// 0.0725 − √(0.0325² + 0.05²) = 0.012866 V·s²/rad, so K_b < 25.73 V·s/rad at 1 ms.
    #[test]
    fn the_brake_is_checked_on_the_arm() {
        let p = ArmSpec::default().params([10.0; 2]);
        let h = p.min_inertia(p.torque_constant.map(|k| 1.0 / k.sqrt()));
        let want = 0.0725 - (0.0325f64.powi(2) + 0.05f64.powi(2)).sqrt();
        assert!((h - want).abs() < 1e-12, "{h} vs {want}");
        Scenario::from_toml(&format!("{ARM}[faults]\nbrake_gain = 25.7\n"), "ok").expect("valid");
        let e = err(&format!("{ARM}[faults]\nbrake_gain = 25.8\n"));
        assert!(
            e.starts_with("faults.brake_gain = 25.8")
                && e.contains("on the two-link arm: its loop factor is 2.005"),
            "{e}"
        );
    }
}
