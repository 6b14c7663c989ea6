//! The parsed config: sections of `key: value` entries with spans, and which keys were read.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{ConfigError, ConfigWarning};
use crate::span::Span;

/// One `key: value` option, possibly spanning several lines.
#[derive(Debug)]
pub struct Entry {
    pub(crate) key: String,
    pub(crate) key_span: Span,
    /// Lines joined with `\n` (blank lines kept inside, trailing ones dropped), as Klipper does.
    pub(crate) value: String,
    /// Each non-blank value line: byte offset in `value` where it starts, and its span in the file.
    pub(crate) pieces: Vec<(usize, Span)>,
    /// Where an empty value would be (just after the `:`), used when `pieces` is empty.
    pub(crate) empty_value_span: Span,
    /// Set when any accessor looked the key up, to report unused (likely misspelt) keys.
    pub(crate) read: AtomicBool,
}

impl Clone for Entry {
    fn clone(&self) -> Self {
        Entry {
            key: self.key.clone(),
            key_span: self.key_span.clone(),
            value: self.value.clone(),
            pieces: self.pieces.clone(),
            empty_value_span: self.empty_value_span.clone(),
            read: AtomicBool::new(self.read.load(Ordering::Relaxed)),
        }
    }
}

impl Entry {
    /// The lower-cased key.
    pub fn key(&self) -> &str {
        &self.key
    }

    pub fn key_span(&self) -> &Span {
        &self.key_span
    }

    /// The raw value text (multi-line values joined with `\n`).
    pub fn value(&self) -> &str {
        &self.value
    }

    /// The span of the value's first non-blank line (or where the empty value sits).
    pub fn value_span(&self) -> &Span {
        self.pieces
            .first()
            .map_or(&self.empty_value_span, |(_, span)| span)
    }

    /// Whether some accessor has read this entry.
    pub fn was_read(&self) -> bool {
        self.read.load(Ordering::Relaxed)
    }

    /// Span of `byte_len` bytes of the value starting at `byte_start`, when they lie on one line.
    pub fn sub_span(&self, byte_start: usize, byte_len: usize) -> Span {
        let piece = self
            .pieces
            .iter()
            .rev()
            .find(|(start, _)| *start <= byte_start);
        let Some((start, span)) = piece else {
            return self.value_span().clone();
        };
        let before = self.value.get(*start..byte_start).unwrap_or_default();
        let part = self
            .value
            .get(byte_start..byte_start + byte_len)
            .unwrap_or_default();
        if before.contains('\n') || part.contains('\n') {
            return span.clone();
        }
        span.narrowed(before.chars().count(), part.chars().count())
    }
}

/// A `[section]` with its options. Duplicate sections in the input are merged into one.
#[derive(Debug, Clone)]
pub struct Section {
    pub(crate) name: String,
    /// `section_key(name)`, kept so lookups need not recompute it.
    pub(crate) key: (String, String),
    pub(crate) header: Span,
    pub(crate) entries: Vec<Entry>,
}

impl Section {
    /// The name as first written (e.g. `stepper_x`, `gcode_macro START_PRINT`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The first word of the name, lower-cased (e.g. `gcode_macro`).
    pub fn kind(&self) -> &str {
        &self.key.0
    }

    /// The text after the first word (e.g. `START_PRINT`), or "".
    pub fn argument(&self) -> &str {
        let trimmed = self.name.trim();
        trimmed
            .split_once(char::is_whitespace)
            .map_or("", |(_, rest)| rest.trim())
    }

    /// Span of the (first) `[section]` header.
    pub fn header_span(&self) -> &Span {
        &self.header
    }

    /// All entries, in the order first written.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Whether the key is present (does not count as reading it).
    pub fn contains(&self, key: &str) -> bool {
        self.find(key).is_some()
    }

    /// The entry for `key` (case-insensitive), marking it as read.
    pub fn entry(&self, key: &str) -> Option<&Entry> {
        let entry = self.find(key)?;
        entry.read.store(true, Ordering::Relaxed);
        Some(entry)
    }

    /// Marks a key as used without interpreting it (a key another module of the printer reads).
    pub fn mark_read(&self, key: &str) {
        let _ = self.entry(key);
    }

    /// Entries no accessor has read (candidates for "unknown option" warnings).
    pub fn unused_entries(&self) -> impl Iterator<Item = &Entry> {
        self.entries.iter().filter(|e| !e.was_read())
    }

    fn find(&self, key: &str) -> Option<&Entry> {
        let key = key.to_lowercase();
        self.entries.iter().find(|e| e.key == key)
    }

    /// Adds or replaces (later wins, as in Klipper) an entry; returns its index.
    pub(crate) fn set(&mut self, entry: Entry) -> usize {
        match self.entries.iter().position(|e| e.key == entry.key) {
            Some(index) => {
                self.entries[index] = entry;
                index
            }
            None => {
                self.entries.push(entry);
                self.entries.len() - 1
            }
        }
    }
}

/// Normalised identity of a section name: first word lower-cased, rest trimmed as written.
pub(crate) fn section_key(name: &str) -> (String, String) {
    let trimmed = name.trim();
    match trimmed.split_once(char::is_whitespace) {
        Some((first, rest)) => (first.to_lowercase(), rest.trim().to_string()),
        None => (trimmed.to_lowercase(), String::new()),
    }
}

/// A whole config: the main file, its includes and its `SAVE_CONFIG` block, merged like Klipper does.
/// Made by the parser (`ConfigDocument::load`, `ConfigDocument::from_str` in `parse.rs`).
#[derive(Debug, Clone)]
pub struct ConfigDocument {
    pub(crate) path: PathBuf,
    pub(crate) sections: Vec<Section>,
    pub(crate) files: Vec<PathBuf>,
    pub(crate) warnings: Vec<ConfigWarning>,
}

impl ConfigDocument {
    /// The main file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every file read, main file first, then includes in reading order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// Non-fatal findings while reading (e.g. an ignored, damaged `SAVE_CONFIG` block).
    pub fn warnings(&self) -> &[ConfigWarning] {
        &self.warnings
    }

    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// The section named `name` (first word compared case-insensitively).
    pub fn section(&self, name: &str) -> Option<&Section> {
        let key = section_key(name);
        self.sections.iter().find(|s| s.key == key)
    }

    /// Sections whose first word is `kind` (e.g. all `gcode_macro …`).
    pub fn sections_of_kind<'a>(&'a self, kind: &'a str) -> impl Iterator<Item = &'a Section> {
        let kind = kind.to_lowercase();
        self.sections.iter().filter(move |s| s.kind() == kind)
    }

    /// The section named `name`, or an error saying why it is needed.
    pub fn require_section(&self, name: &str, reason: &str) -> Result<&Section, ConfigError> {
        self.section(name)
            .ok_or_else(|| ConfigError::MissingSection {
                path: self.path.clone(),
                section: name.to_string(),
                reason: reason.to_string(),
            })
    }
}
