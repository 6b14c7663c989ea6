//! Klipper's printer.cfg syntax: sections, `key: value` / `key = value`, comments, indented
//! continuation lines, `[include …]` (relative paths and globs) and the trailing `#*#` SAVE_CONFIG block.
//!
//! Semantics follow Python's `configparser` as Klipper configures it: inline `#`/`;` comments only after
//! whitespace, comment-only lines inside a multi-line value are skipped, blank lines inside a value are
//! kept and trailing ones dropped, later sections and keys override earlier ones. After an include the
//! including file continues with no current section (Klipper parses the text between includes as a
//! separate unit), so options there need a new section header.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::document::{ConfigDocument, Entry, Section, section_key};
use crate::error::{ConfigError, ConfigWarning};
use crate::span::Span;

const AUTOSAVE_HEADER: &str = "#*# <---------------------- SAVE_CONFIG ---------------------->";
const AUTOSAVE_PREFIX: &str = "#*#";

// The document's constructors live with the parser, so that the document does not depend on its parser.
impl ConfigDocument {
    /// Reads `path` and everything it includes.
    pub fn load(path: impl AsRef<Path>) -> Result<ConfigDocument, ConfigError> {
        parse_file(path.as_ref())
    }

    /// Parses `text` as if it were the file `path` (includes resolve relative to its folder).
    pub fn from_str(text: &str, path: impl AsRef<Path>) -> Result<ConfigDocument, ConfigError> {
        parse_text(text, path.as_ref())
    }
}

/// How deep includes may nest: Klipper sets no limit of its own, but real configs nest two or three deep; an endless
/// chain must stop with a located error, not a stack overflow.
const MAX_INCLUDE_DEPTH: usize = 64;

/// How many files one config may read, includes counted each time they are read: a file included again and again
/// (a "diamond" of files each including the next two) would otherwise be read exponentially often.
const MAX_CONFIG_FILES: usize = 1000;

/// How many bytes all the files of one config may hold together (a printer.cfg is a few kB; a runaway include must
/// not fill memory).
const MAX_CONFIG_BYTES: u64 = 64 << 20;

/// Reads a config file from disk with everything it includes.
fn parse_file(path: &Path) -> Result<ConfigDocument, ConfigError> {
    let io = |source| ConfigError::Io {
        path: path.to_path_buf(),
        source,
    };
    check_readable(path, MAX_CONFIG_BYTES).map_err(io)?;
    let text = read_text(path)?;
    parse_text(&text, path)
}

/// Why `path` may not be read as a config file: not a regular file (a FIFO would block, a device such as
/// `/dev/zero` never ends), or larger than `budget` bytes.
fn check_readable(path: &Path, budget: u64) -> Result<u64, std::io::Error> {
    let meta = std::fs::metadata(path)?;
    let refuse = |what: String| Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, what));
    if !meta.is_file() {
        return refuse(format!("not a regular file ({})", file_kind(&meta)));
    }
    if meta.len() > budget {
        return refuse(format!(
            "{} bytes, more than the {} MiB all config files together may hold",
            meta.len(),
            MAX_CONFIG_BYTES >> 20
        ));
    }
    Ok(meta.len())
}

/// What kind of file system entry `meta` describes, for a refusal.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt as _;
    let kind = meta.file_type();
    match () {
        _ if kind.is_dir() => "a folder",
        _ if kind.is_fifo() => "a FIFO",
        _ if kind.is_char_device() || kind.is_block_device() => "a device",
        _ if kind.is_socket() => "a socket",
        _ => "not a file",
    }
}

