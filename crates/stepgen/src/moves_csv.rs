//! Reading a moves CSV file (`trapq::csv`'s format, plain or gzip as golden `moves.csv.gz`), with errors
//! naming the file.

use std::io::BufReader;
use std::path::Path;

use trapq::csv::ReadError;
use trapq::{Queue, TrapezoidMove};

use crate::error::FileError;
use crate::gzip::open_text;

/// Read every row of a moves file, in file order, as moves to step ([`trapq::csv::read_moves`]).
pub fn read_moves_csv(path: impl AsRef<Path>) -> Result<Vec<(Queue, TrapezoidMove)>, FileError> {
    let path = path.as_ref();
    let io = |source| FileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let input = open_text(path).map_err(io)?;
    trapq::csv::read_moves(BufReader::new(input)).map_err(|e| match e {
        ReadError::Io { source, .. } => io(source),
        ReadError::Parse {
            line,
            column,
            message,
        } => FileError::Parse {
            path: path.to_path_buf(),
            line,
            column,
            message,
        },
    })
}
