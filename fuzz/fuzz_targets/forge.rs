//! Shared by the node targets (`ring`, `slave`, `master`): frames built field by field, any
//! value included (reserved bits, non-finite floats, lengths that do not fit), always with a
//! valid CRC, so that a forged frame gets past the wire layer's CRC check and reaches the
//! nodes' own acceptance checks; and the fuzzer's relative times and cycles.

#![allow(dead_code)] // each target uses part of it

use libfuzzer_sys::arbitrary::{self, Arbitrary};
use ringsync_wire::crc32;

/// T_cyc of every ring the targets build [ns].
pub const CYCLE_NS: i64 = 1_000_000;

/// The last wire timestamp a node may take (`Instant::HORIZON`, i64::MAX / 4) [ns]; the
/// targets check that nothing stamped later changes a node.
pub const HORIZON_NS: i64 = ringsync_proto::Instant::HORIZON.as_ns();

/// Whether a wire timestamp lies past [`HORIZON_NS`].
pub fn past_horizon(t: u64) -> bool {
    t > HORIZON_NS as u64
}

/// A PDU with the given header fields and payload, CRC filled in.
pub fn pdu(kind: u8, flags: u8, retry: u8, cycle: u32, seq: u16, payload: &[u8]) -> Vec<u8> {
    let len = payload.len().min(usize::from(u16::MAX));
    let mut b = Vec::with_capacity(16 + len);
    b.extend_from_slice(&[1, kind, flags, retry]);
    b.extend_from_slice(&cycle.to_le_bytes());
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&(len as u16).to_le_bytes());
    b.extend_from_slice(&payload[..len]);
    let crc = crc32(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

/// Header flags: the defined bits only (STOP, TORQUE_OFF, BRAKE), unless the fuzzer sets
/// bit 7 (then the raw byte, reserved bits and all).
pub fn flags(b: u8) -> u8 {
    if b & 0x80 != 0 { b } else { b & 0x07 }
}

/// Status bits: the defined ones only, unless bit 15 is set (then the raw value).
pub fn status(s: u16) -> u16 {
    if s & 0x8000 != 0 { s } else { s & 0x00FF }
}

/// A slave address from a fuzzer byte: mostly 0 (invalid), 1..=4 (the ring) or 5 (nobody).
pub fn address(a: u8) -> u16 {
    u16::from(a % 6)
}

/// Header fields of a forged frame.
#[derive(Arbitrary, Debug, Clone, Copy)]
pub struct Head {
    /// Cycle counter.
    pub cycle: CycleSel,
    /// Retry count.
    pub retry: u8,
    /// Flags (see [`flags`]).
    pub flags: u8,
    /// Sequence number.
    pub seq: u16,
}

/// A command frame (kind 2).
pub fn command(h: &Head, ref_cycle: i64, target: u16, value: f32, sample: u64) -> Vec<u8> {
    let mut p = Vec::with_capacity(16);
    p.extend_from_slice(&target.to_le_bytes());
    p.extend_from_slice(&0u16.to_le_bytes());
    p.extend_from_slice(&value.to_le_bytes());
    p.extend_from_slice(&sample.to_le_bytes());
    pdu(
        2,
        flags(h.flags),
        h.retry,
        h.cycle.resolve(ref_cycle),
        h.seq,
        &p,
    )
}

/// The payload fields of a forged response frame (kind 3).
#[derive(Arbitrary, Debug, Clone, Copy)]
pub struct Resp {
    /// Source address (see [`address`]).
    pub source: u8,
    /// Status bits (see [`status`]).
    pub status: u16,
    /// Echo of the answered command's cycle.
    pub echo: CycleSel,
    /// Position [counts].
    pub position: i32,
    /// Velocity [counts/s].
    pub velocity: i32,
    /// Measuring instant.
    pub sample: When,
    /// Applied command [V] (any bits: NaN and infinities too).
    pub applied: f32,
}

/// A response frame (kind 3); times relative to `ref_ns`, cycles to `ref_cycle`.
pub fn response(h: &Head, r: &Resp, ref_cycle: i64, ref_ns: i64) -> Vec<u8> {
    let mut p = Vec::with_capacity(28);
    p.extend_from_slice(&address(r.source).to_le_bytes());
    p.extend_from_slice(&status(r.status).to_le_bytes());
    p.extend_from_slice(&r.echo.resolve(ref_cycle).to_le_bytes());
    p.extend_from_slice(&r.position.to_le_bytes());
    p.extend_from_slice(&r.velocity.to_le_bytes());
    p.extend_from_slice(&r.sample.resolve(ref_ns).to_le_bytes());
    p.extend_from_slice(&r.applied.to_le_bytes());
    pdu(
        3,
        flags(h.flags),
        h.retry,
        h.cycle.resolve(ref_cycle),
        h.seq,
        &p,
    )
}

/// A lumped frame of `kind` (1 or 4) whose payload is the stamp, first slot, declared slot
/// count and the slot bytes as given (which need not match the count).
#[allow(clippy::too_many_arguments)]
pub fn lumped(
    kind: u8,
    flags_byte: u8,
    retry: u8,
    cycle: u32,
    seq: u16,
    stamp: u64,
    first: u16,
    count: u16,
    slots: &[u8],
) -> Vec<u8> {
    let mut p = Vec::with_capacity(12 + slots.len());
    p.extend_from_slice(&stamp.to_le_bytes());
    p.extend_from_slice(&first.to_le_bytes());
    p.extend_from_slice(&count.to_le_bytes());
    p.extend_from_slice(slots);
    pdu(kind, flags(flags_byte), retry, cycle, seq, &p)
}

/// Fields of one feedback slot (kind 1; the first 20 B of a kind-4 slot).
#[derive(Arbitrary, Debug, Clone, Copy)]
pub struct Slot {
    /// Position [counts].
    pub position: i32,
    /// Velocity [counts/s].
    pub velocity: i32,
    /// Sampling instant.
    pub sample: When,
    /// Status bits (see [`status`]).
    pub status: u16,
    /// Written marker: 0 or 1, or any byte when bit 7 is set.
    pub written: u8,
    /// Command applied (kind-4 slots only) [V].
    pub command: f32,
}

impl Slot {
    /// Appends the slot's `len` (20 or 32) bytes, times relative to `ref_ns`.
    pub fn put(&self, ref_ns: i64, len: usize, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.position.to_le_bytes());
        out.extend_from_slice(&self.velocity.to_le_bytes());
        out.extend_from_slice(&self.sample.resolve(ref_ns).to_le_bytes());
        out.extend_from_slice(&status(self.status).to_le_bytes());
        let w = if self.written & 0x80 != 0 {
            self.written
        } else {
            self.written & 1
        };
        out.extend_from_slice(&[w, 0]);
        if len > 20 {
            out.extend_from_slice(&self.position.wrapping_add(7).to_le_bytes());
            out.extend_from_slice(&self.velocity.to_le_bytes());
            out.extend_from_slice(&self.command.to_le_bytes());
        }
    }
}

