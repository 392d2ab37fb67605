//! The lumped-only slot (32 B, kind 4): the feedback slot, then the desired state the
//! master writes and the command the slave applied.
//!
//! ```text
//! offset size type  field
//!      0   20       feedback slot (see `feedback`)
//!     20    4 i32   desired position [encoder counts] (written by the master)
//!     24    4 i32   desired velocity [counts/s] (written by the master)
//!     28    4 f32   command applied [V] (written by the slave)
//! ```

use super::feedback::{FeedbackSlot, FeedbackSlotView};
use super::{SlotCodec, room};
use crate::bytes::finite;
use crate::error::{Result, need};
use crate::header::FrameKind;

/// Byte ranges of the lumped-only slot's fields, within the slot (docs/wire.md, "Kind 4").
pub mod field {
    use crate::Field;

    /// The feedback part, laid out as [`feedback::field`](crate::lumped::feedback::field).
    pub const FEEDBACK: Field = 0..crate::lumped::feedback::field::RESERVED.end;
    /// Desired position, i32 [encoder counts], written by the master.
    pub const DESIRED_POSITION: Field = 20..24;
    /// Desired velocity, i32 [counts/s], written by the master.
    pub const DESIRED_VELOCITY: Field = 24..28;
    /// Command the slave applied, f32 \[V\], finite.
    pub const COMMAND: Field = 28..32;
}

/// One slave's part of the lumped-only plan's frame (kind 4): feedback, plus the desired
/// state the master writes and the command the slave computed and applied.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LumpedOnlySlot {
    /// Feedback part, as in kind 1.
    pub feedback: FeedbackSlot,
    /// Desired position for this cycle [encoder counts].
    pub desired_position: i32,
    /// Desired velocity for this cycle [counts/s].
    pub desired_velocity: i32,
    /// Command the slave applied \[V\]; finite.
    pub command_v: f32,
}

impl SlotCodec for LumpedOnlySlot {
    const KIND: FrameKind = FrameKind::LumpedOnly;
    const LEN: usize = field::COMMAND.end;

    fn parse(b: &[u8]) -> Result<Self> {
        let v = LumpedOnlySlotView::new_checked(b)?;
        Ok(LumpedOnlySlot {
            feedback: FeedbackSlot::parse(&b[field::FEEDBACK])?,
            desired_position: v.desired_position(),
            desired_velocity: v.desired_velocity(),
            command_v: finite("slot command", v.command_v())?,
        })
    }

    fn emit(&self, b: &mut [u8]) -> Result<()> {
        room(b, Self::LEN)?;
        self.validate()?;
        let command_v = self.command_v;
        self.feedback.emit(&mut b[field::FEEDBACK])?;
        let mut v = LumpedOnlySlotView::new_unchecked(b);
        v.set_desired_position(self.desired_position);
        v.set_desired_velocity(self.desired_velocity);
        v.set_command_v(command_v);
        Ok(())
    }

    fn validate(&self) -> Result<()> {
        finite("slot command", self.command_v).map(drop)
    }
}

view! {
    /// Zero-copy view of one lumped-only slot in place (from
    /// [`LumpedPayload::lumped_only_slot`](super::LumpedPayload::lumped_only_slot)). The
    /// getters return the raw fields; [`LumpedOnlySlotView::check`] applies the rules.
    LumpedOnlySlotView;
    /// Checks that the buffer holds a slot (32 B; more is ignored).
    fn check_len(b) {
        need("lumped-only slot", b, LumpedOnlySlot::LEN)
    }
}

fields!(LumpedOnlySlotView {
    desired_position, set_desired_position: i32 = field::DESIRED_POSITION, "Desired position for this cycle [encoder counts], written by the master.";
    desired_velocity, set_desired_velocity: i32 = field::DESIRED_VELOCITY, "Desired velocity for this cycle [counts/s], written by the master.";
    command_v, set_command_v: f32 = field::COMMAND, "Command the slave applied \\[V\\] (raw: may be non-finite before `check`).";
});

impl<T: AsRef<[u8]>> LumpedOnlySlotView<T> {
    /// Checks the fields: those of the feedback part, then a finite command.
    pub fn check(&self) -> Result<()> {
        self.feedback().check()?;
        finite("slot command", self.command_v()).map(drop)
    }
    /// The feedback part.
    pub fn feedback(&self) -> FeedbackSlotView<&[u8]> {
        FeedbackSlotView::new_unchecked(&self.buffer.as_ref()[field::FEEDBACK])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> LumpedOnlySlotView<T> {
    /// The feedback part, mutable.
    pub fn feedback_mut(&mut self) -> FeedbackSlotView<&mut [u8]> {
        FeedbackSlotView::new_unchecked(&mut self.buffer.as_mut()[field::FEEDBACK])
    }
}
