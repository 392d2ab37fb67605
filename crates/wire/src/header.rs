//! The common header, trailer and frame view of every ringsync PDU (docs/wire.md).
//!
//! ```text
//! offset size type  field
//!      0    1 u8    version (= 1)
//!      1    1 u8    kind (1 lumped, 2 command, 3 response, 4 lumped-only)
//!      2    1 u8    flags (bit 0: STOP, bit 1: TORQUE_OFF, bit 2: BRAKE; bits 3-7 reserved, 0)
//!      3    1 u8    retry (0 = first attempt, k = k-th retry)
//!      4    4 u32   cycle counter
//!      8    2 u16   sequence number of the sender
//!     10    2 u16   payload length L [B]
//!     12    L       payload
//!   12+L    4 u32   CRC-32 over bytes 0..12+L
//! ```
//! All multi-byte fields are little-endian. Bytes after the CRC (Ethernet padding) are
//! ignored. The offsets are in [`field`].

use crate::bytes::{get, put};
use crate::command::CommandPayload;
use crate::crc::crc32;
use crate::error::{Error, Result, need};
use crate::lumped::{LumpedPayload, field as lumped_field};
use crate::response::ResponsePayload;

/// Byte ranges of the header fields within a PDU (docs/wire.md, "Common header").
pub mod field {
    use crate::{Field, Rest};

    /// Protocol version, u8 (1 in this version).
    pub const VERSION: Field = 0..1;
    /// Frame kind, u8 (1 lumped, 2 command, 3 response, 4 lumped-only).
    pub const KIND: Field = 1..2;
    /// Flags, u8 (bit 0 `STOP`, bit 1 `TORQUE_OFF`, bit 2 `BRAKE`, bits 3-7 reserved).
    pub const FLAGS: Field = 2..3;
    /// Retry count, u8 (0 for the first attempt).
    pub const RETRY: Field = 3..4;
    /// Cycle counter of the sender, u32 (wraps).
    pub const CYCLE: Field = 4..8;
    /// Sequence number of the sender, u16 (wraps).
    pub const SEQ: Field = 8..10;
    /// Payload length L, u16 \[B\].
    pub const LENGTH: Field = 10..12;
    /// The payload starts here; its length is the header's L.
    pub const PAYLOAD: Rest = 12..;

    /// The payload of a PDU whose header declares `len` payload bytes.
    pub const fn payload(len: usize) -> Field {
        PAYLOAD.start..PAYLOAD.start + len
    }

    /// The CRC-32 trailer, u32, of a PDU with `payload_len` payload bytes.
    pub const fn crc(payload_len: usize) -> Field {
        let at = PAYLOAD.start + payload_len;
        at..at + super::CRC_LEN
    }
}

/// Protocol version this crate reads and writes.
pub const VERSION: u8 = 1;
/// Length of the common header \[B\].
pub const HEADER_LEN: usize = field::PAYLOAD.start;
/// Length of the CRC-32 trailer \[B\].
pub const CRC_LEN: usize = 4;

/// The kind of a PDU (header byte 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// Sync lumped frame of the proposed plan: clock sync and feedback of every slave.
    Lumped = 1,
    /// Command frame, master → one slave.
    Command = 2,
    /// Response frame, one slave → master.
    Response = 3,
    /// Lumped frame of the lumped-only plan of ref. \[3\]: feedback plus desired states and
    /// commands (docs/system.md, "The lumped-only plan").
    LumpedOnly = 4,
    /// Delay frame of the start-up phase: a probe round the ring in which every slave
    /// reports its residence, or the master's closing frame with each slave's path delay
    /// (docs/wire.md, "Kind 5").
    Delay = 5,
}

impl FrameKind {
    /// Decodes header byte 1.
    pub fn from_u8(v: u8) -> Result<Self> {
        match v {
            1 => Ok(FrameKind::Lumped),
            2 => Ok(FrameKind::Command),
            3 => Ok(FrameKind::Response),
            4 => Ok(FrameKind::LumpedOnly),
            5 => Ok(FrameKind::Delay),
            other => Err(Error::BadKind(other)),
        }
    }

