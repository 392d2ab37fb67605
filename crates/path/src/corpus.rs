//! Generated part programs, for tests and benchmarks: a random program of lines, arcs,
//! helices, rapids and dwells for a seed, a random machine to run it on, and the small-line
//! approximation of a curve that CAM systems write (many short G1 moves).

use std::fmt::Write as _;

use crate::plan::{Limits, Machine};

/// A small deterministic generator (xorshift64*), so that a seed names one program on every
/// machine.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// The generator of `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x2545_F491_4F6C_DD1D | 1)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in \[0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in \[lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Log-uniform in \[lo, hi).
    pub fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }

    /// Uniform in 0..n.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n.max(1)
    }
}

/// A machine with X, Y and Z and random limits (v 20-200 mm/s, a 200-5 000 mm/s²,
/// j 5 000-100 000 mm/s³, log-uniform), tolerance 0.01 mm.
pub fn machine(seed: u64) -> Machine {
    let mut r = Rng::new(seed ^ 0xA5A5_5A5A);
    let mut one = || {
        Some(Limits {
            v_max: r.log_range(20.0, 200.0),
            a_max: r.log_range(200.0, 5000.0),
            j_max: r.log_range(5000.0, 100_000.0),
        })
    };
    Machine {
        axes: [one(), one(), one()],
        tolerance: 0.01,
    }
}

/// A random program of 3 to 14 moves for seed `seed`, and a path tolerance for it (0,
/// 0.001, 0.01, 0.1 or 0.5 mm): rapids, lines with feeds from 60 to 12 000 mm/min, arcs
/// by centre and by radius in all three planes, helices, full circles, dwells, and runs of
/// short incremental lines.
pub fn program(seed: u64) -> (String, f64) {
    let mut r = Rng::new(seed);
    let tol = [0.0, 0.001, 0.01, 0.1, 0.5][r.below(5) as usize];
    let mut text = String::from("G21 G90 G17\n");
    let mut pos = [0.0f64; 3];
    let moves = 3 + r.below(12);
    let feed = |r: &mut Rng| r.log_range(60.0, 12_000.0);
    let point = |r: &mut Rng| {
        [
            r.range(-50.0, 50.0),
            r.range(-50.0, 50.0),
            r.range(-20.0, 20.0),
        ]
    };
    for _ in 0..moves {
        match r.below(10) {
            0 => {
                let p = point(&mut r);
                let _ = writeln!(text, "G0 X{:.4} Y{:.4} Z{:.4}", p[0], p[1], p[2]);
                pos = p;
            }
            1 => {
                let _ = writeln!(text, "G4 P{:.3}", r.range(0.0, 0.3));
            }
            2 => {
                // A run of short incremental lines along a wavy curve.
                let n = 5 + r.below(40);
                let step = r.log_range(0.01, 1.0);
                let (mut th, dth) = (r.range(0.0, 6.3), r.range(-0.5, 0.5));
                let _ = writeln!(text, "G91 G1 F{:.1}", feed(&mut r));
                for _ in 0..n {
                    let (dx, dy) = (step * th.cos(), step * th.sin());
                    let _ = writeln!(text, "X{dx:.6} Y{dy:.6}");
                    pos[0] += (dx * 1e6).round() / 1e6;
                    pos[1] += (dy * 1e6).round() / 1e6;
                    th += dth * r.range(0.0, 1.0);
                }
                let _ = writeln!(text, "G90");
                // The absolute position from here on is what the text says.
                let _ = writeln!(text, "G1 X{:.6} Y{:.6}", pos[0], pos[1]);
            }
            3..=5 => {
                let p = point(&mut r);
                let _ = writeln!(
                    text,
                    "G1 X{:.4} Y{:.4} Z{:.4} F{:.1}",
                    p[0],
                    p[1],
                    p[2],
                    feed(&mut r)
                );
                pos = p;
            }
            _ => {
                // An arc in a random plane: centre offset, then an end on its circle.
                let plane = r.below(3) as usize;
                let ([a, b, n], code, (li, lj)) = [
                    ([0, 1, 2], "G17", ('I', 'J')),
                    ([2, 0, 1], "G18", ('K', 'I')),
                    ([1, 2, 0], "G19", ('J', 'K')),
                ][plane];
                let (oa, ob) = (r.range(-20.0, 20.0), r.range(-20.0, 20.0));
                let rad = oa.hypot(ob);
                if rad < 0.5 {
                    continue;
                }
                let (ca, cb) = (pos[a] + oa, pos[b] + ob);
                let full = r.below(5) == 0;
                let phi = r.range(0.0, std::f64::consts::TAU);
                let (ea, eb) = if full {
                    (pos[a], pos[b])
                } else {
                    (ca + rad * phi.cos(), cb + rad * phi.sin())
                };
                let dz = if r.below(3) == 0 {
                    r.range(-5.0, 5.0)
                } else {
                    0.0
                };
                let dir = if r.below(2) == 0 { "G2" } else { "G3" };
                let letters = ['X', 'Y', 'Z'];
                let use_r = !full && r.below(3) == 0;
                let centre = if use_r {
                    // R picks the arc by length: the short one (R > 0) or the long one.
                    format!(
                        " R{:.6}",
                        (rad + 2e-6) * if r.below(2) == 0 { 1.0 } else { -1.0 }
                    )
                } else {
                    // The offsets, in the order the plane's letters go.
                    let off = |l: char| if l == ['I', 'J', 'K'][a] { oa } else { ob };
                    format!(" {li}{:.6} {lj}{:.6}", off(li), off(lj))
                };
                let mut end = pos;
                end[a] = (ea * 1e6).round() / 1e6;
                end[b] = (eb * 1e6).round() / 1e6;
                end[n] = ((pos[n] + dz) * 1e6).round() / 1e6;
                let _ = writeln!(
                    text,
                    "{code} {dir} {}{:.6} {}{:.6} {}{:.6}{centre} F{:.1}",
                    letters[a],
                    end[a],
                    letters[b],
                    end[b],
                    letters[n],
                    end[n],
                    feed(&mut r)
                );
                pos = end;
            }
        }
    }
    text.push_str("M2\n");
    (text, tol)
}

/// `n` short G1 moves approximating a spiral-like curve in XY (what CAM output of a spline
/// looks like): segments of about `step` mm, feed `feed` mm/min, coordinates to 4
/// decimals.
pub fn small_lines(n: usize, step: f64, feed: f64) -> String {
    let mut text = String::with_capacity(n * 24 + 64);
    let _ = writeln!(text, "G21 G90 G17 (a curve as {n} short lines)");
    let _ = writeln!(text, "G1 X0 Y0 F{feed:.1}");
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..n {
        // Curvature that changes slowly along the curve: radii from about 5 to 50 mm.
        let kappa = 0.11 * (k as f64 * 0.002).sin() + 0.02 * (k as f64 * 0.013).cos();
        th += kappa * step;
        x += step * th.cos();
        y += step * th.sin();
        let _ = writeln!(text, "X{x:.4} Y{y:.4}");
    }
    text.push_str("M2\n");
    text
}

#[cfg(test)]
mod tests {
    /// examples/programs/spline-10k.ngc is `small_lines(10 000, 0.1, 3000)`, as its docs say.
    #[test]
    fn the_spline_example_is_the_generated_curve() {
        let file = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/programs/spline-10k.ngc"
        );
        let text = std::fs::read_to_string(file).expect("examples/programs/spline-10k.ngc");
        assert!(
            text == super::small_lines(10_000, 0.1, 3000.0),
            "regenerate it from corpus::small_lines"
        );
    }
}
