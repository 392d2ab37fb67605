//! `ringsync check`: the stability analysis of the control library (docs/system.md, "Stability")
//! applied to a scenario, with the sample-to-actuation delays taken from the cycle plan.

use ringsync_control::stability::{
    ContinuousReport, DiscreteReport, Measurement, continuous_conditions, discrete_loop_with,
    lumped_only_loop,
};
use ringsync_control::{
    ControlError, ControlLaw, Sign, SyncController, SyncParams, Trajectory, VelocitySource,
};
use ringsync_plant::IndependentAxes;
use ringsync_proto::plan::{FrameRef, Node};
use ringsync_proto::{CyclePlan, PlanKind};

use crate::scenario::{Scenario, ScenarioError};

/// The registry name of the paper's sync controller: the law the paper's conditions and the
/// robust term belong to.
const SYNC: &str = ringsync_control::law::sync::ENTRY.name;

/// Assumptions of the check that the paper does not make; printed with every result.
pub const ASSUMPTIONS: &[&str] = &[
    "all slaves sample at the same synchronised instant, clock.sample_lead before the cycle start (the cycle start by default); a command takes effect when its last bit reaches its slave (event-level cycle plan, loss-free); on the lumped-only plan, a slave's command when the lumped frame's last bit reaches it, the frame holding this cycle's samples of the slaves up to it and last cycle's of the others",
    "the discrete-time check linearises: Coulomb friction and drive saturation are left out, the axes regulate to a final position (x^d = 0)",
    "a slave's reported velocity is the mean over axis.velocity_window (125 µs by default) of the linear axis with its command held, without the encoder's quantisation",
    "the robust term K_N·sat(Ė/φ) of the sync controller is linear inside its boundary layer with slope K_N/φ: the discrete-time check adds K_N,max/φ to K_D, with K_N,max the largest K_N = Δ_H‖ẍ^d‖ + Δ_C‖ẋ^d‖ at the evaluated points (a frozen worst case; outside the layer the term is bounded); with the exact sign (boundary_layer = 0) and K_N ≠ 0 the loop cannot be linearised and the check cannot vouch for it",
    "the paper's conditions are evaluated along the desired trajectory (x = x^d, ẋ = ẋ^d) at evenly spaced points",
];

/// How the sync controller's robust term K_N·sgn(Ė) (docs/system.md, "Plant and controller") enters the
/// discrete-time check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RobustTerm {
    /// K_N = 0 along the trajectory (Δ_H = Δ_C = 0), or a law without the term.
    Off,
    /// Boundary layer φ > 0: inside it the term is K_N/φ·Ė, modelled as an extra derivative
    /// gain K_N,max/φ on Ė.
    BoundaryLayer {
        /// The largest K_N along the trajectory \[V\].
        kn_max: f64,
        /// φ [rad/s].
        phi: f64,
    },
    /// The exact sign with K_N ≠ 0: not linearisable; the loop was checked without it.
    ExactSign {
        /// The largest K_N along the trajectory \[V\].
        kn_max: f64,
    },
}

impl RobustTerm {
    /// The derivative gain the check adds to K_D [V·s/rad] (0 unless a boundary layer).
    pub fn extra_kd(&self) -> f64 {
        match *self {
            RobustTerm::BoundaryLayer { kn_max, phi } => kn_max / phi,
            _ => 0.0,
        }
    }
}

/// Why the discrete-time check did not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotModelled {
    /// The lumped-only plan with an error observer (`control.velocity = "observer"`) or a
    /// disturbance observer in the slaves: each slave would run its own on its view of the
    /// ring, which the check does not model.
    LumpedOnlyPlan,
    /// The coupled two-link arm (`plant.kind = "two-link-arm"`): the check models
    /// independent linear axes only.
    CoupledPlant,
    /// An axis's velocity window reaches back past its command's effect in the cycle before
    /// (`axis.velocity_window` > T_cyc − delay): the reported velocity would span two
    /// commands, and the check holds one over the window.
    VelocityWindow,
    /// A command takes effect more than a cycle after its sample (`clock.sample_lead` + its
    /// delay > T_cyc): the check holds each command from its effect to the next one within
    /// a cycle.
    LateCommand,
    /// A law whose gains follow the path (`control.law = "ccc"`): the check linearises about
    /// a desired position at rest, where the path has no direction and the contour term
    /// vanishes, so it would vouch for PD instead.
    PathDependentLaw,
}

