//! `ringsync program`: a scenario's part program planned on its machine without a ring.

use std::path::PathBuf;

use clap::Args;
use ringsync::layers::report::path::{program_json, program_svg, program_text, write_blocks_csv};

use crate::sim_cmd::key_value;
use crate::{CliError, Outcome, out};

/// Options of `ringsync program`.
#[derive(Args, Debug)]
pub struct ProgramArgs {
    /// Scenario file or built-in name whose trajectory is a part program
    /// (`trajectory.kind = "program"`), e.g. circle-xy.
    scenario: String,
    /// Set a scenario key before planning, as `sim --set` does (e.g.
    /// `--set trajectory.program=part.ngc`, `--set machine.path_tolerance=0.05`).
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = key_value)]
    set: Vec<(String, String)>,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    json: bool,
    /// Write the feed along the path (planned speed and each block's limit) as SVG.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Write every feed block (where, when, its limits, what bounds it, its speeds) as CSV.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
}

/// Runs `ringsync program`: exit status 3 when a sampled setpoint exceeds a limit by more
/// than 0.1 % or leaves the path tolerance (a planner fault; it should never happen).
pub(crate) fn run(args: &ProgramArgs) -> Result<Outcome, CliError> {
    for p in [&args.svg, &args.csv].into_iter().flatten() {
        ringsync::output::writable(p)?;
    }
    let file = ringsync::load(&args.scenario)?;
    let loaded = ringsync::with_values(&file, &args.set)?;
    let plan = ringsync::plan_program(&loaded.scenario)?;
    let view = plan.view();
    if let Some(p) = &args.svg {
        ringsync::output::write_file(p, program_svg(&view))?;
    }
    if let Some(p) = &args.csv {
        let mut bytes = Vec::new();
        write_blocks_csv(&plan.path, &mut bytes)
            .map_err(|e| CliError::Failure(format!("cannot format the blocks: {e}")))?;
        ringsync::output::write_file(p, bytes)?;
    }
    if args.json {
        let text = serde_json::to_string_pretty(&program_json(&view))
            .map_err(|e| CliError::Failure(format!("cannot format JSON: {e}")))?;
        out(&format!("{text}\n"))?;
    } else {
        out(&program_text(&view))?;
    }
    let bad =
        plan.check.limit_ratio > 1.001 || plan.check.path_deviation > plan.path.tolerance() + 1e-9;
    Ok(Outcome::flagged_if(bad))
}
