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
//! ignored.

use core::fmt;

use crate::crc::crc32;
use crate::error::{Error, Result, need};
use crate::field::{put_u16, put_u32, u16_at, u32_at};

/// Protocol version this crate reads and writes.
pub const VERSION: u8 = 1;
/// Length of the common header [B].
pub const HEADER_LEN: usize = 12;
/// Length of the CRC-32 trailer [B].
pub const CRC_LEN: usize = 4;

mod off {
    pub const VERSION: usize = 0;
    pub const KIND: usize = 1;
    pub const FLAGS: usize = 2;
    pub const RETRY: usize = 3;
    pub const CYCLE: usize = 4;
    pub const SEQ: usize = 8;
    pub const LEN: usize = 10;
}

/// The kind of a PDU (header byte 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// Sync lumped frame of the proposed plan: clock sync and feedback of every slave.
    Lumped = 1,
    /// Command frame, master → one slave.
    Command = 2,
    /// Response frame, one slave → master.
    Response = 3,
    /// Lumped frame of the lumped-only plan of ref. [3]: feedback plus desired states and
    /// commands (docs/system.md, "The lumped-only plan").
    LumpedOnly = 4,
}

impl FrameKind {
    /// Decodes header byte 1.
    pub fn from_u8(v: u8) -> Result<Self> {
        match v {
            1 => Ok(FrameKind::Lumped),
            2 => Ok(FrameKind::Command),
            3 => Ok(FrameKind::Response),
            4 => Ok(FrameKind::LumpedOnly),
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
        }
    }
}

impl fmt::Display for FrameKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
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
    /// The raw byte.
    pub const fn bits(self) -> u8 {
        self.0
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
    /// The last command was clipped to the drive's range.
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
    /// The raw bits.
    pub const fn bits(self) -> u16 {
        self.0
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

/// A read/write view of one PDU in a byte buffer (smoltcp style).
///
/// After [`Frame::new_checked`] every accessor is infallible and cannot panic.
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer without checks; accessors may panic on a short buffer.
    pub const fn new_unchecked(buffer: T) -> Self {
        Frame { buffer }
    }

    /// Wraps a buffer after checking that the header and the payload length it declares,
    /// plus the CRC, fit. Version, kind, flags and CRC are checked by the `Repr` parsers
    /// (or by [`Frame::check`]).
    pub fn new_checked(buffer: T) -> Result<Self> {
        let b = buffer.as_ref();
        need("header", b, HEADER_LEN)?;
        let len = u16_at(b, off::LEN) as usize;
        need("payload and CRC", b, HEADER_LEN + len + CRC_LEN)?;
        Ok(Frame { buffer })
    }

    /// Checks version, kind, flags and CRC; returns the kind.
    pub fn check(&self) -> Result<FrameKind> {
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

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
    /// Protocol version byte.
    pub fn version(&self) -> u8 {
        self.buffer.as_ref()[off::VERSION]
    }
    /// Raw kind byte.
    pub fn kind_byte(&self) -> u8 {
        self.buffer.as_ref()[off::KIND]
    }
    /// Raw flags byte.
    pub fn flags_byte(&self) -> u8 {
        self.buffer.as_ref()[off::FLAGS]
    }
    /// Retry count (0 = first attempt).
    pub fn retry(&self) -> u8 {
        self.buffer.as_ref()[off::RETRY]
    }
    /// Cycle counter.
    pub fn cycle(&self) -> u32 {
        u32_at(self.buffer.as_ref(), off::CYCLE)
    }
    /// Sequence number of the sender.
    pub fn seq(&self) -> u16 {
        u16_at(self.buffer.as_ref(), off::SEQ)
    }
    /// Payload length [B].
    pub fn payload_len(&self) -> usize {
        u16_at(self.buffer.as_ref(), off::LEN) as usize
    }
    /// Length of the PDU, header to CRC [B].
    pub fn pdu_len(&self) -> usize {
        HEADER_LEN + self.payload_len() + CRC_LEN
    }
    /// The payload bytes.
    pub fn payload(&self) -> &[u8] {
        &self.buffer.as_ref()[HEADER_LEN..HEADER_LEN + self.payload_len()]
    }
    /// CRC-32 carried in the trailer.
    pub fn crc(&self) -> u32 {
        u32_at(self.buffer.as_ref(), HEADER_LEN + self.payload_len())
    }
    /// CRC-32 of header and payload as they are now.
    pub fn compute_crc(&self) -> u32 {
        crc32(&self.buffer.as_ref()[..HEADER_LEN + self.payload_len()])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Mutable payload bytes (a slave writes its slot in place, then calls
    /// [`Frame::fill_crc`]).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let len = self.payload_len();
        &mut self.buffer.as_mut()[HEADER_LEN..HEADER_LEN + len]
    }
    /// Sets the retry count.
    pub fn set_retry(&mut self, v: u8) {
        self.buffer.as_mut()[off::RETRY] = v;
    }
    /// Sets the flags byte.
    pub fn set_flags(&mut self, v: Flags) {
        self.buffer.as_mut()[off::FLAGS] = v.bits();
    }
    /// Recomputes and stores the CRC-32 trailer.
    pub fn fill_crc(&mut self) {
        let at = HEADER_LEN + self.payload_len();
        let c = self.compute_crc();
        put_u32(self.buffer.as_mut(), at, c);
    }
}

/// The header fields a representation owns (kind and length follow from the payload).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Common {
    /// Header flags.
    pub flags: Flags,
    /// Retry count (0 = first attempt).
    pub retry: u8,
    /// Cycle counter.
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
        retry: frame.retry(),
        cycle: frame.cycle(),
        seq: frame.seq(),
    };
    let len = frame.payload_len();
    Ok((common, &buf[HEADER_LEN..HEADER_LEN + len]))
}

/// [`parse_common`] for a kind whose payload has one fixed length.
pub(crate) fn parse_fixed(
    buf: &[u8],
    kind: FrameKind,
    payload_len: usize,
    verify: bool,
) -> Result<(Common, &[u8])> {
    let (common, p) = parse_common(buf, kind, verify)?;
    if p.len() != payload_len {
        return Err(Error::PayloadLength {
            kind,
            expected: payload_len,
            got: p.len(),
        });
    }
    Ok((common, p))
}

/// Writes header (kind, common fields, payload length) into `buf`, lets `payload` fill the
/// payload, then the CRC. `buf` must hold `HEADER_LEN + payload_len + CRC_LEN` bytes.
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
    buf[off::VERSION] = VERSION;
    buf[off::KIND] = kind as u8;
    buf[off::FLAGS] = common.flags.bits();
    buf[off::RETRY] = common.retry;
    put_u32(buf, off::CYCLE, common.cycle);
    put_u16(buf, off::SEQ, common.seq);
    put_u16(buf, off::LEN, len16);
    payload(&mut buf[HEADER_LEN..HEADER_LEN + payload_len])?;
    let c = crc32(&buf[..HEADER_LEN + payload_len]);
    put_u32(buf, HEADER_LEN + payload_len, c);
    Ok(total)
}
