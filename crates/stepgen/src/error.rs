//! Errors of step generation and of the file formats this crate reads and writes.

use std::path::PathBuf;

use kinematics::ReachError;

/// Why steps could not be generated for a motor.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The toolhead passes exactly through the polar rotation centre, where the bed angle is undefined
    /// (Klipper fails there too, with "Invalid sequence").
    #[error(
        "{motor}: the move at print time {time:.6} s passes through the rotation centre, where the bed angle is undefined"
    )]
    ThroughCentre { motor: String, time: f64 },
    /// The kinematics refused a pose along a move.
    #[error("{motor}: pose at print time {time:.6} s is not reachable: {source}")]
    Unreachable {
        motor: String,
        time: f64,
        #[source]
        source: ReachError,
    },
    /// A piece carries a non-finite or negative time, or non-finite positions or speeds.
    #[error("{motor}: invalid move piece at print time {time}: {reason}")]
    InvalidPiece {
        motor: String,
        time: f64,
        reason: &'static str,
    },
    /// A motor index, queue or count does not match the machine.
    #[error("configuration mismatch: {0}")]
    Config(String),
    /// A motor's sink could not take its steps (a step file on a full disk); the run stops there.
    #[error("{0}")]
    Output(String),
    /// The caller asked to stop.
    #[error("step generation was cancelled")]
    Cancelled,
    /// Moves arrived before any start pose was declared.
    #[error("moves arrived before the start pose was known (home or SET_KINEMATIC_POSITION first)")]
    NoStartPose,
}

/// Errors reading or writing a file this crate knows (step files, the moves CSV): an I/O error, or a place
/// in the file (1-based line and column) and what is wrong there.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The output could not be created or put in place (or it is an input of the run).
    #[error(transparent)]
    Output(#[from] outfile::OutputError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
}

/// Errors reading a golden `moves.csv(.gz)` file.
pub type MovesCsvError = FileError;

/// Errors reading or writing step files (`clock dir` per line).
pub type StepFileError = FileError;
