//! `ringsync scenario` and `ringsync check`.

use clap::{Args, Subcommand};
use ringsync::layers::report::{check_json, check_text};
use ringsync::{Verdict, builtin, builtin_names};

use crate::{CliError, Outcome, out};

/// `ringsync scenario …`
#[derive(Subcommand, Debug)]
pub enum ScenarioCmd {
    /// List the built-in scenarios.
    List,
    /// Print a built-in scenario as commented TOML, ready to copy and edit.
    Show {
        /// Name of a built-in scenario.
        name: String,
    },
    /// List the control laws (`control.law`) with their own parameters (`[control.params]`).
    Laws,
    /// Check a scenario file (or built-in name): parse and validate, print the error or "ok".
    Validate {
        /// Scenario file or built-in name.
        scenario: String,
    },
}

pub(crate) fn run(cmd: &ScenarioCmd) -> Result<Outcome, CliError> {
    match cmd {
        ScenarioCmd::List => {
            let mut text = String::new();
            for name in builtin_names() {
                let s = ringsync::load(name)?.scenario;
                text.push_str(&format!("{name:<14} {}\n", s.description));
            }
            out(&text)
        }
        ScenarioCmd::Laws => out(&ringsync::layers::control::law::registry::catalogue()),
        ScenarioCmd::Show { name } => match builtin(name) {
            Some(text) => out(text),
            None => Err(CliError::Usage(format!(
                "unknown scenario '{name}': built-in scenarios are {}",
                builtin_names().collect::<Vec<_>>().join(", ")
            ))),
        },
        ScenarioCmd::Validate { scenario } => {
            let s = ringsync::load(scenario)?.scenario;
            out(&format!(
                "{scenario}: ok ({}, {} axes)\n",
                s.name,
                s.axes_count()
            ))
        }
    }
}

/// Options of `ringsync check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scenario file or built-in name (see `ringsync scenario list`).
    scenario: String,
    /// Set a scenario key before the check, as `sim --set` does (e.g.
    /// `--set control.kd=20`).
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = crate::sim_cmd::key_value)]
    set: Vec<(String, String)>,
    /// Points of the trajectory at which the paper's conditions are evaluated.
    #[arg(long, default_value_t = 4001, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    points: u32,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    json: bool,
}

/// From this many axes `check` says beforehand that it will take a while.
const LONG_CHECK_AXES: usize = 64;

/// Runs `ringsync check`: exit status 3 unless the verdict is stable.
pub(crate) fn check(args: &CheckArgs) -> Result<Outcome, CliError> {
    let file = ringsync::load(&args.scenario)?;
    let s = ringsync::with_values(&file, &args.set)?.scenario;
    let n = s.axes_count();
    if n >= LONG_CHECK_AXES {
        // The eigenvalues of the loop (about 9 states per axis) cost the cube of its size.
        eprintln!(
            "ringsync check: {n} axes: the loop has about {} states, and its eigenvalues cost the cube of that (100 axes take seconds, 200 half a minute)",
            9 * n
        );
    }
    let r = ringsync::check(&s, args.points as usize)?;
    if args.json {
        let text = serde_json::to_string_pretty(&check_json(&r))
            .map_err(|e| CliError::Failure(format!("cannot format JSON: {e}")))?;
        out(&format!("{text}\n"))?;
    } else {
        out(&check_text(&r))?;
    }
    Ok(Outcome::flagged_if(r.verdict() != Verdict::Stable))
}