    /// Short name used in messages and traces.
    pub fn name(self) -> &'static str {
        match self {
            FrameKind::Lumped => "lumped",
            FrameKind::Command => "command",
            FrameKind::Response => "response",
            FrameKind::LumpedOnly => "lumped-only",
            FrameKind::Delay => "delay",
        }
    }
}

/// Header flags (header byte 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Flags(u8);

impl Flags {
    /// The master orders a controlled stop of the whole group.
    pub const STOP: Flags = Flags(0x01);
    /// The master orders the target axis's drive to cut torque (in a command frame): the
    /// axis could not follow its stop ramp, or the stop is complete. Latched by the slave.
    pub const TORQUE_OFF: Flags = Flags(0x02);
    /// The master orders the target axis's drive to brake on its own (damp its measured
    /// velocity to standstill, then cut torque): the master has no feedback to control it.
    /// In a lumped-only frame: every slave brakes. Latched by the slave.
    pub const BRAKE: Flags = Flags(0x04);
    /// Bits this version defines.
    pub const DEFINED: u8 = 0x07;

    /// No flag set.
    pub const fn empty() -> Self {
        Flags(0)
    }
    /// Decodes the byte; reserved bits are an error.
    pub fn from_bits(b: u8) -> Result<Self> {
        if b & !Self::DEFINED != 0 {
            Err(Error::ReservedFlags(b))
        } else {
            Ok(Flags(b))
        }
    }
    /// Decodes the byte, dropping reserved bits.
    pub const fn from_bits_truncate(b: u8) -> Self {
        Flags(b & Self::DEFINED)
    }
    /// The raw byte.
    pub const fn bits(self) -> u8 {
        self.0
    }
    /// Whether no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Whether every bit of `other` is set.
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }
    /// `self` with the bits of `other` set.
    pub const fn with(self, other: Flags) -> Self {
        Flags(self.0 | other.0)
    }
}

/// Status bits of a slave (slot and response field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Status(u16);

impl Status {
    /// The axis is in its safe state (0 V) after a fault.
    pub const FAULT: Status = Status(0x0001);
    /// The drive's last command was at its range's limit (clipped to it, or sent at it).
    pub const SATURATED: Status = Status(0x0002);
    /// No valid command arrived for W cycles (watchdog expired).
    pub const WATCHDOG: Status = Status(0x0004);
    /// The slave's clock servo has not locked to the master yet.
    pub const CLOCK_UNLOCKED: Status = Status(0x0008);
    /// The axis exceeded its following-error limit.
    pub const FOLLOWING_ERROR: Status = Status(0x0010);
    /// The axis is stopping on a controlled ramp.
    pub const STOPPING: Status = Status(0x0020);
    /// The drive's torque is off (ordered by the master, or the end of the slave's own
    /// fault reaction); latched.
    pub const TORQUE_OFF: Status = Status(0x0040);
    /// The slave lost its master and is braking its axis to standstill on its own.
    pub const BRAKING: Status = Status(0x0080);
    /// Bits this version defines.
    pub const DEFINED: u16 = 0x00FF;

    /// No bit set.
    pub const fn empty() -> Self {
        Status(0)
    }
    /// Decodes the field; reserved bits are an error.
    pub fn from_bits(b: u16) -> Result<Self> {
        if b & !Self::DEFINED != 0 {
            Err(Error::ReservedStatus(b))
        } else {
            Ok(Status(b))
        }
    }
    /// Decodes the field, dropping reserved bits.
    pub const fn from_bits_truncate(b: u16) -> Self {
        Status(b & Self::DEFINED)
    }
    /// The raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// Whether no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Whether every bit of `other` is set.
    pub const fn contains(self, other: Status) -> bool {
        self.0 & other.0 == other.0
    }
    /// `self` with the bits of `other` set.
    pub const fn with(self, other: Status) -> Self {
        Status(self.0 | other.0)
    }
}

