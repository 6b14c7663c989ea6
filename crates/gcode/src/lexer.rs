//! Zero-copy lexer for one line of G-code: `N` line number, command word, parameter words (values parsed
//! exactly), raw-text parameters (`M117 Hello`), Klipper extended commands (`SET_VELOCITY_LIMIT ACCEL=3000`),
//! `;` and `( )` comments and `*` checksums. Tokens are stored as byte ranges in reusable vectors, so a
//! line costs no allocation once the vectors have grown.
//!
//! Grammar decisions (documented because G-code dialects differ):
//! - Letters are case-insensitive (`x10` is `X10`); words may be packed (`X1Y2E.5`).
//! - A letter directly followed by a space, end of line, `;`, `(` or `*` is a flag word (`G28 X Y`).
//! - Exponents are not G-code: a lower-case `e` right after a number's digits (`X1e5`) is an error; an
//!   upper-case `E` there starts the next word (`X1E5` = `X1 E5`, as firmware reads packed words).
//! - `( )` comments are recognised in classic lines, not in extended commands (Klipper has none).
//! - `*` starts a checksum in classic lines; in extended commands only when the line has an `N` number.
//! - Raw-text commands (everything after the command word up to `;` is one text): M23 M28 M30 M32 M33
//!   M115 M117 M118 M486 M550 M862 (Prusa's checks with quoted strings and versions).

use std::ops::Range;

use crate::command::Span;
use crate::error::ErrorKind;
use crate::number::{NumberError, parse_number};

/// A classic parameter word (`X94.838`, or the flag `X` in `G28 X`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Upper-case ASCII letter.
    pub letter: u8,
    /// `None` for a flag word without a value.
    pub value: Option<f64>,
    pub span: Span,
}

/// The command word of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandWord {
    /// `G1`, `M862.6`, `T0`: upper-case letter, number before and after the `.`.
    Code {
        letter: u8,
        major: u32,
        minor: Option<u32>,
    },
    /// A Klipper extended command (`SET_VELOCITY_LIMIT`); the name is [`Line::command_text`].
    Extended,
}

/// `KEY=VALUE` of an extended command, borrowed from the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExtParam<'a> {
    /// As written (compare with `eq_ignore_ascii_case`).
    pub key: &'a str,
    /// Without surrounding quotes.
    pub value: &'a str,
    /// The value was written in `"…"` or `'…'`.
    pub quoted: bool,
    pub span: Span,
}

/// A comment, borrowed from the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Comment<'a> {
    /// Text after `;`, or between `(` and `)`, as written.
    pub text: &'a str,
    /// `( )` rather than `;`.
    pub parenthesised: bool,
    pub span: Span,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct ExtRaw {
    key: (u32, u32),
    value: (u32, u32),
    quoted: bool,
    span_start: u32,
    span_end: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CommentRaw {
    text: (u32, u32),
    parenthesised: bool,
    span_start: u32,
    span_end: u32,
}

/// Reusable storage for the tokens of one line.
#[derive(Debug, Default, Clone)]
pub struct LineTokens {
    line: u64,
    line_number: Option<(u64, Span)>,
    checksum: Option<(u8, Span)>,
    command: Option<(CommandWord, Range<usize>)>,
    /// End of the last parameter (for the command's span).
    params_end: usize,
    words: Vec<Word>,
    ext: Vec<ExtRaw>,
    raw_text: Option<Range<usize>>,
    comments: Vec<CommentRaw>,
}

impl LineTokens {
    fn clear(&mut self, line: u64) {
        self.line = line;
        self.line_number = None;
        self.checksum = None;
        self.command = None;
        self.params_end = 0;
        self.words.clear();
        self.ext.clear();
        self.raw_text = None;
        self.comments.clear();
    }
}

/// One lexed line: the text and its tokens.
///
/// The text is kept as bytes that are known to be UTF-8 (checked by the reader in large blocks, not
/// line by line); the `&str` views are made only when asked for.
#[derive(Debug, Clone, Copy)]
pub struct Line<'a> {
    text: &'a [u8],
    tokens: &'a LineTokens,
}

