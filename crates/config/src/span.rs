//! Source locations: where in which file a section, key or value was written.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

/// A piece of text in a config file: file, 1-based line and column, length, and the whole line.
///
/// Columns and lengths count characters (not bytes), so a renderer can underline the value under the
/// line text directly. `printer.cfg:12:15` is the `Display` form.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Span {
    pub file: Arc<Path>,
    /// 1-based line number.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// Length in characters (0 for an empty value: the position where it would be).
    pub len: usize,
    /// The full text of the line (without the line ending).
    pub line_text: Arc<str>,
}

impl Span {
    /// Span of `len_chars` characters starting at byte offset `byte_start` of `line_text`.
    pub(crate) fn in_line(
        file: &Arc<Path>,
        line: usize,
        line_text: &Arc<str>,
        byte_start: usize,
        len_chars: usize,
    ) -> Span {
        let prefix = line_text.get(..byte_start).unwrap_or(line_text);
        Span {
            file: Arc::clone(file),
            line,
            column: prefix.chars().count() + 1,
            len: len_chars,
            line_text: Arc::clone(line_text),
        }
    }

    /// A narrower span inside this one: `skip` characters further, `len` characters long.
    /// Falls back to the whole span when the part would not fit (e.g. it lies on another line).
    pub(crate) fn narrowed(&self, skip: usize, len: usize) -> Span {
        if skip + len > self.len {
            return self.clone();
        }
        Span {
            column: self.column + skip,
            len,
            ..self.clone()
        }
    }

    /// Byte range of the spanned text within [`Span::line_text`].
    pub fn byte_range_in_line(&self) -> std::ops::Range<usize> {
        let start = byte_of_char(&self.line_text, self.column.saturating_sub(1));
        let end = byte_of_char(&self.line_text, self.column.saturating_sub(1) + self.len);
        start..end.max(start)
    }

    /// The spanned text itself.
    pub fn text(&self) -> &str {
        self.line_text
            .get(self.byte_range_in_line())
            .unwrap_or_default()
    }

    /// The line followed by a caret line underlining the span (for plain-text diagnostics).
    pub fn underlined(&self) -> String {
        let indent: String = self
            .line_text
            .chars()
            .take(self.column.saturating_sub(1))
            .map(|c| if c == '\t' { '\t' } else { ' ' })
            .collect();
        let carets = "^".repeat(self.len.max(1));
        format!("{}\n{indent}{carets}", self.line_text)
    }
}

/// Byte index of the `n`-th character (or the end of the string).
fn byte_of_char(text: &str, n: usize) -> usize {
    text.char_indices()
        .nth(n)
        .map_or(text.len(), |(byte, _)| byte)
}

impl fmt::Display for Span {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(text: &str, byte_start: usize, len: usize) -> Span {
        let file: Arc<Path> = Arc::from(Path::new("printer.cfg"));
        Span::in_line(&file, 12, &Arc::from(text), byte_start, len)
    }

    #[test]
    fn columns_count_characters_not_bytes() {
        let s = span("größe: 12", 9, 2);
        assert_eq!(s.column, 8);
        assert_eq!(s.text(), "12");
        assert_eq!(s.to_string(), "printer.cfg:12:8");
    }

    #[test]
    fn underline_sits_under_the_value() {
        let s = span("max_velocity: abc", 14, 3);
        assert_eq!(s.underlined(), "max_velocity: abc\n              ^^^");
    }

    #[test]
    fn narrowed_stays_inside_or_falls_back() {
        let s = span("gear_ratio: 80:0", 12, 4);
        let part = s.narrowed(3, 1);
        assert_eq!(part.text(), "0");
        assert_eq!(s.narrowed(3, 5), s);
    }
}
