//! The one-line text form of frames, PDUs, flags and status bits (docs/wire.md, "Text
//! form"). Logs, the live scope and the Wireshark dissector's tests compare these strings:
//! change them only together with the document.

use core::fmt;

use crate::{CommandRepr, Common, Flags, Frame, FrameKind, Pdu, ResponseRepr, Status};

/// Names of the header flags, in bit order.
const FLAG_NAMES: [(Flags, &str); 3] = [
    (Flags::STOP, "STOP"),
    (Flags::TORQUE_OFF, "TORQUE_OFF"),
    (Flags::BRAKE, "BRAKE"),
];

/// Names of the status bits, in bit order.
const STATUS_NAMES: [(Status, &str); 8] = [
    (Status::FAULT, "FAULT"),
    (Status::SATURATED, "SATURATED"),
    (Status::WATCHDOG, "WATCHDOG"),
    (Status::CLOCK_UNLOCKED, "CLOCK_UNLOCKED"),
    (Status::FOLLOWING_ERROR, "FOLLOWING_ERROR"),
    (Status::STOPPING, "STOPPING"),
    (Status::TORQUE_OFF, "TORQUE_OFF"),
    (Status::BRAKING, "BRAKING"),
];

/// Writes the names of the set bits joined by `|`, or `-` when none is set.
fn bit_names<'a>(f: &mut fmt::Formatter<'_>, set: impl Iterator<Item = &'a str>) -> fmt::Result {
    let mut any = false;
    for name in set {
        if any {
            f.write_str("|")?;
        }
        f.write_str(name)?;
        any = true;
    }
    if !any {
        f.write_str("-")?;
    }
    Ok(())
}

impl fmt::Display for FrameKind {
    /// The kind's [`name`](FrameKind::name): `lumped`, `command`, `response`, `lumped-only`,
    /// `delay`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl fmt::Display for Flags {
    /// The names of the set flags in bit order joined by `|` (`STOP|TORQUE_OFF`), or `-`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let set = FLAG_NAMES.iter().filter(|(b, _)| self.contains(*b));
        bit_names(f, set.map(|(_, name)| *name))
    }
}

impl fmt::Display for Status {
    /// The names of the set bits in bit order joined by `|` (`FAULT|SATURATED`), or `-`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let set = STATUS_NAMES.iter().filter(|(b, _)| self.contains(*b));
        bit_names(f, set.map(|(_, name)| *name))
    }
}

/// What the text form of a valid PDU shows, from a [`Frame`] or a [`Pdu`] alike.
enum Summary {
    Lumped {
        kind: FrameKind,
        common: Common,
        first_slot: u16,
        slot_count: usize,
        master_time_ns: u64,
    },
    Command(CommandRepr),
    Response(ResponseRepr),
}

impl Summary {
    fn of_pdu(pdu: &Pdu) -> Self {
        match pdu {
            Pdu::Lumped(l) => Summary::Lumped {
                kind: FrameKind::Lumped,
                common: l.common,
                first_slot: l.first_slot,
                slot_count: l.slots.len(),
                master_time_ns: l.master_time_ns,
            },
            Pdu::LumpedOnly(l) => Summary::Lumped {
                kind: FrameKind::LumpedOnly,
                common: l.common,
                first_slot: l.first_slot,
                slot_count: l.slots.len(),
                master_time_ns: l.master_time_ns,
            },
            Pdu::Delay(l) => Summary::Lumped {
                kind: FrameKind::Delay,
                common: l.common,
                first_slot: l.first_slot,
                slot_count: l.slots.len(),
                master_time_ns: l.master_time_ns,
            },
            Pdu::Command(c) => Summary::Command(*c),
            Pdu::Response(r) => Summary::Response(*r),
        }
    }

