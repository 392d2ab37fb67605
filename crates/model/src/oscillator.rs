//! A slave's oscillator: the local clock its hardware timestamps read, offset and drifting
//! against true (master) time, truncated to the timestamp resolution.

use ringsync_proto::Instant;

use crate::rng::Rng;
use crate::scenario::Scenario;

/// A slave's oscillator: its local clock reads offset + t·rate, truncated to the timestamp
/// resolution, where t is true (master) time.
#[derive(Debug, Clone, Copy)]
pub struct Oscillator {
    /// Local reading at true time 0 \[ns\].
    pub offset: f64,
    /// Local nanoseconds per true nanosecond (1 + drift).
    pub rate: f64,
    /// Timestamp resolution \[ns\], at least 1.
    pub res: i64,
}

impl Oscillator {
    /// The scenario's oscillators: slave i's offset and drift drawn uniformly within the
    /// scenario's bounds from its own seeded stream.
    pub fn for_scenario(s: &Scenario) -> Vec<Oscillator> {
        (0..s.axes_count())
            .map(|i| {
                let mut r = Rng::stream(s.seed, 1_000 + i as u64);
                Oscillator {
                    offset: r.symmetric(s.clock.initial_offset.0.as_ns() as f64),
                    rate: 1.0 + r.symmetric(s.clock.drift_ppm) * 1e-6,
                    res: s.clock.timestamp_resolution.0.as_ns().max(1),
                }
            })
            .collect()
    }

    /// The local clock's reading at true time `t` \[ns\].
    pub fn local(&self, t: i64) -> Instant {
        let l = floor_i64(self.offset + t as f64 * self.rate);
        if self.res == 1 {
            return Instant::from_ns(l);
        }
        if self.res & (self.res - 1) == 0 {
            // A power of two (8 ns, the reference): clearing the low bits rounds down in
            // two's complement exactly as rem_euclid does, without a division.
            return Instant::from_ns(l & !(self.res - 1));
        }
        Instant::from_ns(l - l.rem_euclid(self.res))
    }

    /// The first true time \[ns\] at which the local clock reads at least `l`, searching up
    /// from the estimate ⌈(l − offset)/rate⌉.
    pub fn true_at(&self, l: Instant) -> i64 {
        // A reading off the timestamp grid is first reached where the raw clock reaches the
        // next grid point: start from that point's estimate (the search from t0 would step
        // up to res − 1 ns one at a time), back down while the reading still suffices (the
        // reading never falls as t grows, so this finds the same instant), but not below
        // t0, then up. t0 (a division) is computed only where it decides something: on the
        // grid, or when the reading one nanosecond earlier suffices too (rarely: the grid
        // point's estimate is its first instant but for rounding).
        let mut t = match self.grid_above(l.as_ns()) {
            Some(g) if g != l.as_ns() => {
                let t = self.estimate(g);
                if self.local(t - 1) < l {
                    // As `max(t0)` then the downward search: t ≥ t0 here, since the
                    // estimates never fall as the reading grows (g > l).
                    t
                } else {
                    let t0 = self.estimate(l.as_ns());
                    let mut t = t.max(t0);
                    while t > t0 && self.local(t - 1) >= l {
                        t -= 1;
                    }
                    t
                }
            }
            _ => self.estimate(l.as_ns()),
        };
        while self.local(t) < l {
            t += 1;
        }
        t
    }

    /// ⌈(l − offset)/rate⌉ as computed in floating point [ns].
    fn estimate(&self, l: i64) -> i64 {
        -floor_i64((self.offset - l as f64) / self.rate)
    }

    /// The smallest reading on the timestamp grid at or above `l` (`None` past the range).
    fn grid_above(&self, l: i64) -> Option<i64> {
        let r = if self.res & (self.res - 1) == 0 {
            l & (self.res - 1)
        } else {
            l.rem_euclid(self.res)
        };
        if r == 0 {
            Some(l)
        } else {
            l.checked_add(self.res - r)
        }
    }
}

/// ⌊y⌋ as an integer, without a libm call.
pub(crate) use ringsync_plant::rounding::floor_i64;

#[cfg(test)]
mod tests {

    /// `true_at` against the plain search up from the estimate, for readings on and off
    /// the grid, several resolutions, offsets and drifts.
    #[test]
    fn true_at_finds_what_the_plain_search_finds() {
        use super::Oscillator;
        use ringsync_proto::Instant;
        let plain = |o: &Oscillator, l: Instant| {
            let mut t = -super::floor_i64((o.offset - l.as_ns() as f64) / o.rate);
            while o.local(t) < l {
                t += 1;
            }
            t
        };
        let mut r = crate::rng::Rng::stream(3, 11);
        for k in 0..200_000 {
            let res = [1i64, 8, 64, 10, 1000][k % 5];
            let o = Oscillator {
                offset: r.symmetric(1e6),
                rate: 1.0 + r.symmetric(2e-4),
                res,
            };
            // Readings up to 10 s, and up to 10⁷ s, where the estimates' rounding is coarse
            // enough that a grid point's estimate is sometimes past its first instant (the
            // search then steps down).
            let far = [1e10, 1e13, 1e16][k % 3];
            let l = Instant::from_ns(r.symmetric(far) as i64);
            assert_eq!(o.true_at(l), plain(&o, l), "{o:?} l = {l:?}");
        }
    }

    /// The oscillator's truncation to a power-of-two resolution (a mask) against rem_euclid,
    /// for negative readings too.
    #[test]
    fn power_of_two_resolution_truncates_like_rem_euclid() {
        use super::Oscillator;
        let mut r = crate::rng::Rng::stream(5, 9);
        for k in 0..100_000 {
            let res = [2i64, 8, 64, 1024][k % 4];
            let o = Oscillator {
                offset: r.symmetric(1e9),
                rate: 1.0 + r.symmetric(1e-4),
                res,
            };
            let t = r.symmetric(1e12) as i64;
            let l = super::floor_i64(o.offset + t as f64 * o.rate);
            assert_eq!(o.local(t).as_ns(), l - l.rem_euclid(res), "{o:?} t = {t}");
        }
    }
}
