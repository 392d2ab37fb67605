//! A slave's synchronised clock (SYSTEM.md section 2, IEEE 1588 style, one-way): the master
//! stamps the lumped frame with its send time M; every residence and link delay is fixed and
//! configured, so the master time at which the frame reaches slave i is M + D_i. Each sync
//! gives one pair (local receive timestamp L_k, master time M_k + D_i).
//!
//! The servo steps its offset to each new pair and estimates the rate of the local
//! oscillator against the master's from successive pairs, low-pass filtered:
//!
//! ```text
//! S(L) = M_k + (L − L_k) / ρ̂          ρ̂ ← ρ̂ + g·((L_k − L_{k−1}) / (M_k − M_{k−1}) − ρ̂)
//! ```
//!
//! With exact timestamps and a constant drift the residual error is a few timestamp ticks
//! between syncs (tested). Without sync the clock free-runs: S(L) = L.

use crate::time::{Duration, Instant};

/// Gain of the rate filter (per sync); 1/8 settles within a few tens of cycles.
const RATE_GAIN: f64 = 0.125;

/// How the servo treats each new sync pair. The default (gain 1, rate gain 1/8, no outlier
/// limit) suits exact timestamps (hardware, the simulator). With software timestamps, which
/// jitter by microseconds and now and then by milliseconds, a smaller offset gain averages
/// the jitter and an outlier limit skips the pairs of frames that were read late.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockFilter {
    /// Share of each sync's offset error applied (0 < g ≤ 1; 1 steps to the pair).
    pub offset_gain: f64,
    /// Gain of the rate filter per sync (0 < g ≤ 1).
    pub rate_gain: f64,
    /// Once locked, a pair whose offset error exceeds this is skipped (at most 3 in a row,
    /// then the servo steps). `None`: no limit.
    pub outlier_limit: Option<Duration>,
}

impl Default for ClockFilter {
    fn default() -> Self {
        ClockFilter {
            offset_gain: 1.0,
            rate_gain: RATE_GAIN,
            outlier_limit: None,
        }
    }
}

/// The synchronised clock of one slave.
#[derive(Debug, Clone, PartialEq)]
pub struct SyncClock {
    enabled: bool,
    /// Last sync: (local L_k, master M_k) [ns].
    last: Option<(i64, i64)>,
    /// Last raw pair, for the rate estimate.
    raw: Option<(i64, i64)>,
    /// ρ̂: local ns per master ns.
    rate: f64,
    syncs: u64,
    filter: ClockFilter,
    /// Pairs skipped in a row, and in all.
    skipped_run: u32,
    skipped: u64,
}

impl SyncClock {
    /// A clock that synchronises (`enabled`) or free-runs.
    pub fn new(enabled: bool) -> Self {
        SyncClock {
            enabled,
            last: None,
            raw: None,
            rate: 1.0,
            syncs: 0,
            filter: ClockFilter::default(),
            skipped_run: 0,
            skipped: 0,
        }
    }

    /// Sets the servo's filter (gains outside (0, 1] are clamped into it).
    pub fn set_filter(&mut self, f: ClockFilter) {
        self.filter = ClockFilter {
            offset_gain: f.offset_gain.clamp(1e-3, 1.0),
            rate_gain: f.rate_gain.clamp(1e-6, 1.0),
            outlier_limit: f.outlier_limit,
        };
    }

    /// Sync pairs skipped as outliers.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Takes one sync: the frame was received at local time `local` and left the master at
    /// master time `master_sent`, `path` before it reached this slave.
    pub fn sync(&mut self, local: Instant, master_sent: Instant, path: Duration) {
        if !self.enabled {
            return;
        }
        let (l, m) = (local.as_ns(), (master_sent + path).as_ns());
        let mut anchor = m;
        if self.syncs >= 2 && self.last.is_some() {
            let err = m - self.to_sync(local).as_ns();
            if let Some(limit) = self.filter.outlier_limit
                && err.abs() > limit.as_ns()
                && self.skipped_run < 3
            {
                self.skipped_run += 1;
                self.skipped += 1;
                return;
            }
            if self.filter.offset_gain < 1.0 {
                anchor = m - err + (self.filter.offset_gain * err as f64).round() as i64;
            }
        }
        self.skipped_run = 0;
        if let Some((l0, m0)) = self.raw
            && m > m0
            && l > l0
        {
            let measured = (l - l0) as f64 / (m - m0) as f64;
            self.rate += self.filter.rate_gain * (measured - self.rate);
        }
        self.raw = Some((l, m));
        self.last = Some((l, anchor));
        self.syncs += 1;
    }

