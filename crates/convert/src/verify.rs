//! Verification of converted G-code: replays the written motor-space lines through forward kinematics,
//! interpolating linearly in motor space as firmware does, and measures the nozzle's distance from the
//! intended Cartesian path densely along every written segment; also totals extrusion and print time at the
//! requested speeds on both sides.
//!
//! Matching: the converter writes every segment's end points on the intended path (to rounding), and the
//! last segment of a move at the move's end. Each written segment is compared with the first input move,
//! in order, whose path holds both its end points; after a segment that ends at its move's end point the
//! search starts at the next move. Input moves that wrote nothing are stepped over. A segment off every
//! path is counted in [`VerifyReport::unmatched`] and measured against the nearest upcoming move.

use std::collections::VecDeque;

use gcode::command::Command;
use kinematics::MotorUnit;

use crate::axes::AxisMap;
use crate::options::{AngleUnit, ConvertOptions, Extrusion};
use crate::path::Path;

/// Samples per written segment (evenly spaced, end points included).
pub const SAMPLES_PER_SEGMENT: usize = 32;
/// How many input moves ahead a written segment may belong to.
const LOOKAHEAD: usize = 64;

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
    /// Print time (s) at the requested speeds: input Cartesian, output as firmware times the written lines.
    pub time_in: f64,
    pub time_out: f64,
    /// Part of `time_out` spent rotating in place at the polar centre.
    pub flip_time: f64,
}

/// An output line verification could not read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("output line {line}: cannot read `{text}`")]
pub struct VerifyError {
    pub line: usize,
    pub text: String,
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

/// Replays `output` (written by a converter with `map` and `options`) against the `input` commands.
pub fn verify<'a>(
    map: &AxisMap,
    options: &ConvertOptions,
    input: impl IntoIterator<Item = &'a Command>,
    output: &str,
) -> Result<VerifyReport, VerifyError> {
    verify_segments(map, options, input, output, |_| {})
}

/// [`verify`], also handing every measured segment to `each` in output order.
pub fn verify_segments<'a>(
    map: &AxisMap,
    options: &ConvertOptions,
    input: impl IntoIterator<Item = &'a Command>,
    output: &str,
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
    let mut reader = OutputReader::new(map, options);
    let mut squares = 0.0;
    for (index, line) in output.lines().enumerate() {
        let segment = reader.read(line).map_err(|()| VerifyError {
            line: index + 1,
            text: line.to_string(),
        })?;
        let Some(segment) = segment.filter(|s| !s.positioning) else {
            continue;
        };
        report.segments += 1;
        report.time_out += segment.time;
        let (Ok(start), Ok(end)) = (
            map.from_axes(segment.from, segment.z[0]),
            map.from_axes(segment.to, segment.z[1]),
        ) else {
            report.unmatched += 1;
            continue;
        };
        if segment.from == segment.to {
            // No planar motion (Z or E only): no XY deviation to measure.
            continue;
        }
        if (start[0] - end[0]).hypot(start[1] - end[1]) < 1e-5 {
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

/// Reads the converter's output lines.
struct OutputReader {
    letters: [char; 2],
    /// Written unit → internal unit, per planar axis.
    to_internal: [f64; 2],
    relative_e: bool,
    axes: [f64; 2],
    z: f64,
    e: f64,
    extrusion: f64,
    inverse_time: bool,
}

impl OutputReader {
    fn new(map: &AxisMap, options: &ConvertOptions) -> Self {
        let angle = match options.angle_unit {
            AngleUnit::Degrees => std::f64::consts::PI / 180.0,
            AngleUnit::Radians => 1.0,
        };
        OutputReader {
            letters: options.letters(),
            to_internal: map
                .units()
                .map(|u| if u == MotorUnit::Rad { angle } else { 1.0 }),
            relative_e: options.extrusion == Extrusion::Relative,
            axes: [0.0; 2],
            z: 0.0,
            e: 0.0,
            extrusion: 0.0,
            inverse_time: false,
        }
    }

    /// Applies one line; returns the motion segment it writes, if any.
    fn read(&mut self, line: &str) -> Result<Option<WrittenSegment>, ()> {
        let code = line.split(';').next().unwrap_or("").trim();
        let mut words = code.split_ascii_whitespace();
        let Some(head) = words.next() else {
            return Ok(None);
        };
        match head {
            "G93" => self.inverse_time = true,
            "G94" => self.inverse_time = false,
            "G92" => {
                for w in words {
                    if let Some(v) = w.strip_prefix('E') {
                        self.e = v.parse().map_err(drop)?;
                    }
                }
            }
            "G0" | "G1" => return self.motion(head == "G0", words).map(Some),
            _ => {}
        }
        Ok(None)
    }

    fn motion<'l>(
        &mut self,
        positioning: bool,
        words: impl Iterator<Item = &'l str>,
    ) -> Result<WrittenSegment, ()> {
        let (from, z0) = (self.axes, self.z);
        let mut written_delta = [0.0f64; 3];
        let mut de = 0.0;
        let mut feed = None;
        for w in words {
            let mut chars = w.chars();
            let letter = chars.next().ok_or(())?;
            let value: f64 = chars.as_str().parse().map_err(drop)?;
            if let Some(i) = self.letters.iter().position(|&l| l == letter) {
                let internal = value * self.to_internal[i];
                written_delta[i] = (internal - self.axes[i]) / self.to_internal[i];
                self.axes[i] = internal;
            } else {
                match letter {
                    'Z' => {
                        written_delta[2] = value - self.z;
                        self.z = value;
                    }
                    'E' => {
                        de = if self.relative_e {
                            value
                        } else {
                            value - self.e
                        };
                        self.e = if self.relative_e {
                            self.e + value
                        } else {
                            value
                        };
                    }
                    'F' => feed = Some(value),
                    _ => return Err(()),
                }
            }
        }
        self.extrusion += de;
        let length = written_delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        let time = match feed {
            _ if positioning => 0.0,
            Some(f) if self.inverse_time && f > 0.0 => 60.0 / f,
            Some(f) if f > 0.0 => 60.0 * if length > 0.0 { length } else { de.abs() } / f,
            _ => return Err(()),
        };
        Ok(WrittenSegment {
            from,
            to: self.axes,
            z: [z0, self.z],
            time,
            positioning,
        })
    }
}