/// A `&str` view of bytes known to be UTF-8: a whole line, or a token range of one (token ranges
/// begin and end at ASCII bytes or at the line's ends, so they are UTF-8 too). Never fails in practice;
/// an empty text rather than a panic if that invariant were ever broken.
pub(crate) fn utf8(bytes: &[u8]) -> &str {
    debug_assert!(std::str::from_utf8(bytes).is_ok());
    std::str::from_utf8(bytes).unwrap_or_default()
}

impl<'a> Line<'a> {
    #[cfg(test)]
    pub(crate) fn new(text: &'a str, tokens: &'a LineTokens) -> Self {
        Line {
            text: text.as_bytes(),
            tokens,
        }
    }

    /// A line over bytes the caller has checked to be UTF-8.
    pub(crate) fn from_utf8_bytes(text: &'a [u8], tokens: &'a LineTokens) -> Self {
        Line { text, tokens }
    }

    /// 1-based line number in the input.
    pub fn number(&self) -> u64 {
        self.tokens.line
    }

    /// The whole line without its terminator.
    pub fn text(&self) -> &'a str {
        utf8(self.text)
    }

    /// The `N` line number word, if any.
    pub fn line_number(&self) -> Option<(u64, Span)> {
        self.tokens.line_number
    }

    /// The verified `*` checksum, if any.
    pub fn checksum(&self) -> Option<(u8, Span)> {
        self.tokens.checksum
    }

    /// The command word, or `None` for blank and comment-only lines.
    pub fn command(&self) -> Option<CommandWord> {
        self.tokens.command.as_ref().map(|(word, _)| *word)
    }

    /// The command word as written (`G1`, `g1`, `M862.6`, `set_velocity_limit`).
    pub fn command_text(&self) -> Option<&'a str> {
        self.tokens
            .command
            .as_ref()
            .map(|(_, range)| utf8(&self.text[range.clone()]))
    }

    /// Span of the command word.
    pub fn command_span(&self) -> Option<Span> {
        self.tokens
            .command
            .as_ref()
            .map(|(_, range)| self.span(range.start, range.end))
    }

    /// Span from the command word to the end of the last parameter (the whole line when none).
    pub fn command_extent(&self) -> Span {
        let Some((_, range)) = &self.tokens.command else {
            return self.span(0, self.text.len());
        };
        self.span(range.start, range.end.max(self.tokens.params_end))
    }

    /// Classic parameter words in order.
    pub fn words(&self) -> &'a [Word] {
        &self.tokens.words
    }

    /// The last word with this (upper-case) letter.
    pub fn word(&self, letter: u8) -> Option<&'a Word> {
        self.tokens.words.iter().rev().find(|w| w.letter == letter)
    }

    /// Parameters of an extended command in order.
    pub fn ext_params(&self) -> impl Iterator<Item = ExtParam<'a>> + 'a {
        let text = self.text;
        let line = self.tokens.line;
        self.tokens.ext.iter().map(move |raw| ExtParam {
            key: utf8(&text[raw.key.0 as usize..raw.key.1 as usize]),
            value: utf8(&text[raw.value.0 as usize..raw.value.1 as usize]),
            quoted: raw.quoted,
            span: span_of(line, raw.span_start as usize, raw.span_end as usize),
        })
    }

    /// The last extended parameter with this key (case-insensitive).
    pub fn ext_param(&self, key: &str) -> Option<ExtParam<'a>> {
        self.ext_params()
            .filter(|p| p.key.eq_ignore_ascii_case(key))
            .last()
    }

    /// The text parameter of a raw-text command (`M117 Hello world` → `Hello world`).
    pub fn raw_text(&self) -> Option<&'a str> {
        self.tokens
            .raw_text
            .as_ref()
            .map(|r| utf8(&self.text[r.clone()]))
    }

    /// Comments in order.
    pub fn comments(&self) -> impl Iterator<Item = Comment<'a>> + 'a {
        let text = self.text;
        let line = self.tokens.line;
        self.tokens.comments.iter().map(move |raw| Comment {
            text: utf8(&text[raw.text.0 as usize..raw.text.1 as usize]),
            parenthesised: raw.parenthesised,
            span: span_of(line, raw.span_start as usize, raw.span_end as usize),
        })
    }

    /// True when the line has comments.
    pub fn has_comments(&self) -> bool {
        !self.tokens.comments.is_empty()
    }

    fn span(&self, start: usize, end: usize) -> Span {
        span_of(self.tokens.line, start, end)
    }
}

