//! Streaming summary of a G-code file (backs `jointspace stats`): lines, commands by name, moves,
//! extrusion, XY travel, bounding box of extruding moves (arcs included exactly), layers, features.
//! Memory is constant: one pass, nothing kept per line.

use std::collections::{BTreeMap, BTreeSet};
use std::io::BufRead;
use std::sync::Arc;

use serde::Serialize;

use crate::command::{Arc as ArcMove, Command, Meta, Move, Position, Span, Spanned};
use crate::error::GcodeError;
use crate::interp::{FastSink, Interpreter, InterpreterOptions};
use crate::lexer::{CommandWord, Line};
use crate::reader::Reader;

/// Axis-aligned box, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoundingBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl BoundingBox {
    #[inline(always)]
    fn include(&mut self, p: [f64; 3]) {
        for (axis, value) in p.into_iter().enumerate() {
            self.min[axis] = self.min[axis].min(value);
            self.max[axis] = self.max[axis].max(value);
        }
    }
}

/// The summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Stats {
    pub lines: u64,
    /// Command lines by upper-case name (`G1`, `M104`, `SET_FAN_SPEED`…), state changes included.
    pub commands: BTreeMap<String, u64>,
    /// G0 + G1.
    pub moves: u64,
    /// G2 + G3.
    pub arcs: u64,
    /// Moves and arcs that push filament while moving in XY.
    pub extruding_moves: u64,
    /// Filament pushed (sum of positive E steps), mm.
    pub total_extrusion: f64,
    /// Filament pulled back (sum of negative E steps, positive number), mm.
    pub total_retraction: f64,
    /// XY path length of all moves and arcs, mm.
    pub xy_travel: f64,
    /// Bounding box of the extruding moves (`None` if nothing was extruded).
    pub extrusion_bbox: Option<BoundingBox>,
    /// Layers: those the slicer announces with layer markers; in a file without markers, the Z levels
    /// extrusion starts at (a new one after a non-extruding move, or a Z step of more than 0.02 mm).
    pub layers: u64,
    /// Layer markers seen (`;LAYER_CHANGE`, `;LAYER:n`…).
    pub layer_markers: u64,
    /// Layers counted from Z changes while extruding.
    pub extrusion_z_levels: u64,
    /// Feature types seen (`;TYPE:`…).
    pub features: BTreeSet<String>,
    pub warnings: u64,
}

/// Accumulates [`Stats`] from lines and commands.
#[derive(Debug, Clone)]
pub struct StatsCollector {
    stats: Stats,
    codes: CodeCounts,
    position: Position,
    /// Z of the current extrusion level, and whether the previous move extruded.
    level_z: Option<f64>,
    last_extruded: bool,
    /// `position` is already in the bounding box (the end of an extruding move or arc).
    position_included: bool,
    /// XY steps whose lengths are not yet in [`Stats::xy_travel`] (see [`Self::flush_xy_travel`]):
    /// the first `xy_pending_len` (a fixed array: no capacity check per move).
    xy_pending: Box<[[f64; 2]; XY_BATCH]>,
    xy_pending_len: usize,
    /// The extruded box so far as [`BoundingBox`] bounds, empty (`+inf`/`-inf`) until the first
    /// point: one `min`/`max` per axis and point, no test for a first point.
    bbox: BoundingBox,
    /// `sin_cos` of the quarter angles [`Self::include_arc`] tests (computed once, as it computed them
    /// for each arc).
    quarter_sin_cos: [(f64, f64); 4],
}

/// How many XY steps [`StatsCollector`] holds before adding up their lengths.
const XY_BATCH: usize = 256;

/// A Z step (mm) between two extruding moves that starts a new level (smaller ones are a spiral's climb).
const LEVEL_STEP: f64 = 0.02;

impl Default for StatsCollector {
    fn default() -> Self {
        StatsCollector {
            stats: Stats::default(),
            codes: CodeCounts::default(),
            position: Position::default(),
            level_z: None,
            last_extruded: false,
            position_included: false,
            xy_pending: Box::new([[0.0; 2]; XY_BATCH]),
            xy_pending_len: 0,
            bbox: BoundingBox {
                min: [f64::INFINITY; 3],
                max: [f64::NEG_INFINITY; 3],
            },
            quarter_sin_cos: [0, 1, 2, 3]
                .map(|quarter| (f64::from(quarter) * std::f64::consts::FRAC_PI_2).sin_cos()),
        }
    }
}