/// A cycle counter relative to a reference cycle, or any value.
#[derive(Arbitrary, Debug, Clone, Copy)]
pub enum CycleSel {
    /// The reference cycle plus this.
    Rel(i8),
    /// This value.
    Raw(u32),
}

impl CycleSel {
    /// The wire value (the counter wraps at 2^32, as on the wire).
    pub fn resolve(self, reference: i64) -> u32 {
        match self {
            CycleSel::Rel(d) => reference.wrapping_add(i64::from(d)) as u32,
            CycleSel::Raw(v) => v,
        }
    }
}

/// A timestamp relative to a reference time, or any value.
#[derive(Arbitrary, Debug, Clone, Copy)]
pub enum When {
    /// (reference cycle + `dc`)·T_cyc + `frac` mod T_cyc.
    Cycle {
        /// Cycles from the reference time's cycle.
        dc: i8,
        /// Offset into that cycle [ns] (mod T_cyc).
        frac: u32,
    },
    /// The reference time plus this [ns].
    Near(i32),
    /// This value [ns] (anything up to the end of the u64 time line).
    Raw(u64),
    /// The end of the time line a node takes from the wire ([`HORIZON_NS`]) plus this [ns]:
    /// both sides of the edge.
    Horizon(i16),
}

impl When {
    /// The wire value for the reference time `reference` [ns] (clamped at 0).
    pub fn resolve(self, reference: i64) -> u64 {
        let t = match self {
            When::Cycle { dc, frac } => reference
                .div_euclid(CYCLE_NS)
                .saturating_add(i64::from(dc))
                .saturating_mul(CYCLE_NS)
                .saturating_add(i64::from(frac) % CYCLE_NS),
            When::Near(d) => reference.saturating_add(i64::from(d)),
            When::Raw(v) => return v,
            When::Horizon(d) => HORIZON_NS.saturating_add(i64::from(d)),
        };
        t.max(0) as u64
    }
}

/// `u` clipped to ±`limit`, as the slave clips a command.
pub fn clip(u: f64, limit: f64) -> f64 {
    u.clamp(-limit, limit)
}

/// Whether to print every decoded operation (`RINGSYNC_FUZZ_TRACE=1`, for reading a crash).
pub fn tracing() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var_os("RINGSYNC_FUZZ_TRACE").is_some())
}

/// The wire timestamp a node reads from `bytes` (a lumped frame's send stamp, a command's
/// or a response's sampling instant), if the header and that field are there.
pub fn wire_time(bytes: &[u8]) -> Option<u64> {
    let at = match bytes.get(1)? {
        1 | 4 => 12,
        2 => 20,
        3 => 28,
        _ => return None,
    };
    Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
}
