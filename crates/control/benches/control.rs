//! Per-cycle costs: one controller step (history update + the sync law with the paper's
//! estimator) for n = 4, 64, 1024 axes, and one 1 ms plant interval of one axis.
//!
//! ```sh
//! cargo bench -p ringsync-control --bench control
//! ```

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ringsync_control::{
    ControlInput, ControlOutput, Controller, EstimatorKind, Feedback, Gains, State, SyncController,
    SyncParams, VelocitySource,
};
use ringsync_plant::{Friction, SignModel, TorqueAxis};

fn controller_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("controller_step_sync_paper");
    for n in [4usize, 64, 1024] {
        let params = SyncParams {
            estimator: EstimatorKind::Paper,
            ..SyncParams::reference()
        };
        let law = SyncController::new(Gains::uniform(n, 3.182, 1.591, 0.75), params).expect("law");
        let mut ctl = Controller::new(law, VelocitySource::Reported);
        let mut fb = Feedback::new(n);
        let mut input = ControlInput::new(n, 1e-3);
        let mut out = ControlOutput::new(n);
        for i in 0..n {
            fb.position[i] = 0.01 * i as f64;
            fb.velocity[i] = -0.1;
            fb.desired[i] = State {
                x: 0.02 * i as f64,
                v: 1.0,
                a: 3.0,
            };
            input.apply_time[i] = 130e-6 + 1e-6 * i as f64;
            input.desired[i] = fb.desired[i];
        }
        let mut t = 0.0;
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                t += 1e-3;
                fb.sample_time.fill(t);
                for a in input.apply_time.iter_mut() {
                    *a += 1e-3;
                }
                ctl.update(black_box(&fb), black_box(&input), &mut out)
                    .expect("update");
                black_box(&out.u);
            })
        });
    }
    g.finish();
}

fn plant_interval(c: &mut Criterion) {
    let mut g = c.benchmark_group("plant_interval_1ms_one_axis");
    let (j, ka, b, tc) = (4.96e-4, 0.0318, 1e-5, 0.00636);
    let cases = [
        ("viscous_exact", Friction::viscous(b)),
        (
            "coulomb_exact",
            Friction {
                viscous: b,
                coulomb: tc,
                sign: SignModel::Exact,
            },
        ),
        (
            "coulomb_smooth_rk4_10us",
            Friction {
                viscous: b,
                coulomb: tc,
                sign: SignModel::Smooth { v_s: 1e-3 },
            },
        ),
    ];
    for (name, friction) in cases {
        let axis = TorqueAxis::new(j, ka, friction, 10.0).expect("axis");
        let (mut x, mut v) = (0.0, 0.0);
        let mut k = 0u32;
        g.bench_function(name, |bch| {
            bch.iter(|| {
                k = k.wrapping_add(1);
                let u = if k % 64 < 32 { 2.0 } else { -2.0 };
                axis.step(&mut x, &mut v, black_box(u), 1e-3);
                black_box((x, v));
            })
        });
    }
    g.finish();
}

criterion_group!(benches, controller_step, plant_interval);
criterion_main!(benches);
