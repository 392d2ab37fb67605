//! The stability check of a scenario as text and JSON.

use std::fmt::Write as _;

use ringsync_model::check::{ASSUMPTIONS, CheckReport, NotModelled, RobustTerm, Verdict};
use ringsync_proto::PlanKind;
use serde_json::{Value, json};

/// A readable report of `ringsync check`.
pub fn check_text(r: &CheckReport) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Stability of scenario {} ({} controller, estimator {}, {} axes, {} plan)",
        r.scenario,
        r.law,
        r.estimator,
        r.delays.len().max(1),
        r.plan.name()
    );
    match &r.discrete {
        Some(d) => {
            let delays: Vec<String> = r.delays.iter().map(|d| format!("{:.3}", d * 1e6)).collect();
            let _ = writeln!(
                o,
                "\nSample-to-actuation delays from the cycle plan [µs]{}: {}",
                if r.plan == PlanKind::LumpedOnly {
                    " (each slave's command when the lumped frame passes it, on this cycle's samples up to it and last cycle's after it)"
                } else {
                    ""
                },
                delays.join(", ")
            );
            let _ = writeln!(
                o,
                "Discrete-time check: spectral radius {:.6} of the {}-state sampled loop: {}",
                d.spectral_radius,
                d.states,
                if d.is_stable() { "stable" } else { "UNSTABLE" }
            );
        }
        None => match r.not_modelled {
            Some(NotModelled::CoupledPlant) => {
                let _ = writeln!(
                    o,
                    "\nDiscrete-time check: not available: {}.",
                    NotModelled::CoupledPlant.reason()
                );
            }
            Some(
                m @ (NotModelled::LumpedOnlyPlan
                | NotModelled::VelocityWindow
                | NotModelled::LateCommand
                | NotModelled::PathDependentLaw),
            ) => {
                let _ = writeln!(o, "\nDiscrete-time check: not available: {}.", m.reason());
            }
            None => {
                let _ = writeln!(o, "\nDiscrete-time check: not available.");
            }
        },
    }
    match r.robust {
        RobustTerm::Off => {}
        RobustTerm::BoundaryLayer { kn_max, phi } => {
            let _ = writeln!(
                o,
                "Robust term: K_N up to {kn_max:.4} V along the trajectory, boundary layer φ = {phi} rad/s: checked as K_D + K_N,max/φ = K_D + {:.4} V·s/rad",
                r.robust.extra_kd()
            );
        }
        RobustTerm::ExactSign { kn_max } => {
            let _ = writeln!(
                o,
                "Robust term: K_N up to {kn_max:.4} V with the exact sign (boundary_layer = 0): the sign term cannot be linearised; the spectral radius above leaves it out"
            );
        }
    }
    let _ = writeln!(o, "Verdict: {}", verdict_text(r));
    match &r.continuous {
        Some(c) => {
            let _ = writeln!(
                o,
                "\nThe paper's conditions along the trajectory ({} points):",
                r.points
            );
            let _ = writeln!(
                o,
                "  1. λ_min(K_E) = {:.4} V·s/rad ≥ max ‖αT(½Ḣ − C)‖ = {:.4e} V·s/rad (at t = {:.3} s): margin {:.4e}, {}",
                c.lambda_min_ke,
                c.cond1_bound,
                c.cond1_worst_time,
                c.cond1_margin,
                if c.condition1_holds() {
                    "holds"
                } else {
                    "FAILS"
                }
            );
            let _ = writeln!(
                o,
                "  2. Δ_H ≥ ‖K_H − H‖ = {:.4e} V·s²/rad (margin {:.4e}); Δ_C ≥ ‖K_C − C‖ = {:.4e} V·s/rad (margin {:.4e}): {}",
                c.cond2_h_norm,
                c.cond2_h_margin,
                c.cond2_c_norm,
                c.cond2_c_margin,
                if c.condition2_holds() {
                    "holds"
                } else {
                    "FAILS"
                }
            );
        }
        None if r.not_modelled == Some(NotModelled::CoupledPlant) => {
            let _ = writeln!(
                o,
                "\nThe paper's conditions (section 3.4): not evaluated on the coupled two-link arm."
            );
        }
        None => {
            let _ = writeln!(
                o,
                "\nThe paper's conditions (section 3.4) concern the sync controller; not evaluated for {}.",
                r.law
            );
        }
    }
    let _ = writeln!(o, "\nAssumptions not in the paper:");
    for a in ASSUMPTIONS {
        let _ = writeln!(o, "  - {a}");
    }
    o
}

