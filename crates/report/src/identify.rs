//! The text of `ringsync identify`: per axis the estimates of H = J/K_a, C = b/K_a and
//! F = T_c/K_a with their 95 % intervals, beside the scenario's values.

use std::fmt::Write as _;

use ringsync_control::identify::AxisIdentification;

/// One axis for [`identify_text`]: (axis, 1-based; the estimates; the scenario's (H, C, F)).
pub type AxisRow = (usize, AxisIdentification, (f64, f64, f64));

/// The estimate `e`'s error against the scenario's `t` in per cent, to 2 decimals with its
/// sign; one that rounds to zero is `+0.00 %`, never `-0.00 %`; `–` when `t` is 0.
fn pct_error(e: f64, t: f64) -> String {
    if t == 0.0 {
        return "–".to_string();
    }
    let pct = (e / t - 1.0) * 100.0;
    let pct = if pct.abs() < 0.005 { 0.0 } else { pct };
    format!("{pct:+.2} %")
}

/// A table of the estimates beside the scenario's values, with each estimate's error
/// against them; then what the fit used.
pub fn identify_text(rows: &[AxisRow]) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "| axis | H = J/K_a [V·s²/rad] | scenario | error | C = b/K_a [V·s/rad] | scenario | error | F = T_c/K_a [V] | scenario | error |"
    );
    let _ = writeln!(o, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let err = pct_error;
    for (axis, id, (h, c, f)) in rows {
        let _ = writeln!(
            o,
            "| {axis} | {:.6} ± {:.1e} | {h:.6} | {} | {:.3e} ± {:.1e} | {c:.3e} | {} | {:.4} ± {:.1e} | {f:.4} | {} |",
            id.h.value,
            id.h.ci95,
            err(id.h.value, *h),
            id.c.value,
            id.c.ci95,
            err(id.c.value, *c),
            id.f.value,
            id.f.ci95,
            err(id.f.value, *f),
        );
    }
    if let Some((_, id, _)) = rows.first() {
        let _ = writeln!(
            o,
            "\n± is the 95 % interval. Fit: {} windows of ±{:.1} ms moving one way at ≥ {:.3} rad/s (axis 1), positions quantised to the encoder; residual {:.1} mV RMS (axis 1). \"scenario\" is the simulated plant's value.",
            id.windows,
            id.half_window * 1e3,
            id.v_min,
            id.residual_v * 1e3
        );
    }
    o
}

#[cfg(test)]
mod tests {
    use super::pct_error;

    /// An estimate a hair below its value reads +0.00 %, not -0.00 % (issue 41).
    #[test]
    fn errors_that_round_to_zero_have_no_minus_sign() {
        assert_eq!(pct_error(0.999_99, 1.0), "+0.00 %");
        assert_eq!(pct_error(1.000_01, 1.0), "+0.00 %");
        assert_eq!(pct_error(0.98, 1.0), "-2.00 %");
        assert_eq!(pct_error(1.0, 0.0), "–");
    }
}
