//! Modal interpreter: turns lexed lines into [`Command`]s with Klipper's `gcode_move` semantics
//! (G90/G91, M82/M83, G92 offsets, M220/M221 factors, G20/G21 units, arcs kept whole).
//!
//! State is machine coordinates (`last_position`) plus G92 offsets (`base_position`); the G-code-space
//! position is `last − base` (E divided by the extrude factor, as Klipper reports it).
//! G20 (inches) scales every length the line gives: X Y Z E, I J R and F. The interpreter never
//! guesses where homing leaves the toolhead: the caller tells it with [`Interpreter::set_position`].

use std::collections::VecDeque;
use std::io::BufRead;
use std::sync::Arc;

use crate::command::{
    AccelParams, Arc as ArcMove, Command, Meta, Move, Position, Span, Spanned, VelocityLimit,
};
use crate::error::{ErrorKind, GcodeError, Warning, WarningKind, Warnings};
use crate::lexer::{CommandWord, Line, Word, span_of};
use crate::meta::{CommentMeta, comment_meta, may_start_meta};
use crate::number::parse_number;
use crate::reader::Reader;

/// Interpreter settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterpreterOptions {
    /// Speed before the first F, mm/s (Klipper: 25).
    pub initial_speed: f64,
    /// Machine position at start.
    pub initial_position: Position,
}

impl Default for InterpreterOptions {
    fn default() -> Self {
        InterpreterOptions {
            initial_speed: 25.0,
            initial_position: [0.0; 4],
        }
    }
}

/// An interpretation failure: where and what (boxed: the success path stays small and fast).
type Fail = Box<(Span, ErrorKind)>;

/// Arc plane (G17/G18/G19); only XY arcs are supported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Plane {
    Xy,
    Xz,
    Yz,
}

/// Start and end radii of an arc may differ by this much (mm) … (also how far an R arc's half chord
/// may exceed R: slicers round R and the end point to 3 decimals)
const ARC_RADIUS_TOLERANCE_MM: f64 = 0.005;
/// … or by this fraction of the radius, whichever is larger.
const ARC_RADIUS_TOLERANCE_REL: f64 = 1e-3;

/// The modal state and the queue of interpreted commands.
#[derive(Debug, Clone)]
pub struct Interpreter {
    last: Position,
    base: Position,
    absolute_coord: bool,
    absolute_extrude: bool,
    unit: f64,
    speed: f64,
    speed_factor: f64,
    extrude_factor: f64,
    plane: Plane,
    queue: VecDeque<Spanned<Command>>,
    /// The command of the line the fast path took last, until [`Commands::next_command`] hands it
    /// out (written in place: no copies of a large value through the reader).
    fast_command: Option<Spanned<Command>>,
    /// A layer start seen whose Z has not arrived yet.
    pending_layer: Option<Span>,
    warnings: Warnings,
}

impl Default for Interpreter {
    fn default() -> Self {
        Self::new(InterpreterOptions::default())
    }
}

/// Letter bit for parameter masks.
const fn bit(letter: u8) -> u32 {
    1 << (letter - b'A')
}

const XYZEF: u32 = bit(b'X') | bit(b'Y') | bit(b'Z') | bit(b'E') | bit(b'F');

impl Interpreter {
    pub fn new(options: InterpreterOptions) -> Self {
        Interpreter {
            last: options.initial_position,
            base: [0.0; 4],
            absolute_coord: true,
            absolute_extrude: true,
            unit: 1.0,
            speed: options.initial_speed,
            speed_factor: 1.0 / 60.0,
            extrude_factor: 1.0,
            plane: Plane::Xy,
            queue: VecDeque::new(),
            fast_command: None,
            pending_layer: None,
            warnings: Warnings::default(),
        }
    }

    /// Machine position after the commands interpreted so far.
    pub fn last_position(&self) -> Position {
        self.last
    }

    /// G92 offsets (machine = G-code + base).
    pub fn base_position(&self) -> Position {
        self.base
    }

    /// Position in the G-code frame (`last − base`, E divided by the extrude factor), mm.
    pub fn gcode_position(&self) -> Position {
        let mut p = [0.0; 4];
        for (i, value) in p.iter_mut().enumerate() {
            *value = self.last[i] - self.base[i];
        }
        p[3] /= self.extrude_factor;
        p
    }

    /// Declares the machine position (after homing or `SET_KINEMATIC_POSITION`).
    pub fn set_position(&mut self, position: Position) {
        self.last = position;
    }

    /// Current requested speed, mm/s.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// G90 (true) or G91.
    pub fn absolute_coordinates(&self) -> bool {
        self.absolute_coord
    }

    /// M82 (true) or M83.
    pub fn absolute_extrusion(&self) -> bool {
        self.absolute_extrude
    }

    /// M221 factor (1 = 100 %).
    pub fn extrude_factor(&self) -> f64 {
        self.extrude_factor
    }

    pub fn warnings(&self) -> &Warnings {
        &self.warnings
    }

    pub fn take_warnings(&mut self) -> Vec<Warning> {
        self.warnings.take()
    }

    /// Next interpreted command, if any is queued.
    #[inline]
    pub fn pop_command(&mut self) -> Option<Spanned<Command>> {
        self.queue.pop_front()
    }

    /// Shows `look` the command [`Self::fast_line`] left for the line it took last (none for a
    /// blank line or a comment without metadata) and drops it: nothing is copied out, for a caller
    /// that only looks at the command.
    #[inline(always)]
    pub(crate) fn look_at_fast_command<T>(
        &mut self,
        look: impl FnOnce(Option<&Command>) -> T,
    ) -> T {
        let seen = look(self.fast_command.as_ref().map(|c| &c.value));
        self.fast_command = None;
        seen
    }