    /// Validates the frame as [`Pdu::parse`] does, without allocating.
    fn of_frame<T: AsRef<[u8]>>(frame: &Frame<T>) -> crate::Result<Self> {
        Ok(match frame.validate()? {
            kind @ (FrameKind::Lumped | FrameKind::LumpedOnly | FrameKind::Delay) => {
                let p = frame.lumped()?;
                Summary::Lumped {
                    kind,
                    common: frame.common(),
                    first_slot: p.first_slot(),
                    slot_count: usize::from(p.slot_count()),
                    master_time_ns: p.master_time_ns(),
                }
            }
            FrameKind::Command => Summary::Command(CommandRepr::parse_verified(frame.as_ref())?),
            FrameKind::Response => Summary::Response(ResponseRepr::parse_verified(frame.as_ref())?),
        })
    }
}

/// `{kind} cycle {cycle} seq {seq}`, then ` retry {retry}` unless 0 and ` flags {flags}`
/// unless empty.
fn head(f: &mut fmt::Formatter<'_>, kind: FrameKind, c: &Common) -> fmt::Result {
    write!(f, "{kind} cycle {} seq {}", c.cycle, c.seq)?;
    if c.retry != 0 {
        write!(f, " retry {}", c.retry)?;
    }
    if !c.flags.is_empty() {
        write!(f, " flags {}", c.flags)?;
    }
    Ok(())
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Summary::Lumped {
                kind,
                common,
                first_slot,
                slot_count,
                master_time_ns,
            } => {
                head(f, *kind, common)?;
                let end = usize::from(*first_slot) + slot_count;
                write!(
                    f,
                    ", slots {first_slot}..{end}, sent at {master_time_ns} ns"
                )
            }
            Summary::Command(c) => {
                head(f, FrameKind::Command, &c.common)?;
                write!(
                    f,
                    " → slave {}: {:.3} V, sampled at {} ns",
                    c.target, c.command_v, c.sample_time_ns
                )?;
                if c.link_ns != 0 {
                    write!(f, ", link {} ns", c.link_ns)?;
                }
                Ok(())
            }
            Summary::Response(r) => {
                head(f, FrameKind::Response, &r.common)?;
                write!(
                    f,
                    " from slave {}: status {}, echo cycle {}, position {} counts, \
                     velocity {} counts/s, sampled at {} ns, applied {:.3} V",
                    r.source,
                    r.status,
                    r.echo_cycle,
                    r.position,
                    r.velocity,
                    r.sample_time_ns,
                    r.applied_v
                )
            }
        }
    }
}

impl<T: AsRef<[u8]>> fmt::Display for Frame<T> {
    /// One line, the same as the [`Pdu`] it parses to, for example
    ///
    /// ```text
    /// lumped cycle 9 seq 1, slots 0..2, sent at 123456789 ns
    /// command cycle 7 seq 3 retry 1 flags STOP → slave 2: -1.250 V, sampled at 1000000 ns
    /// ```
    ///
    /// or `bad frame ({error})` when [`Frame::validate`] fails (the error's own text).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match Summary::of_frame(self) {
            Ok(s) => s.fmt(f),
            Err(e) => write!(f, "bad frame ({e})"),
        }
    }
}

impl fmt::Display for Pdu {
    /// One line: `{kind} cycle {cycle} seq {seq}` (then ` retry {r}` unless 0, ` flags
    /// {flags}` unless empty), then per kind
    ///
    /// - lumped, lumped-only: `, slots {f}..{f+m}, sent at {t} ns`
    /// - command: ` → slave {target}: {command:.3} V, sampled at {t} ns`
    /// - response: ` from slave {source}: status {status}, echo cycle {c}, position {p}
    ///   counts, velocity {v} counts/s, sampled at {t} ns, applied {u:.3} V`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        Summary::of_pdu(self).fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_defined_bit_has_one_name() {
        let flags = FLAG_NAMES.iter().fold(0, |acc, (b, _)| acc | b.bits());
        assert_eq!(flags, Flags::DEFINED);
        let status = STATUS_NAMES.iter().fold(0, |acc, (b, _)| acc | b.bits());
        assert_eq!(status, Status::DEFINED);
        assert!(STATUS_NAMES.iter().all(|(b, _)| b.bits().count_ones() == 1));
    }
}
