//! The planned path checked as a drive sees it: sampled at a cycle, its setpoints'
//! finite differences against every axis's limits, and its distance from the program.

use crate::plan::{Machine, PlannedPath};
use crate::vec3::Vec3;

/// What sampling a planned path at a cycle found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Check {
    /// Samples taken.
    pub samples: usize,
    /// Per axis X, Y, Z: the largest |velocity| \[mm/s\], |acceleration| \[mm/s²\] and
    /// |jerk| \[mm/s³\] of the setpoints' finite differences at the cycle.
    pub peak: [[f64; 3]; 3],
    /// The largest of those peaks over its limit, over every axis and derivative (≤ 1:
    /// within the limits).
    pub limit_ratio: f64,
    /// The largest distance of a setpoint from the programmed path \[mm\].
    pub path_deviation: f64,
}

impl Check {
    /// The worse of two checks, figure by figure.
    pub fn worse(self, o: Check) -> Check {
        let mut peak = self.peak;
        for (p, q) in peak.iter_mut().zip(o.peak) {
            for (a, b) in p.iter_mut().zip(q) {
                *a = a.max(b);
            }
        }
        Check {
            samples: self.samples + o.samples,
            peak,
            limit_ratio: self.limit_ratio.max(o.limit_ratio),
            path_deviation: self.path_deviation.max(o.path_deviation),
        }
    }
}

/// Samples `path` every `dt` \[s\] from 3 cycles before its start to 3 after its end, as
/// a master sends setpoints, and checks them against `machine`'s limits (by finite
/// differences: velocity from two samples, acceleration from three, jerk from four) and
/// against the program (each setpoint's distance from the programmed moves near it).
pub fn check_setpoints(path: &PlannedPath, machine: &Machine, dt: f64) -> Check {
    let n = (path.duration() / dt).ceil() as i64 + 3;
    let mut c = Check::default();
    let mut hist: [Vec3; 4] = [path.at(-3.0 * dt).p; 4];
    let mut filled = 0;
    for k in -2..=n {
        let st = path.at(k as f64 * dt);
        hist.rotate_left(1);
        hist[3] = st.p;
        filled += 1;
        c.samples += 1;
        c.path_deviation = c.path_deviation.max(path.contour_error(st.p, st.s));
        if filled < 4 {
            continue;
        }
        let [p0, p1, p2, p3] = hist;
        let v = (p3 - p2) * (1.0 / dt);
        let a = (p3 - p2 * 2.0 + p1) * (1.0 / (dt * dt));
        let j = (p3 - p2 * 3.0 + p1 * 3.0 - p0) * (1.0 / (dt * dt * dt));
        for i in 0..3 {
            let d = [v[i].abs(), a[i].abs(), j[i].abs()];
            for (q, x) in c.peak[i].iter_mut().zip(d) {
                *q = q.max(x);
            }
            if let Some(l) = machine.axes[i] {
                let r = (d[0] / l.v_max).max(d[1] / l.a_max).max(d[2] / l.j_max);
                c.limit_ratio = c.limit_ratio.max(r);
            }
        }
    }
    c
}
