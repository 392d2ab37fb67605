//! The simulator's cost per simulated cycle against the ring size n, from the criterion
//! benchmark's saved estimates, beside a line proportional to n: prints the table for
//! docs/benchmarks.md and writes the figure.
//!
//! ```sh
//! taskset -c 1 cargo bench -p ringsync-sim --bench sim -- cycle_cost
//! cargo run --release --example sim_cost_plot -- docs/img/sim-cost-vs-n.svg
//! ```

use ringsync_report::plot::{PALETTE, Series, line_chart};

/// Ring sizes the benchmark runs (crates/sim/benches/sim.rs), each for 20 cycles.
const SIZES: [u32; 8] = [2, 4, 8, 16, 32, 64, 128, 256];
const CYCLES: f64 = 20.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "sim-cost-vs-n.svg".into());
    let target = std::env::var("CARGO_TARGET_DIR").unwrap_or_else(|_| "target".into());
    println!("| n | time for 20 cycles | per cycle | per cycle and axis |");
    println!("|---:|---:|---:|---:|");
    let mut points = Vec::new();
    for n in SIZES {
        let path = format!("{target}/criterion/cycle_cost_vs_n/{n}/new/estimates.json");
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("{path}: {e} (run the benchmark first)"))?;
        let v: serde_json::Value = serde_json::from_str(&text)?;
        let ns = v["mean"]["point_estimate"]
            .as_f64()
            .ok_or_else(|| format!("{path}: no mean.point_estimate"))?;
        let (cycle_us, axis_us) = (ns / CYCLES * 1e-3, ns / CYCLES / f64::from(n) * 1e-3);
        println!(
            "| {n} | {:.1} µs | {cycle_us:.2} µs | {axis_us:.2} µs |",
            ns * 1e-3
        );
        points.push((f64::from(n), cycle_us, axis_us));
    }
    // Linear growth is a straight line through the origin: the one through the largest ring.
    let per_axis = points.last().map_or(0.0, |p| p.2);
    let svg = line_chart(
        "Simulator cost per simulated cycle against the ring size (M1, pinned)",
        "ring size n [axes]",
        "µs per simulated cycle",
        &[
            Series {
                name: "criterion mean, 20 cycles".into(),
                colour: PALETTE[0],
                points: points.iter().map(|p| (p.0, p.1)).collect(),
                extent: None,
                errors: Vec::new(),
            },
            Series {
                name: format!("{per_axis:.2} µs × n"),
                colour: PALETTE[1],
                points: vec![(0.0, 0.0), (256.0, 256.0 * per_axis)],
                extent: None,
                errors: Vec::new(),
            },
        ],
    );
    std::fs::write(&out, svg)?;
    println!("wrote {out}");
    Ok(())
}
