//! 03: sweep frame loss over several seeds, as `ringsync sweep` does: the cases are plain
//! data (a remote worker could run each), run here on threads, then averaged.
//!
//! ```sh
//! cargo run --release -p ringsync --example 03_sweep
//! ```

use ringsync::sweep::{Sweep, SweepAxis, cases, run_cases};

fn main() -> Result<(), ringsync::Error> {
    let base = ringsync::parse(
        "duration = \"1s\"\n[control]\nlaw = \"sync\"\n",
        "paper-2015, 1 s",
    )?;
    let axes: Vec<SweepAxis> = vec!["faults.loss=0,0.05,0.2".parse()?];
    let cs = cases(&base, &axes, 3, false)?;
    println!("{} cases, e.g. {}", cs.len(), cs[4].name());
    let results = run_cases(&cs, ringsync::sweep::default_jobs(), &|done, total| {
        eprint!("\r  {done}/{total}");
    });
    eprintln!();
    let sw = Sweep::new(&base, &axes, 3, cs, results)?;
    print!("{}", sw.table());
    // More loss, more retries; the axes stay synchronised as long as the ring holds.
    let retries: Vec<u64> = sw.results.iter().map(|r| r.retries).collect();
    assert!(retries[0] == 0 && retries[8] > 0, "{retries:?}");
    assert_eq!(sw.stopped(), 0);
    Ok(())
}
