//! Tables and figures of ringsync results: for now the cycle plan as a text table, a JSON
//! object and a timing diagram (the paper's Fig. 1).

pub mod plan;
mod svg;
pub mod timing;

pub use plan::{plan_json, plan_table};
pub use timing::{MAX_SVG_SLAVES, timing_svg};