/// Parses `text` as the main file `path`.
fn parse_text(text: &str, path: &Path) -> Result<ConfigDocument, ConfigError> {
    let mut builder = Builder {
        sections: Vec::new(),
        files: vec![path.to_path_buf()],
        warnings: Vec::new(),
        include_stack: vec![identity(path)],
        bytes: text.len() as u64,
    };
    let file: Arc<Path> = Arc::from(path);
    let lines = split_lines(text);
    let (regular, autosave) = split_autosave(&lines, &file, &mut builder.warnings);
    builder.parse_lines(&file, regular, 0)?;
    builder.parse_lines(&file, autosave, AUTOSAVE_PREFIX.len() + 1)?;
    Ok(ConfigDocument {
        path: path.to_path_buf(),
        sections: builder.sections,
        files: builder.files,
        warnings: builder.warnings,
    })
}

/// One physical line: 1-based number and text without its line ending.
type Line = (usize, Arc<str>);

fn split_lines(text: &str) -> Vec<Line> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, Arc::from(l.strip_suffix('\r').unwrap_or(l))))
        .collect()
}

/// Reads a file as UTF-8, reporting where the first invalid byte is.
fn read_text(path: &Path) -> Result<String, ConfigError> {
    let bytes = std::fs::read(path).map_err(|source| ConfigError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    String::from_utf8(bytes).map_err(|err| {
        let valid = &err.as_bytes()[..err.utf8_error().valid_up_to()];
        // The prefix is valid UTF-8 by construction; count lines and characters in it.
        let valid = std::str::from_utf8(valid).unwrap_or_default();
        let line = valid.matches('\n').count() + 1;
        let column = valid.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        ConfigError::NotUtf8 {
            path: path.to_path_buf(),
            line,
            column,
        }
    })
}

/// Splits off Klipper's SAVE_CONFIG block. Like Klipper, a damaged block is ignored (with a warning)
/// and its `#*#` lines are then plain comments.
fn split_autosave<'a>(
    lines: &'a [Line],
    file: &Arc<Path>,
    warnings: &mut Vec<ConfigWarning>,
) -> (&'a [Line], &'a [Line]) {
    let Some(header) = lines
        .iter()
        .position(|(_, text)| text.trim_end() == AUTOSAVE_HEADER)
    else {
        return (lines, &[]);
    };
    let (regular, rest) = lines.split_at(header);
    let mut block = &rest[1..];
    while let Some(((_, last), init)) = block.split_last() {
        if !last.trim().is_empty() {
            break;
        }
        block = init;
    }
    if let Some(((_, first), tail)) = block.split_first()
        && first.starts_with("#*# DO NOT EDIT")
    {
        block = tail;
    }
    let stray = regular.iter().find(|(_, text)| text.starts_with("#*# "));
    let damaged = block.iter().find(|(_, text)| {
        !text.starts_with(AUTOSAVE_PREFIX) || (text.len() >= 4 && !text.starts_with("#*# "))
    });
    if let Some((number, text)) = stray.or(damaged) {
        warnings.push(ConfigWarning {
            span: Some(Span::in_line(file, *number, text, 0, text.chars().count())),
            message: "SAVE_CONFIG block is damaged (a line outside the block starts with '#*#', \
                      or a line inside it does not); its values are ignored, as Klipper does"
                .to_string(),
        });
        return (lines, &[]);
    }
    (regular, block)
}

/// Stable identity of a file for include-cycle detection.
fn identity(path: &Path) -> PathBuf {
    std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_path_buf())
}

struct Builder {
    sections: Vec<Section>,
    files: Vec<PathBuf>,
    warnings: Vec<ConfigWarning>,
    /// Files being read, outermost first (canonical paths), to name an include cycle.
    include_stack: Vec<PathBuf>,
    /// Bytes read so far, every file counted each time it is read.
    bytes: u64,
}

/// Where the reader is within one unit of text: current section and the option that may continue.
#[derive(Default)]
struct Cursor {
    section: Option<usize>,
    /// (section index, entry index, indent of the key line)
    option: Option<(usize, usize, usize)>,
    /// Blank lines seen since the option's last line (kept only if more value lines follow).
    pending_blank_lines: usize,
}