/// Span of the byte range `start..end` on `line`.
pub(crate) fn span_of(line: u64, start: usize, end: usize) -> Span {
    Span {
        line,
        column: to_u32(start + 1),
        len: to_u32(end.saturating_sub(start)),
    }
}

/// Lines are bounded by the reader's limit (far below 4 GiB); saturate rather than wrap.
fn to_u32(value: usize) -> u32 {
    u32::try_from(value).unwrap_or(u32::MAX)
}

/// A lexing failure: what, and where (byte range in the line).
#[derive(Debug, Clone, PartialEq)]
pub struct LexError {
    pub kind: ErrorKind,
    pub start: usize,
    pub end: usize,
}

impl LexError {
    fn new(kind: ErrorKind, start: usize, end: usize) -> Self {
        LexError { kind, start, end }
    }
}

/// Most words (and, separately, extended parameters and comments) one line may hold. Real lines have a
/// dozen; the bound keeps a 32 MiB line of `X1X1…` from taking gigabytes of token storage.
pub const MAX_TOKENS_PER_LINE: usize = 1024;

/// An error when a token vector already holds [`MAX_TOKENS_PER_LINE`] entries.
fn check_room(len: usize, start: usize, end: usize) -> Result<(), LexError> {
    if len >= MAX_TOKENS_PER_LINE {
        return Err(LexError::new(
            ErrorKind::TooManyTokens {
                limit: MAX_TOKENS_PER_LINE,
            },
            start,
            end,
        ));
    }
    Ok(())
}

/// Lexes `text` (line `line`) into `tokens`.
pub fn lex_line(text: &str, line: u64, tokens: &mut LineTokens) -> Result<(), LexError> {
    lex_utf8_bytes(text.as_bytes(), line, tokens)
}

/// [`lex_line`] on bytes known to be UTF-8 (the reader checks them in blocks).
pub(crate) fn lex_utf8_bytes(
    bytes: &[u8],
    line: u64,
    tokens: &mut LineTokens,
) -> Result<(), LexError> {
    tokens.clear(line);
    let mut lexer = Lexer {
        bytes,
        pos: 0,
        tokens,
    };
    lexer.run()
}

struct Lexer<'b, 't> {
    bytes: &'b [u8],
    pos: usize,
    tokens: &'t mut LineTokens,
}

#[inline]
fn is_blank(b: u8) -> bool {
    b == b' ' || b == b'\t'
}

/// Bytes that may end a classic word.
#[inline]
fn ends_word(b: Option<u8>) -> bool {
    match b {
        None => true,
        Some(b) => is_blank(b) || b == b';' || b == b'(' || b == b'*',
    }
}

/// Raw-text M commands.
fn takes_raw_text(letter: u8, major: u32) -> bool {
    letter == b'M'
        && matches!(
            major,
            23 | 28 | 30 | 32 | 33 | 115 | 117 | 118 | 486 | 550 | 862
        )
}

/// End of a bad word starting before `from`: up to the next blank or comment.
fn word_end(bytes: &[u8], from: usize) -> usize {
    let mut end = from.min(bytes.len());
    while end < bytes.len() && !ends_word(Some(bytes[end])) {
        end += 1;
    }
    end
}

