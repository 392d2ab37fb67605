//! A part program's run (docs/programs.md): `path.csv` (the tool's actual and commanded
//! position of every machine axis and the contour error, per cycle), its keys in
//! summary.json, its lines in the run's text, and its figures: the path in the plane, the
//! contour error over time, and the ISO 230-4 circular test as a polar plot with the
//! deviation magnified.

use std::fmt::Write as _;

use ringsync_model::contour::{CircularTest, PathResult};
use serde_json::{Value, json};

use crate::svg::{Svg, nice_step};

/// The header of path.csv for machine axes `axes`: `time_s`, then each axis's actual
/// and commanded position \[mm\], then `contour_error` \[mm\].
pub fn path_csv_header(axes: &[char]) -> String {
    let mut h = String::from("time_s");
    for a in axes {
        let _ = write!(h, ",{a},{a}_d");
    }
    h.push_str(",contour_error\n");
    h
}

/// Streams path.csv to `w`: one row per cycle, time and positions to 6 decimals (µs and
/// nm), the contour error to 9 (pm: it is often below a µm).
pub fn write_path_csv(p: &PathResult, w: &mut impl std::io::Write) -> std::io::Result<()> {
    use crate::fixed::push_fixed;
    let tr = &p.trace;
    w.write_all(path_csv_header(&tr.axes).as_bytes())?;
    let m = tr.axes.len();
    crate::fixed::write_lines(w, 0..tr.len(), |o, i| {
        push_fixed(o, tr.t[i], 6);
        for a in 0..m {
            o.push(b',');
            push_fixed(o, tr.actual[i * m + a], 6);
            o.push(b',');
            push_fixed(o, tr.desired[i * m + a], 6);
        }
        o.push(b',');
        push_fixed(o, tr.contour[i], 9);
        o.push(b'\n');
    })
}

/// One circular test as JSON (lengths in mm, the angle's profile left out).
pub fn circular_json(c: &CircularTest) -> Value {
    let letters = ['X', 'Y', 'Z'];
    json!({
        "move": c.circle.mv + 1,
        "plane": format!("{}{}", letters[c.circle.plane[0]], letters[c.circle.plane[1]]),
        "direction": if c.circle.ccw { "ccw" } else { "cw" },
        "radius": c.circle.radius,
        "centre": c.circle.centre,
        "samples": c.samples,
        "mean_radius": c.mean_radius,
        "radius_error": c.mean_radius - c.circle.radius,
        "radial_deviation_min": c.radial_min,
        "radial_deviation_max": c.radial_max,
        "circular_deviation": c.circular_deviation,
        "lsq_centre": c.lsq_centre,
        "lsq_radius": c.lsq_radius,
    })
}

/// The keys summary.json gains for a part program: `contour_rmse`, `contour_max`,
/// `contour_mean` (mm) at the top level, and `program` with the rest.
pub fn path_json(program: &str, p: &PathResult) -> Vec<(&'static str, Value)> {
    vec![
        ("contour_rmse", json!(p.rmse)),
        ("contour_max", json!(p.max)),
        ("contour_mean", json!(p.mean)),
        (
            "program",
            json!({
                "file": program,
                "duration_s": p.program_duration,
                "complete": p.complete,
                "contour_cycles": p.cycles,
                "circular_tests": p.circles.iter().map(circular_json).collect::<Vec<_>>(),
            }),
        ),
    ]
}

/// Lines for the run's text: the contour metrics, and each circular test.
pub fn path_lines(p: &PathResult) -> Vec<String> {
    let um = |mm: f64| mm * 1e3;
    let mut v = vec![format!(
        "contour error: RMS {:.2} µm, max {:.2} µm, mean {:.2} µm over {} cycles{}",
        um(p.rmse),
        um(p.max),
        um(p.mean),
        p.cycles,
        if p.complete {
            String::new()
        } else {
            format!(
                " (the run ended before the program did, at {:.2} s)",
                p.program_duration
            )
        }
    )];
    for c in &p.circles {
        v.push(format!(
            "circle R {} mm {} (ISO 230-4, from feedback): mean radius {:+.2} µm, radial deviation {:+.2} .. {:+.2} µm, circular deviation G {:.2} µm",
            c.circle.radius,
            if c.circle.ccw { "ccw" } else { "cw" },
            um(c.mean_radius - c.circle.radius),
            um(c.radial_min),
            um(c.radial_max),
            um(c.circular_deviation)
        ));
    }
    v
}

