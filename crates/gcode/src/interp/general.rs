//! The general path: a lexed line ([`Line`]) interpreted with every check, error and warning.

use std::sync::Arc;

use super::arcs::{ArcEnds, MAX_ARC_TURNS, centre_offset_from_radius, checked_centre};
use super::state::{Interpreter, Plane, layer_change};
use crate::command::{
    AccelParams, Arc as ArcMove, Command, Meta, Move, Position, Span, Spanned, VelocityLimit,
};
use crate::error::{ErrorKind, GcodeError, WarningKind};
use crate::lexer::{CommandWord, Line, Word};
use crate::meta::{CommentMeta, comment_meta};

/// An interpretation failure: where and what (boxed: the success path stays small and fast).
type Fail = Box<(Span, ErrorKind)>;

/// Letter bit for parameter masks.
const fn bit(letter: u8) -> u32 {
    1 << (letter - b'A')
}

const XYZEF: u32 = bit(b'X') | bit(b'Y') | bit(b'Z') | bit(b'E') | bit(b'F');

impl Interpreter {
    /// Interprets one line, queueing its commands (none on error: the state is left unchanged).
    pub fn interpret_line(&mut self, line: &Line<'_>, source: &Arc<str>) -> Result<(), GcodeError> {
        match self.interpret(line, source) {
            Some(Ok(command)) => self.queue.push_front(command),
            Some(Err(err)) => return Err(err),
            None => {}
        }
        Ok(())
    }

    /// Interprets one line. The line's main command is returned directly when nothing is queued
    /// before it (the common case: no queue round trip, and already in the shape
    /// [`crate::Commands::next_command`] returns); anything else is queued after it.
    pub(super) fn interpret(
        &mut self,
        line: &Line<'_>,
        source: &Arc<str>,
    ) -> Option<Result<Spanned<Command>, GcodeError>> {
        if let Some(result) = self.plain_move(line, source) {
            return Some(result);
        }
        let mut direct = None;
        if let Some(word) = line.command() {
            match self.command(line, word) {
                Err(fail) => {
                    return Some(Err(GcodeError::new(source, fail.0, line.text(), fail.1)));
                }
                Ok(None) => self.flush_pending_layer(),
                Ok(Some(value)) => {
                    self.flush_pending_layer();
                    let command = Spanned {
                        span: line.command_extent(),
                        value,
                    };
                    if self.queue.is_empty() {
                        direct = Some(Ok(command));
                    } else {
                        self.queue.push_back(command);
                    }
                }
            }
        }
        if line.has_comments() {
            self.comments(line);
        }
        direct
    }

    /// The hot path: a G0/G1 on a line without comments, with nothing queued and no layer start
    /// pending, gives the same result as the general path with fewer branches and copies.
    #[inline]
    fn plain_move(
        &mut self,
        line: &Line<'_>,
        source: &Arc<str>,
    ) -> Option<Result<Spanned<Command>, GcodeError>> {
        let Some(CommandWord::Code {
            letter: b'G',
            major: major @ (0 | 1),
            minor: None,
        }) = line.command()
        else {
            return None;
        };
        if line.has_comments() || self.pending_layer.is_some() || !self.queue.is_empty() {
            return None;
        }
        Some(match self.linear_move(line, major == 0) {
            Ok(value) => Ok(Spanned {
                span: line.command_extent(),
                value: Command::Move(value),
            }),
            Err(fail) => Err(GcodeError::new(source, fail.0, line.text(), fail.1)),
        })
    }

    fn comments(&mut self, line: &Line<'_>) {
        for comment in line.comments().filter(|c| !c.parenthesised) {
            match comment_meta(comment.text) {
                None => {}
                Some(CommentMeta::Meta(meta)) => {
                    self.flush_pending_layer();
                    self.queue.push_back(Spanned {
                        span: comment.span,
                        value: Command::Meta(meta),
                    });
                }
                Some(CommentMeta::LayerStart) => {
                    self.flush_pending_layer();
                    self.pending_layer = Some(comment.span);
                }
                Some(CommentMeta::LayerZ(z)) => {
                    if let Some(span) = self.pending_layer.take() {
                        self.queue.push_back(layer_change(span, Some(z)));
                    }
                }
            }
        }
    }

