//! Line charts as SVG: time series of the runs (the paper's Fig. 3-5).

use crate::svg::{Svg, nice_step};

/// One line of a chart.
pub struct Series<'a> {
    /// Legend text.
    pub name: String,
    /// Colour (SVG).
    pub colour: &'a str,
    /// (x, y) points in order of x.
    pub points: Vec<(f64, f64)>,
}

/// Colours for up to 8 axes.
pub const PALETTE: [&str; 8] = [
    "#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#76b7b2", "#edc948", "#b07aa1", "#9c755f",
];

const W: f64 = 760.0;
const H: f64 = 360.0;
const L: f64 = 78.0;
const R: f64 = 150.0;
const T: f64 = 40.0;
const B: f64 = 50.0;

/// Keeps at most `max` points: every k-th, plus the extremes of each bucket, so that peaks
/// survive the thinning.
fn thin(points: &[(f64, f64)], max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max {
        return points.to_vec();
    }
    let bucket = points.len().div_ceil(max / 2);
    let mut out = Vec::with_capacity(max + 2);
    for chunk in points.chunks(bucket) {
        let (mut lo, mut hi) = (chunk[0], chunk[0]);
        for &p in chunk {
            if p.1 < lo.1 {
                lo = p;
            }
            if p.1 > hi.1 {
                hi = p;
            }
        }
        if lo.0 <= hi.0 {
            out.extend([lo, hi]);
        } else {
            out.extend([hi, lo]);
        }
    }
    out
}

fn fmt_tick(v: f64, step: f64) -> String {
    let digits = if step >= 1.0 {
        0
    } else {
        (-step.log10()).ceil() as usize
    };
    // A tick at zero reached by adding steps may be −1e-17: print it as 0, not -0.
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    format!("{v:.digits$}")
}

/// A line chart: title, axis labels with units, series. Returns the SVG document.
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series<'_>]) -> String {
    let mut s = Svg::new(W, H);
    let pw = W - L - R;
    let ph = H - T - B;
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for se in series {
        for &(x, y) in &se.points {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if y1 - y0 < 1e-12 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let x1 = if x1 > x0 { x1 } else { x0 + 1.0 };
    let px = |x: f64| L + (x - x0) / (x1 - x0) * pw;
    let py = |y: f64| T + (y1 - y) / (y1 - y0) * ph;
    s.text(
        L,
        22.0,
        title,
        "start",
        r#"font-size="13" font-weight="bold""#,
    );
    // Grid and ticks.
    let xs = nice_step(x1 - x0, 8.0);
    let mut x = (x0 / xs).ceil() * xs;
    while x <= x1 + 1e-12 {
        s.line(px(x), T, px(x), T + ph, r##"stroke="#eeeeee""##);
        s.text(px(x), T + ph + 16.0, &fmt_tick(x, xs), "middle", "");
        x += xs;
    }
    let ys = nice_step(y1 - y0, 6.0);
    let mut y = (y0 / ys).ceil() * ys;
    while y <= y1 + 1e-15 {
        s.line(L, py(y), L + pw, py(y), r##"stroke="#eeeeee""##);
        s.text(L - 6.0, py(y) + 4.0, &fmt_tick(y, ys), "end", "");
        y += ys;
    }
    s.line(L, T + ph, L + pw, T + ph, r#"stroke="black""#);
    s.line(L, T, L, T + ph, r#"stroke="black""#);
    s.text(L + pw / 2.0, H - 12.0, x_label, "middle", "");
    s.text(
        16.0,
        T + ph / 2.0,
        y_label,
        "middle",
        &format!(r#"transform="rotate(-90 16 {:.1})""#, T + ph / 2.0),
    );
    for (k, se) in series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = thin(&se.points, 1200)
            .into_iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .map(|(x, y)| (px(x), py(y)))
            .collect();
        s.polyline(
            &pts,
            &format!(r#"fill="none" stroke="{}" stroke-width="1.2""#, se.colour),
        );
        let ly = T + 10.0 + 18.0 * k as f64;
        s.line(
            L + pw + 12.0,
            ly,
            L + pw + 32.0,
            ly,
            &format!(r#"stroke="{}" stroke-width="2""#, se.colour),
        );
        s.text(L + pw + 38.0, ly + 4.0, &se.name, "start", "");
    }
    s.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_the_peaks_and_the_count_bounded() {
        let pts: Vec<(f64, f64)> = (0..10_000)
            .map(|i| {
                (
                    i as f64,
                    if i == 7777 {
                        50.0
                    } else {
                        (i as f64 * 0.01).sin()
                    },
                )
            })
            .collect();
        let t = thin(&pts, 1000);
        assert!(t.len() <= 1002, "{}", t.len());
        assert!(t.iter().any(|p| p.1 == 50.0), "the spike survived");
        assert!(t.windows(2).all(|w| w[0].0 <= w[1].0), "in order");
    }

    #[test]
    fn zero_tick_has_no_sign() {
        assert_eq!(fmt_tick(-1e-17, 0.5), "0.0");
        assert_eq!(fmt_tick(-0.5, 0.5), "-0.5");
    }

    #[test]
    fn chart_has_title_labels_and_series() {
        let svg = line_chart(
            "e <test>",
            "t [s]",
            "e [rad]",
            &[Series {
                name: "axis 1".into(),
                colour: PALETTE[0],
                points: vec![(0.0, 0.0), (1.0, 2.0)],
            }],
        );
        assert!(
            svg.contains("e &lt;test&gt;") && svg.contains("axis 1") && svg.contains("<polyline")
        );
        // Degenerate input does not break it.
        let empty = line_chart("x", "t", "y", &[]);
        assert!(empty.ends_with("</svg>\n"));
    }
}