/// The circular test as a polar plot: the programmed circle, and the measured radius with
/// its deviation magnified so that the largest fills a fifth of the radius; rings every
/// tick of deviation.
pub fn circular_svg(c: &CircularTest) -> String {
    let (w, h) = (520.0, 560.0);
    let (cx, cy, rp) = (w / 2.0, 310.0, 175.0);
    let mut s = Svg::new(w, h);
    let dir = if c.circle.ccw {
        "counter-clockwise"
    } else {
        "clockwise"
    };
    s.text(
        20.0,
        22.0,
        &format!("Circular test (ISO 230-4): R {} mm, {dir}", c.circle.radius),
        "start",
        r#"font-size="13" font-weight="bold""#,
    );
    let dev_max = c
        .profile
        .iter()
        .fold(0.0f64, |m, (_, d)| m.max(d.abs()))
        .max(1e-9);
    // Deviation per tick, and how many plot units one mm of deviation takes.
    let tick = nice_step(dev_max, 2.0);
    let ticks = (dev_max / tick).ceil().max(1.0);
    let k = 0.25 * rp / (ticks * tick);
    s.text(
        20.0,
        40.0,
        &format!(
            "radius minus R, magnified {:.0}×; rings every {} µm; mean {:+.2} µm, G {:.2} µm",
            k / (rp / c.circle.radius),
            tick * 1e3,
            (c.mean_radius - c.circle.radius) * 1e3,
            c.circular_deviation * 1e3
        ),
        "start",
        "",
    );
    let ring = |r: f64| {
        (0..=180)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::TAU / 180.0;
                (cx + r * a.cos(), cy - r * a.sin())
            })
            .collect::<Vec<_>>()
    };
    for i in -(ticks as i64)..=(ticks as i64) {
        let r = rp + k * i as f64 * tick;
        let style = if i == 0 {
            r##"fill="none" stroke="#555" stroke-width="1""##
        } else {
            r##"fill="none" stroke="#ddd""##
        };
        s.polyline(&ring(r), style);
        if i != 0 {
            // Labelled along the 45° ray, clear of the axes' labels.
            let d = std::f64::consts::FRAC_1_SQRT_2 * r;
            s.text(
                cx + d + 3.0,
                cy - d - 2.0,
                &format!("{:+} µm", (i as f64 * tick * 1e3 * 100.0).round() / 100.0),
                "start",
                r##"fill="#888" font-size="9""##,
            );
        }
    }
    for (a, label) in [(0.0, "0°"), (90.0, "90°"), (180.0, "180°"), (270.0, "270°")] {
        let r = f64::to_radians(a);
        s.line(
            cx,
            cy,
            cx + (rp * 1.3) * r.cos(),
            cy - (rp * 1.3) * r.sin(),
            r##"stroke="#eee""##,
        );
        s.text(
            cx + (rp * 1.35) * r.cos(),
            cy - (rp * 1.35) * r.sin() + 4.0,
            label,
            "middle",
            r##"fill="#666""##,
        );
    }
    let pts: Vec<(f64, f64)> = c
        .profile
        .iter()
        .map(|(a, d)| {
            let r = rp + k * d;
            (cx + r * a.cos(), cy - r * a.sin())
        })
        .collect();
    s.polyline(&pts, r##"fill="none" stroke="#1f77b4" stroke-width="1.3""##);
    s.finish()
}

/// The contour error over time.
pub fn contour_svg(p: &PathResult) -> String {
    let mut t = crate::plot::Thinning::new(p.trace.len());
    for (x, e) in p.trace.t.iter().zip(&p.trace.contour) {
        t.push((*x, e * 1e3));
    }
    crate::plot::line_chart(
        "Contour error: distance from the tool to the programmed path",
        "t [s]",
        "contour error [µm]",
        &[t.finish("contour error".into(), crate::plot::PALETTE[0])],
    )
}

