//! Errors and warnings of the reader and the interpreter, each with the source name and span.

use std::fmt;
use std::sync::Arc;

use crate::command::Span;

/// How much of the offending line an error keeps (bytes around the column).
const CONTEXT_BYTES: usize = 200;

/// What went wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ErrorKind {
    #[error("read error: {0}")]
    Io(String),
    #[error("invalid UTF-8 outside a comment")]
    InvalidUtf8,
    #[error("line longer than {limit} bytes")]
    LineTooLong { limit: usize },
    /// Bounds the memory one line may take: words are kept per line until the line is interpreted.
    #[error("more than {limit} words, parameters or comments on one line")]
    TooManyTokens { limit: usize },
    #[error("invalid number")]
    InvalidNumber,
    #[error("number out of range")]
    NumberOverflow,
    #[error("exponents are not G-code numbers")]
    ExponentNotAllowed,
    #[error("unexpected character {0:?}")]
    UnexpectedCharacter(char),
    #[error("unterminated '(' comment")]
    UnterminatedComment,
    #[error("unterminated '\"' string")]
    UnterminatedString,
    #[error("malformed checksum")]
    MalformedChecksum,
    #[error("checksum mismatch: line says {written}, computed {computed}")]
    ChecksumMismatch { written: u32, computed: u8 },
    #[error("malformed parameter (expected KEY=VALUE)")]
    MalformedParameter,
    #[error("invalid feed rate")]
    InvalidFeedRate,
    #[error("invalid value for parameter {0}")]
    InvalidParameter(String),
    #[error("negative dwell time")]
    NegativeDwell,
    #[error("G2/G3 does not support relative move mode")]
    ArcRelativeMode,
    #[error("G2/G3 only supported in the XY plane (G17)")]
    ArcPlaneUnsupported,
    #[error("G2/G3 needs I/J offsets or R")]
    ArcMissingCentre,
    #[error("arc radius is zero")]
    ArcZeroRadius,
    #[error("G2/G3 does not support R moves (as Klipper: give the centre with I and J)")]
    ArcRadiusUnsupported,
    #[error(
        "G20 (inch units): Klipper refuses it (\"Machine does not support G20 (inches) command\")"
    )]
    InchUnitsUnsupported,
    #[error(
        "R arc that ends where it starts: its centre is undefined (give I/J for a full circle)"
    )]
    ArcRClosed,
    #[error("R arc: chord longer than the diameter")]
    ArcRadiusTooSmall,
    #[error("inconsistent arc: radius {start_radius} at start, {end_radius} at end")]
    ArcInconsistent { start_radius: f64, end_radius: f64 },
}

/// A reader or interpreter error: `file:line:col: message`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{source_name}:{}:{}: {kind}", span.line, span.column)]
pub struct GcodeError {
    /// File name (or `<stdin>`, `<memory>`…).
    pub source_name: Arc<str>,
    pub span: Span,
    /// The offending line, cut to about 200 bytes around the column.
    pub line_text: String,
    /// Byte offset of `line_text` inside the full line (to place the underline).
    pub line_text_offset: usize,
    pub kind: ErrorKind,
}

impl GcodeError {
    /// Builds an error, keeping a window of `line` around the span's column.
    pub fn new(source_name: &Arc<str>, span: Span, line: &str, kind: ErrorKind) -> Self {
        let (line_text_offset, line_text) = context_window(line, span.column as usize);
        GcodeError {
            source_name: Arc::clone(source_name),
            span,
            line_text,
            line_text_offset,
            kind,
        }
    }
}

/// A window of at most `CONTEXT_BYTES` around 1-based `column`, cut on char boundaries.
fn context_window(line: &str, column: usize) -> (usize, String) {
    if line.len() <= CONTEXT_BYTES {
        return (0, line.to_owned());
    }
    let centre = column.saturating_sub(1).min(line.len());
    let mut start = centre.saturating_sub(CONTEXT_BYTES / 2);
    while !line.is_char_boundary(start) {
        start -= 1;
    }
    let mut end = (start + CONTEXT_BYTES).min(line.len());
    while !line.is_char_boundary(end) {
        end -= 1;
    }
    (start, line[start..end].to_owned())
}

/// What a warning is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WarningKind {
    /// A parameter letter the command does not use (`G1 Q5`).
    UnknownParameter,
    /// The same parameter twice on a line; the last one wins (as Klipper).
    DuplicateParameter,
    /// A command letter other than G, M or T (`X10` alone on a line).
    UnknownCommandLetter,
    /// A command the firmware does not have as configured (G2 without `[gcode_arcs]` on Klipper): skipped.
    UnknownCommand,
    /// Non-UTF-8 bytes inside a comment, replaced by U+FFFD.
    LossyComment,
}

/// A non-fatal finding, with where it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    pub span: Span,
    pub kind: WarningKind,
    pub message: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}: {}",
            self.span.line, self.span.column, self.message
        )
    }
}

/// Warnings kept in memory are capped so a pathological file cannot grow memory; the count is exact.
#[derive(Debug, Clone, Default)]
pub struct Warnings {
    kept: Vec<Warning>,
    total: u64,
}

impl Warnings {
    /// At most this many warnings are stored.
    pub const MAX_KEPT: usize = 1000;

    pub fn push(&mut self, warning: Warning) {
        self.total += 1;
        if self.kept.len() < Self::MAX_KEPT {
            self.kept.push(warning);
        }
    }

    /// Stored warnings (the first `MAX_KEPT`).
    pub fn list(&self) -> &[Warning] {
        &self.kept
    }

    /// How many warnings there were in total.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// Takes the stored warnings out, keeping the total count.
    pub fn take(&mut self) -> Vec<Warning> {
        std::mem::take(&mut self.kept)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_is_file_line_column_message() {
        let source: Arc<str> = Arc::from("part.gcode");
        let span = Span {
            line: 12,
            column: 7,
            len: 3,
        };
        let err = GcodeError::new(&source, span, "G1 X1.2.3", ErrorKind::InvalidNumber);
        assert_eq!(err.to_string(), "part.gcode:12:7: invalid number");
        assert_eq!(err.line_text, "G1 X1.2.3");
    }

    #[test]
    fn long_lines_are_cut_around_the_column() {
        let source: Arc<str> = Arc::from("x");
        let line = format!("{}é{}", "a".repeat(5000), "b".repeat(5000));
        let span = Span {
            line: 1,
            column: 5001,
            len: 1,
        };
        let err = GcodeError::new(&source, span, &line, ErrorKind::InvalidNumber);
        assert!(err.line_text.len() <= CONTEXT_BYTES);
        assert!(err.line_text.contains('é'));
        assert_eq!(
            &line[err.line_text_offset..err.line_text_offset + err.line_text.len()],
            err.line_text
        );
    }

    #[test]
    fn warnings_are_capped_but_counted() {
        let mut warnings = Warnings::default();
        for _ in 0..(Warnings::MAX_KEPT + 5) {
            warnings.push(Warning {
                span: Span::default(),
                kind: WarningKind::UnknownParameter,
                message: String::new(),
            });
        }
        assert_eq!(warnings.list().len(), Warnings::MAX_KEPT);
        assert_eq!(warnings.total(), (Warnings::MAX_KEPT + 5) as u64);
    }
}
