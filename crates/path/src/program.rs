//! The G-code interpreter: a part program's text, parsed by the `gcode` crate's
//! zero-allocation visitor, becomes modal state (plane, units, distance modes, feed) and
//! canonical moves (lines, arcs and helices, dwells), each with the line and column it came
//! from. The dialect is LinuxCNC's where they overlap (docs/programs.md has the table);
//! anything outside it is an error that names the line and column, never a guess.

use std::f64::consts::{PI, TAU};
use std::fmt;

use gcode::core::{
    BlockVisitor, CommandVisitor, ControlFlow, HasDiagnostics, Number, ProgramVisitor, Span,
    TokenType, Value,
};

use crate::geometry::{Helix, Line};
use crate::vec3::Vec3;

/// Where in the program text something was written (1-based line and column).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Source {
    /// Line, from 1.
    pub line: u32,
    /// Column in characters, from 1.
    pub col: u32,
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.col)
    }
}

/// A program that cannot be run: where, and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{at}: {message}")]
pub struct ProgramError {
    /// Where.
    pub at: Source,
    /// What is wrong and what was expected.
    pub message: String,
}

/// What a canonical move does.
#[derive(Debug, Clone, PartialEq)]
pub enum MoveKind {
    /// A straight line (G0, G1).
    Line(Line),
    /// A circular or helical arc (G2, G3).
    Arc(Helix),
    /// A dwell (G4) \[s\].
    Dwell(f64),
}

/// One canonical move of a program.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    /// What it does.
    pub kind: MoveKind,
    /// Programmed feed along the path \[mm/s\]; ∞ for a rapid (G0: as fast as the axes
    /// allow).
    pub feed: f64,
    /// Where it was written.
    pub src: Source,
}

impl Move {
    /// Its path length \[mm\] (0 for a dwell).
    pub fn len(&self) -> f64 {
        match &self.kind {
            MoveKind::Line(l) => l.len,
            MoveKind::Arc(h) => h.len,
            MoveKind::Dwell(_) => 0.0,
        }
    }

    /// Whether it has no path length (a dwell).
    pub fn is_empty(&self) -> bool {
        self.len() == 0.0
    }

    /// Whether it is a rapid (G0).
    pub fn is_rapid(&self) -> bool {
        self.feed.is_infinite()
    }
}

/// A program as canonical moves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// The moves in order.
    pub moves: Vec<Move>,
    /// Where the program leaves the tool \[mm\].
    pub end: Vec3,
    /// Number of lines of text.
    pub lines: u32,
}

/// Largest program text read \[bytes\]: 64 MiB (about 2.5 million short blocks).
pub const MAX_PROGRAM_BYTES: u64 = 64 << 20;

/// Largest coordinate a program may name \[mm\].
pub const MAX_COORDINATE: f64 = 1e6;

/// Letters of the machine's coordinates, X, Y, Z.
pub const AXIS_LETTERS: [char; 3] = ['X', 'Y', 'Z'];

/// Arc centre offsets by coordinate: I for X, J for Y, K for Z.
const OFFSET_LETTERS: [char; 3] = ['I', 'J', 'K'];

/// Planes: (first, second, normal) coordinate and the G-code that selects it.
const PLANES: [([usize; 3], &str); 3] =
    [([0, 1, 2], "G17"), ([2, 0, 1], "G18"), ([1, 2, 0], "G19")];

/// Two end radii of an IJK arc may differ by this much \[mm\] or relatively, whichever is
/// larger (the centre is then moved onto the perpendicular bisector of the chord).
const RADIUS_TOLERANCE_MM: f64 = 0.005;
const RADIUS_TOLERANCE_REL: f64 = 1e-4;

/// An arc whose end lies this close to its start \[mm\] is a full circle.
const FULL_CIRCLE_MM: f64 = 1e-6;

/// Interprets `text` for a machine with the coordinates `axes` (X, Y, Z present or not),
/// starting at the origin.
///
/// ```
/// use ringsync_path::program::{interpret, MoveKind};
/// let p = interpret("G21 G90\nG1 X10 F600\nG3 X0 Y10 R10\nM2\n", [true, true, false]).unwrap();
/// assert_eq!(p.moves.len(), 2);
/// assert!(matches!(p.moves[1].kind, MoveKind::Arc(_)));
/// assert_eq!(p.moves[0].feed, 10.0); // 600 mm/min
/// let e = interpret("G1 X10\n", [true, true, false]).unwrap_err();
/// assert!(e.to_string().starts_with("line 1, column 1: G1 needs a feed"), "{e}");
/// ```
pub fn interpret(text: &str, axes: [bool; 3]) -> Result<Program, ProgramError> {
    let mut c = Collector::new(text, axes);
    if let Some(at) = long_code_number(text) {
        let word = text
            .get(at..)
            .unwrap_or("")
            .split_whitespace()
            .next()
            .unwrap_or("");
        return Err(ProgramError {
            at: c.source(at),
            message: format!(
                "{}: a G, M or T code's number has at most {MAX_CODE_DIGITS} digits",
                clip(word)
            ),
        });
    }
    gcode::core::parse(text, &mut c);
    if let Some(e) = c.error.take() {
        return Err(e);
    }
    c.state.program.end = c.state.pos;
    c.state.program.lines = c.line_starts.len() as u32;
    Ok(c.state.program)
}