impl StatsCollector {
    pub fn new() -> Self {
        Self::default()
    }

    /// Counts a lexed line and its command name.
    pub fn add_line(&mut self, line: &Line<'_>) {
        self.stats.lines += 1;
        match line.command() {
            Some(CommandWord::Code {
                letter,
                major,
                minor,
            }) => self.codes.add(letter, major, minor),
            Some(CommandWord::Extended) => {
                let name = line.command_text().unwrap_or_default().to_ascii_uppercase();
                *self.stats.commands.entry(name).or_default() += 1;
            }
            None => {}
        }
    }

    /// A `G0`/`G1` line's move from the fast path (which counts no code).
    #[inline(always)]
    fn add_fast_move(&mut self, m: &Move) {
        self.codes.add_g(if m.rapid { 0 } else { 1 });
        self.add_move(m);
    }

    /// Accounts for one interpreted command.
    pub fn add_command(&mut self, command: &Command) {
        match command {
            Command::Move(m) => self.add_move(m),
            Command::Arc(arc) => self.add_arc(arc, arc.radius()),
            Command::SetKinematicPosition { position } => {
                self.position_included = false;
                for (axis, value) in position.iter().enumerate() {
                    if let Some(value) = value {
                        self.position[axis] = *value;
                    }
                }
            }
            Command::Meta(Meta::LayerChange { .. }) => self.stats.layer_markers += 1,
            Command::Meta(Meta::Feature(name)) if !self.stats.features.contains(name) => {
                self.stats.features.insert(name.clone());
            }
            _ => {}
        }
    }

    #[inline(always)]
    fn add_move(&mut self, m: &Move) {
        self.stats.moves += 1;
        let start = self.position;
        let step = [m.target[0] - start[0], m.target[1] - start[1]];
        self.travel(&start, &m.target, step);
        // `hypot > 0` without the length, which is summed later.
        let moved = step[0] != 0.0 || step[1] != 0.0;
        let extruding = self.is_extruding(&start, &m.target, moved);
        if extruding {
            // Including a point twice changes nothing: an extrusion run costs one point per move
            // instead of two.
            if !self.position_included {
                self.include(&start);
            }
            self.include(&m.target);
        }
        self.position_included = extruding;
        self.level(extruding, m.target[2]);
        self.position = m.target;
    }

    /// One arc, whose radius (`arc.radius()`) is `radius`.
    fn add_arc(&mut self, arc: &ArcMove, radius: f64) {
        self.stats.arcs += 1;
        // `arc.length_xy()`, with radius and sweep (a hypot and an atan2 each) computed once for
        // the length and the bounding box.
        let sweep = arc.sweep();
        let xy = radius * sweep;
        // A step of (length, 0) adds exactly `length`.
        self.travel(&arc.start, &arc.target, [xy, 0.0]);
        let extruding = self.is_extruding(&arc.start, &arc.target, xy > 0.0);
        if extruding {
            self.include_arc(arc, radius, sweep);
        }
        self.position_included = extruding;
        self.level(extruding, arc.target[2]);
        self.position = arc.target;
    }

    /// Books a move's XY step (its length added later) and its filament.
    #[inline]
    fn travel(&mut self, start: &Position, end: &Position, xy_step: [f64; 2]) {
        // (Always below the batch, which is flushed when full: the mask spares a bounds check.)
        self.xy_pending[self.xy_pending_len % XY_BATCH] = xy_step;
        self.xy_pending_len += 1;
        if self.xy_pending_len == XY_BATCH {
            self.flush_xy_travel();
        }
        let de = end[3] - start[3];
        if de > 0.0 {
            self.stats.total_extrusion += de;
        } else {
            self.stats.total_retraction -= de;
        }
    }