    fn command(&mut self, line: &Line<'_>, word: CommandWord) -> Result<Option<Command>, Fail> {
        match word {
            CommandWord::Code {
                letter: b'G',
                major,
                minor: None,
            } => self.g_code(line, major),
            CommandWord::Code {
                letter: b'M',
                major,
                minor: None,
            } => self.m_code(line, major),
            CommandWord::Code { letter, .. } => {
                if !matches!(letter, b'G' | b'M' | b'T') {
                    self.warn(
                        line.command_span(),
                        WarningKind::UnknownCommandLetter,
                        "unknown command letter",
                    );
                }
                Ok(Some(other(line)))
            }
            CommandWord::Extended => self.extended(line),
        }
    }

    fn g_code(&mut self, line: &Line<'_>, major: u32) -> Result<Option<Command>, Fail> {
        if matches!(major, 2 | 3 | 17..=19) && !self.commands.arcs {
            return Ok(self.unknown_command(line, "without [gcode_arcs]"));
        }
        if major == 20 && !self.commands.inches {
            return Err(Box::new((
                line.command_extent(),
                ErrorKind::InchUnitsUnsupported,
            )));
        }
        let command = match major {
            0 | 1 => Command::Move(self.linear_move(line, major == 0)?),
            2 | 3 => Command::Arc(Box::new(self.arc(line, major == 2)?)),
            4 => self.dwell(line)?,
            17..=19 => {
                self.plane = [Plane::Xy, Plane::Xz, Plane::Yz][(major - 17) as usize];
                return Ok(None);
            }
            20 | 21 => {
                self.unit = if major == 20 { 25.4 } else { 1.0 };
                return Ok(None);
            }
            28 => {
                self.check_letters(line, bit(b'X') | bit(b'Y') | bit(b'Z'));
                let named = |l| line.word(l).is_some();
                let axes = [named(b'X'), named(b'Y'), named(b'Z')];
                // Klipper: a homed axis's G-code offset is its SET_GCODE_OFFSET again (a G92 offset is dropped).
                let all = axes == [false; 3];
                for axis in (0..3).filter(|&a| all || axes[a]) {
                    self.base[axis] = self.homing[axis];
                }
                Command::Home { axes }
            }
            90 | 91 => {
                self.absolute_coord = major == 90;
                return Ok(None);
            }
            92 => self.set_gcode_position(line)?,
            _ => other(line),
        };
        Ok(Some(command))
    }

    fn m_code(&mut self, line: &Line<'_>, major: u32) -> Result<Option<Command>, Fail> {
        let command = match major {
            82 | 83 => {
                self.absolute_extrude = major == 82;
                return Ok(None);
            }
            204 => {
                self.check_letters(line, bit(b'S') | bit(b'P') | bit(b'T') | bit(b'R'));
                Command::SetAccel(AccelParams {
                    s: optional_value(line, b'S')?,
                    p: optional_value(line, b'P')?,
                    t: optional_value(line, b'T')?,
                    r: optional_value(line, b'R')?,
                })
            }
            220 => self.speed_override(line)?,
            221 => self.extrude_override(line)?,
            400 => Command::WaitForMoves,
            _ => other(line),
        };
        Ok(Some(command))
    }

    /// G0/G1: Klipper's `cmd_G1`.
    #[inline]
    fn linear_move(&mut self, line: &Line<'_>, rapid: bool) -> Result<Move, Fail> {
        let (target, named, feed) = self.target(line, XYZEF)?;
        let speed = self.feed(feed)?;
        Ok(self.move_to(target, named, speed, rapid))
    }