/// Most digits of a G, M or T code's number before its point.
pub const MAX_CODE_DIGITS: usize = 8;

/// Where a G, M or T code's number has more than [`MAX_CODE_DIGITS`] digits before its point
/// (outside comments). The `gcode` parser (0.7) multiplies such a number into a `u32` by 10
/// without checking: an overflow, a panic in a build with overflow checks. Byte offset of
/// the letter.
fn long_code_number(text: &str) -> Option<usize> {
    let b = text.as_bytes();
    let (mut i, mut depth) = (0, 0usize);
    while i < b.len() {
        match b[i] {
            b'(' => depth += 1,
            b')' => depth = depth.saturating_sub(1),
            b';' if depth == 0 => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
                continue;
            }
            b'\n' => depth = 0,
            c if depth == 0 && matches!(c.to_ascii_uppercase(), b'G' | b'M' | b'T') => {
                let mut j = i + 1;
                while j < b.len() && b[j].is_ascii_whitespace() {
                    j += 1;
                }
                let digits = b[j..].iter().take_while(|d| d.is_ascii_digit()).count();
                if digits > MAX_CODE_DIGITS {
                    return Some(i);
                }
            }
            _ => {}
        }
        i += 1;
    }
    None
}

/// The modal state and the moves made so far.
struct State {
    axes: [bool; 3],
    pos: Vec3,
    /// Active motion mode: 0, 1, 2, 3.
    motion: Option<u32>,
    /// Index into [`PLANES`].
    plane: usize,
    /// mm per program unit (1 or 25.4).
    unit: f64,
    absolute: bool,
    arc_absolute: bool,
    /// Feed \[mm/s\].
    feed: Option<f64>,
    ended: bool,
    program: Program,
}

/// A code of the block being read: letter, number, byte offset.
#[derive(Clone, Copy)]
struct Code {
    letter: char,
    number: Number,
    at: usize,
}

/// A word of the block being read: letter (upper case), value, byte offset.
#[derive(Clone, Copy)]
struct Word {
    letter: char,
    value: f64,
    at: usize,
}

struct Collector<'s> {
    src: &'s str,
    line_starts: Vec<usize>,
    codes: Vec<Code>,
    words: Vec<Word>,
    error: Option<ProgramError>,
    state: State,
}

