//! Charts as SVG, drawn with plotters: time series of the runs (the paper's Fig. 3-5),
//! a sweep's means with their spread.

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
    /// ± at each point, drawn as error bars (empty: none).
    pub errors: Vec<f64>,
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
            errors: Vec::new(),
        }
    }
}

/// Colours for up to 8 axes: matplotlib's default cycle (tab10), which the Python
/// package's plots use and the live scope's page starts with, so that an axis has one
/// colour everywhere.
pub const PALETTE: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
];

/// Width and height of a chart [px].
const W: u32 = 900;
const H: u32 = 400;

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

/// Widens the extent (x0, x1, y0, y1) to hold (x, y) when both are finite.
pub(crate) fn widen(x0: &mut f64, x1: &mut f64, y0: &mut f64, y1: &mut f64, x: f64, y: f64) {
    if x.is_finite() && y.is_finite() {
        *x0 = x0.min(x);
        *x1 = x1.max(x);
        *y0 = y0.min(y);
        *y1 = y1.max(y);
    }
}

/// The extent (x min, x max, y min, y max) of every finite point of `series` (error bars
/// included); `None` when there is none. Charts meant to be compared share it
/// ([`Chart::y_range`]).
pub fn extent(series: &[Series<'_>]) -> Option<[f64; 4]> {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for se in series {
        if let Some([a, b, c, d]) = se.extent {
            widen(&mut x0, &mut x1, &mut y0, &mut y1, a, c);
            widen(&mut x0, &mut x1, &mut y0, &mut y1, b, d);
            continue;
        }
        for (k, &(x, y)) in se.points.iter().enumerate() {
            let e = se.errors.get(k).copied().unwrap_or(0.0).abs();
            widen(&mut x0, &mut x1, &mut y0, &mut y1, x, y - e);
            widen(&mut x0, &mut x1, &mut y0, &mut y1, x, y + e);
        }
    }
    x0.is_finite().then_some([x0, x1, y0, y1])
}

/// How a chart draws beyond its series: shared ranges, a log axis, categories, markers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Chart {
    /// The y range (before the 5 % margin); `None`: the series' own.
    pub y_range: Option<(f64, f64)>,
    /// A logarithmic x axis, base 2, ticks at the values: drawn when every x is a power of
    /// 2 times the least (ring sizes, cycles), else the axis stays linear.
    pub x_log: bool,
    /// Categories of x: x = 0, 1, … is drawn as these names.
    pub x_categories: Option<Vec<String>>,
    /// A marker at every point (and the error bars' caps).
    pub markers: bool,
    /// A dashed horizontal line at this y, with its legend text.
    pub hline: Option<(f64, String)>,
}

/// An `#rrggbb` colour for plotters (grey when it is not one).
fn rgb(c: &str) -> plotters::style::RGBColor {
    let h = c.trim_start_matches('#');
    let p = |i: usize| h.get(i..i + 2).and_then(|s| u8::from_str_radix(s, 16).ok());
    match (h.len(), p(0), p(2), p(4)) {
        (6, Some(r), Some(g), Some(b)) => plotters::style::RGBColor(r, g, b),
        _ => plotters::style::RGBColor(128, 128, 128),
    }
}

/// A tick label with the digits a step of `step` needs (a tick at zero reached by adding
/// steps may be −1e-17: printed as 0, not -0).
fn fmt_tick(v: f64, step: f64) -> String {
    let digits = if step >= 1.0 || !step.is_finite() || step <= 0.0 {
        0
    } else {
        (-step.log10()).ceil() as usize
    };
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    format!("{v:.digits$}")
}

/// A line chart: title, axis labels with units, series. Returns the SVG document.
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series<'_>]) -> String {
    chart(title, x_label, y_label, series, &Chart::default())
}