    /// New machine position from X Y Z E words (not yet committed) and the F word, in one pass over
    /// the words that also warns about letters outside `allowed` and repeated letters.
    #[allow(clippy::type_complexity)]
    #[inline]
    fn target<'l>(
        &mut self,
        line: &Line<'l>,
        allowed: u32,
    ) -> Result<(Position, [bool; 4], Option<&'l Word>), Fail> {
        let mut target = self.last;
        let mut named = [false; 4];
        let mut feed = None;
        let mut seen = 0u32;
        let (factor, absolute) = self.axis_modes();
        for word in line.words() {
            let letter_bit = bit(word.letter);
            if allowed & letter_bit == 0 || seen & letter_bit != 0 {
                self.letter_warning(word, allowed);
            }
            seen |= letter_bit;
            let axis = match word.letter {
                b'X' => 0,
                b'Y' => 1,
                b'Z' => 2,
                b'E' => 3,
                b'F' => {
                    feed = Some(word);
                    continue;
                }
                _ => continue,
            };
            named[axis] = true;
            target[axis] =
                self.axis_position(axis, required(word)?, target[axis], &factor, &absolute);
            if !target[axis].is_finite() {
                return Err(Box::new((word.span, ErrorKind::NumberOverflow)));
            }
        }
        Ok((target, named, feed))
    }

    /// Speed after this line's F word (if any), mm/s.
    #[inline]
    fn feed(&self, word: Option<&Word>) -> Result<f64, Fail> {
        let Some(word) = word else {
            return Ok(self.speed);
        };
        self.speed_from_f(required(word)?)
            .ok_or_else(|| Box::new((word.span, ErrorKind::InvalidFeedRate)))
    }

    /// G2/G3 in the XY plane, absolute mode only (as Klipper's `gcode_arcs`).
    fn arc(&mut self, line: &Line<'_>, clockwise: bool) -> Result<ArcMove, Fail> {
        let extent = line.command_extent();
        if !self.absolute_coord {
            return Err(Box::new((extent, ErrorKind::ArcRelativeMode)));
        }
        if self.plane != Plane::Xy {
            return Err(Box::new((extent, ErrorKind::ArcPlaneUnsupported)));
        }
        let (target, _, feed) =
            self.target(line, XYZEF | bit(b'I') | bit(b'J') | bit(b'R') | bit(b'P'))?;
        let speed = self.feed(feed)?;
        let start = self.last;
        let i = optional_value(line, b'I')?.map(|v| v * self.unit);
        let j = optional_value(line, b'J')?.map(|v| v * self.unit);
        let offset = if i.is_some() || j.is_some() {
            let offset = [i.unwrap_or(0.0), j.unwrap_or(0.0)];
            // (No radius: `hypot` is 0 exactly when both are, the offsets being finite or infinite.)
            if offset == [0.0; 2] {
                return Err(Box::new((extent, ErrorKind::ArcZeroRadius)));
            }
            offset
        } else if let Some(r_word) = line.word(b'R') {
            if !self.radius_arcs {
                return Err(Box::new((r_word.span, ErrorKind::ArcRadiusUnsupported)));
            }
            let radius = required(r_word)? * self.unit;
            centre_offset_from_radius(&start, &target, radius, clockwise)
                .map_err(|kind| Box::new((extent, kind)))?
        } else {
            return Err(Box::new((extent, ErrorKind::ArcMissingCentre)));
        };
        let (centre, _) =
            checked_centre(&start, &target, offset).map_err(|kind| Box::new((extent, kind)))?;
        let turns = match line.word(b'P') {
            None => 0,
            Some(word) => turns(word)?,
        };
        let e_written = optional_value(line, b'E')?.map(|v| v * self.unit);
        Ok(self.commit_arc(ArcEnds {
            target,
            centre,
            offset,
            clockwise,
            turns,
            speed,
            e_written,
        }))
    }

    /// G4: `P` milliseconds, as Klipper reads it. Klipper ignores `S` (Marlin's seconds), so a `G4 S30` in a
    /// slicer's start code does not wait there: the same here, with a warning at the word.
    fn dwell(&mut self, line: &Line<'_>) -> Result<Command, Fail> {
        self.check_letters(line, bit(b'P') | bit(b'S'));
        if let Some(s) = line.word(b'S') {
            let message =
                "G4 S (seconds) is ignored, as Klipper ignores it: use P (milliseconds) to wait";
            self.warn(Some(s.span), WarningKind::UnknownParameter, message);
        }
        let seconds = match line.word(b'P') {
            None => 0.0,
            Some(word) => {
                let value = required(word)?;
                if value < 0.0 {
                    return Err(Box::new((word.span, ErrorKind::NegativeDwell)));
                }
                value * 1e-3
            }
        };
        Ok(Command::Dwell { seconds })
    }

    /// G92: `base = last − value` for each named axis; bare G92 zeroes all four.
    fn set_gcode_position(&mut self, line: &Line<'_>) -> Result<Command, Fail> {
        self.check_letters(line, XYZEF & !bit(b'F'));
        let mut values = [None; 4];
        let mut spans = [Span::default(); 4];
        for word in line.words() {
            let axis = match word.letter {
                b'X' => 0,
                b'Y' => 1,
                b'Z' => 2,
                b'E' => 3,
                _ => continue,
            };
            values[axis] = Some(required(word)? * self.unit);
            spans[axis] = word.span;
        }
        self.apply_set_position(values)
            .map_err(|axis| Box::new((spans[axis], ErrorKind::NumberOverflow)))
    }

    /// M220 `S<percent>`: rescales the current speed (Klipper keeps the requested F).
    fn speed_override(&mut self, line: &Line<'_>) -> Result<Command, Fail> {
        self.check_letters(line, bit(b'S'));
        let percent = positive_percent(line)?;
        let factor = percent / (60.0 * 100.0);
        let speed = self.speed / self.speed_factor * factor;
        if !(speed.is_finite() && speed > 0.0) {
            return Err(invalid_s(line));
        }
        self.speed = speed;
        self.speed_factor = factor;
        Ok(Command::SpeedFactor(percent))
    }

    /// M221 `S<percent>`: keeps the G-code E position continuous.
    fn extrude_override(&mut self, line: &Line<'_>) -> Result<Command, Fail> {
        self.check_letters(line, bit(b'S'));
        let percent = positive_percent(line)?;
        let new_factor = percent / 100.0;
        let last_e = self.last[3];
        let e_value = (last_e - self.base[3]) / self.extrude_factor;
        let base_e = last_e - e_value * new_factor;
        if !base_e.is_finite() {
            return Err(invalid_s(line));
        }
        self.base[3] = base_e;
        self.extrude_factor = new_factor;
        Ok(Command::ExtrudeFactor(percent))
    }

    fn extended(&mut self, line: &Line<'_>) -> Result<Option<Command>, Fail> {
        let name = line.command_text().unwrap_or_default();
        let is = |n: &str| name.eq_ignore_ascii_case(n);
        let command = if is("SET_VELOCITY_LIMIT") {
            Command::SetVelocityLimit(VelocityLimit {
                velocity: ext_number(line, "VELOCITY")?,
                accel: ext_number(line, "ACCEL")?,
                square_corner_velocity: ext_number(line, "SQUARE_CORNER_VELOCITY")?,
                minimum_cruise_ratio: ext_number(line, "MINIMUM_CRUISE_RATIO")?,
                accel_to_decel: ext_number(line, "ACCEL_TO_DECEL")?,
            })
        } else if is("SET_KINEMATIC_POSITION") && !self.commands.kinematic_position {
            return Ok(self.unknown_command(line, "without [force_move] enable_force_move: True"));
        } else if is("SET_KINEMATIC_POSITION") {
            let position = [
                ext_number(line, "X")?,
                ext_number(line, "Y")?,
                ext_number(line, "Z")?,
            ];
            for (axis, value) in position.iter().enumerate() {
                if let Some(value) = value {
                    self.last[axis] = *value;
                }
            }
            Command::SetKinematicPosition { position }
        } else if is("SET_GCODE_OFFSET") {
            self.set_gcode_offset(line)?
        } else if is("EXCLUDE_OBJECT_START") || is("EXCLUDE_OBJECT_END") {
            let object = line
                .ext_param("NAME")
                .map(|p| p.value.to_owned())
                .unwrap_or_default();
            Command::Meta(if is("EXCLUDE_OBJECT_START") {
                Meta::ObjectStart(object)
            } else {
                Meta::ObjectEnd(object)
            })
        } else {
            other(line)
        };
        Ok(Some(command))
    }

    /// `SET_GCODE_OFFSET` as Klipper's `gcode_move` applies it: each axis's offset (`X=`, or `X_ADJUST=` added to the
    /// current one) shifts the G-code frame by its change (G28 later restores it, not a G92 offset); with `MOVE=1`
    /// the toolhead moves by that change too, at `MOVE_SPEED` (mm/s) or the current speed.
    fn set_gcode_offset(&mut self, line: &Line<'_>) -> Result<Command, Fail> {
        let mut delta = [0.0; 4];
        for (axis, name) in ["X", "Y", "Z", "E"].into_iter().enumerate() {
            let offset = match ext_number(line, name)? {
                Some(offset) => offset,
                None => match ext_number(line, &format!("{name}_ADJUST"))? {
                    Some(adjust) => adjust + self.homing[axis],
                    None => continue,
                },
            };
            delta[axis] = offset - self.homing[axis];
            self.homing[axis] = offset;
            self.base[axis] += delta[axis];
        }
        if !ext_number(line, "MOVE")?.is_some_and(|m| m != 0.0) {
            return Ok(other(line));
        }
        let feed = match ext_number(line, "MOVE_SPEED")? {
            None => self.speed,
            Some(speed) if speed > 0.0 => speed,
            Some(_) => return Err(invalid_ext(line, "MOVE_SPEED")),
        };
        let mut target = self.last;
        for (t, d) in target.iter_mut().zip(delta) {
            *t += d;
        }
        self.last = target;
        let named = delta.map(|d| d != 0.0);
        Ok(Command::Move(Move {
            target,
            named,
            feed,
            rapid: false,
        }))
    }

    /// A command the firmware lacks (`without` says why): Klipper answers "Unknown command" and goes on, so the
    /// line does nothing here either, and says so.
    fn unknown_command(&mut self, line: &Line<'_>, without: &str) -> Option<Command> {
        let name = line.command_text().unwrap_or_default().to_ascii_uppercase();
        let message = format!(
            "Klipper has no {name} {without}: it answers \"Unknown command\" and goes on, so this line does nothing"
        );
        self.warn(line.command_span(), WarningKind::UnknownCommand, &message);
        None
    }

    /// Warns about letters outside `allowed` and about repeated letters.
    fn check_letters(&mut self, line: &Line<'_>, allowed: u32) {
        let mut seen = 0u32;
        for word in line.words() {
            let letter_bit = bit(word.letter);
            if allowed & letter_bit == 0 || seen & letter_bit != 0 {
                self.letter_warning(word, allowed);
            }
            seen |= letter_bit;
        }
    }

    /// The warning for a word outside `allowed` or repeated.
    #[cold]
    fn letter_warning(&mut self, word: &Word, allowed: u32) {
        let letter = word.letter as char;
        if allowed & bit(word.letter) == 0 {
            let message = format!("parameter {letter} ignored by this command");
            self.warn(Some(word.span), WarningKind::UnknownParameter, &message);
        } else {
            let message = format!("parameter {letter} repeated; the last one is used");
            self.warn(Some(word.span), WarningKind::DuplicateParameter, &message);
        }
    }
}

