//! The scope's own cost to the loop, measured within one run (`ringsync rt --scope ADDR
//! --scope-ab PERIOD`): the observer feeds the pages in alternate periods of the run and
//! stays idle in the others, and sorts each cycle-start lateness the driver reports into the
//! histogram of its period's kind. Host noise that comes and goes over seconds or minutes
//! (on a virtual machine it moves a 30 s run's lateness p99 from 4 µs to 3 ms) falls on both
//! kinds alike, where two separate runs each get their own.
//!
//! A cycle's lateness is the driver's wake-up at the cycle start, so it shows what the scope
//! costs through the other threads (its server, the pages' rendering) and through a cycle
//! that the feed made overrun; a cycle counts to the kind of the period it starts in.

/// Lateness histogram bins: 50 ns wide up to 50 µs, then 1 µs wide up to 10 ms, then one
/// bin for everything later.
const FINE_NS: i64 = 50;
const FINE_BINS: usize = 1_000;
const COARSE_NS: i64 = 1_000;
const COARSE_BINS: usize = 9_950;

/// A histogram of cycle-start lateness, allocated once (adding never allocates).
#[derive(Debug, Clone)]
pub struct Lateness {
    counts: Vec<u32>,
    total: u64,
}

impl Default for Lateness {
    fn default() -> Self {
        Lateness {
            counts: vec![0; FINE_BINS + COARSE_BINS + 1],
            total: 0,
        }
    }
}

impl Lateness {
    /// Adds one lateness \[ns\] (negative: early, counted as 0).
    pub fn add(&mut self, ns: i64) {
        let ns = ns.max(0);
        let fine_end = FINE_NS * FINE_BINS as i64;
        let bin = if ns < fine_end {
            (ns / FINE_NS) as usize
        } else {
            (FINE_BINS + ((ns - fine_end) / COARSE_NS) as usize).min(FINE_BINS + COARSE_BINS)
        };
        self.counts[bin] = self.counts[bin].saturating_add(1);
        self.total += 1;
    }

    /// Cycles counted.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// The q-quantile (0 ≤ q ≤ 1) \[µs\]: the middle of the bin it falls in (within 25 ns up
    /// to 50 µs, 0.5 µs up to 10 ms; 10 ms for anything later). `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.total == 0 {
            return None;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0u64;
        for (bin, c) in self.counts.iter().enumerate() {
            seen += u64::from(*c);
            if seen >= rank {
                let ns = if bin < FINE_BINS {
                    (bin as f64 + 0.5) * FINE_NS as f64
                } else if bin < FINE_BINS + COARSE_BINS {
                    (FINE_NS * FINE_BINS as i64) as f64
                        + ((bin - FINE_BINS) as f64 + 0.5) * COARSE_NS as f64
                } else {
                    (FINE_NS * FINE_BINS as i64 + COARSE_NS * COARSE_BINS as i64) as f64
                };
                return Some(ns * 1e-3);
            }
        }
        None
    }
}

/// What an alternating run measured.
#[derive(Debug, Clone, Default)]
pub struct AbReport {
    /// Cycles per period.
    pub period_cycles: i64,
    /// Lateness of the cycles that started while the scope fed its pages.
    pub fed: Lateness,
    /// Lateness of the cycles that started while it stayed idle.
    pub idle: Lateness,
}

impl AbReport {
    /// Whether cycle `k` falls in a fed period (the first period feeds).
    pub fn feeds(&self, k: i64) -> bool {
        self.period_cycles <= 0 || (k.max(0) / self.period_cycles) % 2 == 0
    }

    /// One line: p50, p99 and p99.9 of each kind and the p99's difference.
    pub fn text(&self) -> String {
        let q = |h: &Lateness, q: f64| h.quantile(q).map_or("-".into(), |v| format!("{v:.2}"));
        let diff = match (self.fed.quantile(0.99), self.idle.quantile(0.99)) {
            (Some(f), Some(i)) if i > 0.0 => format!("{:+.1} %", 100.0 * (f - i) / i),
            _ => "-".into(),
        };
        format!(
            "scope A/B over periods of {} cycles: cycle-start lateness p50/p99/p99.9 fed {}/{}/{} µs ({} cycles), idle {}/{}/{} µs ({} cycles); p99 fed vs idle {diff}",
            self.period_cycles,
            q(&self.fed, 0.5),
            q(&self.fed, 0.99),
            q(&self.fed, 0.999),
            self.fed.count(),
            q(&self.idle, 0.5),
            q(&self.idle, 0.99),
            q(&self.idle, 0.999),
            self.idle.count()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_fall_in_their_bins() {
        let mut h = Lateness::default();
        assert_eq!(h.quantile(0.99), None);
        for i in 0..1000 {
            h.add(i * 10); // 0 .. 9.99 µs evenly
        }
        h.add(-5);
        h.add(20_000_000); // 20 ms: the last bin
        let p50 = h.quantile(0.5).expect("p50");
        assert!((p50 - 5.0).abs() <= 0.05, "{p50}");
        let p99 = h.quantile(0.99).expect("p99");
        assert!((p99 - 9.9).abs() <= 0.05, "{p99}");
        assert_eq!(h.quantile(1.0), Some(10_000.0));
        assert_eq!(h.count(), 1002);
        h.add(120_300); // 120.3 µs: a 1 µs bin
        let mut g = Lateness::default();
        g.add(120_300);
        assert_eq!(g.quantile(0.5), Some(120.5));
    }

    #[test]
    fn periods_alternate_from_fed() {
        let r = AbReport {
            period_cycles: 3,
            ..AbReport::default()
        };
        let kinds: Vec<bool> = (0..9).map(|k| r.feeds(k)).collect();
        assert_eq!(
            kinds,
            [true, true, true, false, false, false, true, true, true]
        );
    }
}
