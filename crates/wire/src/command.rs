//! Command frame (kind 2): the master's command for one slave in its time slice.
//!
//! ```text
//! payload
//! offset size type  field
//!      0    2 u16   target slave address (1..=65535)
//!      2    2 u16   link delay [ns]: the master's running estimate behind transparent relays, 0 none
//!      4    4 f32   command [V], finite (IEEE 754 binary32)
//!      8    8 u64   sampling instant the command was computed from [ns, master clock]
//! ```
//! The offsets are in [`field`]; [`CommandPayload`] reads and writes them in place.

use crate::bytes::finite;
use crate::error::{Error, Result, exact_len};
use crate::header::{CRC_LEN, Common, FrameKind, HEADER_LEN, emit_common, parse_common};

/// Byte ranges of the command payload's fields, within the payload (docs/wire.md, "Kind 2").
pub mod field {
    use crate::Field;

    /// Target slave address, u16 (1..=65535; 0 is the master and is rejected).
    pub const TARGET: Field = 0..2;
    /// The master's running estimate of one link's delay behind transparent relays, u16
    /// \[ns\]; 0: none (docs/wire.md).
    pub const LINK: Field = 2..4;
    /// Command, f32 \[V\], finite.
    pub const COMMAND: Field = 4..8;
    /// Sampling instant of the feedback the command was computed from, u64 [ns, master clock].
    pub const SAMPLE_TIME: Field = 8..16;
}

/// Payload length of a command frame \[B\].
pub const COMMAND_PAYLOAD_LEN: usize = field::SAMPLE_TIME.end;
/// Length of a command PDU, header to CRC \[B\].
pub const COMMAND_PDU_LEN: usize = HEADER_LEN + COMMAND_PAYLOAD_LEN + CRC_LEN;

/// Owned representation of a command frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandRepr {
    /// Common header fields.
    pub common: Common,
    /// Target slave address (1-based).
    pub target: u16,
    /// Command for the drive \[V\]; finite.
    pub command_v: f32,
    /// Sampling instant of the feedback the command was computed from [ns, master clock].
    pub sample_time_ns: u64,
    /// The master's running estimate of one link's delay \[ns\] when the relays are
    /// transparent (a slave behind them takes its address times this as its path delay);
    /// 0: none.
    pub link_ns: u16,
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
        let (common, p) = parse_common(buf, FrameKind::Command, verify)?;
        let v = CommandPayload::new_checked(p)?;
        v.check()?;
        Ok(CommandRepr {
            common,
            target: v.target(),
            command_v: v.command_v(),
            sample_time_ns: v.sample_time_ns(),
            link_ns: v.link_ns(),
        })
    }

    /// Length of the emitted PDU \[B\].
    pub const fn buffer_len(&self) -> usize {
        COMMAND_PDU_LEN
    }

    /// Whether [`CommandRepr::emit`] into a buffer of [`CommandRepr::buffer_len`] bytes
    /// would succeed: a slave target (not 0) and a finite command.
    pub fn validate(&self) -> Result<()> {
        if self.target == 0 {
            return Err(Error::BadSlave(0));
        }
        finite("command", self.command_v).map(drop)
    }

    /// Writes the PDU into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        self.validate()?;
        let command_v = self.command_v;
        emit_common(
            buf,
            FrameKind::Command,
            &self.common,
            COMMAND_PAYLOAD_LEN,
            |p| {
                let mut v = CommandPayload::new_unchecked(p);
                v.set_target(self.target);
                v.set_link_ns(self.link_ns);
                v.set_command_v(command_v);
                v.set_sample_time_ns(self.sample_time_ns);
                Ok(())
            },
        )
    }
}

view! {
    /// Zero-copy view of a command payload (from [`Frame::command`](crate::Frame::command)).
    /// The getters return the raw fields; [`CommandPayload::check`] applies the rules of
    /// docs/wire.md (as [`CommandRepr::parse`] does).
    CommandPayload;
    /// Checks that the payload is exactly [`COMMAND_PAYLOAD_LEN`] (16) bytes long.
    fn check_len(b) {
        exact_len(FrameKind::Command, b, COMMAND_PAYLOAD_LEN)
    }
}

fields!(CommandPayload {
    target, set_target: u16 = field::TARGET, "Target slave address (1..=65535 when valid; 0 is the master's).";
    link_ns, set_link_ns: u16 = field::LINK, "The master's estimate of one link's delay behind transparent relays \\[ns\\]; 0: none.";
    command_v, set_command_v: f32 = field::COMMAND, "Command for the drive \\[V\\] (raw: may be non-finite before `check`).";
    sample_time_ns, set_sample_time_ns: u64 = field::SAMPLE_TIME, "Sampling instant of the feedback the command was computed from [ns, master clock].";
});

impl<T: AsRef<[u8]>> CommandPayload<T> {
    /// Checks the fields: a slave target (not 0), a finite command (any link value is
    /// well formed; the slave judges it against its own path).
    pub fn check(&self) -> Result<()> {
        if self.target() == 0 {
            return Err(Error::BadSlave(0));
        }
        finite("command", self.command_v()).map(drop)
    }
}