/// `Other` with the command name upper-cased.
fn other(line: &Line<'_>) -> Command {
    Command::Other {
        name: line.command_text().unwrap_or_default().to_ascii_uppercase(),
    }
}

/// A word's value; a bare flag where a number is needed is an error.
#[inline]
fn required(word: &Word) -> Result<f64, Fail> {
    word.value.ok_or_else(|| {
        Box::new((
            word.span,
            ErrorKind::InvalidParameter((word.letter as char).to_string()),
        ))
    })
}

fn optional_value(line: &Line<'_>, letter: u8) -> Result<Option<f64>, Fail> {
    line.word(letter).map(required).transpose()
}

/// `S` of M220/M221: default 100, must be > 0.
fn positive_percent(line: &Line<'_>) -> Result<f64, Fail> {
    match line.word(b'S') {
        None => Ok(100.0),
        Some(word) => {
            let value = required(word)?;
            if value > 0.0 {
                Ok(value)
            } else {
                Err(Box::new((
                    word.span,
                    ErrorKind::InvalidParameter("S".to_owned()),
                )))
            }
        }
    }
}

/// M220/M221 `S` out of range.
fn invalid_s(line: &Line<'_>) -> Fail {
    let span = line
        .word(b'S')
        .map_or_else(|| line.command_extent(), |w| w.span);
    Box::new((span, ErrorKind::InvalidParameter("S".to_owned())))
}

/// `P` of an arc: a whole number of extra turns, at most [`MAX_ARC_TURNS`].
fn turns(word: &Word) -> Result<u32, Fail> {
    let value = required(word)?;
    let invalid = || Box::new((word.span, ErrorKind::InvalidParameter("P".to_owned())));
    if value < 0.0 || value.fract() != 0.0 || value > f64::from(MAX_ARC_TURNS) {
        return Err(invalid());
    }
    Ok(value as u32)
}

/// A numeric extended parameter (`ACCEL=3000`); must be finite.
/// An extended parameter's value refused.
fn invalid_ext(line: &Line<'_>, key: &str) -> Fail {
    let span = line
        .ext_param(key)
        .map_or_else(|| line.command_extent(), |p| p.span);
    Box::new((span, ErrorKind::InvalidParameter(key.to_owned())))
}

fn ext_number(line: &Line<'_>, key: &str) -> Result<Option<f64>, Fail> {
    let Some(param) = line.ext_param(key) else {
        return Ok(None);
    };
    match param.value.trim().parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(Some(value)),
        _ => Err(Box::new((
            param.span,
            ErrorKind::InvalidParameter(key.to_owned()),
        ))),
    }
}
