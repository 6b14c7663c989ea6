//! The fast path: the commonest lines (plain moves, arcs and G92, blank and comment lines) read in
//! one pass over the bytes and their command handed to the caller where it is made; anything else
//! goes to the general path.

use super::arcs::{ArcEnds, checked_centre};
use super::state::{Interpreter, Plane, layer_change};
use crate::command::{Arc as ArcMove, Command, Move, Position, Span, Spanned};
use crate::lexer::span_of;
use crate::meta::{CommentMeta, comment_meta, may_start_meta};
use crate::number::parse_number;

/// A command the fast path made (none for a blank line or a comment without metadata).
pub(crate) type Made = Option<Spanned<Command>>;

/// Where [`Interpreter::fast_line_with`] hands the command of each line it takes.
pub(crate) trait FastSink {
    /// Any line's command.
    fn take(&mut self, made: Made);

    /// A plain `G0`/`G1`'s move, the commonest command: a sink that looks at the move alone gets
    /// it without the [`Command`] around it, where it was made.
    #[inline(always)]
    fn take_move(&mut self, span: Span, value: Move) {
        let value = Command::Move(value);
        self.take(Some(Spanned { span, value }));
    }

    /// A plain `G2`/`G3`'s arc and its radius (`value.radius()`, to the bit), without the box of
    /// a [`Command::Arc`].
    #[inline(always)]
    fn take_arc(&mut self, span: Span, value: ArcMove, _radius: f64) {
        let value = Command::Arc(Box::new(value));
        self.take(Some(Spanned { span, value }));
    }
}

/// [`Interpreter::fast_line`]'s sink: the command kept.
impl FastSink for Made {
    #[inline(always)]
    fn take(&mut self, made: Made) {
        *self = made;
    }
}

impl Interpreter {
    /// The fast paths for the commonest lines (see [`Self::fast_line_with`]), leaving the line's
    /// command (if any) in `made` ([`crate::Commands`]' slot for it, written in place).
    pub(crate) fn fast_line(&mut self, bytes: &[u8], line: u64, made: &mut Made) -> Option<usize> {
        self.fast_line_with(bytes, line, made)
    }

    /// The fast paths for the commonest lines, read in one pass over the bytes without storing
    /// tokens: a plain move ([`Self::plain_line`]), a blank line and a comment-only line
    /// ([`Self::comment_line`]). `bytes` run from the line's start on (past its end). Gives the
    /// line's length (up to its `\n` or `\r`) and hands its command to `sink`, or gives `None`,
    /// with nothing changed and nothing handed over, for the general path. Inlined into its
    /// caller: a plain move reaches the sink in registers (read back from memory just after its
    /// stores, it stalled the sink's reads).
    #[inline(always)]
    pub(crate) fn fast_line_with(
        &mut self,
        bytes: &[u8],
        line: u64,
        sink: &mut impl FastSink,
    ) -> Option<usize> {
        let start = skip_blanks(bytes, 0);
        match *bytes.get(start)? {
            b'\n' | b'\r' => {
                sink.take(None);
                Some(start)
            }
            b';' => {
                let (len, made) = self.comment_line(bytes, start, line)?;
                sink.take(made);
                Some(len)
            }
            _ => self.plain_line(bytes, start, line, sink),
        }
    }

    /// A comment-only line (its `;` at `semicolon`) as the general path reads it when nothing is
    /// queued: no command, or the one its slicer metadata gives. `None` when the comment is not
    /// UTF-8 (the general path warns) and when its end is not in `bytes`.
    fn comment_line(&mut self, bytes: &[u8], semicolon: usize, line: u64) -> Option<(usize, Made)> {
        let first = skip_blanks(bytes, semicolon + 1);
        let may_hold_meta = may_start_meta(*bytes.get(first)?);
        let end = semicolon + memchr::memchr2(b'\n', b'\r', &bytes[semicolon..])?;
        let text = &bytes[semicolon + 1..end];
        if !may_hold_meta {
            return (text.is_ascii() || std::str::from_utf8(text).is_ok()).then_some((end, None));
        }
        let text = std::str::from_utf8(text).ok()?;
        let made = self.comment_line_meta(text, span_of(line, semicolon, end))?;
        Some((end, made))
    }

    /// [`Self::comments`] for the one comment of a comment-only line; `None` (nothing changed)
    /// where that would flush a pending layer start, which the general path does.
    #[inline(never)]
    fn comment_line_meta(&mut self, text: &str, span: Span) -> Option<Made> {
        if !self.queue.is_empty() {
            return None;
        }
        match comment_meta(text) {
            None => Some(None),
            Some(CommentMeta::Meta(meta)) => {
                if self.pending_layer.is_some() {
                    return None;
                }
                let value = Command::Meta(meta);
                Some(Some(Spanned { span, value }))
            }
            Some(CommentMeta::LayerStart) => {
                if self.pending_layer.is_some() {
                    return None;
                }
                self.pending_layer = Some(span);
                Some(None)
            }
            Some(CommentMeta::LayerZ(z)) => Some(
                self.pending_layer
                    .take()
                    .map(|span| layer_change(span, Some(z))),
            ),
        }
    }