/// The number of the word whose letter is at `word_start`; returns it and the index after it.
#[inline]
fn word_value(bytes: &[u8], word_start: usize) -> Result<(f64, usize), LexError> {
    match parse_number(bytes, word_start + 1) {
        Ok((value, end)) => match bytes.get(end).copied() {
            Some(b'e') => Err(LexError::new(
                ErrorKind::ExponentNotAllowed,
                word_start,
                word_end(bytes, end),
            )),
            Some(b) if !ends_word(Some(b)) && !b.is_ascii_alphabetic() => Err(LexError::new(
                ErrorKind::InvalidNumber,
                word_start,
                word_end(bytes, end),
            )),
            _ => Ok((value, end)),
        },
        Err(NumberError::Invalid) => Err(LexError::new(
            ErrorKind::InvalidNumber,
            word_start,
            word_end(bytes, word_start + 1),
        )),
        Err(NumberError::Overflow) => Err(LexError::new(
            ErrorKind::NumberOverflow,
            word_start,
            word_end(bytes, word_start + 1),
        )),
    }
}

impl Lexer<'_, '_> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn peek_at(&self, offset: usize) -> Option<u8> {
        self.bytes.get(self.pos + offset).copied()
    }

    fn skip_blanks(&mut self) {
        while self.peek().is_some_and(is_blank) {
            self.pos += 1;
        }
    }

    fn run(&mut self) -> Result<(), LexError> {
        self.skip_blanks();
        self.line_number()?;
        self.rest_of_line(true)
    }

    /// The rest of the line: blanks and comments, and, where `code` may still come, a command
    /// or a checksum.
    #[inline(always)]
    fn rest_of_line(&mut self, code: bool) -> Result<(), LexError> {
        loop {
            self.skip_blanks();
            match self.peek() {
                None => return Ok(()),
                Some(b';') => return self.semicolon_comment(),
                Some(b'(') => self.paren_comment()?,
                Some(b'*') if code => return self.checksum(),
                Some(b) if code && (b.is_ascii_alphabetic() || b == b'_') => return self.command(),
                Some(_) => return Err(self.unexpected_char()),
            }
        }
    }

    fn unexpected_char(&self) -> LexError {
        let rest = &self.bytes[self.pos..];
        let text = std::str::from_utf8(rest).unwrap_or("");
        let c = text.chars().next().unwrap_or('\u{fffd}');
        LexError::new(
            ErrorKind::UnexpectedCharacter(c),
            self.pos,
            self.pos + c.len_utf8().max(1),
        )
    }

    /// `N123` at the start of the line.
    fn line_number(&mut self) -> Result<(), LexError> {
        let is_n = matches!(self.peek(), Some(b'N' | b'n'));
        if !is_n || !self.peek_at(1).is_some_and(|b| b.is_ascii_digit()) {
            return Ok(());
        }
        let start = self.pos;
        self.pos += 1;
        let mut value: u64 = 0;
        while let Some(b) = self.peek().filter(u8::is_ascii_digit) {
            value = value
                .checked_mul(10)
                .and_then(|v| v.checked_add(u64::from(b - b'0')))
                .ok_or_else(|| LexError::new(ErrorKind::NumberOverflow, start, self.pos + 1))?;
            self.pos += 1;
        }
        if !ends_word(self.peek()) && !self.peek().is_some_and(|b| b.is_ascii_alphabetic()) {
            return Err(LexError::new(ErrorKind::InvalidNumber, start, self.pos + 1));
        }
        self.tokens.line_number = Some((value, span_of(self.tokens.line, start, self.pos)));
        Ok(())
    }

    fn command(&mut self) -> Result<(), LexError> {
        let start = self.pos;
        let first = self.bytes[start];
        let second = self.peek_at(1);
        if first != b'_' && second.is_some_and(|b| b.is_ascii_digit()) {
            let letter = first.to_ascii_uppercase();
            self.pos += 1;
            let major = self.code_number(start)?;
            let minor = if self.peek() == Some(b'.') {
                self.pos += 1;
                Some(self.code_number(start)?)
            } else {
                None
            };
            self.tokens.command = Some((
                CommandWord::Code {
                    letter,
                    major,
                    minor,
                },
                start..self.pos,
            ));
            if takes_raw_text(letter, major) {
                return self.raw_text();
            }
            return self.classic_params();
        }
        let is_name_byte = |b: &u8| b.is_ascii_alphanumeric() || *b == b'_';
        if first == b'_' || second.is_some_and(|b| b.is_ascii_alphabetic() || b == b'_') {
            while self.peek().as_ref().is_some_and(is_name_byte) {
                self.pos += 1;
            }
            if !matches!(self.peek(), None | Some(b' ' | b'\t' | b';')) {
                return Err(self.unexpected_char());
            }
            self.tokens.command = Some((CommandWord::Extended, start..self.pos));
            return self.extended_params();
        }
        Err(LexError::new(
            ErrorKind::InvalidNumber,
            start,
            self.word_end(start + 1),
        ))
    }

    /// Digits of a command number (`1` in `G1`).
    fn code_number(&mut self, word_start: usize) -> Result<u32, LexError> {
        let digits_start = self.pos;
        let mut value: u32 = 0;
        while let Some(b) = self.peek().filter(u8::is_ascii_digit) {
            value = value
                .checked_mul(10)
                .and_then(|v| v.checked_add(u32::from(b - b'0')))
                .ok_or_else(|| {
                    LexError::new(
                        ErrorKind::NumberOverflow,
                        word_start,
                        self.word_end(self.pos),
                    )
                })?;
            self.pos += 1;
        }
        if self.pos == digits_start {
            return Err(LexError::new(
                ErrorKind::InvalidNumber,
                word_start,
                self.word_end(self.pos),
            ));
        }
        Ok(value)
    }

    /// End of a bad word, for the error span: up to the next blank or comment.
    fn word_end(&self, from: usize) -> usize {
        word_end(self.bytes, from)
    }

    /// Classic words: the hot loop of the lexer, on local copies of the position (faster than
    /// going through `self` for every byte).
    fn classic_params(&mut self) -> Result<(), LexError> {
        let bytes = self.bytes;
        let line = self.tokens.line;
        let mut pos = self.pos;
        loop {
            while let Some(b' ' | b'\t') = bytes.get(pos) {
                pos += 1;
            }
            let Some(&b) = bytes.get(pos) else {
                self.pos = pos;
                return Ok(());
            };
            if !b.is_ascii_alphabetic() {
                self.pos = pos;
                match b {
                    b';' => return self.semicolon_comment(),
                    b'(' => {
                        self.paren_comment()?;
                        pos = self.pos;
                        continue;
                    }
                    b'*' => return self.checksum(),
                    _ => return Err(self.unexpected_char()),
                }
            }
            let start = pos;
            let value = match bytes.get(pos + 1).copied() {
                Some(b'0'..=b'9' | b'.' | b'-' | b'+') => {
                    let (value, end) = word_value(bytes, start)?;
                    pos = end;
                    Some(value)
                }
                next if ends_word(next) => {
                    pos += 1;
                    None
                }
                _ => {
                    let end = word_end(bytes, start + 1);
                    return Err(LexError::new(ErrorKind::InvalidNumber, start, end));
                }
            };
            let letter = b.to_ascii_uppercase();
            check_room(self.tokens.words.len(), start, pos)?;
            self.tokens.words.push(Word {
                letter,
                value,
                span: span_of(line, start, pos),
            });
            self.tokens.params_end = pos;
        }
    }

    /// Everything after the command word up to `;` (and before a trailing `*checksum`) is one text.
    fn raw_text(&mut self) -> Result<(), LexError> {
        self.skip_blanks();
        let start = self.pos;
        let semicolon =
            memchr::memchr(b';', &self.bytes[start..]).map_or(self.bytes.len(), |i| start + i);
        let mut end = semicolon;
        if let Some(star) = memchr::memrchr(b'*', &self.bytes[start..end]).map(|i| start + i) {
            let after = &self.bytes[star + 1..end];
            let digits = after.iter().take_while(|b| b.is_ascii_digit()).count();
            if digits > 0 && after[digits..].iter().all(|&b| is_blank(b)) {
                end = star;
                self.pos = star;
                self.checksum_at(star)?;
            }
        }
        while end > start && is_blank(self.bytes[end - 1]) {
            end -= 1;
        }
        self.tokens.raw_text = Some(start..end);
        self.tokens.params_end = end;
        self.pos = semicolon;
        if semicolon < self.bytes.len() {
            self.semicolon_comment()?;
        }
        Ok(())
    }

    fn extended_params(&mut self) -> Result<(), LexError> {
        loop {
            self.skip_blanks();
            match self.peek() {
                None => return Ok(()),
                Some(b';') => return self.semicolon_comment(),
                Some(b'*') if self.tokens.line_number.is_some() => return self.checksum(),
                Some(_) => self.ext_param()?,
            }
        }
    }

    fn ext_param(&mut self) -> Result<(), LexError> {
        let start = self.pos;
        while self
            .peek()
            .is_some_and(|b| b != b'=' && !is_blank(b) && b != b';')
        {
            self.pos += 1;
        }
        if self.peek() != Some(b'=') || self.pos == start {
            return Err(LexError::new(
                ErrorKind::MalformedParameter,
                start,
                self.pos.max(start + 1),
            ));
        }
        let key = (start, self.pos);
        self.pos += 1;
        // Quoted values as Klipper reads them (shell-style): "…" or '…'.
        let (value, quoted) = if let Some(quote @ (b'"' | b'\'')) = self.peek() {
            let open = self.pos;
            let close = memchr::memchr(quote, &self.bytes[open + 1..])
                .map(|i| open + 1 + i)
                .ok_or_else(|| {
                    LexError::new(ErrorKind::UnterminatedString, open, self.bytes.len())
                })?;
            self.pos = close + 1;
            ((open + 1, close), true)
        } else {
            let value_start = self.pos;
            while self.peek().is_some_and(|b| !is_blank(b) && b != b';') {
                self.pos += 1;
            }
            ((value_start, self.pos), false)
        };
        check_room(self.tokens.ext.len(), start, self.pos)?;
        self.tokens.ext.push(ExtRaw {
            key: (to_u32(key.0), to_u32(key.1)),
            value: (to_u32(value.0), to_u32(value.1)),
            quoted,
            span_start: to_u32(start),
            span_end: to_u32(self.pos),
        });
        self.tokens.params_end = self.pos;
        Ok(())
    }

    fn semicolon_comment(&mut self) -> Result<(), LexError> {
        let start = self.pos;
        let end = self.bytes.len();
        check_room(self.tokens.comments.len(), start, end)?;
        self.tokens.comments.push(CommentRaw {
            text: (to_u32(start + 1), to_u32(end)),
            parenthesised: false,
            span_start: to_u32(start),
            span_end: to_u32(end),
        });
        self.pos = end;
        Ok(())
    }

    fn paren_comment(&mut self) -> Result<(), LexError> {
        let start = self.pos;
        let close = memchr::memchr(b')', &self.bytes[start + 1..])
            .map(|i| start + 1 + i)
            .ok_or_else(|| LexError::new(ErrorKind::UnterminatedComment, start, start + 1))?;
        check_room(self.tokens.comments.len(), start, close + 1)?;
        self.tokens.comments.push(CommentRaw {
            text: (to_u32(start + 1), to_u32(close)),
            parenthesised: true,
            span_start: to_u32(start),
            span_end: to_u32(close + 1),
        });
        self.pos = close + 1;
        Ok(())
    }

    /// `*nn` after the words: must be the XOR of all bytes before `*`; only blanks and comments may follow.
    fn checksum(&mut self) -> Result<(), LexError> {
        let star = self.pos;
        self.checksum_at(star)?;
        self.rest_of_line(false)
    }

    fn checksum_at(&mut self, star: usize) -> Result<(), LexError> {
        let mut pos = star + 1;
        let mut written: u32 = 0;
        while let Some(b) = self.bytes.get(pos).copied().filter(u8::is_ascii_digit) {
            written = written
                .saturating_mul(10)
                .saturating_add(u32::from(b - b'0'));
            pos += 1;
        }
        if pos == star + 1 || !ends_word(self.bytes.get(pos).copied()) {
            return Err(LexError::new(
                ErrorKind::MalformedChecksum,
                star,
                pos.max(star + 1),
            ));
        }
        let computed = self.bytes[..star].iter().fold(0u8, |acc, b| acc ^ b);
        if written != u32::from(computed) {
            return Err(LexError::new(
                ErrorKind::ChecksumMismatch { written, computed },
                star,
                pos,
            ));
        }
        self.tokens.checksum = Some((computed, span_of(self.tokens.line, star, pos)));
        self.pos = pos;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lex(text: &str) -> LineTokens {
        let mut tokens = LineTokens::default();
        lex_line(text, 1, &mut tokens).expect(text);
        tokens
    }

    fn lex_err(text: &str) -> LexError {
        let mut tokens = LineTokens::default();
        lex_line(text, 1, &mut tokens).expect_err(text)
    }

    fn values(text: &str) -> Vec<(char, Option<f64>)> {
        let tokens = lex(text);
        let line = Line::new(text, &tokens);
        line.words()
            .iter()
            .map(|w| (w.letter as char, w.value))
            .collect()
    }

    #[test]
    fn packed_and_lower_case_words() {
        assert_eq!(
            values("G1X94.838Y81.705"),
            vec![('X', Some(94.838)), ('Y', Some(81.705))]
        );
        assert_eq!(
            values("g1 x10 Z.2 E-.54 F+5"),
            vec![
                ('X', Some(10.0)),
                ('Z', Some(0.2)),
                ('E', Some(-0.54)),
                ('F', Some(5.0))
            ]
        );
        assert_eq!(values("G1 X1E5"), vec![('X', Some(1.0)), ('E', Some(5.0))]);
    }

    #[test]
    fn flag_words() {
        assert_eq!(values("G28 X Y"), vec![('X', None), ('Y', None)]);
        assert_eq!(values("M84 E;off"), vec![('E', None)]);
    }

    #[test]
    fn command_words() {
        let tokens = lex("M862.6 P\"Input shaper\"");
        let line = Line::new("M862.6 P\"Input shaper\"", &tokens);
        assert_eq!(
            line.command(),
            Some(CommandWord::Code {
                letter: b'M',
                major: 862,
                minor: Some(6)
            })
        );
        assert_eq!(line.raw_text(), Some("P\"Input shaper\""));
    }

    #[test]
    fn raw_text_ends_at_semicolon() {
        let text = "M117 Hello (world) X1.2.3 ; shown";
        let tokens = lex(text);
        let line = Line::new(text, &tokens);
        assert_eq!(line.raw_text(), Some("Hello (world) X1.2.3"));
        assert_eq!(line.comments().next().map(|c| c.text), Some(" shown"));
    }

    #[test]
    fn extended_commands() {
        let text =
            "EXCLUDE_OBJECT_DEFINE NAME=a POLYGON=[[1,2],[3,4]] MSG=\"two words\" V='200' ; c";
        let tokens = lex(text);
        let line = Line::new(text, &tokens);
        assert_eq!(line.command(), Some(CommandWord::Extended));
        assert_eq!(line.command_text(), Some("EXCLUDE_OBJECT_DEFINE"));
        let params: Vec<_> = line
            .ext_params()
            .map(|p| (p.key, p.value, p.quoted))
            .collect();
        assert_eq!(
            params,
            vec![
                ("NAME", "a", false),
                ("POLYGON", "[[1,2],[3,4]]", false),
                ("MSG", "two words", true),
                ("V", "200", true)
            ]
        );
        assert_eq!(line.ext_param("polygon").map(|p| p.span.column), Some(30));
    }

    #[test]
    fn comments_are_kept() {
        let text = "G1 (move) X1 ; TYPE:Perimeter";
        let tokens = lex(text);
        let line = Line::new(text, &tokens);
        let comments: Vec<_> = line.comments().map(|c| (c.text, c.parenthesised)).collect();
        assert_eq!(comments, vec![("move", true), (" TYPE:Perimeter", false)]);
    }

    #[test]
    fn checksums_are_verified() {
        let body = "N3 G1 X10";
        let sum = body.bytes().fold(0u8, |a, b| a ^ b);
        let good = format!("{body}*{sum}");
        let tokens = lex(&good);
        assert_eq!(tokens.line_number.map(|n| n.0), Some(3));
        assert_eq!(tokens.checksum.map(|c| c.0), Some(sum));
        let bad = format!("{body}*{}", sum ^ 1);
        assert!(matches!(
            lex_err(&bad).kind,
            ErrorKind::ChecksumMismatch { .. }
        ));
    }

    #[test]
    fn a_line_holds_at_most_the_token_limit() {
        let full = format!("G1{}", " X1".repeat(MAX_TOKENS_PER_LINE));
        assert_eq!(lex(&full).words.len(), MAX_TOKENS_PER_LINE);
        let over = format!("{full} Y2");
        let err = lex_err(&over);
        assert_eq!(
            err.kind,
            ErrorKind::TooManyTokens {
                limit: MAX_TOKENS_PER_LINE
            }
        );
        // The error points at the first word past the limit.
        assert_eq!(&over[err.start..err.end], "Y2");
        let comments = format!("G1 X1{}", "(c)".repeat(MAX_TOKENS_PER_LINE + 1));
        assert!(matches!(
            lex_err(&comments).kind,
            ErrorKind::TooManyTokens { .. }
        ));
        let ext = format!("SET_X{}", " A=1".repeat(MAX_TOKENS_PER_LINE + 1));
        assert!(matches!(
            lex_err(&ext).kind,
            ErrorKind::TooManyTokens { .. }
        ));
    }

    #[test]
    fn bad_numbers_have_the_word_span() {
        let err = lex_err("G1 X1.2.3 Y1");
        assert_eq!(
            (err.kind, err.start, err.end),
            (ErrorKind::InvalidNumber, 3, 9)
        );
        assert_eq!(lex_err("G1 X- Y1").kind, ErrorKind::InvalidNumber);
        assert_eq!(lex_err("G1 X.").kind, ErrorKind::InvalidNumber);
        assert_eq!(lex_err("G1 Xabc").kind, ErrorKind::InvalidNumber);
        assert_eq!(lex_err("G1 Xnan").kind, ErrorKind::InvalidNumber);
        assert_eq!(lex_err("G1 X1e5").kind, ErrorKind::ExponentNotAllowed);
        assert_eq!(lex_err("G1 X#1").kind, ErrorKind::InvalidNumber);
    }

    #[test]
    fn command_extent_covers_parameters() {
        let text = "  G1 X1 Y2 ; c";
        let tokens = lex(text);
        let line = Line::new(text, &tokens);
        assert_eq!(
            line.command_extent(),
            Span {
                line: 1,
                column: 3,
                len: 8
            }
        );
    }
}
