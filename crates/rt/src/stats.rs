//! Percentiles of measured delays: of a sample held whole ([`Percentiles::of`], for the
//! start-up measurements), or of a [`Delays`] histogram, which takes a whole run in fixed
//! memory.

use hdrhistogram::Histogram;

/// Percentiles of a sample of durations \[ns\] (nearest rank).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct Percentiles {
    /// Number of values.
    pub count: usize,
    /// Median \[ns\].
    pub p50: i64,
    /// 99th percentile \[ns\].
    pub p99: i64,
    /// 99.9th percentile \[ns\].
    pub p999: i64,
    /// Largest \[ns\].
    pub max: i64,
}

impl Percentiles {
    /// The percentiles of `values` (all zero when empty).
    pub fn of(values: &[i64]) -> Percentiles {
        if values.is_empty() {
            return Percentiles::default();
        }
        let mut v = values.to_vec();
        v.sort_unstable();
        let rank = |q: f64| {
            let r = (q * v.len() as f64).ceil() as usize;
            v[r.clamp(1, v.len()) - 1]
        };
        Percentiles {
            count: v.len(),
            p50: rank(0.5),
            p99: rank(0.99),
            p999: rank(0.999),
            max: v[v.len() - 1],
        }
    }
}

/// The largest delay a [`Delays`] histogram tells apart: one minute [ns]; longer ones count
/// as this (their exact maximum is kept).
const DELAYS_MAX_NS: u64 = 60_000_000_000;

/// A run's delays \[ns\] as a histogram (HdrHistogram, 3 significant digits: exact below
/// 2.048 µs, within 0.1 % above), allocated once: recording never allocates, so a run of
/// any length takes the same memory. The count and the maximum are exact.
#[derive(Debug, Clone)]
pub struct Delays {
    hist: Histogram<u64>,
    max: i64,
}

impl Default for Delays {
    fn default() -> Self {
        Delays {
            // Bounds that are valid by construction: 1 ≤ low, high ≥ 2·low, 3 digits.
            hist: Histogram::new_with_bounds(1, DELAYS_MAX_NS, 3)
                .unwrap_or_else(|_| Histogram::new(3).unwrap_or_else(|_| unreachable!())),
            max: 0,
        }
    }
}

impl Delays {
    /// Records one delay \[ns\] (a negative one as 0).
    pub fn record(&mut self, ns: i64) {
        let v = ns.max(0);
        self.max = if self.hist.is_empty() {
            v
        } else {
            self.max.max(v)
        };
        self.hist.saturating_record(v as u64);
    }

    /// Delays recorded.
    pub fn count(&self) -> usize {
        self.hist.len() as usize
    }

    /// Their percentiles (nearest rank, within the histogram's precision; all zero when
    /// none was recorded).
    pub fn percentiles(&self) -> Percentiles {
        if self.hist.is_empty() {
            return Percentiles::default();
        }
        // A bucket's highest equivalent value, never above the true maximum.
        let at = |q: f64| (self.hist.value_at_quantile(q) as i64).min(self.max);
        Percentiles {
            count: self.count(),
            p50: at(0.5),
            p99: at(0.99),
            p999: at(0.999),
            max: self.max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram's percentiles against the exact ones: equal below 2.048 µs, within
    /// 0.1 % above; count and maximum exact; negatives count as 0.
    #[test]
    fn histogram_percentiles_match_the_sorted_sample() {
        let mut r = 0x2545_f491_4f6c_dd1du64;
        let mut v = Vec::new();
        let mut d = Delays::default();
        for k in 0..100_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            // Mostly microseconds, now and then milliseconds.
            let ns = if k % 97 == 0 {
                (r % 5_000_000) as i64
            } else {
                (r % 20_000) as i64
            };
            v.push(ns);
            d.record(ns);
        }
        let (e, h) = (Percentiles::of(&v), d.percentiles());
        assert_eq!((h.count, h.max), (e.count, e.max));
        for (a, b) in [(h.p50, e.p50), (h.p99, e.p99), (h.p999, e.p999)] {
            assert!((a - b).abs() as f64 <= 0.001 * b as f64 + 1.0, "{a} vs {b}");
        }
        let mut small = Delays::default();
        for ns in [-5, 0, 7, 2_000] {
            small.record(ns);
        }
        assert_eq!(small.percentiles(), Percentiles::of(&[0, 0, 7, 2_000]));
        assert_eq!(Delays::default().percentiles(), Percentiles::default());
    }

    #[test]
    fn nearest_rank_percentiles() {
        let v: Vec<i64> = (1..=1000).rev().collect();
        let p = Percentiles::of(&v);
        assert_eq!(
            (p.count, p.p50, p.p99, p.p999, p.max),
            (1000, 500, 990, 999, 1000)
        );
        assert_eq!(Percentiles::of(&[]), Percentiles::default());
        assert_eq!(Percentiles::of(&[7]).p999, 7);
    }
}
