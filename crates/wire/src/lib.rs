//! Frame layouts of the ringsync ring protocol (`docs/wire.md` is the byte-by-byte spec).
//!
//! Three frames make one cycle of the proposed plan (docs/system.md, "The cycle plan"): the sync
//! [lumped frame](lumped) (kind 1), a [command frame](command) per slave (kind 2) and its
//! [response frame](response) (kind 3). The lumped-only plan of ref. [3] uses its own lumped
//! kind (4) with larger slots. Every PDU is a 12-byte [header](header), a payload and a
//! CRC-32; the same bytes travel as the payload of an Ethernet II frame with EtherType
//! 0x88B5 or as a UDP datagram.
//!
//! In the style of smoltcp's `wire` module there are zero-copy views over byte buffers
//! ([`Frame`], [`LumpedPayload`], [`EthernetFrame`]) and owned representations with `parse`,
//! `emit` and `buffer_len`. No parser panics on any input; each returns an [`Error`] that
//! names what was wrong.
//!
//! ```
//! use ringsync_wire::{CommandRepr, Common, Pdu};
//! let cmd = CommandRepr { common: Common { cycle: 7, ..Common::default() },
//!                         target: 2, command_v: -1.25, sample_time_ns: 1_000_000 };
//! let mut buf = [0u8; 64];
//! let n = cmd.emit(&mut buf).unwrap();
//! assert_eq!(Pdu::parse(&buf[..n]), Ok(Pdu::Command(cmd)));
//! buf[20] ^= 1; // a flipped bit is caught by the CRC
//! assert!(Pdu::parse(&buf[..n]).is_err());
//! ```
#![no_std]

extern crate alloc;

pub mod command;
mod crc;
mod error;
pub mod ethernet;
mod field;
pub mod header;
pub mod lumped;
pub mod response;

pub use command::{COMMAND_PDU_LEN, CommandRepr};
pub use crc::crc32;
pub use error::{Error, Result};
pub use ethernet::{ETHERTYPE, EthernetFrame};
pub use header::{CRC_LEN, Common, Flags, Frame, FrameKind, HEADER_LEN, Status, VERSION};
pub use lumped::{
    FeedbackSlot, LumpedFrameRepr, LumpedOnlyFrameRepr, LumpedOnlySlot, LumpedPayload, LumpedRepr,
    SlotCodec,
};
pub use response::{RESPONSE_PDU_LEN, ResponseRepr};

/// Any ringsync PDU, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum Pdu {
    /// Sync lumped frame of the proposed plan (kind 1).
    Lumped(LumpedFrameRepr),
    /// Command frame (kind 2).
    Command(CommandRepr),
    /// Response frame (kind 3).
    Response(ResponseRepr),
    /// Lumped frame of the lumped-only plan (kind 4).
    LumpedOnly(LumpedOnlyFrameRepr),
}

impl Pdu {
    /// Parses any PDU: header, kind, payload and CRC are all checked. Bytes after the CRC
    /// (Ethernet padding) are ignored.
    pub fn parse(buf: &[u8]) -> Result<Self> {
        let frame = Frame::new_checked(buf)?;
        // The header and CRC are checked once here; the kind's parser checks the payload.
        match frame.check()? {
            FrameKind::Lumped => LumpedRepr::parse_verified(buf).map(Pdu::Lumped),
            FrameKind::Command => CommandRepr::parse_verified(buf).map(Pdu::Command),
            FrameKind::Response => ResponseRepr::parse_verified(buf).map(Pdu::Response),
            FrameKind::LumpedOnly => LumpedRepr::parse_verified(buf).map(Pdu::LumpedOnly),
        }
    }

    /// The frame kind.
    pub fn kind(&self) -> FrameKind {
        match self {
            Pdu::Lumped(_) => FrameKind::Lumped,
            Pdu::Command(_) => FrameKind::Command,
            Pdu::Response(_) => FrameKind::Response,
            Pdu::LumpedOnly(_) => FrameKind::LumpedOnly,
        }
    }

    /// Length of the emitted PDU, header to CRC [B].
    pub fn buffer_len(&self) -> usize {
        match self {
            Pdu::Lumped(r) => r.buffer_len(),
            Pdu::Command(r) => r.buffer_len(),
            Pdu::Response(r) => r.buffer_len(),
            Pdu::LumpedOnly(r) => r.buffer_len(),
        }
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        match self {
            Pdu::Lumped(r) => r.emit(buf),
            Pdu::Command(r) => r.emit(buf),
            Pdu::Response(r) => r.emit(buf),
            Pdu::LumpedOnly(r) => r.emit(buf),
        }
    }
}
