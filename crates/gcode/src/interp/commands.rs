//! [`Commands`]: a reader's lines through the interpreter, the fast path first.

use std::io::BufRead;
use std::sync::Arc;

use super::fast::Made;
use super::state::{Interpreter, InterpreterOptions};
use crate::command::{Command, Spanned};
use crate::error::{GcodeError, Warning};
use crate::reader::Reader;

/// Reader + interpreter: the stream of commands of one input.
#[derive(Debug)]
pub struct Commands<R> {
    reader: Reader<R>,
    interpreter: Interpreter,
    source: Arc<str>,
    finished: bool,
    /// The command of the line the fast path took last, until [`Self::next_command`] hands it out
    /// (written in place: no copies of a large value through the reader).
    fast_command: Made,
    /// Plain moves, blank and comment-only lines take [`Interpreter::fast_line`] (off only in tests,
    /// to compare).
    pub(super) fast_lines: bool,
}

impl<R: BufRead> Commands<R> {
    pub fn new(reader: Reader<R>, options: InterpreterOptions) -> Self {
        let source = Arc::clone(reader.source());
        Commands {
            reader,
            interpreter: Interpreter::new(options),
            source,
            finished: false,
            fast_command: None,
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
                let (interpreter, made) = (&mut self.interpreter, &mut self.fast_command);
                let taken = self
                    .reader
                    .take_line_with(|bytes, number| interpreter.fast_line(bytes, number, made));
                if taken.is_some() {
                    match self.fast_command.take() {
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
