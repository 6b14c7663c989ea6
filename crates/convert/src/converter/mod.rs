//! The streaming converter: interpreted commands (with their raw line text) in, output G-code lines out.
//!
//! Memory is bounded by the longest single move's segment list; nothing else grows with the input.
//!
//! Output conventions:
//! - Axes are absolute (`G90` in the header), in mm; planar axes are the two output axes (see
//!   [`crate::Target`]), Z is Cartesian Z, E follows [`Extrusion`] (`M83` or `M82` in the header, after the
//!   `G90`, which in Marlin also sets E). Input `G90/G91/M82/M83/G20/G21/G17/G18/G19` lines never reach the
//!   output live: they are written as comments (the interpreter has applied them to the positions);
//!   `M220/M221` likewise (already in the feed and E).
//! - Nothing is invented: at the start and after a `G28` the position is the homing pose of
//!   [`ConvertOptions::home`]; without one, a coordinate the input has not set yet is refused
//!   ([`ConvertError::UnknownPosition`]).
//! - Every converted motion line is `G1` (so every line's `F` has the same meaning); the one exception is the
//!   first move after the start or a `G28`, whose start point is unknown: it is written as a single `G0`
//!   without `F` (a positioning move; its path is not defined by the input either). Until a move names X
//!   or Y, such moves write only Z and E.
//! - `G92 E` is written through; `G92 X/Y/Z` only renames coordinates (the interpreter has applied it) and is
//!   kept as a comment; `SET_KINEMATIC_POSITION` is refused.
//! - A move through the exact polar centre is cut there and the bed turns by the shortest rotation in a
//!   separate rotate-in-place line with E unchanged, at [`ConvertOptions::flip_speed`].

use std::io::Write;

use gcode::CommandWord;
use gcode::command::{Arc as ArcMove, Command, Move, Span, Spanned};
use kinematics::{CENTRE_TURN_GAP, MotorUnit, ReachError, SegmentError};

use crate::axes::AxisMap;
use crate::error::ConvertError;
use crate::format::{OutBuf, to_units};
use crate::limits::AxisLimits;
use crate::options::{ConvertOptions, Extrusion, FeedMode, Segmentation};
use crate::path::Path;
use crate::segment::{Breakpoint, Budget, CutError, cut_adaptive, cut_fixed};

mod checks;
mod writing;

use checks::{
    check_feed, check_magnitudes, is_consumed_mode, is_mode_command, passes_through, validate, xyz,
};

/// Share of the tolerance the probe check may use (the rest covers probe sampling and rounding).
const PROBE_MARGIN: f64 = 0.9;

/// Counts of what was written.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ConvertStats {
    /// Motion lines written for converted moves (not counting flips and positioning moves).
    pub segments: u64,
    /// Input moves and arcs converted.
    pub moves: u64,
    /// Rotate-in-place lines at the polar centre.
    pub flips: u64,
    /// Moves with an unknown start written as a single `G0`.
    pub positioning_moves: u64,
    /// Motion lines (segments and turns) slowed below their Cartesian time's feed by a motor speed limit.
    pub limited: u64,
}

/// One input line as the converter needs it.
#[derive(Debug, Clone, Copy)]
pub struct InputLine<'a> {
    /// The line's text, without its line end.
    pub text: &'a str,
    /// Its command word, if it has one.
    pub command: Option<CommandWord>,
    /// `G91` was in force for this line (its axis values are relative).
    pub relative_axes: bool,
}

/// What the converter has written so far, in output units.
#[derive(Debug, Clone, Copy, Default)]
struct Written {
    axes: [i64; 2],
    z: i64,
    /// Machine E at the last written point, in extrusion units.
    e: i64,
    /// Absolute mode: machine E units minus written E units (changed by `G92 E`).
    e_offset: i64,
    z_known: bool,
}

