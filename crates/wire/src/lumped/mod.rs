//! Sync lumped frames: the proposed plan's (kind 1) and the lumped-only plan's (kind 4);
//! and the start-up phase's delay frame (kind 5), which goes round the ring the same way.
//!
//! ```text
//! payload
//! offset size type  field
//!      0    8 u64   master send timestamp [ns, master clock]
//!      8    2 u16   first slot index f (slot k belongs to slave f + k + 1)
//!     10    2 u16   slot count m
//!     12  m*S       slots, S = 20 B (kind 1), 32 B (kind 4) or 12 B (kind 5)
//! ```
//! The offsets of the prefix are in [`field`], those of the slots in [`feedback::field`]
//! (kind 1, and the first 20 B of a kind-4 slot), [`lumped_only::field`] (kind 4) and
//! [`delay::field`] (kind 5).

use alloc::vec::Vec;

use crate::bytes::{get, put};
use crate::error::{Error, Result, need};
use crate::ethernet::MTU;
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, emit_common, parse_common};

pub mod delay;
pub mod feedback;
pub mod lumped_only;

pub use delay::{DelayMarker, DelaySlot, DelaySlotView};
pub use feedback::{FeedbackSlot, FeedbackSlotView};
pub use lumped_only::{LumpedOnlySlot, LumpedOnlySlotView};

/// Byte ranges of the lumped payload prefix, within the payload (docs/wire.md, "Kind 1").
pub mod field {
    use crate::{Field, Rest};

    /// Master send timestamp, u64 [ns, master clock].
    pub const MASTER_TIME: Field = 0..8;
    /// First slot index f, u16: slot k belongs to slave f + k + 1.
    pub const FIRST_SLOT: Field = 8..10;
    /// Slot count m, u16.
    pub const SLOT_COUNT: Field = 10..12;
    /// The slots start here, m slots of the kind's slot length.
    pub const SLOTS: Rest = 12..;
}

/// Bytes of the lumped payload before the first slot \[B\].
pub const LUMPED_PREFIX_LEN: usize = field::SLOTS.start;

/// Most slots of `slot_len` bytes that one lumped frame carries within the Ethernet MTU.
pub const fn slot_capacity(slot_len: usize) -> usize {
    (MTU - HEADER_LEN - CRC_LEN - LUMPED_PREFIX_LEN) / slot_len
}

/// Length of a lumped PDU with `slots` slots of `slot_len` bytes, header to CRC \[B\].
pub const fn lumped_pdu_len(slots: usize, slot_len: usize) -> usize {
    HEADER_LEN + LUMPED_PREFIX_LEN + slots * slot_len + CRC_LEN
}

/// A slot layout: how one slave's part of a lumped frame is encoded.
pub trait SlotCodec: Sized + Copy {
    /// Frame kind that carries this slot layout.
    const KIND: FrameKind;
    /// Encoded length of one slot \[B\].
    const LEN: usize;
    /// Decodes one slot from the first `LEN` bytes of `b`, checking every field.
    fn parse(b: &[u8]) -> Result<Self>;
    /// Encodes into the first `LEN` bytes of `b` (reserved bytes zeroed).
    fn emit(&self, b: &mut [u8]) -> Result<()>;
    /// Whether [`SlotCodec::emit`] into a buffer of `LEN` bytes would succeed (the values
    /// it refuses, such as a non-finite command); `emit` checks the same.
    fn validate(&self) -> Result<()> {
        Ok(())
    }
}

