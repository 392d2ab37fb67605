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
//! The offsets are in [`field`]; [`ResponsePayload`] reads and writes them in place.

use crate::bytes::{finite, put};
use crate::error::{Error, Result, exact_len};
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, Status, emit_common, parse_common};

/// Byte ranges of the response payload's fields, within the payload (docs/wire.md,
/// "Kind 3").
pub mod field {
    use crate::Field;

    /// Source slave address, u16 (1..=65535).
    pub const SOURCE: Field = 0..2;
    /// Status bits, u16.
    pub const STATUS: Field = 2..4;
    /// Cycle counter of the command being answered, u32.
    pub const ECHO_CYCLE: Field = 4..8;
    /// Measured position, i32 [encoder counts].
    pub const POSITION: Field = 8..12;
    /// Measured velocity, i32 [counts/s].
    pub const VELOCITY: Field = 12..16;
    /// Measuring instant, u64 [ns, slave's synchronised clock].
    pub const SAMPLE_TIME: Field = 16..24;
    /// Command applied after clipping, f32 \[V\], finite.
    pub const APPLIED: Field = 24..28;
}

/// Payload length of a response frame \[B\].
pub const RESPONSE_PAYLOAD_LEN: usize = field::APPLIED.end;
/// Length of a response PDU, header to CRC \[B\].
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
    /// Command the slave applied \[V\]; finite.
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
        let (common, p) = parse_common(buf, FrameKind::Response, verify)?;
        let v = ResponsePayload::new_checked(p)?;
        v.check()?;
        Ok(ResponseRepr {
            common,
            source: v.source(),
            status: v.status(),
            echo_cycle: v.echo_cycle(),
            position: v.position(),
            velocity: v.velocity(),
            sample_time_ns: v.sample_time_ns(),
            applied_v: v.applied_v(),
        })
    }

    /// Length of the emitted PDU \[B\].
    pub const fn buffer_len(&self) -> usize {
        RESPONSE_PDU_LEN
    }

    /// Whether [`ResponseRepr::emit`] into a buffer of [`ResponseRepr::buffer_len`] bytes
    /// would succeed: a slave source (not 0) and a finite applied command.
    pub fn validate(&self) -> Result<()> {
        if self.source == 0 {
            return Err(Error::BadSlave(0));
        }
        finite("applied command", self.applied_v).map(drop)
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        self.validate()?;
        let applied_v = self.applied_v;
        emit_common(
            buf,
            FrameKind::Response,
            &self.common,
            RESPONSE_PAYLOAD_LEN,
            |p| {
                let mut v = ResponsePayload::new_unchecked(p);
                v.set_source(self.source);
                v.set_status(self.status);
                v.set_echo_cycle(self.echo_cycle);
                v.set_position(self.position);
                v.set_velocity(self.velocity);
                v.set_sample_time_ns(self.sample_time_ns);
                v.set_applied_v(applied_v);
                Ok(())
            },
        )
    }
}

view! {
    /// Zero-copy view of a response payload (from
    /// [`Frame::response`](crate::Frame::response)). The getters return the raw fields;
    /// [`ResponsePayload::check`] applies the rules of docs/wire.md (as
    /// [`ResponseRepr::parse`] does).
    ResponsePayload;
    /// Checks that the payload is exactly [`RESPONSE_PAYLOAD_LEN`] (28) bytes long.
    fn check_len(b) {
        exact_len(FrameKind::Response, b, RESPONSE_PAYLOAD_LEN)
    }
}

fields!(ResponsePayload {
    source, set_source: u16 = field::SOURCE, "Source slave address (1..=65535 when valid).";
    status_bits: u16 = field::STATUS, "Raw status bits, reserved bits included (see [`ResponsePayload::status`]).";
    echo_cycle, set_echo_cycle: u32 = field::ECHO_CYCLE, "Cycle counter of the command this answers \\[cycles\\].";
    position, set_position: i32 = field::POSITION, "Measured position [encoder counts].";
    velocity, set_velocity: i32 = field::VELOCITY, "Measured velocity [counts/s].";
    sample_time_ns, set_sample_time_ns: u64 = field::SAMPLE_TIME, "Measuring instant [ns, slave's synchronised clock].";
    applied_v, set_applied_v: f32 = field::APPLIED, "Command the slave applied, after clipping \\[V\\] (raw: may be non-finite before `check`).";
});

impl<T: AsRef<[u8]>> ResponsePayload<T> {
    /// Checks the fields: a slave source (not 0), no reserved status bit, a finite applied
    /// command.
    pub fn check(&self) -> Result<()> {
        if self.source() == 0 {
            return Err(Error::BadSlave(0));
        }
        Status::from_bits(self.status_bits())?;
        finite("applied command", self.applied_v()).map(drop)
    }
    /// Status bits; reserved bits are dropped ([`ResponsePayload::check`] rejects them).
    pub fn status(&self) -> Status {
        Status::from_bits_truncate(self.status_bits())
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ResponsePayload<T> {
    /// Writes [`status`](Self::status): the slave's status bits.
    pub fn set_status(&mut self, v: Status) {
        put(self.buffer.as_mut(), field::STATUS, v.bits());
    }
}
