//! Streaming line reader: pulls lines from any `BufRead` into one reused buffer (`\n`, `\r\n` and `\r`
//! line ends), checks UTF-8 and lexes each line. Lines inside the input's buffer are lexed in place,
//! and their UTF-8 is checked in blocks of many lines (one long check costs far less than one per
//! line). Memory is bounded by the longest line, never by the file size; lines longer than
//! `ReaderOptions::max_line_len` are an error (and are skipped whole).
//!
//! Non-UTF-8 bytes: an error with line and column, except inside a `;` comment, where they are replaced
//! by U+FFFD and reported as a [`WarningKind::LossyComment`] warning (old slicers write Latin-1 names).

use std::io::{self, BufRead};
use std::sync::Arc;

use crate::command::Span;
use crate::error::{ErrorKind, GcodeError, Warning, WarningKind, Warnings};
use crate::lexer::{Line, LineTokens, lex_utf8_bytes, span_of, utf8};

/// The input's buffered bytes (`fill_buf`, retried while interrupted); another read error goes to
/// `$failed`, which must leave the function. A macro, not a function: a function returning the
/// bytes from its retry loop would keep the input borrowed on the retrying path too (the borrow
/// checker's "NLL problem case 3"), and one taking a closure made the fast path's per-line
/// hand-over a few instructions longer.
macro_rules! filled {
    ($input:expr, $err:ident => $failed:expr) => {
        loop {
            match $input.fill_buf() {
                Ok(bytes) => break bytes,
                Err(err) if err.kind() == io::ErrorKind::Interrupted => continue,
                Err($err) => $failed,
            }
        }
    };
}

/// Reader settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReaderOptions {
    /// Longest accepted line in bytes (default 32 MiB: base64 thumbnails fit, memory stays bounded).
    pub max_line_len: usize,
}

impl Default for ReaderOptions {
    fn default() -> Self {
        ReaderOptions {
            max_line_len: 32 << 20,
        }
    }
}

/// Reads and lexes lines one at a time (a lending iterator: each [`Line`] borrows the reader).
#[derive(Debug)]
pub struct Reader<R> {
    input: R,
    source: Arc<str>,
    options: ReaderOptions,
    /// `max_line_len + 1`: the most bytes [`Self::take_line_with`] offers.
    offer_len: usize,
    buf: Vec<u8>,
    lossy: String,
    tokens: LineTokens,
    line: u64,
    /// The previous line ended in `\r`: a `\n` right after it belongs to the same line end.
    skip_lf: bool,
    bytes_consumed: u64,
    /// Bytes of the line handed out last, consumed at the next call.
    deferred_consume: usize,
    /// The input's buffer is known to be UTF-8 from the current line's start up to here.
    utf8_checked: usize,
    /// An I/O error met by [`Self::take_line_with`], reported by the next [`Self::next_line`].
    pending_io_error: Option<io::Error>,
    warnings: Warnings,
    failed_io: bool,
    /// Nothing read yet: a UTF-8 byte-order mark there is skipped.
    at_start: bool,
}

/// Where the next line is.
enum Located {
    Eof,
    /// Entirely inside the input's buffer, at `start..end`; `consume` bytes include its line end.
    InBuffer {
        start: usize,
        end: usize,
        consume: usize,
    },
    /// Crosses the buffer's end (or is too long): read it by copying.
    Split,
}

/// How a raw line read ended.
enum RawLine {
    Eof,
    Line { too_long: bool },
}

impl<R: BufRead> Reader<R> {
    /// A reader over `input`; `source` names it in errors (a file name, `<stdin>`).
    pub fn new(input: R, source: impl Into<Arc<str>>) -> Self {
        Self::with_options(input, source, ReaderOptions::default())
    }

    pub fn with_options(input: R, source: impl Into<Arc<str>>, options: ReaderOptions) -> Self {
        Reader {
            input,
            source: source.into(),
            options,
            offer_len: options.max_line_len.saturating_add(1),
            buf: Vec::with_capacity(256),
            lossy: String::new(),
            tokens: LineTokens::default(),
            line: 0,
            skip_lf: false,
            bytes_consumed: 0,
            deferred_consume: 0,
            utf8_checked: 0,
            pending_io_error: None,
            warnings: Warnings::default(),
            failed_io: false,
            at_start: true,
        }
    }

    /// The name used in errors.
    pub fn source(&self) -> &Arc<str> {
        &self.source
    }

