//! Fixed-precision decimal formatting for the outputs' numbers: the same bytes as Rust's
//! `format!("{x:.d$}")`, at a fraction of its cost.
//!
//! The standard formatter computes the correctly rounded decimal expansion of the binary
//! value (Grisu with a Dragon fallback), about 950 instructions per number in trace.csv. Here,
//! |x|·10^d is formed in one multiplication (10^d is exact for d ≤ 22) and split into integer
//! and fraction. The product is within half an ulp of the true scaled value: under 1.2·10⁻⁴
//! while it stays below 10¹², so unless the fraction is within 10⁻³ of one half, rounding the
//! computed product to the nearest integer rounds the true value the same way (a fraction
//! near 0 or 1 ends on the same integer either side). Near a tie, for larger magnitudes, and
//! for NaN and infinities the standard formatter decides. The sign is written whenever the
//! sign bit is set, as the standard formatter does (`-0.000000` for −10⁻⁹ at 6 digits).

use std::io::{self, Write};

/// Most decimals [`push_fixed`] takes on its fast path (the outputs use 0, 6 and 9).
pub const MAX_DECIMALS: usize = 9;

const POW10: [f64; MAX_DECIMALS + 1] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9];
const IPOW10: [u64; MAX_DECIMALS + 1] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
    1_000_000_000,
];

/// Below this the scaled value's rounding error (half an ulp, < 1.2·10⁻⁴) is far inside the
/// tie margin.
const FAST_LIMIT: f64 = 1e12;
/// How far from one half the computed fraction must be for the fast path.
const TIE_MARGIN: f64 = 1e-3;

/// Appends `x` with `decimals` digits after the point to `out`: the bytes of
/// `format!("{x:.decimals$}")`.
#[inline]
pub fn push_fixed(out: &mut Vec<u8>, x: f64, decimals: usize) {
    if decimals <= MAX_DECIMALS && x.is_finite() {
        let scaled = x.abs() * POW10[decimals];
        if scaled < FAST_LIMIT {
            // Truncation of a non-negative value below 2⁶⁴; the difference is exact
            // (int ≤ scaled < int + 1 ≤ 2·int, or int = 0).
            let int = scaled as u64;
            let frac = scaled - int as f64;
            if (frac - 0.5).abs() > TIE_MARGIN {
                let n = int + u64::from(frac > 0.5);
                if x.is_sign_negative() {
                    out.push(b'-');
                }
                push_u64(out, n / IPOW10[decimals]);
                if decimals > 0 {
                    out.push(b'.');
                    push_padded(out, n % IPOW10[decimals], decimals);
                }
                return;
            }
        }
    }
    let _ = write!(out, "{x:.decimals$}");
}

/// The two-digit strings "00" to "99", so that digits are made two at a time (one division
/// by 100 where one by 10 made one digit).
const PAIRS: &[u8; 200] = b"\
0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes the decimal digits of `n` into `buf` to end at `end`, two at a time, zero-padded
/// on the left to at least `min` digits (at most `end`); returns where they start.
#[inline]
fn digits_into(buf: &mut [u8; 20], end: usize, mut n: u64, min: usize) -> usize {
    let mut i = end;
    while n >= 100 {
        let p = (n % 100) as usize * 2;
        n /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[p..p + 2]);
    }
    if n >= 10 {
        let p = n as usize * 2;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&PAIRS[p..p + 2]);
    } else {
        i -= 1;
        buf[i] = b'0' + n as u8;
    }
    while end - i < min.min(end) {
        i -= 1;
        buf[i] = b'0';
    }
    i
}

/// Appends the decimal digits of `n`.
#[inline]
pub fn push_u64(out: &mut Vec<u8>, n: u64) {
    let mut buf = [0u8; 20];
    let i = digits_into(&mut buf, 20, n, 1);
    out.extend_from_slice(&buf[i..]);
}

/// Appends `n` (< 10^width) as exactly `width` digits, zero-padded on the left.
#[inline]
fn push_padded(out: &mut Vec<u8>, n: u64, width: usize) {
    let mut buf = [b'0'; 20];
    let i = digits_into(&mut buf, 20, n, width);
    out.extend_from_slice(&buf[i..]);
}

/// Writes rows to `w` through one reused line buffer: `row` appends a line's bytes (with its
/// newline) for each item.
pub fn write_lines<T, W: Write>(
    w: &mut W,
    items: impl IntoIterator<Item = T>,
    mut row: impl FnMut(&mut Vec<u8>, T),
) -> io::Result<()> {
    let mut line = Vec::with_capacity(256);
    for item in items {
        line.clear();
        row(&mut line, item);
        w.write_all(&line)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn fixed(x: f64, d: usize) -> String {
        let mut v = Vec::new();
        push_fixed(&mut v, x, d);
        String::from_utf8(v).expect("ascii")
    }

    fn same(x: f64, d: usize) {
        assert_eq!(fixed(x, d), format!("{x:.d$}"), "{x:e} at {d} decimals");
    }

    #[test]
    fn edge_values_match_the_standard_formatter() {
        let values = [
            0.0,
            -0.0,
            1e-10,
            -1e-10,
            0.5,
            1.5,
            2.5,
            -2.5,
            0.0000005,
            0.0000015,
            0.0000025,
            0.1234565,
            1.0000000005,
            999_999.9999995,
            123_456_789.123,
            1e11,
            1e12,
            1e15,
            -1e20,
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::EPSILON,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for x in values {
            for d in [0, 1, 3, 6, 9, 12] {
                same(x, d);
            }
        }
    }

    #[test]
    fn integers_are_written_in_full() {
        let mut ns = vec![0u64, 7, 10, 99, 100, 101, 999, 1_000_000, u64::MAX];
        ns.extend((0..20).map(|k| 10u64.pow(k)));
        ns.extend((1..20).map(|k| 10u64.pow(k) - 1));
        for n in ns {
            let mut v = Vec::new();
            push_u64(&mut v, n);
            assert_eq!(String::from_utf8(v).expect("ascii"), n.to_string());
        }
        // Zero-padded fractions, every width, odd and even digit counts.
        for (width, &limit) in IPOW10.iter().enumerate().skip(1) {
            for n in [0, 1, 9, 10, 99, 100, 12345, limit - 1] {
                let n = n.min(limit - 1);
                let mut v = Vec::new();
                push_padded(&mut v, n, width);
                assert_eq!(String::from_utf8(v).expect("ascii"), format!("{n:0width$}"));
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        /// Any finite value, the digits trace.csv uses.
        #[test]
        fn any_value_matches_the_standard_formatter(
            bits in any::<u64>(), d in prop_oneof![Just(0usize), Just(6), Just(9)],
        ) {
            let x = f64::from_bits(bits);
            prop_assert_eq!(fixed(x, d), format!("{x:.d$}"));
        }

        /// Values of the size the outputs hold, including many near ties.
        #[test]
        fn output_sized_values_match(
            m in -1e7f64..1e7, d in 0usize..=9, k in -9i32..=9,
        ) {
            let x = m * 10f64.powi(k) / 1e3;
            prop_assert_eq!(fixed(x, d), format!("{x:.d$}"));
            // A decimal tie at this precision, and its neighbours.
            let tie = ((x * 10f64.powi(d as i32)).trunc() + 0.5) / 10f64.powi(d as i32);
            for y in [tie, f64::from_bits(tie.to_bits() + 1), f64::from_bits(tie.to_bits().saturating_sub(1))] {
                prop_assert_eq!(fixed(y, d), format!("{y:.d$}"));
            }
        }
    }
}
