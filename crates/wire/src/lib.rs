//! Frame layouts of the ringsync ring protocol (`docs/wire.md` is the byte-by-byte spec).
//!
//! Three frames make one cycle of the proposed plan (docs/system.md, "The cycle plan"): the sync
//! [lumped frame](lumped) (kind 1), a [command frame](command) per slave (kind 2) and its
//! [response frame](response) (kind 3). The lumped-only plan of ref. \[3\] uses its own lumped
//! kind (4) with larger slots. Before the cycles start, both plans measure the ring's delays
//! with [delay frames](lumped::delay) (kind 5), which have the lumped layout too. Every PDU
//! is a 12-byte [header], a payload and a CRC-32; the same bytes travel as the
//! payload of an Ethernet II frame with EtherType 0x88B5 or as a UDP datagram.
//!
//! In the style of smoltcp's `wire` module each layout has
//!
//! - a `field` module of byte ranges ([`header::field`], [`lumped::field`],
//!   [`lumped::feedback::field`], [`lumped::lumped_only::field`], [`lumped::delay::field`],
//!   [`command::field`], [`response::field`], [`ethernet::field`]); a test checks them
//!   against the tables of docs/wire.md;
//! - a zero-copy view over a byte buffer ([`Frame`], [`LumpedPayload`],
//!   [`FeedbackSlotView`], [`LumpedOnlySlotView`], [`DelaySlotView`], [`CommandPayload`],
//!   [`ResponsePayload`], [`EthernetFrame`]): `new_checked` checks the length, after which
//!   no getter can panic. Getters return the raw wire values (typed bit sets drop reserved
//!   bits); each view's `check` applies the field rules (reserved zero, finite floats,
//!   addresses);
//! - an owned representation with `parse`, `emit` and `buffer_len`, which reads and writes
//!   through the view.
//!
//! No parser panics on any input; each returns an [`Error`] that names what was wrong.
//! Frames and PDUs print as one line ([`Frame`]'s and [`Pdu`]'s `Display`).
//!
//! ```
//! use ringsync_wire::{CommandRepr, Common, Frame, Pdu, Route};
//! let cmd = CommandRepr { common: Common { cycle: 7, ..Common::default() },
//!                         target: 2, command_v: -1.25, sample_time_ns: 1_000_000,
//!                         link_ns: 0 };
//! let mut buf = [0u8; 64];
//! let n = cmd.emit(&mut buf).unwrap();
//! assert_eq!(Pdu::parse(&buf[..n]), Ok(Pdu::Command(cmd)));
//!
//! // A driver routes a frame without parsing it, and reads single fields in place.
//! let frame = Frame::new_checked(&buf[..n]).unwrap();
//! assert_eq!(frame.route(), Ok(Route::Command { target: 2 }));
//! assert_eq!(frame.command().unwrap().command_v(), -1.25);
//! assert_eq!(frame.to_string(),
//!            "command cycle 7 seq 0 → slave 2: -1.250 V, sampled at 1000000 ns");
//!
//! buf[20] ^= 1; // a flipped bit is caught by the CRC
//! assert!(Pdu::parse(&buf[..n]).is_err());
//! ```
#![no_std]

extern crate alloc;

#[macro_use]
mod bytes;
pub mod command;
mod crc;
mod display;
mod error;
pub mod ethernet;
pub mod header;
pub mod lumped;
pub mod response;

pub use command::{COMMAND_PDU_LEN, CommandPayload, CommandRepr};
pub use crc::crc32;
pub use error::{Error, Result};
pub use ethernet::{ETHERTYPE, EthernetFrame};
pub use header::{CRC_LEN, Common, Flags, Frame, FrameKind, HEADER_LEN, Route, Status, VERSION};
pub use lumped::{
    DelayFrameRepr, DelayMarker, DelaySlot, DelaySlotView, FeedbackSlot, FeedbackSlotView,
    LumpedFrameRepr, LumpedOnlyFrameRepr, LumpedOnlySlot, LumpedOnlySlotView, LumpedPayload,
    LumpedRepr, Relayed, SlotCodec, add_to_master_time,
};
pub use response::{RESPONSE_PDU_LEN, ResponsePayload, ResponseRepr};

