//! Part programs planned without a ring (docs/programs.md, "Planning a program"): the
//! planned path of a scenario's program on its machine, and its setpoints sampled at the
//! scenario's cycle as a master would send them: how long the program takes, each axis's
//! peak velocity, acceleration and jerk against its limits, and where the limits bind.

use std::sync::Arc;

use ringsync_model::Scenario;
use ringsync_model::scenario::{MachineMap, TrajectorySpec};
use ringsync_path::PlannedPath;
use ringsync_path::check::{Check, check_setpoints};

use crate::error::{Error, Result};

/// A scenario's part program, planned and checked.
#[derive(Debug, Clone)]
pub struct ProgramPlan {
    /// The scenario's name.
    pub scenario: String,
    /// The program as the scenario names it.
    pub file: String,
    /// The planned path.
    pub path: Arc<PlannedPath>,
    /// The machine.
    pub machine: MachineMap,
    /// The setpoints sampled at the cycle: peaks, the largest share of a limit, the
    /// largest distance from the program.
    pub check: Check,
    /// The cycle the setpoints were sampled at \[s\].
    pub t_cyc: f64,
}

impl ProgramPlan {
    /// What the report's text, JSON and figure take (`ringsync program`).
    pub fn view(&self) -> ringsync_report::path::ProgramView<'_> {
        ringsync_report::path::ProgramView {
            scenario: &self.scenario,
            file: &self.file,
            path: &self.path,
            axes: self
                .machine
                .axes
                .iter()
                .map(|a| (a.name, a.coord, a.limits))
                .collect(),
            check: &self.check,
            t_cyc: self.t_cyc,
        }
    }
}

/// Plans the scenario's part program (`trajectory.kind = "program"`) and samples its
/// setpoints at the scenario's cycle.
///
/// ```
/// let s = ringsync::load("circle-xy")?.scenario;
/// let p = ringsync::plan_program(&s)?;
/// assert!(p.path.duration() > 10.0);
/// // Sampled at the cycle, no axis exceeds its limits.
/// assert!(p.check.limit_ratio <= 1.001, "{:?}", p.check);
/// let e = ringsync::plan_program(&ringsync::load("paper-2015")?.scenario).unwrap_err();
/// assert!(e.is_usage());
/// # Ok::<(), ringsync::Error>(())
/// ```
pub fn plan_program(s: &Scenario) -> Result<ProgramPlan> {
    let TrajectorySpec::Program { program } = &s.trajectory else {
        return Err(Error::Input(format!(
            "scenario {}: its trajectory is not a part program (trajectory.kind = \"program\" with program = \"FILE\")",
            s.name
        )));
    };
    let (Some(path), Some(machine)) = (s.planned_path()?, s.machine_map()?) else {
        return Err(Error::Input(format!(
            "scenario {}: a part program needs a [machine] table",
            s.name
        )));
    };
    let t_cyc = s.ring.cycle.secs();
    let check = check_setpoints(&path, &machine.planner(), t_cyc);
    Ok(ProgramPlan {
        scenario: s.name.clone(),
        file: program.clone(),
        path,
        machine,
        check,
        t_cyc,
    })
}
