//! Time in integer nanoseconds: [`Duration`] (signed span) and [`Instant`] (a point on one
//! node's time line). Never `f64` seconds in the protocol layer.

use core::fmt;
use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

use serde::Serialize;

/// A signed span of time \[ns\]. Signed so that a shortfall (negative idle time) or a clock
/// offset is representable.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, serde::Deserialize,
)]
#[serde(transparent)]
pub struct Duration(i64);

impl Duration {
    /// Zero length.
    pub const ZERO: Duration = Duration(0);

    /// From nanoseconds.
    pub const fn from_ns(ns: i64) -> Self {
        Duration(ns)
    }
    /// From microseconds.
    pub const fn from_us(us: i64) -> Self {
        Duration(us * 1_000)
    }
    /// From milliseconds.
    pub const fn from_ms(ms: i64) -> Self {
        Duration(ms * 1_000_000)
    }
    /// Length \[ns\].
    pub const fn as_ns(self) -> i64 {
        self.0
    }
    /// Length \[µs\], for display.
    pub fn as_us_f64(self) -> f64 {
        self.0 as f64 / 1_000.0
    }
    /// Whether the span is negative.
    pub const fn is_negative(self) -> bool {
        self.0 < 0
    }
    /// Saturating sum.
    pub const fn saturating_add(self, other: Duration) -> Duration {
        Duration(self.0.saturating_add(other.0))
    }
}

impl fmt::Display for Duration {
    /// Microseconds with three decimals (nanosecond resolution), e.g. `10.720 µs`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sign = if self.0 < 0 { "-" } else { "" };
        let a = self.0.unsigned_abs();
        write!(f, "{sign}{}.{:03} µs", a / 1_000, a % 1_000)
    }
}

impl Add for Duration {
    type Output = Duration;
    fn add(self, rhs: Duration) -> Duration {
        Duration(self.0 + rhs.0)
    }
}
impl AddAssign for Duration {
    fn add_assign(&mut self, rhs: Duration) {
        self.0 += rhs.0;
    }
}
impl Sub for Duration {
    type Output = Duration;
    fn sub(self, rhs: Duration) -> Duration {
        Duration(self.0 - rhs.0)
    }
}
impl SubAssign for Duration {
    fn sub_assign(&mut self, rhs: Duration) {
        self.0 -= rhs.0;
    }
}
impl Neg for Duration {
    type Output = Duration;
    fn neg(self) -> Duration {
        Duration(-self.0)
    }
}
impl Mul<i64> for Duration {
    type Output = Duration;
    fn mul(self, k: i64) -> Duration {
        Duration(self.0 * k)
    }
}
impl core::iter::Sum for Duration {
    fn sum<I: Iterator<Item = Duration>>(iter: I) -> Duration {
        iter.fold(Duration::ZERO, Add::add)
    }
}

/// A point in time on one time line [ns since that line's origin]; in a cycle plan, the
/// origin is the cycle start (the master starts sending the lumped frame).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, serde::Deserialize,
)]
#[serde(transparent)]
pub struct Instant(i64);

impl Instant {
    /// The origin.
    pub const ZERO: Instant = Instant(0);
    /// From nanoseconds since the origin.
    pub const fn from_ns(ns: i64) -> Self {
        Instant(ns)
    }
    /// Nanoseconds since the origin.
    pub const fn as_ns(self) -> i64 {
        self.0
    }
    /// Span from the origin.
    pub const fn since_origin(self) -> Duration {
        Duration(self.0)
    }
    /// The end of the time line that timestamps from the wire may reach [ns, ≈ 73 years]:
    /// a quarter of the i64 range, so that a node's arithmetic on times up to it (a cycle
    /// index times the cycle, a sampling instant, a path delay added) cannot overflow.
    pub const HORIZON: Instant = Instant(i64::MAX / 4);
    /// From a timestamp carried on the wire (unsigned ns); `None` beyond [`Instant::HORIZON`].
    pub fn from_wire(ns: u64) -> Option<Self> {
        i64::try_from(ns)
            .ok()
            .filter(|t| *t <= Self::HORIZON.0)
            .map(Instant)
    }
    /// `self + d`, or `None` on overflow (for values that came from the wire).
    pub const fn checked_add(self, d: Duration) -> Option<Instant> {
        match self.0.checked_add(d.0) {
            Some(v) => Some(Instant(v)),
            None => None,
        }
    }
    /// `self − other`, or `None` on overflow.
    pub const fn checked_since(self, other: Instant) -> Option<Duration> {
        match self.0.checked_sub(other.0) {
            Some(v) => Some(Duration(v)),
            None => None,
        }
    }
}

