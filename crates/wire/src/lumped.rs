//! Sync lumped frames: the proposed plan's (kind 1) and the lumped-only plan's (kind 4).
//!
//! ```text
//! payload
//! offset size type  field
//!      0    8 u64   master send timestamp [ns, master clock]
//!      8    2 u16   first slot index f (slot k belongs to slave f + k + 1)
//!     10    2 u16   slot count m
//!     12  m*S       slots, S = 20 B (kind 1) or 32 B (kind 4)
//!
//! feedback slot (kind 1, and the first 20 B of a kind-4 slot)
//!      0    4 i32   position [encoder counts]
//!      4    4 i32   velocity [counts/s]
//!      8    8 u64   sampling timestamp [ns, slave's synchronised clock]
//!     16    2 u16   status bits
//!     18    1 u8    written this cycle (0 or 1)
//!     19    1 u8    reserved, 0
//!
//! lumped-only slot (kind 4), after the feedback part
//!     20    4 i32   desired position [encoder counts] (written by the master)
//!     24    4 i32   desired velocity [counts/s] (written by the master)
//!     28    4 f32   command applied [V] (written by the slave)
//! ```

use alloc::vec::Vec;

use crate::error::{Error, Result, need};
use crate::ethernet::MTU;
use crate::field::{f32_at, finite, i32_at, put_f32, put_i32, put_u16, put_u64, u16_at, u64_at};
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, Status, emit_common, parse_common};

/// Bytes of the lumped payload before the first slot [B].
pub const LUMPED_PREFIX_LEN: usize = 12;

/// Most slots of `slot_len` bytes that one lumped frame carries within the Ethernet MTU.
pub const fn slot_capacity(slot_len: usize) -> usize {
    (MTU - HEADER_LEN - CRC_LEN - LUMPED_PREFIX_LEN) / slot_len
}

/// Length of a lumped PDU with `slots` slots of `slot_len` bytes, header to CRC [B].
pub const fn lumped_pdu_len(slots: usize, slot_len: usize) -> usize {
    HEADER_LEN + LUMPED_PREFIX_LEN + slots * slot_len + CRC_LEN
}

/// A slot layout: how one slave's part of a lumped frame is encoded.
pub trait SlotCodec: Sized + Copy {
    /// Frame kind that carries this slot layout.
    const KIND: FrameKind;
    /// Encoded length of one slot [B].
    const LEN: usize;
    /// Decodes one slot from exactly `LEN` bytes.
    fn parse(b: &[u8]) -> Result<Self>;
    /// Encodes into exactly `LEN` bytes.
    fn emit(&self, b: &mut [u8]) -> Result<()>;
}

/// One slave's feedback in the lumped frame (kind 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FeedbackSlot {
    /// Position sampled at the synchronised sampling instant [encoder counts].
    pub position: i32,
    /// Velocity measured by the slave [counts/s].
    pub velocity: i32,
    /// Sampling instant on the slave's synchronised clock [ns].
    pub sample_time_ns: u64,
    /// Status bits.
    pub status: Status,
    /// The slave wrote this slot in this cycle (`false`: the values are older).
    pub written: bool,
}

impl SlotCodec for FeedbackSlot {
    const KIND: FrameKind = FrameKind::Lumped;
    const LEN: usize = 20;

    fn parse(b: &[u8]) -> Result<Self> {
        need("feedback slot", b, Self::LEN)?;
        let written = match b[18] {
            0 => false,
            1 => true,
            m => return Err(Error::BadMarker(m)),
        };
        if b[19] != 0 {
            return Err(Error::Reserved {
                field: "slot byte 19",
                value: u32::from(b[19]),
            });
        }
        Ok(FeedbackSlot {
            position: i32_at(b, 0),
            velocity: i32_at(b, 4),
            sample_time_ns: u64_at(b, 8),
            status: Status::from_bits(u16_at(b, 16))?,
            written,
        })
    }

