//! The one clock and wait discipline of a real-time loop, shared by the ring's loop and the
//! host probe (`ringsync latency`), so that both measure a stall the same way.
//!
//! Times are ns from the loop's start (true time 0 of a run), on `CLOCK_MONOTONIC`. Every
//! reading also measures the **stall** since the previous one: the loop reads the clock at
//! least once per frame and timer, so a gap between two readings longer than a send, a
//! receive and their processing (a few µs) is time the host held the loop off its CPU. A
//! sleep or a wait is not a stall; only its late return is.
//!
//! ```
//! use ringsync_rt::clock::Clock;
//! let mut c = Clock::start_in(0);
//! let t = c.now();
//! c.sleep_until(t + 100_000);
//! assert!(c.now() >= t + 100_000);
//! // The stall is how far the sleep overran, and the gaps between readings since.
//! assert!(c.take_stall() >= 0);
//! ```

use std::io;

use crate::sys;

/// The loop's clock (see the module docs).
#[derive(Debug, Clone)]
pub struct Clock {
    t0: i64,
    last: i64,
    stall: i64,
    /// `CLOCK_REALTIME` less `CLOCK_MONOTONIC` [ns] when last measured (kernel stamps).
    realtime: i64,
}

impl Clock {
    /// A clock whose time 0 is `lead` ns from now (a loop starts a little ahead, so that its
    /// first deadline is met).
    pub fn start_in(lead: i64) -> Clock {
        let now = sys::now_ns();
        Clock {
            t0: now + lead,
            last: -lead,
            stall: 0,
            realtime: sys::realtime_offset(),
        }
    }

    /// A clock whose time 0 is the monotonic clock's reading `t0` \[ns\] (an epoch shared by
    /// the processes of a ring on one host).
    pub fn starting_at(t0: i64) -> Clock {
        Clock {
            t0,
            last: sys::now_ns() - t0,
            stall: 0,
            realtime: sys::realtime_offset(),
        }
    }

    /// `CLOCK_MONOTONIC` at time 0 \[ns\].
    pub fn t0(&self) -> i64 {
        self.t0
    }

    /// Now [ns from time 0]; measures the stall since the last reading.
    pub fn now(&mut self) -> i64 {
        let t = sys::now_ns() - self.t0;
        self.stall = self.stall.max(t - self.last);
        self.last = t;
        t
    }

    /// A kernel receive stamp (`CLOCK_REALTIME` \[ns\], read with `SO_TIMESTAMPNS`) as a time of
    /// this clock [ns from time 0].
    pub fn from_realtime(&self, stamp: i64) -> i64 {
        stamp.saturating_sub(self.realtime).saturating_sub(self.t0)
    }

    /// Measures again how far `CLOCK_REALTIME` is from `CLOCK_MONOTONIC` (a system clock
    /// set during the run moves it).
    pub fn measure_realtime(&mut self) {
        self.realtime = sys::realtime_offset();
    }

    /// The last reading [ns from time 0], without reading the clock.
    pub fn last(&self) -> i64 {
        self.last
    }

    /// Back from a sleep or a wait planned to end at `planned` [ns]: only a late return
    /// counts as a stall.
    fn woke(&mut self, planned: i64) -> i64 {
        let t = sys::now_ns() - self.t0;
        self.stall = self.stall.max(t - planned);
        self.last = t;
        t
    }

    /// Sleeps until time `t` \[ns\] (an absolute deadline: no drift accumulates); returns the
    /// time it woke.
    pub fn sleep_until(&mut self, t: i64) -> i64 {
        sys::sleep_until(self.t0 + t);
        self.woke(t)
    }

    /// Waits until one of `fds` is readable or time `t` \[ns\] comes; returns the time it
    /// returned. A wait that a frame ended early is no stall; one that returned after `t`
    /// is late by the overrun.
    pub fn wait_readable_until(&mut self, fds: &mut [libc::pollfd], t: i64) -> io::Result<i64> {
        let rest = t - (sys::now_ns() - self.t0);
        sys::wait_readable(fds, rest)?;
        Ok(self.woke(t))
    }

    /// Busy-waits until time `t` \[ns\], reading the clock; returns the first reading at or
    /// after `t`.
    pub fn spin_until(&mut self, t: i64) -> i64 {
        loop {
            let now = self.now();
            if now >= t {
                return now;
            }
        }
    }

    /// Counts `ns` as a stall (a late start, measured by the caller).
    pub fn note_stall(&mut self, ns: i64) {
        self.stall = self.stall.max(ns);
    }

    /// The longest stall since the last call \[ns\]; starts a new measure.
    pub fn take_stall(&mut self) -> i64 {
        std::mem::take(&mut self.stall)
    }
}