impl<'s> Collector<'s> {
    fn new(src: &'s str, axes: [bool; 3]) -> Self {
        let line_starts = std::iter::once(0)
            .chain(src.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Collector {
            src,
            line_starts,
            codes: Vec::new(),
            words: Vec::new(),
            error: None,
            state: State {
                axes,
                pos: Vec3::ZERO,
                motion: None,
                plane: 0,
                unit: 1.0,
                absolute: true,
                arc_absolute: false,
                feed: None,
                ended: false,
                program: Program::default(),
            },
        }
    }

    /// Line and column of byte offset `at`.
    fn source(&self, at: usize) -> Source {
        let at = at.min(self.src.len());
        let line = self.line_starts.partition_point(|&s| s <= at).max(1);
        let start = self.line_starts[line - 1];
        let col = self.src.get(start..at).map_or(0, |s| s.chars().count()) + 1;
        Source {
            line: line as u32,
            col: col as u32,
        }
    }

    fn fail(&mut self, at: usize, message: String) {
        if self.error.is_none() {
            self.error = Some(ProgramError {
                at: self.source(at),
                message,
            });
        }
    }

    fn done(&self) -> bool {
        self.error.is_some() || self.state.ended
    }

    /// A word's value at full precision: the number as written after its letter (the
    /// parser's own value is an f32).
    fn word(&mut self, letter: char, value: Value<'_>, span: Span) {
        if self.done() {
            return;
        }
        let letter = letter.to_ascii_uppercase();
        let text = self
            .src
            .get(span.start..span.end())
            .unwrap_or("")
            .get(1..)
            .unwrap_or("")
            .trim();
        let value = match value {
            Value::Literal(v) => text.parse::<f64>().unwrap_or(f64::from(v)),
            Value::Variable(_) => {
                return self.fail(
                    span.start,
                    format!("{letter}{}: parameters (#…) are not supported", clip(text)),
                );
            }
        };
        if !value.is_finite() {
            return self.fail(
                span.start,
                format!("{letter}{}: not a finite number", clip(text)),
            );
        }
        self.words.push(Word {
            letter,
            value,
            at: span.start,
        });
    }

    /// The block is complete: check it and run it.
    fn end_block(&mut self) {
        let codes = std::mem::take(&mut self.codes);
        let words = std::mem::take(&mut self.words);
        if !self.done()
            && let Err((at, message)) = self.run_block(&codes, &words)
        {
            self.fail(at, message);
        }
        self.codes = codes;
        self.codes.clear();
        self.words = words;
        self.words.clear();
    }

    fn run_block(&mut self, codes: &[Code], words: &[Word]) -> Result<(), (usize, String)> {
        let block_at = codes
            .iter()
            .map(|c| c.at)
            .chain(words.iter().map(|w| w.at))
            .min();
        let Some(block_at) = block_at else {
            return Ok(());
        };
        let get = |l: char| words.iter().find(|w| w.letter == l).copied();
        // Codes, by modal group.
        let mut motion: Option<Code> = None;
        let mut dwell: Option<Code> = None;
        let mut plane: Option<(Code, usize)> = None;
        let mut units: Option<(Code, f64)> = None;
        let mut distance: Option<(Code, bool)> = None;
        let mut arc_distance: Option<(Code, bool)> = None;
        let mut end: Option<Code> = None;
        fn once<T>(
            slot: &mut Option<T>,
            v: T,
            c: Code,
            group: &str,
        ) -> Result<(), (usize, String)> {
            if slot.is_some() {
                return Err((c.at, format!("two {group} codes in one block")));
            }
            *slot = Some(v);
            Ok(())
        }
        for &c in codes {
            let (major, minor) = (c.number.major(), c.number.minor().map_or(0, |m| m.get()));
            match (c.letter, major, minor) {
                ('G', 0..=3, 0) => once(&mut motion, c, c, "motion (G0 G1 G2 G3)")?,
                ('G', 4, 0) => once(&mut dwell, c, c, "dwell (G4)")?,
                ('G', 17..=19, 0) => once(
                    &mut plane,
                    (c, (major - 17) as usize),
                    c,
                    "plane (G17 G18 G19)",
                )?,
                ('G', 20, 0) => once(&mut units, (c, 25.4), c, "units (G20 G21)")?,
                ('G', 21, 0) => once(&mut units, (c, 1.0), c, "units (G20 G21)")?,
                ('G', 90, 0) => once(&mut distance, (c, true), c, "distance mode (G90 G91)")?,
                ('G', 91, 0) => once(&mut distance, (c, false), c, "distance mode (G90 G91)")?,
                ('G', 90, 1) => once(
                    &mut arc_distance,
                    (c, true),
                    c,
                    "arc distance mode (G90.1 G91.1)",
                )?,
                ('G', 91, 1) => once(
                    &mut arc_distance,
                    (c, false),
                    c,
                    "arc distance mode (G90.1 G91.1)",
                )?,
                ('G', 94, 0) => {}
                ('M', 2 | 30, 0) => once(&mut end, c, c, "program end (M2 M30)")?,
                (l, _, _) => {
                    return Err((
                        c.at,
                        format!("{l}{}: {}", c.number, unsupported(l, major, minor)),
                    ));
                }
            }
        }
        // Words: each letter once.
        for (i, w) in words.iter().enumerate() {
            if words[..i].iter().any(|o| o.letter == w.letter) {
                return Err((w.at, format!("{} appears twice in one block", w.letter)));
            }
            if !"XYZIJKRPF".contains(w.letter) {
                return Err((
                    w.at,
                    format!(
                        "{}: not a word ringsync reads (X Y Z for the axes, I J K R for arcs, P for G4 and arc turns, F for the feed)",
                        w.letter
                    ),
                ));
            }
        }
        if let (Some(m), Some(d)) = (motion, dwell) {
            let _ = m;
            return Err((d.at, "G4 (dwell) and a motion code in one block".into()));
        }
        // Modal settings first, in RS274NGC's order: feed, plane, units, distance modes.
        if let Some((_, u)) = units {
            self.state.unit = u;
        }
        let unit = self.state.unit;
        if let Some(f) = get('F') {
            if f.value <= 0.0 {
                return Err((
                    f.at,
                    format!(
                        "F{}: the feed must be > 0 (in {} per minute)",
                        f.value,
                        unit_name(unit)
                    ),
                ));
            }
            self.state.feed = Some(f.value * unit / 60.0);
        }
        if let Some((_, p)) = plane {
            self.state.plane = p;
        }
        if let Some((_, a)) = distance {
            self.state.absolute = a;
        }
        if let Some((_, a)) = arc_distance {
            self.state.arc_absolute = a;
        }
        let axis_words: Vec<Word> = words
            .iter()
            .filter(|w| AXIS_LETTERS.contains(&w.letter))
            .copied()
            .collect();
        for w in &axis_words {
            let i = axis_index(w.letter);
            if !self.state.axes[i] {
                return Err((
                    w.at,
                    format!(
                        "{}: the machine has no {} axis ({})",
                        w.letter,
                        w.letter,
                        self.axes_list()
                    ),
                ));
            }
        }
        let arc_words: Vec<Word> = words
            .iter()
            .filter(|w| "IJKR".contains(w.letter))
            .copied()
            .collect();
        if let Some(d) = dwell {
            if let Some(w) = axis_words.first().or(arc_words.first()) {
                return Err((
                    w.at,
                    format!("{}: G4 (dwell) takes only P (seconds)", w.letter),
                ));
            }
            let Some(p) = get('P') else {
                return Err((d.at, "G4 needs P, the dwell in seconds".into()));
            };
            if !(0.0..=3600.0).contains(&p.value) {
                return Err((p.at, format!("P{}: a dwell of 0 ..= 3600 s", p.value)));
            }
            if p.value > 0.0 {
                self.state.program.moves.push(Move {
                    kind: MoveKind::Dwell(p.value),
                    feed: 0.0,
                    src: self.source(d.at),
                });
            }
        } else {
            if let Some(m) = motion {
                self.state.motion = Some(m.number.major());
            }
            let mode = self.state.motion;
            let is_arc = matches!(mode, Some(2 | 3));
            if let Some(w) = arc_words.first().filter(|_| !is_arc) {
                return Err((w.at, format!("{}: arc words need G2 or G3", w.letter)));
            }
            if let Some(p) = get('P').filter(|_| !is_arc) {
                return Err((p.at, "P: only G4 (dwell) and G2/G3 (turns) take P".into()));
            }
            let moves = !axis_words.is_empty() || (is_arc && !arc_words.is_empty());
            if moves || motion.is_some_and(|_| is_arc) {
                let at = motion
                    .map(|m| m.at)
                    .or(axis_words.first().map(|w| w.at))
                    .unwrap_or(block_at);
                match mode {
                    None => {
                        return Err((
                            at,
                            "no motion mode is active: give G0, G1, G2 or G3 first".into(),
                        ));
                    }
                    Some(0) => self.line(&axis_words, f64::INFINITY, at),
                    Some(1) => {
                        let feed = self.feed("G1", at)?;
                        self.line(&axis_words, feed, at);
                    }
                    Some(m) => {
                        let feed = self.feed(if m == 2 { "G2" } else { "G3" }, at)?;
                        self.arc(m == 3, &axis_words, &arc_words, get('P'), feed, at)?;
                    }
                }
            }
        }
        if end.is_some() {
            self.state.ended = true;
        }
        Ok(())
    }

    fn axes_list(&self) -> String {
        let have: Vec<String> = AXIS_LETTERS
            .iter()
            .zip(self.state.axes)
            .filter(|(_, on)| *on)
            .map(|(l, _)| l.to_string())
            .collect();
        format!("its axes are {}", have.join(", "))
    }

    fn feed(&self, code: &str, at: usize) -> Result<f64, (usize, String)> {
        self.state.feed.ok_or_else(|| {
            (
                at,
                format!(
                    "{code} needs a feed: no F word has been given yet (F in {} per minute)",
                    unit_name(self.state.unit)
                ),
            )
        })
    }

    /// The end point the axis words name.
    fn target(&self, axis_words: &[Word]) -> Result<Vec3, (usize, String)> {
        let mut p = self.state.pos;
        for w in axis_words {
            let i = axis_index(w.letter);
            let v = w.value * self.state.unit;
            p[i] = if self.state.absolute { v } else { p[i] + v };
            if p[i].abs() > MAX_COORDINATE {
                return Err((
                    w.at,
                    format!("{}: {} mm is beyond ±{MAX_COORDINATE} mm", w.letter, p[i]),
                ));
            }
        }
        Ok(p)
    }

    fn line(&mut self, axis_words: &[Word], feed: f64, at: usize) {
        let to = match self.target(axis_words) {
            Ok(p) => p,
            Err((at, m)) => return self.fail(at, m),
        };
        if let Some(l) = Line::between(self.state.pos, to) {
            let src = self.source(at);
            self.state.program.moves.push(Move {
                kind: MoveKind::Line(l),
                feed,
                src,
            });
        }
        self.state.pos = to;
    }

    fn arc(
        &mut self,
        ccw: bool,
        axis_words: &[Word],
        arc_words: &[Word],
        turns: Option<Word>,
        feed: f64,
        at: usize,
    ) -> Result<(), (usize, String)> {
        let code = if ccw { "G3" } else { "G2" };
        let ([a, b, n], plane_code) = PLANES[self.state.plane];
        let plane_name = format!("{}{}", AXIS_LETTERS[a], AXIS_LETTERS[b]);
        if !(self.state.axes[a] && self.state.axes[b]) {
            return Err((
                at,
                format!(
                    "{code} in the {plane_name} plane ({plane_code}) needs machine axes {} and {} ({})",
                    AXIS_LETTERS[a],
                    AXIS_LETTERS[b],
                    self.axes_list()
                ),
            ));
        }
        let from = self.state.pos;
        let to = self.target(axis_words)?;
        let unit = self.state.unit;
        let r_word = arc_words.iter().find(|w| w.letter == 'R');
        let offsets: Vec<&Word> = arc_words.iter().filter(|w| w.letter != 'R').collect();
        if let (Some(r), Some(o)) = (r_word, offsets.first()) {
            let _ = r;
            return Err((
                o.at,
                format!(
                    "{code}: give either R or the centre ({}{}), not both",
                    OFFSET_LETTERS[a], OFFSET_LETTERS[b]
                ),
            ));
        }
        if let Some(o) = offsets.iter().find(|w| w.letter == OFFSET_LETTERS[n]) {
            return Err((
                o.at,
                format!(
                    "{}: not a centre offset in the {plane_name} plane ({plane_code}): use {} and {}",
                    o.letter, OFFSET_LETTERS[a], OFFSET_LETTERS[b]
                ),
            ));
        }
        let turns = match turns {
            None => 1,
            Some(p) if p.value >= 1.0 && p.value <= 1000.0 && p.value.fract() == 0.0 => {
                p.value as u32
            }
            Some(p) => {
                return Err((
                    p.at,
                    format!(
                        "P{}: the number of turns, a whole number 1 ..= 1000",
                        p.value
                    ),
                ));
            }
        };
        let (pa, pb, ea, eb) = (from[a], from[b], to[a], to[b]);
        let chord = (ea - pa).hypot(eb - pb);
        let full = chord <= FULL_CIRCLE_MM;
        let (ca, cb, r) = if let Some(rw) = r_word {
            let r = rw.value * unit;
            if r == 0.0 {
                return Err((rw.at, "R0: an arc's radius must not be 0".into()));
            }
            if full {
                return Err((
                    rw.at,
                    format!(
                        "{code}: an R-form arc cannot end where it starts (a full circle needs {}{})",
                        OFFSET_LETTERS[a], OFFSET_LETTERS[b]
                    ),
                ));
            }
            let rr = r.abs();
            let half = 0.5 * chord;
            if half > rr * (1.0 + 1e-9) + 1e-9 {
                return Err((
                    rw.at,
                    format!(
                        "R{}: a radius of {rr:.4} mm cannot reach the end point, {chord:.4} mm away (at most 2·R = {:.4} mm)",
                        rw.value,
                        2.0 * rr
                    ),
                ));
            }
            let h = (rr * rr - half * half).max(0.0).sqrt();
            let (ua, ub) = ((ea - pa) / chord, (eb - pb) / chord);
            // The left normal of the chord: a counter-clockwise minor arc has its centre
            // there; a clockwise one, or a major arc (R < 0), on the other side.
            let side = if ccw == (r > 0.0) { 1.0 } else { -1.0 };
            let (ma, mb) = (0.5 * (pa + ea), 0.5 * (pb + eb));
            (ma - side * h * ub, mb + side * h * ua, rr)
        } else {
            if offsets.is_empty() {
                return Err((
                    at,
                    format!(
                        "{code} needs the centre ({}{}) or the radius (R)",
                        OFFSET_LETTERS[a], OFFSET_LETTERS[b]
                    ),
                ));
            }
            let off = |i: usize| {
                offsets
                    .iter()
                    .find(|w| w.letter == OFFSET_LETTERS[i])
                    .map(|w| w.value * unit)
            };
            let (ca, cb) = if self.state.arc_absolute {
                (off(a).unwrap_or(0.0), off(b).unwrap_or(0.0))
            } else {
                (pa + off(a).unwrap_or(0.0), pb + off(b).unwrap_or(0.0))
            };
            let r0 = (pa - ca).hypot(pb - cb);
            let r1 = (ea - ca).hypot(eb - cb);
            if r0 <= 1e-9 {
                return Err((
                    offsets[0].at,
                    format!("{code}: the centre is the start point (radius 0)"),
                ));
            }
            let tol = RADIUS_TOLERANCE_MM.max(RADIUS_TOLERANCE_REL * r0);
            if (r1 - r0).abs() > tol {
                return Err((
                    at,
                    format!(
                        "{code}: the end point is {:.4} mm from the centre and the start {:.4} mm: the radii differ by {:.4} mm (at most {tol:.4} mm)",
                        r1,
                        r0,
                        (r1 - r0).abs()
                    ),
                ));
            }
            if full {
                (ca, cb, r0)
            } else {
                // The centre on the chord's perpendicular bisector, nearest the given one.
                let (ma, mb) = (0.5 * (pa + ea), 0.5 * (pb + eb));
                let (wa, wb) = (-(eb - pb) / chord, (ea - pa) / chord);
                let k = (ca - ma) * wa + (cb - mb) * wb;
                let (ca, cb) = (ma + k * wa, mb + k * wb);
                (ca, cb, (pa - ca).hypot(pb - cb))
            }
        };
        let phi0 = (pb - cb).atan2(pa - ca);
        let phi1 = (eb - cb).atan2(ea - ca);
        let extra = TAU * f64::from(turns - 1);
        let sweep = if full {
            if ccw { TAU + extra } else { -(TAU + extra) }
        } else if ccw {
            (phi1 - phi0).rem_euclid(TAU) + extra
        } else {
            -((phi0 - phi1).rem_euclid(TAU) + extra)
        };
        if sweep == 0.0 {
            return Ok(());
        }
        debug_assert!(sweep.abs() <= TAU * 1000.0 + PI);
        let mut c = Vec3::ZERO;
        c[a] = ca;
        c[b] = cb;
        c[n] = from[n];
        let h = Helix::new(
            c,
            Vec3::axis(a),
            Vec3::axis(b),
            r,
            phi0,
            sweep,
            to[n] - from[n],
        );
        let src = self.source(at);
        self.state.program.moves.push(Move {
            kind: MoveKind::Arc(h),
            feed,
            src,
        });
        self.state.pos = to;
        Ok(())
    }
}

fn axis_index(letter: char) -> usize {
    AXIS_LETTERS.iter().position(|&l| l == letter).unwrap_or(0)
}

fn unit_name(unit: f64) -> &'static str {
    if unit == 1.0 { "mm" } else { "inches" }
}

