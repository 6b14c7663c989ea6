//! Errors of a conversion, carrying the input line and column where the input has them.

use gcode::command::Span;
use kinematics::ReachError;

#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    #[error("line {}:{}: {}", span.line, span.column, self.message())]
    Unreachable { span: Span, reason: ReachError },
    #[error("line {}:{}: {}", span.line, span.column, self.message())]
    Unsupported {
        span: Span,
        what: String,
        why: String,
    },
    #[error("line {}:{}: {}", span.line, span.column, self.message())]
    NoConvergence {
        span: Span,
        x: f64,
        y: f64,
        tolerance: f64,
    },
    #[error("line {}:{}: {}", span.line, span.column, self.message())]
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

impl ConvertError {
    /// The input line and column the error is about, where it has one.
    pub fn place(&self) -> Option<Span> {
        match self {
            ConvertError::Unreachable { span, .. }
            | ConvertError::Unsupported { span, .. }
            | ConvertError::NoConvergence { span, .. }
            | ConvertError::UnknownPosition { span, .. } => Some(*span),
            ConvertError::Gcode(g) => Some(g.span),
            _ => None,
        }
    }

    /// What is wrong, without its place (a diagnostic shows the place itself).
    pub fn message(&self) -> String {
        match self {
            ConvertError::Unreachable { reason, .. } => reason.to_string(),
            ConvertError::Unsupported { what, why, .. } => {
                format!("{what} cannot be converted: {why}")
            }
            ConvertError::NoConvergence {
                x, y, tolerance, ..
            } => format!(
                "the chord error cannot be brought under {tolerance} mm near ({x:.4}, {y:.4})"
            ),
            ConvertError::UnknownPosition { axis, .. } => format!(
                "{axis} is not known here: the input has not set it since the start or the last G28, and no \
                 homed position was given (the config's `position_endstop` values); set it first (e.g. \
                 `G1 {axis}…`) rather than have it guessed"
            ),
            ConvertError::Gcode(g) => g.kind.to_string(),
            other => other.to_string(),
        }
    }
}
