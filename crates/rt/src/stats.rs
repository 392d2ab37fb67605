//! Percentiles of measured delays.

/// Percentiles of a sample of durations [ns] (nearest rank).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Percentiles {
    /// Number of values.
    pub count: usize,
    /// Median [ns].
    pub p50: i64,
    /// 99th percentile [ns].
    pub p99: i64,
    /// 99.9th percentile [ns].
    pub p999: i64,
    /// Largest [ns].
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

#[cfg(test)]
mod tests {
    use super::*;

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
