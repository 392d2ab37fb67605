//! The delay slot (12 B, kind 5): one slave's part of a delay frame, the frame of the
//! start-up phase in which the nodes measure the ring's delays (docs/wire.md, "Kind 5").
//!
//! A delay frame goes round the ring like the sync lumped frame. In a *probe* the master
//! leaves every path delay 0; each slave, as the probe passes, writes how long it held the
//! previous probe it forwarded (its residence, first bit in to first bit out, on its own
//! clock) and that probe's sequence number: a two-step report, as an IEEE 1588 transparent
//! clock gives its residence in a follow-up, since a slave knows when a frame left only
//! after it left. In a *closing* frame the master writes each slave's path delay; the slave
//! takes its own and marks its slot written as the acknowledgement.
//!
//! ```text
//! offset size type  field
//!      0    4 u32   residence [ns, slave's clock] of the probe `residence_of`
//!      4    4 u32   path delay [ns]: master send to this slave's first bit in (closing
//!                   frame; 0 in a probe)
//!      8    2 u16   residence_of: header sequence number of the probe measured
//!     10    1 u8    marker: 0 not written, 1 written (no residence yet, or a closing
//!                   frame's delay taken), 2 written with a residence
//!     11    1 u8    reserved, 0
//! ```

use super::{SlotCodec, room};
use crate::bytes::{get, put};
use crate::error::{Error, Result, need};
use crate::header::FrameKind;

/// Byte ranges of the delay slot's fields, within the slot (docs/wire.md, "Kind 5").
pub mod field {
    use crate::Field;

    /// Residence, u32 [ns, slave's own clock].
    pub const RESIDENCE: Field = 0..4;
    /// Path delay, u32 \[ns\], written by the master in a closing frame.
    pub const PATH_DELAY: Field = 4..8;
    /// Sequence number of the probe whose residence the slot reports, u16.
    pub const RESIDENCE_OF: Field = 8..10;
    /// Marker, u8: 0 not written, 1 written, 2 written with a residence.
    pub const MARKER: Field = 10..11;
    /// Reserved, u8 (0).
    pub const RESERVED: Field = 11..12;
}

/// What a slave wrote into its delay slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DelayMarker {
    /// The slave has not written the slot (it did not see the frame, or refused it).
    #[default]
    Empty,
    /// Written: a probe seen with no earlier probe to report, or a closing frame's path
    /// delay taken.
    Written,
    /// Written with the residence of probe `residence_of`.
    Residence,
}

impl DelayMarker {
    fn byte(self) -> u8 {
        match self {
            DelayMarker::Empty => 0,
            DelayMarker::Written => 1,
            DelayMarker::Residence => 2,
        }
    }

    fn from_byte(b: u8) -> Result<Self> {
        match b {
            0 => Ok(DelayMarker::Empty),
            1 => Ok(DelayMarker::Written),
            2 => Ok(DelayMarker::Residence),
            other => Err(Error::BadDelayMarker(other)),
        }
    }
}

/// One slave's part of a delay frame (kind 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DelaySlot {
    /// Residence of probe `residence_of` at this slave [ns, its own clock].
    pub residence_ns: u32,
    /// This slave's path delay, master send to its first bit in \[ns\] (closing frames; 0 in
    /// a probe).
    pub path_delay_ns: u32,
    /// Header sequence number of the probe whose residence this is.
    pub residence_of: u16,
    /// What the slave wrote.
    pub marker: DelayMarker,
}

impl SlotCodec for DelaySlot {
    const KIND: FrameKind = FrameKind::Delay;
    const LEN: usize = field::RESERVED.end;

    fn parse(b: &[u8]) -> Result<Self> {
        let v = DelaySlotView::new_checked(b)?;
        v.check()?;
        Ok(DelaySlot {
            residence_ns: v.residence_ns(),
            path_delay_ns: v.path_delay_ns(),
            residence_of: v.residence_of(),
            marker: v.marker()?,
        })
    }

    fn emit(&self, b: &mut [u8]) -> Result<()> {
        room(b, Self::LEN)?;
        let mut v = DelaySlotView::new_unchecked(&mut b[..Self::LEN]);
        v.set_residence_ns(self.residence_ns);
        v.set_path_delay_ns(self.path_delay_ns);
        v.set_residence_of(self.residence_of);
        v.set_marker(self.marker);
        put(v.into_inner(), field::RESERVED, 0u8);
        Ok(())
    }
}

view! {
    /// Zero-copy view of one delay slot in place (from
    /// [`LumpedPayload::delay_slot`](super::LumpedPayload::delay_slot)).
    DelaySlotView;
    /// Checks that the buffer holds a slot (12 B; more is ignored).
    fn check_len(b) {
        need("delay slot", b, DelaySlot::LEN)
    }
}

fields!(DelaySlotView {
    residence_ns, set_residence_ns: u32 = field::RESIDENCE, "Residence of probe `residence_of` [ns, the slave's own clock].";
    path_delay_ns, set_path_delay_ns: u32 = field::PATH_DELAY, "Path delay the master measured for this slave \\[ns\\] (0 in a probe).";
    residence_of, set_residence_of: u16 = field::RESIDENCE_OF, "Sequence number of the probe whose residence the slot reports.";
});

impl<T: AsRef<[u8]>> DelaySlotView<T> {
    /// The marker; a byte other than 0, 1 or 2 is an error.
    pub fn marker(&self) -> Result<DelayMarker> {
        DelayMarker::from_byte(get(self.buffer.as_ref(), field::MARKER))
    }
    /// Checks the marker and the reserved byte (as [`DelaySlot::parse`] does).
    pub fn check(&self) -> Result<()> {
        let b = self.buffer.as_ref();
        self.marker()?;
        let reserved: u8 = get(b, field::RESERVED);
        if reserved != 0 {
            return Err(Error::Reserved {
                field: "delay slot byte 11",
                value: u32::from(reserved),
            });
        }
        Ok(())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> DelaySlotView<T> {
    /// Writes the marker.
    pub fn set_marker(&mut self, m: DelayMarker) {
        put(self.buffer.as_mut(), field::MARKER, m.byte());
    }
}
