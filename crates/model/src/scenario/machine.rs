//! `[machine]` and part programs (docs/programs.md): the machine axes X, Y, Z, which ring
//! axes drive each (two make a gantry pair) through which transmission, their limits, the
//! path tolerance; `[trajectory] kind = "program"` and its file, found, read, interpreted and
//! planned once per text and machine (a planned path is shared by every run that asks for
//! it again).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use ringsync_path::plan::{Limits, Machine};
use ringsync_path::program::{AXIS_LETTERS, MAX_PROGRAM_BYTES};
use ringsync_path::{PlannedPath, Vec3};
use serde::Deserialize;

use super::error::{ScenarioError, out_of_range};
use super::load::fnv1a;
use super::schema::{PerAxis, Scenario, TrajectorySpec};

/// `[machine]`: the machine the ring's axes make.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineSpec {
    /// How far the path may leave the programmed corners when they are blended \[mm\]
    /// (0: the path stops at every corner).
    #[serde(default = "default_tolerance")]
    pub path_tolerance: f64,
    /// The machine axes by name (`X`, `Y`, `Z`).
    #[serde(default)]
    pub axes: BTreeMap<String, MachineAxisSpec>,
}

fn default_tolerance() -> f64 {
    0.01
}

/// `[machine.axes.<name>]`: one machine axis.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineAxisSpec {
    /// The ring axes (1-based) that drive it: one, or two for a gantry pair.
    pub drives: Vec<u32>,
    /// Lead of each drive's screw \[mm per revolution\]: one number for every drive, or one
    /// per drive; negative for a drive mounted the other way round.
    #[serde(default = "default_lead")]
    pub lead: PerAxis,
    /// Largest speed \[mm/s\].
    #[serde(default = "default_v")]
    pub v_max: f64,
    /// Largest acceleration \[mm/s²\].
    #[serde(default = "default_a")]
    pub a_max: f64,
    /// Largest jerk \[mm/s³\].
    #[serde(default = "default_j")]
    pub j_max: f64,
}

fn default_lead() -> PerAxis {
    PerAxis::One(10.0)
}
fn default_v() -> f64 {
    100.0
}
fn default_a() -> f64 {
    500.0
}
fn default_j() -> f64 {
    10_000.0
}

/// One machine axis as built: its coordinate and its drives.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineAxis {
    /// Its letter.
    pub name: char,
    /// Its coordinate: 0 = X, 1 = Y, 2 = Z.
    pub coord: usize,
    /// Each drive: the ring axis (0-based) and its transmission \[rad/mm\].
    pub drives: Vec<(usize, f64)>,
    /// Its limits.
    pub limits: Limits,
}

/// The machine a scenario describes, built: which ring axis moves which coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineMap {
    /// The machine axes, in the order X, Y, Z.
    pub axes: Vec<MachineAxis>,
    /// The path tolerance \[mm\].
    pub tolerance: f64,
}

impl MachineMap {
    /// What the planner needs: the limits of X, Y, Z and the tolerance.
    pub fn planner(&self) -> Machine {
        let mut axes = [None; 3];
        for a in &self.axes {
            axes[a.coord] = Some(a.limits);
        }
        Machine {
            axes,
            tolerance: self.tolerance,
        }
    }

    /// The coordinate ring axis `i` (0-based) moves and its transmission \[rad/mm\];
    /// `None` for a ring axis no machine axis lists (another device on the ring, holding
    /// still at 0).
    pub fn drive(&self, i: usize) -> Option<(usize, f64)> {
        self.axes.iter().find_map(|a| {
            a.drives
                .iter()
                .find(|(r, _)| *r == i)
                .map(|(_, k)| (a.coord, *k))
        })
    }

    /// The tool's position \[mm\] when the ring axes stand at `x` \[rad\]: each machine axis
    /// the mean of its drives' positions through their transmissions (a gantry's tool
    /// sits on the middle of its crossbeam).
    pub fn position(&self, x: &[f64]) -> Vec3 {
        let mut p = Vec3::ZERO;
        for a in &self.axes {
            let sum: f64 = a
                .drives
                .iter()
                .map(|(r, k)| x.get(*r).copied().unwrap_or(0.0) / k)
                .sum();
            p[a.coord] = sum / a.drives.len().max(1) as f64;
        }
        p
    }
}

