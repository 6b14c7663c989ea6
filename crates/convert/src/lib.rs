//! G-code → G-code conversion for firmware without polar/SCARA kinematics, and centre correction of a
//! mis-centred polar bed.
//!
//! - [`Converter`]: streaming conversion of interpreted commands into motor-space lines with a bounded
//!   Cartesian chord error ([`Segmentation::Adaptive`]), Cartesian-time feed ([`FeedMode`]), exact extrusion
//!   ([`Extrusion`]) and unwrapped angles; [`convert_gcode`] drives it from G-code text.
//! - [`AxisMap`]: what the output axes are (two motors of a [`kinematics::Kinematics`], or corrected
//!   Cartesian XY); [`CentreCorrection`] builds the maps for an offset polar machine.
//! - [`verify`]: replays written G-code through forward kinematics and measures the deviation densely.

pub mod axes;
pub mod converter;
pub mod correction;
pub mod error;
pub mod format;
pub mod options;
pub mod path;
pub mod segment;
pub mod verify;

use std::io::{BufRead, Write};
use std::sync::Arc;

pub use axes::AxisMap;
pub use converter::{ConvertStats, Converter};
pub use correction::CentreCorrection;
pub use error::ConvertError;
pub use options::{AngleUnit, ConvertOptions, Decimals, Extrusion, FeedMode, Segmentation, Target};
pub use verify::{VerifyError, VerifyReport, verify};

use gcode::{Command, Commands, GcodeError, Interpreter, Reader, Spanned};

/// Converts the G-code text `input` (named `source` in errors) line by line into `converter`.
pub fn convert_gcode<R: BufRead, W: Write>(
    input: R,
    source: &str,
    converter: &mut Converter<W>,
) -> Result<(), ConvertError> {
    let mut reader = Reader::new(input, source);
    let source: Arc<str> = Arc::clone(reader.source());
    let mut interpreter = Interpreter::default();
    let mut commands: Vec<Spanned<Command>> = Vec::new();
    while let Some(line) = reader.next_line() {
        let line = line?;
        interpreter.interpret_line(&line, &source)?;
        commands.clear();
        while let Some(c) = interpreter.pop_command() {
            commands.push(c);
        }
        converter.line(line.text(), &commands)?;
    }
    // `finish` only releases slicer metadata, which writes nothing.
    interpreter.finish();
    Ok(())
}

/// All commands of a G-code text, for [`verify`].
pub fn read_commands<R: BufRead>(input: R, source: &str) -> Result<Vec<Command>, GcodeError> {
    Commands::from_reader(input, source)
        .map(|c| c.map(|s| s.value))
        .collect()
}
