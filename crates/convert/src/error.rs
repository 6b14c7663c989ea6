//! Errors of a conversion, carrying the input line and column where the input has them.

use gcode::command::Span;
use kinematics::ReachError;

#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    #[error("line {}:{}: {reason}", span.line, span.column)]
    Unreachable { span: Span, reason: ReachError },
    #[error("line {}:{}: {what} cannot be converted: {why}", span.line, span.column)]
    Unsupported {
        span: Span,
        what: String,
        why: String,
    },
    #[error(
        "line {}:{}: the chord error cannot be brought under {tolerance} mm near ({x:.4}, {y:.4})",
        span.line,
        span.column
    )]
    NoConvergence {
        span: Span,
        x: f64,
        y: f64,
        tolerance: f64,
    },
    #[error(
        "line {}:{}: {axis} is not known here: the input has not set it since the start or the last G28, and no \
         homed position was given (the config's `position_endstop` values); set it first (e.g. `G1 {axis}…`) \
         rather than have it guessed",
        span.line,
        span.column
    )]
    UnknownPosition { span: Span, axis: char },
    #[error("machine setup: {0}")]
    Setup(String),
    #[error("invalid options: {0}")]
    Options(String),
    #[error(transparent)]
    Gcode(#[from] gcode::GcodeError),
    #[error("writing output: {0}")]
    Io(#[from] std::io::Error),
}
