//! Lumped frames of both kinds, through the owned parser and the in-place slot view.
#![no_main]

#[path = "seal.rs"]
#[macro_use]
mod seal;
use ringsync_wire::{FeedbackSlot, Frame, LumpedOnlySlot, LumpedPayload, LumpedRepr, SlotCodec};

fuzz_raw_and_sealed!(check);

fn check(data: &[u8]) {
    let _ = LumpedRepr::<FeedbackSlot>::parse(data);
    let _ = LumpedRepr::<LumpedOnlySlot>::parse(data);
    let mut buf = data.to_vec();
    if let Ok(mut frame) = Frame::new_checked(&mut buf[..]) {
        if let Ok(kind) = frame.check() {
            if let Ok(mut p) = LumpedPayload::new_checked(frame.payload_mut(), kind) {
                let count = usize::from(p.slot_count());
                for k in 0..=count {
                    if let Some(b) = p.slot_bytes(k) {
                        let _ = FeedbackSlot::parse(b);
                        let _ = LumpedOnlySlot::parse(b);
                    }
                }
                if let Some(k) = p.slot_index(1) {
                    if let Some(b) = p.slot_bytes_mut(k) {
                        let _ = FeedbackSlot::default().emit(b);
                    }
                }
            }
            frame.fill_crc();
        }
    }
}
