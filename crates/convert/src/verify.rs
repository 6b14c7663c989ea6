//! Verification of converted G-code: re-reads the written text through the G-code reader, applying every
//! mode line the way the chosen firmware ([`ConvertOptions::firmware`]) does, replays the motor-space lines
//! through forward kinematics, interpolating linearly in motor space as firmware does, and measures the
//! nozzle's distance from the intended Cartesian path densely along every written segment; also totals
//! extrusion and print time (the input's Cartesian time at the requested speeds; the output's time as the
//! firmware runs its written feeds) and checks every written line against the motors' speed limits. It
//! knows nothing of how the converter meant the lines: a stray `G91` or `M82` in the output shows as a
//! wrong path or a wrong extrusion.
//!
//! Matching: the converter writes every segment's end points on the intended path (to rounding), and the
//! last segment of a move at the move's end. Each written segment is compared with the first input move,
//! in order, whose path holds both its end points; after a segment that ends at its move's end point the
//! search starts at the next move. Input moves that wrote nothing are stepped over. A segment off every
//! path is counted in [`VerifyReport::unmatched`] and measured against the nearest upcoming move.

use std::collections::VecDeque;
use std::io::BufRead;

use gcode::command::Command;
use gcode::{CommandWord, Line, Reader};
use kinematics::MotorUnit;

use crate::axes::AxisMap;
use crate::limits::AxisLimits;
use crate::options::{AngleUnit, ConvertOptions, Firmware, ModeState};
use crate::path::Path;

/// Samples per written segment (evenly spaced, end points included).
pub const SAMPLES_PER_SEGMENT: usize = 32;
/// How many input moves ahead a written segment may belong to.
const LOOKAHEAD: usize = 64;
/// A written line within this share of a motor's speed limit runs at that limit (feeds are written to 1e-7).
const LIMIT_SLACK: f64 = 1e-6;

/// What verification found.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VerifyReport {
    /// Largest nozzle distance from the intended path (mm).
    pub max_deviation: f64,
    /// Where the largest deviation occurs (Cartesian XY).
    pub worst_point: [f64; 2],
    /// Root mean square over all samples (mm).
    pub rms_deviation: f64,
    /// Motion lines checked (positioning `G0`s excluded).
    pub segments: u64,
    pub samples: u64,
    /// Written segments whose end points lie on none of the next input moves.
    pub unmatched: u64,
    /// Net extrusion (mm of filament) of the input and of the output.
    pub extrusion_in: f64,
    pub extrusion_out: f64,
    /// Print time (s): the input's Cartesian time at the requested speeds, and the time the machine takes:
    /// the written lines timed from their written feeds as the firmware reads them (`F` over the written axes'
    /// combined distance, or `G93` inverse time).
    pub time_in: f64,
    pub time_out: f64,
    /// Part of `time_out` spent rotating in place at the polar centre.
    pub flip_time: f64,
    /// Part of `time_out` (turns at the centre excluded) in lines that run a motor at its speed limit
    /// ([`ConvertOptions::motor_limits`]): where the machine may take longer than the Cartesian time.
    pub limited_time: f64,
    /// Written lines that drive a motor faster than its limit allows (more than 1e-6 over).
    pub over_limit: u64,
    /// The largest motor speed of any written line as a share of that motor's limit (0 without limits).
    pub max_limit_use: f64,
}

/// An output line verification could not read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("output line {line}: cannot replay `{text}`: {why}")]
pub struct VerifyError {
    pub line: u64,
    pub text: String,
    pub why: String,
}

/// One input move with a known start.
#[derive(Debug, Clone, Copy)]
struct Intended {
    path: Path,
}

/// One written segment with XY motion, as measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentDeviation {
    /// Largest sampled distance from the intended path (mm).
    pub max: f64,
    /// The segment ends at its input move's end point.
    pub ends_move: bool,
}

