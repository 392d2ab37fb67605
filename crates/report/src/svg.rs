//! A minimal SVG writer: enough for timing diagrams, with text escaped.

use std::fmt::Write as _;

/// Escapes text for SVG content and attributes.
pub(crate) fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            c => o.push(c),
        }
    }
    o
}

/// An SVG document under construction.
pub(crate) struct Svg {
    body: String,
    width: f64,
    height: f64,
}

impl Svg {
    pub(crate) fn new(width: f64, height: f64) -> Self {
        Svg {
            body: String::new(),
            width,
            height,
        }
    }

    /// A rectangle with an optional hover title.
    pub(crate) fn rect(
        &mut self,
        x: f64,
        y: f64,
        w: f64,
        h: f64,
        style: &str,
        title: Option<&str>,
    ) {
        let _ = write!(
            self.body,
            r#"<rect x="{x:.2}" y="{y:.2}" width="{:.2}" height="{h:.2}" {style}"#,
            w.max(0.5)
        );
        match title {
            Some(t) => {
                let _ = writeln!(self.body, "><title>{}</title></rect>", esc(t));
            }
            None => self.body.push_str("/>\n"),
        }
    }

    pub(crate) fn line(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, style: &str) {
        let _ = writeln!(
            self.body,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" {style}/>"#
        );
    }

    pub(crate) fn polyline(&mut self, pts: &[(f64, f64)], style: &str) {
        use crate::fixed::push_fixed;
        let mut p = Vec::with_capacity(pts.len() * 16);
        for (i, &(x, y)) in pts.iter().enumerate() {
            if i > 0 {
                p.push(b' ');
            }
            push_fixed(&mut p, x, 2);
            p.push(b',');
            push_fixed(&mut p, y, 2);
        }
        let p = String::from_utf8(p).unwrap_or_default();
        let _ = writeln!(self.body, r#"<polyline points="{p}" {style}/>"#);
    }

    /// Text; `anchor` is start, middle or end.
    pub(crate) fn text(&mut self, x: f64, y: f64, s: &str, anchor: &str, style: &str) {
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.2}" y="{y:.2}" text-anchor="{anchor}" {style}>{}</text>"#,
            esc(s)
        );
    }

    pub(crate) fn finish(self) -> String {
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"DejaVu Sans, Verdana, sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}</svg>\n",
            self.body,
            w = self.width,
            h = self.height
        )
    }
}

/// A "nice" tick step (1, 2 or 5 × 10^k) for about `target` ticks over `span`.
pub(crate) fn nice_step(span: f64, target: f64) -> f64 {
    let raw = (span / target).max(f64::MIN_POSITIVE);
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let m = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    m * mag
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup() {
        assert_eq!(esc("a<b & \"c\">"), "a&lt;b &amp; &quot;c&quot;&gt;");
    }

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(225.0, 10.0), 20.0);
        assert_eq!(nice_step(1000.0, 10.0), 100.0);
        assert_eq!(nice_step(48.0, 10.0), 5.0);
    }
}