/// What the check concludes, in one sentence.
pub fn verdict_text(r: &CheckReport) -> &'static str {
    match (r.verdict(), r.discrete.is_some()) {
        (Verdict::Stable, _) => "stable: the linearised sampled loop has spectral radius < 1",
        (Verdict::Unstable, _) => "UNSTABLE: the linearised sampled loop has spectral radius >= 1",
        (Verdict::NotShown, false) if r.not_modelled == Some(NotModelled::CoupledPlant) => {
            "NOT SHOWN: the discrete-time check models independent linear axes, not the coupled two-link arm (plant.kind = \"two-link-arm\")"
        }
        (Verdict::NotShown, false) if r.not_modelled == Some(NotModelled::LateCommand) => {
            "NOT SHOWN: the discrete-time check does not model a command that takes effect more than a cycle after its sample"
        }
        (Verdict::NotShown, false) if r.not_modelled == Some(NotModelled::PathDependentLaw) => {
            "NOT SHOWN: the discrete-time check linearises about a desired position at rest, where the contour law (ccc) has no direction and its coupling vanishes"
        }
        (Verdict::NotShown, false) if r.not_modelled == Some(NotModelled::VelocityWindow) => {
            "NOT SHOWN: the discrete-time check does not model a velocity window that spans two commands (axis.velocity_window > T_cyc − the command's delay)"
        }
        (Verdict::NotShown, false) => {
            "NOT SHOWN: the discrete-time check does not model the slaves' own error or disturbance observers on the lumped-only plan"
        }
        (Verdict::NotShown, true) => {
            "NOT SHOWN: the check cannot vouch for stability with K_N != 0 and the exact sign; set control.boundary_layer > 0 to have it modelled"
        }
    }
}

/// `ringsync check --json`, with `ringsync_version` and `schema_version` (1) first.
pub fn check_json(r: &CheckReport) -> Value {
    crate::provenance::stamp(check_json_fields(r), 1)
}

/// The same as one JSON object (delays in ns, rounded).
fn check_json_fields(r: &CheckReport) -> Value {
    json!({
        "scenario": r.scenario,
        "law": r.law,
        "estimator": r.estimator,
        "plan": r.plan.name(),
        "delays_ns": r.delays.iter().map(|d| (d * 1e9).round() as i64).collect::<Vec<_>>(),
        "discrete": r.discrete.map(|d| json!({
            "spectral_radius": d.spectral_radius,
            "states": d.states,
            "stable": d.is_stable(),
            "state_names": r.state_names,
        })),
        "not_modelled": r.not_modelled.map(NotModelled::reason),
        "robust_term": match r.robust {
            RobustTerm::Off => Value::Null,
            RobustTerm::BoundaryLayer { kn_max, phi } => json!({
                "kn_max": kn_max, "boundary_layer": phi, "extra_kd": r.robust.extra_kd(), "modelled": true,
            }),
            RobustTerm::ExactSign { kn_max } => json!({
                "kn_max": kn_max, "boundary_layer": 0.0, "modelled": false,
            }),
        },
        "verdict": match r.verdict() {
            Verdict::Stable => "stable",
            Verdict::Unstable => "unstable",
            Verdict::NotShown => "not shown",
        },
        "verdict_text": verdict_text(r),
        "conditions": r.continuous.map(|c| json!({
            "points": r.points,
            "lambda_min_ke": c.lambda_min_ke,
            "cond1_bound": c.cond1_bound,
            "cond1_worst_time_s": c.cond1_worst_time,
            "cond1_margin": c.cond1_margin,
            "cond1_holds": c.condition1_holds(),
            "cond2_h_norm": c.cond2_h_norm,
            "cond2_h_margin": c.cond2_h_margin,
            "cond2_c_norm": c.cond2_c_norm,
            "cond2_c_margin": c.cond2_c_margin,
            "cond2_holds": c.condition2_holds(),
        })),
        "assumptions": ASSUMPTIONS,
    })
}
