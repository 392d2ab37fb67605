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
    /// The extent (x min, x max, y min, y max) of every finite point the series had before
    /// it was thinned ([`Thinning`]); `None`: `points` are all of them.
    pub extent: Option<[f64; 4]>,
}

/// Most points [`line_chart`] draws per series.
const MAX_POINTS: usize = 1200;

/// A series thinned as it is built, as [`line_chart`] would thin it whole: a long run's
/// figures never hold every point of a column (a 600 s run of 4 axes: 38 MB per figure).
#[derive(Debug)]
pub struct Thinning {
    /// Points per bucket (0: keep every point).
    bucket: usize,
    in_bucket: usize,
    lo: (f64, f64),
    hi: (f64, f64),
    out: Vec<(f64, f64)>,
    extent: [f64; 4],
}

impl Thinning {
    /// For a series of `len` points, pushed in order.
    pub fn new(len: usize) -> Self {
        let bucket = if len <= MAX_POINTS {
            0
        } else {
            len.div_ceil(MAX_POINTS / 2)
        };
        Thinning {
            bucket,
            in_bucket: 0,
            lo: (0.0, 0.0),
            hi: (0.0, 0.0),
            out: Vec::with_capacity(len.min(MAX_POINTS + 2)),
            extent: [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
        }
    }

    /// The next point.
    pub fn push(&mut self, p: (f64, f64)) {
        if p.0.is_finite() && p.1.is_finite() {
            let e = &mut self.extent;
            e[0] = e[0].min(p.0);
            e[1] = e[1].max(p.0);
            e[2] = e[2].min(p.1);
            e[3] = e[3].max(p.1);
        }
        if self.bucket == 0 {
            self.out.push(p);
            return;
        }
        if self.in_bucket == 0 {
            (self.lo, self.hi) = (p, p);
        } else {
            if p.1 < self.lo.1 {
                self.lo = p;
            }
            if p.1 > self.hi.1 {
                self.hi = p;
            }
        }
        self.in_bucket += 1;
        if self.in_bucket == self.bucket {
            self.flush();
        }
    }

    fn flush(&mut self) {
        if self.in_bucket == 0 {
            return;
        }
        if self.lo.0 <= self.hi.0 {
            self.out.extend([self.lo, self.hi]);
        } else {
            self.out.extend([self.hi, self.lo]);
        }
        self.in_bucket = 0;
    }

    /// The series, named and coloured.
    pub fn finish<'a>(mut self, name: String, colour: &'a str) -> Series<'a> {
        self.flush();
        Series {
            name,
            colour,
            points: self.out,
            extent: (self.bucket > 0).then_some(self.extent),
        }
    }
}

/// Colours for up to 8 axes: matplotlib's default cycle (tab10), which the Python
/// package's plots use and the live scope's page starts with, so that an axis has one
/// colour everywhere.
pub const PALETTE: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
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

/// Widens the extent (x0, x1, y0, y1) to hold (x, y) when both are finite.
pub(crate) fn widen(x0: &mut f64, x1: &mut f64, y0: &mut f64, y1: &mut f64, x: f64, y: f64) {
    if x.is_finite() && y.is_finite() {
        *x0 = x0.min(x);
        *x1 = x1.max(x);
        *y0 = y0.min(y);
        *y1 = y1.max(y);
    }
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
        if let Some([a, b, c, d]) = se.extent {
            x0 = x0.min(a);
            x1 = x1.max(b);
            y0 = y0.min(c);
            y1 = y1.max(d);
            continue;
        }
        for &(x, y) in &se.points {
            widen(&mut x0, &mut x1, &mut y0, &mut y1, x, y);
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
        let pts: Vec<(f64, f64)> = thin(&se.points, MAX_POINTS)
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

    /// A series thinned as it is built draws the same chart as the whole series, for
    /// lengths around the thinning threshold and with NaN points, long and short.
    #[test]
    fn thinning_as_built_draws_what_the_whole_series_draws() {
        for len in [0, 1, 7, 1199, 1200, 1201, 1800, 4001, 60_000] {
            let pts: Vec<(f64, f64)> = (0..len)
                .map(|i| {
                    let y = if i % 977 == 5 {
                        f64::NAN
                    } else {
                        (i as f64 * 0.003).sin() * (1.0 + i as f64 * 1e-4)
                    };
                    (i as f64 * 1e-3, y)
                })
                .collect();
            let whole = Series {
                name: "a".into(),
                colour: PALETTE[0],
                points: pts.clone(),
                extent: None,
            };
            let mut t = Thinning::new(len);
            for p in &pts {
                t.push(*p);
            }
            let built = t.finish("a".into(), PALETTE[0]);
            assert!(built.points.len() <= MAX_POINTS + 2, "{len}");
            assert_eq!(
                line_chart("t", "x", "y", &[whole]),
                line_chart("t", "x", "y", &[built]),
                "{len} points"
            );
        }
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
                extent: None,
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