/// Replays `output` (G-code text written for `map`'s axes with `options`' letters and units, read as
/// `options.firmware` reads it) against the `input` commands.
pub fn verify<'a>(
    map: &AxisMap,
    options: &ConvertOptions,
    input: impl IntoIterator<Item = &'a Command>,
    output: impl BufRead,
) -> Result<VerifyReport, VerifyError> {
    verify_segments(map, options, input, output, |_| {})
}

/// [`verify`], also handing every measured segment to `each` in output order.
pub fn verify_segments<'a>(
    map: &AxisMap,
    options: &ConvertOptions,
    input: impl IntoIterator<Item = &'a Command>,
    output: impl BufRead,
    mut each: impl FnMut(SegmentDeviation),
) -> Result<VerifyReport, VerifyError> {
    let mut report = VerifyReport::default();
    let mut moves = Matcher {
        moves: IntendedMoves::new(input.into_iter(), options),
        window: VecDeque::new(),
        // Segment ends lie on their path up to the output's rounding.
        on_path: 3.0 * options.rounding_budget(map.units()) + 1e-9,
        move_finished: false,
    };
    let mut reader = OutputReader::new(map, options, options.firmware);
    let limits = AxisLimits::new(map, &options.motor_limits);
    let mut lines = Reader::new(output, "<output>");
    let mut squares = 0.0;
    while let Some(line) = lines.next_line() {
        let line = line.map_err(|e| VerifyError {
            line: e.span.line,
            text: e.line_text.clone(),
            why: e.kind.to_string(),
        })?;
        let segment = reader.read(&line).map_err(|why| VerifyError {
            line: line.number(),
            text: line.text().to_string(),
            why,
        })?;
        let Some(segment) = segment.filter(|s| !s.positioning) else {
            continue;
        };
        report.segments += 1;
        report.time_out += segment.time;
        let at_limit = limit_use(&limits, &segment, &mut report);
        let (Ok(start), Ok(end)) = (
            map.from_axes(segment.from, segment.z[0]),
            map.from_axes(segment.to, segment.z[1]),
        ) else {
            report.unmatched += 1;
            continue;
        };
        let turn =
            segment.from != segment.to && (start[0] - end[0]).hypot(start[1] - end[1]) < 1e-5;
        if at_limit && !turn {
            report.limited_time += segment.time;
        }
        if segment.from == segment.to {
            // No planar motion (Z or E only): no XY deviation to measure.
            continue;
        }
        if turn {
            report.flip_time += segment.time;
        }
        let Some(path) = moves.path_of(start, end, &mut report) else {
            continue;
        };
        let (sum, max) = measure(map, &path, &segment, &mut report);
        squares += sum;
        each(SegmentDeviation {
            max,
            ends_move: moves.move_finished,
        });
    }
    moves.moves.by_ref().for_each(drop);
    report.rms_deviation = if report.samples > 0 {
        (squares / report.samples as f64).sqrt()
    } else {
        0.0
    };
    report.extrusion_in = moves.moves.extrusion;
    report.time_in = moves.moves.time;
    report.extrusion_out = reader.extrusion;
    Ok(report)
}

/// Records how fast a written segment drives its limited motors (travel over the segment's time, against each
/// motor's limit); returns whether it runs one at its limit.
fn limit_use(limits: &AxisLimits, segment: &WrittenSegment, report: &mut VerifyReport) -> bool {
    if !limits.any() {
        return false;
    }
    let travel = [
        segment.to[0] - segment.from[0],
        segment.to[1] - segment.from[1],
        segment.z[1] - segment.z[0],
    ];
    let least = limits.min_time(travel);
    if least <= 0.0 {
        return false;
    }
    let share = least / segment.time;
    report.max_limit_use = report.max_limit_use.max(share);
    if share > 1.0 + LIMIT_SLACK {
        report.over_limit += 1;
    }
    share >= 1.0 - LIMIT_SLACK
}

