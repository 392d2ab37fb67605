//! Encoder quantisation and velocity by encoder difference (docs/system.md, "The reference scenario").

use std::f64::consts::TAU;

use crate::error::PlantError;

/// An incremental encoder with `counts_per_rev` counts per revolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Encoder {
    /// Counts per revolution (the reference axes: 2^20).
    pub counts_per_rev: u32,
}

impl Encoder {
    /// A checked encoder (at least 4 counts per revolution).
    pub fn new(counts_per_rev: u32) -> Result<Self, PlantError> {
        if counts_per_rev < 4 {
            return Err(PlantError::InvalidParameter {
                name: "counts_per_rev",
                value: f64::from(counts_per_rev),
                expected: ">= 4 counts per revolution",
            });
        }
        Ok(Encoder { counts_per_rev })
    }

    /// Angle of one count \[rad\].
    pub fn resolution(&self) -> f64 {
        TAU / f64::from(self.counts_per_rev)
    }

    /// The count for position `x` \[rad\]: the edges passed, floor(x / resolution).
    pub fn counts(&self, x: f64) -> i64 {
        crate::rounding::floor_i64(x / self.resolution())
    }

    /// The position a count stands for \[rad\].
    pub fn position(&self, counts: i64) -> f64 {
        counts as f64 * self.resolution()
    }

    /// Velocity by encoder difference [rad/s]: counts moved over `dt` \[s\].
    pub fn velocity(&self, counts_now: i64, counts_before: i64, dt: f64) -> f64 {
        (counts_now - counts_before) as f64 * self.resolution() / dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_error_is_below_one_count() {
        let e = Encoder::new(1 << 20).expect("encoder");
        for k in -1000..1000 {
            let x = k as f64 * 0.012_345_6;
            let q = e.position(e.counts(x));
            assert!(q <= x && x - q < e.resolution(), "{x} -> {q}");
        }
        assert_eq!(e.counts(TAU), 1 << 20);
        assert_eq!(e.counts(-1e-12), -1);
    }

    #[test]
    fn velocity_by_difference() {
        let e = Encoder::new(1 << 20).expect("encoder");
        // 15.12 rad/s over 125 µs moves 1.89 mrad ≈ 315.4 counts; the estimate is within
        // one count per interval.
        let (v, dt) = (15.12, 125e-6);
        let c0 = e.counts(1.0);
        let c1 = e.counts(1.0 + v * dt);
        let est = e.velocity(c1, c0, dt);
        assert!((est - v).abs() <= e.resolution() / dt, "{est}");
        assert!(Encoder::new(0).is_err());
    }
}