    fn emit(&self, b: &mut [u8]) -> Result<()> {
        put_i32(b, 0, self.position);
        put_i32(b, 4, self.velocity);
        put_u64(b, 8, self.sample_time_ns);
        put_u16(b, 16, self.status.bits());
        b[18] = u8::from(self.written);
        b[19] = 0;
        Ok(())
    }
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
    /// Command the slave applied [V]; finite.
    pub command_v: f32,
}

impl SlotCodec for LumpedOnlySlot {
    const KIND: FrameKind = FrameKind::LumpedOnly;
    const LEN: usize = 32;

    fn parse(b: &[u8]) -> Result<Self> {
        need("lumped-only slot", b, Self::LEN)?;
        Ok(LumpedOnlySlot {
            feedback: FeedbackSlot::parse(&b[..FeedbackSlot::LEN])?,
            desired_position: i32_at(b, 20),
            desired_velocity: i32_at(b, 24),
            command_v: finite("slot command", f32_at(b, 28))?,
        })
    }

    fn emit(&self, b: &mut [u8]) -> Result<()> {
        self.feedback.emit(&mut b[..FeedbackSlot::LEN])?;
        put_i32(b, 20, self.desired_position);
        put_i32(b, 24, self.desired_velocity);
        put_f32(b, 28, finite("slot command", self.command_v)?);
        Ok(())
    }
}

/// Owned representation of a lumped frame with slots of layout `S`.
#[derive(Debug, Clone, PartialEq)]
pub struct LumpedRepr<S> {
    /// Common header fields.
    pub common: Common,
    /// Master's send timestamp [ns, master clock].
    pub master_time_ns: u64,
    /// Index of the first slot: slot k belongs to slave `first_slot + k + 1`.
    pub first_slot: u16,
    /// The slots, in ring order.
    pub slots: Vec<S>,
}

/// The proposed plan's sync lumped frame.
pub type LumpedFrameRepr = LumpedRepr<FeedbackSlot>;
/// The lumped-only plan's frame.
pub type LumpedOnlyFrameRepr = LumpedRepr<LumpedOnlySlot>;

/// Checks a lumped payload prefix against its length and returns (first slot, slot count).
fn check_prefix(payload: &[u8], kind: FrameKind, slot_len: usize) -> Result<(u16, u16)> {
    need("lumped payload prefix", payload, LUMPED_PREFIX_LEN)?;
    let first = u16_at(payload, 8);
    let count = u16_at(payload, 10);
    let capacity = slot_capacity(slot_len);
    if usize::from(count) > capacity {
        return Err(Error::SlotCountOverCapacity {
            count: count.into(),
            capacity,
        });
    }
    if u32::from(first) + u32::from(count) > u32::from(u16::MAX) {
        return Err(Error::SlotRange { first, count });
    }
    let expected = LUMPED_PREFIX_LEN + usize::from(count) * slot_len;
    if payload.len() != expected {
        return Err(Error::PayloadLength {
            kind,
            expected,
            got: payload.len(),
        });
    }
    Ok((first, count))
}

impl<S: SlotCodec> LumpedRepr<S> {
    /// Parses and checks a whole PDU (header, payload, CRC).
    pub fn parse(buf: &[u8]) -> Result<Self> {
        Self::parse_inner(buf, true)
    }

    /// Parses a PDU whose header and CRC the caller has just verified with
    /// [`Frame::check`](crate::Frame::check); the payload is still checked.
    pub fn parse_verified(buf: &[u8]) -> Result<Self> {
        Self::parse_inner(buf, false)
    }

    fn parse_inner(buf: &[u8], verify: bool) -> Result<Self> {
        let (common, payload) = parse_common(buf, S::KIND, verify)?;
        let (first_slot, count) = check_prefix(payload, S::KIND, S::LEN)?;
        let mut slots = Vec::with_capacity(count.into());
        for chunk in payload[LUMPED_PREFIX_LEN..].chunks_exact(S::LEN) {
            slots.push(S::parse(chunk)?);
        }
        Ok(LumpedRepr {
            common,
            master_time_ns: u64_at(payload, 0),
            first_slot,
            slots,
        })
    }