/// Samples one written segment densely; returns the sum of squared deviations and the largest.
fn measure(
    map: &AxisMap,
    path: &Path,
    segment: &WrittenSegment,
    report: &mut VerifyReport,
) -> (f64, f64) {
    let part = path.part(0.0, 1.0);
    let (mut squares, mut max) = (0.0, 0.0f64);
    for i in 0..=SAMPLES_PER_SEGMENT {
        let u = i as f64 / SAMPLES_PER_SEGMENT as f64;
        let a = [0, 1].map(|j| segment.from[j] + (segment.to[j] - segment.from[j]) * u);
        let z = segment.z[0] + (segment.z[1] - segment.z[0]) * u;
        let Ok(q) = map.from_axes(a, z) else {
            report.unmatched += 1;
            break;
        };
        let d = part.distance(q);
        squares += d * d;
        max = max.max(d);
        report.samples += 1;
        if d > report.max_deviation {
            report.max_deviation = d;
            report.worst_point = q;
        }
    }
    (squares, max)
}

/// Finds the input move each written segment belongs to (see the module documentation).
struct Matcher<'o, I> {
    moves: IntendedMoves<'o, I>,
    window: VecDeque<Intended>,
    on_path: f64,
    /// The previous segment ended at its move's end point.
    move_finished: bool,
}

impl<'a, I: Iterator<Item = &'a Command>> Matcher<'_, I> {
    fn path_of(
        &mut self,
        start: [f64; 2],
        end: [f64; 2],
        report: &mut VerifyReport,
    ) -> Option<Path> {
        while self.window.len() < LOOKAHEAD {
            match self.moves.next() {
                Some(m) => self.window.push_back(m),
                None => break,
            }
        }
        if self.move_finished {
            self.window.pop_front();
        }
        let miss = |m: &Intended| {
            let part = m.path.part(0.0, 1.0);
            part.distance(start).max(part.distance(end))
        };
        let k = match self.window.iter().position(|m| miss(m) <= self.on_path) {
            Some(k) => k,
            None => {
                // Off every path: compare with the nearest one, so a wrong output shows how wrong it is.
                report.unmatched += 1;
                let nearest = self
                    .window
                    .iter()
                    .map(miss)
                    .enumerate()
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                nearest?.0
            }
        };
        self.window.drain(..k);
        let path = self.window.front()?.path;
        let path_end = path.point(1.0);
        self.move_finished = (end[0] - path_end[0]).hypot(end[1] - path_end[1]) <= self.on_path;
        Some(path)
    }
}

/// The input's moves with known starts, with extrusion and time totals.
struct IntendedMoves<'o, I> {
    commands: I,
    options: &'o ConvertOptions,
    position: Option<[f64; 4]>,
    last_e: f64,
    extrusion: f64,
    time: f64,
}

impl<'a, 'o, I: Iterator<Item = &'a Command>> IntendedMoves<'o, I> {
    fn new(commands: I, options: &'o ConvertOptions) -> Self {
        IntendedMoves {
            commands,
            options,
            position: None,
            last_e: 0.0,
            extrusion: 0.0,
            time: 0.0,
        }
    }

    fn placed(&self, p: [f64; 4]) -> [f64; 4] {
        let [x, y] = self.options.place([p[0], p[1]]);
        [x, y, p[2], p[3]]
    }

    /// Records a move to `target`; returns its start when known.
    fn advance(&mut self, target: [f64; 4]) -> Option<[f64; 4]> {
        self.extrusion += target[3] - self.last_e;
        self.last_e = target[3];
        self.position.replace(target)
    }
}

