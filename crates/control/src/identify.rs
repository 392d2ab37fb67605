//! Identification of a torque-mode axis from a run: least squares on the axis model
//! (docs/system.md, "The reference scenario"; docs/control.md, "Identification")
//!
//! ```text
//! J·ẍ = K_a·u − b·ẋ − T_c·sgn(ẋ)   divided by K_a:   H·ẍ + C·ẋ + F·sgn(ẋ) = u
//! H = J/K_a [V·s²/rad],  C = b/K_a [V·s/rad],  F = T_c/K_a [V]
//! ```
//!
//! H, C and F are exactly the feed-forward gains K_H, K_C and K_F that cancel the axis
//! (eq. 9 with K_H = H, K_C = C; K_F is ringsync's Coulomb feed-forward), so nothing needs
//! K_a on its own.
//!
//! The positions are the encoder's (quantised to its resolution, as the master sees them),
//! one per cycle; the input is the command each cycle's slave applied, held from its
//! application time on. Differentiating quantised positions twice would drown the
//! acceleration in noise, so the model is integrated instead: over a window of ±T_m around
//! the sample k (T_m = m cycles) with the weight w(s) = T_m − |s|,
//!
//! ```text
//! ∫ w(s)·ẍ(t_k+s) ds = x(t_k+T_m) − 2·x(t_k) + x(t_k−T_m)                         (A_k)
//! ∫ w(s)·ẋ(t_k+s) ds = ∫_0^T_m x(t_k+s) ds − ∫_0^T_m x(t_k−s) ds   (trapezoid)  (V_k)
//! ∫ w(s)·sgn ẋ ds     = ±T_m² when the window moves one way only               (S_k)
//! ∫ w(s)·u(t_k+s) ds  = exact, u piecewise constant between application times   (Y_k)
//! ```
//!
//! so `Y_k = H·A_k + C·V_k + F·S_k`, a linear regression. Windows do not overlap (their
//! errors are independent, which the confidence intervals assume), and only windows in which
//! the axis moves one way at a speed of at least `v_min` count: at standstill the Coulomb
//! force is whatever holds the axis, not F. A run that does not tell H, C and F apart (too
//! little motion, acceleration at the encoder's noise, one speed only) is refused, with what
//! it lacks.

use nalgebra::{Matrix3, Vector3};

/// What one axis's run gives the identification: one sample per cycle.
#[derive(Debug, Clone, Copy)]
pub struct AxisRecord<'a> {
    /// Cycle start times t_k \[s\], increasing, evenly spaced by the cycle.
    pub t: &'a [f64],
    /// Position at each cycle start \[rad\] (quantised here to `resolution`).
    pub x: &'a [f64],
    /// Command computed in cycle k \[V\] (clipped here to ±`u_max`).
    pub u: &'a [f64],
    /// When cycle k's command took effect \[s\]; NaN when it never arrived (the previous one
    /// is then held).
    pub apply_time: &'a [f64],
    /// Encoder resolution [rad per count], > 0.
    pub resolution: f64,
    /// Drive range ±u_max \[V\], > 0.
    pub u_max: f64,
}

/// One identified parameter: estimate and 95 % confidence half-width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// The estimate.
    pub value: f64,
    /// Half-width of the 95 % confidence interval (1.96 standard errors).
    pub ci95: f64,
}

/// An axis identified: H, C, F and how well the model fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisIdentification {
    /// H = J/K_a [V·s²/rad]: the acceleration feed-forward K_H.
    pub h: Estimate,
    /// C = b/K_a [V·s/rad]: the velocity feed-forward K_C.
    pub c: Estimate,
    /// F = T_c/K_a \[V\]: the Coulomb feed-forward K_F.
    pub f: Estimate,
    /// Windows used.
    pub windows: usize,
    /// Half-width of a window T_m \[s\].
    pub half_window: f64,
    /// Least speed a window needed [rad/s].
    pub v_min: f64,
    /// RMS of the fit's residual, as an equivalent voltage \[V\] (residual / T_m²).
    pub residual_v: f64,
}

/// Why an axis cannot be identified from a run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IdentifyError {
    /// Inconsistent or too short records.
    #[error("{0}")]
    BadRecord(String),
    /// The run does not excite the axis enough to tell H, C and F apart.
    #[error("not enough excitation: {0}")]
    NotExcited(String),
}

/// Fewest windows an identification takes.
pub const MIN_WINDOWS: usize = 30;

/// The longest half-width of a window T_m tried \[s\]. The encoder's quantisation weighs on
/// the acceleration's integral as 1/T_m², so longer windows fit better as long as enough of
/// them remain: T_m is halved from this until [`GOOD_WINDOWS`] windows count (down to two
/// cycles, and then at least [`MIN_WINDOWS`]).
pub const HALF_WINDOW: f64 = 20e-3;

