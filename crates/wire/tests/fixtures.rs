//! Byte fixtures for every frame kind. Each fixture is written out field by field from
//! docs/wire.md; the CRC-32 trailers were computed independently with Python's
//! `zlib.crc32` over the same bytes.

use ringsync_wire::{
    CommandRepr, Common, Error, FeedbackSlot, Flags, FrameKind, LumpedFrameRepr,
    LumpedOnlyFrameRepr, LumpedOnlySlot, LumpedPayload, Pdu, ResponseRepr, SlotCodec, Status,
    ethernet,
};

#[rustfmt::skip]
const COMMAND: [u8; 32] = [
    0x01, 0x02, 0x01, 0x01,             // version 1, kind 2 (command), flags STOP, retry 1
    0x04, 0x03, 0x02, 0x01,             // cycle 0x01020304
    0x06, 0x05,                         // seq 0x0506
    0x10, 0x00,                         // payload length 16
    0x03, 0x00,                         // target slave 3
    0x00, 0x00,                         // reserved
    0x00, 0x00, 0xC0, 0x3F,             // command 1.5 V (f32)
    0x40, 0x42, 0x0F, 0x00, 0, 0, 0, 0, // sampled at 1 000 000 ns
    0xDC, 0x8A, 0x88, 0x8F,             // CRC-32 0x8f888adc
];

fn command_repr() -> CommandRepr {
    CommandRepr {
        common: Common {
            flags: Flags::STOP,
            retry: 1,
            cycle: 0x0102_0304,
            seq: 0x0506,
        },
        target: 3,
        command_v: 1.5,
        sample_time_ns: 1_000_000,
    }
}

#[rustfmt::skip]
const RESPONSE: [u8; 44] = [
    0x01, 0x03, 0x00, 0x00,             // version 1, kind 3 (response), no flags, retry 0
    42, 0, 0, 0,                        // cycle 42
    7, 0,                               // seq 7
    28, 0,                              // payload length 28
    0x02, 0x00,                         // source slave 2
    0x02, 0x00,                         // status SATURATED
    0x0D, 0x0C, 0x0B, 0x0A,             // echo cycle 0x0A0B0C0D
    0xFE, 0xFF, 0xFF, 0xFF,             // position -2 counts
    0xE8, 0x03, 0x00, 0x00,             // velocity 1000 counts/s
    0xFD, 0x84, 0x1E, 0x00, 0, 0, 0, 0, // measured at 2 000 125 ns
    0x00, 0x00, 0x00, 0xBF,             // applied -0.5 V
    0xBA, 0xB8, 0xA7, 0x8C,             // CRC-32 0x8ca7b8ba
];

fn response_repr() -> ResponseRepr {
    ResponseRepr {
        common: Common {
            flags: Flags::empty(),
            retry: 0,
            cycle: 42,
            seq: 7,
        },
        source: 2,
        status: Status::SATURATED,
        echo_cycle: 0x0A0B_0C0D,
        position: -2,
        velocity: 1000,
        sample_time_ns: 2_000_125,
        applied_v: -0.5,
    }
}

#[rustfmt::skip]
const LUMPED: [u8; 68] = [
    0x01, 0x01, 0x00, 0x00,             // version 1, kind 1 (lumped)
    9, 0, 0, 0,                         // cycle 9
    1, 0,                               // seq 1
    52, 0,                              // payload length 12 + 2 * 20
    0x15, 0xCD, 0x5B, 0x07, 0, 0, 0, 0, // master time 123 456 789 ns
    0, 0,                               // first slot 0
    2, 0,                               // 2 slots
    // slot of slave 1
    0x00, 0x00, 0x10, 0x00,             // position 2^20 counts
    0x9C, 0xFF, 0xFF, 0xFF,             // velocity -100 counts/s
    0xE8, 0x03, 0, 0, 0, 0, 0, 0,       // sampled at 1000 ns
    0, 0,                               // status
    1, 0,                               // written, reserved
    // slot of slave 2
    0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0,
    0x08, 0x00,                         // status CLOCK_UNLOCKED
    0, 0,                               // not written, reserved
    0xAC, 0x27, 0x35, 0x90,             // CRC-32 0x903527ac
];

fn lumped_repr() -> LumpedFrameRepr {
    LumpedFrameRepr {
        common: Common {
            cycle: 9,
            seq: 1,
            ..Common::default()
        },
        master_time_ns: 123_456_789,
        first_slot: 0,
        slots: vec![
            FeedbackSlot {
                position: 1 << 20,
                velocity: -100,
                sample_time_ns: 1000,
                status: Status::empty(),
                written: true,
            },
            FeedbackSlot {
                status: Status::CLOCK_UNLOCKED,
                ..FeedbackSlot::default()
            },
        ],
    }
}

