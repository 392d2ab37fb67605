//! What the host gives a real-time loop, measured without the ring (`ringsync latency`, in
//! the spirit of cyclictest): the runtime's own waiting discipline and real-time settings,
//! with the ring's work replaced by reading the clock.
//!
//! Every cycle the loop sleeps until `spin` before the deadline, busy-waits to it, then keeps
//! reading the clock for `busy` (where the ring would carry its frames). Measured per cycle,
//! with the definitions of [`Timing`](crate::Timing):
//! - the start's lateness: the first reading at or after the deadline, minus the deadline;
//! - the stall: the longest gap between two readings in the cycle beyond what a sleep asked
//!   for (a late wake-up counts as a gap), or the late start if longer.
//!
//! A run of the ring loses cycles the host stalls; comparing `ringsync rt` with this probe
//! on the same machine tells the host's share from the runtime's.

use std::sync::atomic::{AtomicBool, Ordering};

use ringsync_proto::Duration;

use crate::clock::Clock;
use crate::realtime::{Applied, Realtime};
use crate::stats::Percentiles;
use crate::timing::STALL;

/// How to probe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HostOptions {
    /// Cycle time.
    pub cycle: Duration,
    /// How long to probe.
    pub duration: Duration,
    /// How long after each deadline the loop keeps reading the clock (the ring's busy part:
    /// lumped frame and time slices).
    pub busy: Duration,
    /// Real-time settings, as for the ring.
    pub realtime: Realtime,
    /// Print a progress line a second to standard error.
    pub verbose: bool,
}

impl Default for HostOptions {
    /// 10 s of 1 ms cycles, busy 300 µs (a 4-slave ring's lumped frame and slices here).
    fn default() -> Self {
        HostOptions {
            cycle: Duration::from_ms(1),
            duration: Duration::from_ms(10_000),
            busy: Duration::from_us(300),
            realtime: Realtime::default(),
            verbose: false,
        }
    }
}

/// Stall thresholds counted in [`HostLatency::over`] \[ns\].
pub const THRESHOLDS: [i64; 6] = [50_000, 100_000, 200_000, 500_000, 1_000_000, 5_000_000];

/// What the host gave.
#[derive(Debug, Clone, PartialEq)]
pub struct HostLatency {
    /// Cycles probed.
    pub cycles: u64,
    /// Lateness of each cycle's start \[ns\].
    pub lateness: Percentiles,
    /// The longest stall of each cycle \[ns\].
    pub stalls: Percentiles,
    /// Cycles with a stall of [`STALL`] or more.
    pub cycles_stalled: u64,
    /// Cycles whose stall reached each of [`THRESHOLDS`]: (threshold \[ns\], cycles).
    pub over: Vec<(i64, u64)>,
    /// The longest run of consecutive cycles with a stall of [`STALL`] or more.
    pub longest_stalled_run: u64,
    /// Real-time settings applied, and warnings for those that were not.
    pub realtime: Vec<String>,
    /// Ended early by `stop`.
    pub interrupted: bool,
}

/// What is wrong with the options.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HostError {
    /// An option out of range.
    #[error("{name} = {value} is out of range ({range})")]
    OutOfRange {
        /// The option.
        name: &'static str,
        /// Its value.
        value: String,
        /// What is allowed.
        range: &'static str,
    },
}

