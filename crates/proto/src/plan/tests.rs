use proptest::prelude::*;

use super::*;
use crate::time::Instant;

fn ns(v: i64) -> Duration {
    Duration::from_ns(v)
}

/// Reference scenario, n = 4, every term computed by hand from docs/system.md, "The cycle plan":
/// hop L = 60 + 2·5 + 240 = 310 ns; lumped PDU 12 + 12 + 4·20 + 4 = 108 B → frame 126 B →
/// 134 B on the wire → 10.72 µs; command PDU 32 B → padded 64 B frame → 72 B → 5.76 µs.
#[test]
fn reference_scenario_by_hand() {
    let p = CyclePlan::new(&RingParams::default()).expect("plan");
    assert_eq!(p.hop, ns(310));
    assert_eq!(p.lumped.frame_bytes, vec![126]);
    assert_eq!(p.command_frame_bytes, 64);
    assert_eq!(p.response_frame_bytes, 64);
    assert_eq!(p.t_lmf, ns(10_720));
    // D_ms(4) = 4·310 + 3·1000; D_snm = 1000 + 310.
    assert_eq!(p.d_ms, ns(4_240));
    assert_eq!(p.d_snm, ns(1_310));
    assert_eq!(p.t_syn, ns(10_720 + 4_240 + 1_310 + 100_000));
    assert_eq!(p.t_cmf, ns(5_760));
    // D_ci = i·310 + (i−1)·1000; T_slot(i) = 5760 + 2·D_ci + 2000.
    assert_eq!(p.d_c, vec![ns(310), ns(1_620), ns(2_930), ns(4_240)]);
    assert_eq!(p.slot, vec![ns(8_380), ns(11_000), ns(13_620), ns(16_240)]);
    assert_eq!(p.reserve_slices, 2);
    assert_eq!(p.reserve_slice, ns(16_240));
    assert_eq!(p.min_t_cyc, ns(116_270 + 49_240 + 32_480));
    assert_eq!(p.t_idle, ns(1_000_000 - 197_990));
    // Event level: 5760 + 2000 + 5760 + 5·310 + 3·1000 = 18 070 ns for every slice.
    assert_eq!(p.event.slot, vec![ns(18_070); 4]);
    assert_eq!(p.event.min_t_cyc, ns(116_270 + 4 * 18_070 + 2 * 18_070));
    assert!(p.check_fits().is_ok());
    // Lumped-only plan: 32-byte slots → PDU 156 B → frame 174 B → 182 B → 14.56 µs.
    assert_eq!(p.lumped_only.lumped.frame_bytes, vec![174]);
    assert_eq!(
        p.lumped_only.min_t_cyc,
        ns(14_560 + 4_240 + 1_310 + 100_000)
    );
}

#[test]
fn reserve_count_is_floor_n_over_4_plus_1() {
    for (n, k) in [(1, 1), (3, 1), (4, 2), (7, 2), (8, 3), (13, 4)] {
        let p = CyclePlan::new(&RingParams {
            slaves: n,
            t_cyc: Duration::from_ms(10),
            ..RingParams::default()
        })
        .expect("plan");
        assert_eq!(p.reserve_slices, k, "n = {n}");
    }
}

#[test]
fn a_long_ring_splits_the_lumped_frame() {
    let p = CyclePlan::new(&RingParams {
        slaves: 100,
        t_cyc: Duration::from_ms(10),
        ..RingParams::default()
    })
    .expect("plan");
    // 1472 B of slot room / 20 B = 73 slots per frame, so 73 + 27.
    assert_eq!(p.lumped.frame_slots, vec![73, 27]);
    // 12 + 12 + 1460 + 4 = 1488 → 1506 B frame; 12 + 12 + 540 + 4 = 568 → 586 B frame.
    assert_eq!(p.lumped.frame_bytes, vec![1_506, 586]);
    // (8 + 1506)·80 + 960 (gap) + (8 + 586)·80.
    assert_eq!(p.t_lmf, ns(121_120 + 960 + 47_520));
}