    /// Number of the last line read (1-based; 0 before the first).
    pub fn line_number(&self) -> u64 {
        self.line
    }

    /// Input bytes consumed so far (for progress bars).
    pub fn bytes_consumed(&self) -> u64 {
        self.bytes_consumed
    }

    /// Warnings so far (lossy comments).
    pub fn warnings(&self) -> &Warnings {
        &self.warnings
    }

    pub fn warnings_mut(&mut self) -> &mut Warnings {
        &mut self.warnings
    }

    /// The next lexed line; `None` at the end of input. After an error the next call continues with
    /// the following line (an I/O error ends the input).
    #[allow(clippy::should_implement_trait)]
    pub fn next_line(&mut self) -> Option<Result<Line<'_>, GcodeError>> {
        if self.failed_io {
            return None;
        }
        if self.at_start {
            self.skip_byte_order_mark();
        }
        if let Some(err) = self.pending_io_error.take() {
            return Some(Err(self.io_error(&err)));
        }
        self.consume_deferred();
        let located = match self.locate_line() {
            Ok(located) => located,
            Err(err) => return Some(Err(self.io_error(&err))),
        };
        match located {
            Located::Eof => None,
            Located::InBuffer {
                start,
                end,
                consume,
            } => {
                self.line += 1;
                self.bytes_consumed += consume as u64;
                self.deferred_consume = consume;
                // The buffer is not empty, so `fill_buf` returns the same bytes without reading
                // (the `BufRead` contract): the line is lexed in place, without a copy.
                let available = match self.input.fill_buf() {
                    Ok(available) if available.len() >= end => available,
                    other => {
                        self.failed_io = true;
                        let err = other
                            .err()
                            .unwrap_or_else(|| io::Error::other("input buffer changed"));
                        return Some(Err(io_error(&self.source, self.line, &err)));
                    }
                };
                if end > self.utf8_checked {
                    self.utf8_checked =
                        utf8_checked_up_to(available, start.max(self.utf8_checked), end);
                }
                let checked = end <= self.utf8_checked;
                let bytes = &available[start..end];
                let out = (&mut self.tokens, &mut self.lossy, &mut self.warnings);
                Some(lex_bytes(bytes, checked, self.line, out, &self.source))
            }
            Located::Split => {
                self.utf8_checked = 0;
                let too_long = match self.read_raw_line() {
                    Ok(RawLine::Eof) => return None,
                    Ok(RawLine::Line { too_long }) => too_long,
                    Err(err) => return Some(Err(self.io_error(&err))),
                };
                self.line += 1;
                if too_long {
                    let limit = self.options.max_line_len;
                    let span = span_of(self.line, limit, limit.saturating_add(1));
                    return Some(Err(self.error(span, ErrorKind::LineTooLong { limit })));
                }
                let out = (&mut self.tokens, &mut self.lossy, &mut self.warnings);
                Some(lex_bytes(&self.buf, false, self.line, out, &self.source))
            }
        }
    }

    /// Skips a UTF-8 byte-order mark at the very start of the input (editors on Windows write one; it is not
    /// part of the first line). An I/O error is left for the next read to report.
    #[cold]
    fn skip_byte_order_mark(&mut self) {
        self.at_start = false;
        const BOM: &[u8] = b"\xEF\xBB\xBF";
        if let Ok(available) = self.input.fill_buf()
            && available.starts_with(BOM)
        {
            self.input.consume(BOM.len());
            self.bytes_consumed += BOM.len() as u64;
        }
    }

    /// Offers the buffered bytes from the next line's start to `take`, which reads the line itself
    /// (one pass: no separate search for the line end, no UTF-8 check) and gives `Some(len)` when
    /// it took the whole line: `len` bytes, then a `\n` or `\r` inside the offered bytes; the line
    /// is then consumed. `take` must accept only UTF-8 lines and change nothing when it gives
    /// `None`; the line is then read by [`Self::next_line`] as usual. At most `max_line_len + 1`
    /// bytes are offered, so a line too long for `next_line` is never taken.
    #[inline(always)]
    pub(crate) fn take_line_with(
        &mut self,
        take: impl FnOnce(&[u8], u64) -> Option<usize>,
    ) -> Option<()> {
        // The first line goes through `next_line`, which skips a byte-order mark.
        if self.failed_io || self.pending_io_error.is_some() || self.at_start {
            return None;
        }
        self.consume_deferred();
        let available = filled!(self.input, err => {
            self.pending_io_error = Some(err);
            return None;
        });
        let start = usize::from(self.skip_lf && available.first() == Some(&b'\n'));
        let offered_end = available.len().min(start.saturating_add(self.offer_len));
        let len = take(available.get(start..offered_end)?, self.line + 1)?;
        let end = start + len;
        debug_assert!(matches!(available.get(end), Some(b'\n' | b'\r')));
        self.skip_lf = available.get(end) == Some(&b'\r');
        let consume = (end + 1).min(available.len());
        self.input.consume(consume);
        self.utf8_checked = self.utf8_checked.saturating_sub(consume);
        self.line += 1;
        self.bytes_consumed += consume as u64;
        Some(())
    }

    /// [`Self::take_line_with`] for every line in the input's buffer, one after another, until
    /// `take` gives `None` or the buffer ends: the buffer is looked at once and consumed once for
    /// the whole run (not once a line). What is left (the line `take` refused, a line crossing the
    /// buffer's end) is read as [`Self::take_line_with`] leaves it. Gives the number of lines taken.
    #[inline(always)]
    pub(crate) fn take_lines_with(
        &mut self,
        mut take: impl FnMut(&[u8], u64) -> Option<usize>,
    ) -> usize {
        if self.failed_io || self.pending_io_error.is_some() || self.at_start {
            return 0;
        }
        self.consume_deferred();
        let offer_len = self.offer_len;
        let available = filled!(self.input, err => {
            self.pending_io_error = Some(err);
            return 0;
        });
        let (mut pos, mut skip_lf, mut line) = (0, self.skip_lf, self.line);
        loop {
            let start = pos + usize::from(skip_lf && available.get(pos) == Some(&b'\n'));
            let offered_end = available.len().min(start.saturating_add(offer_len));
            let Some(offered) = available.get(start..offered_end) else {
                break;
            };
            let Some(len) = take(offered, line + 1) else {
                break;
            };
            let end = start + len;
            debug_assert!(matches!(available.get(end), Some(b'\n' | b'\r')));
            skip_lf = available.get(end) == Some(&b'\r');
            pos = (end + 1).min(available.len());
            line += 1;
        }
        let taken = (line - self.line) as usize;
        self.input.consume(pos);
        self.skip_lf = skip_lf;
        self.line = line;
        self.utf8_checked = self.utf8_checked.saturating_sub(pos);
        self.bytes_consumed += pos as u64;
        taken
    }

    /// Consumes the line handed out last.
    fn consume_deferred(&mut self) {
        if self.deferred_consume > 0 {
            let consumed = std::mem::take(&mut self.deferred_consume);
            self.input.consume(consumed);
            self.utf8_checked = self.utf8_checked.saturating_sub(consumed);
        }
    }

    /// Finds the next line in the current input buffer without consuming it.
    fn locate_line(&mut self) -> io::Result<Located> {
        let available = filled!(self.input, err => return Err(err));
        if available.is_empty() {
            return Ok(Located::Eof);
        }
        let start = usize::from(self.skip_lf && available[0] == b'\n');
        let Some(i) = memchr::memchr2(b'\n', b'\r', &available[start..]) else {
            return Ok(Located::Split);
        };
        let end = start + i;
        if end - start > self.options.max_line_len {
            return Ok(Located::Split);
        }
        self.skip_lf = available[end] == b'\r';
        Ok(Located::InBuffer {
            start,
            end,
            consume: end + 1,
        })
    }

    fn io_error(&mut self, err: &io::Error) -> GcodeError {
        self.failed_io = true;
        io_error(&self.source, self.line + 1, err)
    }

    fn error(&self, span: Span, kind: ErrorKind) -> GcodeError {
        let text = String::from_utf8_lossy(&self.buf);
        GcodeError::new(&self.source, span, &text, kind)
    }

    /// Reads bytes up to the next line end into `buf` (without the terminator), keeping at most
    /// `max_line_len` bytes.
    fn read_raw_line(&mut self) -> io::Result<RawLine> {
        self.buf.clear();
        let mut got_any = false;
        let mut too_long = false;
        loop {
            let available = filled!(self.input, err => return Err(err));
            if available.is_empty() {
                return Ok(if got_any {
                    RawLine::Line { too_long }
                } else {
                    RawLine::Eof
                });
            }
            let start = usize::from(std::mem::take(&mut self.skip_lf) && available[0] == b'\n');
            let rest = &available[start..];
            let found = memchr::memchr2(b'\n', b'\r', rest);
            let take = found.unwrap_or(rest.len());
            let room = self.options.max_line_len - self.buf.len();
            if take > room {
                too_long = true;
            }
            self.buf.extend_from_slice(&rest[..take.min(room)]);
            got_any |= take > 0;
            let consumed = match found {
                Some(i) => {
                    self.skip_lf = rest[i] == b'\r';
                    start + i + 1
                }
                None => start + take,
            };
            self.input.consume(consumed);
            self.bytes_consumed += consumed as u64;
            if found.is_some() {
                return Ok(RawLine::Line { too_long });
            }
        }
    }
}

