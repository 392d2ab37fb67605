//! 04: a master and two slaves driven by hand, no simulator: the sans-IO nodes of
//! `ringsync-proto` and the calls any driver makes (the simulator and the real-time runtime
//! make exactly these). Ideal links with the plan's figures (a hop's PHY and cable latency,
//! each frame's wire time, cut-through forwarding after the residence time), slave clocks
//! that read true time, the scenario's servo axes moved between events.
//!
//! ```sh
//! cargo run --release -p ringsync --example 04_nodes_by_hand
//! ```

use ringsync::layers::model::axes::{Axes, ServoAxes};
use ringsync::layers::proto::Instant;
use ringsync::layers::proto::node::{FrameOutcome, MasterEvent, SlaveEvent};

fn main() -> Result<(), ringsync::Error> {
    // The reference scenario on a ring of two slaves: the spec holds every node's config.
    let s = ringsync::parse("[ring]\nslaves = 2\n", "two slaves")?.scenario;
    let spec = s.build()?;
    let (mut master, mut slaves) = spec.nodes()?;
    let mut axes = ServoAxes::for_scenario(&s)?;
    // The links: first-bit latency of a hop, a frame's wire time, a slave's residence [ns].
    let link = spec.plan.link;
    let hop = link.hop().as_ns();
    let wire_time = |len: usize| link.frame_time(len).as_ns();
    let residence = s.ring.residence.0.as_ns();
    let next_node = |node: usize| (node + 1) % (spec.axes() + 1);
    let end = 200 * s.ring.cycle.0.as_ns(); // 200 cycles
    // Frames on the wire: (time the whole frame has arrived [ns], node it reaches: 0 is the
    // master, i is slave i, the frame).
    let mut wire: Vec<(i64, usize, Vec<u8>)> = Vec::new();
    let mut computed = 0;
    loop {
        // The next thing to happen: the master's timeout, a slave's latch, a frame arriving.
        let t_master = master.poll_timeout().as_ns();
        let (t_latch, i_latch) = (0..slaves.len())
            .map(|i| (slaves[i].poll_timeout().as_ns(), i))
            .min()
            .unwrap_or((i64::MAX, 0));
        let next_frame = (0..wire.len()).min_by_key(|&j| wire[j].0);
        let t_frame = next_frame.map_or(i64::MAX, |j| wire[j].0);
        let now = t_master.min(t_latch).min(t_frame);
        if now >= end {
            break;
        }
        if now == t_latch {
            // An encoder latch: the axis at this instant, its count to the slave.
            let i = i_latch;
            axes.advance(i, now.max(0));
            slaves[i].handle_sample(Instant::from_ns(now), axes.counts(i));
        } else if now == t_master {
            master.handle_timeout(Instant::from_ns(now));
        } else if let Some(j) = next_frame {
            let (_, node, mut bytes) = wire.swap_remove(j);
            if node == 0 {
                master.handle_frame(Instant::from_ns(now), &bytes);
            } else {
                let i = node - 1;
                let (first_bit, last_bit) = (now - wire_time(bytes.len()), now);
                let rx = (Instant::from_ns(first_bit), Instant::from_ns(last_bit));
                if slaves[i].handle_frame(rx.0, rx.1, &mut bytes) == FrameOutcome::Forward {
                    // Cut-through: out a residence after its first bit came in.
                    wire.push((now + residence + hop, next_node(node), bytes));
                }
                // The slave's responses and events.
                while let Some(tx) = slaves[i].poll_transmit() {
                    let arrives = tx.at.as_ns() + hop + wire_time(tx.bytes.len());
                    wire.push((arrives, next_node(node), tx.bytes));
                }
                while let Some(ev) = slaves[i].poll_event() {
                    axes.advance(i, now);
                    if let SlaveEvent::Apply { u } | SlaveEvent::Brake { u } = ev {
                        axes.set_command(i, u);
                    }
                }
            }
        }
        // The master's frames and events, after whatever it handled.
        while let Some(tx) = master.poll_transmit() {
            let arrives = tx.at.as_ns() + hop + wire_time(tx.bytes.len());
            wire.push((arrives, 1, tx.bytes));
        }
        while let Some(ev) = master.poll_event() {
            match ev {
                MasterEvent::Computed { k } => {
                    computed += 1;
                    if k % 50 == 0 {
                        let r = master.record();
                        println!(
                            "cycle {k:3}: commands {:+.3} V, {:+.3} V (samples from {:.4} s)",
                            r.u[0], r.u[1], r.sample_time[0]
                        );
                    }
                }
                MasterEvent::GroupStop { reason, .. } => println!("group stop: {}", reason.name()),
                MasterEvent::Order { .. }
                | MasterEvent::Monitor { .. }
                | MasterEvent::Ring { .. } => {}
            }
        }
    }
    let c = master.counters();
    println!(
        "{computed} law runs; {} frames sent; refused {}; retries {}; axis 1 at {:.3} rad",
        c.frames_sent,
        c.rejected.total(),
        c.retries,
        axes.position(0)
    );
    // The ring ran every cycle, refused nothing and kept the motion.
    assert!(computed >= 199, "{computed}");
    assert_eq!(c.rejected.total(), 0);
    assert!(!master.is_stopping());
    let x_d = master.desired(0, end as f64 * 1e-9).x;
    assert!(
        (x_d - axes.position(0)).abs() < 0.5,
        "{x_d} vs {}",
        axes.position(0)
    );
    Ok(())
}