/// Why a code is refused.
fn unsupported(letter: char, major: u32, minor: u32) -> &'static str {
    match (letter, major, minor) {
        ('G', 5..=6, _) => "splines are not supported",
        ('G', 10 | 28 | 30 | 53..=59 | 92, _) => {
            "coordinate systems, offsets and homing are not supported: the program runs in machine coordinates from the origin"
        }
        ('G', 33 | 76, _) => "threading (spindle-synchronised motion) is not supported",
        ('G', 38, _) => "probing is not supported",
        ('G', 40..=43 | 49, _) => "tool radius and length compensation are not supported",
        ('G', 61 | 64, _) => {
            "path control modes are not supported: ringsync blends corners within [machine] path_tolerance"
        }
        ('G', 73 | 80..=89, _) => "canned cycles are not supported",
        ('G', 93 | 95, _) => "only units-per-minute feed (G94) is supported",
        ('M', 0 | 1 | 60, _) => "program pauses are not supported",
        ('T', _, _) | ('M', 6, _) => "tool changes are not supported",
        ('M', 3..=9, _) => "spindle and coolant codes are not supported: ringsync moves axes only",
        _ => "not in ringsync's dialect (docs/programs.md lists what is)",
    }
}

impl gcode::core::Diagnostics for Collector<'_> {
    fn emit_unknown_content(&mut self, text: &str, span: Span) {
        if !self.done() {
            self.fail(span.start, format!("cannot read '{}' here", clip(text)));
        }
    }
    fn emit_unexpected(&mut self, actual: &str, expected: &[TokenType], span: Span) {
        if !self.done() {
            let want: Vec<&str> = expected.iter().map(|t| t.as_str()).collect();
            self.fail(
                span.start,
                format!(
                    "unexpected '{}' (expected {})",
                    clip(actual),
                    want.join(" or ")
                ),
            );
        }
    }
    fn emit_parse_int_error(&mut self, value: &str, _e: std::num::ParseIntError, span: Span) {
        if !self.done() {
            self.fail(
                span.start,
                format!("'{}' is not a whole number", clip(value)),
            );
        }
    }
}

