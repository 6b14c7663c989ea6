//! Turning library errors into `miette` diagnostics: `file:line:col`, the offending line, the word underlined.
//!
//! Library errors carry the offending line's text (or the CLI re-reads that one line), so a diagnostic for line
//! 3 000 000 of a huge file costs nothing and shows the real line number.

use miette::{
    Diagnostic, LabeledSpan, MietteError, MietteSpanContents, SourceCode, SourceSpan, SpanContents,
};
use std::fmt;
use std::io::BufRead;
use std::path::Path;

/// One line of a source file, presented to miette at its real line number.
#[derive(Debug, Clone)]
pub struct LineSource {
    pub name: String,
    /// 1-based line number of `text` in the file.
    pub line: usize,
    pub text: String,
}

impl SourceCode for LineSource {
    fn read_span<'a>(
        &'a self,
        span: &SourceSpan,
        _context_lines_before: usize,
        _context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'a> + 'a>, MietteError> {
        if span.offset() + span.len() > self.text.len() {
            return Err(MietteError::OutOfBounds);
        }
        Ok(Box::new(MietteSpanContents::new_named(
            self.name.clone(),
            self.text.as_bytes(),
            (0, self.text.len()).into(),
            self.line.saturating_sub(1),
            0,
            1,
        )))
    }
}

/// A diagnostic pointing at a word on one line of a file.
#[derive(Debug)]
pub struct SourceDiagnostic {
    pub message: String,
    pub source: Option<LineSource>,
    /// Byte offset and length of the underlined word within `source.text`.
    pub offset: usize,
    pub len: usize,
    pub label: String,
    pub help: Option<String>,
}

impl fmt::Display for SourceDiagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for SourceDiagnostic {}

impl Diagnostic for SourceDiagnostic {
    fn source_code(&self) -> Option<&dyn SourceCode> {
        self.source.as_ref().map(|s| s as &dyn SourceCode)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let source = self.source.as_ref()?;
        let offset = self.offset.min(source.text.len());
        let len = self
            .len
            .min(source.text.len() - offset)
            .max(usize::from(offset < source.text.len()));
        Some(Box::new(std::iter::once(LabeledSpan::new(
            Some(self.label.clone()),
            offset,
            len,
        ))))
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }
}

/// The text of line `line` (1-based) of `path`, read again for an error message.
pub fn read_line_of(path: &Path, line: u64) -> Option<String> {
    let file = std::fs::File::open(path).ok()?;
    let mut reader = std::io::BufReader::new(file);
    let mut buf = Vec::new();
    for _ in 1..line {
        buf.clear();
        if reader.read_until(b'\n', &mut buf).ok()? == 0 {
            return None;
        }
    }
    buf.clear();
    reader.read_until(b'\n', &mut buf).ok()?;
    let text = String::from_utf8_lossy(&buf);
    Some(
        text.trim_end_matches(['\n', '\r'])
            .chars()
            .take(400)
            .collect(),
    )
}

/// A G-code reader/interpreter error.
pub fn gcode_error(e: &gcode::GcodeError) -> SourceDiagnostic {
    let column = (e.span.column as usize).saturating_sub(1);
    SourceDiagnostic {
        message: e.to_string(),
        source: Some(LineSource {
            name: e.source_name.to_string(),
            line: e.span.line as usize,
            text: e.line_text.clone(),
        }),
        offset: column.saturating_sub(e.line_text_offset),
        len: e.span.len as usize,
        label: e.kind.to_string(),
        help: None,
    }
}

/// A printer.cfg error (the span, when there is one, carries its line text).
pub fn config_error(e: &config::ConfigError) -> SourceDiagnostic {
    match e.span() {
        Some(span) => SourceDiagnostic {
            message: e.to_string(),
            source: Some(LineSource {
                name: span.file.display().to_string(),
                line: span.line,
                text: span.line_text.to_string(),
            }),
            offset: span.column.saturating_sub(1),
            len: span.len,
            label: "here".into(),
            help: None,
        },
        None => SourceDiagnostic {
            message: e.to_string(),
            source: None,
            offset: 0,
            len: 0,
            label: String::new(),
            help: None,
        },
    }
}

/// An error at a G-code span whose line text must be read again from the file.
pub fn at_gcode_line(
    path: &Path,
    span: gcode::Span,
    message: String,
    label: String,
) -> SourceDiagnostic {
    let name = path.display().to_string();
    let text = read_line_of(path, span.line);
    SourceDiagnostic {
        message: format!("{name}:{}:{}: {message}", span.line, span.column),
        source: text.map(|text| LineSource {
            name,
            line: span.line as usize,
            text,
        }),
        offset: (span.column as usize).saturating_sub(1),
        len: span.len as usize,
        label,
        help: None,
    }
}

/// A step stream no MCU could run, as a diagnostic on the G-code line it comes from (when it could be found).
pub fn step_stream_error(
    file: &Path,
    line: Option<u64>,
    e: &printjob::StepStreamError,
) -> miette::Report {
    match line {
        Some(line) => {
            let span = gcode::Span {
                line,
                column: 1,
                len: 0,
            };
            miette::Report::new(at_gcode_line(
                file,
                span,
                e.to_string(),
                "the steps of this move".into(),
            ))
        }
        None => miette::miette!("{}: {e}", file.display()),
    }
}

/// A planning error as a diagnostic on the G-code line.
pub fn pipeline_error(file: &Path, e: printjob::PipelineError) -> miette::Report {
    match e {
        printjob::PipelineError::Gcode(e) => miette::Report::new(gcode_error(&e)),
        printjob::PipelineError::Plan(e) => miette::Report::new(at_gcode_line(
            file,
            e.span,
            e.kind.to_string(),
            "this move".into(),
        )),
        // Not the file's fault: an output could not take the moves.
        printjob::PipelineError::Sink { span, error } => miette::miette!(
            "{error} (stopped while planning {}:{})",
            file.display(),
            span.line
        ),
    }
}