    /// Length of the emitted PDU [B].
    pub fn buffer_len(&self) -> usize {
        lumped_pdu_len(self.slots.len(), S::LEN)
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let count = self.slots.len();
        let capacity = slot_capacity(S::LEN);
        if count > capacity {
            return Err(Error::SlotCountOverCapacity { count, capacity });
        }
        // count <= capacity < 2^16, so the cast is exact.
        let count16 = count as u16;
        if u32::from(self.first_slot) + u32::from(count16) > u32::from(u16::MAX) {
            return Err(Error::SlotRange {
                first: self.first_slot,
                count: count16,
            });
        }
        let len = LUMPED_PREFIX_LEN + count * S::LEN;
        emit_common(buf, S::KIND, &self.common, len, |p| {
            put_u64(p, 0, self.master_time_ns);
            put_u16(p, 8, self.first_slot);
            put_u16(p, 10, count16);
            for (slot, chunk) in self
                .slots
                .iter()
                .zip(p[LUMPED_PREFIX_LEN..].chunks_exact_mut(S::LEN))
            {
                slot.emit(chunk)?;
            }
            Ok(())
        })
    }
}

/// Zero-copy view of a lumped payload (the bytes [`crate::Frame::payload`] returns), for a
/// slave that reads the master timestamp and writes its own slot as the frame passes.
#[derive(Debug)]
pub struct LumpedPayload<T: AsRef<[u8]>> {
    buffer: T,
    slot_len: usize,
}

impl<T: AsRef<[u8]>> LumpedPayload<T> {
    /// Wraps a payload of a frame of kind `kind` after checking its prefix and length.
    pub fn new_checked(buffer: T, kind: FrameKind) -> Result<Self> {
        let slot_len = match kind {
            FrameKind::Lumped => FeedbackSlot::LEN,
            FrameKind::LumpedOnly => LumpedOnlySlot::LEN,
            other => {
                return Err(Error::WrongKind {
                    expected: FrameKind::Lumped,
                    got: other,
                });
            }
        };
        check_prefix(buffer.as_ref(), kind, slot_len)?;
        Ok(LumpedPayload { buffer, slot_len })
    }
    /// Master's send timestamp [ns, master clock].
    pub fn master_time_ns(&self) -> u64 {
        u64_at(self.buffer.as_ref(), 0)
    }
    /// Index of the first slot.
    pub fn first_slot(&self) -> u16 {
        u16_at(self.buffer.as_ref(), 8)
    }
    /// Number of slots.
    pub fn slot_count(&self) -> u16 {
        u16_at(self.buffer.as_ref(), 10)
    }
    /// Index in this frame of the slot of slave `address` (1-based), if it is here.
    pub fn slot_index(&self, address: u16) -> Option<usize> {
        let k = usize::from(address).checked_sub(usize::from(self.first_slot()) + 1)?;
        (k < usize::from(self.slot_count())).then_some(k)
    }
    /// Bytes of slot `k`, or `None` past the end.
    pub fn slot_bytes(&self, k: usize) -> Option<&[u8]> {
        if k >= usize::from(self.slot_count()) {
            return None;
        }
        let at = LUMPED_PREFIX_LEN + k * self.slot_len;
        Some(&self.buffer.as_ref()[at..at + self.slot_len])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> LumpedPayload<T> {
    /// Mutable bytes of slot `k`, or `None` past the end.
    pub fn slot_bytes_mut(&mut self, k: usize) -> Option<&mut [u8]> {
        if k >= usize::from(self.slot_count()) {
            return None;
        }
        let at = LUMPED_PREFIX_LEN + k * self.slot_len;
        let len = self.slot_len;
        Some(&mut self.buffer.as_mut()[at..at + len])
    }
}