/// The path in its first two machine axes: commanded and actual (they differ by the
/// following error along the path and the contour error across it).
pub fn xy_svg(p: &PathResult) -> Option<String> {
    let tr = &p.trace;
    let m = tr.axes.len();
    if m < 2 || tr.is_empty() {
        return None;
    }
    let (w, h) = (560.0, 560.0);
    let (l, r, t, b) = (60.0, 20.0, 50.0, 50.0);
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for i in 0..tr.len() {
        for v in [&tr.actual, &tr.desired] {
            crate::plot::widen(&mut x0, &mut x1, &mut y0, &mut y1, v[i * m], v[i * m + 1]);
        }
    }
    if !x0.is_finite() {
        return None;
    }
    // Equal scales on both axes.
    let span = (x1 - x0).max(y1 - y0).max(1e-6) * 1.05;
    let (mx, my) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (x0, y1) = (mx - span / 2.0, my + span / 2.0);
    let pw = w - l - r;
    let ph = h - t - b;
    let px = |x: f64| l + (x - x0) / span * pw;
    let py = |y: f64| t + (y1 - y) / span * ph;
    let mut s = Svg::new(w, h);
    s.text(
        l,
        22.0,
        &format!("Path in {}{}: commanded and actual", tr.axes[0], tr.axes[1]),
        "start",
        r#"font-size="13" font-weight="bold""#,
    );
    let step = nice_step(span, 6.0);
    let mut g = (x0 / step).ceil() * step;
    while g <= x0 + span + 1e-12 {
        s.line(px(g), t, px(g), t + ph, r##"stroke="#eee""##);
        s.text(px(g), t + ph + 16.0, &format!("{g}"), "middle", "");
        g += step;
    }
    let mut g = ((y1 - span) / step).ceil() * step;
    while g <= y1 + 1e-12 {
        s.line(l, py(g), l + pw, py(g), r##"stroke="#eee""##);
        s.text(l - 6.0, py(g) + 4.0, &format!("{g}"), "end", "");
        g += step;
    }
    s.text(
        l + pw / 2.0,
        h - 12.0,
        &format!("{} [mm]", tr.axes[0]),
        "middle",
        "",
    );
    s.text(
        16.0,
        t + ph / 2.0,
        &format!("{} [mm]", tr.axes[1]),
        "middle",
        &format!(r#"transform="rotate(-90 16 {:.1})""#, t + ph / 2.0),
    );
    let every = tr.len().div_ceil(4000).max(1);
    for (v, colour, width) in [
        (&tr.desired, "#999999", "2.5"),
        (&tr.actual, "#d62728", "1"),
    ] {
        let pts: Vec<(f64, f64)> = (0..tr.len())
            .step_by(every)
            .map(|i| (px(v[i * m]), py(v[i * m + 1])))
            .collect();
        s.polyline(
            &pts,
            &format!(r#"fill="none" stroke="{colour}" stroke-width="{width}""#),
        );
    }
    s.line(
        l + pw - 150.0,
        t + 10.0,
        l + pw - 130.0,
        t + 10.0,
        r##"stroke="#999999" stroke-width="2.5""##,
    );
    s.text(l + pw - 125.0, t + 14.0, "commanded", "start", "");
    s.line(
        l + pw - 150.0,
        t + 28.0,
        l + pw - 130.0,
        t + 28.0,
        r##"stroke="#d62728" stroke-width="1""##,
    );
    s.text(l + pw - 125.0, t + 32.0, "actual", "start", "");
    Some(s.finish())
}

/// The figures of a part program's run: `path-xy.svg` (two or more axes),
/// `contour-error.svg`, and `circular-test-N.svg` per circle.
pub fn path_figures(p: &PathResult) -> Vec<(String, String)> {
    let mut v = Vec::new();
    if let Some(xy) = xy_svg(p) {
        v.push(("path-xy.svg".to_string(), xy));
    }
    if !p.trace.is_empty() {
        v.push(("contour-error.svg".to_string(), contour_svg(p)));
    }
    for (i, c) in p.circles.iter().enumerate() {
        v.push((format!("circular-test-{}.svg", i + 1), circular_svg(c)));
    }
    v
}

/// What `ringsync program` reports of a planned program.
pub struct ProgramView<'a> {
    /// The scenario's name.
    pub scenario: &'a str,
    /// The program as the scenario names it.
    pub file: &'a str,
    /// The planned path.
    pub path: &'a ringsync_path::PlannedPath,
    /// The machine's axes (letter, coordinate, limits).
    pub axes: Vec<(char, usize, ringsync_path::Limits)>,
    /// The setpoints sampled at the cycle.
    pub check: &'a ringsync_path::check::Check,
    /// The cycle \[s\].
    pub t_cyc: f64,
}

/// Time and length of the path under each kind of binding limit: (label, blocks, mm, s).
fn bindings(v: &ProgramView<'_>) -> Vec<(String, usize, f64, f64)> {
    let mut out: Vec<(String, usize, f64, f64)> = Vec::new();
    for b in v.path.blocks() {
        // A block that never reaches its V runs under its speed changes, not under V.
        let label = if b.v_peak < 0.999 * b.v_max {
            "acceleration and jerk (V not reached)".to_string()
        } else {
            b.binding.label()
        };
        match out.iter_mut().find(|(l, ..)| *l == label) {
            Some(e) => {
                e.1 += 1;
                e.2 += b.len;
                e.3 += b.duration;
            }
            None => out.push((label, 1, b.len, b.duration)),
        }
    }
    out.sort_by(|a, b| b.3.total_cmp(&a.3));
    out
}

/// The plan as text: duration and length, each axis's peaks against its limits, what
/// bounds the feed and for how long.
pub fn program_text(v: &ProgramView<'_>) -> String {
    let p = v.path;
    let c = v.check;
    let mut o = format!(
        "{}: program {} on {} machine axes\n  {:.3} s, {:.3} mm of path; {} moves, {} pieces ({} corner blends, {} {} on the path), {} feed blocks\n",
        v.scenario,
        v.file,
        v.axes.len(),
        p.duration(),
        p.length(),
        p.moves().len(),
        p.pieces().len(),
        p.blends(),
        p.stops(),
        if p.stops() == 1 { "stop" } else { "stops" },
        p.blocks().len()
    );
    let _ = writeln!(
        o,
        "  setpoints every {:.3} ms (finite differences): largest share of a limit {:.4}, largest distance from the program {:.3} µm (tolerance {} µm)",
        v.t_cyc * 1e3,
        c.limit_ratio,
        c.path_deviation * 1e3,
        p.tolerance() * 1e3
    );
    o.push_str(
        "  axis   v peak / limit [mm/s]   a peak / limit [mm/s²]   j peak / limit [mm/s³]\n",
    );
    for (name, coord, l) in &v.axes {
        let [pv, pa, pj] = c.peak[*coord];
        let _ = writeln!(
            o,
            "  {name}      {pv:>8.2} / {:<10.2}    {pa:>9.1} / {:<10.1}    {pj:>10.0} / {:<10.0}",
            l.v_max, l.a_max, l.j_max
        );
    }
    o.push_str("  what bounds the feed           blocks   length [mm]   time [s]\n");
    for (label, n, len, t) in bindings(v) {
        let _ = writeln!(o, "  {label:<30} {n:>6}   {len:>11.3}   {t:>8.3}");
    }
    o
}

/// `ringsync program --json`, with `ringsync_version` and `schema_version` (1) first.
pub fn program_json(v: &ProgramView<'_>) -> Value {
    crate::provenance::stamp(program_json_fields(v), 1)
}

/// The plan as JSON (lengths in mm, times in s).
fn program_json_fields(v: &ProgramView<'_>) -> Value {
    let p = v.path;
    let c = v.check;
    json!({
        "scenario": v.scenario,
        "program": v.file,
        "duration_s": p.duration(),
        "length": p.length(),
        "moves": p.moves().len(),
        "pieces": p.pieces().len(),
        "blends": p.blends(),
        "stops": p.stops(),
        "blocks": p.blocks().len(),
        "t_cyc_s": v.t_cyc,
        "path_tolerance": p.tolerance(),
        "limit_ratio": c.limit_ratio,
        "path_deviation": c.path_deviation,
        "axes": v.axes.iter().map(|(name, coord, l)| json!({
            "axis": name.to_string(),
            "v_max": l.v_max, "a_max": l.a_max, "j_max": l.j_max,
            "v_peak": c.peak[*coord][0], "a_peak": c.peak[*coord][1], "j_peak": c.peak[*coord][2],
        })).collect::<Vec<_>>(),
        "bound_by": bindings(v).into_iter().map(|(label, n, len, t)| json!({
            "limit": label, "blocks": n, "length": len, "time_s": t,
        })).collect::<Vec<_>>(),
    })
}

/// The header of the blocks' CSV.
pub const BLOCKS_CSV_HEADER: &str = "block,line,s0_mm,length_mm,t0_s,duration_s,v_limit,a_limit,j_limit,bound_by,v_in,v_out,v_peak\n";

/// Every feed block as CSV: where it starts along the path and in time, its limits
/// (mm/s, mm/s², mm/s³), what set its speed limit, its entry, exit and peak speeds.
pub fn write_blocks_csv(
    p: &ringsync_path::PlannedPath,
    w: &mut impl std::io::Write,
) -> std::io::Result<()> {
    w.write_all(BLOCKS_CSV_HEADER.as_bytes())?;
    for (i, b) in p.blocks().iter().enumerate() {
        writeln!(
            w,
            "{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.3},{:.1},{},{:.6},{:.6},{:.6}",
            i + 1,
            b.src.line,
            b.s0,
            b.len,
            b.t0,
            b.duration,
            b.v_max,
            b.a_max,
            b.j_max,
            b.binding.label(),
            b.v_in,
            b.v_out,
            b.v_peak
        )?;
    }
    Ok(())
}

/// The feed along the path: the planned path speed over time, and the speed limit V of
/// the block it is in.
pub fn program_svg(v: &ProgramView<'_>) -> String {
    let p = v.path;
    let steps = 4000usize;
    let dt = p.duration().max(1e-9) / steps as f64;
    let mut speed = crate::plot::Thinning::new(steps + 1);
    for k in 0..=steps {
        let t = k as f64 * dt;
        speed.push((t, p.at(t).speed));
    }
    let mut limit = Vec::with_capacity(2 * p.blocks().len());
    for b in p.blocks() {
        limit.push((b.t0, b.v_max));
        limit.push((b.t0 + b.duration, b.v_max));
    }
    crate::plot::line_chart(
        &format!("Feed along the path: {}", v.file),
        "t [s]",
        "path speed [mm/s]",
        &[
            speed.finish("planned speed".into(), crate::plot::PALETTE[0]),
            crate::plot::Series {
                name: "speed limit V of the block".into(),
                colour: crate::plot::PALETTE[1],
                points: limit,
                extent: None,
                errors: Vec::new(),
            },
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use ringsync_model::contour::PathTrace;

    fn result() -> PathResult {
        PathResult {
            trace: PathTrace {
                axes: vec!['X', 'Y'],
                t: vec![0.0, 0.001],
                actual: vec![0.0, 0.0, 0.05, 1e-7],
                desired: vec![0.0, 0.0, 0.05, 0.0],
                contour: vec![0.0, 1e-7],
            },
            rmse: 1e-7 / 2f64.sqrt(),
            max: 1e-7,
            mean: 5e-8,
            cycles: 2,
            circles: Vec::new(),
            program_duration: 0.001,
            complete: true,
            drives: vec![Some(('X', 1.0)), Some(('Y', 1.0))],
        }
    }

    /// path.csv names its columns and writes positions to 6 decimals.
    #[test]
    fn path_csv_has_its_columns() {
        let mut o = Vec::new();
        write_path_csv(&result(), &mut o).expect("written");
        let text = String::from_utf8(o).expect("utf-8");
        assert_eq!(
            text,
            "time_s,X,X_d,Y,Y_d,contour_error\n0.000000,0.000000,0.000000,0.000000,0.000000,0.000000000\n0.001000,0.050000,0.050000,0.000000,0.000000,0.000000100\n"
        );
    }
}