    /// Whether at least one sync has been taken (or the clock free-runs by design).
    pub fn is_locked(&self) -> bool {
        !self.enabled || self.syncs >= 2
    }

    /// The synchronised time S(L) for local time `local`.
    pub fn to_sync(&self, local: Instant) -> Instant {
        match self.last {
            Some((l0, m0)) if self.enabled => {
                Instant::from_ns(m0 + ((local.as_ns() - l0) as f64 / self.rate).round() as i64)
            }
            _ => local,
        }
    }

    /// The local time at which the synchronised clock reads `sync`.
    pub fn to_local(&self, sync: Instant) -> Instant {
        match self.last {
            Some((l0, m0)) if self.enabled => {
                Instant::from_ns(l0 + ((sync.as_ns() - m0) as f64 * self.rate).round() as i64)
            }
            _ => sync,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drifting oscillator: local = offset + t·(1 + ppm·1e-6), truncated to `res` ns.
    fn local(t: i64, offset: i64, ppm: f64, res: i64) -> Instant {
        let l = offset + (t as f64 * (1.0 + ppm * 1e-6)).floor() as i64;
        Instant::from_ns(l - l.rem_euclid(res))
    }

    #[test]
    fn converges_to_master_time_with_drift() {
        let (offset, ppm, path) = (7_300, 48.0, 4_240);
        let mut c = SyncClock::new(true);
        let mut worst_late = 0;
        for k in 0..400i64 {
            let sent = k * 1_000_000;
            let rx = sent + path;
            c.sync(
                local(rx, offset, ppm, 8),
                Instant::from_ns(sent),
                Duration::from_ns(path),
            );
            // Half a cycle later the synchronised clock still reads master time.
            let t = sent + 500_000;
            let err = (c.to_sync(local(t, offset, ppm, 8)).as_ns() - t).abs();
            if k >= 100 {
                worst_late = worst_late.max(err);
            }
        }
        assert!(c.is_locked());
        assert!(worst_late <= 16, "residual {worst_late} ns");
        // to_local inverts to_sync within rounding.
        let s = Instant::from_ns(399_250_000);
        assert!((c.to_sync(c.to_local(s)).as_ns() - s.as_ns()).abs() <= 1);
    }

    #[test]
    fn the_filter_averages_jitter_and_skips_outliers() {
        let (path, cycles) = (5_000, 600i64);
        // Every 50th frame is read 900 µs late; all of them come after the clock locks.
        let late = |k: i64| k % 50 == 49;
        let run = |filter: ClockFilter| {
            let mut c = SyncClock::new(true);
            c.set_filter(filter);
            let mut r = 12_345u64;
            let mut worst = 0;
            for k in 0..cycles {
                r = r
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                // ±4 µs jitter, and a frame read 900 µs late every 50 cycles.
                let mut jitter = ((r >> 33) % 8_001) as i64 - 4_000;
                if late(k) {
                    jitter = 900_000;
                }
                let sent = k * 1_000_000;
                c.sync(
                    local(sent + path + jitter, 300, 20.0, 1),
                    Instant::from_ns(sent),
                    Duration::from_ns(path),
                );
                let t = sent + 999_000;
                if k >= 100 {
                    worst = worst.max((c.to_sync(local(t, 300, 20.0, 1)).as_ns() - t).abs());
                }
            }
            (worst, c.skipped())
        };
        let (raw, skipped_raw) = run(ClockFilter::default());
        let (filtered, skipped) = run(ClockFilter {
            offset_gain: 0.25,
            rate_gain: 0.01,
            outlier_limit: Some(Duration::from_us(50)),
        });
        assert!(
            raw > 800_000,
            "the unfiltered clock follows the late frame: {raw}"
        );
        assert_eq!(skipped_raw, 0);
        assert!(filtered < 6_000, "filtered residual {filtered} ns");
        // Each late frame is skipped on its own (the run of skips resets on the next good pair).
        assert_eq!(skipped, (0..cycles).filter(|&k| late(k)).count() as u64);
        assert_eq!(skipped, 12);
    }

    #[test]
    fn without_sync_the_clock_free_runs() {
        let mut c = SyncClock::new(false);
        c.sync(Instant::from_ns(5), Instant::from_ns(0), Duration::ZERO);
        assert_eq!(c.to_sync(Instant::from_ns(1234)), Instant::from_ns(1234));
        assert!(c.is_locked());
        assert!(!SyncClock::new(true).is_locked());
    }
}