impl fmt::Display for Instant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        Duration(self.0).fmt(f)
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        Instant(self.0 + d.0)
    }
}
impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        self.0 += d.0;
    }
}
impl Sub<Duration> for Instant {
    type Output = Instant;
    fn sub(self, d: Duration) -> Instant {
        Instant(self.0 - d.0)
    }
}
impl Sub for Instant {
    type Output = Duration;
    fn sub(self, other: Instant) -> Duration {
        Duration(self.0 - other.0)
    }
}

/// Why a duration string was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParseDurationError {
    /// No unit after the number.
    #[error("'{0}' has no unit: write e.g. 1ms, 250us, 800ns")]
    NoUnit(String),
    /// A unit other than ns, us, µs, ms, s.
    #[error("'{0}' has an unknown unit: use ns, us (or µs), ms or s")]
    BadUnit(String),
    /// Not a number.
    #[error("'{0}' is not a number followed by a unit, e.g. 1ms")]
    BadNumber(String),
    /// Finer than 1 ns.
    #[error("'{0}' is not a whole number of nanoseconds")]
    NotWholeNs(String),
    /// Beyond ±292 years.
    #[error("'{0}' is too large")]
    TooLarge(String),
}

impl core::str::FromStr for Duration {
    type Err = ParseDurationError;

    /// Parses `<number><unit>` with unit ns, us, µs, ms or s, e.g. `1ms`, `2.5us`, `-40ns`.
    /// The value must be a whole number of nanoseconds.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+'))
            .unwrap_or(t.len());
        let (num, unit) = t.split_at(split);
        let unit = unit.trim();
        if unit.is_empty() {
            return Err(ParseDurationError::NoUnit(s.to_string()));
        }
        let scale: i128 = match unit {
            "ns" => 1,
            "us" | "µs" | "μs" => 1_000,
            "ms" => 1_000_000,
            "s" => 1_000_000_000,
            _ => return Err(ParseDurationError::BadUnit(s.to_string())),
        };
        let value = parse_decimal_scaled(num, scale)
            .ok_or_else(|| ParseDurationError::BadNumber(s.to_string()))?;
        let Some(ns) = value else {
            return Err(ParseDurationError::NotWholeNs(s.to_string()));
        };
        i64::try_from(ns)
            .map(Duration)
            .map_err(|_| ParseDurationError::TooLarge(s.to_string()))
    }
}

