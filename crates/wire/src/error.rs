//! Parse and emit errors of the wire layer.

use core::fmt;

use crate::FrameKind;

/// Everything that can be wrong with a received buffer, or with a representation that is
/// to be emitted. Every variant says what was found and what was expected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// The buffer ends before the structure does.
    Truncated {
        /// What was being read.
        what: &'static str,
        /// Bytes needed \[B\].
        needed: usize,
        /// Bytes available \[B\].
        got: usize,
    },
    /// The protocol version byte is not [`crate::VERSION`].
    BadVersion(u8),
    /// The frame-kind byte names no known kind.
    BadKind(u8),
    /// A parser for one kind was handed a frame of another kind.
    WrongKind {
        /// Kind the parser decodes.
        expected: FrameKind,
        /// Kind found in the header.
        got: FrameKind,
    },
    /// Header flag bits that this version does not define are set.
    ReservedFlags(u8),
    /// Status bits that this version does not define are set.
    ReservedStatus(u16),
    /// The header's payload length does not fit the frame kind.
    PayloadLength {
        /// Kind of the frame.
        kind: FrameKind,
        /// Payload length the kind requires \[B\].
        expected: usize,
        /// Payload length in the header \[B\].
        got: usize,
    },
    /// The CRC-32 at the end of the PDU does not match its contents.
    BadCrc {
        /// CRC carried in the frame.
        carried: u32,
        /// CRC computed over header and payload.
        computed: u32,
    },
    /// More slots than one frame may carry (the Ethernet MTU bounds it).
    SlotCountOverCapacity {
        /// Slots in the frame.
        count: usize,
        /// Most slots one frame of this kind carries.
        capacity: usize,
    },
    /// A slave address is 0 (the master's) where a slave 1..=65535 is required.
    BadSlave(u16),
    /// A command or slot value that must be a finite IEEE 754 number is NaN or infinite.
    NonFinite(&'static str),
    /// A reserved field is not zero.
    Reserved {
        /// Which field.
        field: &'static str,
        /// Value found.
        value: u32,
    },
    /// Slot addresses run past slave 65535 (first slot index + slot count too large).
    SlotRange {
        /// First slot index in the frame.
        first: u16,
        /// Slot count in the frame.
        count: u16,
    },
    /// A "written this cycle" marker other than 0 or 1.
    BadMarker(u8),
    /// A delay slot's marker other than 0, 1 or 2.
    BadDelayMarker(u8),
    /// The output buffer is shorter than [`buffer_len`](crate::Pdu::buffer_len) \[B\].
    BufferTooSmall {
        /// Bytes needed \[B\].
        needed: usize,
        /// Bytes available \[B\].
        got: usize,
    },
    /// The EtherType of an Ethernet II frame is not [`crate::ETHERTYPE`].
    BadEtherType(u16),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { what, needed, got } => {
                write!(f, "truncated {what}: need {needed} bytes, got {got}")
            }
            Error::BadVersion(v) => write!(
                f,
                "bad protocol version {v}: this build speaks version {}",
                crate::VERSION
            ),
            Error::BadKind(k) => write!(
                f,
                "bad frame kind {k}: expected 1 (lumped), 2 (command), 3 (response), 4 (lumped-only) or 5 (delay)"
            ),
            Error::WrongKind { expected, got } => {
                write!(f, "wrong frame kind: expected {expected}, got {got}")
            }
            Error::ReservedFlags(b) => write!(
                f,
                "reserved header flag bits set: 0x{b:02x} (allowed: 0x{:02x})",
                crate::Flags::DEFINED
            ),
            Error::ReservedStatus(b) => write!(
                f,
                "reserved status bits set: 0x{b:04x} (allowed: 0x{:04x})",
                crate::Status::DEFINED
            ),
            Error::PayloadLength {
                kind,
                expected,
                got,
            } => write!(
                f,
                "bad payload length for a {kind} frame: expected {expected} bytes, header says {got}"
            ),
            Error::BadCrc { carried, computed } => write!(
                f,
                "bad CRC-32: frame carries 0x{carried:08x}, contents give 0x{computed:08x}"
            ),
            Error::SlotCountOverCapacity { count, capacity } => write!(
                f,
                "slot count {count} over capacity: one frame carries at most {capacity} slots"
            ),
            Error::BadSlave(a) => write!(f, "bad slave address {a}: expected 1..=65535"),
            Error::NonFinite(what) => write!(f, "{what} is not a finite number"),
            Error::Reserved { field, value } => {
                write!(f, "reserved field {field} is {value}, expected 0")
            }
            Error::SlotRange { first, count } => {
                write!(f, "slots {first}+{count} address slaves past 65535")
            }
            Error::BadMarker(m) => write!(f, "bad written-this-cycle marker {m}: expected 0 or 1"),
            Error::BadDelayMarker(m) => write!(f, "bad delay slot marker {m}: expected 0, 1 or 2"),
            Error::BufferTooSmall { needed, got } => {
                write!(f, "output buffer too small: need {needed} bytes, got {got}")
            }
            Error::BadEtherType(t) => write!(
                f,
                "bad EtherType 0x{t:04x}: expected 0x{:04x}",
                crate::ETHERTYPE
            ),
        }
    }
}

impl core::error::Error for Error {}

/// Result of the wire layer.
pub type Result<T> = core::result::Result<T, Error>;

/// Returns `Err(Truncated)` unless `buf` holds at least `needed` bytes.
pub(crate) fn need(what: &'static str, buf: &[u8], needed: usize) -> Result<()> {
    if buf.len() < needed {
        Err(Error::Truncated {
            what,
            needed,
            got: buf.len(),
        })
    } else {
        Ok(())
    }
}

/// Returns `Err(PayloadLength)` unless the payload of a `kind` frame is `expected` bytes.
pub(crate) fn exact_len(kind: FrameKind, payload: &[u8], expected: usize) -> Result<()> {
    if payload.len() == expected {
        Ok(())
    } else {
        Err(Error::PayloadLength {
            kind,
            expected,
            got: payload.len(),
        })
    }
}