/// Windows a half-width should give before a longer one is preferred to a shorter one.
pub const GOOD_WINDOWS: usize = 60;

/// Largest part of the RMS input an uncertain parameter may explain (its 95 % half-width
/// times its regressor's RMS) before the run counts as not exciting it.
pub const MAX_UNCERTAIN_SHARE: f64 = 0.05;

/// Identifies one torque axis from its record (see the module's docs).
pub fn identify_axis(r: &AxisRecord<'_>) -> Result<AxisIdentification, IdentifyError> {
    let n = r.t.len();
    for (what, len) in [
        ("x", r.x.len()),
        ("u", r.u.len()),
        ("apply_time", r.apply_time.len()),
    ] {
        if len != n {
            return Err(IdentifyError::BadRecord(format!(
                "{what} has {len} samples, t has {n}"
            )));
        }
    }
    if !(r.resolution > 0.0 && r.resolution.is_finite() && r.u_max > 0.0) {
        return Err(IdentifyError::BadRecord(format!(
            "encoder resolution {} rad and drive range {} V must be > 0",
            r.resolution, r.u_max
        )));
    }
    if n < 3 {
        return Err(IdentifyError::BadRecord(format!(
            "{n} samples: too short a run"
        )));
    }
    let dt = (r.t[n - 1] - r.t[0]) / (n - 1) as f64;
    if !(dt > 0.0 && dt.is_finite())
        || r.t
            .windows(2)
            .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(IdentifyError::BadRecord(
            "cycle times must increase".to_string(),
        ));
    }
    let q = r.resolution;
    let xq: Vec<f64> = r.x.iter().map(|x| (x / q).floor() * q).collect();
    let input = Input::new(r);
    let peak = xq
        .windows(2)
        .map(|w| ((w[1] - w[0]) / dt).abs())
        .fold(0.0, f64::max);
    let mut m = ((HALF_WINDOW / dt).round() as usize).max(2);
    let (mut rows, mut tm, mut v_min) = windows(r, &xq, &input, m, dt, peak);
    while rows.len() < GOOD_WINDOWS && m > 2 {
        m = (m / 2).max(2);
        let shorter = windows(r, &xq, &input, m, dt, peak);
        if shorter.0.len() > rows.len() {
            (rows, tm, v_min) = shorter;
        }
    }
    if rows.len() < MIN_WINDOWS {
        return Err(IdentifyError::NotExcited(format!(
            "{} windows of ±{:.1} ms in which the axis moves one way at {:.3} rad/s or faster; {MIN_WINDOWS} needed (a longer run, or one that moves more)",
            rows.len(),
            tm * 1e3,
            v_min
        )));
    }
    fit(rows, tm, v_min, q)
}

/// The regression rows (A, V, S; Y) of the non-overlapping windows of half-width m cycles
/// in which the axis moves one way at v_min or faster (20 counts over the window at least,
/// and 2 % of the run's peak speed); with T_m [s] and v_min [rad/s].
#[allow(clippy::type_complexity)]
fn windows(
    r: &AxisRecord<'_>,
    xq: &[f64],
    input: &Input,
    m: usize,
    dt: f64,
    peak: f64,
) -> (Vec<([f64; 3], f64)>, f64, f64) {
    let n = xq.len();
    let q = r.resolution;
    let tm = m as f64 * dt;
    let v_min = (20.0 * q / (2.0 * tm)).max(0.02 * peak);
    let mut rows: Vec<([f64; 3], f64)> = Vec::new();
    let mut k = m;
    while k + m < n {
        let span = &xq[k - m..=k + m];
        let dir = (span[2 * m] - span[0]).signum();
        let moving = span.windows(2).all(|w| (w[1] - w[0]) * dir > 0.0)
            && (span[2 * m] - span[0]).abs() / (2.0 * tm) >= v_min;
        if moving {
            let a = span[2 * m] - 2.0 * span[m] + span[0];
            let trapezoid = |side: &[f64]| {
                dt * (side.iter().sum::<f64>() - 0.5 * (side[0] + side[side.len() - 1]))
            };
            let v = trapezoid(&span[m..]) - trapezoid(&span[..=m]);
            let s = dir * tm * tm;
            rows.push(([a, v, s], input.weighted(r.t[k], tm)));
        }
        k += 2 * m;
    }
    (rows, tm, v_min)
}