/// Program text as a message echoes it: at most 40 characters, control characters (a line
/// break the parser stopped at) escaped, so that the message stays one line.
fn clip(s: &str) -> String {
    let mut out: String = s
        .chars()
        .take(40)
        .flat_map(|c| {
            let e: Vec<char> = if c.is_control() {
                c.escape_default().collect()
            } else {
                vec![c]
            };
            e
        })
        .collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}

struct BlockCollector<'c, 's>(&'c mut Collector<'s>);
struct CodeCollector<'c, 's>(&'c mut Collector<'s>, char, Number);

impl HasDiagnostics for BlockCollector<'_, '_> {
    fn diagnostics(&mut self) -> &mut dyn gcode::core::Diagnostics {
        self.0
    }
}

impl HasDiagnostics for CodeCollector<'_, '_> {
    fn diagnostics(&mut self) -> &mut dyn gcode::core::Diagnostics {
        self.0
    }
}

impl ProgramVisitor for Collector<'_> {
    fn start_block(&mut self) -> ControlFlow<impl BlockVisitor + '_> {
        if self.done() {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(BlockCollector(self))
    }
}

impl BlockVisitor for BlockCollector<'_, '_> {
    fn program_delimiter(&mut self, _span: Span) {}
    fn word_address(&mut self, letter: char, value: Value<'_>, span: Span) {
        self.0.word(letter, value, span);
    }
    fn start_general_code(&mut self, number: Number) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(CodeCollector(&mut *self.0, 'G', number))
    }
    fn start_miscellaneous_code(
        &mut self,
        number: Number,
    ) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(CodeCollector(&mut *self.0, 'M', number))
    }
    fn start_tool_change_code(&mut self, number: Number) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(CodeCollector(&mut *self.0, 'T', number))
    }
    fn end_line(self, _span: Span) {
        self.0.end_block();
    }
}

