//! Plans a long program of short lines (CAM output of a curve) and prints how long the
//! interpreter and the planner took and what they made:
//! `cargo run --release -p ringsync-path --example long_program -- 150000`; with a file
//! name after the count it also writes the program there (for `ringsync sim`,
//! docs/benchmarks.md, "Part programs").

use ringsync_path::corpus;
use ringsync_path::interpret;
use ringsync_path::plan::{Limits, Machine, plan};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 150_000,
    };
    let text = corpus::small_lines(n, 0.1, 3000.0);
    if let Some(file) = std::env::args().nth(2) {
        std::fs::write(&file, &text)?;
    }
    let l = Limits {
        v_max: 100.0,
        a_max: 1000.0,
        j_max: 20000.0,
    };
    let m = Machine {
        axes: [Some(l), Some(l), None],
        tolerance: 0.01,
    };
    let t0 = std::time::Instant::now();
    let p = interpret(&text, m.present())?;
    let t1 = std::time::Instant::now();
    let path = plan(&p, &m)?;
    let t2 = std::time::Instant::now();
    println!(
        "{} bytes, {} moves: interpreted in {:.3} s, planned in {:.3} s; {} pieces, {} blocks, {} phases; {:.1} mm in {:.1} s",
        text.len(),
        p.moves.len(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        path.pieces().len(),
        path.blocks().len(),
        path.phases().len(),
        path.length(),
        path.duration(),
    );
    Ok(())
}