/// Streaming G-code converter. Feed it every input line with [`Converter::line`], then call
/// [`Converter::finish`].
#[derive(Debug)]
pub struct Converter<W: Write> {
    map: AxisMap,
    options: ConvertOptions,
    out: W,
    /// Output not yet handed to `out`.
    buf: OutBuf,
    cuts: Vec<Breakpoint>,
    /// Cartesian machine position `[x, y, z, e]` after the last command; `None` = unknown (start, G28).
    position: Option<[f64; 4]>,
    /// Output axes at the last written point (mm / rad, unwrapped).
    axes: [f64; 2],
    /// The last written point is at the polar centre (the next move starts with a flip).
    at_centre: bool,
    written: Written,
    /// Scale from internal axis units to written units, per planar axis.
    axis_scale: [f64; 2],
    axis_decimals: [u8; 2],
    rotary: [bool; 2],
    budget: Budget,
    /// The written axes' speed limits.
    limits: AxisLimits,
    started: bool,
    stats: ConvertStats,
    /// Which of the input's X Y Z are known (set by the input, or by the homing pose).
    known: [bool; 3],
}

impl<W: Write> Converter<W> {
    /// A converter writing motor-space G-code for `map`'s machine to `out`.
    pub fn new(map: AxisMap, options: ConvertOptions, out: W) -> Result<Self, ConvertError> {
        validate(&options)?;
        let units = map.units();
        let rotary = units.map(|u| u == MotorUnit::Rad);
        let axis_scale = units.map(|u| options.axis_scale(u));
        let axis_decimals = units.map(|u| options.axis_decimals(u));
        let budget = match options.segmentation {
            Segmentation::Adaptive { tolerance } => {
                let rounding = options.rounding_budget(units);
                Budget {
                    bound: tolerance - rounding,
                    probe: tolerance * PROBE_MARGIN - rounding,
                }
            }
            Segmentation::Fixed { .. } => Budget {
                bound: f64::INFINITY,
                probe: f64::INFINITY,
            },
        };
        if budget.probe <= 0.0 {
            return Err(ConvertError::Options(
                "tolerance is below the output's rounding: raise decimals".into(),
            ));
        }
        let home_known = options.home.is_some();
        let limits = AxisLimits::new(&map, &options.motor_limits);
        Ok(Converter {
            map,
            options,
            out,
            buf: OutBuf::default(),
            cuts: Vec::new(),
            position: None,
            axes: [0.0; 2],
            at_centre: false,
            written: Written::default(),
            axis_scale,
            axis_decimals,
            rotary,
            budget,
            limits,
            started: false,
            stats: ConvertStats::default(),
            known: [home_known; 3],
        })
    }

    pub fn stats(&self) -> ConvertStats {
        self.stats
    }

    pub fn options(&self) -> &ConvertOptions {
        &self.options
    }

    /// Converts one input line: `input` is its text and command word, `commands` what the interpreter made
    /// of it (empty for blank and comment-only lines, and for the mode lines the interpreter consumes).
    pub fn line(
        &mut self,
        input: InputLine<'_>,
        commands: &[Spanned<Command>],
    ) -> Result<(), ConvertError> {
        self.start()?;
        let raw = input.text;
        if commands.is_empty() && input.command.is_some_and(is_consumed_mode) {
            return self.write_note(raw, "already applied: the output uses mm and absolute axes");
        }
        if commands.iter().all(|c| passes_through(&c.value)) {
            return self.write_raw(raw);
        }
        if let Some(comment) = raw.find(';').map(|i| &raw[i..]) {
            self.write_raw(comment)?;
        }
        for command in commands {
            self.command(raw, command, input.relative_axes)?;
        }
        Ok(())
    }

    /// Ends the output (`G94` after inverse-time output), flushes, and returns the writer and the counts.
    pub fn finish(mut self) -> Result<(W, ConvertStats), ConvertError> {
        self.start()?;
        if self.options.feed == FeedMode::InverseTime {
            self.write_raw("G94")?;
        }
        self.buf.flush_to(&mut self.out)?;
        self.out.flush()?;
        Ok((self.out, self.stats))
    }

    fn start(&mut self) -> Result<(), ConvertError> {
        if self.started {
            return Ok(());
        }
        self.started = true;
        let e_mode = match self.options.extrusion {
            Extrusion::Relative => "M83",
            Extrusion::Absolute => "M82",
        };
        self.write_raw("; converted by jointspace")?;
        self.write_raw("G90")?;
        self.write_raw(e_mode)?;
        if self.options.feed == FeedMode::InverseTime {
            self.write_raw("G93")?;
        }
        Ok(())
    }

