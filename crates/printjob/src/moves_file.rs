//! The moves CSV of a run: written to a temporary file and renamed into place when complete (never over an
//! input), or to standard output for `-`.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use outfile::{OutputError, PendingFile, write_error};
use trapq::SinkError;
use trapq::csv::CsvSink;

type Output = BufWriter<Box<dyn Write + Send>>;

/// A [`trapq::MoveSink`] writing the planned moves as CSV.
pub struct MovesFile {
    sink: CsvSink<Output>,
    /// The file being written; `None` for standard output.
    pending: Option<PendingFile>,
    path: PathBuf,
}

impl std::fmt::Debug for MovesFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MovesFile")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl MovesFile {
    pub fn create(path: &Path) -> Result<MovesFile, OutputError> {
        let (out, pending): (Box<dyn Write + Send>, _) = if outfile::is_stdio(path) {
            (Box::new(std::io::stdout()), None)
        } else {
            let pending = PendingFile::create(path)?;
            (Box::new(pending.reopen()?), Some(pending))
        };
        Ok(MovesFile {
            sink: CsvSink::new(BufWriter::new(out)),
            pending,
            path: path.to_path_buf(),
        })
    }

    /// Flush the moves and rename the file into place.
    pub fn finish(self) -> Result<(), OutputError> {
        let fail = |e| write_error(&self.path, e);
        let writer = self.sink.finish().map_err(fail)?;
        let mut out = writer.into_inner().map_err(|e| fail(e.into_error()))?;
        out.flush().map_err(fail)?;
        match self.pending {
            Some(pending) => pending.commit(),
            None => Ok(()),
        }
    }
}

impl trapq::MoveSink for MovesFile {
    /// A write error names the file and stops the run.
    fn append(&mut self, queue: trapq::Queue, mv: &trapq::TrapezoidMove) -> Result<(), SinkError> {
        self.sink
            .append(queue, mv)
            .map_err(|e| SinkError::new(format!("cannot write {}: {e}", self.path.display())))
    }
}