impl CommandVisitor for CodeCollector<'_, '_> {
    fn argument(&mut self, letter: char, value: Value<'_>, span: Span) {
        self.0.word(letter, value, span);
    }
    fn end_command(self, span: Span) {
        self.0.codes.push(Code {
            letter: self.1,
            number: self.2,
            at: span.start,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const XYZ: [bool; 3] = [true, true, true];

    fn arc(p: &Program, i: usize) -> Helix {
        match &p.moves[i].kind {
            MoveKind::Arc(h) => *h,
            k => panic!("not an arc: {k:?}"),
        }
    }

    fn end_of(h: &Helix) -> Vec3 {
        h.frame(h.len).p
    }

    #[test]
    fn modal_lines_units_and_distance_modes() {
        let p = interpret(
            "%\nN10 G21 G90 (mm, absolute)\nG1 X10 Y5 F1200\nX20\nG91 Y-5 ; incremental\nG20 G90 X1\nG0 Z0.5\nM30\nG1 X99\n",
            XYZ,
        )
        .expect("valid");
        let ends: Vec<Vec3> = p
            .moves
            .iter()
            .map(|m| match &m.kind {
                MoveKind::Line(l) => l.point(l.len),
                _ => panic!("line"),
            })
            .collect();
        let want = [
            Vec3::new(10.0, 5.0, 0.0),
            Vec3::new(20.0, 5.0, 0.0),
            Vec3::new(20.0, 0.0, 0.0),
            Vec3::new(25.4, 0.0, 0.0),
            Vec3::new(25.4, 0.0, 12.7),
        ];
        for (e, w) in ends.iter().zip(want) {
            assert!((*e - w).norm() < 1e-12, "{e:?} {w:?}");
        }
        assert_eq!(ends.len(), 5, "nothing after M30");
        assert_eq!(p.moves[0].feed, 20.0);
        assert_eq!(
            p.moves[3].feed, 20.0,
            "the feed in mm/s stays when the units change"
        );
        assert!(p.moves[4].is_rapid());
        assert_eq!(p.moves[1].src, Source { line: 4, col: 1 });
        assert_eq!(p.moves[2].src, Source { line: 5, col: 5 });
    }

    #[test]
    fn arcs_by_centre_and_radius_in_every_plane() {
        // A quarter circle counter-clockwise from (10, 0) to (0, 10) about the origin,
        // three ways.
        for text in [
            "G1 X10 F600\nG3 X0 Y10 I-10 J0\n",
            "G1 X10 F600\nG3 X0 Y10 R10\n",
            "G1 X10 F600\nG90.1 G3 X0 Y10 I0 J0\n",
        ] {
            let p = interpret(text, XYZ).expect("valid");
            let h = arc(&p, 1);
            assert!(
                (h.r - 10.0).abs() < 1e-12 && (h.sweep - PI / 2.0).abs() < 1e-12,
                "{text}: {h:?}"
            );
            assert!((end_of(&h) - Vec3::new(0.0, 10.0, 0.0)).norm() < 1e-9);
        }
        // R < 0 takes the long way: three quarters clockwise.
        let p = interpret("G1 X10 F600\nG2 X0 Y10 R-10\n", XYZ).expect("valid");
        let h = arc(&p, 1);
        assert!((h.sweep + 1.5 * PI).abs() < 1e-12, "{h:?}");
        // G18 (ZX plane, I and K) and G19 (YZ, J and K), helical with the third axis.
        let p = interpret("G1 X10 F600\nG18 G3 X0 Z10 I-10 K0 Y5\n", XYZ).expect("valid");
        let h = arc(&p, 1);
        assert!(
            (end_of(&h) - Vec3::new(0.0, 5.0, 10.0)).norm() < 1e-9,
            "{:?}",
            end_of(&h)
        );
        let p = interpret("G1 Y10 F600\nG19 G2 Y0 Z-10 J-10 X3 P2\n", XYZ).expect("valid");
        let h = arc(&p, 1);
        assert!((end_of(&h) - Vec3::new(3.0, 0.0, -10.0)).norm() < 1e-9);
        assert!(
            (h.sweep.abs() - 2.5 * PI).abs() < 1e-12,
            "two turns: {}",
            h.sweep
        );
        // A full circle: I/J with the end at the start.
        let p = interpret("G1 X50 F600\nG2 I-50\n", XYZ).expect("valid");
        let h = arc(&p, 1);
        assert!(
            (h.sweep + TAU).abs() < 1e-12 && (h.len - TAU * 50.0).abs() < 1e-9,
            "{h:?}"
        );
    }

    #[test]
    fn refusals_name_the_line_and_column() {
        let cases = [
            ("G1 X1\n", "line 1, column 1: G1 needs a feed"),
            (
                "G0 X1\nG1 X2 F100\nG2 X5 Y0 R1\n",
                "line 3, column 10: R1: a radius of 1.0000 mm cannot reach",
            ),
            ("G0 X1 A3\n", "line 1, column 7: A: not a word"),
            ("G0 X1\n  G0 W3\n", "line 2, column 6: W: not a word"),
            (
                "G1 F100 Z1\n",
                "line 1, column 9: Z: the machine has no Z axis (its axes are X, Y)",
            ),
            (
                "G0 X1\nM3 S1000\n",
                "line 2, column 1: M3: spindle and coolant",
            ),
            ("G41 X1\n", "line 1, column 1: G41: tool radius"),
            (
                "G1 X1 F100\nG2 X2 I1 J1\n",
                "line 2, column 1: G2: the end point",
            ),
            (
                "G1 X1 F100\nG2 X2 Y2 I1 R1\n",
                "give either R or the centre",
            ),
            (
                "G1 X1 F100\nG2 X0 K1\n",
                "K: not a centre offset in the XY plane (G17)",
            ),
            (
                "G1 X1 F100\nG2 X0\n",
                "G2 needs the centre (IJ) or the radius (R)",
            ),
            ("G1 X1 F100\nG2 R5\n", "cannot end where it starts"),
            ("X1\n", "no motion mode is active"),
            ("G4\n", "G4 needs P"),
            ("G4 P1 X2\n", "X: G4 (dwell) takes only P"),
            (
                "G0 G1 X1 F100\n",
                "two motion (G0 G1 G2 G3) codes in one block",
            ),
            ("G0 X1 X2\n", "X appears twice in one block"),
            ("G1 X1 F0\n", "F0: the feed must be > 0"),
            ("G1 X#1 F10\n", "line 1, column"),
            ("G0 X2000000\n", "beyond"),
            (
                "G18 G2 X1 R1 F100\n",
                "G2 in the ZX plane (G18) needs machine axes Z and X",
            ),
            (
                "G1 X1 F100 P2\n",
                "only G4 (dwell) and G2/G3 (turns) take P",
            ),
            // The fuzzer's: a word cut off by the line's end is echoed escaped, on one line;
            // code numbers the gcode parser would overflow on.
            ("G1 F100 X\n", "line 1, column"),
            (
                "G0 X1\n G1191813220\n",
                "line 2, column 2: G1191813220: a G, M or T code's number has at most 8 digits",
            ),
            (
                "G\r2000000000\n",
                "line 1, column 1: G: a G, M or T code's number",
            ),
        ];
        for (text, want) in cases {
            let e = interpret(text, [true, true, false])
                .expect_err(text)
                .to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }

    #[test]
    fn full_precision_and_dwells() {
        let p = interpret("G1 X10.123456789 F600\nG4 P0.25\nG4 P0\n", XYZ).expect("valid");
        match &p.moves[0].kind {
            MoveKind::Line(l) => assert_eq!(l.len, 10.123456789),
            _ => panic!("line"),
        }
        assert_eq!(p.moves[1].kind, MoveKind::Dwell(0.25));
        assert_eq!(p.moves.len(), 2, "a zero dwell is nothing");
    }
}
