//! Property tests: emit → parse is the identity for every frame kind, the views read what
//! the representations wrote (and write what they read), and no parser or view panics on
//! arbitrary bytes.

use proptest::prelude::*;
use ringsync_wire::{
    CommandPayload, CommandRepr, Common, DelayMarker, DelaySlot, DelaySlotView, EthernetFrame,
    FeedbackSlot, FeedbackSlotView, Flags, Frame, FrameKind, LumpedOnlySlot, LumpedOnlySlotView,
    LumpedPayload, LumpedRepr, Pdu, ResponsePayload, ResponseRepr, Route, SlotCodec, Status,
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

fn delay_marker() -> impl Strategy<Value = DelayMarker> {
    prop_oneof![
        Just(DelayMarker::Empty),
        Just(DelayMarker::Written),
        Just(DelayMarker::Residence),
    ]
}

fn delay_slot() -> impl Strategy<Value = DelaySlot> {
    (any::<u32>(), any::<u32>(), any::<u16>(), delay_marker()).prop_map(
        |(residence_ns, path_delay_ns, residence_of, marker)| DelaySlot {
            residence_ns,
            path_delay_ns,
            residence_of,
            marker,
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
        (
            common(),
            any::<u64>(),
            0u16..1000,
            prop::collection::vec(delay_slot(), 0..=122)
        )
            .prop_map(|(common, master_time_ns, first_slot, slots)| Pdu::Delay(
                LumpedRepr {
                    common,
                    master_time_ns,
                    first_slot,
                    slots
                }
            )),
        (common(), 1u16.., finite_f32(), any::<u64>(), any::<u16>()).prop_map(
            |(common, target, command_v, sample_time_ns, link_ns)| Pdu::Command(CommandRepr {
                common,
                target,
                command_v,
                sample_time_ns,
                link_ns,
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
        let _ = LumpedRepr::<DelaySlot>::parse(&bytes);
        let _ = FeedbackSlot::parse(&bytes);
        let _ = LumpedOnlySlot::parse(&bytes);
        let _ = DelaySlot::parse(&bytes);
        if let Ok(f) = Frame::new_checked(&bytes[..]) {
            let _ = (f.check(), f.payload(), f.crc(), f.cycle());
            for kind in [
                FrameKind::Lumped,
                FrameKind::LumpedOnly,
                FrameKind::Delay,
                FrameKind::Command,
            ] {
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
    fn sealed_random_payloads_never_panic(kind in 0u8..7, payload in prop::collection::vec(any::<u8>(), 0..200)) {
        let mut b = vec![1, kind, 0, 0, 0, 0, 0, 0, 0, 0];
        b.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        b.extend_from_slice(&payload);
        let crc = ringsync_wire::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        let _ = Pdu::parse(&b);
    }
}

/// A feedback slot as read through its view.
fn feedback_of<T: AsRef<[u8]>>(v: &FeedbackSlotView<T>) -> FeedbackSlot {
    FeedbackSlot {
        position: v.position(),
        velocity: v.velocity(),
        sample_time_ns: v.sample_time_ns(),
        status: v.status(),
        written: v.written(),
    }
}

/// The PDU as read through the views alone.
fn read_through_views(f: &Frame<&[u8]>) -> Pdu {
    let common = f.common();
    match f.kind().expect("kind") {
        FrameKind::Command => {
            let c = f.command().expect("command view");
            Pdu::Command(CommandRepr {
                common,
                target: c.target(),
                command_v: c.command_v(),
                sample_time_ns: c.sample_time_ns(),
                link_ns: c.link_ns(),
            })
        }
        FrameKind::Response => {
            let r = f.response().expect("response view");
            Pdu::Response(ResponseRepr {
                common,
                source: r.source(),
                status: r.status(),
                echo_cycle: r.echo_cycle(),
                position: r.position(),
                velocity: r.velocity(),
                sample_time_ns: r.sample_time_ns(),
                applied_v: r.applied_v(),
            })
        }
        FrameKind::Lumped => {
            let p = f.lumped().expect("lumped view");
            Pdu::Lumped(LumpedRepr {
                common,
                master_time_ns: p.master_time_ns(),
                first_slot: p.first_slot(),
                slots: p.feedback_slots().map(|s| feedback_of(&s)).collect(),
            })
        }
        FrameKind::LumpedOnly => {
            let p = f.lumped().expect("lumped-only view");
            let slots = (0..usize::from(p.slot_count()))
                .map(|k| {
                    let s = p.lumped_only_slot(k).expect("slot in range");
                    LumpedOnlySlot {
                        feedback: feedback_of(&s.feedback()),
                        desired_position: s.desired_position(),
                        desired_velocity: s.desired_velocity(),
                        command_v: s.command_v(),
                    }
                })
                .collect();
            Pdu::LumpedOnly(LumpedRepr {
                common,
                master_time_ns: p.master_time_ns(),
                first_slot: p.first_slot(),
                slots,
            })
        }
        FrameKind::Delay => {
            let p = f.lumped().expect("delay view");
            let slots = (0..usize::from(p.slot_count()))
                .map(|k| {
                    let s = p.delay_slot(k).expect("slot in range");
                    DelaySlot {
                        residence_ns: s.residence_ns(),
                        path_delay_ns: s.path_delay_ns(),
                        residence_of: s.residence_of(),
                        marker: s.marker().expect("marker"),
                    }
                })
                .collect();
            Pdu::Delay(LumpedRepr {
                common,
                master_time_ns: p.master_time_ns(),
                first_slot: p.first_slot(),
                slots,
            })
        }
    }
}

/// Writes every field of `pdu` into `buf` (a frame of the same kind and slot count) through
/// the mutable views, then seals it.
fn write_through_views(pdu: &Pdu, buf: &mut [u8]) {
    let mut f = Frame::new_checked(buf).expect("frame");
    let c = match pdu {
        Pdu::Lumped(l) => l.common,
        Pdu::LumpedOnly(l) => l.common,
        Pdu::Delay(l) => l.common,
        Pdu::Command(c) => c.common,
        Pdu::Response(r) => r.common,
    };
    f.set_flags(c.flags);
    f.set_retry(c.retry);
    f.set_cycle(c.cycle);
    f.set_seq(c.seq);
    let put_feedback = |v: &mut FeedbackSlotView<&mut [u8]>, s: &FeedbackSlot| {
        v.set_position(s.position);
        v.set_velocity(s.velocity);
        v.set_sample_time_ns(s.sample_time_ns);
        v.set_status(s.status);
        v.set_written(s.written);
    };
    match pdu {
        Pdu::Command(r) => {
            let mut v = f.command_mut().expect("command view");
            v.set_target(r.target);
            v.set_command_v(r.command_v);
            v.set_sample_time_ns(r.sample_time_ns);
            v.set_link_ns(r.link_ns);
        }
        Pdu::Response(r) => {
            let mut v = f.response_mut().expect("response view");
            v.set_source(r.source);
            v.set_status(r.status);
            v.set_echo_cycle(r.echo_cycle);
            v.set_position(r.position);
            v.set_velocity(r.velocity);
            v.set_sample_time_ns(r.sample_time_ns);
            v.set_applied_v(r.applied_v);
        }
        Pdu::Lumped(l) => {
            let mut p = f.lumped_mut().expect("lumped view");
            p.set_master_time_ns(l.master_time_ns);
            for (k, s) in l.slots.iter().enumerate() {
                put_feedback(&mut p.feedback_slot_mut(k).expect("slot"), s);
            }
        }
        Pdu::LumpedOnly(l) => {
            let mut p = f.lumped_mut().expect("lumped-only view");
            p.set_master_time_ns(l.master_time_ns);
            for (k, s) in l.slots.iter().enumerate() {
                let mut v = p.lumped_only_slot_mut(k).expect("slot");
                put_feedback(&mut v.feedback_mut(), &s.feedback);
                v.set_desired_position(s.desired_position);
                v.set_desired_velocity(s.desired_velocity);
                v.set_command_v(s.command_v);
            }
        }
        Pdu::Delay(l) => {
            let mut p = f.lumped_mut().expect("delay view");
            p.set_master_time_ns(l.master_time_ns);
            for (k, s) in l.slots.iter().enumerate() {
                let mut v = p.delay_slot_mut(k).expect("slot");
                v.set_residence_ns(s.residence_ns);
                v.set_path_delay_ns(s.path_delay_ns);
                v.set_residence_of(s.residence_of);
                v.set_marker(s.marker);
            }
        }
    }
    f.fill_crc();
}

/// Every accessor of every view the bytes admit; the result is thrown away: only a panic
/// would fail.
fn touch_everything(bytes: &[u8]) {
    if let Ok(f) = Frame::new_checked(bytes) {
        let _ = (
            f.kind(),
            f.flags(),
            f.common(),
            f.route(),
            f.check(),
            f.validate(),
        );
        let _ = (
            f.version(),
            f.kind_byte(),
            f.flags_byte(),
            f.pdu_len(),
            f.to_string(),
        );
        if let Ok(c) = f.command() {
            let _ = (c.target(), c.command_v(), c.sample_time_ns(), c.check());
        }
        if let Ok(r) = f.response() {
            let _ = (
                r.source(),
                r.status(),
                r.status_bits(),
                r.echo_cycle(),
                r.check(),
            );
            let _ = (
                r.position(),
                r.velocity(),
                r.sample_time_ns(),
                r.applied_v(),
            );
        }
        if let Ok(p) = f.lumped() {
            touch_lumped(&p);
        }
        for kind in [
            FrameKind::Lumped,
            FrameKind::LumpedOnly,
            FrameKind::Delay,
            FrameKind::Response,
        ] {
            if let Ok(p) = LumpedPayload::new_checked(f.payload(), kind) {
                touch_lumped(&p);
            }
        }
    }
    if let Ok(c) = CommandPayload::new_checked(bytes) {
        let _ = (c.target(), c.command_v(), c.sample_time_ns(), c.check());
    }
    if let Ok(r) = ResponsePayload::new_checked(bytes) {
        let _ = (r.source(), r.status(), r.applied_v(), r.check());
    }
    if let Ok(s) = FeedbackSlotView::new_checked(bytes) {
        let _ = (feedback_of(&s), s.status_bits(), s.check());
    }
    if let Ok(s) = LumpedOnlySlotView::new_checked(bytes) {
        let _ = (
            feedback_of(&s.feedback()),
            s.command_v(),
            s.desired_position(),
            s.check(),
        );
    }
    if let Ok(s) = DelaySlotView::new_checked(bytes) {
        let _ = (
            s.residence_ns(),
            s.path_delay_ns(),
            s.residence_of(),
            s.marker(),
            s.check(),
        );
    }
    if let Ok(e) = EthernetFrame::new_checked(bytes) {
        let _ = e.ringsync_pdu().map(touch_everything);
    }
}

fn touch_lumped(p: &LumpedPayload<&[u8]>) {
    let _ = (p.kind(), p.master_time_ns(), p.check_slots(), p.slot_len());
    for k in 0..=usize::from(p.slot_count()) {
        if let Some(s) = p.feedback_slot(k) {
            let _ = (feedback_of(&s), s.check());
        }
        if let Some(s) = p.lumped_only_slot(k) {
            let _ = (s.desired_velocity(), s.command_v(), s.check());
        }
        if let Some(s) = p.delay_slot(k) {
            let _ = (s.residence_ns(), s.path_delay_ns(), s.marker(), s.check());
        }
        let _ = p.slot_bytes(k);
    }
    for s in p.feedback_slots() {
        let _ = (s.sample_time_ns(), s.written());
    }
    let _ = (p.slot_index(0), p.slot_index(1), p.slot_index(u16::MAX));
}

/// `bytes` with the declared payload length cut to fit and a correct CRC, so that the
/// payload checks behind the CRC are reached (as the fuzz targets' `seal`).
fn sealed(bytes: &[u8]) -> Option<Vec<u8>> {
    if bytes.len() < 16 {
        return None;
    }
    let mut b = bytes.to_vec();
    let len = usize::from(u16::from_le_bytes([b[10], b[11]])).min(b.len() - 16);
    b[10..12].copy_from_slice(&(len as u16).to_le_bytes());
    let crc = ringsync_wire::crc32(&b[..12 + len]);
    b[12 + len..16 + len].copy_from_slice(&crc.to_le_bytes());
    Some(b)
}

proptest! {
    /// Any emitted representation reads back, field by field, through the views; the route,
    /// the validation and the text form agree with it, and no accessor panics on it.
    #[test]
    fn views_read_what_reprs_emit(p in pdu(), pad in 0usize..8) {
        let mut buf = vec![0u8; p.buffer_len() + pad];
        p.emit(&mut buf).expect("emit");
        let f = Frame::new_checked(&buf[..]).expect("frame");
        prop_assert_eq!(f.validate(), Ok(p.kind()));
        prop_assert_eq!(read_through_views(&f), p.clone());
        let route = match &p {
            Pdu::Lumped(l) => Route::Lumped { first_slot: l.first_slot, slot_count: l.slots.len() as u16 },
            Pdu::LumpedOnly(l) => Route::LumpedOnly { first_slot: l.first_slot, slot_count: l.slots.len() as u16 },
            Pdu::Delay(l) => Route::Delay { first_slot: l.first_slot, slot_count: l.slots.len() as u16 },
            Pdu::Command(c) => Route::Command { target: c.target },
            Pdu::Response(r) => Route::Response { source: r.source },
        };
        prop_assert_eq!(f.route(), Ok(route));
        prop_assert_eq!(p.route(), route);
        prop_assert_eq!(route.kind(), p.kind());
        prop_assert_eq!(f.to_string(), p.to_string());
        // Every accessor over a valid frame of each kind (random bytes rarely make one).
        touch_everything(&buf);
    }

    /// Writing a representation's fields through the views into a blank frame of the same
    /// kind and slot count gives the bytes its own emit gives.
    #[test]
    fn views_write_what_reprs_emit(p in pdu()) {
        let blank = match &p {
            Pdu::Lumped(l) => Pdu::Lumped(LumpedRepr {
                common: Common::default(),
                master_time_ns: 0,
                first_slot: l.first_slot,
                slots: vec![FeedbackSlot::default(); l.slots.len()],
            }),
            Pdu::LumpedOnly(l) => Pdu::LumpedOnly(LumpedRepr {
                common: Common::default(),
                master_time_ns: 0,
                first_slot: l.first_slot,
                slots: vec![LumpedOnlySlot::default(); l.slots.len()],
            }),
            Pdu::Delay(l) => Pdu::Delay(LumpedRepr {
                common: Common::default(),
                master_time_ns: 0,
                first_slot: l.first_slot,
                slots: vec![DelaySlot::default(); l.slots.len()],
            }),
            Pdu::Command(_) => Pdu::Command(CommandRepr {
                common: Common::default(),
                target: 1,
                command_v: 0.0,
                sample_time_ns: 0,
                link_ns: 0,
            }),
            Pdu::Response(_) => Pdu::Response(ResponseRepr {
                common: Common::default(),
                source: 1,
                status: Status::empty(),
                echo_cycle: 0,
                position: 0,
                velocity: 0,
                sample_time_ns: 0,
                applied_v: 0.0,
            }),
        };
        let mut buf = vec![0u8; blank.buffer_len()];
        blank.emit(&mut buf).expect("emit");
        write_through_views(&p, &mut buf);
        let mut want = vec![0u8; p.buffer_len()];
        p.emit(&mut want).expect("emit");
        prop_assert_eq!(buf, want);
    }

    /// No view accessor panics on any buffer that its `new_checked` accepts, and
    /// `Frame::validate` reports exactly what `Pdu::parse` reports.
    #[test]
    fn views_never_panic_and_validate_agrees_with_parse(bytes in prop::collection::vec(any::<u8>(), 0..1600)) {
        for b in [Some(bytes.clone()), sealed(&bytes)].into_iter().flatten() {
            touch_everything(&b);
            let validated = Frame::new_checked(&b[..]).and_then(|f| f.validate());
            prop_assert_eq!(validated, Pdu::parse(&b).map(|p| p.kind()));
            let mut m = b.clone();
            if let Ok(mut f) = Frame::new_checked(&mut m[..]) {
                if let Ok(mut p) = f.lumped_mut() {
                    p.set_master_time_ns(1);
                    if let Some(mut s) = p.feedback_slot_mut(0) { s.set_written(true); }
                    if let Some(mut s) = p.lumped_only_slot_mut(0) { s.set_command_v(1.0); }
                    if let Some(mut s) = p.delay_slot_mut(0) { s.set_marker(DelayMarker::Written); }
                }
                if let Ok(mut c) = f.command_mut() { c.set_target(1); }
                if let Ok(mut r) = f.response_mut() { r.set_status(Status::FAULT); }
                f.fill_crc();
            }
        }
    }

    /// Random headers and payloads, sealed, of every kind: reaches the views' payload checks.
    #[test]
    fn sealed_random_frames_through_the_views(kind in 0u8..7, flags in 0u8..4, payload in prop::collection::vec(any::<u8>(), 0..200)) {
        let mut b = vec![1, kind, flags, 0, 0, 0, 0, 0, 0, 0];
        b.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        b.extend_from_slice(&payload);
        let crc = ringsync_wire::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        touch_everything(&b);
        let validated = Frame::new_checked(&b[..]).and_then(|f| f.validate());
        prop_assert_eq!(validated, Pdu::parse(&b).map(|p| p.kind()));
    }
}
