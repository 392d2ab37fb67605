//! Ethernet II framing facts (IEEE 802.3) and a view of an Ethernet II frame that carries a
//! ringsync PDU with EtherType 0x88B5.
//!
//! On the wire a frame is: preamble + SFD (8 B), destination MAC (6), source MAC (6),
//! EtherType (2, big-endian), payload (padded to 46 B), FCS (4), then an inter-frame gap of
//! 12 B before the next frame. "Frame length" here is MAC header to FCS (≥ 64 B). The
//! offsets of the MAC header are in [`field`].

use crate::error::{Error, Result, need};
use crate::header::Frame;

/// Byte ranges of the Ethernet II header, within the frame as a raw socket hands it over
/// (docs/wire.md, "Ethernet II header").
pub mod field {
    use crate::{Field, Rest};

    /// Destination MAC address, 6 B.
    pub const DESTINATION: Field = 0..6;
    /// Source MAC address, 6 B.
    pub const SOURCE: Field = 6..12;
    /// EtherType, u16 big-endian (0x88B5 for ringsync).
    pub const ETHERTYPE: Field = 12..14;
    /// The payload (a ringsync PDU, then padding) starts here.
    pub const PAYLOAD: Rest = 14..;
}

/// EtherType of ringsync frames (IEEE 802 local experimental EtherType 1).
pub const ETHERTYPE: u16 = 0x88B5;
/// Preamble plus start-of-frame delimiter \[B\].
pub const PREAMBLE_SFD_LEN: usize = 8;
/// MAC header: destination, source, EtherType \[B\].
pub const ETH_HEADER_LEN: usize = field::PAYLOAD.start;
/// Frame check sequence \[B\].
pub const FCS_LEN: usize = 4;
/// Minimum frame length, MAC header to FCS \[B\].
pub const MIN_FRAME_LEN: usize = 64;
/// Inter-frame gap \[B\] (96 bit times).
pub const IFG_LEN: usize = 12;
/// Largest payload of a standard Ethernet II frame (MTU) \[B\].
pub const MTU: usize = 1500;

/// Frame length, MAC header to FCS, of a frame whose payload is `payload_len` bytes
/// (padding to the 64-byte minimum included) \[B\].
pub const fn frame_len(payload_len: usize) -> usize {
    let raw = ETH_HEADER_LEN + payload_len + FCS_LEN;
    if raw < MIN_FRAME_LEN {
        MIN_FRAME_LEN
    } else {
        raw
    }
}

/// Bytes on the wire for one frame: preamble + SFD + frame, excluding the gap \[B\].
pub const fn wire_len(payload_len: usize) -> usize {
    PREAMBLE_SFD_LEN + frame_len(payload_len)
}

/// A 48-bit MAC address.
pub type MacAddr = [u8; 6];

fn mac(b: &[u8], f: crate::Field) -> MacAddr {
    let mut a = [0; 6];
    a.copy_from_slice(&b[f]);
    a
}

/// A view of an Ethernet II frame as a raw socket hands it over (no preamble, no FCS).
#[derive(Debug, Clone)]
pub struct EthernetFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EthernetFrame<T> {
    /// Wraps a buffer after checking that it holds a MAC header.
    pub fn new_checked(buffer: T) -> Result<Self> {
        need("Ethernet header", buffer.as_ref(), ETH_HEADER_LEN)?;
        Ok(EthernetFrame { buffer })
    }
    /// Destination MAC address.
    pub fn dst(&self) -> MacAddr {
        mac(self.buffer.as_ref(), field::DESTINATION)
    }
    /// Source MAC address.
    pub fn src(&self) -> MacAddr {
        mac(self.buffer.as_ref(), field::SOURCE)
    }
    /// EtherType (big-endian on the wire).
    pub fn ethertype(&self) -> u16 {
        let mut a = [0; 2];
        a.copy_from_slice(&self.buffer.as_ref()[field::ETHERTYPE]);
        u16::from_be_bytes(a)
    }
    /// The payload (a ringsync PDU, possibly followed by padding), if the EtherType is
    /// ringsync's.
    pub fn ringsync_payload(&self) -> Result<&[u8]> {
        match self.ethertype() {
            ETHERTYPE => Ok(&self.buffer.as_ref()[field::PAYLOAD]),
            other => Err(Error::BadEtherType(other)),
        }
    }
    /// The ringsync PDU without the Ethernet padding: the payload cut to the length its
    /// header declares (header, payload, CRC). A payload too short for its header or for
    /// the length it declares is returned whole, for the receiving node to reject.
    pub fn ringsync_pdu(&self) -> Result<&[u8]> {
        let payload = self.ringsync_payload()?;
        let frame = Frame::new_unchecked(payload);
        Ok(match frame.check_len() {
            Ok(()) => &payload[..frame.pdu_len()],
            Err(_) => payload,
        })
    }
}

/// Writes a MAC header with ringsync's EtherType into `buf[..14]`.
pub fn emit_header(buf: &mut [u8], dst: MacAddr, src: MacAddr) -> Result<usize> {
    if buf.len() < ETH_HEADER_LEN {
        return Err(Error::BufferTooSmall {
            needed: ETH_HEADER_LEN,
            got: buf.len(),
        });
    }
    buf[field::DESTINATION].copy_from_slice(&dst);
    buf[field::SOURCE].copy_from_slice(&src);
    buf[field::ETHERTYPE].copy_from_slice(&ETHERTYPE.to_be_bytes());
    Ok(ETH_HEADER_LEN)
}