/// A line with comments removed: its text and where that text starts in the physical line.
struct Content<'a> {
    text: &'a str,
    start: usize,
    indent: usize,
    /// True when the line held only whitespace (no comment either).
    blank: bool,
}

impl Builder {
    /// Parses lines whose meaningful text starts at byte `offset` (4 for `#*# ` lines).
    fn parse_lines(
        &mut self,
        file: &Arc<Path>,
        lines: &[Line],
        offset: usize,
    ) -> Result<(), ConfigError> {
        let mut cursor = Cursor::default();
        for (number, text) in lines {
            let content = strip_line(text, offset);
            if content.text.is_empty() {
                if content.blank && cursor.option.is_some() {
                    cursor.pending_blank_lines += 1;
                }
                continue;
            }
            let span = Span::in_line(
                file,
                *number,
                text,
                content.start,
                content.text.chars().count(),
            );
            match cursor.option {
                Some((section, entry, key_indent)) if content.indent > key_indent => {
                    self.continue_value(section, entry, content.text, span, &mut cursor);
                }
                _ => self.parse_statement(file, &content, span, &mut cursor)?,
            }
        }
        Ok(())
    }

    fn continue_value(
        &mut self,
        section: usize,
        entry: usize,
        text: &str,
        span: Span,
        cursor: &mut Cursor,
    ) {
        let entry = &mut self.sections[section].entries[entry];
        for _ in 0..=cursor.pending_blank_lines {
            entry.value.push('\n');
        }
        cursor.pending_blank_lines = 0;
        entry.pieces.push((entry.value.len(), span));
        entry.value.push_str(text);
    }

    /// A line that is not a continuation: a section header, an include, or a new option.
    fn parse_statement(
        &mut self,
        file: &Arc<Path>,
        content: &Content<'_>,
        span: Span,
        cursor: &mut Cursor,
    ) -> Result<(), ConfigError> {
        cursor.option = None;
        cursor.pending_blank_lines = 0;
        if content.text.starts_with('[') {
            let name = header_name(content.text, &span)?;
            if let Some(pattern) = include_pattern(name) {
                self.include(file, pattern, &span)?;
                // Klipper parses the text after an include as a new unit: no current section.
                *cursor = Cursor::default();
            } else {
                cursor.section = Some(self.open_section(name, span));
            }
            return Ok(());
        }
        let Some(section) = cursor.section else {
            return Err(ConfigError::Syntax {
                span: Box::new(span),
                message: "option outside of any [section]".to_string(),
            });
        };
        let entry = parse_option(content, span)?;
        let index = self.sections[section].set(entry);
        cursor.option = Some((section, index, content.indent));
        Ok(())
    }

    /// Index of the section `name`, creating it if new; duplicates merge into the first.
    fn open_section(&mut self, name: &str, header: Span) -> usize {
        let key = section_key(name);
        if let Some(index) = self.sections.iter().position(|s| s.key == key) {
            return index;
        }
        self.sections.push(Section {
            name: name.to_string(),
            key,
            header,
            entries: Vec::new(),
        });
        self.sections.len() - 1
    }

    /// Reads every file an `[include …]` names, in sorted order, like Klipper.
    fn include(
        &mut self,
        including: &Arc<Path>,
        pattern: &str,
        span: &Span,
    ) -> Result<(), ConfigError> {
        for path in resolve_include(including, pattern, span)? {
            let id = identity(&path);
            if let Some(start) = self.include_stack.iter().position(|p| *p == id) {
                let mut chain = self.include_stack[start..].to_vec();
                chain.push(id);
                return Err(ConfigError::IncludeCycle {
                    span: Box::new(span.clone()),
                    chain,
                });
            }
            self.check_include(&path, span)?;
            let text = read_text(&path)?;
            self.bytes += text.len() as u64;
            self.files.push(path.clone());
            self.include_stack.push(id);
            let file: Arc<Path> = Arc::from(path.as_path());
            self.parse_lines(&file, &split_lines(&text), 0)?;
            self.include_stack.pop();
        }
        Ok(())
    }
}