/// Least squares on the rows, the excitation checks, the intervals.
fn fit(
    rows: Vec<([f64; 3], f64)>,
    tm: f64,
    v_min: f64,
    q: f64,
) -> Result<AxisIdentification, IdentifyError> {
    // Least squares on columns scaled to unit RMS (conditioning), then scaled back.
    let rms =
        |j: usize| (rows.iter().map(|(x, _)| x[j] * x[j]).sum::<f64>() / rows.len() as f64).sqrt();
    let scale = Vector3::new(rms(0), rms(1), rms(2));
    let noise_a = q * 0.5_f64.sqrt();
    if scale[0] < 30.0 * noise_a {
        return Err(IdentifyError::NotExcited(format!(
            "the acceleration is at the encoder's noise level (RMS {:.3e} rad of second difference over ±{:.1} ms against {:.3e} rad of quantisation): H cannot be found; the run needs the axis to speed up and slow down",
            scale[0],
            tm * 1e3,
            noise_a
        )));
    }
    let mut xtx = Matrix3::<f64>::zeros();
    let mut xty = Vector3::<f64>::zeros();
    for (x, y) in &rows {
        let z = Vector3::new(x[0] / scale[0], x[1] / scale[1], x[2] / scale[2]);
        xtx += z * z.transpose();
        xty += z * *y;
    }
    let names = ["H (acceleration)", "C (speed)", "F (Coulomb)"];
    let eig = xtx.symmetric_eigen();
    let (imin, lmin) =
        eig.eigenvalues
            .iter()
            .enumerate()
            .fold(
                (0, f64::INFINITY),
                |acc, (i, &l)| if l < acc.1 { (i, l) } else { acc },
            );
    if lmin < 1e-6 * rows.len() as f64 {
        let v = eig.eigenvectors.column(imin);
        let mut parts: Vec<&str> = (0..3)
            .filter(|&j| v[j].abs() > 0.3)
            .map(|j| names[j])
            .collect();
        parts.sort_unstable();
        return Err(IdentifyError::NotExcited(format!(
            "{} cannot be told apart in this run (the motion keeps them in proportion); the run needs several speeds, both ways",
            parts.join(" and ")
        )));
    }
    let inv = xtx
        .try_inverse()
        .ok_or_else(|| IdentifyError::NotExcited("the regression is singular".to_string()))?;
    let theta_z = inv * xty;
    let dof = (rows.len() - 3) as f64;
    let rss: f64 = rows
        .iter()
        .map(|(x, y)| {
            let z = Vector3::new(x[0] / scale[0], x[1] / scale[1], x[2] / scale[2]);
            (y - z.dot(&theta_z)).powi(2)
        })
        .sum();
    let sigma2 = rss / dof;
    let y_rms = (rows.iter().map(|(_, y)| y * y).sum::<f64>() / rows.len() as f64).sqrt();
    let mut est = [Estimate {
        value: 0.0,
        ci95: 0.0,
    }; 3];
    for j in 0..3 {
        let half_z = 1.96 * (sigma2 * inv[(j, j)]).sqrt();
        est[j] = Estimate {
            value: theta_z[j] / scale[j],
            ci95: half_z / scale[j],
        };
        // The uncertain part of this parameter's share of the input, against the input.
        if half_z > MAX_UNCERTAIN_SHARE * y_rms {
            return Err(IdentifyError::NotExcited(format!(
                "{} is uncertain by ±{:.0} % of the input it explains; the run needs more motion of that kind",
                names[j],
                100.0 * half_z / y_rms
            )));
        }
    }
    Ok(AxisIdentification {
        h: est[0],
        c: est[1],
        f: est[2],
        windows: rows.len(),
        half_window: tm,
        v_min,
        residual_v: (rss / rows.len() as f64).sqrt() / (tm * tm),
    })
}

/// The applied input: piecewise constant, each command (clipped to the drive's range) held
/// from its application time until the next one's.
struct Input {
    /// (from [s], u [V]), in time order.
    steps: Vec<(f64, f64)>,
}

impl Input {
    fn new(r: &AxisRecord<'_>) -> Self {
        let mut steps: Vec<(f64, f64)> = r
            .apply_time
            .iter()
            .zip(r.u)
            .filter(|(a, u)| a.is_finite() && u.is_finite())
            .map(|(&a, &u)| (a, u.clamp(-r.u_max, r.u_max)))
            .collect();
        steps.sort_by(|a, b| a.0.total_cmp(&b.0));
        Input { steps }
    }

    /// ∫ (T_m − |s|)·u(t + s) ds over |s| ≤ T_m [V·s²].
    fn weighted(&self, t: f64, tm: f64) -> f64 {
        weighted_input(&self.steps, t, tm)
    }
}