/// `Err(BufferTooSmall)` unless `b` holds `len` bytes (a slot to be emitted).
pub(crate) fn room(b: &[u8], len: usize) -> Result<()> {
    if b.len() < len {
        Err(Error::BufferTooSmall {
            needed: len,
            got: b.len(),
        })
    } else {
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
/// The start-up phase's delay frame.
pub type DelayFrameRepr = LumpedRepr<DelaySlot>;

/// Slot length of a lumped kind, or `WrongKind` for the others.
fn slot_len(kind: FrameKind) -> Result<usize> {
    match kind {
        FrameKind::Lumped => Ok(FeedbackSlot::LEN),
        FrameKind::LumpedOnly => Ok(LumpedOnlySlot::LEN),
        FrameKind::Delay => Ok(DelaySlot::LEN),
        other => Err(Error::WrongKind {
            expected: FrameKind::Lumped,
            got: other,
        }),
    }
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
        let p = LumpedPayload::new_checked(payload, S::KIND)?;
        let slots = p.slot_chunks().map(S::parse).collect::<Result<Vec<_>>>()?;
        Ok(LumpedRepr {
            common,
            master_time_ns: p.master_time_ns(),
            first_slot: p.first_slot(),
            slots,
        })
    }

    /// Length of the emitted PDU \[B\].
    pub fn buffer_len(&self) -> usize {
        lumped_pdu_len(self.slots.len(), S::LEN)
    }

    /// Whether [`LumpedRepr::emit`] into a buffer of [`LumpedRepr::buffer_len`] bytes
    /// would succeed: the slot count within the MTU's capacity, the slot addresses within
    /// 65535, every slot emittable. Returns the slot count.
    pub fn validate(&self) -> Result<u16> {
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
        self.slots.iter().try_for_each(S::validate)?;
        Ok(count16)
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let count = self.slots.len();
        let count16 = self.validate()?;
        let len = LUMPED_PREFIX_LEN + count * S::LEN;
        emit_common(buf, S::KIND, &self.common, len, |p| {
            put(p, field::MASTER_TIME, self.master_time_ns);
            put(p, field::FIRST_SLOT, self.first_slot);
            put(p, field::SLOT_COUNT, count16);
            for (slot, chunk) in self
                .slots
                .iter()
                .zip(p[field::SLOTS].chunks_exact_mut(S::LEN))
            {
                slot.emit(chunk)?;
            }
            Ok(())
        })
    }
}

/// Zero-copy view of a lumped payload (the bytes [`Frame::payload`](crate::Frame::payload)
/// returns, or [`Frame::lumped`](crate::Frame::lumped) directly), for a slave that reads the
/// master timestamp and writes its own slot as the frame passes, and for the master that
/// reads the slots in place.
///
/// After [`LumpedPayload::new_checked`] (prefix and slot count agree with the length) no
/// accessor can panic; slot accessors return `None` past the last slot.
#[derive(Debug, Clone, Copy)]
pub struct LumpedPayload<T: AsRef<[u8]>> {
    buffer: T,
    kind: FrameKind,
}

impl<T: AsRef<[u8]>> LumpedPayload<T> {
    /// Wraps the payload of a frame of kind `kind` (lumped, lumped-only or delay) after checking
    /// its prefix: the slot count within the MTU's capacity, the slot addresses within
    /// 65535, and the payload length equal to prefix plus slots.
    pub fn new_checked(buffer: T, kind: FrameKind) -> Result<Self> {
        let slot_len = slot_len(kind)?;
        let payload = buffer.as_ref();
        need("lumped payload prefix", payload, LUMPED_PREFIX_LEN)?;
        let first: u16 = get(payload, field::FIRST_SLOT);
        let count: u16 = get(payload, field::SLOT_COUNT);
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
        Ok(LumpedPayload { buffer, kind })
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
    /// Frame kind: [`FrameKind::Lumped`], [`FrameKind::LumpedOnly`] or [`FrameKind::Delay`].
    pub fn kind(&self) -> FrameKind {
        self.kind
    }
    /// Length of one slot \[B\]: 20 (kind 1), 32 (kind 4) or 12 (kind 5).
    pub fn slot_len(&self) -> usize {
        match self.kind {
            FrameKind::LumpedOnly => LumpedOnlySlot::LEN,
            FrameKind::Delay => DelaySlot::LEN,
            _ => FeedbackSlot::LEN,
        }
    }
    /// Master's send timestamp [ns, master clock].
    pub fn master_time_ns(&self) -> u64 {
        get(self.buffer.as_ref(), field::MASTER_TIME)
    }
    /// Index of the first slot: slot k belongs to slave `first_slot + k + 1`.
    pub fn first_slot(&self) -> u16 {
        get(self.buffer.as_ref(), field::FIRST_SLOT)
    }
    /// Number of slots.
    pub fn slot_count(&self) -> u16 {
        get(self.buffer.as_ref(), field::SLOT_COUNT)
    }
    /// Index in this frame of the slot of slave `address` (1-based), if it is here.
    pub fn slot_index(&self, address: u16) -> Option<usize> {
        let k = usize::from(address).checked_sub(usize::from(self.first_slot()) + 1)?;
        (k < usize::from(self.slot_count())).then_some(k)
    }
    /// Byte range of slot `k` within the payload, or `None` past the end.
    fn slot_range(&self, k: usize) -> Option<crate::Field> {
        if k >= usize::from(self.slot_count()) {
            return None;
        }
        let at = LUMPED_PREFIX_LEN + k * self.slot_len();
        Some(at..at + self.slot_len())
    }
    /// Bytes of slot `k`, or `None` past the end.
    pub fn slot_bytes(&self, k: usize) -> Option<&[u8]> {
        self.slot_range(k).map(|r| &self.buffer.as_ref()[r])
    }
    /// Every slot's bytes, in ring order.
    fn slot_chunks(&self) -> core::slice::ChunksExact<'_, u8> {
        self.buffer.as_ref()[field::SLOTS].chunks_exact(self.slot_len())
    }
    /// The feedback part of slot `k` (the whole slot of kind 1, the first 20 B of a kind-4
    /// slot), or `None` past the end or in a delay frame.
    pub fn feedback_slot(&self, k: usize) -> Option<FeedbackSlotView<&[u8]>> {
        if self.kind == FrameKind::Delay {
            return None;
        }
        self.slot_bytes(k).map(FeedbackSlotView::new_unchecked)
    }
    /// Slot `k` of a delay frame; `None` past the end or in a frame of another kind.
    pub fn delay_slot(&self, k: usize) -> Option<DelaySlotView<&[u8]>> {
        if self.kind != FrameKind::Delay {
            return None;
        }
        self.slot_bytes(k).map(DelaySlotView::new_unchecked)
    }
    /// The feedback part of every slot, in ring order (slot k belongs to slave
    /// `first_slot + k + 1`); none in a delay frame, whose slots hold no feedback.
    pub fn feedback_slots(&self) -> impl ExactSizeIterator<Item = FeedbackSlotView<&[u8]>> {
        // A delay slot (12 B) is shorter than a feedback slot (20 B): its view's getters
        // would read past it.
        let slots = if self.kind == FrameKind::Delay {
            &[][..]
        } else {
            &self.buffer.as_ref()[field::SLOTS]
        };
        slots
            .chunks_exact(self.slot_len())
            .map(FeedbackSlotView::new_unchecked)
    }
    /// Slot `k` of a lumped-only frame; `None` past the end or in a frame of another kind.
    pub fn lumped_only_slot(&self, k: usize) -> Option<LumpedOnlySlotView<&[u8]>> {
        if self.kind != FrameKind::LumpedOnly {
            return None;
        }
        self.slot_bytes(k).map(LumpedOnlySlotView::new_unchecked)
    }
    /// Checks every slot's fields (markers, reserved bytes, status bits, finite commands),
    /// in ring order, as [`LumpedRepr::parse`] does; the first failure is returned.
    pub fn check_slots(&self) -> Result<()> {
        let each = |b: &[u8]| match self.kind {
            FrameKind::LumpedOnly => LumpedOnlySlotView::new_unchecked(b).check(),
            FrameKind::Delay => DelaySlotView::new_unchecked(b).check(),
            _ => FeedbackSlotView::new_unchecked(b).check(),
        };
        self.slot_chunks().try_for_each(each)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> LumpedPayload<T> {
    /// Writes [`master_time_ns`](Self::master_time_ns): the master's send timestamp
    /// [ns, master clock].
    pub fn set_master_time_ns(&mut self, v: u64) {
        put(self.buffer.as_mut(), field::MASTER_TIME, v);
    }
    /// Mutable bytes of slot `k`, or `None` past the end.
    pub fn slot_bytes_mut(&mut self, k: usize) -> Option<&mut [u8]> {
        let r = self.slot_range(k)?;
        Some(&mut self.buffer.as_mut()[r])
    }
    /// The feedback part of slot `k`, mutable (see [`LumpedPayload::feedback_slot`]).
    pub fn feedback_slot_mut(&mut self, k: usize) -> Option<FeedbackSlotView<&mut [u8]>> {
        if self.kind == FrameKind::Delay {
            return None;
        }
        self.slot_bytes_mut(k).map(FeedbackSlotView::new_unchecked)
    }
    /// Slot `k` of a delay frame, mutable (see [`LumpedPayload::delay_slot`]).
    pub fn delay_slot_mut(&mut self, k: usize) -> Option<DelaySlotView<&mut [u8]>> {
        if self.kind != FrameKind::Delay {
            return None;
        }
        self.slot_bytes_mut(k).map(DelaySlotView::new_unchecked)
    }
    /// Slot `k` of a lumped-only frame, mutable (see [`LumpedPayload::lumped_only_slot`]).
    pub fn lumped_only_slot_mut(&mut self, k: usize) -> Option<LumpedOnlySlotView<&mut [u8]>> {
        if self.kind != FrameKind::LumpedOnly {
            return None;
        }
        self.slot_bytes_mut(k)
            .map(LumpedOnlySlotView::new_unchecked)
    }
}

/// What a transparent relay did to a frame it passes on ([`add_to_master_time`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Relayed {
    /// A sync lumped frame (kind 1 or 4): its stamp moved on, its CRC filled again.
    Corrected,
    /// Another kind, which carries no stamp a slave follows: left as it was.
    NotLumped,
    /// The stamp plus the residence would pass the largest u64: left as it was (the
    /// slaves further on refuse so far a stamp anyway).
    Overflow,
}

/// A transparent relay, as a PTP transparent clock corrects a sync message for the time it
/// spent in the bridge: adds `residence_ns` (how long the relay held the frame, first bit
/// in to first bit out, on its own clock) to the master send timestamp of the sync lumped
/// PDU `pdu` (header to CRC) and fills its CRC again, so that every slave after it sees
/// the master's stamp plus the relays' residences, and a slave's path delay is its links
/// alone. A frame that fails its checks (version, kind, flags, CRC, payload length) is
/// left untouched and the error returned: a relay never makes a bad frame good.
pub fn add_to_master_time(pdu: &mut [u8], residence_ns: u64) -> Result<Relayed> {
    let mut frame = crate::Frame::new_checked(&mut pdu[..])?;
    let kind = frame.check()?;
    if !matches!(kind, FrameKind::Lumped | FrameKind::LumpedOnly) {
        return Ok(Relayed::NotLumped);
    }
    let mut p = LumpedPayload::new_checked(frame.payload_mut(), kind)?;
    let Some(stamp) = p.master_time_ns().checked_add(residence_ns) else {
        return Ok(Relayed::Overflow);
    };
    p.set_master_time_ns(stamp);
    frame.fill_crc();
    Ok(Relayed::Corrected)
}

#[cfg(test)]
mod relay_tests {
    use super::*;
    use crate::{Common, Pdu};
    use alloc::vec;

    fn lumped(stamp: u64) -> Vec<u8> {
        let repr = LumpedRepr {
            common: Common {
                cycle: 7,
                seq: 3,
                ..Common::default()
            },
            master_time_ns: stamp,
            first_slot: 0,
            slots: vec![FeedbackSlot::default(); 2],
        };
        let pdu: Pdu = repr.into();
        let mut b = vec![0u8; pdu.buffer_len()];
        pdu.emit(&mut b).expect("emit");
        b
    }

    /// The stamp moves on by the residence and the frame stays whole; everything else in it
    /// is as it was.
    #[test]
    fn a_relay_adds_its_residence_to_the_stamp_and_keeps_the_frame_whole() {
        let mut b = lumped(1_000_000);
        let before = b.clone();
        assert_eq!(add_to_master_time(&mut b, 6_900), Ok(Relayed::Corrected));
        let f = crate::Frame::new_checked(&b[..]).expect("frame");
        assert_eq!(f.check(), Ok(FrameKind::Lumped));
        let p = LumpedPayload::new_checked(f.payload(), FrameKind::Lumped).expect("payload");
        assert_eq!(p.master_time_ns(), 1_006_900);
        let stamp = HEADER_LEN + field::MASTER_TIME.start..HEADER_LEN + field::MASTER_TIME.end;
        let crc = b.len() - CRC_LEN..b.len();
        for k in 0..b.len() {
            if !stamp.contains(&k) && !crc.contains(&k) {
                assert_eq!(b[k], before[k], "byte {k}");
            }
        }
    }

    /// A frame with a bad CRC stays bad (and untouched); a stamp that would wrap is left;
    /// a frame of another kind is left.
    #[test]
    fn a_relay_never_mends_a_bad_frame_nor_wraps_a_stamp() {
        let mut b = lumped(5);
        b[HEADER_LEN + 1] ^= 0x10;
        let bad = b.clone();
        assert!(matches!(
            add_to_master_time(&mut b, 100),
            Err(Error::BadCrc { .. })
        ));
        assert_eq!(b, bad);
        let mut b = lumped(u64::MAX - 10);
        let kept = b.clone();
        assert_eq!(add_to_master_time(&mut b, 11), Ok(Relayed::Overflow));
        assert_eq!(b, kept);
        assert_eq!(add_to_master_time(&mut b, 10), Ok(Relayed::Corrected));
        let cmd = Pdu::Command(crate::CommandRepr {
            common: Common::default(),
            target: 1,
            command_v: 0.5,
            sample_time_ns: 0,
            link_ns: 0,
        });
        let mut c = vec![0u8; cmd.buffer_len()];
        cmd.emit(&mut c).expect("emit");
        let kept = c.clone();
        assert_eq!(add_to_master_time(&mut c, 10), Ok(Relayed::NotLumped));
        assert_eq!(c, kept);
        assert!(add_to_master_time(&mut [0u8; 3], 10).is_err());
    }
}