impl<'a, I: Iterator<Item = &'a Command>> Iterator for IntendedMoves<'_, I> {
    type Item = Intended;

    fn next(&mut self) -> Option<Intended> {
        loop {
            let (path, feed, de) = match self.commands.next()? {
                Command::Move(m) => {
                    let target = self.placed(m.target);
                    if self.position.is_none() && !(m.named[0] || m.named[1]) {
                        // XY still unknown: the converter writes a positioning Z, or a timed E-only line.
                        let de = target[3] - self.last_e;
                        if !m.named[2] && m.feed > 0.0 {
                            self.time += de.abs() / m.feed;
                        }
                        self.advance(target);
                        self.position = None;
                        continue;
                    }
                    let Some(start) = self.advance(target) else {
                        continue;
                    };
                    let path = Path::Line {
                        from: [start[0], start[1], start[2]],
                        to: [target[0], target[1], target[2]],
                    };
                    (path, m.feed, target[3] - start[3])
                }
                Command::Arc(a) => {
                    let target = self.placed(a.target);
                    let Some(start) = self.advance(target) else {
                        continue;
                    };
                    let centre = self.options.place(a.centre);
                    let path = Path::arc(
                        [start[0], start[1], start[2]],
                        [target[0], target[1], target[2]],
                        centre,
                        a.clockwise,
                        a.turns,
                    );
                    (path, a.feed, target[3] - start[3])
                }
                Command::Home { .. } => {
                    self.position = None;
                    continue;
                }
                _ => continue,
            };
            let length = path.length();
            let distance = if length > 0.0 { length } else { de.abs() };
            if feed > 0.0 {
                self.time += distance / feed;
            }
            if distance > 0.0 {
                return Some(Intended { path });
            }
        }
    }
}

/// One written motion line, in internal units (mm, rad).
struct WrittenSegment {
    from: [f64; 2],
    to: [f64; 2],
    z: [f64; 2],
    time: f64,
    positioning: bool,
}

/// Reads written G-code as the chosen firmware does: every mode line (`G90/G91`, `M82/M83`, `G20/G21`,
/// `G92`, `G93/G94`, `M220/M221`) acts as it does there, whoever wrote it.
struct OutputReader {
    letters: [u8; 2],
    /// Written unit → internal unit, per planar axis.
    to_internal: [f64; 2],
    modes: ModeState,
    /// Machine position in written units: the two planar axes, Z, E.
    machine: [f64; 4],
    /// `G92` offsets (machine − logical), written units.
    offset: [f64; 4],
    /// Where the machine is is unknown (after `G28`) until a move names both planar axes and Z.
    known: [bool; 3],
    /// `G20`: values are inches.
    unit: f64,
    feed: Option<f64>,
    speed_factor: f64,
    extrude_factor: f64,
    extrusion: f64,
    inverse_time: bool,
}

/// Why an output line cannot be replayed.
type LineFault = String;

impl OutputReader {
    fn new(map: &AxisMap, options: &ConvertOptions, firmware: Firmware) -> Self {
        let angle = match options.angle_unit {
            AngleUnit::Degrees => std::f64::consts::PI / 180.0,
            AngleUnit::Radians => 1.0,
        };
        let letters = options.letters().map(|c| c.to_ascii_uppercase() as u8);
        OutputReader {
            letters,
            to_internal: map
                .units()
                .map(|u| if u == MotorUnit::Rad { angle } else { 1.0 }),
            modes: ModeState::new(firmware),
            machine: [0.0; 4],
            offset: [0.0; 4],
            known: [true; 3],
            unit: 1.0,
            feed: None,
            speed_factor: 1.0,
            extrude_factor: 1.0,
            extrusion: 0.0,
            inverse_time: false,
        }
    }

    /// Index (0, 1 planar, 2 Z, 3 E) of a word letter, if it is an axis.
    fn axis(&self, letter: u8) -> Option<usize> {
        match letter {
            l if l == self.letters[0] => Some(0),
            l if l == self.letters[1] => Some(1),
            b'Z' => Some(2),
            b'E' => Some(3),
            _ => None,
        }
    }