/// The built-in part programs, by name: the example programs under `examples/programs/`
/// that built-in scenarios run (a program named by a scenario is looked for as a file
/// first).
const BUILTIN_PROGRAMS: &[(&str, &str)] = &[
    (
        "circle-r50.ngc",
        include_str!("../../../../examples/programs/circle-r50.ngc"),
    ),
    (
        "gantry-square.ngc",
        include_str!("../../../../examples/programs/gantry-square.ngc"),
    ),
    (
        "pocket.ngc",
        include_str!("../../../../examples/programs/pocket.ngc"),
    ),
    (
        "corners.ngc",
        include_str!("../../../../examples/programs/corners.ngc"),
    ),
];

/// Names of the built-in part programs.
pub fn builtin_programs() -> impl Iterator<Item = &'static str> {
    BUILTIN_PROGRAMS.iter().map(|(n, _)| *n)
}

/// The text of a built-in part program.
pub fn builtin_program(name: &str) -> Option<&'static str> {
    BUILTIN_PROGRAMS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, t)| *t)
}

/// Planned paths kept for the runs that ask again (a sweep's cases, a master and its
/// lumped-only slaves): (text and machine hash, path), the most recent last.
static PLANNED: Mutex<Vec<(u64, Arc<PlannedPath>)>> = Mutex::new(Vec::new());
/// How many planned paths are kept.
const PLANNED_KEPT: usize = 4;

/// A part program as found: where (for messages) and its text.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramText {
    /// The file as the user will recognise it (or the built-in name).
    pub shown: String,
    /// Its path, when it is a file.
    pub path: Option<PathBuf>,
    /// The text.
    pub text: Arc<str>,
}

impl Scenario {
    /// The built machine: `None` without a `[machine]` table.
    pub fn machine_map(&self) -> Result<Option<MachineMap>, ScenarioError> {
        let Some(m) = &self.machine else {
            return Ok(None);
        };
        let n = self.axes_count();
        if !(m.path_tolerance.is_finite() && (0.0..=10.0).contains(&m.path_tolerance)) {
            return Err(out_of_range(
                "machine.path_tolerance",
                m.path_tolerance,
                "0 ..= 10 mm (0: stop at every corner)",
            ));
        }
        if m.axes.is_empty() {
            return Err(out_of_range(
                "machine.axes",
                "{}",
                "at least one machine axis, e.g. [machine.axes.X] with drives = [1]",
            ));
        }
        let mut owner: Vec<Option<String>> = vec![None; n];
        let mut axes = Vec::new();
        for (name, a) in &m.axes {
            let key = format!("machine.axes.{name}");
            let coord = match name.as_str() {
                "X" => 0,
                "Y" => 1,
                "Z" => 2,
                _ => {
                    return Err(out_of_range(
                        key.clone(),
                        format!("[{key}]"),
                        "X, Y or Z: ringsync's part programs move the linear axes X, Y and Z (rotary axes A, B, C are not supported)",
                    ));
                }
            };
            if a.drives.is_empty() || a.drives.len() > n {
                return Err(out_of_range(
                    format!("{key}.drives"),
                    format!("{:?}", a.drives),
                    format!("1 ..= {n} ring axes, numbered from 1"),
                ));
            }
            let leads = match &a.lead {
                PerAxis::One(l) => vec![*l; a.drives.len()],
                PerAxis::Each(v) if v.len() == a.drives.len() => v.clone(),
                PerAxis::Each(v) => {
                    return Err(out_of_range(
                        format!("{key}.lead"),
                        format!("{v:?}"),
                        format!(
                            "one lead for every drive, or a list of {} (one per drive)",
                            a.drives.len()
                        ),
                    ));
                }
            };
            let mut drives = Vec::new();
            for (&d, &lead) in a.drives.iter().zip(&leads) {
                if d == 0 || d as usize > n {
                    return Err(out_of_range(
                        format!("{key}.drives"),
                        d,
                        format!("a ring axis 1 ..= {n} (ring.slaves = {n})"),
                    ));
                }
                let i = d as usize - 1;
                if let Some(other) = &owner[i] {
                    return Err(out_of_range(
                        format!("{key}.drives"),
                        d,
                        format!(
                            "a ring axis no other machine axis drives: ring axis {d} drives {other}"
                        ),
                    ));
                }
                owner[i] = Some(name.clone());
                if !(lead.is_finite() && lead != 0.0 && lead.abs() <= 1e4) {
                    return Err(out_of_range(
                        format!("{key}.lead"),
                        lead,
                        "a lead of 1e-4 ..= 1e4 mm per revolution, negative for a reversed drive",
                    ));
                }
                drives.push((i, std::f64::consts::TAU / lead));
            }
            for (k, v, unit) in [
                ("v_max", a.v_max, "mm/s"),
                ("a_max", a.a_max, "mm/s²"),
                ("j_max", a.j_max, "mm/s³"),
            ] {
                if !(v.is_finite() && v > 0.0 && v <= 1e9) {
                    return Err(out_of_range(
                        format!("{key}.{k}"),
                        v,
                        format!("> 0 ..= 1e9 {unit}"),
                    ));
                }
            }
            axes.push(MachineAxis {
                name: AXIS_LETTERS[coord],
                coord,
                drives,
                limits: Limits {
                    v_max: a.v_max,
                    a_max: a.a_max,
                    j_max: a.j_max,
                },
            });
        }
        if self.plant.arm().is_some() {
            return Err(out_of_range(
                "machine",
                "[machine]",
                "independent axes: the joints of plant.kind = \"two-link-arm\" are not linear machine axes",
            ));
        }
        Ok(Some(MachineMap {
            axes,
            tolerance: m.path_tolerance,
        }))
    }

