//! Step files in the golden format: one line `clock dir` per step (dir 1 = position increases), plain text or
//! gzip when the name ends in `.gz`. Written to a temporary file beside the target and renamed into place on
//! [`StepFileWriter::finish`], so a failed run leaves no half-written file. Also reads such files back.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use flate2::Compression;
use flate2::write::GzEncoder;
use outfile::PendingFile;

use crate::error::StepFileError;
use crate::gzip::{is_gzip, open_text};
use crate::sink::{Step, StepSink};

enum Output {
    Plain(BufWriter<File>),
    Gzip(GzEncoder<BufWriter<File>>),
}

/// A [`StepSink`] writing one motor's steps to a file. I/O errors are kept and reported by `finish`.
pub struct StepFileWriter {
    path: PathBuf,
    /// The file as it is written; it appears at `path` when finished ([`outfile`]: never over an input).
    pending: Option<PendingFile>,
    out: Option<Output>,
    error: Option<std::io::Error>,
    line: Vec<u8>,
}

impl std::fmt::Debug for StepFileWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StepFileWriter")
            .field("path", &self.path)
            .finish()
    }
}

impl StepFileWriter {
    /// Start writing `path` (gzip if it ends in `.gz`).
    pub fn create(path: impl AsRef<Path>) -> Result<Self, StepFileError> {
        let path = path.as_ref().to_path_buf();
        let pending = PendingFile::create(&path)?;
        let buffered = BufWriter::with_capacity(1 << 16, pending.reopen()?);
        let out = if is_gzip(&path) {
            Output::Gzip(GzEncoder::new(buffered, Compression::default()))
        } else {
            Output::Plain(buffered)
        };
        Ok(StepFileWriter {
            path,
            pending: Some(pending),
            out: Some(out),
            error: None,
            line: Vec::with_capacity(32),
        })
    }

    /// Flush, close and put the file in place.
    pub fn finish(mut self) -> Result<PathBuf, StepFileError> {
        let io = |source| StepFileError::Io {
            path: self.path.clone(),
            source,
        };
        if let Some(e) = self.error.take() {
            return Err(io(e));
        }
        let buffered = match self.out.take() {
            Some(Output::Plain(b)) => b,
            Some(Output::Gzip(g)) => g.finish().map_err(io)?,
            None => return Err(io(std::io::Error::other("writer already finished"))),
        };
        drop(buffered.into_inner().map_err(|e| io(e.into_error()))?);
        if let Some(pending) = self.pending.take() {
            pending.commit()?;
        }
        Ok(self.path)
    }

    fn write_line(&mut self, clock: u64, dir: bool) -> std::io::Result<()> {
        self.line.clear();
        writeln!(self.line, "{} {}", clock, u8::from(dir))?;
        match &mut self.out {
            Some(Output::Plain(w)) => w.write_all(&self.line),
            Some(Output::Gzip(w)) => w.write_all(&self.line),
            None => Ok(()),
        }
    }
}

impl StepSink for StepFileWriter {
    fn step(&mut self, clock: u64, dir: bool) {
        if self.error.is_none()
            && let Err(e) = self.write_line(clock, dir)
        {
            self.error = Some(e);
        }
    }

    /// A write error, named with the file (the writer keeps nothing after it: [`StepFileWriter::finish`] fails).
    fn failure(&self) -> Option<String> {
        let e = self.error.as_ref()?;
        Some(format!("cannot write {}: {e}", self.path.display()))
    }
}

/// Read a step file (`clock dir` per line; gzip if the name ends in `.gz`).
pub fn read_step_file(path: impl AsRef<Path>) -> Result<Vec<Step>, StepFileError> {
    let path = path.as_ref();
    let io = |source| StepFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let reader = open_text(path).map_err(io)?;
    let mut steps = Vec::new();
    for (index, line) in BufReader::with_capacity(1 << 16, reader)
        .lines()
        .enumerate()
    {
        let line = line.map_err(io)?;
        if line.trim().is_empty() {
            continue;
        }
        steps.push(
            parse_step_line(&line).map_err(|(column, message)| StepFileError::Parse {
                path: path.to_path_buf(),
                line: index + 1,
                column,
                message,
            })?,
        );
    }
    Ok(steps)
}

fn parse_step_line(line: &str) -> Result<Step, (usize, String)> {
    let mut fields = line.split_ascii_whitespace();
    let clock_text = fields.next().ok_or((1, "empty line".to_string()))?;
    let clock = clock_text
        .parse::<u64>()
        .map_err(|e| (1, format!("bad clock {clock_text:?}: {e}")))?;
    let dir_column = line
        .find(clock_text)
        .map_or(1, |p| p + clock_text.len() + 2);
    let dir = match fields.next() {
        Some("1") => true,
        Some("0") => false,
        other => {
            return Err((
                dir_column,
                format!("direction must be 0 or 1, found {other:?}"),
            ));
        }
    };
    if let Some(extra) = fields.next() {
        return Err((dir_column + 2, format!("unexpected field {extra:?}")));
    }
    Ok(Step { clock, dir })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_plain_and_gzip() {
        let dir = tempfile::tempdir().expect("temp dir");
        for name in ["m.txt", "m.txt.gz"] {
            let path = dir.path().join(name);
            let mut w = StepFileWriter::create(&path).expect("create");
            w.step(4_000_000, true);
            w.step(4_000_100, false);
            w.finish().expect("finish");
            let back = read_step_file(&path).expect("read");
            assert_eq!(
                back,
                vec![
                    Step {
                        clock: 4_000_000,
                        dir: true
                    },
                    Step {
                        clock: 4_000_100,
                        dir: false
                    }
                ]
            );
        }
        let text = std::fs::read_to_string(dir.path().join("m.txt")).expect("read text");
        assert_eq!(text, "4000000 1\n4000100 0\n");
    }

    #[test]
    fn bad_lines_report_position() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("bad.txt");
        std::fs::write(&path, "1 1\n2 x\n").expect("write");
        match read_step_file(&path) {
            Err(StepFileError::Parse { line, column, .. }) => assert_eq!((line, column), (2, 3)),
            other => panic!("expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn unfinished_writer_leaves_no_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("never.txt");
        let mut w = StepFileWriter::create(&path).expect("create");
        w.step(1, true);
        drop(w);
        assert!(!path.exists());
    }
}