    fn command(
        &mut self,
        raw: &str,
        command: &Spanned<Command>,
        relative_axes: bool,
    ) -> Result<(), ConvertError> {
        let span = command.span;
        match &command.value {
            Command::Move(m) => {
                check_magnitudes(span, &m.target)?;
                if !relative_axes {
                    for i in 0..3 {
                        self.known[i] |= m.named[i];
                    }
                }
                self.straight(span, m)
            }
            Command::Arc(a) => {
                check_magnitudes(span, &a.target)?;
                // Arcs are absolute (the interpreter refuses them under G91); an axis the arc leaves out keeps
                // its value, so only an end that differs from the start was given.
                for i in 0..3 {
                    self.known[i] |= a.target[i] != a.start[i];
                }
                self.arc(span, a)
            }
            Command::Home { axes } => self.home(raw, *axes),
            Command::SetPosition { position } => {
                // A G92 value as far out as a move's would overflow the written E's integer units.
                check_magnitudes(span, &position.map(|v| v.unwrap_or(0.0)))?;
                self.set_position(raw, position)
            }
            Command::SetKinematicPosition { .. } => Err(ConvertError::Unsupported {
                span,
                what: "SET_KINEMATIC_POSITION".into(),
                why: "it declares a Cartesian pose the output firmware cannot interpret".into(),
            }),
            Command::SpeedFactor(_) | Command::ExtrudeFactor(_) => {
                self.write_note(raw, "already applied to the converted moves")
            }
            Command::Other { name } if is_mode_command(name) => {
                self.write_note(raw, "already applied: the output uses mm and absolute axes")
            }
            _ => Ok(()),
        }
    }

    fn home(&mut self, raw: &str, axes: [bool; 3]) -> Result<(), ConvertError> {
        self.position = None;
        self.at_centre = false;
        self.written.z_known = false;
        let all = !axes.iter().any(|&a| a);
        for (known, homed) in self.known.iter_mut().zip(axes) {
            if all || homed {
                *known = self.options.home.is_some();
            }
        }
        let letters = self.options.letters();
        if letters == ['X', 'Y'] || !(axes[0] || axes[1]) {
            return self.write_raw(raw);
        }
        let mut line = format!("G28 {} {}", letters[0], letters[1]);
        if axes[2] {
            line.push_str(" Z");
        }
        self.write_raw(&line)
    }

    fn set_position(&mut self, raw: &str, position: &[Option<f64>; 4]) -> Result<(), ConvertError> {
        if position[..3].iter().any(Option::is_some) {
            self.write_note(
                raw,
                "coordinates renamed; the output is in machine coordinates",
            )?;
        }
        let Some(e) = position[3] else { return Ok(()) };
        let decimals = self.options.decimals.extrusion;
        let new_units = to_units(e, decimals);
        if let Some(p) = self.position {
            self.written.e = to_units(p[3], decimals);
        }
        self.written.e_offset = self.written.e - new_units;
        self.buf.line_room(&mut self.out)?;
        self.buf.push_array(b"G92");
        self.buf.word('E', new_units, decimals);
        self.buf.push_array(b"\n");
        Ok(())
    }

    fn straight(&mut self, span: Span, m: &Move) -> Result<(), ConvertError> {
        let target = self.placed(m.target);
        let Some(start) = self.position else {
            if !(m.named[0] || m.named[1]) {
                return self.write_z_and_e_only(span, m);
            }
            return self.positioning_move(span, target);
        };
        self.stats.moves += 1;
        let path = Path::Line {
            from: xyz(start),
            to: xyz(target),
        };
        self.position = Some(target);
        if path.xy_length() == 0.0 {
            check_feed(span, m.feed)?;
            return self.write_in_place(start, target, m.feed);
        }
        let crossing = self.line_crossing(span, &path)?;
        self.convert_path(span, &path, crossing, (start[3], target[3]), m.feed)
    }

