//! Command frame (kind 2): the master's command for one slave in its time slice.
//!
//! ```text
//! payload
//! offset size type  field
//!      0    2 u16   target slave address (1..=65535)
//!      2    2 u16   reserved, 0
//!      4    4 f32   command [V], finite (IEEE 754 binary32)
//!      8    8 u64   sampling instant the command was computed from [ns, master clock]
//! ```

use crate::error::{Error, Result};
use crate::field::{f32_at, finite, put_f32, put_u16, put_u64, u16_at, u64_at};
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, emit_common, parse_fixed};

/// Payload length of a command frame [B].
pub const COMMAND_PAYLOAD_LEN: usize = 16;
/// Length of a command PDU, header to CRC [B].
pub const COMMAND_PDU_LEN: usize = HEADER_LEN + COMMAND_PAYLOAD_LEN + CRC_LEN;

/// Owned representation of a command frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandRepr {
    /// Common header fields.
    pub common: Common,
    /// Target slave address (1-based).
    pub target: u16,
    /// Command for the drive [V]; finite.
    pub command_v: f32,
    /// Sampling instant of the feedback the command was computed from [ns, master clock].
    pub sample_time_ns: u64,
}

impl CommandRepr {
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
        let (common, p) = parse_fixed(buf, FrameKind::Command, COMMAND_PAYLOAD_LEN, verify)?;
        let target = u16_at(p, 0);
        if target == 0 {
            return Err(Error::BadSlave(target));
        }
        let reserved = u16_at(p, 2);
        if reserved != 0 {
            return Err(Error::Reserved {
                field: "command bytes 2-3",
                value: reserved.into(),
            });
        }
        Ok(CommandRepr {
            common,
            target,
            command_v: finite("command", f32_at(p, 4))?,
            sample_time_ns: u64_at(p, 8),
        })
    }

    /// Length of the emitted PDU [B].
    pub const fn buffer_len(&self) -> usize {
        COMMAND_PDU_LEN
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        if self.target == 0 {
            return Err(Error::BadSlave(0));
        }
        let v = finite("command", self.command_v)?;
        emit_common(
            buf,
            FrameKind::Command,
            &self.common,
            COMMAND_PAYLOAD_LEN,
            |p| {
                put_u16(p, 0, self.target);
                put_u16(p, 2, 0);
                put_f32(p, 4, v);
                put_u64(p, 8, self.sample_time_ns);
                Ok(())
            },
        )
    }
}