/// ∫ (T_m − |s|)·u(t + s) ds over |s| ≤ T_m [V·s²] of a piecewise-constant input given as
/// `steps` (from [s], u [V]) in time order: each held until the next; 0 V before the first.
/// Exact. Shared by the identification and the disturbance observer.
pub(crate) fn weighted_input(steps: &[(f64, f64)], t: f64, tm: f64) -> f64 {
    // W(s) = T_m·s − s·|s|/2, the weight's antiderivative.
    let w = |s: f64| tm * s - s * s.abs() / 2.0;
    let (lo, hi) = (t - tm, t + tm);
    // The step in effect at lo: the last one applied at or before it (0 V before any).
    let first = steps.partition_point(|s| s.0 <= lo);
    let mut u = if first == 0 { 0.0 } else { steps[first - 1].1 };
    let mut from = lo;
    let mut sum = 0.0;
    for &(at, next) in &steps[first..] {
        if at >= hi {
            break;
        }
        sum += u * (w(at - t) - w(from - t));
        from = at;
        u = next;
    }
    sum + u * (w(hi - t) - w(from - t))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A torque axis H·ẍ + C·ẋ + F·sgn(ẋ) = u under PD on a cosine, stepped finely, with
    /// the command applied `delay` after each cycle start.
    fn record(
        h: f64,
        c: f64,
        f: f64,
        cycles: usize,
        delay: f64,
        peak: f64,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let dt = 1e-3;
        let (p, a) = (2.0, peak * 2.0 / std::f64::consts::TAU);
        let w = std::f64::consts::TAU / p;
        let (mut x, mut v, mut held) = (0.0_f64, 0.0_f64, 0.0);
        let (mut ts, mut xs, mut us, mut ap) = (vec![], vec![], vec![], vec![]);
        let sub = 100;
        for k in 0..cycles {
            let t = k as f64 * dt;
            let xd = a * (1.0 - (w * t).cos());
            let vd = a * w * (w * t).sin();
            let u = 3.0 * (xd - x) + 1.5 * (vd - v);
            ts.push(t);
            xs.push(x);
            us.push(u);
            ap.push(t + delay);
            for j in 0..sub {
                let tj = t + j as f64 * dt / sub as f64;
                let uj = if tj < t + delay {
                    held
                } else {
                    u.clamp(-10.0, 10.0)
                };
                let acc = (uj - c * v - f * v.signum()) / h;
                v += acc * dt / sub as f64;
                x += v * dt / sub as f64;
            }
            held = u.clamp(-10.0, 10.0);
        }
        (ts, xs, us, ap)
    }

    fn run(h: f64, c: f64, f: f64, peak: f64) -> Result<AxisIdentification, IdentifyError> {
        let (t, x, u, a) = record(h, c, f, 4000, 150e-6, peak);
        identify_axis(&AxisRecord {
            t: &t,
            x: &x,
            u: &u,
            apply_time: &a,
            resolution: std::f64::consts::TAU / f64::from(1u32 << 20),
            u_max: 10.0,
        })
    }

    #[test]
    fn recovers_the_axis_it_was_given() {
        let id = run(0.0164, 0.05, 0.2, 15.12).expect("identified");
        assert!((id.h.value / 0.0164 - 1.0).abs() < 0.01, "{id:?}");
        assert!((id.c.value / 0.05 - 1.0).abs() < 0.05, "{id:?}");
        assert!((id.f.value / 0.2 - 1.0).abs() < 0.05, "{id:?}");
        // The true values lie inside the intervals (allowing for the Euler stepping).
        assert!(
            (id.h.value - 0.0164).abs() < 2.0 * id.h.ci95 + 1e-4,
            "{id:?}"
        );
        assert!(id.windows >= GOOD_WINDOWS, "{id:?}");
    }

    #[test]
    fn a_still_axis_is_refused() {
        let e = run(0.0164, 0.05, 0.2, 1e-4).expect_err("refused");
        assert!(matches!(e, IdentifyError::NotExcited(_)), "{e}");
        assert!(e.to_string().contains("windows"), "{e}");
    }

    #[test]
    fn the_applied_input_is_integrated_exactly() {
        let r = AxisRecord {
            t: &[0.0, 1.0],
            x: &[0.0, 0.0],
            u: &[1.0, 3.0],
            apply_time: &[0.25, f64::NAN],
            resolution: 1.0,
            u_max: 2.0,
        };
        let i = Input::new(&r);
        // 0 V until 0.25 s, then 1 V: ∫_{0.25}^{1} (1 − |s|) ds = 0.28125.
        assert!((i.weighted(0.0, 1.0) - 0.28125).abs() < 1e-15);
        // A constant input u gives u·T_m².
        let r = AxisRecord {
            apply_time: &[-5.0, f64::NAN],
            u: &[5.0, 0.0],
            ..r
        };
        assert!(
            (Input::new(&r).weighted(0.0, 0.5) - 2.0 * 0.25).abs() < 1e-15,
            "clipped to 2 V"
        );
        let bad = AxisRecord { x: &[0.0], ..r };
        assert!(matches!(
            identify_axis(&bad),
            Err(IdentifyError::BadRecord(_))
        ));
    }
}