    /// Counts extrusion Z levels (see [`Stats::layers`]).
    fn level(&mut self, extruding: bool, z: f64) {
        if extruding {
            let new = match self.level_z {
                None => true,
                Some(level) => {
                    let step = (z - level).abs();
                    step > LEVEL_STEP || (!self.last_extruded && step > 1e-6)
                }
            };
            if new {
                self.stats.extrusion_z_levels += 1;
            }
            if new || !self.last_extruded {
                self.level_z = Some(z);
            }
        }
        self.last_extruded = extruding;
    }

    /// Adds the pending XY steps' lengths to the travel, in file order (the same sum, to the bit,
    /// as adding each at its move). Why batched: between two moves' square roots lies a line's
    /// parsing, and each root's long latency stalls it; a loop of nothing but independent roots lets
    /// the processor overlap them.
    #[inline(never)]
    fn flush_xy_travel(&mut self) {
        let pending = &self.xy_pending[..std::mem::take(&mut self.xy_pending_len)];
        for &[dx, dy] in pending {
            self.stats.xy_travel += xy_length(dx, dy);
        }
    }

    /// Whether a move that `moved` in XY extruded (counted if so).
    fn is_extruding(&mut self, start: &Position, end: &Position, moved: bool) -> bool {
        let extruding = end[3] > start[3] && moved;
        if extruding {
            self.stats.extruding_moves += 1;
        }
        extruding
    }

    /// Grows the box to `p`. (From the empty box, the first point gives its own coordinates
    /// exactly: `inf.min(v)` is `v`, signed zeros included; positions are never NaN.)
    #[inline(always)]
    fn include(&mut self, p: &Position) {
        self.bbox.include([p[0], p[1], p[2]]);
    }

    /// End points plus every axis extreme (0°, 90°, 180°, 270°) the arc passes.
    /// (`r` and `sweep`: the arc's radius and sweep.)
    fn include_arc(&mut self, arc: &ArcMove, r: f64, sweep: f64) {
        self.include(&arc.start);
        self.include(&arc.target);
        let start_angle = (arc.start[1] - arc.centre[1]).atan2(arc.start[0] - arc.centre[0]);
        let z_mid = 0.5 * (arc.start[2] + arc.target[2]);
        for quarter in 0..4 {
            let angle = f64::from(quarter) * std::f64::consts::FRAC_PI_2;
            let travelled = if arc.clockwise {
                start_angle - angle
            } else {
                angle - start_angle
            };
            if rem_turn(travelled) <= sweep {
                let (s, c) = self.quarter_sin_cos[quarter as usize];
                let z = if arc.start[2] == arc.target[2] {
                    arc.start[2]
                } else {
                    z_mid
                };
                self.include(&[arc.centre[0] + r * c, arc.centre[1] + r * s, z, 0.0]);
            }
        }
    }

    /// The summary so far.
    pub fn finish(mut self, warnings: u64) -> Stats {
        self.flush_xy_travel();
        // Something was included exactly when the box is not empty.
        if self.bbox.min[0] <= self.bbox.max[0] {
            self.stats.extrusion_bbox = Some(self.bbox);
        }
        for ((letter, major, minor), count) in self.codes.counts() {
            let name = match minor {
                Some(minor) => format!("{}{major}.{minor}", letter as char),
                None => format!("{}{major}", letter as char),
            };
            *self.stats.commands.entry(name).or_default() += count;
        }
        self.stats.warnings = warnings;
        self.stats.layers = if self.stats.layer_markers > 0 {
            self.stats.layer_markers
        } else {
            self.stats.extrusion_z_levels
        };
        self.stats
    }
}

/// The lines the interpreter's fast path takes, counted and accounted for as it reads them. That
/// path takes only plain `G0`/`G1`/`G2`/`G3`/`G92` lines, blank lines and comment-only lines (whose
/// slicer metadata is a [`Command::Meta`], no command word), so the command tells the line's G code.
/// `file_stats_checked_against_the_general_path` keeps this in step with the fast path.
impl FastSink for StatsCollector {
    #[inline(always)]
    fn take(&mut self, made: Option<Spanned<Command>>) {
        self.stats.lines += 1;
        match made.map(|command| command.value) {
            // Moves and arcs come through `take_move` and `take_arc`.
            None => {}
            Some(Command::SetPosition { .. }) => self.codes.add_g(92),
            Some(other) => {
                debug_assert!(
                    matches!(other, Command::Meta(_)),
                    "the fast path gave {other:?}"
                );
                self.add_command(&other);
            }
        }
    }