fn io_error(source: &Arc<str>, line: u64, err: &io::Error) -> GcodeError {
    GcodeError::new(
        source,
        span_of(line, 0, 0),
        "",
        ErrorKind::Io(err.to_string()),
    )
}

/// Bytes checked for UTF-8 at once: many lines, so that the check runs over long stretches.
const UTF8_BLOCK: usize = 64 << 10;

/// Checks `buffer` from `from` (a character boundary) over at least a block, or up to `end`;
/// returns where the UTF-8 part ends (a line reaching past it is checked again on its own).
fn utf8_checked_up_to(buffer: &[u8], from: usize, end: usize) -> usize {
    let stop = buffer.len().min(end.max(from.saturating_add(UTF8_BLOCK)));
    match std::str::from_utf8(&buffer[from..stop]) {
        Ok(_) => stop,
        Err(err) => from + err.valid_up_to(),
    }
}

/// Checks UTF-8 unless `checked` (lossy inside `;` comments, with a warning) and lexes one line.
fn lex_bytes<'a>(
    bytes: &'a [u8],
    checked: bool,
    line: u64,
    (tokens, lossy, warnings): (&'a mut LineTokens, &'a mut String, &mut Warnings),
    source: &Arc<str>,
) -> Result<Line<'a>, GcodeError> {
    if checked {
        return lex_text(bytes, line, tokens, source);
    }
    let text = match std::str::from_utf8(bytes) {
        Ok(text) => text,
        Err(err) => {
            let bad = err.valid_up_to();
            let span = span_of(line, bad, bad + 1);
            if memchr::memchr(b';', &bytes[..bad]).is_none() {
                let text = String::from_utf8_lossy(bytes);
                return Err(GcodeError::new(source, span, &text, ErrorKind::InvalidUtf8));
            }
            lossy.clear();
            lossy.push_str(&String::from_utf8_lossy(bytes));
            warnings.push(Warning {
                span,
                kind: WarningKind::LossyComment,
                message: "non-UTF-8 bytes in a comment replaced by U+FFFD".to_owned(),
            });
            lossy.as_str()
        }
    };
    lex_text(text.as_bytes(), line, tokens, source)
}