/// EtherCAT's published figure (Beckhoff): 100 servo axes updated every 100 µs. The
/// lumped-only plan is the EtherCAT-like one: one frame that every slave reads and writes on
/// the fly. With 8 B of process data per axis, EtherCAT-like forwarding (cut-through, 1 µs
/// residence, the coupler figure of docs/system.md, "Wire facts") and no master computation in the cycle:
#[test]
fn hundred_axes_match_ethercat_order_of_magnitude() {
    let params = RingParams {
        slaves: 100,
        lumped_only_slot_bytes: 8,
        t_rest: Duration::ZERO,
        t_cyc: Duration::from_ms(10),
        ..RingParams::default()
    };
    let lo = CyclePlan::new(&params).expect("plan").lumped_only;
    // One frame: 12 + 12 + 800 + 4 = 828 B PDU → 846 B frame → 854 B → 68.32 µs on the wire.
    assert_eq!(lo.lumped.frame_bytes, vec![846]);
    assert_eq!(lo.lumped.t_lmf, ns(68_320));
    // Plus D_ms(100) = 100·310 + 99·1000 and D_snm = 1310: 199.63 µs in all, the same order
    // of magnitude as the published 100 µs (docs/planner.md discusses the difference).
    assert_eq!(lo.min_t_cyc, ns(68_320 + 130_000 + 1_310));
    assert!(lo.min_t_cyc > Duration::from_us(50) && lo.min_t_cyc < Duration::from_us(300));
    // The frame alone takes about two thirds of EtherCAT's 100 µs.
    assert!(lo.lumped.t_lmf < Duration::from_us(100));
}

#[test]
fn too_short_cycle_names_the_shortfall() {
    let p = CyclePlan::new(&RingParams {
        t_cyc: Duration::from_us(200),
        ..RingParams::default()
    })
    .expect("plan");
    // Eq. 1 needs 197.99 µs (fits) but the ring path needs 224.69 µs.
    assert_eq!(
        p.check_fits(),
        Err(PlanError::CycleTooShort {
            slaves: 4,
            t_cyc: Duration::from_us(200),
            needed: ns(224_690),
            short: ns(24_690),
            basis: "event level",
        })
    );
    let msg = p.check_fits().expect_err("short").to_string();
    assert!(msg.contains("short by 24.690 µs"), "{msg}");
}

/// A huge or tiny value is echoed in scientific notation, not as hundreds of digits.
#[test]
fn an_extreme_value_is_echoed_short() {
    let msg = |p: RingParams| CyclePlan::new(&p).expect_err("out of range").to_string();
    let d = RingParams::default;
    assert_eq!(
        msg(RingParams {
            cable_m: 1e300,
            ..d()
        }),
        "cable_m = 1e300 m is out of range: allowed 0 ..= 100000 m"
    );
    assert_eq!(
        msg(RingParams {
            propagation_ns_per_m: -2.5e-300,
            ..d()
        }),
        "propagation_ns_per_m = -2.5e-300 ns/m is out of range: allowed 0 ..= 1000 ns/m"
    );
    assert_eq!(super::short_number(1500.0), "1500");
    assert_eq!(super::short_number(0.0), "0");
}