    #[inline(always)]
    fn take_move(&mut self, _: Span, m: Move) {
        self.stats.lines += 1;
        self.add_fast_move(&m);
    }

    /// (The fast path's radius spares a second `hypot`, and the arc its box.)
    #[inline(always)]
    fn take_arc(&mut self, _: Span, arc: ArcMove, radius: f64) {
        self.stats.lines += 1;
        self.codes.add_g(if arc.clockwise { 2 } else { 3 });
        self.add_arc(&arc, radius);
    }
}

/// The length of an XY step: `√(dx² + dy²)`, within a relative 2⁻⁵² of `hypot`, without its library call (the largest
/// cost the statistics added to the reading; in [`StatsCollector::flush_xy_travel`]'s loop the square roots are
/// independent and overlap). Where the squares would overflow or underflow (coordinates beyond about 1e154 or
/// below 1e-154, which a file can hold), `hypot` itself.
#[inline]
fn xy_length(dx: f64, dy: f64) -> f64 {
    let squares = dx * dx + dy * dy;
    if (f64::MIN_POSITIVE..=f64::MAX).contains(&squares) {
        squares.sqrt()
    } else if dx == 0.0 && dy == 0.0 {
        0.0
    } else {
        dx.hypot(dy)
    }
}

/// `angle.rem_euclid(TAU)`, to the bit, without its `fmod` call (a tenth of an arc's cost) for an
/// angle within one turn either way, as nearly all [`StatsCollector::include_arc`] tests are: there
/// `fmod` gives the angle itself, and `rem_euclid` adds `TAU` to a negative one.
#[inline]
fn rem_turn(angle: f64) -> f64 {
    use std::f64::consts::TAU;
    if (0.0..TAU).contains(&angle) {
        angle
    } else if -TAU < angle && angle < 0.0 {
        angle + TAU
    } else {
        angle.rem_euclid(TAU)
    }
}

/// G and M codes below this without a minor number (all a slicer writes) are counted in a flat
/// table; others in a map.
const TABLE_CODES: u32 = 1024;

/// Command lines by code. A table, not a hash map: counting is one index per line instead of
/// hashing a key on every command line of the file.
#[derive(Debug, Clone)]
struct CodeCounts {
    /// `G0..G1023` then `M0..M1023` (an array: no length to check on each count).
    table: Box<[u64; 2 * TABLE_CODES as usize]>,
    rest: BTreeMap<(u8, u32, Option<u32>), u64>,
}

impl Default for CodeCounts {
    fn default() -> Self {
        CodeCounts {
            table: Box::new([0; 2 * TABLE_CODES as usize]),
            rest: BTreeMap::new(),
        }
    }
}

impl CodeCounts {
    #[inline]
    fn add(&mut self, letter: u8, major: u32, minor: Option<u32>) {
        let row = match letter {
            b'G' => 0,
            b'M' => TABLE_CODES,
            _ => u32::MAX,
        };
        if minor.is_none() && major < TABLE_CODES && row != u32::MAX {
            self.table[(row + major) as usize] += 1;
        } else {
            *self.rest.entry((letter, major, minor)).or_default() += 1;
        }
    }

    /// One more `G<major>` (`major` below [`TABLE_CODES`]).
    #[inline]
    fn add_g(&mut self, major: u32) {
        self.table[major as usize] += 1;
    }

    /// Every code counted at least once, with its count.
    fn counts(&self) -> impl Iterator<Item = ((u8, u32, Option<u32>), u64)> + '_ {
        let table = self
            .table
            .iter()
            .zip(0u32..)
            .filter(|(count, _)| **count > 0);
        let table = table.map(|(&count, index)| {
            let letter = if index < TABLE_CODES { b'G' } else { b'M' };
            ((letter, index % TABLE_CODES, None), count)
        });
        table.chain(self.rest.iter().map(|(&code, &count)| (code, count)))
    }
}

/// Summarises a whole input; stops at the first error.
pub fn file_stats(
    mut input: impl BufRead,
    source: impl Into<Arc<str>>,
) -> Result<Stats, GcodeError> {
    stats_of(&mut input, source.into(), true)
}