    fn arc(&mut self, span: Span, a: &ArcMove) -> Result<(), ConvertError> {
        let start = match self.position {
            Some(p) => p,
            None => self.placed(a.start),
        };
        let target = self.placed(a.target);
        let centre = self.options.place(a.centre);
        let path = Path::arc(xyz(start), xyz(target), centre, a.clockwise, a.turns);
        if self.position.is_none() {
            return self.positioning_move(span, target);
        }
        self.stats.moves += 1;
        self.position = Some(target);
        if path.xy_length() < 1e-9 {
            check_feed(span, a.feed)?;
            return self.write_in_place(start, target, a.feed);
        }
        if self.arc_meets_centre(&path) {
            return Err(ConvertError::Unsupported {
                span,
                what: "an arc through the polar centre".into(),
                why: "the bed angle is undefined there; write it as straight moves".into(),
            });
        }
        self.convert_path(span, &path, None, (start[3], target[3]), a.feed)
    }

    /// Input position moved by the placement offset.
    fn placed(&self, p: [f64; 4]) -> [f64; 4] {
        let [x, y] = self.options.place([p[0], p[1]]);
        [x, y, p[2], p[3]]
    }

    /// Where (as a path fraction) a straight move passes exactly through the polar centre.
    fn line_crossing(&self, span: Span, path: &Path) -> Result<Option<f64>, ConvertError> {
        let Path::Line { from, to } = *path else {
            return Ok(None);
        };
        match self.map.check_line(from, to) {
            Ok(()) => {}
            Err(SegmentError {
                t,
                reason: ReachError::AtCentre { .. },
            }) => {
                // Through the centre: each half is radial, so its ends bound what the arm must reach.
                for end in [from, to] {
                    if let Err(reason) = self.map.machine().check_point(end) {
                        return Err(ConvertError::Unreachable { span, reason });
                    }
                }
                return Ok(Some(t.clamp(0.0, 1.0)));
            }
            Err(SegmentError { reason, .. }) => {
                return Err(ConvertError::Unreachable { span, reason });
            }
        }
        // A line within the machine's centre tolerance (and the conversion's) meets the centre, as the planner
        // plans it: it is converted through the centre, where the bed turns in place.
        let Some((c, snap)) = self.centre_snap() else {
            return Ok(None);
        };
        let d = [to[0] - from[0], to[1] - from[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let t = (((c[0] - from[0]) * d[0] + (c[1] - from[1]) * d[1]) / len2).clamp(0.0, 1.0);
        let (mx, my) = (from[0] + d[0] * t - c[0], from[1] + d[1] * t - c[1]);
        let miss = (mx * mx + my * my).sqrt();
        Ok((miss <= snap).then_some(t))
    }

    /// The polar centre and the distance within which a path meets it: the machine's centre tolerance (as the
    /// planner and the plug-in use it), at most the conversion's tolerance.
    fn centre_snap(&self) -> Option<([f64; 2], f64)> {
        let centre = self.map.centre()?;
        let snap = match self.options.segmentation {
            Segmentation::Adaptive { tolerance } => centre.tolerance.min(tolerance),
            Segmentation::Fixed { .. } => centre.tolerance,
        };
        Some((centre.point, snap))
    }

    fn arc_meets_centre(&self, path: &Path) -> bool {
        match self.centre_snap() {
            Some((c, snap)) => path.distance_xy(c, 0.0, 1.0) <= snap,
            None => false,
        }
    }

    /// Converts a path with XY motion; `crossing` = fraction where it meets the polar centre.
    fn convert_path(
        &mut self,
        span: Span,
        path: &Path,
        crossing: Option<f64>,
        e: (f64, f64),
        feed: f64,
    ) -> Result<(), ConvertError> {
        check_feed(span, feed)?;
        let gap = (CENTRE_TURN_GAP / path.xy_length()).min(0.5);
        let mut s = 0.0;
        if self.at_centre || crossing.is_some_and(|t| t <= gap) {
            s = gap;
            self.flip(span, path, s, feed)?;
        }
        if let Some(t) = crossing.filter(|&t| t > gap) {
            let ends_at_centre = t + gap >= 1.0;
            let s_in = (t - gap).max(s);
            self.cut_and_write(span, path, (s, s_in), e, feed, ends_at_centre)?;
            if ends_at_centre {
                self.at_centre = true;
                return Ok(());
            }
            s = t + gap;
            self.flip(span, path, s, feed)?;
        }
        self.cut_and_write(span, path, (s, 1.0), e, feed, true)?;
        self.at_centre = false;
        Ok(())
    }

    /// Rotate in place at the centre to the axes of `path.point(s)`, the nearest equivalent angle.
    fn flip(&mut self, span: Span, path: &Path, s: f64, feed: f64) -> Result<(), ConvertError> {
        let to = self
            .map
            .to_axes(path.point(s), self.axes)
            .map_err(|reason| ConvertError::Unreachable { span, reason })?;
        let turn = (0..2)
            .filter(|&i| self.rotary[i])
            .map(|i| (to[i] - self.axes[i]).abs())
            .fold(0.0, f64::max);
        self.axes = to;
        self.at_centre = false;
        // A machine without rotary output axes (corrected Cartesian) only crosses the gap.
        let time = (turn / self.options.flip_speed).max(2.0 * CENTRE_TURN_GAP / feed);
        let z = path.point(s)[2];
        let e_units = self.written.e;
        if self.write_motion(to, z, e_units, time, feed)? {
            self.stats.flips += 1;
        }
        Ok(())
    }

    /// Cuts `[s0, s1]` of `path` and writes its segments with their share of E and Cartesian time; the last
    /// segment of the move (`last`) writes the move's end E exactly, absorbing rounding.
    fn cut_and_write(
        &mut self,
        span: Span,
        path: &Path,
        (s0, s1): (f64, f64),
        e: (f64, f64),
        feed: f64,
        last: bool,
    ) -> Result<(), ConvertError> {
        if s1 <= s0 {
            return Ok(());
        }
        let length = path.length();
        let mut cuts = std::mem::take(&mut self.cuts);
        cuts.clear();
        let from = (s0, self.axes);
        let result = match self.options.segmentation {
            Segmentation::Adaptive { .. } => {
                cut_adaptive(path, &self.map, from, s1, self.budget, &mut cuts)
            }
            Segmentation::Fixed {
                segments_per_second,
                min_length,
            } => {
                let piece = length * (s1 - s0);
                let by_time = (piece / feed * segments_per_second).round();
                let by_length = (piece / min_length).floor().max(1.0);
                cut_fixed(
                    path,
                    &self.map,
                    from,
                    s1,
                    by_time.clamp(1.0, by_length) as usize,
                    &mut cuts,
                )
            }
        };
        if let Err(e) = result {
            self.cuts = cuts;
            return Err(self.cut_error(span, path, e));
        }
        let decimals = self.options.decimals.extrusion;
        let mut s_prev = s0;
        for cut in &cuts {
            let p = path.point(cut.s);
            if matches!(path, Path::Arc { .. }) {
                self.map.check_line(path.point(s_prev), p).map_err(|err| {
                    ConvertError::Unreachable {
                        span,
                        reason: err.reason,
                    }
                })?;
            }
            let e_units = if last && cut.s >= s1 {
                to_units(e.1, decimals)
            } else {
                to_units(e.0 + (e.1 - e.0) * cut.s, decimals)
            };
            let time = length * (cut.s - s_prev) / feed;
            self.axes = cut.axes;
            if self.write_motion(cut.axes, p[2], e_units, time, feed)? {
                self.stats.segments += 1;
            }
            s_prev = cut.s;
        }
        self.cuts = cuts;
        Ok(())
    }

    fn tolerance(&self) -> f64 {
        match self.options.segmentation {
            Segmentation::Adaptive { tolerance } => tolerance,
            Segmentation::Fixed { .. } => f64::INFINITY,
        }
    }

    fn cut_error(&self, span: Span, path: &Path, e: CutError) -> ConvertError {
        match e {
            CutError::Reach(reason) => ConvertError::Unreachable { span, reason },
            CutError::NoConvergence { s } => {
                let p = path.point(s);
                ConvertError::NoConvergence {
                    span,
                    x: p[0],
                    y: p[1],
                    tolerance: self.tolerance(),
                }
            }
        }
    }
}
