//! Response frame (kind 3): a slave's answer to its command.
//!
//! ```text
//! payload
//! offset size type  field
//!      0    2 u16   source slave address (1..=65535)
//!      2    2 u16   status bits
//!      4    4 u32   echo of the answered command's cycle counter
//!      8    4 i32   measured position [encoder counts]
//!     12    4 i32   measured velocity [counts/s]
//!     16    8 u64   measuring instant [ns, slave's synchronised clock]
//!     24    4 f32   command applied [V], finite
//! ```

use crate::error::{Error, Result};
use crate::field::{
    f32_at, finite, i32_at, put_f32, put_i32, put_u16, put_u32, put_u64, u16_at, u32_at, u64_at,
};
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, Status, emit_common, parse_fixed};

/// Payload length of a response frame [B].
pub const RESPONSE_PAYLOAD_LEN: usize = 28;
/// Length of a response PDU, header to CRC [B].
pub const RESPONSE_PDU_LEN: usize = HEADER_LEN + RESPONSE_PAYLOAD_LEN + CRC_LEN;

/// Owned representation of a response frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseRepr {
    /// Common header fields.
    pub common: Common,
    /// Source slave address (1-based).
    pub source: u16,
    /// Status bits of the slave.
    pub status: Status,
    /// Cycle counter of the command this answers.
    pub echo_cycle: u32,
    /// Measured position [encoder counts].
    pub position: i32,
    /// Measured velocity [counts/s].
    pub velocity: i32,
    /// Measuring instant [ns, slave's synchronised clock].
    pub sample_time_ns: u64,
    /// Command the slave applied [V]; finite.
    pub applied_v: f32,
}

impl ResponseRepr {
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
        let (common, p) = parse_fixed(buf, FrameKind::Response, RESPONSE_PAYLOAD_LEN, verify)?;
        let source = u16_at(p, 0);
        if source == 0 {
            return Err(Error::BadSlave(source));
        }
        Ok(ResponseRepr {
            common,
            source,
            status: Status::from_bits(u16_at(p, 2))?,
            echo_cycle: u32_at(p, 4),
            position: i32_at(p, 8),
            velocity: i32_at(p, 12),
            sample_time_ns: u64_at(p, 16),
            applied_v: finite("applied command", f32_at(p, 24))?,
        })
    }

    /// Length of the emitted PDU [B].
    pub const fn buffer_len(&self) -> usize {
        RESPONSE_PDU_LEN
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        if self.source == 0 {
            return Err(Error::BadSlave(0));
        }
        let v = finite("applied command", self.applied_v)?;
        emit_common(
            buf,
            FrameKind::Response,
            &self.common,
            RESPONSE_PAYLOAD_LEN,
            |p| {
                put_u16(p, 0, self.source);
                put_u16(p, 2, self.status.bits());
                put_u32(p, 4, self.echo_cycle);
                put_i32(p, 8, self.position);
                put_i32(p, 12, self.velocity);
                put_u64(p, 16, self.sample_time_ns);
                put_f32(p, 24, v);
                Ok(())
            },
        )
    }
}
