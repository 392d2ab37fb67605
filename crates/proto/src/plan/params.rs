//! Inputs of the cycle plan and their validation.

use ringsync_wire::{FeedbackSlot, LumpedOnlySlot, SlotCodec, ethernet::MTU};
use serde::Serialize;

use super::link::Link;
use crate::time::Duration;

/// Everything the cycle plan depends on (docs/system.md, "The cycle plan"). Defaults are the reference
/// scenario `paper-2015` (docs/system.md, "The reference scenario").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RingParams {
    /// Number of slaves n on the ring (1..=65535).
    pub slaves: u32,
    /// Link bit rate [bit/s].
    pub bit_rate_bps: u64,
    /// PHY receive latency \[ns\] (MII, DP83848 family: 240 ns).
    pub phy_rx: Duration,
    /// PHY transmit latency \[ns\] (MII: about 60 ns).
    pub phy_tx: Duration,
    /// Cable length of each hop \[m\].
    pub cable_m: f64,
    /// Signal propagation in the cable [ns/m] (about 5 ns/m).
    pub propagation_ns_per_m: f64,
    /// Residence time T_t of a slave that forwards a frame, first bit in to first bit out
    /// \[ns\] (cut-through).
    pub residence: Duration,
    /// Response delay T_ti of a slave, last bit of its command in to first bit of its
    /// response out \[ns\].
    pub response_delay: Duration,
    /// Reserve T_rest between the sync phase and the P2P phase (master computes) \[ns\].
    pub t_rest: Duration,
    /// Cycle time T_cyc \[ns\].
    pub t_cyc: Duration,
    /// Bytes per slave in the proposed plan's lumped frame \[B\] (wire format: 20).
    pub slot_bytes: usize,
    /// Bytes per slave in the lumped-only plan's frame \[B\] (wire format: 32).
    pub lumped_only_slot_bytes: usize,
    /// Largest Ethernet payload \[B\] (standard: 1500).
    pub mtu: usize,
}

impl Default for RingParams {
    fn default() -> Self {
        RingParams {
            slaves: 4,
            bit_rate_bps: 100_000_000,
            phy_rx: Duration::from_ns(240),
            phy_tx: Duration::from_ns(60),
            cable_m: 2.0,
            propagation_ns_per_m: 5.0,
            residence: Duration::from_us(1),
            response_delay: Duration::from_us(2),
            t_rest: Duration::from_us(100),
            t_cyc: Duration::from_ms(1),
            slot_bytes: FeedbackSlot::LEN,
            lumped_only_slot_bytes: LumpedOnlySlot::LEN,
            mtu: MTU,
        }
    }
}

/// A parameter out of its range, or a plan that does not fit its cycle.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A parameter outside its allowed range. `field` is the parameter's name as in
    /// [`RingParams`] (the CLI option is `--` plus the name with `-` for `_`).
    #[error("{field} = {value} is out of range: allowed {allowed}")]
    OutOfRange {
        /// Parameter name.
        field: &'static str,
        /// The value given, as text.
        value: String,
        /// The allowed range, as text with units.
        allowed: &'static str,
    },
    /// The cycle is shorter than the plan needs.
    #[error(
        "t_cyc = {t_cyc} is too short for {slaves} slaves: the plan needs {needed} ({basis}), short by {short}"
    )]
    CycleTooShort {
        /// Number of slaves.
        slaves: u32,
        /// Cycle time given.
        t_cyc: Duration,
        /// Shortest cycle that fits.
        needed: Duration,
        /// Shortfall.
        short: Duration,
        /// Which figure decided: "eq. 1" or "event level".
        basis: &'static str,
    },
}

/// `x` for a message: as written up to a billion, in scientific notation beyond (or below a
/// thousandth), so that 1e300 does not print 300 digits.
pub fn short_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-3..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Largest value of any time parameter [ns]: 10 s.
const MAX_SPAN_NS: i64 = 10_000_000_000;

fn span(
    field: &'static str,
    d: Duration,
    allowed: &'static str,
    min: i64,
) -> Result<(), PlanError> {
    if d.as_ns() < min || d.as_ns() > MAX_SPAN_NS {
        Err(PlanError::OutOfRange {
            field,
            value: d.to_string(),
            allowed,
        })
    } else {
        Ok(())
    }
}

impl RingParams {
    /// Checks every parameter against its range; the error names the first bad one.
    pub fn validate(&self) -> Result<(), PlanError> {
        if !(1..=65_535).contains(&self.slaves) {
            return Err(PlanError::OutOfRange {
                field: "slaves",
                value: self.slaves.to_string(),
                allowed: "1..=65535",
            });
        }
        if !(1_000..=400_000_000_000).contains(&self.bit_rate_bps) {
            return Err(PlanError::OutOfRange {
                field: "bit_rate",
                value: format!("{} bit/s", self.bit_rate_bps),
                allowed: "1 kbit/s ..= 400 Gbit/s",
            });
        }
        span("phy_rx", self.phy_rx, "0 ..= 10 s", 0)?;
        span("phy_tx", self.phy_tx, "0 ..= 10 s", 0)?;
        span("residence", self.residence, "0 ..= 10 s", 0)?;
        span("response_delay", self.response_delay, "0 ..= 10 s", 0)?;
        span("t_rest", self.t_rest, "0 ..= 10 s", 0)?;
        span("t_cyc", self.t_cyc, "1 ns ..= 10 s", 1)?;
        if !(self.cable_m.is_finite() && (0.0..=100_000.0).contains(&self.cable_m)) {
            return Err(PlanError::OutOfRange {
                field: "cable_m",
                value: format!("{} m", short_number(self.cable_m)),
                allowed: "0 ..= 100000 m",
            });
        }
        if !(self.propagation_ns_per_m.is_finite()
            && (0.0..=1_000.0).contains(&self.propagation_ns_per_m))
        {
            return Err(PlanError::OutOfRange {
                field: "propagation_ns_per_m",
                value: format!("{} ns/m", short_number(self.propagation_ns_per_m)),
                allowed: "0 ..= 1000 ns/m",
            });
        }
        if !(46..=9_000).contains(&self.mtu) {
            return Err(PlanError::OutOfRange {
                field: "mtu",
                value: format!("{} B", self.mtu),
                allowed: "46 ..= 9000 B",
            });
        }
        let max_slot = self.slot_room();
        for (field, v) in [
            ("slot_bytes", self.slot_bytes),
            ("lumped_only_slot_bytes", self.lumped_only_slot_bytes),
        ] {
            if v == 0 || v > max_slot {
                return Err(PlanError::OutOfRange {
                    field,
                    value: format!("{v} B"),
                    allowed: "1 B ..= MTU - 28 B (one slot must fit one frame)",
                });
            }
        }
        Ok(())
    }

    /// Bytes of one lumped frame's payload available for slots [B].
    pub(crate) fn slot_room(&self) -> usize {
        self.mtu
            .saturating_sub(ringsync_wire::HEADER_LEN + ringsync_wire::CRC_LEN)
            .saturating_sub(ringsync_wire::lumped::LUMPED_PREFIX_LEN)
    }

    /// The link these parameters describe; the cable delay is rounded to the nearest ns.
    pub fn link(&self) -> Link {
        Link {
            bit_rate_bps: self.bit_rate_bps,
            phy_tx: self.phy_tx,
            phy_rx: self.phy_rx,
            cable: Duration::from_ns((self.cable_m * self.propagation_ns_per_m).round() as i64),
        }
    }
}
