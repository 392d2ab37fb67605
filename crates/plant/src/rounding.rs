//! `floor` and `round` without a call into libm. x86-64's baseline instruction set has no
//! rounding instruction (SSE4.1's `roundsd` is not in it), so `f64::floor` and `f64::round`
//! are library calls there; these give the same results for every input from a truncating
//! conversion and a comparison.

/// 2⁵²: every f64 of at least this magnitude is an integer.
const INTEGRAL: f64 = 4_503_599_627_370_496.0;

/// `y.floor() as i64` for every `y` (saturating at the ends of the range, 0 for NaN).
#[inline]
pub fn floor_i64(y: f64) -> i64 {
    // `as` truncates toward zero and saturates; below zero a fractional part makes the
    // truncation one too high.
    let t = y as i64;
    if (t as f64) > y {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `x.round()` for every `x`: to the nearest integer, halves away from zero, the sign of
/// zero kept.
#[inline]
pub fn round_f64(x: f64) -> f64 {
    // Larger magnitudes are integers already, and NaN and the infinities stay as they are.
    if x.is_nan() || x.abs() >= INTEGRAL {
        return x;
    }
    // Below 2⁵² in magnitude, x − trunc(x) is exact: comparing it with ±0.5 decides.
    let t = x as i64;
    let f = x - t as f64;
    let r = if f >= 0.5 {
        t + 1
    } else if f <= -0.5 {
        t - 1
    } else {
        t
    };
    (r as f64).copysign(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values where rounding is decided: integers, halves, their neighbours one ulp away,
    /// zeros, the ends of the integer range and past them, NaN and the infinities.
    fn edges() -> Vec<f64> {
        let mut v = vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            INTEGRAL,
            -INTEGRAL,
            i64::MAX as f64,
            i64::MIN as f64,
            1e19,
            -1e19,
        ];
        for base in [0.0, 1.0, 2.0, 3.0, 1e6, 4.5e15, INTEGRAL / 2.0, 9.2e18] {
            for d in [0.0, 0.5, 0.25, 0.75] {
                for sign in [1.0, -1.0] {
                    let x: f64 = sign * (base + d);
                    v.extend([x, x.next_up(), x.next_down()]);
                }
            }
        }
        v
    }

    #[test]
    fn floor_i64_is_floor_then_cast() {
        for y in edges() {
            assert_eq!(floor_i64(y), y.floor() as i64, "{y:e} ({:#x})", y.to_bits());
        }
    }

    #[test]
    fn round_f64_is_round() {
        for x in edges() {
            let (got, want) = (round_f64(x), x.round());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{x:e} ({:#x}): {got:e} against {want:e}",
                x.to_bits()
            );
        }
    }

    proptest::proptest! {
        /// Any bit pattern: the same as the library's floor and round.
        #[test]
        fn the_same_as_the_library(bits in proptest::num::u64::ANY, small in -1e7f64..1e7) {
            for x in [f64::from_bits(bits), small] {
                proptest::prop_assert_eq!(floor_i64(x), x.floor() as i64);
                let (got, want) = (round_f64(x), x.round());
                proptest::prop_assert!(
                    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan())
                );
            }
        }
    }
}