/// Where a frame goes, read from its header and routing fields only ([`Frame::route`]).
///
/// Slot k of a lumped frame belongs to slave `first_slot + k + 1`, so a lumped frame serves
/// slaves `first_slot + 1 ..= first_slot + slot_count`. Addresses are raw wire values: a
/// corrupted frame routes somewhere, and the node that receives it rejects it (its CRC).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Route {
    /// Sync lumped frame (kind 1), for the slaves of its slots, then back to the master.
    Lumped {
        /// Index of the first slot.
        first_slot: u16,
        /// Number of slots.
        slot_count: u16,
    },
    /// Lumped-only frame (kind 4), for the slaves of its slots, then back to the master.
    LumpedOnly {
        /// Index of the first slot.
        first_slot: u16,
        /// Number of slots.
        slot_count: u16,
    },
    /// Delay frame (kind 5), for the slaves of its slots, then back to the master.
    Delay {
        /// Index of the first slot.
        first_slot: u16,
        /// Number of slots.
        slot_count: u16,
    },
    /// Command frame (kind 2), for one slave.
    Command {
        /// Target slave address (1..=65535 when valid).
        target: u16,
    },
    /// Response frame (kind 3), from one slave to the master.
    Response {
        /// Source slave address (1..=65535 when valid).
        source: u16,
    },
}

impl Route {
    /// The frame kind.
    pub fn kind(&self) -> FrameKind {
        match self {
            Route::Lumped { .. } => FrameKind::Lumped,
            Route::LumpedOnly { .. } => FrameKind::LumpedOnly,
            Route::Delay { .. } => FrameKind::Delay,
            Route::Command { .. } => FrameKind::Command,
            Route::Response { .. } => FrameKind::Response,
        }
    }
}

view! {
    /// A read/write view of one PDU in a byte buffer (smoltcp style).
    ///
    /// After [`Frame::new_checked`] (header, declared payload and CRC fit) no accessor can
    /// panic. The raw getters (`version`, `kind_byte`, `flags_byte`, `retry`, `cycle`, `seq`)
    /// return the bytes as they are; [`Frame::check`] checks version, kind, flags and CRC,
    /// [`Frame::validate`] everything [`Pdu::parse`](crate::Pdu::parse) checks.
    ///
    /// A driver that only needs to know what a frame is and where it goes calls
    /// [`Frame::route`]; one that needs a payload field reads it through [`Frame::lumped`],
    /// [`Frame::command`] or [`Frame::response`]. None of these checks the CRC: the node
    /// that takes the frame does. Setters on a mutable buffer change the bytes only: call
    /// [`Frame::fill_crc`] after the last one.
    Frame;
    /// Checks that the buffer holds the header, the payload length it declares and the CRC.
    fn check_len(b) {
        need("header", b, HEADER_LEN)?;
        let len = usize::from(get::<u16>(b, field::LENGTH));
        need("payload and CRC", b, HEADER_LEN + len + CRC_LEN)
    }
}

fields!(Frame {
    version: u8 = field::VERSION, "Protocol version byte (1 in this version of the format).";
    kind_byte: u8 = field::KIND, "Raw kind byte (1 lumped, 2 command, 3 response, 4 lumped-only, 5 delay); [`Frame::kind`] decodes it.";
    flags_byte: u8 = field::FLAGS, "Raw flags byte, reserved bits included; [`Frame::flags`] decodes it.";
    retry, set_retry: u8 = field::RETRY, "Retry count: 0 for the first attempt, k for the k-th retry.";
    cycle, set_cycle: u32 = field::CYCLE, "Cycle counter of the sender (wraps) \\[cycles\\].";
    seq, set_seq: u16 = field::SEQ, "Sequence number of the sender (wraps), one per PDU sent.";
});

impl<T: AsRef<[u8]>> Frame<T> {
    /// Checks version, kind, flags and CRC; returns the kind. The payload is not checked
    /// (see [`Frame::validate`]).
    pub fn check(&self) -> Result<FrameKind> {
        self.check_len()?;
        if self.version() != VERSION {
            return Err(Error::BadVersion(self.version()));
        }
        let kind = FrameKind::from_u8(self.kind_byte())?;
        Flags::from_bits(self.flags_byte())?;
        let carried = self.crc();
        let computed = self.compute_crc();
        if carried != computed {
            return Err(Error::BadCrc { carried, computed });
        }
        Ok(kind)
    }

