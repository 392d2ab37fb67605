//! `ringsync check`: the stability analysis of the control library (SYSTEM.md section 3.4)
//! applied to a scenario, with the sample-to-actuation delays taken from the cycle plan.

use ringsync_control::ControlError;
use ringsync_control::stability::{
    ContinuousReport, DiscreteReport, continuous_conditions, discrete_check,
};
use ringsync_plant::IndependentAxes;
use ringsync_proto::plan::{FrameRef, Node};
use ringsync_proto::{CyclePlan, PlanKind};

use crate::scenario::{LawKind, Scenario, ScenarioError};

/// Assumptions of the check that the paper does not make; printed with every result.
pub const ASSUMPTIONS: &[&str] = &[
    "all slaves sample at the synchronised cycle start; a command takes effect when its last bit reaches its slave (event-level cycle plan, loss-free)",
    "the discrete-time check linearises: Coulomb friction and drive saturation are left out, the axes regulate to a final position (x^d = 0, so K_N = 0)",
    "the paper's conditions are evaluated along the desired trajectory (x = x^d, ẋ = ẋ^d) at evenly spaced points",
];

/// The result of checking a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Scenario name.
    pub scenario: String,
    /// Law name.
    pub law: &'static str,
    /// Estimator name.
    pub estimator: &'static str,
    /// Sample-to-actuation delay of each axis [s].
    pub delays: Vec<f64>,
    /// The discrete-time check; `None` for the lumped-only plan (not modelled yet).
    pub discrete: Option<DiscreteReport>,
    /// The paper's conditions; `None` unless the law is the sync controller.
    pub continuous: Option<ContinuousReport>,
    /// Points of the trajectory evaluated.
    pub points: usize,
}

/// What can go wrong in a check.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The analysis failed numerically.
    #[error("stability analysis: {0}")]
    Control(#[from] ControlError),
}

/// Sample-to-actuation delay of each axis [s] in the proposed plan: from the cycle start
/// (the sampling instant) to the last bit of the axis's command at its slave.
pub fn command_delays(plan: &CyclePlan) -> Vec<f64> {
    let tl = plan.timeline();
    (1..=plan.slaves())
        .map(|i| {
            tl.passages
                .iter()
                .find(|p| p.frame == FrameRef::Command(i) && p.node == Node::Slave(i))
                .and_then(|p| p.rx)
                .map_or(f64::NAN, |rx| rx.end.as_ns() as f64 * 1e-9)
        })
        .collect()
}

/// Runs the discrete-time check (proposed plan) and, for the sync controller, the paper's
/// conditions along `points` instants of the scenario's duration.
pub fn check(s: &Scenario, points: usize) -> Result<CheckReport, CheckError> {
    s.validate()?;
    let plan = CyclePlan::new(&s.ring_params()).map_err(|e| ScenarioError::OutOfRange {
        key: "ring".into(),
        value: "?".into(),
        allowed: e.to_string(),
    })?;
    let models = s
        .axis_models()
        .map_err(|(i, e)| ScenarioError::OutOfRange {
            key: format!("axis[{i}]"),
            value: "?".into(),
            allowed: e.to_string(),
        })?;
    let law = s.law()?;
    let (delays, discrete) = match s.ring.plan {
        PlanKind::P2pLumped => {
            let delays = command_delays(&plan);
            let linear: Vec<(f64, f64)> = models.iter().map(|m| m.linear_part()).collect();
            let r = discrete_check(law.as_ref(), &linear, s.ring.cycle.secs(), &delays)?;
            (delays, Some(r))
        }
        PlanKind::LumpedOnly => (Vec::new(), None),
    };
    let continuous = if s.control.law == LawKind::Sync {
        let plant = IndependentAxes::new(models);
        let c = &s.control;
        Some(continuous_conditions(
            &plant,
            &s.trajectories()?,
            &s.gains(),
            (c.alpha, c.delta_h, c.delta_c),
            s.duration.secs(),
            points,
        )?)
    } else {
        None
    };
    Ok(CheckReport {
        scenario: s.name.clone(),
        law: s.control.law.name(),
        estimator: s.control.estimator.name(),
        delays,
        discrete,
        continuous,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_scenario_passes_the_discrete_check() {
        let r = check(&Scenario::default(), 401).expect("check");
        let d = r.discrete.expect("p2p plan");
        assert!(d.is_stable(), "ρ = {}", d.spectral_radius);
        // Delays from the plan: slice i starts at 116.27 µs + (i−1)·18.07 µs; the command's
        // last bit reaches slave i after D_ci + T_cmf = i·0.31 + (i−1)·1.0 + 5.76 µs.
        let want = [122.34e-6, 141.72e-6, 161.10e-6, 180.48e-6];
        for (d, w) in r.delays.iter().zip(want) {
            assert!((d - w).abs() < 1e-12, "{d} vs {w}");
        }
        let c = r.continuous.expect("sync law");
        assert!(c.condition1_holds() && !c.condition2_holds());
    }

    #[test]
    fn an_unstable_scenario_is_flagged() {
        let s = Scenario::from_toml("[control]\nkd = 159.1\n", "high-kd").expect("valid");
        let r = check(&s, 11).expect("check");
        assert!(!r.discrete.expect("p2p").is_stable());
    }

    #[test]
    fn pd_has_no_paper_conditions_and_lumped_only_no_discrete_check() {
        let s = Scenario::from_toml(
            "[control]\nlaw = \"pd\"\n[ring]\nplan = \"lumped-only\"\n",
            "x",
        )
        .expect("valid");
        let r = check(&s, 11).expect("check");
        assert!(r.continuous.is_none() && r.discrete.is_none());
    }
}