    /// A plain `G0`/`G1`/`G2`/`G3`/`G92` (its command word at `start`): blank-separated X Y Z E F
    /// words (arcs also I J; G92 no F), each once, each with a number, and nothing else. Any
    /// other line, a line whose end is not in `bytes`, and a command that would fail or warn, give
    /// `None` and go through the lexer and [`Self::interpret`], which give the same command for the
    /// lines this takes (checked by the `fast_path_*` tests). Gives the line's length and hands
    /// its command to `sink`.
    #[inline(always)]
    fn plain_line(
        &mut self,
        bytes: &[u8],
        start: usize,
        line: u64,
        sink: &mut impl FastSink,
    ) -> Option<usize> {
        if self.pending_layer.is_some() || !self.queue.is_empty() {
            return None;
        }
        let rapid = match bytes.get(start..start + 2)? {
            [b'G' | b'g', b'0'] => true,
            [b'G' | b'g', b'1'] => false,
            [b'G' | b'g', b'2'] if self.commands.arcs => {
                return self.plain_arc_line(bytes, start, line, true, sink);
            }
            [b'G' | b'g', b'3'] if self.commands.arcs => {
                return self.plain_arc_line(bytes, start, line, false, sink);
            }
            [b'G' | b'g', b'9'] if bytes.get(start + 2) == Some(&b'2') => {
                return hand_over(self.plain_set_position_line(bytes, start, line), sink);
            }
            _ => return None,
        };
        let command_end = start + 2;
        let (words, params_end, line_len) = plain_move_words::<LINEAR_SLOTS>(bytes, command_end)?;
        let value = self.plain_linear_move(&words, rapid)?;
        sink.take_move(span_of(line, start, command_end.max(params_end)), value);
        Some(line_len)
    }

    /// [`Self::plain_line`] for `G2`/`G3`, kept out of line: arcs are rarer, and the
    /// straight moves' loop stays as tight as without them.
    #[inline(never)]
    fn plain_arc_line(
        &mut self,
        bytes: &[u8],
        start: usize,
        line: u64,
        clockwise: bool,
        sink: &mut impl FastSink,
    ) -> Option<usize> {
        let command_end = start + 2;
        let (words, params_end, line_len) = plain_move_words::<ARC_SLOTS>(bytes, command_end)?;
        let (value, radius) = self.plain_arc(&words, clockwise)?;
        sink.take_arc(
            span_of(line, start, command_end.max(params_end)),
            value,
            radius,
        );
        Some(line_len)
    }

    /// [`Self::plain_line`] for `G92` with X Y Z E words (slicers reset E this way).
    #[inline(never)]
    fn plain_set_position_line(
        &mut self,
        bytes: &[u8],
        start: usize,
        line: u64,
    ) -> Option<(usize, Spanned<Command>)> {
        let command_end = start + 3;
        let (words, params_end, line_len) = plain_move_words::<POSITION_SLOTS>(bytes, command_end)?;
        let values = [0, 1, 2, 3].map(|axis| words.get(axis).map(|v| v * self.unit));
        let value = self.apply_set_position(values).ok()?;
        let span = span_of(line, start, command_end.max(params_end));
        Some((line_len, Spanned { span, value }))
    }

    /// [`Self::linear_move`] for the words of a plain line; `None` where that would fail.
    #[inline(always)]
    fn plain_linear_move(&mut self, words: &MoveWords, rapid: bool) -> Option<Move> {
        let (target, named) = self.plain_target(words)?;
        let speed = self.plain_speed(words)?;
        Some(self.move_to(target, named, speed, rapid))
    }

    /// [`Self::arc`] for the words of a plain line with I or J, and the arc's radius; `None` where
    /// that would fail.
    fn plain_arc(&mut self, words: &MoveWords, clockwise: bool) -> Option<(ArcMove, f64)> {
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
        if offset == [0.0; 2] {
            return None;
        }
        let (centre, radius) = checked_centre(&self.last, &target, offset).ok()?;
        let e_written = words.get(E_SLOT).map(|v| v * self.unit);
        let arc = self.commit_arc(ArcEnds {
            target,
            centre,
            offset,
            clockwise,
            turns: 0,
            speed,
            e_written,
        });
        Some((arc, radius))
    }

    /// [`Self::target`] for the words of a plain line (not committed); `None` where that would
    /// fail.
    #[inline(always)]
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
}

/// Hands a rarer line's command (if the line was taken) to `sink`; the line's length.
fn hand_over(taken: Option<(usize, Spanned<Command>)>, sink: &mut impl FastSink) -> Option<usize> {
    let (len, command) = taken?;
    sink.take(Some(command));
    Some(len)
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
#[inline(always)]
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