#[test]
fn out_of_range_parameters_are_named() {
    let bad = |p: RingParams| match CyclePlan::new(&p) {
        Err(PlanError::OutOfRange { field, .. }) => field,
        other => panic!("expected OutOfRange, got {other:?}"),
    };
    let d = RingParams::default;
    assert_eq!(bad(RingParams { slaves: 0, ..d() }), "slaves");
    assert_eq!(
        bad(RingParams {
            slaves: 70_000,
            ..d()
        }),
        "slaves"
    );
    assert_eq!(
        bad(RingParams {
            bit_rate_bps: 0,
            ..d()
        }),
        "bit_rate"
    );
    assert_eq!(
        bad(RingParams {
            t_cyc: Duration::ZERO,
            ..d()
        }),
        "t_cyc"
    );
    assert_eq!(
        bad(RingParams {
            residence: ns(-1),
            ..d()
        }),
        "residence"
    );
    assert_eq!(
        bad(RingParams {
            cable_m: f64::NAN,
            ..d()
        }),
        "cable_m"
    );
    assert_eq!(
        bad(RingParams {
            cable_m: -1.0,
            ..d()
        }),
        "cable_m"
    );
    assert_eq!(
        bad(RingParams {
            slot_bytes: 0,
            ..d()
        }),
        "slot_bytes"
    );
    assert_eq!(
        bad(RingParams {
            slot_bytes: 1_473,
            ..d()
        }),
        "slot_bytes"
    );
    assert_eq!(bad(RingParams { mtu: 10, ..d() }), "mtu");
}

#[test]
fn max_slaves_is_the_largest_that_fits() {
    let params = RingParams::default();
    let n = max_slaves(&params, PlanKind::P2pLumped).expect("max");
    assert!(n > 4);
    let at = |n| {
        CyclePlan::new(&RingParams {
            slaves: n,
            ..params.clone()
        })
        .expect("plan")
    };
    assert!(at(n).check_fits().is_ok());
    assert!(at(n + 1).check_fits().is_err());
    let tiny = RingParams {
        t_cyc: Duration::from_us(10),
        ..params
    };
    assert_eq!(max_slaves(&tiny, PlanKind::P2pLumped), Ok(0));
    // The lumped-only plan has no P2P phase, so a longer ring fits the same cycle.
    let lo = max_slaves(&params, PlanKind::LumpedOnly).expect("max");
    assert!(lo > n);
    let at_lo = |n| at(n).check_fits_for(PlanKind::LumpedOnly);
    assert!(at_lo(lo).is_ok() && at_lo(lo + 1).is_err());
}

#[test]
fn timeline_of_the_reference_cycle() {
    let p = CyclePlan::new(&RingParams::default()).expect("plan");
    let tl = p.timeline();
    let at = |frame, node| {
        tl.passages
            .iter()
            .find(|x| {
                x.frame == frame && x.node == node && (x.rx.is_some() || node != Node::Master)
            })
            .copied()
            .expect("passage")
    };
    // The lumped frame reaches slave 1 after one hop and leaves it T_t later.
    let s1 = at(FrameRef::Lumped(0), Node::Slave(1));
    assert_eq!(s1.rx.expect("rx").start, Instant::from_ns(310));
    assert_eq!(s1.tx.expect("tx").start, Instant::from_ns(1_310));
    // Back at the master completely at T_lmf + D_ms + D_snm.
    let back = at(FrameRef::Lumped(0), Node::Master);
    assert_eq!(
        back.rx.expect("rx").end,
        Instant::from_ns(10_720 + 4_240 + 1_310)
    );
    assert!(back.tx.is_none());
    assert_eq!(p.event.p2p_start, p.t_syn);
    assert_eq!(p.event.turnaround, Duration::ZERO);
    // Slice 1 starts at T_syn; the command reaches slave 1 one hop later.
    let c1 = at(FrameRef::Command(1), Node::Slave(1));
    assert_eq!(c1.rx.expect("rx").start, Instant::from_ns(116_270 + 310));
    assert!(c1.tx.is_none(), "the target consumes its command");
    // The response of slave 1 passes slaves 2..4 and reaches the master.
    let r1 = at(FrameRef::Response(1), Node::Master);
    assert_eq!(r1.rx.expect("rx").end, Instant::from_ns(116_270 + 18_070));
    assert!(at(FrameRef::Response(1), Node::Slave(3)).tx.is_some());
    assert_eq!(tl.busy_end(), Instant::ZERO + p.event.min_t_cyc);
    let idle = tl.phase(PhaseKind::Idle).expect("idle");
    assert_eq!(idle.end - idle.start, p.event.t_idle);
}