/// The bytes of one fixed-size field: its range within its layout (header, payload or slot),
/// as the `field` modules give them.
pub type Field = core::ops::Range<usize>;
/// Where a variable-length part (a payload, the slots) starts, to the end of its layout.
pub type Rest = core::ops::RangeFrom<usize>;

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
    /// Delay frame of the start-up phase (kind 5).
    Delay(DelayFrameRepr),
}

impl From<LumpedFrameRepr> for Pdu {
    fn from(r: LumpedFrameRepr) -> Self {
        Pdu::Lumped(r)
    }
}

impl From<LumpedOnlyFrameRepr> for Pdu {
    fn from(r: LumpedOnlyFrameRepr) -> Self {
        Pdu::LumpedOnly(r)
    }
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
            FrameKind::Delay => LumpedRepr::parse_verified(buf).map(Pdu::Delay),
        }
    }

    /// The frame kind.
    pub fn kind(&self) -> FrameKind {
        match self {
            Pdu::Lumped(_) => FrameKind::Lumped,
            Pdu::Command(_) => FrameKind::Command,
            Pdu::Response(_) => FrameKind::Response,
            Pdu::LumpedOnly(_) => FrameKind::LumpedOnly,
            Pdu::Delay(_) => FrameKind::Delay,
        }
    }

    /// Length of the emitted PDU, header to CRC \[B\].
    pub fn buffer_len(&self) -> usize {
        match self {
            Pdu::Lumped(r) => r.buffer_len(),
            Pdu::Command(r) => r.buffer_len(),
            Pdu::Response(r) => r.buffer_len(),
            Pdu::LumpedOnly(r) => r.buffer_len(),
            Pdu::Delay(r) => r.buffer_len(),
        }
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        match self {
            Pdu::Lumped(r) => r.emit(buf),
            Pdu::Command(r) => r.emit(buf),
            Pdu::Response(r) => r.emit(buf),
            Pdu::LumpedOnly(r) => r.emit(buf),
            Pdu::Delay(r) => r.emit(buf),
        }
    }

    /// Whether [`Pdu::emit`] into a buffer of [`Pdu::buffer_len`] bytes would succeed (the
    /// same checks, without writing).
    pub fn validate(&self) -> Result<()> {
        match self {
            Pdu::Lumped(r) => r.validate().map(drop),
            Pdu::Command(r) => r.validate(),
            Pdu::Response(r) => r.validate(),
            Pdu::LumpedOnly(r) => r.validate().map(drop),
            Pdu::Delay(r) => r.validate().map(drop),
        }
    }

    /// The PDU's bytes in `buf` (cleared and resized to [`Pdu::buffer_len`]); `Err` (and
    /// `buf` empty) for a PDU [`Pdu::emit`] refuses.
    pub fn emit_into(&self, buf: &mut alloc::vec::Vec<u8>) -> Result<()> {
        buf.clear();
        buf.resize(self.buffer_len(), 0);
        match self.emit(buf) {
            Ok(_) => Ok(()),
            Err(e) => {
                buf.clear();
                Err(e)
            }
        }
    }

    /// The common header fields (cycle, sequence, retry, flags).
    pub fn common(&self) -> &Common {
        match self {
            Pdu::Lumped(r) => &r.common,
            Pdu::Command(r) => &r.common,
            Pdu::Response(r) => &r.common,
            Pdu::LumpedOnly(r) => &r.common,
            Pdu::Delay(r) => &r.common,
        }
    }

    /// Where the frame goes, as [`Frame::route`] reads it from the bytes (a slot count
    /// past 65535 saturates; [`Pdu::validate`] refuses it).
    pub fn route(&self) -> Route {
        let count = |n: usize| u16::try_from(n).unwrap_or(u16::MAX);
        match self {
            Pdu::Lumped(r) => Route::Lumped {
                first_slot: r.first_slot,
                slot_count: count(r.slots.len()),
            },
            Pdu::LumpedOnly(r) => Route::LumpedOnly {
                first_slot: r.first_slot,
                slot_count: count(r.slots.len()),
            },
            Pdu::Delay(r) => Route::Delay {
                first_slot: r.first_slot,
                slot_count: count(r.slots.len()),
            },
            Pdu::Command(r) => Route::Command { target: r.target },
            Pdu::Response(r) => Route::Response { source: r.source },
        }
    }
}