impl NotModelled {
    /// Why, in words.
    pub fn reason(self) -> &'static str {
        match self {
            NotModelled::LumpedOnlyPlan => {
                "on the lumped-only plan every slave would run its own error observer (control.velocity = \"observer\") or disturbance observer on its view of the ring, which the check does not model"
            }
            NotModelled::LateCommand => {
                "a command takes effect more than a cycle after its sample (clock.sample_lead plus its delay exceeds the cycle), which the check does not model"
            }
            NotModelled::VelocityWindow => {
                "an axis's velocity window (axis.velocity_window) reaches back past its command's effect in the cycle before, so its reported velocity spans two commands, which the check does not model"
            }
            NotModelled::PathDependentLaw => {
                "the law's coupling follows the path's direction and curvature (control.law = \"ccc\"): linearised about a desired position at rest its contour term vanishes, so the check would show PD's loop, not this one"
            }
            NotModelled::CoupledPlant => {
                "the plant is the coupled two-link arm (plant.kind = \"two-link-arm\"): the check models independent linear axes only, and the arm's inertia couples its joints and changes with its configuration"
            }
        }
    }
}

/// What the check says about the loop as a whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The linearised sampled loop has spectral radius < 1.
    Stable,
    /// Spectral radius ≥ 1.
    Unstable,
    /// The check cannot vouch for stability: the lumped-only plan's slaves running their own
    /// observers or the coupled arm are not modelled ([`NotModelled`]), or the exact sign
    /// with K_N ≠ 0 cannot be linearised.
    NotShown,
}

/// The result of checking a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Scenario name.
    pub scenario: String,
    /// Law name.
    pub law: &'static str,
    /// Estimator name.
    pub estimator: &'static str,
    /// The cycle plan checked.
    pub plan: PlanKind,
    /// Sample-to-actuation delay of each axis \[s\]: from the sample (`clock.sample_lead`
    /// before the cycle start) to its command's arrival on the proposed plan, to the lumped
    /// frame's pass at its slave on the lumped-only plan.
    pub delays: Vec<f64>,
    /// The discrete-time check; `None` when it does not model the scenario.
    pub discrete: Option<DiscreteReport>,
    /// The closed-loop matrix M of the discrete-time check (z[k+1] = M·z\[k\] over one
    /// cycle), row-major, `discrete.states` × `discrete.states`: the states of
    /// [`CheckReport::state_names`] per axis, axis-major; `None` with `discrete`.
    pub discrete_matrix: Option<Vec<f64>>,
    /// The names of an axis's states in the matrix, in their order: on the proposed plan
    /// [`ringsync_control::stability::discrete_loop_with`]'s (x \[rad\], ẋ [rad/s], u[k−1]
    /// \[V\], e[k−1..k−3] \[rad\], ė[k−1..k−3] [rad/s], then the error observer's ê, ė̂ and the
    /// disturbance observer's u[k−2], u[k−3], d̂ when they run), on the lumped-only plan
    /// [`ringsync_control::stability::LUMPED_ONLY_STATE_NAMES`]; empty without the matrix.
    pub state_names: Vec<&'static str>,
    /// Why the discrete-time check did not run (`None` when it ran).
    pub not_modelled: Option<NotModelled>,
    /// How the robust term entered the discrete-time check.
    pub robust: RobustTerm,
    /// The paper's conditions; `None` unless the law is the sync controller on independent
    /// axes.
    pub continuous: Option<ContinuousReport>,
    /// Points of the trajectory evaluated.
    pub points: usize,
}

