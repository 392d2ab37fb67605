//! docs/wire.md and the code must agree: every row of every layout table (offset, size, and
//! the width of its type) against the `field` modules, the frame-kind and size tables
//! against the length constants, and the examples of the text form against `Display`.

use ringsync_wire::ethernet::{self, frame_len, wire_len};
use ringsync_wire::lumped::{
    self, LUMPED_PREFIX_LEN, delay, feedback, lumped_only, lumped_pdu_len,
};
use ringsync_wire::{
    COMMAND_PDU_LEN, CRC_LEN, CommandRepr, Common, DelayFrameRepr, DelayMarker, DelaySlot,
    FeedbackSlot, Field, Flags, Frame, FrameKind, HEADER_LEN, LumpedFrameRepr, LumpedOnlyFrameRepr,
    LumpedOnlySlot, Pdu, RESPONSE_PDU_LEN, ResponseRepr, SlotCodec, Status, command, header,
    response,
};

const DOC: &str = include_str!("../../../docs/wire.md");

/// A markdown table: the heading it stands under, its column names, its rows.
struct Table {
    heading: String,
    columns: Vec<String>,
    rows: Vec<Vec<String>>,
}

fn cells(line: &str) -> Vec<String> {
    let inner = line.trim().trim_start_matches('|').trim_end_matches('|');
    inner.split('|').map(|c| c.trim().to_string()).collect()
}

fn tables(doc: &str) -> Vec<Table> {
    let mut out = Vec::new();
    let mut heading = String::new();
    let mut current: Option<Table> = None;
    let mut in_code = false;
    for line in doc.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
        }
        if !in_code && line.starts_with('#') {
            heading = line.trim_start_matches('#').trim().to_string();
        }
        if !in_code && line.starts_with('|') {
            let row = cells(line);
            let rule = row
                .iter()
                .all(|c| !c.is_empty() && c.chars().all(|ch| matches!(ch, '-' | ':')));
            match current.as_mut() {
                None => {
                    current = Some(Table {
                        heading: heading.clone(),
                        columns: row,
                        rows: Vec::new(),
                    })
                }
                Some(_) if rule => {}
                Some(t) => t.rows.push(row),
            }
        } else if let Some(t) = current.take() {
            out.push(t);
        }
    }
    out.extend(current);
    out
}

/// One row as the code has it: the doc's field name, offset and size, and the field when it
/// has a fixed size.
struct Row {
    name: &'static str,
    offset: String,
    size: String,
    field: Option<Field>,
}

fn fixed(name: &'static str, f: Field) -> Row {
    Row {
        name,
        offset: f.start.to_string(),
        size: f.len().to_string(),
        field: Some(f),
    }
}

fn open(name: &'static str, offset: impl ToString, size: &str) -> Row {
    Row {
        name,
        offset: offset.to_string(),
        size: size.to_string(),
        field: None,
    }
}

/// A layout: the heading its table stands under and its rows, whose fixed fields must tile
/// it from the first one's offset to `len`.
struct Layout {
    heading: &'static str,
    rows: Vec<Row>,
    len: usize,
}