    /// Checks everything [`Pdu::parse`](crate::Pdu::parse) checks, in the same order and
    /// with the same errors, without building the representation (no allocation): header,
    /// CRC, then the kind's payload length and fields. Returns the kind.
    pub fn validate(&self) -> Result<FrameKind> {
        let kind = self.check()?;
        match kind {
            FrameKind::Lumped | FrameKind::LumpedOnly | FrameKind::Delay => {
                self.lumped()?.check_slots()?
            }
            FrameKind::Command => self.command()?.check()?,
            FrameKind::Response => self.response()?.check()?,
        }
        Ok(kind)
    }

    /// The frame kind, from the kind byte alone (no version or CRC check).
    pub fn kind(&self) -> Result<FrameKind> {
        self.check_len()?;
        FrameKind::from_u8(self.kind_byte())
    }

    /// The header flags; reserved bits are dropped ([`Frame::check`] rejects them).
    pub fn flags(&self) -> Flags {
        Flags::from_bits_truncate(self.flags_byte())
    }

    /// The header fields a representation owns; reserved flag bits are dropped.
    pub fn common(&self) -> Common {
        Common {
            flags: self.flags(),
            retry: self.retry(),
            cycle: self.cycle(),
            seq: self.seq(),
        }
    }

    /// What the frame is and where it goes, from the kind byte and the routing fields
    /// (first slot and slot count, target, source): the cheap question a driver asks to
    /// decide which node processes the frame next. Neither the version, the CRC, the payload
    /// length nor the addresses are checked (the receiving node checks them); the routing
    /// fields must lie inside the declared payload.
    pub fn route(&self) -> Result<Route> {
        let kind = self.kind()?;
        let p = self.payload();
        let word = |f: crate::Field| -> Result<u16> {
            need("routing fields", p, f.end)?;
            Ok(get(p, f))
        };
        Ok(match kind {
            FrameKind::Lumped | FrameKind::LumpedOnly | FrameKind::Delay => {
                let slot_count = word(lumped_field::SLOT_COUNT)?;
                let first_slot = word(lumped_field::FIRST_SLOT)?;
                match kind {
                    FrameKind::Lumped => Route::Lumped {
                        first_slot,
                        slot_count,
                    },
                    FrameKind::LumpedOnly => Route::LumpedOnly {
                        first_slot,
                        slot_count,
                    },
                    _ => Route::Delay {
                        first_slot,
                        slot_count,
                    },
                }
            }
            FrameKind::Command => Route::Command {
                target: word(crate::command::field::TARGET)?,
            },
            FrameKind::Response => Route::Response {
                source: word(crate::response::field::SOURCE)?,
            },
        })
    }

    /// The payload of a lumped frame (kind 1 or 4) as a view: master send stamp, slots.
    /// Checks the kind and the prefix against the payload length, not the CRC.
    pub fn lumped(&self) -> Result<LumpedPayload<&[u8]>> {
        let kind = self.kind()?;
        LumpedPayload::new_checked(self.payload(), kind)
    }

    /// The payload of a command frame as a view. Checks the kind and the payload length,
    /// not the CRC.
    pub fn command(&self) -> Result<CommandPayload<&[u8]>> {
        self.expect_kind(FrameKind::Command)?;
        CommandPayload::new_checked(self.payload())
    }

    /// The payload of a response frame as a view. Checks the kind and the payload length,
    /// not the CRC.
    pub fn response(&self) -> Result<ResponsePayload<&[u8]>> {
        self.expect_kind(FrameKind::Response)?;
        ResponsePayload::new_checked(self.payload())
    }

    fn expect_kind(&self, expected: FrameKind) -> Result<()> {
        let got = self.kind()?;
        if got == expected {
            Ok(())
        } else {
            Err(Error::WrongKind { expected, got })
        }
    }

    /// Payload length L the header declares \[B\].
    pub fn payload_len(&self) -> usize {
        usize::from(get::<u16>(self.buffer.as_ref(), field::LENGTH))
    }
    /// Length of the PDU, header to CRC \[B\].
    pub fn pdu_len(&self) -> usize {
        HEADER_LEN + self.payload_len() + CRC_LEN
    }
    /// The payload bytes.
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[field::payload(self.payload_len())]
    }
    /// CRC-32 carried in the trailer.
    pub fn crc(&self) -> u32 {
        get(self.buffer.as_ref(), field::crc(self.payload_len()))
    }
    /// CRC-32 of header and payload as they are now.
    pub fn compute_crc(&self) -> u32 {
        crc32(&self.buffer.as_ref()[..HEADER_LEN + self.payload_len()])
    }
}