impl Builder {
    /// Whether the include of `path` at `span` stays within what one config may read.
    fn check_include(&self, path: &Path, span: &Span) -> Result<(), ConfigError> {
        let refuse = |message: String| ConfigError::IncludeRefused {
            span: Box::new(span.clone()),
            message,
        };
        if self.include_stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(refuse(format!(
                "includes nest more than {MAX_INCLUDE_DEPTH} files deep"
            )));
        }
        if self.files.len() >= MAX_CONFIG_FILES {
            return Err(refuse(format!(
                "more than {MAX_CONFIG_FILES} files read for one config (a file included again and again?)"
            )));
        }
        let budget = MAX_CONFIG_BYTES.saturating_sub(self.bytes);
        check_readable(path, budget)
            .map(|_| ())
            .map_err(|e| refuse(format!("cannot include {}: {e}", path.display())))
    }
}

/// Removes comments and surrounding whitespace from a line's text after `offset`.
fn strip_line(text: &str, offset: usize) -> Content<'_> {
    let line = text.get(offset..).unwrap_or_default();
    let comment = comment_start(line);
    let code = &line[..comment.unwrap_or(line.len())];
    let trimmed_start = code.trim_start();
    let lead = code.len() - trimmed_start.len();
    Content {
        text: trimmed_start.trim_end(),
        start: offset + lead,
        indent: line.chars().take_while(|c| c.is_whitespace()).count(),
        blank: comment.is_none(),
    }
}

/// Byte index where a comment starts: a full-line `#`/`;` comment, or one preceded by whitespace.
fn comment_start(line: &str) -> Option<usize> {
    let mut previous_is_space = true;
    for (index, c) in line.char_indices() {
        if (c == '#' || c == ';') && previous_is_space {
            return Some(index);
        }
        previous_is_space = c.is_whitespace();
    }
    None
}

/// The name inside `[ … ]`; anything after the closing bracket is an error.
fn header_name<'a>(text: &'a str, span: &Span) -> Result<&'a str, ConfigError> {
    let Some(close) = text.rfind(']') else {
        return Err(ConfigError::Syntax {
            span: Box::new(span.clone()),
            message: "section header is missing its closing ']'".to_string(),
        });
    };
    if close + 1 != text.len() {
        let trailing = &text[close + 1..];
        let extra = trailing.trim_start();
        let skip = text.len() - extra.len();
        return Err(ConfigError::Syntax {
            span: Box::new(span.narrowed(text[..skip].chars().count(), extra.chars().count())),
            message: "unexpected text after the section header".to_string(),
        });
    }
    let name = text[1..close].trim();
    if name.is_empty() {
        return Err(ConfigError::Syntax {
            span: Box::new(span.clone()),
            message: "empty section name".to_string(),
        });
    }
    Ok(name)
}

/// `Some(pattern)` when the header is `[include pattern]`.
fn include_pattern(name: &str) -> Option<&str> {
    let (first, rest) = name.split_once(char::is_whitespace)?;
    (first == "include").then(|| rest.trim())
}

/// A `key: value` or `key = value` line (the first `:` or `=` separates them).
fn parse_option(content: &Content<'_>, span: Span) -> Result<Entry, ConfigError> {
    let text = content.text;
    let Some(separator) = text.find([':', '=']) else {
        return Err(ConfigError::Syntax {
            span: Box::new(span),
            message: "expected 'key: value' or 'key = value'".to_string(),
        });
    };
    let key_text = text[..separator].trim_end();
    if key_text.is_empty() {
        return Err(ConfigError::Syntax {
            span: Box::new(span),
            message: "option name is missing before the separator".to_string(),
        });
    }
    let after = &text[separator + 1..];
    let value = after.trim_start();
    let value_start = content.start + separator + 1 + (after.len() - value.len());
    let value_span = Span::in_line(
        &span.file,
        span.line,
        &span.line_text,
        value_start,
        value.chars().count(),
    );
    let key_span = Span::in_line(
        &span.file,
        span.line,
        &span.line_text,
        content.start,
        key_text.chars().count(),
    );
    let pieces = if value.is_empty() {
        Vec::new()
    } else {
        vec![(0, value_span.clone())]
    };
    Ok(Entry {
        key: key_text.to_lowercase(),
        key_span,
        value: value.to_string(),
        pieces,
        empty_value_span: value_span,
        read: AtomicBool::new(false),
    })
}

