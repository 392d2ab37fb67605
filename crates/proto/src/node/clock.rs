//! A slave's synchronised clock (docs/system.md, "The cycle plan", IEEE 1588 style, one-way): the master
//! stamps the lumped frame with its send time M; every residence and link delay is fixed and
//! configured, so the master time at which the frame reaches slave i is M + D_i. Each sync
//! gives one pair (local receive timestamp L_k, master time M_k + D_i).
//!
//! The servo steps its offset to each new pair and estimates the rate of the local
//! oscillator against the master's from pairs at least a baseline apart (successive pairs
//! by default), low-pass filtered:
//!
//! ```text
//! S(L) = M_k + (L − L_k) / ρ̂          ρ̂ ← ρ̂ + g·((L_k − L_b) / (M_k − M_b) − ρ̂)
//! ```
//!
//! where b is the baseline pair. With software timestamps a long baseline matters: a pair
//! read 10 µs late measures the rate of a 1 ms interval 1 % wrong, of a 100 ms one 0.01 %.
//!
//! With exact timestamps and a constant drift the residual error is a few timestamp ticks
//! between syncs (tested). Without sync the clock free-runs: S(L) = L.

use crate::time::{Duration, Instant, round_i64};

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
    /// Once locked, a pair whose offset error exceeds this is skipped (at most
    /// `max_skips` in a row, then the servo takes it for its offset, never for the rate).
    /// `None`: no limit.
    pub outlier_limit: Option<Duration>,
    /// Outliers skipped in a row before the servo takes one (a clock that is really off
    /// must come back; a burst of late frames should not move it).
    pub max_skips: u32,
    /// The rate is measured between accepted pairs at least this far apart in master time
    /// (zero: successive pairs).
    pub rate_interval: Duration,
    /// A rate measurement further from 1 than this is not taken (oscillators are good to
    /// ±100 ppm; two frames whose stamps lie about the time between them would otherwise
    /// set any rate, and every later frame would fall outside the clock's window).
    pub max_rate_error: f64,
}

/// [`ClockFilter::max_rate_error`] by default: 1000 ppm, ten times the worst oscillator.
pub const MAX_RATE_ERROR: f64 = 1e-3;

impl Default for ClockFilter {
    fn default() -> Self {
        ClockFilter {
            offset_gain: 1.0,
            rate_gain: RATE_GAIN,
            outlier_limit: None,
            max_skips: 3,
            rate_interval: Duration::ZERO,
            max_rate_error: MAX_RATE_ERROR,
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
    /// Rate measurements refused as implausible.
    rates_refused: u64,
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
            rates_refused: 0,
        }
    }

    /// Sets the servo's filter (gains outside (0, 1] are clamped into it).
    pub fn set_filter(&mut self, f: ClockFilter) {
        self.filter = ClockFilter {
            offset_gain: f.offset_gain.clamp(1e-3, 1.0),
            rate_gain: f.rate_gain.clamp(1e-6, 1.0),
            outlier_limit: f.outlier_limit,
            max_skips: f.max_skips,
            rate_interval: f.rate_interval.max(Duration::ZERO),
            max_rate_error: f.max_rate_error.clamp(1e-6, 0.5),
        };
    }

    /// Sync pairs skipped as outliers.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Rate measurements refused as implausible (further from 1 than
    /// [`ClockFilter::max_rate_error`]).
    pub fn rates_refused(&self) -> u64 {
        self.rates_refused
    }

    /// The estimated rate ρ̂ of the local oscillator [local ns per master ns].
    pub fn rate(&self) -> f64 {
        self.rate
    }