    fn planar(&self) -> [f64; 2] {
        [0, 1].map(|i| self.machine[i] * self.to_internal[i])
    }

    /// Applies one line; returns the motion segment it writes, if any.
    fn read(&mut self, line: &Line<'_>) -> Result<Option<WrittenSegment>, LineFault> {
        let Some(CommandWord::Code {
            letter,
            major,
            minor: None,
        }) = line.command()
        else {
            return Ok(None);
        };
        let value = |l: u8| line.word(l).and_then(|w| w.value);
        match (letter, major) {
            (b'G', 0 | 1) => return self.motion(major == 0, line).map(Some),
            (b'G', 2 | 3) => {
                return Err("an arc: the firmware would interpolate it in motor space".into());
            }
            (b'G', 20) => self.unit = 25.4,
            (b'G', 21) => self.unit = 1.0,
            (b'G', 28) => {
                let named: Vec<usize> = line
                    .words()
                    .iter()
                    .filter_map(|w| self.axis(w.letter))
                    .collect();
                for i in 0..3 {
                    if named.is_empty() || named.contains(&i) {
                        self.known[i] = false;
                    }
                }
            }
            (b'G', 90) => self.modes.axes_mode(false),
            (b'G', 91) => self.modes.axes_mode(true),
            (b'G', 92) => {
                for w in line.words() {
                    let Some(i) = self.axis(w.letter) else {
                        continue;
                    };
                    let v = w.value.unwrap_or(0.0) * self.unit;
                    self.offset[i] = self.machine[i] - v;
                }
            }
            (b'G', 93) => self.inverse_time = true,
            (b'G', 94) => self.inverse_time = false,
            (b'M', 82) => self.modes.extrusion_mode(false),
            (b'M', 83) => self.modes.extrusion_mode(true),
            (b'M', 220) => self.speed_factor = value(b'S').unwrap_or(100.0) / 100.0,
            (b'M', 221) => self.extrude_factor = value(b'S').unwrap_or(100.0) / 100.0,
            _ => {}
        }
        Ok(None)
    }

    fn motion(&mut self, positioning: bool, line: &Line<'_>) -> Result<WrittenSegment, LineFault> {
        let (from, z0, e0) = (self.planar(), self.machine[2], self.machine[3]);
        let before = self.machine;
        // A move that names an axis whose place is unknown (after G28) starts nowhere: positioning.
        let mut from_unknown = false;
        for w in line.words() {
            let Some(value) = w.value else {
                return Err(format!("`{}` without a value", w.letter as char));
            };
            if w.letter == b'F' {
                self.feed = Some(value * self.unit);
                continue;
            }
            let Some(i) = self.axis(w.letter) else {
                return Err(format!("an unexpected `{}` word", w.letter as char));
            };
            let value = value * self.unit;
            let relative = if i == 3 {
                self.modes.relative_e()
            } else {
                self.modes.relative_axes()
            };
            self.machine[i] = if relative {
                self.machine[i] + value
            } else {
                value + self.offset[i]
            };
            if i < 3 {
                from_unknown |= !self.known[i];
                self.known[i] |= !relative;
            }
        }
        let de = (self.machine[3] - e0) * self.extrude_factor;
        self.extrusion += de;
        let written_delta = [0, 1, 2].map(|i| self.machine[i] - before[i]);
        let length = written_delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        let feed = self.feed.map(|f| f * self.speed_factor);
        let positioning = positioning || from_unknown;
        let time = match feed {
            _ if positioning => 0.0,
            Some(f) if self.inverse_time && f > 0.0 => 60.0 / f,
            Some(f) if f > 0.0 => 60.0 * if length > 0.0 { length } else { de.abs() } / f,
            _ => return Err("a timed move without a positive F".into()),
        };
        Ok(WrittenSegment {
            from,
            to: self.planar(),
            z: [z0, self.machine[2]],
            time,
            positioning,
        })
    }
}