/// Files matched by an include pattern, relative to the including file's folder, sorted.
/// No match is an error only for a pattern without wildcards (Klipper's rule).
fn resolve_include(
    including: &Path,
    pattern: &str,
    span: &Span,
) -> Result<Vec<PathBuf>, ConfigError> {
    let folder = including.parent().unwrap_or(Path::new(""));
    let joined = folder.join(pattern);
    let has_wildcards = pattern.contains(['*', '?', '[']);
    if !has_wildcards {
        return if joined.exists() {
            Ok(vec![joined])
        } else {
            Err(ConfigError::IncludeNotFound {
                span: Box::new(span.clone()),
                pattern: joined.display().to_string(),
            })
        };
    }
    let full_pattern = if Path::new(pattern).is_absolute() || folder.as_os_str().is_empty() {
        pattern.to_string()
    } else {
        format!(
            "{}/{pattern}",
            glob::Pattern::escape(&folder.to_string_lossy())
        )
    };
    let options = glob::MatchOptions {
        case_sensitive: true,
        require_literal_separator: true,
        require_literal_leading_dot: true,
    };
    let paths =
        glob::glob_with(&full_pattern, options).map_err(|err| ConfigError::IncludePattern {
            span: Box::new(span.clone()),
            pattern: pattern.to_string(),
            message: err.msg.to_string(),
        })?;
    let mut found = Vec::new();
    // Bounded: more matches than a config may read are refused by the reader anyway.
    for path in paths.take(MAX_CONFIG_FILES + 1) {
        let path = path.map_err(|err| ConfigError::Io {
            path: err.path().to_path_buf(),
            source: std::io::Error::new(err.error().kind(), err.error().to_string()),
        })?;
        found.push(path);
    }
    found.sort();
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inline_comments_need_whitespace_before_them() {
        assert_eq!(comment_start("pin: PA1 # x"), Some(9));
        assert_eq!(comment_start("pin: PA1;x"), None);
        assert_eq!(comment_start("  ; whole line"), Some(2));
        assert_eq!(comment_start("value: a#b"), None);
    }

    #[test]
    fn header_names_and_includes() {
        let file: Arc<Path> = Arc::from(Path::new("p.cfg"));
        let span = Span::in_line(&file, 1, &Arc::from("[x]"), 0, 3);
        assert_eq!(header_name("[ stepper_x ]", &span).ok(), Some("stepper_x"));
        assert!(header_name("[stepper_x", &span).is_err());
        assert!(header_name("[]", &span).is_err());
        assert!(header_name("[a] b", &span).is_err());
        assert_eq!(
            include_pattern("include macros/*.cfg"),
            Some("macros/*.cfg")
        );
        assert_eq!(include_pattern("includes"), None);
    }

    #[test]
    fn autosave_block_is_split_after_its_header() {
        let text = "[printer]\nmax_velocity: 1\n\n#*# <---------------------- SAVE_CONFIG ---------------------->\n#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n#*# [printer]\n#*# max_velocity = 2\n\n";
        let lines = split_lines(text);
        let file: Arc<Path> = Arc::from(Path::new("p.cfg"));
        let mut warnings = Vec::new();
        let (regular, block) = split_autosave(&lines, &file, &mut warnings);
        assert_eq!(regular.len(), 3);
        assert_eq!(block.len(), 3);
        assert!(warnings.is_empty());
    }
}
