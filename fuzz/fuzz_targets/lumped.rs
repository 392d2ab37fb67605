//! Lumped frames of every kind (sync lumped, lumped-only, delay), through the owned parser
//! and the in-place payload and slot views.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::{
    DelayMarker, DelaySlot, FeedbackSlot, Frame, LumpedOnlySlot, LumpedRepr, SlotCodec,
};

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    // Every `let _` here: a parser, accessor or in-place write run on any bytes only to show
    // that none panics or writes out of bounds (AddressSanitizer); its result is not the point.
    let _ = LumpedRepr::<FeedbackSlot>::parse(data);
    let _ = LumpedRepr::<LumpedOnlySlot>::parse(data);
    let _ = LumpedRepr::<DelaySlot>::parse(data);
    let mut buf = data.to_vec();
    if let Ok(mut frame) = Frame::new_checked(&mut buf[..]) {
        let _ = frame.route();
        if let Ok(p) = frame.lumped() {
            let _ = (p.master_time_ns(), p.first_slot(), p.check_slots());
            for k in 0..=usize::from(p.slot_count()) {
                if let Some(s) = p.feedback_slot(k) {
                    let _ = (s.position(), s.status(), s.written(), s.check());
                }
                if let Some(s) = p.lumped_only_slot(k) {
                    let _ = (s.feedback().sample_time_ns(), s.command_v(), s.check());
                }
                if let Some(s) = p.delay_slot(k) {
                    let _ = (s.residence_ns(), s.path_delay_ns(), s.residence_of());
                    let _ = (s.marker(), s.check());
                }
                if let Some(b) = p.slot_bytes(k) {
                    let _ = FeedbackSlot::parse(b);
                    let _ = LumpedOnlySlot::parse(b);
                    let _ = DelaySlot::parse(b);
                }
            }
            for s in p.feedback_slots() {
                let _ = (s.sample_time_ns(), s.written());
            }
        }
        if frame.check().is_ok() {
            if let Ok(mut p) = frame.lumped_mut() {
                if let Some(k) = p.slot_index(1) {
                    if let Some(b) = p.slot_bytes_mut(k) {
                        let _ = FeedbackSlot::default().emit(b);
                    }
                    if let Some(mut s) = p.feedback_slot_mut(k) {
                        s.set_written(true);
                    }
                    if let Some(mut s) = p.delay_slot_mut(k) {
                        s.set_residence_ns(1);
                        s.set_marker(DelayMarker::Residence);
                    }
                }
            }
            frame.fill_crc();
        }
    }
}