    /// Takes one sync: the frame was received at local time `local` and reached this slave
    /// at master time `master_at` (its send stamp plus the path delay; the caller checks
    /// that sum, which comes from the wire, for overflow and plausibility first).
    pub fn sync(&mut self, local: Instant, master_at: Instant) {
        if !self.enabled {
            return;
        }
        let (l, m) = (local.as_ns(), master_at.as_ns());
        let mut anchor = m;
        let mut outlier = false;
        if self.syncs >= 2 && self.last.is_some() {
            let err = m.saturating_sub(self.to_sync(local).as_ns());
            if let Some(limit) = self.filter.outlier_limit
                && err.saturating_abs() > limit.as_ns()
            {
                if self.skipped_run < self.filter.max_skips {
                    self.skipped_run += 1;
                    self.skipped += 1;
                    return;
                }
                outlier = true;
            }
            if self.filter.offset_gain < 1.0 {
                anchor = m
                    .saturating_sub(err)
                    .saturating_add(round_i64(self.filter.offset_gain * err as f64));
            }
        }
        self.skipped_run = 0;
        // An outlier is taken for its offset only: it measures no rate, nor is it a baseline.
        if !outlier {
            match self.raw {
                Some((l0, m0)) if m.saturating_sub(m0) >= self.filter.rate_interval.as_ns() => {
                    if m > m0 && l > l0 {
                        let measured = (l - l0) as f64 / (m - m0) as f64;
                        if (measured - 1.0).abs() > self.filter.max_rate_error {
                            // A pair that lies about the time between frames (or one too
                            // noisy to measure a rate): no rate from it, and not a baseline.
                            self.rates_refused += 1;
                            self.last = Some((l, anchor));
                            self.syncs += 1;
                            return;
                        }
                        self.rate += self.filter.rate_gain * (measured - self.rate);
                    }
                    self.raw = Some((l, m));
                }
                Some(_) => {}
                None => self.raw = Some((l, m)),
            }
        }
        self.last = Some((l, anchor));
        self.syncs += 1;
    }

    /// Starts acquisition afresh from one pair (the frames before it disagreed with it):
    /// the clock steps to the pair and is not locked until the next sync.
    pub fn restart(&mut self, local: Instant, master_at: Instant) {
        self.step_to(local, master_at, 1);
    }

    /// Re-locks to a new time line: the master's clock really stepped (it restarted, or its
    /// time base was set), and frames of the new time line have come for long enough with
    /// none of the old one (the slave decides: [`crate::node::Slave`]). The clock steps to
    /// the pair and measures its rate afresh; the estimated rate is kept.
    pub fn relock(&mut self, local: Instant, master_at: Instant) {
        self.step_to(local, master_at, self.syncs.max(2));
    }

    /// Steps to the pair, measuring the rate afresh from it, with `syncs` taken.
    fn step_to(&mut self, local: Instant, master_at: Instant, syncs: u64) {
        if !self.enabled {
            return;
        }
        let pair = (local.as_ns(), master_at.as_ns());
        self.last = Some(pair);
        self.raw = Some(pair);
        self.skipped_run = 0;
        self.syncs = syncs;
    }

    /// Whether at least one sync has been taken (or the clock free-runs by design).
    pub fn is_locked(&self) -> bool {
        !self.enabled || self.syncs >= 2
    }

    /// The synchronised time S(L) for local time `local`.
    pub fn to_sync(&self, local: Instant) -> Instant {
        match self.last {
            Some((l0, m0)) if self.enabled => Instant::from_ns(m0.saturating_add(round_i64(
                local.as_ns().saturating_sub(l0) as f64 / self.rate,
            ))),
            _ => local,
        }
    }