impl CheckReport {
    /// Stable only when the discrete-time check ran, modelled every term, and found a
    /// spectral radius below 1.
    pub fn verdict(&self) -> Verdict {
        match self.discrete {
            Some(d) if !d.is_stable() => Verdict::Unstable,
            Some(_) if matches!(self.robust, RobustTerm::ExactSign { .. }) => Verdict::NotShown,
            Some(_) => Verdict::Stable,
            None => Verdict::NotShown,
        }
    }
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

/// Delay of each axis's command \[s\] on the lumped-only plan: from the cycle start (when the
/// master sends the frame) to the lumped frame's last bit at the axis's slave, D_ci + the
/// frame's wire time. The check adds `clock.sample_lead`: the sample comes that much earlier.
pub fn lumped_only_passes(plan: &CyclePlan) -> Vec<f64> {
    let wire = plan.lumped_only.lumped.frame_time[0];
    plan.d_c
        .iter()
        .map(|&d| (d + wire).as_ns() as f64 * 1e-9)
        .collect()
}

/// Delay of each axis's command \[s\] in the proposed plan: from the cycle start to the last
/// bit of the axis's command at its slave. The check adds `clock.sample_lead`: the sample
/// comes that much earlier.
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
    let robust = robust_term(s, points)?;
    let law: Box<dyn ControlLaw> = match robust {
        // Inside the layer K_N·sat(Ė/φ) = (K_N/φ)·Ė: one more derivative gain on the Ė
        // the law already forms. Only the sync law has the robust term (robust_term is Off
        // for every other registered law), and it takes no parameters of its own
        // (`[control.params]`); should it gain some, build it here through its registry
        // entry with the raised K_D instead.
        RobustTerm::BoundaryLayer { .. } | RobustTerm::ExactSign { .. } => {
            let mut g = s.gains();
            for kd in &mut g.kd {
                *kd += robust.extra_kd();
            }
            let p = SyncParams {
                delta_h: 0.0,
                delta_c: 0.0,
                ..s.sync_params()
            };
            Box::new(SyncController::new(g, p)?)
        }
        RobustTerm::Off => s.law()?,
    };
    let coupled = s.plant.arm().is_some();
    let linear: Vec<(f64, f64)> = models.iter().map(|m| m.linear_part()).collect();
    // How the law takes ė: each drive reports the mean velocity over its axis's window.
    let measurement = Measurement {
        velocity: s.velocity_source(),
        dob: s.dob_params(),
        velocity_window: (0..models.len())
            .map(|i| s.axis_spec(i).map_or(0.0, |a| a.velocity_window.secs()))
            .collect(),
    };
    // A window reaching back past the command's effect spans two commands.
    let spans_two = |delays: &[f64]| {
        matches!(measurement.velocity, VelocitySource::Reported)
            && delays
                .iter()
                .zip(&measurement.velocity_window)
                .any(|(d, w)| *w > s.ring.cycle.secs() - d)
    };
    let late = |delays: &[f64]| delays.iter().any(|d| *d > s.ring.cycle.secs());
    // From the sample, clock.sample_lead before the cycle start, to the command's effect.
    let lead = s.clock.sample_lead.secs();
    let delays: Vec<f64> = match s.ring.plan {
        PlanKind::P2pLumped => command_delays(&plan),
        PlanKind::LumpedOnly => lumped_only_passes(&plan),
    }
    .into_iter()
    .map(|d| d + lead)
    .collect();
    let lumped_only = s.ring.plan == PlanKind::LumpedOnly;
    let not_modelled = if coupled {
        Some(NotModelled::CoupledPlant)
    } else if s.control.law == ringsync_control::law::ccc::ENTRY.name {
        Some(NotModelled::PathDependentLaw)
    } else if late(&delays) {
        Some(NotModelled::LateCommand)
    } else if spans_two(&delays) {
        Some(NotModelled::VelocityWindow)
    } else if lumped_only
        && (matches!(measurement.velocity, VelocitySource::Observer(_))
            || measurement.dob.is_some())
    {
        Some(NotModelled::LumpedOnlyPlan)
    } else {
        None
    };
    let t_cyc = s.ring.cycle.secs();
    let discrete = match not_modelled {
        Some(_) => None,
        None if lumped_only => Some(lumped_only_loop(
            law.as_ref(),
            &linear,
            t_cyc,
            &delays,
            &measurement,
        )?),
        None => Some(discrete_loop_with(
            law.as_ref(),
            &linear,
            t_cyc,
            &delays,
            &measurement,
        )?),
    };
    let discrete_matrix = discrete
        .as_ref()
        .map(|l| l.matrix.transpose().as_slice().to_vec());
    let state_names = discrete
        .as_ref()
        .map(|l| l.state_names.clone())
        .unwrap_or_default();
    let discrete = discrete.map(|l| l.report);
    let continuous = if s.control.law == SYNC && !coupled {
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
        law: s.law_name(),
        estimator: s.control.estimator.name(),
        plan: s.ring.plan,
        delays,
        discrete,
        discrete_matrix,
        state_names,
        not_modelled,
        robust,
        continuous,
        points,
    })
}