fn layouts() -> Vec<Layout> {
    use delay::field as dl;
    use ethernet::field as eth;
    use feedback::field as fb;
    use header::field as h;
    use lumped::field as lp;
    use lumped_only::field as lo;
    let crc = header::field::crc(0);
    vec![
        Layout {
            heading: "Common header (12 B) and trailer (4 B)",
            rows: vec![
                fixed("version", h::VERSION),
                fixed("kind", h::KIND),
                fixed("flags", h::FLAGS),
                fixed("retry", h::RETRY),
                fixed("cycle", h::CYCLE),
                fixed("seq", h::SEQ),
                fixed("payload length L", h::LENGTH),
                open("payload", h::PAYLOAD.start, "L"),
                open(
                    "CRC-32",
                    format!("{} + L", crc.start),
                    &crc.len().to_string(),
                ),
            ],
            len: HEADER_LEN,
        },
        Layout {
            heading: "Kind 1: sync lumped frame",
            rows: vec![
                fixed("master send timestamp", lp::MASTER_TIME),
                fixed("first slot index f", lp::FIRST_SLOT),
                fixed("slot count m", lp::SLOT_COUNT),
                open(
                    "slots",
                    lp::SLOTS.start,
                    &format!("{}·m", FeedbackSlot::LEN),
                ),
            ],
            len: LUMPED_PREFIX_LEN,
        },
        Layout {
            heading: "Kind 1: sync lumped frame",
            rows: vec![
                fixed("position", fb::POSITION),
                fixed("velocity", fb::VELOCITY),
                fixed("sampling timestamp", fb::SAMPLE_TIME),
                fixed("status", fb::STATUS),
                fixed("written", fb::WRITTEN),
                fixed("reserved", fb::RESERVED),
            ],
            len: FeedbackSlot::LEN,
        },
        Layout {
            heading: "Kind 2: command frame",
            rows: vec![
                fixed("target slave", command::field::TARGET),
                fixed("link delay", command::field::LINK),
                fixed("command", command::field::COMMAND),
                fixed("sampling instant", command::field::SAMPLE_TIME),
            ],
            len: command::COMMAND_PAYLOAD_LEN,
        },
        Layout {
            heading: "Kind 3: response frame",
            rows: vec![
                fixed("source slave", response::field::SOURCE),
                fixed("status", response::field::STATUS),
                fixed("echo cycle", response::field::ECHO_CYCLE),
                fixed("position", response::field::POSITION),
                fixed("velocity", response::field::VELOCITY),
                fixed("measuring instant", response::field::SAMPLE_TIME),
                fixed("applied command", response::field::APPLIED),
            ],
            len: response::RESPONSE_PAYLOAD_LEN,
        },
        Layout {
            heading: "Kind 4: lumped-only frame (the plan of ref. [3])",
            rows: vec![
                fixed("feedback slot", lo::FEEDBACK),
                fixed("desired position", lo::DESIRED_POSITION),
                fixed("desired velocity", lo::DESIRED_VELOCITY),
                fixed("command", lo::COMMAND),
            ],
            len: LumpedOnlySlot::LEN,
        },
        Layout {
            heading: "Kind 5: delay frame",
            rows: vec![
                fixed("residence", dl::RESIDENCE),
                fixed("path delay", dl::PATH_DELAY),
                fixed("residence of", dl::RESIDENCE_OF),
                fixed("marker", dl::MARKER),
                fixed("reserved", dl::RESERVED),
            ],
            len: DelaySlot::LEN,
        },
        Layout {
            heading: "Ethernet II header (14 B)",
            rows: vec![
                fixed("destination MAC", eth::DESTINATION),
                fixed("source MAC", eth::SOURCE),
                fixed("EtherType", eth::ETHERTYPE),
                open("payload", eth::PAYLOAD.start, "n"),
            ],
            len: ethernet::ETH_HEADER_LEN,
        },
    ]
}

/// Width of a wire type [B], or `None` for a row without one (byte strings, parts).
fn width(ty: &str) -> Option<usize> {
    match ty {
        "u8" => Some(1),
        "u16" => Some(2),
        "u32" | "i32" | "f32" => Some(4),
        "u64" => Some(8),
        "" => None,
        other => panic!("unknown wire type {other:?} in docs/wire.md"),
    }
}

#[test]
fn every_layout_table_matches_the_field_modules() {
    let docs: Vec<Table> = tables(DOC)
        .into_iter()
        .filter(|t| t.columns.starts_with(&["offset".into(), "size".into()]))
        .collect();
    let code = layouts();
    assert_eq!(
        docs.iter().map(|t| t.heading.as_str()).collect::<Vec<_>>(),
        code.iter().map(|l| l.heading).collect::<Vec<_>>(),
        "the layout tables of docs/wire.md, in order"
    );
    for (doc, layout) in docs.iter().zip(&code) {
        let doc_names: Vec<&str> = doc.rows.iter().map(|r| r[3].as_str()).collect();
        let code_names: Vec<&str> = layout.rows.iter().map(|r| r.name).collect();
        assert_eq!(
            doc_names, code_names,
            "rows of the table under {}",
            doc.heading
        );
        for (cells, row) in doc.rows.iter().zip(&layout.rows) {
            let at = format!("{} / {}", doc.heading, row.name);
            assert_eq!(cells[0], row.offset, "offset of {at}");
            assert_eq!(cells[1], row.size, "size of {at}");
            if let Some(w) = width(&cells[2]) {
                assert_eq!(w.to_string(), row.size, "type {} of {at}", cells[2]);
            }
        }
    }
}

#[test]
fn fixed_fields_tile_each_layout() {
    for layout in layouts() {
        let tiles: Vec<&Field> = layout
            .rows
            .iter()
            .filter_map(|r| r.field.as_ref())
            .collect();
        let mut at = tiles[0].start;
        for f in tiles {
            assert_eq!(f.start, at, "gap or overlap in {} at {f:?}", layout.heading);
            at = f.end;
        }
        assert_eq!(at, layout.len, "length of {}", layout.heading);
    }
    assert_eq!(
        header::field::crc(16),
        28..32,
        "the CRC follows the payload"
    );
    assert_eq!(CRC_LEN, header::field::crc(0).len());
}

