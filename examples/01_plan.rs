//! 01: plan a ring (eq. 1-2). How fast can a ring of 8 axes on 100 Mbit/s Ethernet cycle,
//! and where does the time go?
//!
//! ```sh
//! cargo run --release -p ringsync --example 01_plan
//! ```

use ringsync::{Duration, PlanKind, RingParams};

fn main() -> Result<(), ringsync::Error> {
    // The reference ring's figures (PHY latencies, cable, residence, T_rest), 8 slaves.
    let params = RingParams {
        slaves: 8,
        t_cyc: Duration::from_us(500),
        ..RingParams::default()
    };
    let plan = ringsync::plan(&params, PlanKind::P2pLumped)?;
    println!(
        "8 slaves: shortest cycle {} (eq. 1), {} at the event level; a 500 µs cycle leaves {} spare",
        plan.min_t_cyc,
        plan.event.min_t_cyc,
        params.t_cyc - plan.min_t_cyc.max(plan.event.min_t_cyc)
    );
    // The table `ringsync plan` prints.
    print!(
        "{}",
        ringsync::layers::report::plan_table(&plan, PlanKind::P2pLumped)
    );
    assert!(plan.min_t_cyc <= params.t_cyc);

    // Too many slaves for the cycle: the error says by how much it is short.
    let crowded = RingParams {
        slaves: 200,
        ..params
    };
    let e = ringsync::plan(&crowded, PlanKind::P2pLumped).expect_err("200 slaves in 500 µs");
    println!("\n200 slaves: {e}");
    assert!(e.is_usage());
    Ok(())
}
