//! Byte fixtures for every frame kind. Each fixture is written out field by field from
//! docs/wire.md; the CRC-32 trailers were computed independently with Python's
//! `zlib.crc32` over the same bytes.

use ringsync_wire::{
    CommandPayload, CommandRepr, Common, DelayFrameRepr, DelayMarker, DelaySlot, DelaySlotView,
    Error, FeedbackSlot, FeedbackSlotView, Flags, Frame, FrameKind, LumpedFrameRepr,
    LumpedOnlyFrameRepr, LumpedOnlySlot, LumpedOnlySlotView, LumpedPayload, Pdu, ResponsePayload,
    ResponseRepr, Route, SlotCodec, Status, ethernet,
};

#[rustfmt::skip]
const COMMAND: [u8; 32] = [
    0x01, 0x02, 0x01, 0x01,             // version 1, kind 2 (command), flags STOP, retry 1
    0x04, 0x03, 0x02, 0x01,             // cycle 0x01020304
    0x06, 0x05,                         // seq 0x0506
    0x10, 0x00,                         // payload length 16
    0x03, 0x00,                         // target slave 3
    0x00, 0x00,                         // link delay: none
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
        link_ns: 0,
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

#[rustfmt::skip]
const DELAY: [u8; 64] = [
    0x01, 0x05, 0x00, 0x00,             // version 1, kind 5 (delay): a probe
    3, 0, 0, 0,                         // cycle 3
    12, 0,                              // seq 12
    48, 0,                              // payload length 12 + 3 * 12
    0xE8, 0x03, 0, 0, 0, 0, 0, 0,       // master time 1000 ns
    0, 0,                               // first slot 0
    3, 0,                               // 3 slots
    // slot of slave 1
    0x36, 0x01, 0x00, 0x00,             // residence 310 ns
    0, 0, 0, 0,                         // path delay 0 (a probe)
    11, 0,                              // residence of probe seq 11
    2, 0,                               // marker 2 (written with a residence), reserved
    // slot of slave 2
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    1, 0,                               // marker 1 (written, no residence yet), reserved
    // slot of slave 3
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0,                               // marker 0 (not written), reserved
    0x83, 0x14, 0xFB, 0xDE,             // CRC-32 0xdefb1483
];

fn delay_repr() -> DelayFrameRepr {
    DelayFrameRepr {
        common: Common {
            cycle: 3,
            seq: 12,
            ..Common::default()
        },
        master_time_ns: 1000,
        first_slot: 0,
        slots: vec![
            DelaySlot {
                residence_ns: 310,
                path_delay_ns: 0,
                residence_of: 11,
                marker: DelayMarker::Residence,
            },
            DelaySlot {
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            },
            DelaySlot::default(),
        ],
    }
}

#[rustfmt::skip]
const DELAY_CLOSING: [u8; 52] = [
    0x01, 0x05, 0x00, 0x00,             // version 1, kind 5 (delay): a closing frame
    4, 0, 0, 0,                         // cycle 4
    13, 0,                              // seq 13
    36, 0,                              // payload length 12 + 2 * 12
    0x90, 0xD0, 0x03, 0, 0, 0, 0, 0,    // master time 250 000 ns
    1, 0,                               // first slot 1: slot 0 is slave 2's
    2, 0,                               // 2 slots
    // slot of slave 2
    0, 0, 0, 0,                         // residence 0
    0x54, 0x06, 0x00, 0x00,             // path delay 1620 ns
    0, 0,                               // residence of 0
    1, 0,                               // marker 1 (delay taken), reserved
    // slot of slave 3
    0, 0, 0, 0,                         // residence 0
    0x72, 0x0B, 0x00, 0x00,             // path delay 2930 ns
    0, 0,                               // residence of 0
    0, 0,                               // marker 0 (not taken yet), reserved
    0xF3, 0x4C, 0xC1, 0xAF,             // CRC-32 0xafc14cf3
];

fn delay_closing_repr() -> DelayFrameRepr {
    DelayFrameRepr {
        common: Common {
            cycle: 4,
            seq: 13,
            ..Common::default()
        },
        master_time_ns: 250_000,
        first_slot: 1,
        slots: vec![
            DelaySlot {
                path_delay_ns: 1620,
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            },
            DelaySlot {
                path_delay_ns: 2930,
                ..DelaySlot::default()
            },
        ],
    }
}

/// Every fixture of this file.
const FIXTURES: [&[u8]; 6] = [
    &COMMAND,
    &RESPONSE,
    &LUMPED,
    &LUMPED_ONLY,
    &DELAY,
    &DELAY_CLOSING,
];

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
fn delay_fixtures() {
    assert_eq!(Pdu::parse(&DELAY), Ok(Pdu::Delay(delay_repr())));
    assert_eq!(emit(&Pdu::Delay(delay_repr())), DELAY);
    assert_eq!(
        Pdu::parse(&DELAY_CLOSING),
        Ok(Pdu::Delay(delay_closing_repr()))
    );
    assert_eq!(emit(&Pdu::Delay(delay_closing_repr())), DELAY_CLOSING);
    assert_eq!(DelayFrameRepr::parse(&DELAY), Ok(delay_repr()));
    assert_eq!(delay_repr().buffer_len(), DELAY.len());
    assert_eq!(DelaySlot::LEN, 12);
    assert_eq!(DelayMarker::default(), DelayMarker::Empty);
}

#[test]
fn ethernet_padding_after_crc_is_ignored() {
    let mut padded = COMMAND.to_vec();
    padded.resize(60, 0);
    assert_eq!(Pdu::parse(&padded), Ok(Pdu::Command(command_repr())));
}

#[test]
fn every_single_bit_flip_is_rejected() {
    for fixture in FIXTURES {
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
    // Bytes 2-3 are the master's link estimate: any value is well formed.
    match at(14, 0xC4, &COMMAND) {
        Ok(Pdu::Command(c)) => assert_eq!(c.link_ns, 0xC4),
        other => panic!("a command with a link estimate: {other:?}"),
    }
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
    // Kind 5 is known, 6 is not. A command's payload read as a delay prefix: slot count 15
    // (the sample time's bytes 2-3), so 12 + 15 * 12 bytes expected.
    assert_eq!(
        at(1, 5, &COMMAND),
        Err(Error::PayloadLength {
            kind: FrameKind::Delay,
            expected: 192,
            got: 16
        })
    );
    assert_eq!(at(1, 6, &DELAY), Err(Error::BadKind(6)));
    // Delay slots: marker 0, 1 or 2; byte 11 reserved.
    assert_eq!(at(24 + 10, 3, &DELAY), Err(Error::BadDelayMarker(3)));
    assert_eq!(at(24 + 10, 0xFF, &DELAY), Err(Error::BadDelayMarker(0xFF)));
    assert_eq!(
        at(24 + 12 + 11, 7, &DELAY),
        Err(Error::Reserved {
            field: "delay slot byte 11",
            value: 7
        })
    );
    // A delay frame that declares 4 slots but carries 3, or more than one frame holds.
    assert_eq!(
        at(22, 4, &DELAY),
        Err(Error::PayloadLength {
            kind: FrameKind::Delay,
            expected: 60,
            got: 48
        })
    );
    assert_eq!(
        at(22, 123, &DELAY),
        Err(Error::SlotCountOverCapacity {
            count: 123,
            capacity: 122
        })
    );
    // Slots 65535 + 1 would address slave 65536.
    let mut far = DELAY_CLOSING.to_vec();
    far[20..22].copy_from_slice(&65534u16.to_le_bytes());
    assert_eq!(
        Pdu::parse(&reseal(far)),
        Err(Error::SlotRange {
            first: 65534,
            count: 2
        })
    );
    assert_eq!(
        DelayFrameRepr::parse(&LUMPED),
        Err(Error::WrongKind {
            expected: FrameKind::Delay,
            got: FrameKind::Lumped
        })
    );
    assert_eq!(
        LumpedFrameRepr::parse(&DELAY),
        Err(Error::WrongKind {
            expected: FrameKind::Lumped,
            got: FrameKind::Delay
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
    let mut big = delay_repr();
    big.slots = vec![DelaySlot::default(); 123];
    let mut out = vec![0u8; big.buffer_len()];
    assert_eq!(
        big.emit(&mut out),
        Err(Error::SlotCountOverCapacity {
            count: 123,
            capacity: 122
        })
    );
    big.slots.truncate(122);
    let mut out = vec![0u8; big.buffer_len()];
    // 12 header + 12 prefix + 122 * 12 + 4 CRC = 1492 <= 1500; 123 slots would be 1504.
    assert_eq!(big.emit(&mut out), Ok(1492));
    assert_eq!(
        delay_repr().emit(&mut out[..63]),
        Err(Error::BufferTooSmall {
            needed: 64,
            got: 63
        })
    );
    let mut far = delay_closing_repr();
    far.first_slot = 65534;
    assert_eq!(
        far.emit(&mut out),
        Err(Error::SlotRange {
            first: 65534,
            count: 2
        })
    );
    assert_eq!(
        DelaySlot::default().emit(&mut [0u8; 11]),
        Err(Error::BufferTooSmall {
            needed: 12,
            got: 11
        })
    );
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
fn slave_writes_its_delay_slot_in_place() {
    // Slave 3 reports its residence of probe 11 as probe 12 passes.
    let mut buf = DELAY.to_vec();
    let mut frame = Frame::new_checked(&mut buf[..]).expect("frame");
    assert_eq!(frame.check(), Ok(FrameKind::Delay));
    let mut payload = frame.lumped_mut().expect("payload");
    let k = payload.slot_index(3).expect("slot");
    assert_eq!(k, 2);
    let mut s = payload.delay_slot_mut(k).expect("delay slot");
    s.set_residence_ns(290);
    s.set_residence_of(11);
    s.set_marker(DelayMarker::Residence);
    frame.fill_crc();
    let mut want = delay_repr();
    want.slots[2] = DelaySlot {
        residence_ns: 290,
        path_delay_ns: 0,
        residence_of: 11,
        marker: DelayMarker::Residence,
    };
    assert_eq!(Pdu::parse(&buf), Ok(Pdu::Delay(want.clone())));
    // The same through the slot codec over the slot's bytes.
    let mut buf = DELAY.to_vec();
    let mut frame = Frame::new_checked(&mut buf[..]).expect("frame");
    let mut payload = frame.lumped_mut().expect("payload");
    want.slots[2]
        .emit(payload.slot_bytes_mut(2).expect("bytes"))
        .expect("emit slot");
    frame.fill_crc();
    assert_eq!(Pdu::parse(&buf), Ok(Pdu::Delay(want)));
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

// ---- views over the same fixtures ----------------------------------------------------------

fn frame(bytes: &[u8]) -> Frame<&[u8]> {
    Frame::new_checked(bytes).expect("frame")
}

#[test]
fn header_view_of_the_command_fixture() {
    let f = frame(&COMMAND);
    assert_eq!(f.kind(), Ok(FrameKind::Command));
    assert_eq!(f.flags(), Flags::STOP);
    assert_eq!(f.common(), command_repr().common);
    assert_eq!(
        (f.version(), f.retry(), f.cycle(), f.seq()),
        (1, 1, 0x0102_0304, 0x0506)
    );
    assert_eq!(
        (f.payload_len(), f.pdu_len(), f.crc()),
        (16, 32, 0x8f88_8adc)
    );
    assert_eq!(f.validate(), Ok(FrameKind::Command));
}

#[test]
fn command_view_reads_and_writes_the_fixture() {
    let f = frame(&COMMAND);
    assert_eq!(f.route(), Ok(Route::Command { target: 3 }));
    let c = f.command().expect("command");
    assert_eq!(
        (c.target(), c.command_v(), c.sample_time_ns()),
        (3, 1.5, 1_000_000)
    );
    assert_eq!(c.check(), Ok(()));
    // Written field by field into another command, the view makes the fixture's bytes.
    let mut other = command_repr();
    other.target = 9;
    other.command_v = -7.0;
    other.sample_time_ns = 5;
    let mut buf = vec![0u8; COMMAND.len()];
    other.emit(&mut buf).expect("emit");
    let mut f = Frame::new_checked(&mut buf[..]).expect("frame");
    let mut c = f.command_mut().expect("command");
    c.set_target(3);
    c.set_command_v(1.5);
    c.set_sample_time_ns(1_000_000);
    f.fill_crc();
    assert_eq!(buf, COMMAND);
}

#[test]
fn response_view_reads_and_writes_the_fixture() {
    let f = frame(&RESPONSE);
    assert_eq!(f.route(), Ok(Route::Response { source: 2 }));
    let r = f.response().expect("response");
    assert_eq!(
        (r.source(), r.status(), r.status_bits()),
        (2, Status::SATURATED, 2)
    );
    assert_eq!(
        (r.echo_cycle(), r.position(), r.velocity()),
        (0x0A0B_0C0D, -2, 1000)
    );
    assert_eq!((r.sample_time_ns(), r.applied_v()), (2_000_125, -0.5));
    assert_eq!(r.check(), Ok(()));
    let mut buf = vec![0u8; RESPONSE.len()];
    ResponseRepr {
        source: 1,
        status: Status::FAULT,
        ..response_repr()
    }
    .emit(&mut buf)
    .expect("emit");
    let mut f = Frame::new_checked(&mut buf[..]).expect("frame");
    let mut r = f.response_mut().expect("response");
    r.set_source(2);
    r.set_status(Status::SATURATED);
    r.set_echo_cycle(0x0A0B_0C0D);
    r.set_position(-2);
    r.set_velocity(1000);
    r.set_sample_time_ns(2_000_125);
    r.set_applied_v(-0.5);
    f.fill_crc();
    assert_eq!(buf, RESPONSE);
}

#[test]
fn lumped_views_read_the_fixture_slots() {
    let f = frame(&LUMPED);
    assert_eq!(
        f.route(),
        Ok(Route::Lumped {
            first_slot: 0,
            slot_count: 2
        })
    );
    let p = f.lumped().expect("lumped");
    assert_eq!(p.kind(), FrameKind::Lumped);
    assert_eq!(
        (p.master_time_ns(), p.first_slot(), p.slot_count()),
        (123_456_789, 0, 2)
    );
    assert_eq!(p.slot_len(), 20);
    assert_eq!(p.check_slots(), Ok(()));
    let s0 = p.feedback_slot(0).expect("slot 0");
    assert_eq!(
        (s0.position(), s0.velocity(), s0.sample_time_ns()),
        (1 << 20, -100, 1000)
    );
    assert_eq!((s0.status(), s0.written()), (Status::empty(), true));
    let s1 = p.feedback_slot(1).expect("slot 1");
    assert_eq!((s1.status(), s1.written()), (Status::CLOCK_UNLOCKED, false));
    assert!(p.feedback_slot(2).is_none());
    assert!(
        p.lumped_only_slot(0).is_none(),
        "no lumped-only slots in kind 1"
    );
    let positions: Vec<i32> = p.feedback_slots().map(|s| s.position()).collect();
    assert_eq!(positions, [1 << 20, 0]);
}

#[test]
fn feedback_slot_view_writes_what_the_repr_emits() {
    let mine = lumped_repr().slots[0];
    let mut by_view = [0xAAu8; 20];
    let mut v = FeedbackSlotView::new_checked(&mut by_view[..]).expect("slot");
    v.set_position(mine.position);
    v.set_velocity(mine.velocity);
    v.set_sample_time_ns(mine.sample_time_ns);
    v.set_status(mine.status);
    v.set_written(mine.written);
    assert_eq!(
        v.check(),
        Err(Error::Reserved {
            field: "slot byte 19",
            value: 0xAA
        })
    );
    by_view[19] = 0;
    assert_eq!(by_view[..], LUMPED[24..44]);
    assert_eq!(FeedbackSlot::parse(&by_view), Ok(mine));
}

#[test]
fn lumped_only_views_read_and_write_the_fixture_slot() {
    let f = frame(&LUMPED_ONLY);
    assert_eq!(
        f.route(),
        Ok(Route::LumpedOnly {
            first_slot: 4,
            slot_count: 1
        })
    );
    let p = f.lumped().expect("lumped-only");
    assert_eq!(
        (p.kind(), p.slot_len(), p.slot_index(5)),
        (FrameKind::LumpedOnly, 32, Some(0))
    );
    let s = p.lumped_only_slot(0).expect("slot");
    assert_eq!(
        (s.desired_position(), s.desired_velocity(), s.command_v()),
        (5, -5, 2.0)
    );
    let fb = s.feedback();
    assert_eq!(
        (
            fb.position(),
            fb.velocity(),
            fb.sample_time_ns(),
            fb.written()
        ),
        (7, 8, 9, true)
    );
    // The feedback part reads the same through either accessor.
    assert_eq!(p.feedback_slot(0).expect("feedback").position(), 7);
    assert_eq!(s.check(), Ok(()));

    let mut buf = LUMPED_ONLY.to_vec();
    let mut f = Frame::new_checked(&mut buf[..]).expect("frame");
    let mut p = f.lumped_mut().expect("lumped-only");
    p.set_master_time_ns(6);
    let mut s = p.lumped_only_slot_mut(0).expect("slot");
    s.set_command_v(-1.0);
    s.set_desired_position(50);
    s.set_desired_velocity(-50);
    s.feedback_mut().set_status(Status::STOPPING);
    p.feedback_slot_mut(0).expect("feedback").set_velocity(80);
    f.fill_crc();
    let mut want = lumped_only_repr();
    want.master_time_ns = 6;
    let slot = &mut want.slots[0];
    (slot.command_v, slot.desired_position, slot.desired_velocity) = (-1.0, 50, -50);
    (slot.feedback.status, slot.feedback.velocity) = (Status::STOPPING, 80);
    assert_eq!(Pdu::parse(&buf), Ok(Pdu::LumpedOnly(want)));
}

#[test]
fn delay_views_read_and_write_the_fixtures() {
    let f = frame(&DELAY);
    assert_eq!(f.kind(), Ok(FrameKind::Delay));
    assert_eq!(f.kind_byte(), 5);
    assert_eq!(
        f.route(),
        Ok(Route::Delay {
            first_slot: 0,
            slot_count: 3
        })
    );
    assert_eq!(f.route().map(|r| r.kind()), Ok(FrameKind::Delay));
    assert_eq!(f.validate(), Ok(FrameKind::Delay));
    assert_eq!((f.cycle(), f.seq(), f.payload_len()), (3, 12, 48));
    let p = f.lumped().expect("delay");
    assert_eq!(
        (p.kind(), p.slot_len(), p.slot_count(), p.master_time_ns()),
        (FrameKind::Delay, 12, 3, 1000)
    );
    assert_eq!(
        (
            p.slot_index(0),
            p.slot_index(1),
            p.slot_index(3),
            p.slot_index(4)
        ),
        (None, Some(0), Some(2), None)
    );
    assert_eq!(p.check_slots(), Ok(()));
    let s0 = p.delay_slot(0).expect("slot 0");
    assert_eq!(
        (s0.residence_ns(), s0.path_delay_ns(), s0.residence_of()),
        (310, 0, 11)
    );
    assert_eq!(s0.marker(), Ok(DelayMarker::Residence));
    assert_eq!(s0.check(), Ok(()));
    let markers: Vec<_> = (0..3)
        .map(|k| p.delay_slot(k).expect("slot").marker())
        .collect();
    assert_eq!(
        markers,
        [
            Ok(DelayMarker::Residence),
            Ok(DelayMarker::Written),
            Ok(DelayMarker::Empty)
        ]
    );
    assert!(p.delay_slot(3).is_none());
    assert_eq!(p.slot_bytes(1), Some(&DELAY[36..48]));
    // A delay slot is neither a feedback slot nor a lumped-only slot.
    assert!(p.feedback_slot(0).is_none());
    assert!(p.lumped_only_slot(0).is_none());
    assert_eq!(p.feedback_slots().len(), 0);
    // ... and kinds 1 and 4 have no delay slots.
    assert!(
        frame(&LUMPED)
            .lumped()
            .expect("lumped")
            .delay_slot(0)
            .is_none()
    );
    let lumped_only = frame(&LUMPED_ONLY);
    assert!(
        lumped_only
            .lumped()
            .expect("lumped-only")
            .delay_slot(0)
            .is_none()
    );

    let f = frame(&DELAY_CLOSING);
    assert_eq!(
        f.route(),
        Ok(Route::Delay {
            first_slot: 1,
            slot_count: 2
        })
    );
    let p = f.lumped().expect("delay");
    assert_eq!((p.slot_index(2), p.slot_index(3)), (Some(0), Some(1)));
    let delays: Vec<u32> = (0..2)
        .map(|k| p.delay_slot(k).expect("slot").path_delay_ns())
        .collect();
    assert_eq!(delays, [1620, 2930]);

    // The master turns a blank frame into the closing fixture through the views: path delays
    // in; slave 2 takes its own and marks its slot.
    let blank = DelayFrameRepr {
        common: Common {
            cycle: 4,
            seq: 13,
            ..Common::default()
        },
        master_time_ns: 0,
        first_slot: 1,
        slots: vec![DelaySlot::default(); 2],
    };
    let mut buf = vec![0u8; blank.buffer_len()];
    blank.emit(&mut buf).expect("emit");
    let mut f = Frame::new_checked(&mut buf[..]).expect("frame");
    let mut p = f.lumped_mut().expect("delay");
    p.set_master_time_ns(250_000);
    assert!(p.feedback_slot_mut(0).is_none());
    assert!(p.lumped_only_slot_mut(0).is_none());
    assert!(p.delay_slot_mut(2).is_none());
    for (k, d) in [1620, 2930].into_iter().enumerate() {
        p.delay_slot_mut(k).expect("slot").set_path_delay_ns(d);
    }
    p.delay_slot_mut(0)
        .expect("slot")
        .set_marker(DelayMarker::Written);
    f.fill_crc();
    assert_eq!(buf, DELAY_CLOSING);
}

#[test]
fn delay_slot_view_writes_what_the_repr_emits() {
    let mine = delay_repr().slots[0];
    let mut by_view = [0xAAu8; 12];
    let mut v = DelaySlotView::new_checked(&mut by_view[..]).expect("slot");
    v.set_residence_ns(mine.residence_ns);
    v.set_path_delay_ns(mine.path_delay_ns);
    v.set_residence_of(mine.residence_of);
    v.set_marker(mine.marker);
    assert_eq!(
        v.check(),
        Err(Error::Reserved {
            field: "delay slot byte 11",
            value: 0xAA
        })
    );
    by_view[11] = 0;
    assert_eq!(by_view[..], DELAY[24..36]);
    assert_eq!(DelaySlot::parse(&by_view), Ok(mine));
    // Bytes past the slot are ignored.
    assert_eq!(DelaySlot::parse(&DELAY[24..48]), Ok(mine));
    for (byte, marker) in [
        (0, DelayMarker::Empty),
        (1, DelayMarker::Written),
        (2, DelayMarker::Residence),
    ] {
        by_view[10] = byte;
        let v = DelaySlotView::new_checked(&by_view[..]).expect("slot");
        assert_eq!((v.marker(), v.check()), (Ok(marker), Ok(())));
        let mut again = [0xAAu8; 12];
        DelaySlotView::new_checked(&mut again[..])
            .expect("slot")
            .set_marker(marker);
        assert_eq!(again[10], byte);
    }
    by_view[10] = 3;
    let v = DelaySlotView::new_checked(&by_view[..]).expect("slot");
    assert_eq!(
        (v.marker(), v.check()),
        (Err(Error::BadDelayMarker(3)), Err(Error::BadDelayMarker(3)))
    );
    assert_eq!(DelaySlot::parse(&by_view), Err(Error::BadDelayMarker(3)));
}

#[test]
fn view_accessors_name_the_wrong_kind_or_length() {
    assert_eq!(
        frame(&RESPONSE).command().map(|_| ()),
        Err(Error::WrongKind {
            expected: FrameKind::Command,
            got: FrameKind::Response
        })
    );
    assert_eq!(
        frame(&COMMAND).lumped().map(|_| ()),
        Err(Error::WrongKind {
            expected: FrameKind::Lumped,
            got: FrameKind::Command
        })
    );
    assert_eq!(
        frame(&LUMPED).response().map(|_| ()),
        Err(Error::WrongKind {
            expected: FrameKind::Response,
            got: FrameKind::Lumped
        })
    );
    let mut b = COMMAND.to_vec();
    b[1] = 9;
    assert_eq!(frame(&b).kind(), Err(Error::BadKind(9)));
    assert_eq!(frame(&b).route(), Err(Error::BadKind(9)));
    assert_eq!(
        CommandPayload::new_checked(&COMMAND[12..27]).map(|_| ()),
        Err(Error::PayloadLength {
            kind: FrameKind::Command,
            expected: 16,
            got: 15
        })
    );
    assert_eq!(
        ResponsePayload::new_checked(&RESPONSE[12..]).map(|_| ()),
        Err(Error::PayloadLength {
            kind: FrameKind::Response,
            expected: 28,
            got: 32
        })
    );
    assert_eq!(
        FeedbackSlotView::new_checked(&LUMPED[24..43]).map(|_| ()),
        Err(Error::Truncated {
            what: "feedback slot",
            needed: 20,
            got: 19
        })
    );
    assert_eq!(
        LumpedOnlySlotView::new_checked(&LUMPED_ONLY[24..55]).map(|_| ()),
        Err(Error::Truncated {
            what: "lumped-only slot",
            needed: 32,
            got: 31
        })
    );
    assert_eq!(
        DelaySlotView::new_checked(&DELAY[24..35]).map(|_| ()),
        Err(Error::Truncated {
            what: "delay slot",
            needed: 12,
            got: 11
        })
    );
    assert_eq!(
        DelaySlot::parse(&DELAY[24..35]),
        Err(Error::Truncated {
            what: "delay slot",
            needed: 12,
            got: 11
        })
    );
    assert_eq!(
        frame(&DELAY).command().map(|_| ()),
        Err(Error::WrongKind {
            expected: FrameKind::Command,
            got: FrameKind::Delay
        })
    );
    assert_eq!(
        frame(&DELAY).response().map(|_| ()),
        Err(Error::WrongKind {
            expected: FrameKind::Response,
            got: FrameKind::Delay
        })
    );
    // The delay payload read as another lumped kind: its slots do not fit that length.
    assert_eq!(
        LumpedPayload::new_checked(&DELAY[12..60], FrameKind::Lumped).map(|_| ()),
        Err(Error::PayloadLength {
            kind: FrameKind::Lumped,
            expected: 72,
            got: 48
        })
    );
    assert_eq!(
        LumpedPayload::new_checked(&LUMPED[12..64], FrameKind::Delay).map(|_| ()),
        Err(Error::PayloadLength {
            kind: FrameKind::Delay,
            expected: 36,
            got: 52
        })
    );
    let mut b = DELAY.to_vec();
    b[1] = 6;
    assert_eq!(frame(&b).kind(), Err(Error::BadKind(6)));
    assert_eq!(frame(&b).route(), Err(Error::BadKind(6)));
    // A command whose header declares a 1-byte payload: the target is not there to route by.
    let mut short = COMMAND[..17].to_vec();
    short[10] = 1;
    assert_eq!(
        frame(&short).route(),
        Err(Error::Truncated {
            what: "routing fields",
            needed: 2,
            got: 1
        })
    );
}

#[test]
fn route_reads_no_crc_but_validate_does() {
    let mut b = COMMAND.to_vec();
    b[31] ^= 0xFF;
    let f = frame(&b);
    assert_eq!(f.route(), Ok(Route::Command { target: 3 }));
    assert_eq!(f.command().map(|c| c.target()), Ok(3));
    assert!(matches!(f.validate(), Err(Error::BadCrc { .. })));
}

#[test]
fn view_checks_report_what_the_parsers_report() {
    let at = |i: usize, v: u8, f: &[u8]| {
        let mut b = f.to_vec();
        b[i] = v;
        reseal(b)
    };
    let b = at(12, 0, &COMMAND);
    assert_eq!(
        frame(&b).command().expect("view").check(),
        Err(Error::BadSlave(0))
    );
    let b = at(14, 1, &COMMAND);
    let c = frame(&b);
    let c = c.command().expect("view");
    assert_eq!((c.check(), c.link_ns()), (Ok(()), 1));
    let b = at(15, 0x40, &RESPONSE);
    let f = frame(&b);
    let r = f.response().expect("view");
    assert_eq!(r.check(), Err(Error::ReservedStatus(0x4002)));
    assert_eq!((r.status(), r.status_bits()), (Status::SATURATED, 0x4002));
    let b = at(42, 2, &LUMPED);
    let p = frame(&b).lumped().map(|p| p.check_slots());
    assert_eq!(p, Ok(Err(Error::BadMarker(2))));
    // Marker 2 is good in a delay slot, 3 is not.
    let b = at(24 + 12 + 10, 2, &DELAY);
    let p = frame(&b).lumped().map(|p| p.check_slots());
    assert_eq!(p, Ok(Ok(())));
    let b = at(24 + 12 + 10, 3, &DELAY);
    let f = frame(&b);
    let p = f.lumped().expect("view");
    assert_eq!(p.check_slots(), Err(Error::BadDelayMarker(3)));
    let s = p.delay_slot(1).expect("slot");
    assert_eq!(
        (s.marker(), s.check()),
        (Err(Error::BadDelayMarker(3)), Err(Error::BadDelayMarker(3)))
    );
    assert_eq!(f.validate(), Err(Error::BadDelayMarker(3)));
    let b = at(24 + 11, 1, &DELAY);
    let p = frame(&b).lumped().map(|p| p.check_slots());
    assert_eq!(
        p,
        Ok(Err(Error::Reserved {
            field: "delay slot byte 11",
            value: 1
        }))
    );
    let mut b = LUMPED_ONLY.to_vec();
    b[52..56].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let b = reseal(b);
    let f = frame(&b);
    let p = f.lumped().expect("view");
    let s = p.lumped_only_slot(0).expect("slot");
    assert_eq!(s.check(), Err(Error::NonFinite("slot command")));
    assert_eq!(s.command_v(), f32::INFINITY);
}

#[test]
fn validate_and_parse_agree_on_every_single_bit_flip() {
    for fixture in FIXTURES {
        for byte in 0..fixture.len() {
            for bit in 0..8 {
                let mut b = fixture.to_vec();
                b[byte] ^= 1 << bit;
                // Resealed too (when the length still fits), to reach the payload checks.
                let declared = usize::from(u16::from_le_bytes([b[10], b[11]]));
                let sealed = (16 + declared <= b.len()).then(|| reseal(b.clone()));
                for b in [Some(b), sealed].into_iter().flatten() {
                    let parsed = Pdu::parse(&b).map(|p| p.kind());
                    let validated = Frame::new_checked(&b[..]).and_then(|f| f.validate());
                    assert_eq!(validated, parsed, "flip of byte {byte} bit {bit}");
                }
            }
        }
    }
}

#[test]
fn display_of_the_fixtures() {
    let line = |b: &[u8]| frame(b).to_string();
    assert_eq!(
        line(&COMMAND),
        "command cycle 16909060 seq 1286 retry 1 flags STOP → slave 3: 1.500 V, sampled at 1000000 ns"
    );
    assert_eq!(
        line(&RESPONSE),
        "response cycle 42 seq 7 from slave 2: status SATURATED, echo cycle 168496141, \
         position -2 counts, velocity 1000 counts/s, sampled at 2000125 ns, applied -0.500 V"
    );
    assert_eq!(
        line(&LUMPED),
        "lumped cycle 9 seq 1, slots 0..2, sent at 123456789 ns"
    );
    assert_eq!(
        line(&LUMPED_ONLY),
        "lumped-only cycle 10 seq 2, slots 4..5, sent at 5 ns"
    );
    assert_eq!(
        line(&DELAY),
        "delay cycle 3 seq 12, slots 0..3, sent at 1000 ns"
    );
    assert_eq!(
        line(&DELAY_CLOSING),
        "delay cycle 4 seq 13, slots 1..3, sent at 250000 ns"
    );
    for (bytes, pdu) in [
        (&COMMAND[..], Pdu::Command(command_repr())),
        (&RESPONSE[..], Pdu::Response(response_repr())),
        (&LUMPED[..], Pdu::Lumped(lumped_repr())),
        (&LUMPED_ONLY[..], Pdu::LumpedOnly(lumped_only_repr())),
        (&DELAY[..], Pdu::Delay(delay_repr())),
        (&DELAY_CLOSING[..], Pdu::Delay(delay_closing_repr())),
    ] {
        assert_eq!(line(bytes), pdu.to_string());
    }
    assert_eq!(
        Frame::new_unchecked(&COMMAND[..5]).to_string(),
        "bad frame (truncated header: need 12 bytes, got 5)"
    );
    assert_eq!(
        Frame::new_unchecked(&COMMAND[..30]).to_string(),
        "bad frame (truncated payload and CRC: need 32 bytes, got 30)"
    );
    let b = {
        let mut b = LUMPED.to_vec();
        b[42] = 2;
        reseal(b)
    };
    assert_eq!(
        line(&b),
        "bad frame (bad written-this-cycle marker 2: expected 0 or 1)"
    );
    let b = {
        let mut b = COMMAND.to_vec();
        b[1] = 6;
        reseal(b)
    };
    assert_eq!(
        line(&b),
        "bad frame (bad frame kind 6: expected 1 (lumped), 2 (command), 3 (response), \
         4 (lumped-only) or 5 (delay))"
    );
    let mut brake = delay_repr();
    brake.common.flags = Flags::BRAKE;
    brake.common.retry = 3;
    assert_eq!(
        Pdu::Delay(brake).to_string(),
        "delay cycle 3 seq 12 retry 3 flags BRAKE, slots 0..3, sent at 1000 ns"
    );
    let mut stop = command_repr();
    stop.common.flags = Flags::STOP.with(Flags::TORQUE_OFF);
    stop.common.retry = 0;
    assert!(
        Pdu::Command(stop)
            .to_string()
            .starts_with("command cycle 16909060 seq 1286 flags STOP|TORQUE_OFF → ")
    );
}

#[test]
fn display_of_flags_and_status() {
    assert_eq!(Flags::empty().to_string(), "-");
    assert_eq!(Flags::TORQUE_OFF.to_string(), "TORQUE_OFF");
    assert_eq!(
        Flags::TORQUE_OFF.with(Flags::STOP).to_string(),
        "STOP|TORQUE_OFF"
    );
    assert_eq!(Status::empty().to_string(), "-");
    assert_eq!(
        Status::BRAKING
            .with(Status::FAULT)
            .with(Status::SATURATED)
            .to_string(),
        "FAULT|SATURATED|BRAKING"
    );
    let all = Status::from_bits(Status::DEFINED).expect("defined");
    assert_eq!(
        all.to_string(),
        "FAULT|SATURATED|WATCHDOG|CLOCK_UNLOCKED|FOLLOWING_ERROR|STOPPING|TORQUE_OFF|BRAKING"
    );
    assert_eq!(Status::from_bits_truncate(0xFF02), Status::SATURATED);
    assert_eq!(Flags::from_bits_truncate(0x81), Flags::STOP);
}

#[test]
fn ethernet_view_strips_the_padding() {
    let mut buf = [0u8; 60];
    ethernet::emit_header(&mut buf, [0xFF; 6], [2; 6]).expect("header");
    buf[ethernet::field::PAYLOAD.start..][..COMMAND.len()].copy_from_slice(&COMMAND);
    let eth = ringsync_wire::EthernetFrame::new_checked(&buf[..]).expect("eth");
    assert_eq!((eth.dst(), eth.src()), ([0xFF; 6], [2; 6]));
    assert_eq!(eth.ringsync_payload().map(<[u8]>::len), Ok(46));
    assert_eq!(eth.ringsync_pdu(), Ok(&COMMAND[..]));
    // A PDU that declares more than the frame holds is handed over whole, to be rejected.
    buf[ethernet::field::PAYLOAD.start + 10] = 200;
    let eth = ringsync_wire::EthernetFrame::new_checked(&buf[..]).expect("eth");
    assert_eq!(eth.ringsync_pdu().map(<[u8]>::len), Ok(46));
}
