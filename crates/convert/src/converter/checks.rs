//! Checks on what the converter is given (options, feeds, magnitudes) and which input lines pass through.

use gcode::CommandWord;
use gcode::command::{Command, Span};

use crate::error::ConvertError;
use crate::options::{ConvertOptions, Segmentation};

pub(super) fn check_feed(span: Span, feed: f64) -> Result<(), ConvertError> {
    if feed.is_finite() && feed > 0.0 {
        Ok(())
    } else {
        Err(ConvertError::Unsupported {
            span,
            what: "a move".into(),
            why: format!("its feed rate {feed} mm/s is not positive"),
        })
    }
}

/// Largest |coordinate| or |E| (mm) accepted: far beyond any machine, well inside the integer units the output
/// is counted in, so nothing can overflow.
const MAX_MAGNITUDE: f64 = 1e9;

pub(super) fn check_magnitudes(span: Span, target: &[f64; 4]) -> Result<(), ConvertError> {
    for (value, name) in target.iter().zip(["X", "Y", "Z", "E"]) {
        if !value.is_finite() || value.abs() > MAX_MAGNITUDE {
            return Err(ConvertError::Unsupported {
                span,
                what: format!("{name} {value:e}"),
                why: format!("values beyond ±{MAX_MAGNITUDE:e} mm are out of range"),
            });
        }
    }
    Ok(())
}

pub(super) fn xyz(p: [f64; 4]) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

/// Commands written through as their raw line.
pub(super) fn passes_through(c: &Command) -> bool {
    match c {
        Command::Move(_)
        | Command::Arc(_)
        | Command::Home { .. }
        | Command::SetPosition { .. }
        | Command::SetKinematicPosition { .. }
        | Command::SpeedFactor(_)
        | Command::ExtrudeFactor(_) => false,
        Command::Other { name } => !is_mode_command(name),
        _ => true,
    }
}

/// The mode lines the interpreter consumes without a command (positioning, extrusion, units, arc plane):
/// never written live, since the output has modes of its own.
pub(super) fn is_consumed_mode(word: CommandWord) -> bool {
    matches!(
        word,
        CommandWord::Code {
            letter: b'G',
            major: 17..=21 | 90 | 91,
            minor: None,
        } | CommandWord::Code {
            letter: b'M',
            major: 82 | 83,
            minor: None,
        }
    )
}

/// Positioning-mode and unit commands the conversion consumes (the interpreter has applied them).
pub(super) fn is_mode_command(name: &str) -> bool {
    ["G90", "G91", "M82", "M83", "G20", "G21"]
        .iter()
        .any(|m| name.eq_ignore_ascii_case(m))
}

pub(super) fn validate(o: &ConvertOptions) -> Result<(), ConvertError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    match o.segmentation {
        Segmentation::Adaptive { tolerance } if !positive(tolerance) => {
            return Err(ConvertError::Options(
                "tolerance must be a positive number of mm".into(),
            ));
        }
        Segmentation::Fixed {
            segments_per_second,
            min_length,
        } if !positive(segments_per_second) || !positive(min_length) => {
            return Err(ConvertError::Options(
                "fixed segmentation needs positive rate and length".into(),
            ));
        }
        _ => {}
    }
    if !positive(o.flip_speed) {
        return Err(ConvertError::Options("flip speed must be positive".into()));
    }
    let d = o.decimals;
    if d.linear > 9 || d.angle > 9 || d.extrusion > 9 {
        return Err(ConvertError::Options("at most 9 decimals".into()));
    }
    if o.translate.iter().any(|v| !v.is_finite()) || !positive(o.scale_xy) {
        return Err(ConvertError::Options(
            "placement offset must be finite".into(),
        ));
    }
    Ok(())
}
