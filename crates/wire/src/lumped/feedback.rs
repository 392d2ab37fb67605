//! The feedback slot (20 B): one slave's feedback in a lumped frame (all of a kind-1 slot,
//! the first 20 B of a kind-4 slot).
//!
//! ```text
//! offset size type  field
//!      0    4 i32   position [encoder counts]
//!      4    4 i32   velocity [counts/s]
//!      8    8 u64   sampling timestamp [ns, slave's synchronised clock]
//!     16    2 u16   status bits
//!     18    1 u8    written this cycle (0 or 1)
//!     19    1 u8    reserved, 0
//! ```

use super::{SlotCodec, room};
use crate::bytes::{get, put};
use crate::error::{Error, Result, need};
use crate::header::{FrameKind, Status};

/// Byte ranges of the feedback slot's fields, within the slot (docs/wire.md, "Kind 1").
pub mod field {
    use crate::Field;

    /// Position, i32 [encoder counts], sampled at the synchronised sampling instant.
    pub const POSITION: Field = 0..4;
    /// Velocity, i32 [counts/s].
    pub const VELOCITY: Field = 4..8;
    /// Sampling timestamp, u64 [ns, slave's synchronised clock].
    pub const SAMPLE_TIME: Field = 8..16;
    /// Status bits, u16.
    pub const STATUS: Field = 16..18;
    /// Written-this-cycle marker, u8 (0 or 1).
    pub const WRITTEN: Field = 18..19;
    /// Reserved, u8 (0).
    pub const RESERVED: Field = 19..20;
}

/// One slave's feedback in the lumped frame (kind 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FeedbackSlot {
    /// Position sampled at the synchronised sampling instant [encoder counts].
    pub position: i32,
    /// Velocity measured by the slave [counts/s].
    pub velocity: i32,
    /// Sampling instant on the slave's synchronised clock \[ns\].
    pub sample_time_ns: u64,
    /// Status bits.
    pub status: Status,
    /// The slave wrote this slot in this cycle (`false`: the values are older).
    pub written: bool,
}

impl SlotCodec for FeedbackSlot {
    const KIND: FrameKind = FrameKind::Lumped;
    const LEN: usize = field::RESERVED.end;

    fn parse(b: &[u8]) -> Result<Self> {
        let v = FeedbackSlotView::new_checked(b)?;
        v.check()?;
        Ok(FeedbackSlot {
            position: v.position(),
            velocity: v.velocity(),
            sample_time_ns: v.sample_time_ns(),
            status: v.status(),
            written: v.written(),
        })
    }

    fn emit(&self, b: &mut [u8]) -> Result<()> {
        room(b, Self::LEN)?;
        let mut v = FeedbackSlotView::new_unchecked(&mut b[..Self::LEN]);
        v.set_position(self.position);
        v.set_velocity(self.velocity);
        v.set_sample_time_ns(self.sample_time_ns);
        v.set_status(self.status);
        v.set_written(self.written);
        put(v.into_inner(), field::RESERVED, 0u8);
        Ok(())
    }
}

view! {
    /// Zero-copy view of one feedback slot in place (from
    /// [`LumpedPayload::feedback_slot`](super::LumpedPayload::feedback_slot)): a slave
    /// writes its feedback into a passing frame, the master reads every slot without
    /// copying. The getters return the raw fields; [`FeedbackSlotView::check`] applies the
    /// rules of docs/wire.md.
    FeedbackSlotView;
    /// Checks that the buffer holds a slot (20 B; more is ignored).
    fn check_len(b) {
        need("feedback slot", b, FeedbackSlot::LEN)
    }
}

fields!(FeedbackSlotView {
    position, set_position: i32 = field::POSITION, "Position sampled at the synchronised sampling instant [encoder counts].";
    velocity, set_velocity: i32 = field::VELOCITY, "Velocity measured by the slave [counts/s].";
    sample_time_ns, set_sample_time_ns: u64 = field::SAMPLE_TIME, "Sampling instant [ns, slave's synchronised clock].";
    status_bits: u16 = field::STATUS, "Raw status bits, reserved bits included (see [`FeedbackSlotView::status`]).";
});

impl<T: AsRef<[u8]>> FeedbackSlotView<T> {
    /// Checks the fields: the written marker is 0 or 1, the reserved byte 0, no reserved
    /// status bit set.
    pub fn check(&self) -> Result<()> {
        let b = self.buffer.as_ref();
        let marker: u8 = get(b, field::WRITTEN);
        if marker > 1 {
            return Err(Error::BadMarker(marker));
        }
        let reserved: u8 = get(b, field::RESERVED);
        if reserved != 0 {
            return Err(Error::Reserved {
                field: "slot byte 19",
                value: u32::from(reserved),
            });
        }
        Status::from_bits(self.status_bits()).map(drop)
    }
    /// Status bits; reserved bits are dropped ([`FeedbackSlotView::check`] rejects them).
    pub fn status(&self) -> Status {
        Status::from_bits_truncate(self.status_bits())
    }
    /// The slave wrote this slot in this cycle (marker 1; any other value reads `false`).
    pub fn written(&self) -> bool {
        get::<u8>(self.buffer.as_ref(), field::WRITTEN) == 1
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> FeedbackSlotView<T> {
    /// Writes [`status`](Self::status): the slave's status bits.
    pub fn set_status(&mut self, v: Status) {
        put(self.buffer.as_mut(), field::STATUS, v.bits());
    }
    /// Writes [`written`](Self::written): whether the slave wrote the slot in this cycle.
    pub fn set_written(&mut self, v: bool) {
        put(self.buffer.as_mut(), field::WRITTEN, u8::from(v));
    }
}
