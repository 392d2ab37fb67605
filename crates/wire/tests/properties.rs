//! Property tests: emit → parse is the identity for every frame kind, and no parser panics
//! on arbitrary bytes.

use proptest::prelude::*;
use ringsync_wire::{
    CommandRepr, Common, EthernetFrame, FeedbackSlot, Flags, Frame, FrameKind, LumpedOnlySlot,
    LumpedPayload, LumpedRepr, Pdu, ResponseRepr, SlotCodec, Status,
};

fn common() -> impl Strategy<Value = Common> {
    (any::<bool>(), any::<u8>(), any::<u32>(), any::<u16>()).prop_map(
        |(stop, retry, cycle, seq)| Common {
            flags: if stop { Flags::STOP } else { Flags::empty() },
            retry,
            cycle,
            seq,
        },
    )
}

fn status() -> impl Strategy<Value = Status> {
    (0u16..=Status::DEFINED).prop_map(|b| Status::from_bits(b).expect("defined bits"))
}

fn finite_f32() -> impl Strategy<Value = f32> {
    any::<f32>().prop_filter("finite", |v| v.is_finite())
}

fn feedback() -> impl Strategy<Value = FeedbackSlot> {
    (
        any::<i32>(),
        any::<i32>(),
        any::<u64>(),
        status(),
        any::<bool>(),
    )
        .prop_map(
            |(position, velocity, sample_time_ns, status, written)| FeedbackSlot {
                position,
                velocity,
                sample_time_ns,
                status,
                written,
            },
        )
}

fn lumped_only_slot() -> impl Strategy<Value = LumpedOnlySlot> {
    (feedback(), any::<i32>(), any::<i32>(), finite_f32()).prop_map(
        |(feedback, desired_position, desired_velocity, command_v)| LumpedOnlySlot {
            feedback,
            desired_position,
            desired_velocity,
            command_v,
        },
    )
}

fn pdu() -> impl Strategy<Value = Pdu> {
    prop_oneof![
        (
            common(),
            any::<u64>(),
            0u16..1000,
            prop::collection::vec(feedback(), 0..=73)
        )
            .prop_map(|(common, master_time_ns, first_slot, slots)| Pdu::Lumped(
                LumpedRepr {
                    common,
                    master_time_ns,
                    first_slot,
                    slots
                }
            )),
        (
            common(),
            any::<u64>(),
            0u16..1000,
            prop::collection::vec(lumped_only_slot(), 0..=46)
        )
            .prop_map(
                |(common, master_time_ns, first_slot, slots)| Pdu::LumpedOnly(LumpedRepr {
                    common,
                    master_time_ns,
                    first_slot,
                    slots
                })
            ),
        (common(), 1u16.., finite_f32(), any::<u64>()).prop_map(
            |(common, target, command_v, sample_time_ns)| Pdu::Command(CommandRepr {
                common,
                target,
                command_v,
                sample_time_ns
            })
        ),
        (
            common(),
            1u16..,
            status(),
            any::<u32>(),
            any::<i32>(),
            any::<i32>(),
            any::<u64>(),
            finite_f32()
        )
            .prop_map(
                |(
                    common,
                    source,
                    status,
                    echo_cycle,
                    position,
                    velocity,
                    sample_time_ns,
                    applied_v,
                )| {
                    Pdu::Response(ResponseRepr {
                        common,
                        source,
                        status,
                        echo_cycle,
                        position,
                        velocity,
                        sample_time_ns,
                        applied_v,
                    })
                }
            ),
    ]
}

proptest! {
    #[test]
    fn emit_then_parse_is_identity(p in pdu(), pad in 0usize..64) {
        let mut buf = vec![0u8; p.buffer_len() + pad];
        let n = p.emit(&mut buf).expect("emit");
        prop_assert_eq!(n, p.buffer_len());
        // Trailing bytes (Ethernet padding) do not change the result.
        prop_assert_eq!(Pdu::parse(&buf), Ok(p.clone()));
        prop_assert_eq!(Pdu::parse(&buf[..n]), Ok(p));
    }

    #[test]
    fn any_truncation_is_an_error(p in pdu(), cut in any::<prop::sample::Index>()) {
        let mut buf = vec![0u8; p.buffer_len()];
        p.emit(&mut buf).expect("emit");
        let cut = cut.index(buf.len());
        prop_assert!(Pdu::parse(&buf[..cut]).is_err());
    }

    #[test]
    fn parsers_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..1600)) {
        let _ = Pdu::parse(&bytes);
        let _ = CommandRepr::parse(&bytes);
        let _ = ResponseRepr::parse(&bytes);
        let _ = LumpedRepr::<FeedbackSlot>::parse(&bytes);
        let _ = LumpedRepr::<LumpedOnlySlot>::parse(&bytes);
        let _ = FeedbackSlot::parse(&bytes);
        let _ = LumpedOnlySlot::parse(&bytes);
        if let Ok(f) = Frame::new_checked(&bytes[..]) {
            let _ = (f.check(), f.payload(), f.crc(), f.cycle());
            for kind in [FrameKind::Lumped, FrameKind::LumpedOnly, FrameKind::Command] {
                if let Ok(p) = LumpedPayload::new_checked(f.payload(), kind) {
                    for k in 0..=usize::from(p.slot_count()) {
                        let _ = p.slot_bytes(k);
                    }
                    let _ = (p.slot_index(1), p.slot_index(u16::MAX), p.master_time_ns());
                }
            }
        }
        if let Ok(e) = EthernetFrame::new_checked(&bytes[..]) {
            let _ = (e.dst(), e.src(), e.ringsync_payload().map(Pdu::parse));
        }
    }

    /// Valid header with random payload bytes and a correct CRC: reaches the payload checks.
    #[test]
    fn sealed_random_payloads_never_panic(kind in 0u8..6, payload in prop::collection::vec(any::<u8>(), 0..200)) {
        let mut b = vec![1, kind, 0, 0, 0, 0, 0, 0, 0, 0];
        b.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        b.extend_from_slice(&payload);
        let crc = ringsync_wire::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        let _ = Pdu::parse(&b);
    }
}
