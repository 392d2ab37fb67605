//! Tables and figures of ringsync results: the cycle plan as a text table, a JSON object and
//! a timing diagram (the paper's Fig. 1); the stability check of a scenario.

pub mod check;
pub mod columnar;
pub mod fixed;
pub mod identify;
pub mod path;
pub mod pcap;
pub mod plan;
pub mod plot;
pub mod provenance;
pub mod repro;
pub mod sim;
mod svg;
pub mod timing;

pub use check::{check_json, check_text};
pub use plan::{plan_json, plan_table};
pub use timing::{MAX_SVG_SLAVES, timing_svg};