/// [`file_stats`]; with `fast_lines`, the lines the interpreter's fast path takes are neither lexed
/// nor interpreted a second time (the path [`crate::Commands`] takes; off only in tests, to compare).
/// Not generic: compiled once, in this crate, whatever the input, so `jointspace stats` runs the
/// code this crate's bench measures (an instance compiled in the CLI's crate took 8 % more
/// instructions). Only refills and the rare general lines reach the input through `dyn`.
fn stats_of(
    input: &mut dyn BufRead,
    source: Arc<str>,
    fast_lines: bool,
) -> Result<Stats, GcodeError> {
    let mut reader = Reader::new(input, source);
    let source = Arc::clone(reader.source());
    let mut interpreter = Interpreter::new(InterpreterOptions::default());
    let mut collector = StatsCollector::new();
    loop {
        // The interpreter's queue is empty here (drained after every general line), as the fast
        // path requires for a line to give the command the general path would.
        // All the lines the fast path takes in the input's buffer in one run; each command is
        // looked at where the fast path makes it, not stored and read back.
        if fast_lines
            && reader.take_lines_with(|bytes, number| {
                interpreter.fast_line_with(bytes, number, &mut collector)
            }) > 0
        {
            continue;
        }
        let Some(line) = reader.next_line() else {
            break;
        };
        let line = line?;
        collector.add_line(&line);
        interpreter.interpret_line(&line, &source)?;
        while let Some(command) = interpreter.pop_command() {
            collector.add_command(&command.value);
        }
    }
    interpreter.finish();
    while let Some(command) = interpreter.pop_command() {
        collector.add_command(&command.value);
    }
    let warnings = reader.warnings().total() + interpreter.warnings().total();
    Ok(collector.finish(warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_input::{each_corpus_file, gcode_lines};

    #[test]
    fn square_with_extrusion() {
        let text =
            "G90\nM82\nG0 X0 Y0 Z0.2\n;TYPE:Wall\nG1 X10 E1\nG1 Y10 E2\nG1 X0 E1.5\nG0 X-5 Y-5\n";
        let stats = file_stats(text.as_bytes(), "t").expect("stats");
        assert_eq!(stats.lines, 8);
        assert_eq!(stats.commands.get("G1"), Some(&3));
        assert_eq!(stats.commands.get("G90"), Some(&1));
        assert_eq!(stats.moves, 5);
        assert_eq!(stats.extruding_moves, 2);
        assert_eq!(stats.total_extrusion, 2.0);
        assert_eq!(stats.total_retraction, 0.5);
        assert!((stats.xy_travel - (30.0 + 250f64.sqrt())).abs() < 1e-12);
        assert_eq!(
            stats.extrusion_bbox,
            Some(BoundingBox {
                min: [0.0, 0.0, 0.2],
                max: [10.0, 10.0, 0.2]
            })
        );
        assert!(stats.features.contains("Wall"));
    }

    #[test]
    fn arc_bbox_reaches_the_circle_extremes() {
        // Half circle of radius 5 around (5, 0), counter-clockwise from (10,0) through (5,5) to (0,0).
        let stats = file_stats(&b"G1 X10 Y0\nG3 X0 Y0 I-5 J0 E3\n"[..], "t").expect("stats");
        let bbox = stats.extrusion_bbox.expect("bbox");
        assert!((bbox.max[1] - 5.0).abs() < 1e-12 && bbox.min[1].abs() < 1e-12);
        assert!((stats.xy_travel - (10.0 + 5.0 * std::f64::consts::PI)).abs() < 1e-12);
    }

    /// Both paths, as text (an error included): they must agree to the bit.
    fn both_paths(text: &[u8], capacity: usize) -> (String, String) {
        let mut buffered = std::io::BufReader::with_capacity(capacity, text);
        let fast = stats_of(&mut buffered, "t".into(), true);
        let general = stats_of(&mut &text[..], "t".into(), false);
        (format!("{fast:?}"), format!("{general:?}"))
    }

    #[test]
    fn file_stats_checked_against_the_general_path() {
        let text = "G90\nG0 X1 Y1\ng1 X2 E1\nG2 X3 Y2 I1\nG3 X2 Y1 J-1 E2\nG92 E0\nG92\n\
                    ;TYPE:Wall\n;LAYER_CHANGE\n;Z:0.2\nG1 Z0.2\nM104 S200\nG92.1\nG01 X1\n\n; c\n";
        for capacity in [1, 7, 64, 1 << 16] {
            let (fast, general) = both_paths(text.as_bytes(), capacity);
            assert_eq!(fast, general, "buffer of {capacity} bytes");
        }
        let stats = file_stats(text.as_bytes(), "t").expect("stats");
        let count = |name: &str| stats.commands.get(name).copied();
        assert_eq!(
            [
                count("G0"),
                count("G1"),
                count("G2"),
                count("G3"),
                count("G92")
            ],
            [Some(1), Some(3), Some(1), Some(1), Some(2)]
        );
        assert_eq!((count("G92.1"), count("M104")), (Some(1), Some(1)));
    }

    #[test]
    fn file_stats_on_the_corpus_as_the_general_path_gives() {
        each_corpus_file(|path, text| {
            let (fast, general) = both_paths(text, 1 << 16);
            assert!(fast == general, "{}", path.display());
        });
    }

    proptest::proptest! {
        #[test]
        fn file_stats_as_the_general_path_gives_on_any_lines(
            text in gcode_lines(
                vec![
                    "G1", "G0", "g1", "G01", "G1.5", "G2", "G3", "g2", "G92", "g92 E-1",
                    "G92.1", "G920", "M83", "M82", "G91", "G90", "G4 P1", "M104 S1",
                    "SET_FAN_SPEED FAN=a", ";LAYER_CHANGE", ";Z:0.4", ";TYPE:Wall", "",
                    "; c", "G1 ;c", ";LAYER:3", "; feature skirt", "G17", "G18",
                ],
                vec![
                    " X1.5", " Y-2", " Z.3", " E0.5", " E-1.25", " F1800", " I1",
                    " J-1", " X", " Q1", " ;c", "  ",
                ],
                4,
                16,
            ),
            capacity in 1usize..48,
        ) {
            let (fast, general) = both_paths(text.as_bytes(), capacity);
            proptest::prop_assert_eq!(fast, general);
        }
    }

    #[test]
    fn xy_length_is_hypot_within_rounding() {
        let values = [
            0.0,
            -0.0,
            3.0,
            -4.5,
            1e-6,
            -1e4,
            0.1,
            123.456_789,
            1e-310,
            -1e300,
            f64::MIN_POSITIVE,
            f64::MAX,
        ];
        for dx in values {
            for dy in values {
                let (ours, libm) = (xy_length(dx, dy), dx.hypot(dy));
                assert!(
                    ours == libm || (ours - libm).abs() <= f64::EPSILON * libm,
                    "({dx}, {dy}): {ours} vs {libm}"
                );
            }
        }
        // Along an axis the length is the coordinate's magnitude, exactly.
        assert_eq!(xy_length(-4.5, 0.0), 4.5);
        assert_eq!(xy_length(0.0, 123.456_789), 123.456_789);
    }

    #[test]
    fn rem_turn_is_rem_euclid_to_the_bit() {
        use std::f64::consts::{PI, TAU};
        let mut angles = vec![
            0.0,
            -0.0,
            TAU,
            -TAU,
            PI,
            -PI,
            2.5 * PI,
            -2.5 * PI,
            1e-300,
            -1e-300,
        ];
        angles.extend([TAU, -TAU, 0.0].map(|a: f64| a.next_up()));
        angles.extend([TAU, -TAU, 0.0].map(|a: f64| a.next_down()));
        angles.extend((-400..=400).map(|i| f64::from(i) * 0.0157));
        for angle in angles {
            let (ours, std) = (rem_turn(angle), angle.rem_euclid(TAU));
            assert_eq!(ours.to_bits(), std.to_bits(), "{angle}");
        }
    }

    #[test]
    fn serialises_to_json() {
        let stats = file_stats(&b"G1 X1 E1\n"[..], "t").expect("stats");
        let json = serde_json::to_string(&stats).expect("json");
        assert!(json.contains("\"moves\":1"));
    }
}