fn params() -> impl Strategy<Value = RingParams> {
    (
        1u32..200,
        prop_oneof![
            Just(10_000_000u64),
            Just(100_000_000),
            Just(1_000_000_000),
            1_000_000u64..2_000_000_000
        ],
        0i64..2_000,
        0i64..2_000,
        0.0f64..200.0,
        0i64..5_000,
        0i64..10_000,
        0i64..500_000,
        1i64..20_000_000,
        1usize..200,
        1usize..200,
    )
        .prop_map(
            |(slaves, bps, rx, tx, cable, tt, tti, rest, cyc, sb, lsb)| RingParams {
                slaves,
                bit_rate_bps: bps,
                phy_rx: ns(rx),
                phy_tx: ns(tx),
                cable_m: cable,
                residence: ns(tt),
                response_delay: ns(tti),
                t_rest: ns(rest),
                t_cyc: ns(cyc),
                slot_bytes: sb,
                lumped_only_slot_bytes: lsb,
                ..RingParams::default()
            },
        )
}

proptest! {
    /// Eq. 1 from its parts: the budget rows add up to T_cyc exactly.
    #[test]
    fn eq1_terms_sum_to_t_cyc(p in params()) {
        let plan = CyclePlan::new(&p).expect("plan");
        let sum: Duration = plan.budget().iter().map(|(_, d)| *d).sum();
        prop_assert_eq!(sum, p.t_cyc);
        let sum: Duration = plan.lumped_only_budget().iter().map(|(_, d)| *d).sum();
        prop_assert_eq!(sum, p.t_cyc);
        prop_assert_eq!(plan.t_syn, plan.t_lmf + plan.d_ms + plan.d_snm + p.t_rest);
        for (i, s) in plan.slot.iter().enumerate() {
            prop_assert_eq!(*s, plan.t_cmf + plan.d_c[i] * 2 + p.response_delay);
        }
    }

    /// The frame-by-frame timeline agrees with the closed-form event-level figures.
    #[test]
    fn timeline_matches_closed_form(p in params()) {
        let plan = CyclePlan::new(&p).expect("plan");
        let tl = plan.timeline();
        let back = tl.phase(PhaseKind::Sync).expect("sync").end;
        prop_assert_eq!(back + p.t_rest, Instant::ZERO + plan.t_syn);
        prop_assert!(plan.event.p2p_start >= plan.t_syn);
        for i in 1..=p.slaves {
            let s = tl.phase(PhaseKind::Slice(i)).expect("slice");
            prop_assert_eq!(s.end - s.start, plan.event.slot[i as usize - 1]);
            let cmd = tl.passages.iter()
                .find(|x| x.frame == FrameRef::Command(i) && x.node == Node::Slave(i))
                .expect("command at target");
            // The command's first bit reaches slave i after D_ci, as in eq. 2.
            // (On every link frames keep the inter-frame gap; checked below.)
            prop_assert_eq!(cmd.rx.expect("rx").start - s.start, plan.d_c[i as usize - 1]);
        }
        prop_assert_eq!(tl.busy_end() - Instant::ZERO, plan.event.min_t_cyc);
        // Frames never overlap on any link: each node's transmissions are spaced by at least
        // the gap (the master's too).
        let mut by_node: std::collections::BTreeMap<Node, Vec<(Instant, Instant)>> = Default::default();
        for x in &tl.passages {
            if let Some(t) = x.tx { by_node.entry(x.node).or_default().push((t.start, t.end)); }
        }
        for (_, mut v) in by_node {
            v.sort();
            for w in v.windows(2) {
                prop_assert!(w[1].0 - w[0].1 >= plan.link.gap());
            }
        }
    }
}