/// The robust term of the scenario's law: K_N,max = the largest Δ_H‖ẍ^d‖ + Δ_C‖ẋ^d‖ (norms
/// over all axes, as the sync controller forms it) at `points` evenly spaced instants of the
/// scenario's duration.
pub fn robust_term(s: &Scenario, points: usize) -> Result<RobustTerm, CheckError> {
    let c = &s.control;
    if s.control.law != SYNC || (c.delta_h == 0.0 && c.delta_c == 0.0) {
        return Ok(RobustTerm::Off);
    }
    let trajectories = s.trajectories()?;
    let points = points.max(2);
    let t_end = s.duration.secs();
    let kn_max = (0..points)
        .map(|p| {
            let t = t_end * p as f64 / (points - 1) as f64;
            let (a2, v2) = trajectories.iter().fold((0.0, 0.0), |(a2, v2), tr| {
                let d = tr.at(t);
                (a2 + d.a * d.a, v2 + d.v * d.v)
            });
            c.delta_h * a2.sqrt() + c.delta_c * v2.sqrt()
        })
        .fold(0.0, f64::max);
    Ok(match s.sync_params().sign {
        _ if kn_max == 0.0 => RobustTerm::Off,
        Sign::BoundaryLayer(phi) => RobustTerm::BoundaryLayer { kn_max, phi },
        Sign::Exact => RobustTerm::ExactSign { kn_max },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scenario from TOML text the test knows to be valid.
    fn valid(text: &str) -> Scenario {
        Scenario::from_toml(text, "test").expect("valid")
    }

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
        // The loop matrix behind the radius travels with the report: 9 states per axis,
        // row-major; row 3 of axis 1 is e[k−1] = −x.
        let m = r.discrete_matrix.expect("matrix with the discrete check");
        assert_eq!((d.states, m.len()), (36, 36 * 36));
        assert_eq!(m[3 * 36], -1.0);
    }

    #[test]
    fn an_unstable_scenario_is_flagged() {
        let s = valid("[control]\nkd = 159.1\n");
        let r = check(&s, 11).expect("check");
        assert!(!r.discrete.expect("p2p").is_stable());
    }

    #[test]
    fn a_thin_boundary_layer_with_a_large_robust_gain_is_unstable() {
        // K_N up to Δ_C·‖ẋ^d‖ = 1 × 2 × 15.12 V: inside φ = 0.01 rad/s its slope, 3024
        // V·s/rad on Ė, swamps K_D. Checked with K_N = 0 this was called stable (ρ 0.9986).
        let s = valid("[control]\ndelta_c = 1.0\nboundary_layer = 0.01\n");
        let r = check(&s, 4001).expect("check");
        match r.robust {
            RobustTerm::BoundaryLayer { kn_max, phi } => {
                assert!((kn_max - 30.24).abs() < 1e-9, "{kn_max}");
                assert_eq!(phi, 0.01);
            }
            other => panic!("{other:?}"),
        }
        assert!(r.discrete.expect("p2p").spectral_radius > 1.0);
        assert_eq!(r.verdict(), Verdict::Unstable);
        // A small robust gain in the same layer stays stable, and the reference has none.
        let s = valid("[control]\ndelta_c = 1e-4\n");
        assert_eq!(check(&s, 401).expect("check").verdict(), Verdict::Stable);
        let r = check(&Scenario::default(), 401).expect("check");
        assert_eq!((r.robust, r.verdict()), (RobustTerm::Off, Verdict::Stable));
    }

    #[test]
    fn the_exact_sign_with_a_robust_gain_is_not_vouched_for() {
        let s = valid("[control]\ndelta_h = 0.01\nboundary_layer = 0.0\n");
        let r = check(&s, 401).expect("check");
        assert!(matches!(r.robust, RobustTerm::ExactSign { kn_max } if kn_max > 0.0));
        assert!(r.discrete.expect("p2p").is_stable());
        assert_eq!(r.verdict(), Verdict::NotShown);
        // The exact sign alone, with K_N = 0, is nothing to linearise.
        let s = valid("[control]\nboundary_layer = 0.0\n");
        assert_eq!(check(&s, 11).expect("check").verdict(), Verdict::Stable);
    }

    #[test]
    fn pd_has_no_paper_conditions_and_lumped_only_its_own_discrete_check() {
        let s = valid("[control]\nlaw = \"pd\"\n[ring]\nplan = \"lumped-only\"\n");
        let r = check(&s, 11).expect("check");
        assert!(r.continuous.is_none() && r.not_modelled.is_none());
        let d = r.discrete.expect("lumped-only loop");
        assert_eq!(d.states, 4 * 11);
        assert_eq!(r.state_names.len(), 11);
        assert_eq!(r.discrete_matrix.as_ref().map(Vec::len), Some(44 * 44));
        assert_eq!(r.verdict(), Verdict::Stable);
        // Each slave takes the frame D_ci + its wire time (14.56 µs) after the cycle start:
        // D_ci = i·0.31 + (i − 1)·1.0 µs.
        let want = [14.87e-6, 16.18e-6, 17.49e-6, 18.80e-6];
        for (d, w) in r.delays.iter().zip(want) {
            assert!((d - w).abs() < 1e-12, "{d} vs {w}");
        }
        // Gains far too high are flagged on this plan too.
        let hot = valid("[control]\nlaw = \"pd\"\nkd = 159.1\n[ring]\nplan = \"lumped-only\"\n");
        assert_eq!(check(&hot, 11).expect("check").verdict(), Verdict::Unstable);
        // The slaves' own observers are not modelled: said, not guessed.
        let obs = valid("[control]\nvelocity = \"observer\"\n[ring]\nplan = \"lumped-only\"\n");
        let r = check(&obs, 11).expect("check");
        assert!(r.discrete.is_none() && r.state_names.is_empty());
        assert_eq!(r.not_modelled, Some(NotModelled::LumpedOnlyPlan));
        assert_eq!(r.verdict(), Verdict::NotShown);
    }

    /// A sampling lead moves every delay by itself; a command that lands more than a cycle
    /// after its sample is not modelled, and said.
    #[test]
    fn a_sampling_lead_lengthens_every_delay() {
        let base = check(&Scenario::default(), 11).expect("check");
        let s = valid("[clock]\nsample_lead = \"300us\"\n");
        let r = check(&s, 11).expect("check");
        for (a, b) in r.delays.iter().zip(&base.delays) {
            assert!((a - b - 300e-6).abs() < 1e-12, "{a} vs {b}");
        }
        assert!(r.discrete.is_some());
        // Sixteen slaves: slave 11's command arrives 508.26 µs into the 1 ms cycle, 1.008 ms
        // after a sample taken 500 µs early.
        let late = valid("[ring]\nslaves = 16\n[clock]\nsample_lead = \"500us\"\n");
        let r = check(&late, 11).expect("check");
        assert!(
            (r.delays[10] - 1008.26e-6).abs() < 1e-12,
            "{}",
            r.delays[10]
        );
        assert_eq!(r.not_modelled, Some(NotModelled::LateCommand));
        assert_eq!(r.verdict(), Verdict::NotShown);
    }

    /// A velocity window that reaches back past the command's effect is said, not guessed:
    /// 900 µs against the proposed plan's 877.66 µs from the last command to the next sample.
    #[test]
    fn a_window_spanning_two_commands_is_not_shown() {
        let s = valid("[[axis]]\nvelocity_window = \"900us\"\n");
        let r = check(&s, 11).expect("check");
        assert_eq!(r.not_modelled, Some(NotModelled::VelocityWindow));
        assert_eq!(r.verdict(), Verdict::NotShown);
        let s = valid("[[axis]]\nvelocity_window = \"800us\"\n");
        assert!(check(&s, 11).expect("check").discrete.is_some());
    }

    /// The check models independent linear axes: on the two-link arm it does not analyse
    /// the wrong plant, it says why it cannot vouch for the loop. The same ring with
    /// independent axes is analysed.
    #[test]
    fn the_coupled_arm_is_not_shown() {
        let ring = "[ring]\nslaves = 2\n";
        let arm = valid(&format!("{ring}[plant]\nkind = \"two-link-arm\"\n"));
        let r = check(&arm, 11).expect("check");
        assert_eq!(r.not_modelled, Some(NotModelled::CoupledPlant));
        assert!(r.discrete.is_none() && r.continuous.is_none());
        assert_eq!(r.verdict(), Verdict::NotShown);
        assert!(
            r.not_modelled
                .expect("why")
                .reason()
                .contains("coupled two-link arm")
        );
        assert_eq!(r.delays.len(), 2);
        let axes = valid(ring);
        let r = check(&axes, 11).expect("check");
        assert!(r.not_modelled.is_none() && r.discrete.is_some() && r.continuous.is_some());
        assert_eq!(r.verdict(), Verdict::Stable);
    }
}