/// Lexes one line of UTF-8 bytes.
fn lex_text<'a>(
    text: &'a [u8],
    line: u64,
    tokens: &'a mut LineTokens,
    source: &Arc<str>,
) -> Result<Line<'a>, GcodeError> {
    match lex_utf8_bytes(text, line, tokens) {
        Ok(()) => Ok(Line::from_utf8_bytes(text, tokens)),
        Err(err) => {
            let span = span_of(line, err.start, err.end);
            Err(GcodeError::new(source, span, utf8(text), err.kind))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &[u8]) -> Vec<String> {
        let mut reader = Reader::new(input, "t");
        let mut out = Vec::new();
        while let Some(line) = reader.next_line() {
            out.push(line.expect("line").text().to_owned());
        }
        out
    }

    #[test]
    fn line_ends() {
        assert_eq!(lines(b"G1\nG2\r\n;c\rM3"), vec!["G1", "G2", ";c", "M3"]);
        assert_eq!(lines(b"G1\r\n\r\nG2\n"), vec!["G1", "", "G2"]);
        assert!(lines(b"").is_empty());
        assert_eq!(lines(b"\n"), vec![""]);
    }

    #[test]
    fn crlf_split_across_buffer_refills() {
        let data = b"G1 X1\r\nG1 X2\r\nG1 X3";
        for capacity in 1..8 {
            let reader = io::BufReader::with_capacity(capacity, &data[..]);
            let mut reader = Reader::new(reader, "t");
            let mut count = 0;
            while let Some(line) = reader.next_line() {
                let line = line.expect("line");
                count += 1;
                assert_eq!(line.number(), count);
                assert_eq!(line.words().len(), 1);
            }
            assert_eq!(count, 3, "capacity {capacity}");
        }
    }

    /// Reference line splitting: `\r\n`, `\r` and `\n` end a line; a final line needs no end.
    fn split_lines(text: &str) -> Vec<String> {
        let normalised = text.replace("\r\n", "\n").replace('\r', "\n");
        let mut lines: Vec<String> = normalised.split('\n').map(str::to_owned).collect();
        if lines.last().is_some_and(String::is_empty) {
            lines.pop();
        }
        lines
    }

    proptest::proptest! {
        #[test]
        fn any_buffer_size_gives_the_same_lines(text in "(;[a-z ]{0,12}|[\r\n]){0,30}", capacity in 1usize..40) {
            let reader = io::BufReader::with_capacity(capacity, text.as_bytes());
            let mut reader = Reader::new(reader, "t");
            let mut lines = Vec::new();
            while let Some(line) = reader.next_line() {
                lines.push(line.map(|l| l.text().to_owned()).map_err(|e| e.to_string()));
            }
            let expected: Vec<Result<String, String>> = split_lines(&text).into_iter().map(Ok).collect();
            proptest::prop_assert_eq!(lines, expected);
        }
    }

    #[test]
    fn too_long_lines_are_skipped_with_an_error() {
        let data = format!("G1 X{}\nG1 X2\n", "1".repeat(100));
        let options = ReaderOptions { max_line_len: 50 };
        let mut reader = Reader::with_options(data.as_bytes(), "t", options);
        let first = reader.next_line().map(|r| r.map(|l| l.number()));
        assert!(matches!(
            first,
            Some(Err(GcodeError {
                kind: ErrorKind::LineTooLong { .. },
                ..
            }))
        ));
        let second = reader.next_line().map(|r| r.map(|l| l.number()));
        assert_eq!(second, Some(Ok(2)));
    }

    #[test]
    fn invalid_utf8_in_comment_is_lossy() {
        let mut reader = Reader::new(&b"G1 X1 ; caf\xe9\n"[..], "t");
        let line = reader
            .next_line()
            .map(|r| r.map(|l| l.comments().next().map(|c| c.text.to_owned())));
        assert_eq!(line, Some(Ok(Some(" caf\u{fffd}".to_owned()))));
        assert_eq!(reader.warnings().total(), 1);
    }

    /// Every line's text or error, and the warning count.
    fn outcome<R: BufRead>(input: R) -> (Vec<Result<String, String>>, u64) {
        let mut reader = Reader::new(input, "t");
        let mut out = Vec::new();
        while let Some(line) = reader.next_line() {
            out.push(line.map(|l| l.text().to_owned()).map_err(|e| e.to_string()));
        }
        (out, reader.warnings().total())
    }

    #[test]
    fn utf8_checked_in_blocks_gives_the_same_lines_as_line_by_line() {
        // Multi-byte characters straddle block ends, and bad bytes sit in code and in comments,
        // before and after the first block end.
        let mut data = Vec::new();
        for i in 0..12_000 {
            match i % 997 {
                5 => data.extend_from_slice(b"G1 X\xff2\n"),
                9 => data.extend_from_slice(b"G1 X1 ; caf\xe9\n"),
                _ => data
                    .extend_from_slice(format!("G1 X{i} ; \u{e9}\u{2013}\u{1f600}\n").as_bytes()),
            }
        }
        let whole = outcome(&data[..]);
        // A 5-byte buffer holds almost no whole line: nearly every line is copied and checked alone.
        let line_by_line = outcome(io::BufReader::with_capacity(5, &data[..]));
        assert_eq!(whole, line_by_line);
        assert_eq!(whole.1, 13);
        assert_eq!(whole.0.iter().filter(|r| r.is_err()).count(), 13);
    }

    #[test]
    fn invalid_utf8_in_code_is_an_error() {
        let mut reader = Reader::new(&b"G1 X1\nG1 X\xff2\n"[..], "t");
        assert!(reader.next_line().is_some_and(|r| r.is_ok()));
        let err = reader.next_line().and_then(|r| r.err());
        assert_eq!(
            err.map(|e| (e.kind, e.span.line, e.span.column)),
            Some((ErrorKind::InvalidUtf8, 2, 5))
        );
    }
}