    /// The local time at which the synchronised clock reads `sync`.
    pub fn to_local(&self, sync: Instant) -> Instant {
        match self.last {
            Some((l0, m0)) if self.enabled => Instant::from_ns(l0.saturating_add(round_i64(
                sync.as_ns().saturating_sub(m0) as f64 * self.rate,
            ))),
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

    /// Syncs a clock with `filter` `cycles` times 1 ms apart, on an oscillator 300 ns off and
    /// `ppm` fast with 1 ns timestamps, over a 5 µs path; frame k is read `late(k)` ns after
    /// it arrives. After each sync `each(k, sent, clock)` looks at the clock.
    fn drive(
        filter: ClockFilter,
        ppm: f64,
        cycles: i64,
        mut late: impl FnMut(i64) -> i64,
        mut each: impl FnMut(i64, i64, &SyncClock),
    ) -> SyncClock {
        let path = 5_000;
        let mut c = SyncClock::new(true);
        c.set_filter(filter);
        for k in 0..cycles {
            let sent = k * 1_000_000;
            c.sync(
                local(sent + path + late(k), 300, ppm, 1),
                Instant::from_ns(sent + path),
            );
            each(k, sent, &c);
        }
        c
    }

    /// |S(L) − t| at true time `t` [ns], on the oscillator of [`drive`].
    fn error_at(c: &SyncClock, t: i64, ppm: f64) -> i64 {
        (c.to_sync(local(t, 300, ppm, 1)).as_ns() - t).abs()
    }

    #[test]
    fn converges_to_master_time_with_drift() {
        let (offset, ppm, path) = (7_300, 48.0, 4_240);
        let mut c = SyncClock::new(true);
        let mut worst_late = 0;
        for k in 0..400i64 {
            let sent = k * 1_000_000;
            let rx = sent + path;
            c.sync(local(rx, offset, ppm, 8), Instant::from_ns(sent + path));
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
        let cycles = 600i64;
        // Every 50th frame is read 900 µs late; all of them come after the clock locks.
        let late = |k: i64| k % 50 == 49;
        let run = |filter: ClockFilter| {
            let mut r = 12_345u64;
            let mut worst = 0;
            // ±4 µs jitter, and a frame read 900 µs late every 50 cycles.
            let jitter = move |k: i64| {
                r = r
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                if late(k) {
                    900_000
                } else {
                    ((r >> 33) % 8_001) as i64 - 4_000
                }
            };
            let c = drive(filter, 20.0, cycles, jitter, |k, sent, c| {
                if k >= 100 {
                    worst = worst.max(error_at(c, sent + 999_000, 20.0));
                }
            });
            (worst, c.skipped(), c.rate())
        };
        let (raw, skipped_raw, _) = run(ClockFilter::default());
        let (filtered, skipped, rate) = run(ClockFilter {
            offset_gain: 0.25,
            rate_gain: 0.01,
            outlier_limit: Some(Duration::from_us(50)),
            max_skips: 3,
            rate_interval: Duration::ZERO,
            max_rate_error: MAX_RATE_ERROR,
        });
        // The same with the rate measured over 100 ms between accepted pairs.
        let (long, skipped_long, rate_long) = run(ClockFilter {
            offset_gain: 0.25,
            rate_gain: 0.25,
            outlier_limit: Some(Duration::from_us(50)),
            max_skips: 3,
            rate_interval: Duration::from_ms(100),
            max_rate_error: MAX_RATE_ERROR,
        });
        assert!(long < 6_000, "long-baseline residual {long} ns");
        assert_eq!(skipped_long, skipped);
        // The oscillator runs 20 ppm fast. Successive pairs 1 ms apart with ±4 µs of jitter
        // measure the rate up to 8000 ppm wrong each, pairs 100 ms apart up to 80 ppm: the
        // long baseline's estimate is the closer one.
        let (err, err_long) = ((rate - 1.0 - 20e-6).abs(), (rate_long - 1.0 - 20e-6).abs());
        assert!(err_long < err, "{err_long} vs {err}");
        assert!(err_long < 20e-6, "rate {rate_long} with a 100 ms baseline");
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

    /// Bursts of late frames, as when the host stalls a software ring for several cycles:
    /// six frames in a row read 150-400 µs late every 200 cycles. The outlier limit skips
    /// three and must then take the fourth for its offset; taken as a rate measurement too,
    /// a frame 300 µs late over a 1 ms interval would throw ρ̂ off by 30 % × the rate gain
    /// (3000 ppm at 1/100) for as long as the filter remembers it.
    #[test]
    fn bursts_of_late_frames_leave_the_rate_alone() {
        let ppm = 20.0;
        let run = |filter: ClockFilter| {
            let late = |k: i64| match k % 200 {
                150..156 => 150_000 + 50_000 * (k % 200 - 150),
                _ => 0,
            };
            let mut worst = 0.0f64;
            let c = drive(filter, ppm, 3_000, late, |k, _, c| {
                // Once the filter has learnt the rate (the bursts go on).
                if k >= 1_500 {
                    worst = worst.max((c.rate() - 1.0 - ppm * 1e-6).abs());
                }
            });
            (c.skipped(), worst * 1e6)
        };
        let limit = Some(Duration::from_us(50));
        for filter in [
            ClockFilter {
                offset_gain: 0.25,
                rate_gain: 0.01,
                outlier_limit: limit,
                max_skips: 3,
                rate_interval: Duration::ZERO,
                max_rate_error: MAX_RATE_ERROR,
            },
            ClockFilter {
                offset_gain: 0.25,
                rate_gain: 0.25,
                outlier_limit: limit,
                max_skips: 3,
                rate_interval: Duration::from_ms(100),
                max_rate_error: MAX_RATE_ERROR,
            },
        ] {
            let (skipped, worst) = run(filter);
            assert!(skipped >= 30, "{skipped} pairs skipped");
            assert!(worst < 1.0, "{filter:?}: rate off by {worst} ppm");
        }
    }

    /// With room for a whole burst (six late frames) the servo skips every late frame and
    /// coasts on its rate: the clock does not move at all.
    #[test]
    fn a_long_skip_run_rides_out_a_burst() {
        let run = |max_skips: u32| {
            let filter = ClockFilter {
                offset_gain: 0.25,
                rate_gain: 0.25,
                outlier_limit: Some(Duration::from_us(50)),
                max_skips,
                rate_interval: Duration::from_ms(100),
                max_rate_error: MAX_RATE_ERROR,
            };
            let late = |k: i64| if (700..706).contains(&k) { 300_000 } else { 0 };
            let mut worst = 0;
            let c = drive(filter, 20.0, 1_000, late, |k, sent, c| {
                if k >= 600 {
                    worst = worst.max(error_at(c, sent + 999_000, 20.0));
                }
            });
            (worst, c.skipped())
        };
        let (short, skipped_short) = run(3);
        let (long, skipped_long) = run(20);
        // The long run skips exactly the burst; the short one also skips good frames after
        // it, while it walks the clock back from the late frame it took.
        assert_eq!(skipped_long, 6);
        assert!(skipped_short > skipped_long, "{skipped_short}");
        assert!(
            short > 50_000,
            "the 4th late frame moves the clock: {short} ns"
        );
        assert!(long < 100, "the clock stays: {long} ns");
    }

    /// Two pairs whose stamps lie about the time between them (20 µs of local time for
    /// 1 ns of master time) set no rate: the clock keeps ρ̂ = 1.
    #[test]
    fn an_implausible_rate_is_not_taken() {
        let mut c = SyncClock::new(true);
        c.sync(Instant::from_ns(1_000_000), Instant::from_ns(1_000_000));
        c.sync(Instant::from_ns(1_020_000), Instant::from_ns(1_000_001));
        assert_eq!(c.rate(), 1.0);
        assert_eq!(c.rates_refused(), 1);
        // Honest pairs 1 ms apart, 50 ppm fast, are taken.
        c.sync(Instant::from_ns(2_020_050), Instant::from_ns(2_000_001));
        assert!((c.rate() - 1.0).abs() < 1e-4, "{}", c.rate());
    }

    /// Clock readings never overflow, whatever pair the clock holds.
    #[test]
    fn readings_saturate_instead_of_overflowing() {
        let mut c = SyncClock::new(true);
        c.sync(Instant::from_ns(0), Instant::from_ns(i64::MAX - 10));
        c.sync(Instant::from_ns(1_000), Instant::from_ns(i64::MAX - 5));
        assert_eq!(
            c.to_sync(Instant::from_ns(i64::MAX)),
            Instant::from_ns(i64::MAX)
        );
        assert!(c.to_local(Instant::from_ns(i64::MIN)).as_ns() < i64::MIN / 2);
    }

    #[test]
    fn a_relock_steps_to_the_new_time_line() {
        let mut c = SyncClock::new(true);
        for k in 0..10 {
            c.sync(
                Instant::from_ns(k * 1_000_000),
                Instant::from_ns(k * 1_000_000 + 5),
            );
        }
        c.relock(Instant::from_ns(10_000_000), Instant::from_ns(777_000_000));
        assert_eq!(c.to_sync(Instant::from_ns(10_500_000)).as_ns(), 777_500_000);
        assert!(c.is_locked());
    }

    #[test]
    fn without_sync_the_clock_free_runs() {
        let mut c = SyncClock::new(false);
        c.sync(Instant::from_ns(5), Instant::from_ns(0));
        assert_eq!(c.to_sync(Instant::from_ns(1234)), Instant::from_ns(1234));
        assert!(c.is_locked());
        assert!(!SyncClock::new(true).is_locked());
    }
}