#[rustfmt::skip]
const LUMPED_ONLY: [u8; 60] = [
    0x01, 0x04, 0x00, 0x00,             // version 1, kind 4 (lumped-only)
    10, 0, 0, 0,                        // cycle 10
    2, 0,                               // seq 2
    44, 0,                              // payload length 12 + 32
    5, 0, 0, 0, 0, 0, 0, 0,             // master time 5 ns
    4, 0,                               // first slot 4: the slot is slave 5's
    1, 0,                               // 1 slot
    7, 0, 0, 0,                         // position 7
    8, 0, 0, 0,                         // velocity 8
    9, 0, 0, 0, 0, 0, 0, 0,             // sampled at 9 ns
    0, 0, 1, 0,                         // status, written, reserved
    5, 0, 0, 0,                         // desired position 5
    0xFB, 0xFF, 0xFF, 0xFF,             // desired velocity -5
    0x00, 0x00, 0x00, 0x40,             // command 2.0 V
    0x9D, 0xC3, 0xB0, 0x96,             // CRC-32 0x96b0c39d
];

fn lumped_only_repr() -> LumpedOnlyFrameRepr {
    LumpedOnlyFrameRepr {
        common: Common {
            cycle: 10,
            seq: 2,
            ..Common::default()
        },
        master_time_ns: 5,
        first_slot: 4,
        slots: vec![LumpedOnlySlot {
            feedback: FeedbackSlot {
                position: 7,
                velocity: 8,
                sample_time_ns: 9,
                status: Status::empty(),
                written: true,
            },
            desired_position: 5,
            desired_velocity: -5,
            command_v: 2.0,
        }],
    }
}

fn emit(pdu: &Pdu) -> Vec<u8> {
    let mut buf = vec![0xAA; pdu.buffer_len()];
    let n = pdu.emit(&mut buf).expect("emit");
    assert_eq!(n, buf.len());
    buf
}

#[test]
fn command_fixture() {
    assert_eq!(Pdu::parse(&COMMAND), Ok(Pdu::Command(command_repr())));
    assert_eq!(emit(&Pdu::Command(command_repr())), COMMAND);
}

#[test]
fn response_fixture() {
    assert_eq!(Pdu::parse(&RESPONSE), Ok(Pdu::Response(response_repr())));
    assert_eq!(emit(&Pdu::Response(response_repr())), RESPONSE);
}

#[test]
fn lumped_fixture() {
    assert_eq!(Pdu::parse(&LUMPED), Ok(Pdu::Lumped(lumped_repr())));
    assert_eq!(emit(&Pdu::Lumped(lumped_repr())), LUMPED);
}

#[test]
fn lumped_only_fixture() {
    assert_eq!(
        Pdu::parse(&LUMPED_ONLY),
        Ok(Pdu::LumpedOnly(lumped_only_repr()))
    );
    assert_eq!(emit(&Pdu::LumpedOnly(lumped_only_repr())), LUMPED_ONLY);
}

#[test]
fn ethernet_padding_after_crc_is_ignored() {
    let mut padded = COMMAND.to_vec();
    padded.resize(60, 0);
    assert_eq!(Pdu::parse(&padded), Ok(Pdu::Command(command_repr())));
}

#[test]
fn every_single_bit_flip_is_rejected() {
    for fixture in [&COMMAND[..], &RESPONSE[..], &LUMPED[..], &LUMPED_ONLY[..]] {
        for byte in 0..fixture.len() {
            for bit in 0..8 {
                let mut b = fixture.to_vec();
                b[byte] ^= 1 << bit;
                assert!(
                    Pdu::parse(&b).is_err(),
                    "flip of byte {byte} bit {bit} accepted"
                );
            }
        }
    }
}