#[test]
fn frame_kind_table_matches_the_payload_lengths() {
    let kinds = tables(DOC)
        .into_iter()
        .find(|t| t.columns.first().map(String::as_str) == Some("kind"))
        .expect("the frame kinds table");
    let lumped = |slot: usize| format!("{LUMPED_PREFIX_LEN} + {slot}·m");
    let expect = [
        (FrameKind::Lumped, lumped(FeedbackSlot::LEN)),
        (FrameKind::Command, command::COMMAND_PAYLOAD_LEN.to_string()),
        (
            FrameKind::Response,
            response::RESPONSE_PAYLOAD_LEN.to_string(),
        ),
        (FrameKind::LumpedOnly, lumped(LumpedOnlySlot::LEN)),
        (FrameKind::Delay, lumped(DelaySlot::LEN)),
    ];
    assert_eq!(kinds.rows.len(), expect.len());
    for (row, (kind, len)) in kinds.rows.iter().zip(expect) {
        assert_eq!(row[0], (kind as u8).to_string());
        assert_eq!(row[3], len, "payload length of kind {kind}");
    }
}

#[test]
fn size_table_matches_the_lengths() {
    let sizes = tables(DOC)
        .into_iter()
        .find(|t| t.heading == "Sizes on the wire")
        .expect("the sizes table");
    let pdus = [
        ("lumped, n = 4", lumped_pdu_len(4, FeedbackSlot::LEN)),
        (
            "lumped, 73 slots (largest)",
            lumped_pdu_len(lumped::slot_capacity(FeedbackSlot::LEN), FeedbackSlot::LEN),
        ),
        ("command", COMMAND_PDU_LEN),
        ("response", RESPONSE_PDU_LEN),
        ("lumped-only, n = 4", lumped_pdu_len(4, LumpedOnlySlot::LEN)),
        ("delay, n = 4", lumped_pdu_len(4, DelaySlot::LEN)),
    ];
    assert_eq!(sizes.rows.len(), pdus.len());
    let lead = |s: &str| s.split(' ').next().unwrap_or_default().to_string();
    for (row, (name, pdu)) in sizes.rows.iter().zip(pdus) {
        assert_eq!(row[0], name);
        assert_eq!(row[1], pdu.to_string(), "PDU of {name}");
        assert_eq!(lead(&row[2]), frame_len(pdu).to_string(), "frame of {name}");
        // On the wire at 100 Mbit/s: 0.08 µs per byte.
        let wire = wire_len(pdu);
        let micros = wire as f64 * 0.08;
        assert_eq!(
            row[3],
            format!("{wire} B = {micros:.2} µs"),
            "wire of {name}"
        );
    }
}

/// The lines of the `text` block of the "Text form" section.
fn text_form_examples() -> Vec<&'static str> {
    let section = DOC
        .split("## Text form")
        .nth(1)
        .expect("a Text form section");
    let block = section
        .split("```text\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("a text block");
    block.lines().collect()
}

#[test]
fn text_form_examples_are_what_display_prints() {
    let command = CommandRepr {
        common: Common {
            flags: Flags::STOP,
            retry: 1,
            cycle: 7,
            seq: 3,
        },
        target: 2,
        command_v: -1.25,
        sample_time_ns: 1_000_000,
        link_ns: 0,
    };
    let response = ResponseRepr {
        common: Common {
            cycle: 42,
            seq: 7,
            ..Common::default()
        },
        source: 2,
        status: Status::SATURATED,
        echo_cycle: 41,
        position: -2,
        velocity: 1000,
        sample_time_ns: 2_000_125,
        applied_v: -0.5,
    };
    let lumped = LumpedFrameRepr {
        common: Common {
            cycle: 9,
            seq: 1,
            ..Common::default()
        },
        master_time_ns: 123_456_789,
        first_slot: 0,
        slots: vec![FeedbackSlot::default(); 2],
    };
    let lumped_only = LumpedOnlyFrameRepr {
        common: Common {
            cycle: 10,
            seq: 2,
            ..Common::default()
        },
        master_time_ns: 5,
        first_slot: 4,
        slots: vec![LumpedOnlySlot::default()],
    };
    let delay = DelayFrameRepr {
        common: Common {
            seq: 4,
            ..Common::default()
        },
        master_time_ns: 250_000,
        first_slot: 0,
        slots: vec![
            DelaySlot {
                marker: DelayMarker::Written,
                ..DelaySlot::default()
            };
            4
        ],
    };
    // The command above with its CRC's lowest bit flipped.
    let mut bad = [0u8; COMMAND_PDU_LEN];
    command.emit(&mut bad).expect("emit");
    bad[COMMAND_PDU_LEN - CRC_LEN] ^= 1;
    let mut printed: Vec<String> = [
        Pdu::Lumped(lumped),
        Pdu::LumpedOnly(lumped_only),
        Pdu::Delay(delay),
        Pdu::Command(command),
        Pdu::Response(response),
    ]
    .iter()
    .map(|p| {
        let mut buf = vec![0; p.buffer_len()];
        p.emit(&mut buf).expect("emit");
        let frame = Frame::new_checked(&buf[..]).expect("frame").to_string();
        assert_eq!(frame, p.to_string(), "Frame and Pdu print alike");
        frame
    })
    .collect();
    printed.push(Frame::new_checked(&bad[..]).expect("frame").to_string());
    assert_eq!(text_form_examples(), printed);
}
