//! Simulator speed: one whole `paper-2015` run (4 s simulated, 4 axes, every frame timed on
//! every hop), and the cost per simulated cycle as the ring grows.
//!
//! ```sh
//! cargo bench -p ringsync-sim --bench sim
//! ```

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ringsync_model::scenario::{Dur, Scenario};
use ringsync_proto::{CyclePlan, Duration};
use ringsync_sim::run::{RunOptions, run};

fn paper_2015(c: &mut Criterion) {
    let s = Scenario::default();
    c.bench_function("paper_2015_run_4s", |b| {
        b.iter(|| black_box(run(&s, RunOptions::default()).expect("run")))
    });
}

/// A ring of n reference axes with the shortest cycle that holds it (+10 %), 20 cycles.
fn ring(n: u32) -> Scenario {
    let mut s = Scenario::default();
    s.ring.slaves = n;
    s.ring.cycle = Dur(Duration::from_ms(10_000));
    let plan = CyclePlan::new(&s.ring_params()).expect("plan");
    let need = plan.min_t_cyc.max(plan.event.min_t_cyc).as_ns();
    let cycle = ((need + need / 10) / 1000 + 1) * 1000;
    s.ring.cycle = Dur(Duration::from_ns(cycle));
    s.duration = Dur(Duration::from_ns(cycle * 20));
    s
}

fn cycle_cost(c: &mut Criterion) {
    let mut g = c.benchmark_group("cycle_cost_vs_n");
    g.sample_size(20);
    for n in [2u32, 4, 8, 16, 32, 64, 128, 256] {
        let s = ring(n);
        g.throughput(Throughput::Elements(20));
        g.bench_with_input(BenchmarkId::from_parameter(n), &s, |b, s| {
            b.iter(|| black_box(run(s, RunOptions::default()).expect("run")))
        });
    }
    g.finish();
}

criterion_group!(benches, paper_2015, cycle_cost);
criterion_main!(benches);