/// A chart of `series` drawn with plotters: lines (thinned to at most 1 200 points each),
/// with [`Chart`]'s options; the legend to the right of the plot, as wide as its longest
/// entry. Returns the SVG document.
pub fn chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series<'_>],
    opts: &Chart,
) -> String {
    // A log axis is drawn as a linear one over log_b(x), b = 2 when every x is a power of 2
    // times the least (ring sizes, cycles), else 10, labelled b^k at whole k: the ticks fall
    // on the values a sweep takes.
    let finite_x = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .filter(|x| x.is_finite())
    };
    let lo = finite_x().fold(f64::INFINITY, f64::min);
    let doubling = finite_x().all(|x| {
        let r = (x / lo).log2();
        (r - r.round()).abs() < 1e-9
    });
    let log = opts.x_log && opts.x_categories.is_none() && lo > 0.0 && doubling;
    let base = 2.0f64;
    let logged: Vec<Series<'_>>;
    let series = if log {
        logged = series
            .iter()
            .map(|s| Series {
                name: s.name.clone(),
                colour: s.colour,
                points: s.points.iter().map(|&(x, y)| (x.log(base), y)).collect(),
                extent: s
                    .extent
                    .map(|[a, b, c, d]| [a.log(base), b.log(base), c, d]),
                errors: s.errors.clone(),
            })
            .collect();
        &logged[..]
    } else {
        series
    };
    let [mut x0, mut x1, mut y0, mut y1] = extent(series).unwrap_or([0.0, 1.0, 0.0, 1.0]);
    if let Some((a, b)) = opts.y_range {
        (y0, y1) = (a.min(y0), b.max(y1));
    }
    if let Some((v, _)) = &opts.hline {
        (y0, y1) = (y0.min(*v), y1.max(*v));
    }
    if y1 - y0 < 1e-12 * y1.abs().max(1e-300) {
        let d = if y1 == 0.0 { 1.0 } else { y1.abs() * 0.5 };
        (y0, y1) = (y0 - d, y1 + d);
    }
    let pad = 0.05 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    if let Some(c) = &opts.x_categories {
        (x0, x1) = (-0.5, c.len().max(1) as f64 - 0.5);
    } else if x1 <= x0 {
        (x0, x1) = (x0 - 0.5, x0 + 0.5);
    } else if opts.markers {
        // Room for the first and last markers.
        let m = 0.04 * (x1 - x0);
        (x0, x1) = (x0 - m, x1 + m);
    }
    let mut legend: Vec<(String, String, bool)> = series
        .iter()
        .map(|s| (s.name.clone(), s.colour.to_string(), false))
        .collect();
    if let Some((_, name)) = &opts.hline {
        legend.push((name.clone(), "#555555".into(), true));
    }
    let longest = legend
        .iter()
        .map(|l| l.0.chars().count())
        .max()
        .unwrap_or(0);
    let legend_w = if legend.is_empty() {
        20
    } else {
        (longest as u32 * 7 + 44).clamp(90, 340)
    };
    let mut out = String::new();
    {
        use plotters::prelude::*;
        let root = SVGBackend::with_string(&mut out, (W, H)).into_drawing_area();
        let _ = root.fill(&WHITE);
        let (plot, side) = root.split_horizontally(W - legend_w);
        let text = |size: u32| ("sans-serif", size).into_font();
        macro_rules! builder {
            () => {{
                let mut b = ChartBuilder::on(&plot);
                b.caption(title, text(15).style(FontStyle::Bold))
                    .margin(12)
                    .x_label_area_size(44)
                    .y_label_area_size(78);
                b
            }};
        }
        // Digits enough for ticks a twentieth of the range apart, whichever plotters picks.
        let y_step = (y1 - y0) / 20.0;
        let x_step = (x1 - x0) / 20.0;
        let cats = opts.x_categories.clone();
        macro_rules! body {
            ($ch:expr) => {{
                let mut ch = $ch;
                let yf = |v: &f64| fmt_tick(*v, y_step);
                let mut mesh = ch.configure_mesh();
                mesh.x_desc(x_label)
                    .y_desc(y_label)
                    .label_style(text(12))
                    .axis_desc_style(text(13))
                    .light_line_style(WHITE.mix(0.0))
                    .bold_line_style(BLACK.mix(0.08))
                    .y_label_formatter(&yf);
                let xf = |v: &f64| match &cats {
                    Some(c) => {
                        let k = v.round();
                        if (v - k).abs() < 1e-6 && k >= 0.0 {
                            c.get(k as usize).cloned().unwrap_or_default()
                        } else {
                            String::new()
                        }
                    }
                    None if log => {
                        let k = v.round();
                        if (v - k).abs() < 1e-6 {
                            let x = base.powf(k);
                            let s = format!("{}", (x * 1e9).round() / 1e9);
                            if s.len() > 9 { format!("{x:.2e}") } else { s }
                        } else {
                            String::new()
                        }
                    }
                    None => fmt_tick(*v, x_step),
                };
                mesh.x_label_formatter(&xf);
                if let Some(c) = &cats {
                    mesh.x_labels(c.len() + 1);
                }
                let _ = mesh.draw();
                if let Some((v, _)) = &opts.hline {
                    let (a, b) = (x0, x1);
                    let style = ShapeStyle::from(&RGBColor(85, 85, 85)).stroke_width(1);
                    let _ =
                        ch.draw_series(DashedLineSeries::new(vec![(a, *v), (b, *v)], 6, 4, style));
                }
                for s in series {
                    let pts: Vec<(f64, f64)> = thin(&s.points, MAX_POINTS)
                        .into_iter()
                        .filter(|p| p.0.is_finite() && p.1.is_finite())
                        .collect();
                    let c = rgb(s.colour);
                    let style = ShapeStyle::from(&c).stroke_width(if opts.markers { 2 } else { 1 });
                    let _ = ch.draw_series(LineSeries::new(pts.iter().copied(), style));
                    if opts.markers {
                        let _ = ch.draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())));
                    }
                    if !s.errors.is_empty() {
                        let bars = s.points.iter().zip(&s.errors).filter(|(p, e)| {
                            p.0.is_finite() && p.1.is_finite() && e.is_finite() && **e > 0.0
                        });
                        let _ = ch.draw_series(bars.map(|(&(x, y), &e)| {
                            ErrorBar::new_vertical(x, y - e, y, y + e, c.stroke_width(1), 8)
                        }));
                    }
                }
            }};
        }
        if let Ok(ch) = builder!().build_cartesian_2d(x0..x1, y0..y1) {
            body!(ch);
        }
        for (k, (name, colour, dashed)) in legend.iter().enumerate() {
            let y = 52 + 20 * k as i32;
            if y > H as i32 - 10 {
                break;
            }
            let c = rgb(colour);
            let _ = if *dashed {
                side.draw(&PathElement::new(vec![(4, y), (12, y)], c.stroke_width(2)))
                    .and_then(|()| {
                        side.draw(&PathElement::new(vec![(18, y), (26, y)], c.stroke_width(2)))
                    })
            } else {
                side.draw(&PathElement::new(vec![(4, y), (26, y)], c.stroke_width(2)))
            };
            if opts.markers && !dashed {
                let _ = side.draw(&Circle::new((15, y), 4, c.filled()));
            }
            let _ = side.draw(&Text::new(name.clone(), (32, y - 7), text(12)));
        }
        let _ = root.present();
    }
    if !out.ends_with('\n') {
        out.push('\n');
    }
    out
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
                errors: Vec::new(),
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
                errors: Vec::new(),
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
