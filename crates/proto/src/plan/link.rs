//! Wire-time arithmetic of one link (docs/system.md, "Wire facts"): how long bytes
//! take at a bit rate, and the first-bit latency of one hop.

use ringsync_wire::ethernet::{IFG_LEN, wire_len};
use serde::Serialize;

use crate::time::Duration;

/// One full-duplex link of the ring, the same for every hop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Link {
    /// Bit rate [bit/s].
    pub bit_rate_bps: u64,
    /// PHY transmit latency, MAC to medium \[ns\].
    pub phy_tx: Duration,
    /// PHY receive latency, medium to MAC \[ns\].
    pub phy_rx: Duration,
    /// Cable propagation delay of one hop \[ns\].
    pub cable: Duration,
}

impl Link {
    /// Time to put `bytes` on the wire, rounded up to a whole nanosecond \[ns\].
    pub fn bytes_time(&self, bytes: usize) -> Duration {
        let bits = bytes as u128 * 8 * 1_000_000_000;
        let bps = u128::from(self.bit_rate_bps.max(1));
        let ns = bits.div_ceil(bps);
        Duration::from_ns(i64::try_from(ns).unwrap_or(i64::MAX))
    }

    /// Wire time of one Ethernet frame whose payload (the ringsync PDU) is `pdu_len` bytes:
    /// preamble + SFD + max(64, 18 + payload) bytes, without the inter-frame gap \[ns\].
    pub fn frame_time(&self, pdu_len: usize) -> Duration {
        self.bytes_time(wire_len(pdu_len))
    }

    /// The inter-frame gap, 12 byte times \[ns\] (0.96 µs at 100 Mbit/s).
    pub fn gap(&self) -> Duration {
        self.bytes_time(IFG_LEN)
    }

    /// First-bit latency of one hop: PHY transmit + cable + PHY receive \[ns\].
    pub fn hop(&self) -> Duration {
        self.phy_tx + self.cable + self.phy_rx
    }
}

/// Parses a bit rate: a number with an optional decimal prefix k, M or G and an optional
/// `bps` or `bit/s`, e.g. `100M`, `100Mbps`, `1G`, `2.5Gbit/s`, `100000000`. Returns
/// bit/s, or a message that says what is wrong.
pub fn parse_bit_rate(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let body = t
        .strip_suffix("bit/s")
        .or_else(|| t.strip_suffix("bps"))
        .unwrap_or(t)
        .trim_end();
    let (num, scale) = match body.chars().last() {
        Some('k') => (&body[..body.len() - 1], 1_000),
        Some('M') => (&body[..body.len() - 1], 1_000_000),
        Some('G') => (&body[..body.len() - 1], 1_000_000_000),
        _ => (body, 1),
    };
    match crate::time::parse_decimal_scaled(num.trim(), scale) {
        None => Err(format!(
            "'{s}' is not a bit rate: write e.g. 100M, 100Mbps or 1G"
        )),
        Some(None) => Err(format!("'{s}' is not a whole number of bit/s")),
        Some(Some(v)) => u64::try_from(v).map_err(|_| {
            if v < 0 {
                format!("'{s}' is negative: a bit rate must be > 0")
            } else {
                format!("'{s}' is too large")
            }
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_rates_parse() {
        assert_eq!(parse_bit_rate("100M"), Ok(100_000_000));
        assert_eq!(parse_bit_rate("100Mbps"), Ok(100_000_000));
        assert_eq!(parse_bit_rate("2.5Gbit/s"), Ok(2_500_000_000));
        assert_eq!(parse_bit_rate("10000000"), Ok(10_000_000));
        assert_eq!(parse_bit_rate("0"), Ok(0));
        assert!(parse_bit_rate("-5M").expect_err("neg").contains("negative"));
        assert!(parse_bit_rate("fast").is_err());
        assert!(parse_bit_rate("1.5").is_err());
    }

    fn fast_ethernet() -> Link {
        Link {
            bit_rate_bps: 100_000_000,
            phy_tx: Duration::from_ns(60),
            phy_rx: Duration::from_ns(240),
            cable: Duration::from_ns(10),
        }
    }

    #[test]
    fn byte_and_bit_times_at_100_mbit() {
        let l = fast_ethernet();
        // 10 ns per bit, 80 ns per byte.
        assert_eq!(l.bytes_time(1), Duration::from_ns(80));
        // The gap is 12 bytes = 96 bit times = 0.96 µs.
        assert_eq!(l.gap(), Duration::from_ns(960));
    }

    #[test]
    fn minimum_frame_is_padded() {
        let l = fast_ethernet();
        // An empty payload still makes a 64-byte frame, plus 8 bytes of preamble + SFD:
        // 72 bytes * 80 ns = 5.76 µs.
        assert_eq!(l.frame_time(0), Duration::from_ns(5_760));
        // 46 bytes of payload is exactly the minimum: 14 + 46 + 4 = 64.
        assert_eq!(l.frame_time(46), Duration::from_ns(5_760));
        // One more byte lengthens the frame: (8 + 65) * 80 ns.
        assert_eq!(l.frame_time(47), Duration::from_ns(5_840));
        // A full 1500-byte payload: (8 + 1518) * 80 ns = 122.08 µs.
        assert_eq!(l.frame_time(1500), Duration::from_ns(122_080));
    }

    #[test]
    fn other_bit_rates_round_up() {
        let gig = Link {
            bit_rate_bps: 1_000_000_000,
            ..fast_ethernet()
        };
        assert_eq!(gig.frame_time(0), Duration::from_ns(576));
        // 3 Mbit/s: one byte takes 2666.67 ns, rounded up.
        let odd = Link {
            bit_rate_bps: 3_000_000,
            ..fast_ethernet()
        };
        assert_eq!(odd.bytes_time(1), Duration::from_ns(2_667));
    }

    #[test]
    fn hop_latency_is_tx_cable_rx() {
        assert_eq!(fast_ethernet().hop(), Duration::from_ns(310));
    }
}