/// Re-seals a modified fixture with a correct CRC so that the field check itself is hit.
fn reseal(mut b: Vec<u8>) -> Vec<u8> {
    let len = u16::from_le_bytes([b[10], b[11]]) as usize;
    let crc = ringsync_wire::crc32(&b[..12 + len]);
    b[12 + len..16 + len].copy_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn typed_errors_name_the_problem() {
    let at = |i: usize, v: u8, f: &[u8]| {
        let mut b = f.to_vec();
        b[i] = v;
        Pdu::parse(&reseal(b))
    };
    assert_eq!(
        Pdu::parse(&COMMAND[..5]),
        Err(Error::Truncated {
            what: "header",
            needed: 12,
            got: 5
        })
    );
    assert_eq!(
        Pdu::parse(&COMMAND[..30]),
        Err(Error::Truncated {
            what: "payload and CRC",
            needed: 32,
            got: 30
        })
    );
    assert_eq!(at(0, 2, &COMMAND), Err(Error::BadVersion(2)));
    assert_eq!(at(1, 9, &COMMAND), Err(Error::BadKind(9)));
    assert_eq!(at(2, 0x80, &COMMAND), Err(Error::ReservedFlags(0x80)));
    assert_eq!(at(2, 0x08, &COMMAND), Err(Error::ReservedFlags(0x08)));
    assert_eq!(at(12, 0, &COMMAND), Err(Error::BadSlave(0)));
    assert_eq!(
        at(14, 1, &COMMAND),
        Err(Error::Reserved {
            field: "command bytes 2-3",
            value: 1
        })
    );
    // 0x7FC00000 is a NaN.
    let mut nan = COMMAND.to_vec();
    nan[16..20].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(Pdu::parse(&reseal(nan)), Err(Error::NonFinite("command")));
    assert_eq!(at(15, 0x40, &RESPONSE), Err(Error::ReservedStatus(0x4002)));
    assert_eq!(at(42, 2, &LUMPED), Err(Error::BadMarker(2)));
    let mut b = COMMAND.to_vec();
    b[31] ^= 0xFF;
    assert!(matches!(Pdu::parse(&b), Err(Error::BadCrc { .. })));
    // A command frame whose header claims 12 payload bytes.
    let mut short = COMMAND[..28].to_vec();
    short[10] = 12;
    assert_eq!(
        Pdu::parse(&reseal(short)),
        Err(Error::PayloadLength {
            kind: FrameKind::Command,
            expected: 16,
            got: 12
        })
    );
    // A lumped frame that declares 3 slots but carries 2.
    assert_eq!(
        at(22, 3, &LUMPED),
        Err(Error::PayloadLength {
            kind: FrameKind::Lumped,
            expected: 72,
            got: 52
        })
    );
    assert_eq!(
        at(22, 200, &LUMPED),
        Err(Error::SlotCountOverCapacity {
            count: 200,
            capacity: 73
        })
    );
    assert_eq!(
        CommandRepr::parse(&RESPONSE),
        Err(Error::WrongKind {
            expected: FrameKind::Command,
            got: FrameKind::Response
        })
    );
}

#[test]
fn emit_rejects_what_it_cannot_encode() {
    let mut buf = [0u8; 64];
    let mut c = command_repr();
    c.command_v = f32::INFINITY;
    assert_eq!(c.emit(&mut buf), Err(Error::NonFinite("command")));
    c.command_v = 0.0;
    c.target = 0;
    assert_eq!(c.emit(&mut buf), Err(Error::BadSlave(0)));
    assert_eq!(
        command_repr().emit(&mut buf[..31]),
        Err(Error::BufferTooSmall {
            needed: 32,
            got: 31
        })
    );
    let mut big = lumped_repr();
    big.slots = vec![FeedbackSlot::default(); 74];
    let mut out = vec![0u8; big.buffer_len()];
    assert_eq!(
        big.emit(&mut out),
        Err(Error::SlotCountOverCapacity {
            count: 74,
            capacity: 73
        })
    );
    big.slots.truncate(73);
    let mut out = vec![0u8; big.buffer_len()];
    // 12 header + 12 prefix + 73 * 20 + 4 CRC = 1488 <= 1500 (MTU); 74 slots would be 1508.
    assert_eq!(big.emit(&mut out), Ok(1488));
}

#[test]
fn slave_writes_its_slot_in_place() {
    let mut buf = LUMPED.to_vec();
    let mut frame = ringsync_wire::Frame::new_checked(&mut buf[..]).expect("frame");
    assert_eq!(frame.check(), Ok(FrameKind::Lumped));
    let mut payload =
        LumpedPayload::new_checked(frame.payload_mut(), FrameKind::Lumped).expect("payload");
    assert_eq!(payload.master_time_ns(), 123_456_789);
    assert_eq!(payload.slot_index(1), Some(0));
    assert_eq!(payload.slot_index(2), Some(1));
    assert_eq!(payload.slot_index(3), None);
    assert_eq!(payload.slot_index(0), None);
    let k = payload.slot_index(2).expect("slot");
    let mine = FeedbackSlot {
        position: -5,
        velocity: 6,
        sample_time_ns: 77,
        status: Status::empty(),
        written: true,
    };
    mine.emit(payload.slot_bytes_mut(k).expect("bytes"))
        .expect("emit slot");
    frame.fill_crc();
    let Ok(Pdu::Lumped(r)) = Pdu::parse(&buf) else {
        panic!("reparse")
    };
    assert_eq!(r.slots[1], mine);
    assert_eq!(r.slots[0], lumped_repr().slots[0]);
}

#[test]
fn ethernet_frame_lengths() {
    // Hand-computed: 14 + 32 + 4 = 50 < 64, so a command frame is padded to 64 B.
    assert_eq!(ethernet::frame_len(32), 64);
    assert_eq!(ethernet::wire_len(32), 72);
    // 14 + 108 + 4 = 126 for a 4-slot lumped frame.
    assert_eq!(ethernet::frame_len(108), 126);
    assert_eq!(ethernet::frame_len(46), 64);
    assert_eq!(ethernet::frame_len(47), 65);
    let mut buf = [0u8; 60];
    ethernet::emit_header(&mut buf, [1; 6], [2; 6]).expect("header");
    buf[14..46].copy_from_slice(&COMMAND);
    let eth = ringsync_wire::EthernetFrame::new_checked(&buf[..]).expect("eth");
    assert_eq!(eth.ethertype(), 0x88B5);
    assert_eq!(eth.dst(), [1; 6]);
    assert_eq!(
        Pdu::parse(eth.ringsync_payload().expect("ours")),
        Ok(Pdu::Command(command_repr()))
    );
    buf[13] = 0x00;
    let eth = ringsync_wire::EthernetFrame::new_checked(&buf[..]).expect("eth");
    assert_eq!(eth.ringsync_payload(), Err(Error::BadEtherType(0x8800)));
}