/// `x.round() as i64` (half away from zero, saturating, NaN to 0) with integer arithmetic:
/// bit for bit the same, without the software `round` that a target without SSE4.1 calls
/// (3.8 % of a simulation's instructions went to it). For |x| < 2⁵², `x − trunc(x)` is exact,
/// so comparing it with ±0.5 decides the rounding exactly; larger values are integers.
#[inline]
pub fn round_i64(x: f64) -> i64 {
    let t = x as i64;
    let f = x - t as f64;
    if f >= 0.5 {
        t.saturating_add(1)
    } else if f <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Parses a plain decimal number (optional sign, digits, optional fraction; no exponent)
/// and multiplies it by `scale` exactly. `None`: not a number; `Some(None)`: the product is
/// not an integer.
pub(crate) fn parse_decimal_scaled(num: &str, scale: i128) -> Option<Option<i128>> {
    let (neg, digits) = match num.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, num.strip_prefix('+').unwrap_or(num)),
    };
    let (int, frac) = digits.split_once('.').unwrap_or((digits, ""));
    if int.is_empty() && frac.is_empty() {
        return None;
    }
    if !int.chars().chain(frac.chars()).all(|c| c.is_ascii_digit()) || int.len() + frac.len() > 30 {
        return None;
    }
    let mut v: i128 = 0;
    for c in int.chars().chain(frac.chars()) {
        v = v.checked_mul(10)?.checked_add(i128::from(c as u8 - b'0'))?;
    }
    let den = 10i128.checked_pow(frac.len() as u32)?;
    let scaled = v.checked_mul(scale)?;
    let out = if scaled % den == 0 {
        Some(scaled / den)
    } else {
        None
    };
    Some(out.map(|x| if neg { -x } else { x }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`round_i64`] against `f64::round` on values near every tie (k + 0.5 and its
    /// neighbours, both signs, small to beyond 2⁵³), the special values, and any bit pattern.
    #[test]
    fn integer_rounding_matches_round() {
        let check =
            |x: f64| assert_eq!(round_i64(x), x.round() as i64, "{x:e} ({:#x})", x.to_bits());
        for k in [
            0i64,
            1,
            2,
            3,
            7,
            1 << 20,
            1 << 40,
            (1 << 51) - 1,
            1 << 51,
            1 << 52,
            1 << 53,
        ] {
            for sign in [1.0, -1.0] {
                let tie = sign * (k as f64 + 0.5);
                for x in [tie, tie.next_up(), tie.next_down(), sign * k as f64] {
                    check(x);
                }
            }
        }
        for x in [
            0.0,
            -0.0,
            0.49999999999999994,
            -0.49999999999999994,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
            i64::MAX as f64,
            i64::MIN as f64,
            (i64::MAX as f64).next_down(),
            1e300,
            f64::MIN_POSITIVE,
        ] {
            check(x);
        }
    }

    proptest::proptest! {
        #[test]
        fn integer_rounding_matches_round_on_any_bits(bits: u64) {
            let x = f64::from_bits(bits);
            proptest::prop_assert_eq!(round_i64(x), x.round() as i64);
        }

        #[test]
        fn integer_rounding_matches_round_in_the_simulated_range(x in -1e13f64..1e13) {
            proptest::prop_assert_eq!(round_i64(x), x.round() as i64);
        }
    }

    #[test]
    fn parses_units() {
        let d = |s: &str| s.parse::<Duration>();
        assert_eq!(d("1ms"), Ok(Duration::from_ms(1)));
        assert_eq!(d("250us"), Ok(Duration::from_us(250)));
        assert_eq!(d("250 µs"), Ok(Duration::from_us(250)));
        assert_eq!(d("2.5us"), Ok(Duration::from_ns(2_500)));
        assert_eq!(d("240ns"), Ok(Duration::from_ns(240)));
        assert_eq!(d("0.001s"), Ok(Duration::from_ms(1)));
        assert_eq!(d("-40ns"), Ok(Duration::from_ns(-40)));
        assert_eq!(d("1000"), Err(ParseDurationError::NoUnit("1000".into())));
        assert_eq!(d("1h"), Err(ParseDurationError::BadUnit("1h".into())));
        assert_eq!(
            d("0.5ns"),
            Err(ParseDurationError::NotWholeNs("0.5ns".into()))
        );
        assert_eq!(d("ms"), Err(ParseDurationError::BadNumber("ms".into())));
        assert_eq!(
            d("1.2.3ms"),
            Err(ParseDurationError::BadNumber("1.2.3ms".into()))
        );
        assert!(matches!(
            d("99999999999s"),
            Err(ParseDurationError::TooLarge(_))
        ));
    }

    #[test]
    fn display_has_ns_resolution() {
        assert_eq!(Duration::from_ns(10_720).to_string(), "10.720 µs");
        assert_eq!(Duration::from_ns(-5).to_string(), "-0.005 µs");
        assert_eq!(Duration::from_ms(1).to_string(), "1000.000 µs");
    }

    #[test]
    fn arithmetic() {
        let t = Instant::ZERO + Duration::from_us(3);
        assert_eq!(t - Instant::from_ns(1_000), Duration::from_ns(2_000));
        assert_eq!(Duration::from_ns(7) * 3, Duration::from_ns(21));
        let s: Duration = [1, 2, 3].into_iter().map(Duration::from_ns).sum();
        assert_eq!(s, Duration::from_ns(6));
    }

    #[test]
    fn checked_arithmetic_for_wire_values() {
        assert_eq!(Instant::from_wire(5), Some(Instant::from_ns(5)));
        assert_eq!(Instant::from_wire(u64::MAX), None);
        assert_eq!(Instant::from_wire(1 << 63), None);
        assert_eq!(
            Instant::from_wire((i64::MAX / 4) as u64),
            Some(Instant::HORIZON)
        );
        assert_eq!(Instant::from_wire((i64::MAX / 4 + 1) as u64), None);
        let far = Instant::from_ns(i64::MAX - 1);
        assert_eq!(far.checked_add(Duration::from_ns(2)), None);
        assert_eq!(
            far.checked_add(Duration::from_ns(1)),
            Some(Instant::from_ns(i64::MAX))
        );
        assert_eq!(
            Instant::from_ns(i64::MIN).checked_since(Instant::from_ns(1)),
            None
        );
    }
}