    /// Finds the part program `trajectory.program` names: a file relative to the
    /// scenario file's directory (or the working directory for a scenario given as
    /// text), or an absolute path; else a built-in program of that name.
    pub fn program_text(&self) -> Result<Option<ProgramText>, ScenarioError> {
        let TrajectorySpec::Program { program } = &self.trajectory else {
            return Ok(None);
        };
        let given = Path::new(program);
        let path = match (&self.dir, given.is_absolute()) {
            (Some(d), false) => d.join(given),
            _ => given.to_path_buf(),
        };
        let shown = path.display().to_string();
        if !path.exists() {
            if let Some(text) = builtin_program(program) {
                return Ok(Some(ProgramText {
                    shown: program.clone(),
                    path: None,
                    text: Arc::from(text),
                }));
            }
            let names: Vec<&str> = builtin_programs().collect();
            return Err(ScenarioError::Program {
                file: shown,
                message: format!(
                    "no such file, and no built-in program of that name ({})",
                    names.join(", ")
                ),
            });
        }
        use std::io::Read as _;
        let mut bytes = Vec::new();
        std::fs::File::open(&path)
            .and_then(|f| f.take(MAX_PROGRAM_BYTES + 1).read_to_end(&mut bytes))
            .map_err(|e| ScenarioError::Program {
                file: shown.clone(),
                message: format!("cannot read it: {e}"),
            })?;
        if bytes.len() as u64 > MAX_PROGRAM_BYTES {
            return Err(ScenarioError::Program {
                file: shown,
                message: format!(
                    "larger than {} MiB, the limit for a part program",
                    MAX_PROGRAM_BYTES >> 20
                ),
            });
        }
        let text = String::from_utf8(bytes).map_err(|e| ScenarioError::Program {
            file: shown.clone(),
            message: format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        })?;
        Ok(Some(ProgramText {
            shown,
            path: Some(path),
            text: Arc::from(text),
        }))
    }

    /// The scenario's part program, interpreted and planned for its machine (`None` for
    /// other trajectories). Planned once per program text and machine: later calls with
    /// the same get the same path.
    pub fn planned_path(&self) -> Result<Option<Arc<PlannedPath>>, ScenarioError> {
        let Some(prog) = self.program_text()? else {
            return Ok(None);
        };
        let Some(map) = self.machine_map()? else {
            return Err(out_of_range(
                "trajectory.kind",
                "\"program\"",
                "a kind other than \"program\", or a [machine] table saying which ring axes drive X, Y and Z (docs/programs.md)",
            ));
        };
        let machine = map.planner();
        let key =
            fnv1a(prog.text.as_bytes()) ^ fnv1a(format!("{machine:?}").as_bytes()).rotate_left(17);
        if let Ok(kept) = PLANNED.lock()
            && let Some((_, p)) = kept.iter().find(|(k, _)| *k == key)
        {
            return Ok(Some(p.clone()));
        }
        let program = ringsync_path::interpret(&prog.text, machine.present()).map_err(|e| {
            ScenarioError::Program {
                file: prog.shown.clone(),
                message: e.to_string(),
            }
        })?;
        let path = ringsync_path::plan(&program, &machine).map_err(|e| ScenarioError::Program {
            file: prog.shown.clone(),
            message: e.to_string(),
        })?;
        let path = Arc::new(path);
        if let Ok(mut kept) = PLANNED.lock() {
            if kept.len() >= PLANNED_KEPT {
                kept.remove(0);
            }
            kept.push((key, path.clone()));
        }
        Ok(Some(path))
    }
}