    /// End of input: emits a layer start still waiting for its Z.
    pub fn finish(&mut self) {
        self.flush_pending_layer();
    }

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
    /// [`Commands::next_command`] returns); anything else is queued after it.
    fn interpret(
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

    fn flush_pending_layer(&mut self) {
        if let Some(span) = self.pending_layer.take() {
            let value = Command::Meta(Meta::LayerChange {
                index: None,
                z: None,
            });
            self.queue.push_back(Spanned { span, value });
        }
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
                        let value = Command::Meta(Meta::LayerChange {
                            index: None,
                            z: Some(z),
                        });
                        self.queue.push_back(Spanned { span, value });
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
                Command::Home {
                    axes: [named(b'X'), named(b'Y'), named(b'Z')],
                }
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

    /// The move to `target` at `speed` (mm/s), which becomes the modal position and speed.
    #[inline(always)]
    fn move_to(&mut self, target: Position, named: [bool; 4], speed: f64, rapid: bool) -> Move {
        self.last = target;
        self.speed = speed;
        Move {
            target,
            named,
            feed: speed,
            rapid,
        }
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

    /// Per axis, decided once per line rather than per word: the factor after the unit (M221 on E
    /// only; `x * 1.0` is exact, so X Y Z round as without it) and whether a value is absolute.
    #[inline]
    fn axis_modes(&self) -> ([f64; 4], [bool; 4]) {
        let coord = self.absolute_coord;
        let factor = [1.0, 1.0, 1.0, self.extrude_factor];
        (
            factor,
            [coord, coord, coord, coord && self.absolute_extrude],
        )
    }

    /// Machine position of `axis` for the G-code value `value` (`current`: the position so far).
    #[inline]
    fn axis_position(
        &self,
        axis: usize,
        value: f64,
        current: f64,
        factor: &[f64; 4],
        absolute: &[bool; 4],
    ) -> f64 {
        let value = value * self.unit * factor[axis];
        let origin = if absolute[axis] {
            self.base[axis]
        } else {
            current
        };
        value + origin
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

    /// Speed for the F value `f`, mm/s; `None` when not a positive finite speed.
    #[inline]
    fn speed_from_f(&self, f: f64) -> Option<f64> {
        let speed = f * self.unit * self.speed_factor;
        (f > 0.0 && speed.is_finite() && speed > 0.0).then_some(speed)
    }

    /// The fast paths for the commonest lines, read in one pass over the bytes without storing
    /// tokens: a plain move ([`Self::plain_move_line`]), a blank line and a comment-only line
    /// ([`Self::comment_line`]). `bytes` run from the line's start on (past its
    /// end). Gives the line's length (up to its `\n` or `\r`) and leaves its command (if any) in
    /// `fast_command`, or gives `None` for the general path.
    pub(crate) fn fast_line(&mut self, bytes: &[u8], line: u64) -> Option<usize> {
        let start = skip_blanks(bytes, 0);
        match *bytes.get(start)? {
            b'\n' | b'\r' => Some(start),
            b';' => self.comment_line(bytes, start, line),
            _ => self.plain_move_line(bytes, start, line),
        }
    }

    /// A comment-only line (its `;` at `semicolon`) as the general path reads it when nothing is
    /// queued: no command, or the one its slicer metadata gives. `None` when the comment is not
    /// UTF-8 (the general path warns) and when its end is not in `bytes`.
    fn comment_line(&mut self, bytes: &[u8], semicolon: usize, line: u64) -> Option<usize> {
        let first = skip_blanks(bytes, semicolon + 1);
        let may_hold_meta = may_start_meta(*bytes.get(first)?);
        let end = semicolon + memchr::memchr2(b'\n', b'\r', &bytes[semicolon..])?;
        let text = &bytes[semicolon + 1..end];
        if !may_hold_meta {
            return (text.is_ascii() || std::str::from_utf8(text).is_ok()).then_some(end);
        }
        let text = std::str::from_utf8(text).ok()?;
        self.comment_line_meta(text, span_of(line, semicolon, end))?;
        Some(end)
    }

    /// [`Self::comments`] for the one comment of a comment-only line; `None` (nothing changed)
    /// where that would flush a pending layer start, which the general path does.
    #[inline(never)]
    fn comment_line_meta(&mut self, text: &str, span: Span) -> Option<()> {
        if !self.queue.is_empty() {
            return None;
        }
        match comment_meta(text) {
            None => {}
            Some(CommentMeta::Meta(meta)) => {
                if self.pending_layer.is_some() {
                    return None;
                }
                let value = Command::Meta(meta);
                self.fast_command = Some(Spanned { span, value });
            }
            Some(CommentMeta::LayerStart) => {
                if self.pending_layer.is_some() {
                    return None;
                }
                self.pending_layer = Some(span);
            }
            Some(CommentMeta::LayerZ(z)) => {
                if let Some(span) = self.pending_layer.take() {
                    let value = Command::Meta(Meta::LayerChange {
                        index: None,
                        z: Some(z),
                    });
                    self.fast_command = Some(Spanned { span, value });
                }
            }
        }
        Some(())
    }

    /// A plain `G0`/`G1`/`G2`/`G3`/`G92` (its command word at `start`): blank-separated X Y Z E F
    /// words (arcs also I J; G92 no F), each once, each with a number, and nothing else. Any
    /// other line, a line whose end is not in `bytes`, and a command that would fail or warn, give
    /// `None` and go through the lexer and [`Self::interpret`], which give the same command for the
    /// lines this takes (checked by the `fast_path_*` tests). Gives the line's length and leaves
    /// its command in `fast_command`.
    fn plain_move_line(&mut self, bytes: &[u8], start: usize, line: u64) -> Option<usize> {
        if self.pending_layer.is_some() || !self.queue.is_empty() {
            return None;
        }
        let rapid = match bytes.get(start..start + 2)? {
            [b'G' | b'g', b'0'] => true,
            [b'G' | b'g', b'1'] => false,
            [b'G' | b'g', b'2'] => return self.plain_arc_line(bytes, start, line, true),
            [b'G' | b'g', b'3'] => return self.plain_arc_line(bytes, start, line, false),
            [b'G' | b'g', b'9'] if bytes.get(start + 2) == Some(&b'2') => {
                return self.plain_set_position_line(bytes, start, line);
            }
            _ => return None,
        };
        let command_end = start + 2;
        let (words, params_end, line_len) = plain_move_words::<LINEAR_SLOTS>(bytes, command_end)?;
        let value = Command::Move(self.plain_linear_move(&words, rapid)?);
        let span = span_of(line, start, command_end.max(params_end));
        self.fast_command = Some(Spanned { span, value });
        Some(line_len)
    }

    /// [`Self::plain_move_line`] for `G2`/`G3`, kept out of line: arcs are rarer, and the
    /// straight moves' loop stays as tight as without them.
    #[inline(never)]
    fn plain_arc_line(
        &mut self,
        bytes: &[u8],
        start: usize,
        line: u64,
        clockwise: bool,
    ) -> Option<usize> {
        let command_end = start + 2;
        let (words, params_end, line_len) = plain_move_words::<ARC_SLOTS>(bytes, command_end)?;
        let value = Command::Arc(Box::new(self.plain_arc(&words, clockwise)?));
        let span = span_of(line, start, command_end.max(params_end));
        self.fast_command = Some(Spanned { span, value });
        Some(line_len)
    }

    /// [`Self::plain_move_line`] for `G92` with X Y Z E words (slicers reset E this way).
    #[inline(never)]
    fn plain_set_position_line(&mut self, bytes: &[u8], start: usize, line: u64) -> Option<usize> {
        let command_end = start + 3;
        let (words, params_end, line_len) = plain_move_words::<POSITION_SLOTS>(bytes, command_end)?;
        let values = [0, 1, 2, 3].map(|axis| words.get(axis).map(|v| v * self.unit));
        let value = self.apply_set_position(values).ok()?;
        let span = span_of(line, start, command_end.max(params_end));
        self.fast_command = Some(Spanned { span, value });
        Some(line_len)
    }

    /// [`Self::linear_move`] for the words of a plain line; `None` where that would fail.
    fn plain_linear_move(&mut self, words: &MoveWords, rapid: bool) -> Option<Move> {
        let (target, named) = self.plain_target(words)?;
        let speed = self.plain_speed(words)?;
        Some(self.move_to(target, named, speed, rapid))
    }

    /// [`Self::arc`] for the words of a plain line with I or J; `None` where that would fail.
    fn plain_arc(&mut self, words: &MoveWords, clockwise: bool) -> Option<ArcMove> {
        if !self.absolute_coord || self.plane != Plane::Xy {
            return None;
        }
        let (target, _) = self.plain_target(words)?;
        let speed = self.plain_speed(words)?;
        let i = words.get(I_SLOT).map(|v| v * self.unit);
        let j = words.get(J_SLOT).map(|v| v * self.unit);
        if i.is_none() && j.is_none() {
            return None;
        }
        let offset = [i.unwrap_or(0.0), j.unwrap_or(0.0)];
        if offset[0].hypot(offset[1]) == 0.0 {
            return None;
        }
        let centre = checked_centre(&self.last, &target, offset).ok()?;
        let e_written = words.get(E_SLOT).map(|v| v * self.unit);
        Some(self.commit_arc(ArcEnds {
            target,
            centre,
            offset,
            clockwise,
            turns: 0,
            speed,
            e_written,
        }))
    }

    /// [`Self::target`] for the words of a plain line (not committed); `None` where that would
    /// fail.
    fn plain_target(&self, words: &MoveWords) -> Option<(Position, [bool; 4])> {
        let (factor, absolute) = self.axis_modes();
        let mut target = self.last;
        let mut named = [false; 4];
        for axis in 0..4 {
            if let Some(value) = words.get(axis) {
                named[axis] = true;
                target[axis] = self.axis_position(axis, value, target[axis], &factor, &absolute);
            }
        }
        // One test for the four axes: the sum is finite only if each is (a finite sum too large
        // to add up merely sends the line to the general path).
        (target[0] + target[1] + target[2] + target[3])
            .is_finite()
            .then_some((target, named))
    }

    /// [`Self::feed`] for the words of a plain line; `None` where that would fail.
    fn plain_speed(&self, words: &MoveWords) -> Option<f64> {
        match words.get(F_SLOT) {
            None => Some(self.speed),
            Some(f) => self.speed_from_f(f),
        }
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
            if offset[0].hypot(offset[1]) == 0.0 {
                return Err(Box::new((extent, ErrorKind::ArcZeroRadius)));
            }
            offset
        } else if let Some(r_word) = line.word(b'R') {
            let radius = required(r_word)? * self.unit;
            centre_offset_from_radius(&start, &target, radius, clockwise)
                .map_err(|kind| Box::new((extent, kind)))?
        } else {
            return Err(Box::new((extent, ErrorKind::ArcMissingCentre)));
        };
        let centre =
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

    /// Moves to the arc's end (the checks passed) and gives the arc from the current position.
    fn commit_arc(&mut self, ends: ArcEnds) -> ArcMove {
        let start = self.last;
        self.last = ends.target;
        self.speed = ends.speed;
        ArcMove {
            start,
            target: ends.target,
            centre: ends.centre,
            offset: ends.offset,
            clockwise: ends.clockwise,
            turns: ends.turns,
            feed: ends.speed,
            e_written: ends.e_written,
            base: self.base,
            extrude_factor: self.extrude_factor,
            absolute_extrude: self.absolute_extrude,
        }
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

    /// G92 for the G-code values given (in mm): `base = last − value` for each, or all four zeroed
    /// when none is given. `Err(axis)`, with nothing changed, when an axis's offset overflows.
    fn apply_set_position(&mut self, values: [Option<f64>; 4]) -> Result<Command, usize> {
        let mut position = [None; 4];
        if values.iter().all(Option::is_none) {
            self.base = self.last;
            return Ok(Command::SetPosition {
                position: [Some(0.0); 4],
            });
        }
        let mut base = self.base;
        for (axis, value) in values.iter().enumerate() {
            let Some(value) = *value else {
                continue;
            };
            let offset = if axis == 3 {
                value * self.extrude_factor
            } else {
                value
            };
            base[axis] = self.last[axis] - offset;
            if !base[axis].is_finite() {
                return Err(axis);
            }
            position[axis] = Some(value);
        }
        self.base = base;
        Ok(Command::SetPosition { position })
    }

    /// M220 S<percent>: rescales the current speed (Klipper keeps the requested F).
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

    /// M221 S<percent>: keeps the G-code E position continuous.
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

    fn warn(&mut self, span: Option<Span>, kind: WarningKind, message: &str) {
        self.warnings.push(Warning {
            span: span.unwrap_or_default(),
            kind,
            message: message.to_owned(),
        });
    }
}

/// Index of the first byte from `pos` that is not a blank.
fn skip_blanks(text: &[u8], pos: usize) -> usize {
    let blanks = text
        .get(pos..)
        .unwrap_or_default()
        .iter()
        .take_while(|&&b| b == b' ' || b == b'\t')
        .count();
    pos + blanks
}

/// The values of a plain move's words, by slot (see [`SLOT_BITS`]).
#[derive(Default)]
struct MoveWords {
    /// (Eight, one more than the slots: a slot masked to 0..=7 indexes it without a bounds check.)
    values: [f64; 8],
    /// Bit `slot` set when the word was given.
    given: u8,
}

impl MoveWords {
    fn get(&self, slot: usize) -> Option<f64> {
        (self.given & (1 << slot) != 0).then(|| self.values[slot])
    }
}

/// Slots of the words in [`MoveWords`]: X Y Z E are 0 to 3, as the axes.
const E_SLOT: usize = 3;
const F_SLOT: usize = 4;
const I_SLOT: usize = 5;
const J_SLOT: usize = 6;
/// The slots a plain G0/G1 may give, those a plain G2/G3 may give, and those of G92.
const LINEAR_SLOTS: u8 = 0b1_1111;
const POSITION_SLOTS: u8 = 0b1111;
const ARC_SLOTS: u8 = 0b111_1111;
/// Bit of each byte that is a plain-move letter (X Y Z E F I J in either case): `1 << slot`, else
/// 0. One look-up per word gives the bit to test and set, and the slot (its position).
const SLOT_BITS: [u8; 256] = {
    let mut table = [0; 256];
    let letters = *b"XYZEFIJ";
    let mut slot = 0;
    while slot < letters.len() {
        table[letters[slot] as usize] = 1 << slot;
        table[letters[slot].to_ascii_lowercase() as usize] = 1 << slot;
        slot += 1;
    }
    table
};

/// The words of a plain move, the end of its last word and the end of the line (where its `\n` or
/// `\r` is), from `pos` just after the command word; `None` unless the rest of the line is only
/// words with a slot in `ALLOWED`, each preceded by blanks, each letter once, each with a number
/// the lexer would accept.
#[inline]
fn plain_move_words<const ALLOWED: u8>(
    bytes: &[u8],
    mut pos: usize,
) -> Option<(MoveWords, usize, usize)> {
    let mut words = MoveWords::default();
    let mut params_end = pos;
    loop {
        // Blanks or the line end must follow the command and each word.
        match *bytes.get(pos)? {
            b' ' | b'\t' => pos += 1,
            b'\n' | b'\r' => return Some((words, params_end, pos)),
            _ => return None,
        }
        while let Some(b' ' | b'\t') = bytes.get(pos) {
            pos += 1;
        }
        let letter = *bytes.get(pos)?;
        let slot_bit = SLOT_BITS[usize::from(letter)];
        if slot_bit == 0 {
            return matches!(letter, b'\n' | b'\r').then_some((words, params_end, pos));
        }
        if (words.given | !ALLOWED) & slot_bit != 0 {
            return None;
        }
        let (value, after) = parse_number(bytes, pos + 1).ok()?;
        words.values[slot_bit.trailing_zeros() as usize & 7] = value;
        words.given |= slot_bit;
        pos = after;
        params_end = after;
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

/// Most extra turns an arc's `P` may ask for. Real prints use a handful; the bound keeps a stray
/// `P4000000000` from becoming trillions of chords downstream.
pub const MAX_ARC_TURNS: u32 = 1000;

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

/// Centre offset (from the start) of an R arc: short arc for R > 0, long arc for R < 0.
fn centre_offset_from_radius(
    start: &Position,
    target: &Position,
    radius: f64,
    clockwise: bool,
) -> Result<[f64; 2], ErrorKind> {
    let (dx, dy) = (target[0] - start[0], target[1] - start[1]);
    let chord = dx.hypot(dy);
    let half = chord / 2.0;
    let r = radius.abs();
    if r == 0.0 {
        return Err(ErrorKind::ArcZeroRadius);
    }
    if chord == 0.0 {
        return Err(ErrorKind::ArcRClosed);
    }
    if half > r + ARC_RADIUS_TOLERANCE_MM {
        return Err(ErrorKind::ArcRadiusTooSmall);
    }
    // Distance from the chord's midpoint to the centre (0 when the chord is a diameter).
    let h = (r * r - half * half).max(0.0).sqrt();
    // Counter-clockwise short arcs have their centre left of the chord; each flip changes side.
    let left = if clockwise == (radius < 0.0) {
        1.0
    } else {
        -1.0
    };
    let (ux, uy) = (dx / chord, dy / chord);
    Ok([dx / 2.0 - left * h * uy, dy / 2.0 + left * h * ux])
}

/// What an arc line gives besides the interpreter's state, once checked.
struct ArcEnds {
    target: Position,
    centre: [f64; 2],
    offset: [f64; 2],
    clockwise: bool,
    turns: u32,
    speed: f64,
    e_written: Option<f64>,
}

/// The XY centre at `offset` from `start`, when finite and as far from `target` as from `start`.
fn checked_centre(
    start: &Position,
    target: &Position,
    offset: [f64; 2],
) -> Result<[f64; 2], ErrorKind> {
    let centre = [start[0] + offset[0], start[1] + offset[1]];
    if !(centre[0].is_finite() && centre[1].is_finite()) {
        return Err(ErrorKind::NumberOverflow);
    }
    check_radii(start, target, &centre)?;
    Ok(centre)
}

/// Radius at start and end must agree (within 0.005 mm or 0.1 %).
fn check_radii(start: &Position, target: &Position, centre: &[f64; 2]) -> Result<(), ErrorKind> {
    let start_radius = (start[0] - centre[0]).hypot(start[1] - centre[1]);
    let end_radius = (target[0] - centre[0]).hypot(target[1] - centre[1]);
    let diff = (start_radius - end_radius).abs();
    let relative = diff / start_radius.max(end_radius);
    if diff > ARC_RADIUS_TOLERANCE_MM && relative > ARC_RADIUS_TOLERANCE_REL {
        return Err(ErrorKind::ArcInconsistent {
            start_radius,
            end_radius,
        });
    }
    Ok(())
}

/// Reader + interpreter: the stream of commands of one input.
#[derive(Debug)]
pub struct Commands<R> {
    reader: Reader<R>,
    interpreter: Interpreter,
    source: Arc<str>,
    finished: bool,
    /// Plain moves, blank and comment-only lines take [`Interpreter::fast_line`] (off only in tests,
    /// to compare).
    fast_lines: bool,
}

impl<R: BufRead> Commands<R> {
    pub fn new(reader: Reader<R>, options: InterpreterOptions) -> Self {
        let source = Arc::clone(reader.source());
        Commands {
            reader,
            interpreter: Interpreter::new(options),
            source,
            finished: false,
            fast_lines: true,
        }
    }

    /// Shorthand: read `input` named `source` with default options.
    pub fn from_reader(input: R, source: impl Into<Arc<str>>) -> Self {
        Self::new(Reader::new(input, source), InterpreterOptions::default())
    }

    /// The next command; `None` at the end. After an error, the next call continues with the next line.
    pub fn next_command(&mut self) -> Option<Result<Spanned<Command>, GcodeError>> {
        loop {
            if let Some(command) = self.interpreter.pop_command() {
                return Some(Ok(command));
            }
            if self.finished {
                return None;
            }
            if self.fast_lines {
                let interpreter = &mut self.interpreter;
                let taken = self
                    .reader
                    .take_line_with(|bytes, number| interpreter.fast_line(bytes, number));
                if taken.is_some() {
                    match self.interpreter.fast_command.take() {
                        Some(command) => return Some(Ok(command)),
                        None => continue,
                    }
                }
            }
            match self.reader.next_line() {
                None => {
                    self.interpreter.finish();
                    self.finished = true;
                }
                Some(Err(err)) => return Some(Err(err)),
                Some(Ok(line)) => {
                    if let Some(result) = self.interpreter.interpret(&line, &self.source) {
                        return Some(result);
                    }
                }
            }
        }
    }

    pub fn interpreter(&self) -> &Interpreter {
        &self.interpreter
    }

    /// For `set_position` after homing.
    pub fn interpreter_mut(&mut self) -> &mut Interpreter {
        &mut self.interpreter
    }

    pub fn reader(&self) -> &Reader<R> {
        &self.reader
    }

    /// All warnings so far (reader's, then interpreter's).
    pub fn take_warnings(&mut self) -> Vec<Warning> {
        let mut warnings = self.reader.warnings_mut().take();
        warnings.extend(self.interpreter.take_warnings());
        warnings
    }

    /// Number of warnings so far, including those not stored.
    pub fn warning_count(&self) -> u64 {
        self.reader.warnings().total() + self.interpreter.warnings().total()
    }
}

impl<R: BufRead> Iterator for Commands<R> {
    type Item = Result<Spanned<Command>, GcodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_command()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reader::ReaderOptions;

    fn run(text: &str) -> (Vec<Command>, Interpreter) {
        let mut commands = Commands::from_reader(text.as_bytes(), "t");
        let mut out = Vec::new();
        while let Some(command) = commands.next_command() {
            out.push(command.expect("command").value);
        }
        (out, commands.interpreter().clone())
    }

    fn first_error(text: &str) -> GcodeError {
        first_error_or_none(text).expect("an error")
    }

    fn first_error_or_none(text: &str) -> Option<GcodeError> {
        Commands::from_reader(text.as_bytes(), "t").find_map(Result::err)
    }

    fn moves(commands: &[Command]) -> Vec<Move> {
        commands
            .iter()
            .filter_map(|c| {
                if let Command::Move(m) = c {
                    Some(*m)
                } else {
                    None
                }
            })
            .collect()
    }

    #[test]
    fn absolute_relative_and_g92() {
        let (commands, state) = run("G1 X10 Y5 F600\nG91\nG1 X1 E2\nG90\nG92 X0\nG1 X3\n");
        let m = moves(&commands);
        assert_eq!(m[0].target, [10.0, 5.0, 0.0, 0.0]);
        assert_eq!(m[0].feed, 10.0);
        assert_eq!(m[1].target, [11.0, 5.0, 0.0, 2.0]);
        assert_eq!(m[2].target, [14.0, 5.0, 0.0, 2.0]);
        assert_eq!(state.base_position(), [11.0, 0.0, 0.0, 0.0]);
        assert_eq!(state.gcode_position(), [3.0, 5.0, 0.0, 2.0]);
    }

    #[test]
    fn relative_extrusion_and_bare_g92() {
        let (commands, state) = run("M83\nG1 E1\nG1 E1.5\nG92\nG1 E0.5\n");
        let m = moves(&commands);
        assert_eq!(m[1].target[3], 2.5);
        assert_eq!(m[2].target[3], 3.0);
        assert!(commands.contains(&Command::SetPosition {
            position: [Some(0.0); 4]
        }));
        assert_eq!(state.gcode_position()[3], 0.5);
    }

    #[test]
    fn m220_scales_speed_and_m221_keeps_e_continuous() {
        let (commands, state) = run("G1 X1 F6000\nM220 S50\nG1 X2\nM221 S200\nG1 E1\n");
        let m = moves(&commands);
        assert_eq!(m[0].feed, 100.0);
        assert_eq!(m[1].feed, 50.0);
        // E continuous at 0, then E1 at 200 % extrudes 2 mm of filament.
        assert_eq!(m[2].target[3], 2.0);
        assert_eq!(state.gcode_position()[3], 1.0);
    }

    #[test]
    fn inches() {
        let (commands, _) = run("G20\nG1 X1 F60\n");
        assert_eq!(moves(&commands)[0].target[0], 25.4);
        assert_eq!(moves(&commands)[0].feed, 25.4);
    }

    #[test]
    fn arcs_from_ij_and_r() {
        let (commands, _) = run("G1 X10 Y0\nG3 X0 Y10 I-10 J0\nG2 X10 Y0 R10\n");
        let arcs: Vec<_> = commands
            .iter()
            .filter_map(|c| {
                if let Command::Arc(a) = c {
                    Some(**a)
                } else {
                    None
                }
            })
            .collect();
        assert_eq!(arcs[0].centre, [0.0, 0.0]);
        assert!(!arcs[0].clockwise);
        // Short clockwise arc from (0,10) to (10,0): centre at the origin.
        assert!(
            arcs[1].centre[0].abs() < 1e-12 && arcs[1].centre[1].abs() < 1e-12,
            "{:?}",
            arcs[1].centre
        );
        let (commands, _) = run("G1 X10 Y0\nG2 X0 Y10 R-10\n");
        let Some(Command::Arc(long)) = commands.last() else {
            panic!("no arc")
        };
        assert!(
            long.centre[0].abs() < 1e-12 && long.centre[1].abs() < 1e-12,
            "{:?}",
            long.centre
        );
        let (commands, _) = run("G1 X10 Y0\nG3 X0 Y10 R-10\n");
        let Some(Command::Arc(long_ccw)) = commands.last() else {
            panic!("no arc")
        };
        assert!(
            (long_ccw.centre[0] - 10.0).abs() < 1e-12 && (long_ccw.centre[1] - 10.0).abs() < 1e-12
        );
    }

    #[test]
    fn arc_errors() {
        assert_eq!(first_error("G2 X1 Y1").kind, ErrorKind::ArcMissingCentre);
        assert_eq!(
            first_error("G91\nG2 X1 Y1 I1").kind,
            ErrorKind::ArcRelativeMode
        );
        assert_eq!(
            first_error("G2 X10 Y0 R2").kind,
            ErrorKind::ArcRadiusTooSmall
        );
        assert!(matches!(
            first_error("G2 X10 Y0 I1 J0").kind,
            ErrorKind::ArcInconsistent { .. }
        ));
        assert_eq!(
            first_error("G18\nG2 X1 I1").kind,
            ErrorKind::ArcPlaneUnsupported
        );
    }

    #[test]
    fn arc_turns_are_bounded() {
        let full_circles = |p: &str| format!("G1 X10 Y0\nG2 X10 Y0 I-10 J0 {p}");
        assert!(first_error_or_none(&full_circles(&format!("P{MAX_ARC_TURNS}"))).is_none());
        let err = first_error_or_none(&full_circles("P4000000000"))
            .expect("P beyond the bound is an error");
        assert_eq!(err.kind, ErrorKind::InvalidParameter("P".to_owned()));
        assert_eq!((err.span.line, err.span.column), (2, 19));
    }

    #[test]
    fn overflowing_values_are_errors_not_infinities() {
        let huge = "9".repeat(308);
        assert_eq!(
            first_error(&format!("G20\nG1 X{huge}")).kind,
            ErrorKind::NumberOverflow
        );
        assert_eq!(
            first_error(&format!("G20\nG2 X1 Y1 I{huge}")).kind,
            ErrorKind::NumberOverflow
        );
        let err = first_error(&format!("G1 F{huge}\nM220 S{huge}"));
        assert_eq!(err.kind, ErrorKind::InvalidParameter("S".to_owned()));
        let err = first_error(&format!("G1 E1\nG92 E-{huge}\nM221 S{huge}"));
        assert_eq!(err.kind, ErrorKind::InvalidParameter("S".to_owned()));
    }

    #[test]
    fn feed_and_dwell_errors() {
        let err = first_error("G1 X1 F0");
        assert_eq!((err.kind, err.span.column), (ErrorKind::InvalidFeedRate, 7));
        assert_eq!(first_error("G1 F-10").kind, ErrorKind::InvalidFeedRate);
        assert_eq!(first_error("G4 P-1").kind, ErrorKind::NegativeDwell);
        // Klipper reads only P: `G4 S2` does not wait, and says so at the word.
        let (commands, interpreter) = run("G4 P250\nG4 S2\nG4 P100 S5\n");
        assert_eq!(
            commands,
            vec![
                Command::Dwell { seconds: 0.25 },
                Command::Dwell { seconds: 0.0 },
                Command::Dwell { seconds: 0.1 }
            ]
        );
        let s_warnings: Vec<_> = interpreter
            .warnings()
            .list()
            .iter()
            .filter(|w| w.message.contains("G4 S"))
            .map(|w| (w.span.line, w.span.column))
            .collect();
        assert_eq!(s_warnings, vec![(2, 4), (3, 9)]);
    }

    #[test]
    fn klipper_extended_commands() {
        let (commands, state) = run(
            "SET_VELOCITY_LIMIT ACCEL=3000 SQUARE_CORNER_VELOCITY=5\nSET_KINEMATIC_POSITION X=300 Y=0\nset_fan_speed FAN=a SPEED=1\n",
        );
        assert_eq!(
            commands[0],
            Command::SetVelocityLimit(VelocityLimit {
                accel: Some(3000.0),
                square_corner_velocity: Some(5.0),
                ..VelocityLimit::default()
            })
        );
        assert_eq!(
            commands[1],
            Command::SetKinematicPosition {
                position: [Some(300.0), Some(0.0), None]
            }
        );
        assert_eq!(state.last_position(), [300.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            commands[2],
            Command::Other {
                name: "SET_FAN_SPEED".to_owned()
            }
        );
    }

    #[test]
    fn klipper_quoted_values_read_as_klipper_reads_them() {
        // Klipper splits extended parameters like a shell: '…' and "…" both quote.
        for text in [
            "SET_VELOCITY_LIMIT VELOCITY='200' ACCEL=\"3000\"\n",
            "SET_VELOCITY_LIMIT VELOCITY=200 ACCEL=3000\n",
        ] {
            let (commands, _) = run(text);
            assert_eq!(
                commands[0],
                Command::SetVelocityLimit(VelocityLimit {
                    velocity: Some(200.0),
                    accel: Some(3000.0),
                    ..VelocityLimit::default()
                }),
                "{text}"
            );
        }
    }

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_first_line() {
        let (commands, _) = run("\u{feff}G1 X10 F600\nG1 X20\n");
        assert_eq!(commands.len(), 2);
        assert!(matches!(commands[0], Command::Move(m) if m.target[0] == 10.0));
        // Elsewhere it is still an unexpected character.
        let text = "G1 X1\n\u{feff}G1 X2\n";
        let errors: Vec<_> = Commands::from_reader(text.as_bytes(), "t")
            .filter_map(Result::err)
            .collect();
        assert_eq!(errors.len(), 1);
        assert_eq!(errors[0].span.line, 2);
    }

    #[test]
    fn layer_metadata() {
        let (commands, _) = run(
            ";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nG1 X1\n; CHANGE_LAYER\nG1 X2\n;TYPE:Perimeter\n",
        );
        assert_eq!(
            commands[0],
            Command::Meta(Meta::LayerChange {
                index: None,
                z: Some(0.2)
            })
        );
        assert_eq!(
            commands[2],
            Command::Meta(Meta::LayerChange {
                index: None,
                z: None
            })
        );
        assert_eq!(
            commands[4],
            Command::Meta(Meta::Feature("Perimeter".to_owned()))
        );
    }

    /// Everything a stream gives, as text (`{:?}` tells `-0.0` from `0.0`): each command or error,
    /// the warnings, and the final state.
    fn stream(text: &[u8], fast_lines: bool) -> String {
        stream_from(text, fast_lines)
    }

    /// [`stream`] from any input (a small `BufReader` splits lines across refills).
    fn stream_from(input: impl BufRead, fast_lines: bool) -> String {
        let mut commands = Commands::from_reader(input, "t");
        commands.fast_lines = fast_lines;
        let out: Vec<_> = commands.by_ref().collect();
        let warnings = commands.take_warnings();
        let state = commands.interpreter();
        format!(
            "{out:?}\n{warnings:?}\n{:?} {:?}",
            state.last_position(),
            state.speed()
        )
    }

    #[test]
    fn fast_path_gives_what_the_general_path_gives() {
        let text = "G1 X1 Y2 F600\n  g0 x-1.5\tE.5 \nG1 X1 X2\nG1 X1 Q2\nG1 X\nG1 F0\nG1X1\nG01 X1\n\
                    G1 X1e5\nG1 X1 ;c\nG91\nG1 Z.2\nM83\nG1 E-0\nG20\nG1 X1 F60\n;LAYER_CHANGE\nG1 X3\n";
        assert_eq!(
            stream(text.as_bytes(), true),
            stream(text.as_bytes(), false)
        );
    }

    proptest::proptest! {
        #[test]
        fn fast_path_matches_the_general_path_on_any_lines(
            lines in proptest::collection::vec(
                (
                    proptest::sample::select(vec![
                        "G1", "G0", "g1", "G01", "G1.5", "G2", "G4", "M83", "M82", "G91", "G90",
                        "G92 E0", "G92 X1", "M221 S150", "M220 S50", "G20", "G21", "N5 G1", " G1",
                        ";LAYER_CHANGE", ";Z:0.4", "", "G1 ;c", "G28", "; note", ";TIME_ELAPSED:5",
                        ";TYPE:Perimeter", "  ; x", ";", "   ", "\t;c", "; caf\u{e9}", "; Z:1",
                        "G2", "G3", "g2", "G2 I1", "G3 J-1", "G2 X2 I1", "G3 Y0 I-1 J0", "G18",
                        "G17", ";LAYER:3", "; CHANGE_LAYER", "; Z_HEIGHT: 0.6", "; printing object a",
                        ";TYPE:", "; feature skirt", ";Z:x", "G92", "g92 E-1", "G92.1", "G920",
                    ]),
                    proptest::collection::vec(
                        proptest::sample::select(vec![
                            " X1.5", " Y-2", " Z.3", " E0.0123", " E-1.25", " F1800", " F0", " F-5",
                            " X", " Q1", "X2", " x3", "\tY4", " E1e5", " X1.2.3", " ;c", " (p)",
                            " *12", "  ", " X+5", " X5.", " Y-.5", " F9e9", " X#", " E99999999999",
                            " Z123456789012345678901234", " I1", " E", " J1", " I-1", " J0", " R1",
                            " P1", " I", " J.5",
                        ]),
                        0..5,
                    ),
                    proptest::sample::select(vec!["\n", "\r\n", "\r"]),
                ),
                0..12,
            ),
            capacity in 1usize..48,
        ) {
            let mut text = String::new();
            for (command, words, end) in &lines {
                text.push_str(command);
                for word in words {
                    text.push_str(word);
                }
                text.push_str(end);
            }
            let general = stream(text.as_bytes(), false);
            proptest::prop_assert_eq!(&stream(text.as_bytes(), true), &general);
            let small_buffer = std::io::BufReader::with_capacity(capacity, text.as_bytes());
            proptest::prop_assert_eq!(&stream_from(small_buffer, true), &general);
        }
    }

    #[test]
    fn fast_path_gives_the_arcs_the_general_path_gives() {
        let text = "G1 X10 Y0 F600\nG3 X0 Y10 I-10 J0 E1\nG2 X10 Y0 I0 J-10 F1200\nG3 X10 Y0 J5\n\
                    G2 X0 Y0 I0 J0\nG2 X1 Y1 I1 I2\nG2 X1 Y1 I1 Q2\nG2 X5 Y5 I3\nM83\nM221 S90\n\
                    G92 E0\nG3 X10 Y10 Z1 I-5 J5 E.5\nG20\nG2 X0 Y0 I.1 J.1\nG21\nG18\nG2 X1 I1\n\
                    G17\nG91\nG2 X1 I1\nG90\n;LAYER_CHANGE\nG3 X0 Y0 I1 J1\n;Z:2\nG2 X0 Y0 I-1 F0\n";
        assert_eq!(
            stream(text.as_bytes(), true),
            stream(text.as_bytes(), false)
        );
    }

    #[test]
    fn fast_path_gives_the_g92_the_general_path_gives() {
        let huge = "9".repeat(308);
        let text = format!(
            "G1 X5 E3\nG92 E0\nG92\nM221 S50\nG92 E1 X2 Y3 Z4\nG20\nG92 X{huge}\nG92 E2 E3\n\
             G92 F1\nG92 E\n;LAYER_CHANGE\nG92 E0\n"
        );
        assert_eq!(
            stream(text.as_bytes(), true),
            stream(text.as_bytes(), false)
        );
    }

    #[test]
    fn fast_path_keeps_comment_warnings_and_the_line_limit() {
        let text =
            b"G1 X1\n; caf\xe9\n  ;\xff\r\n;ok\n\nG1 X2 Y3 E4 F5\n; a longer comment line\nG1 X3\n";
        assert_eq!(stream(text, true), stream(text, false));
        assert!(stream(text, true).contains("LossyComment"));
        for max_line_len in 0..24 {
            let run = |fast_lines| {
                let reader = Reader::with_options(&text[..], "t", ReaderOptions { max_line_len });
                let mut commands = Commands::new(reader, InterpreterOptions::default());
                commands.fast_lines = fast_lines;
                format!("{:?}", commands.collect::<Vec<_>>())
            };
            assert_eq!(run(true), run(false), "max_line_len {max_line_len}");
        }
    }

    /// Input that fails after its text.
    struct FailingAfter<'a>(&'a [u8]);

    impl std::io::Read for FailingAfter<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.0.is_empty() {
                return Err(std::io::Error::other("disk on fire"));
            }
            let n = self.0.len().min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn fast_path_keeps_io_errors() {
        let text = b"G1 X1\r\nG1 X2\rG1 X3\nG1 X4";
        for capacity in [4, 8, 64] {
            let run = |fast_lines| {
                let input = std::io::BufReader::with_capacity(capacity, FailingAfter(text));
                let mut commands = Commands::from_reader(input, "t");
                commands.fast_lines = fast_lines;
                format!("{:?}", commands.collect::<Vec<_>>())
            };
            let fast = run(true);
            assert_eq!(fast, run(false));
            assert!(fast.contains("disk on fire"), "{fast}");
        }
    }

    #[test]
    fn fast_path_matches_the_general_path_on_the_corpus() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus");
        let Ok(entries) = std::fs::read_dir(&dir) else {
            eprintln!("{} absent: skipped", dir.display());
            return;
        };
        for path in entries.filter_map(Result::ok).map(|e| e.path()) {
            let text = std::fs::read(&path).expect("corpus file reads");
            let fast = stream(&text, true);
            assert!(fast == stream(&text, false), "{}", path.display());
        }
    }

    #[test]
    fn unknown_parameters_warn() {
        let mut commands = Commands::from_reader(&b"G1 X1 Q2 X3\n"[..], "t");
        let all: Vec<_> = commands.by_ref().collect();
        assert_eq!(all.len(), 1);
        let kinds: Vec<_> = commands
            .take_warnings()
            .into_iter()
            .map(|w| w.kind)
            .collect();
        assert_eq!(
            kinds,
            vec![
                WarningKind::UnknownParameter,
                WarningKind::DuplicateParameter
            ]
        );
    }
}