/// Probes the host for `opts.duration` (or until `stop` rises).
pub fn probe(opts: &HostOptions, stop: &AtomicBool) -> Result<HostLatency, HostError> {
    let (t_cyc, spin, busy) = (
        opts.cycle.as_ns(),
        opts.realtime.spin.as_ns(),
        opts.busy.as_ns(),
    );
    let range = |name, value: Duration, range| HostError::OutOfRange {
        name,
        value: value.to_string(),
        range,
    };
    if !(10_000..=1_000_000_000).contains(&t_cyc) {
        return Err(range("cycle", opts.cycle, "10 µs ..= 1 s"));
    }
    if !(0..=t_cyc).contains(&spin) {
        return Err(range("spin", opts.realtime.spin, "0 ..= cycle"));
    }
    if !(0..=t_cyc).contains(&(spin + busy)) || busy < 0 {
        return Err(range("busy", opts.busy, "0 ..= cycle − spin"));
    }
    if !(t_cyc..=86_400_000_000_000).contains(&opts.duration.as_ns()) {
        return Err(range("duration", opts.duration, "one cycle ..= 24 h"));
    }
    let cycles = (opts.duration.as_ns() / t_cyc) as usize;
    // The CPU claim (`_cpu`) holds the loop's CPU against other runs until the probe ends.
    let Applied {
        lines: realtime,
        cpu: _cpu,
    } = opts.realtime.apply();
    if opts.verbose {
        for r in &realtime {
            eprintln!("ringsync latency: {r}");
        }
    }
    let mut lateness = Vec::with_capacity(cycles);
    let mut stalls = Vec::with_capacity(cycles);
    let (mut run, mut longest) = (0u64, 0u64);
    let mut clock = Clock::start_in(2_000_000);
    let mut interrupted = false;
    for k in 0..cycles as i64 {
        if stop.load(Ordering::Relaxed) {
            interrupted = true;
            break;
        }
        let deadline = k * t_cyc;
        let wake = deadline - spin;
        if clock.now() < wake {
            clock.sleep_until(wake);
        }
        let t = clock.spin_until(deadline);
        lateness.push(t - deadline);
        clock.note_stall(t - deadline);
        clock.spin_until(deadline + busy);
        let stall = clock.take_stall();
        stalls.push(stall);
        if stall >= STALL {
            run += 1;
            longest = longest.max(run);
        } else {
            run = 0;
        }
        if opts.verbose && (k + 1) % (1_000_000_000 / t_cyc).max(1) == 0 {
            let p = Percentiles::of(&stalls);
            eprintln!(
                "ringsync latency: {:5.1} s  stalls per cycle p99 {:.1} µs, max {:.1} µs",
                (k + 1) as f64 * t_cyc as f64 * 1e-9,
                p.p99 as f64 * 1e-3,
                p.max as f64 * 1e-3
            );
        }
    }
    Ok(HostLatency {
        cycles: stalls.len() as u64,
        lateness: Percentiles::of(&lateness),
        stalls: Percentiles::of(&stalls),
        cycles_stalled: stalls.iter().filter(|s| **s >= STALL).count() as u64,
        over: THRESHOLDS
            .iter()
            .map(|&th| (th, stalls.iter().filter(|s| **s >= th).count() as u64))
            .collect(),
        longest_stalled_run: longest,
        realtime,
        interrupted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realtime::Pin;

    fn quiet(cycle_us: i64, cycles: i64) -> HostOptions {
        HostOptions {
            cycle: Duration::from_us(cycle_us),
            duration: Duration::from_us(cycle_us * cycles),
            busy: Duration::from_us(cycle_us / 4),
            // No real-time requests: the test must not pin or lock the test process.
            realtime: Realtime {
                spin: Duration::from_us(cycle_us / 4),
                priority: 0,
                cpu: Pin::Off,
                lock_memory: false,
            },
            verbose: false,
        }
    }

    #[test]
    fn every_cycle_is_measured() {
        let r = probe(&quiet(1_000, 200), &AtomicBool::new(false)).expect("probe");
        assert_eq!(r.cycles, 200);
        assert_eq!((r.lateness.count, r.stalls.count), (200, 200));
        // A cycle's stall includes its late start.
        assert!(r.stalls.max >= r.lateness.max);
        let counts: Vec<u64> = r.over.iter().map(|(_, c)| *c).collect();
        assert!(counts.windows(2).all(|w| w[0] >= w[1]), "{counts:?}");
        assert_eq!(counts[0], r.cycles_stalled);
        assert!(r.longest_stalled_run <= r.cycles_stalled);
        assert!(!r.interrupted);
        assert_eq!(r.realtime.len(), 1, "{:?}", r.realtime);
    }

    #[test]
    fn stop_ends_it_early() {
        let r = probe(&quiet(1_000, 100), &AtomicBool::new(true)).expect("probe");
        assert!(r.interrupted);
        assert_eq!(r.cycles, 0);
    }

    #[test]
    fn bad_options_are_named() {
        let stop = AtomicBool::new(false);
        let name = |o: HostOptions| match probe(&o, &stop) {
            Err(HostError::OutOfRange { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        let mut o = quiet(1_000, 10);
        o.cycle = Duration::from_us(1);
        assert_eq!(name(o), "cycle");
        let mut o = quiet(1_000, 10);
        o.busy = Duration::from_us(900);
        assert_eq!(name(o), "busy");
        let mut o = quiet(1_000, 10);
        o.realtime.spin = Duration::from_ms(2);
        assert_eq!(name(o), "spin");
        let mut o = quiet(1_000, 10);
        o.duration = Duration::ZERO;
        assert_eq!(name(o), "duration");
    }
}