impl<T: AsRef<[u8]>> AsRef<[u8]> for Frame<T> {
    /// The whole underlying buffer (the PDU, then any padding).
    fn as_ref(&self) -> &[u8] {
        self.buffer.as_ref()
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Mutable payload bytes (a slave writes its slot in place, then calls
    /// [`Frame::fill_crc`]).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let len = self.payload_len();
        &mut self.buffer.as_mut()[field::payload(len)]
    }
    /// The payload of a lumped frame as a mutable view (see [`Frame::lumped`]).
    pub fn lumped_mut(&mut self) -> Result<LumpedPayload<&mut [u8]>> {
        let kind = self.kind()?;
        LumpedPayload::new_checked(self.payload_mut(), kind)
    }
    /// The payload of a command frame as a mutable view (see [`Frame::command`]).
    pub fn command_mut(&mut self) -> Result<CommandPayload<&mut [u8]>> {
        self.expect_kind(FrameKind::Command)?;
        CommandPayload::new_checked(self.payload_mut())
    }
    /// The payload of a response frame as a mutable view (see [`Frame::response`]).
    pub fn response_mut(&mut self) -> Result<ResponsePayload<&mut [u8]>> {
        self.expect_kind(FrameKind::Response)?;
        ResponsePayload::new_checked(self.payload_mut())
    }
    /// Sets the flags byte.
    pub fn set_flags(&mut self, v: Flags) {
        put(self.buffer.as_mut(), field::FLAGS, v.bits());
    }
    /// Recomputes and stores the CRC-32 trailer.
    pub fn fill_crc(&mut self) {
        let at = field::crc(self.payload_len());
        let c = self.compute_crc();
        put(self.buffer.as_mut(), at, c);
    }
}

/// The header fields a representation owns (kind and length follow from the payload).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Common {
    /// Header flags.
    pub flags: Flags,
    /// Retry count (0 = first attempt).
    pub retry: u8,
    /// Cycle counter \[cycles\].
    pub cycle: u32,
    /// Sequence number of the sender.
    pub seq: u16,
}

/// Parses the header of `buf` for a frame of kind `kind` and returns the common fields and
/// the payload slice; the caller checks the payload. With `verify` the version, flags and
/// CRC are checked too; without, the caller has just done so with [`Frame::check`].
pub(crate) fn parse_common(buf: &[u8], kind: FrameKind, verify: bool) -> Result<(Common, &[u8])> {
    let frame = Frame::new_checked(buf)?;
    let got = if verify {
        frame.check()?
    } else {
        FrameKind::from_u8(frame.kind_byte())?
    };
    if got != kind {
        return Err(Error::WrongKind {
            expected: kind,
            got,
        });
    }
    let common = Common {
        flags: Flags::from_bits(frame.flags_byte())?,
        ..frame.common()
    };
    Ok((common, &buf[field::payload(frame.payload_len())]))
}

/// Writes header (kind, common fields, payload length) into `buf`, zeroes the payload and
/// lets `payload` fill it, then writes the CRC. Returns the PDU length.
pub(crate) fn emit_common(
    buf: &mut [u8],
    kind: FrameKind,
    common: &Common,
    payload_len: usize,
    payload: impl FnOnce(&mut [u8]) -> Result<()>,
) -> Result<usize> {
    let total = HEADER_LEN + payload_len + CRC_LEN;
    if buf.len() < total {
        return Err(Error::BufferTooSmall {
            needed: total,
            got: buf.len(),
        });
    }
    let Ok(len16) = u16::try_from(payload_len) else {
        return Err(Error::BufferTooSmall {
            needed: total,
            got: usize::from(u16::MAX),
        });
    };
    put(buf, field::VERSION, VERSION);
    put(buf, field::KIND, kind as u8);
    put(buf, field::LENGTH, len16);
    let mut frame = Frame::new_unchecked(&mut buf[..total]);
    frame.set_flags(common.flags);
    frame.set_retry(common.retry);
    frame.set_cycle(common.cycle);
    frame.set_seq(common.seq);
    let p = frame.payload_mut();
    p.fill(0);
    payload(p)?;
    frame.fill_crc();
    Ok(total)
}
