//! What a part program's run did to the part: at every cycle start, the tool's actual
//! position (the encoders' true positions through the transmissions), the commanded one, and
//! the contour error, the distance from the actual position to the programmed path's
//! geometry (not to the time-shifted reference; docs/programs.md, "Contour error"); per run
//! its RMS, largest and time-averaged value; and for every programmed full circle the
//! ISO 230-4 circular test from the same feedback.

use std::sync::Arc;

pub use ringsync_path::circular::CircularTest;
use ringsync_path::circular::{Circle, circular_test};
use ringsync_path::{MoveKind, PlannedPath};

use crate::record::AxisProbe;
use crate::scenario::MachineMap;

/// The per-cycle path table: one row per cycle, each with every machine axis's actual and
/// commanded position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PathTrace {
    /// The machine axes' letters, in column order (X, Y, Z as present).
    pub axes: Vec<char>,
    /// Cycle start \[s\].
    pub t: Vec<f64>,
    /// Actual position of each axis at each cycle start \[mm\] (row-major: axes per row).
    pub actual: Vec<f64>,
    /// Commanded (desired) position of each axis \[mm\].
    pub desired: Vec<f64>,
    /// Contour error \[mm\].
    pub contour: Vec<f64>,
}

/// One ring axis as the machine uses it: the letter of the machine axis it drives and its
/// transmission \[rad/mm\] (`None`: it drives none and holds still).
pub type Drive = Option<(char, f64)>;

impl PathTrace {
    /// Rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether it has no row.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// A part program's run: the path table, the contour metrics and the circular tests.
#[derive(Debug, Clone, PartialEq)]
pub struct PathResult {
    /// The per-cycle table (empty when the run kept no trace).
    pub trace: PathTrace,
    /// RMS contour error over the cycles before any group stop, rapids (G0) left out
    /// \[mm\].
    pub rmse: f64,
    /// Largest contour error \[mm\].
    pub max: f64,
    /// Time-averaged contour error (the mean over the cycles) \[mm\].
    pub mean: f64,
    /// Cycles counted.
    pub cycles: u64,
    /// The ISO 230-4 circular test of each programmed full circle the run completed.
    pub circles: Vec<CircularTest>,
    /// How long the program takes as planned \[s\].
    pub program_duration: f64,
    /// Whether the run lasted to the program's end.
    pub complete: bool,
    /// What each ring axis drives (index: ring axis − 1).
    pub drives: Vec<Drive>,
}

/// The contour part of the recorder.
#[derive(Debug)]
pub struct ContourRecorder {
    map: MachineMap,
    path: Arc<PlannedPath>,
    keep: bool,
    x: Vec<f64>,
    xd: Vec<f64>,
    trace: PathTrace,
    sum_sq: f64,
    sum: f64,
    max: f64,
    cycles: u64,
    last_t: f64,
    /// The full circles, their samples (plane coordinates), and whether the reference has
    /// gone past them.
    circles: Vec<(Circle, Vec<[f64; 2]>, bool)>,
}

impl ContourRecorder {
    /// Records the run of `path` on the machine `map`; `keep` keeps the per-cycle table.
    pub fn new(map: MachineMap, path: Arc<PlannedPath>, keep: bool) -> Self {
        let circles = path
            .moves()
            .iter()
            .enumerate()
            .filter_map(|(i, m)| match &m.kind {
                MoveKind::Arc(h) => Circle::of(i, h).map(|c| (c, Vec::new(), false)),
                _ => None,
            })
            .collect();
        ContourRecorder {
            trace: PathTrace {
                axes: map.axes.iter().map(|a| a.name).collect(),
                ..PathTrace::default()
            },
            map,
            path,
            keep,
            x: Vec::new(),
            xd: Vec::new(),
            sum_sq: 0.0,
            sum: 0.0,
            max: 0.0,
            cycles: 0,
            last_t: 0.0,
            circles,
        }
    }

    /// Cycle start at true time `t` \[s\] with the axes at `probe`; `counting` is false
    /// once the group has stopped (the metrics then stop: the tool no longer follows the
    /// program). Cycles whose reference is on a rapid (G0) are recorded in the table but
    /// not counted in the metrics.
    pub fn cycle(&mut self, t: f64, probe: &[AxisProbe], counting: bool) {
        self.x.clear();
        self.xd.clear();
        self.x.extend(probe.iter().map(|p| p.x));
        self.xd.extend(probe.iter().map(|p| p.x_d));
        let q = self.map.position(&self.x);
        let reference = self.path.at(t);
        let e = self.path.contour_error(q, reference.s);
        self.last_t = t;
        // Rapids (G0) position the tool; they do not cut: the metrics leave them out.
        let rapid = self
            .path
            .move_of(reference.piece)
            .is_some_and(|m| m.is_rapid());
        if counting && !rapid {
            self.sum_sq += e * e;
            self.sum += e;
            self.max = self.max.max(e);
            self.cycles += 1;
            // A sample of a full circle: the reference is on the circle's own arc (not on a
            // blend into or out of it).
            if let Some(piece) = self.path.pieces().get(reference.piece) {
                let on_arc = matches!(piece.curve, ringsync_path::geometry::Curve::Arc(_));
                let mv = piece.mv as usize;
                for (c, pts, done) in &mut self.circles {
                    if on_arc && c.mv == mv {
                        pts.push([q[c.plane[0]], q[c.plane[1]]]);
                    }
                    *done |= mv > c.mv || t >= self.path.duration();
                }
            }
        }
        if self.keep {
            let qd = self.map.position(&self.xd);
            self.trace.t.push(t);
            for a in &self.map.axes {
                self.trace.actual.push(q[a.coord]);
                self.trace.desired.push(qd[a.coord]);
            }
            self.trace.contour.push(e);
        }
    }

    /// The result.
    pub fn finish(self) -> PathResult {
        let n = self.cycles.max(1) as f64;
        let ring_axes = self
            .map
            .axes
            .iter()
            .flat_map(|a| a.drives.iter().map(|(i, _)| i + 1))
            .max()
            .unwrap_or(0)
            .max(self.x.len());
        let drives = (0..ring_axes)
            .map(|i| {
                self.map.drive(i).map(|(c, k)| {
                    let name = self
                        .map
                        .axes
                        .iter()
                        .find(|a| a.coord == c)
                        .map_or('?', |a| a.name);
                    (name, k)
                })
            })
            .collect();
        let duration = self.path.duration();
        let circles = self
            .circles
            .into_iter()
            .filter(|(_, _, done)| *done)
            .filter_map(|(c, pts, _)| circular_test(c, &pts))
            .collect();
        PathResult {
            trace: self.trace,
            rmse: (self.sum_sq / n).sqrt(),
            max: self.max,
            mean: self.sum / n,
            cycles: self.cycles,
            circles,
            program_duration: duration,
            complete: self.last_t >= duration,
            drives,
        }
    }
}
