//! G-code → G-code conversion for firmware without polar/SCARA kinematics, and centre correction of a
//! mis-centred polar bed.
//!
//! - [`Converter`]: streaming conversion of interpreted commands into motor-space lines with a bounded
//!   Cartesian chord error ([`Segmentation::Adaptive`]), Cartesian-time feed ([`FeedMode`]), slowed where a
//!   motor speed limit needs it ([`MotorLimit`], [`limits`]), exact extrusion
//!   ([`Extrusion`]) and unwrapped angles; [`convert_gcode`] drives it from G-code text.
//! - [`AxisMap`]: what the output axes are (two motors of a [`kinematics::Kinematics`], or corrected
//!   Cartesian XY); [`CentreCorrection`] builds the maps for an offset polar machine.
//! - [`verify`]: replays written G-code through forward kinematics and measures the deviation densely.
//!
//! ```
//! use std::sync::Arc;
//! use convert::{AxisMap, ConvertOptions, Converter, Target, convert_gcode, read_commands, verify};
//! use kinematics::{PolarParams, StepperParams, polar::Polar};
//!
//! let stepper = |name: &str| StepperParams { name: name.into(), step_distance: 0.01, position_min: None, position_max: None };
//! let polar = Polar::new(PolarParams {
//!     bed: stepper("stepper_bed"), arm: stepper("stepper_arm"), z: stepper("stepper_z"),
//!     arm_zero_offset: 0.0, arm_lateral_offset: 0.0,
//! }).unwrap();
//! let map = AxisMap::motors(Arc::new(polar), Target::Cylindrical).unwrap();
//! let options = ConvertOptions::default(); // X = radius, Y = bed angle in degrees, 0.005 mm
//! let input = b"G0 X-20 Y5 Z0.2\nG1 X20 Y5 E2 F1800\n";
//! let mut converter = Converter::new(map.clone(), options.clone(), Vec::new()).unwrap();
//! convert_gcode(&input[..], "part.gcode", &mut converter).unwrap();
//! let (output, stats) = converter.finish().unwrap();
//! assert!(stats.segments > 10); // the line passes 5 mm from the centre
//! let output = String::from_utf8(output).unwrap();
//! let report = verify(&map, &options, &read_commands(&input[..], "part.gcode").unwrap(), output.as_bytes()).unwrap();
//! assert!(report.max_deviation <= 0.005);
//! ```

pub mod axes;
pub mod bound;
pub mod converter;
pub mod correction;
pub mod error;
pub mod format;
pub mod limits;
pub mod options;
pub mod path;
pub mod segment;
pub mod verify;

use std::io::{BufRead, Write};
use std::sync::Arc;

pub use axes::AxisMap;
pub use converter::{ConvertStats, Converter, InputLine};
pub use correction::CentreCorrection;
pub use error::ConvertError;
pub use limits::AxisLimits;
pub use options::{
    AngleUnit, ConvertOptions, Decimals, Extrusion, FeedMode, Firmware, ModeState, MotorLimit,
    Segmentation, Target,
};
pub use verify::{SegmentDeviation, VerifyError, VerifyReport, verify, verify_segments};

use gcode::{Command, Commands, GcodeError, Interpreter, Reader, Spanned};

/// Converts the G-code text `input` (named `source` in errors) line by line into `converter`; returns the
/// reader's warnings (ignored parameters, lossy comments…), at most [`gcode::Warnings::MAX_KEPT`], and their
/// total.
pub fn convert_gcode<R: BufRead, W: Write>(
    input: R,
    source: &str,
    converter: &mut Converter<W>,
) -> Result<(Vec<gcode::Warning>, u64), ConvertError> {
    let mut reader = Reader::new(input, source);
    let source: Arc<str> = Arc::clone(reader.source());
    let home = converter.options().home;
    // The machine starts at its homing pose; without one the converter refuses what it would have to guess.
    let mut interpreter = Interpreter::new(gcode::InterpreterOptions {
        initial_position: home.map_or([0.0; 4], |h| [h[0], h[1], h[2], 0.0]),
        ..gcode::InterpreterOptions::default()
    });
    let mut commands: Vec<Spanned<Command>> = Vec::new();
    while let Some(line) = reader.next_line() {
        let line = line?;
        interpreter.interpret_line(&line, &source)?;
        commands.clear();
        while let Some(c) = interpreter.pop_command() {
            if let (Command::Home { axes }, Some(home)) = (&c.value, home) {
                // G28 leaves the homed axes at the homing pose.
                let all = !axes.iter().any(|&a| a);
                let mut position = interpreter.last_position();
                for i in 0..3 {
                    if all || axes[i] {
                        position[i] = home[i];
                    }
                }
                interpreter.set_position(position);
            }
            commands.push(c);
        }
        let input = InputLine {
            text: line.text(),
            command: line.command(),
            relative_axes: !interpreter.absolute_coordinates(),
        };
        converter.line(input, &commands)?;
    }
    // `finish` only releases slicer metadata, which writes nothing.
    interpreter.finish();
    let total = reader.warnings().total() + interpreter.warnings().total();
    let mut warnings = reader.warnings_mut().take();
    warnings.extend(interpreter.take_warnings());
    warnings.sort_by_key(|w| (w.span.line, w.span.column));
    Ok((warnings, total))
}

/// All commands of a G-code text, for [`verify`].
pub fn read_commands<R: BufRead>(input: R, source: &str) -> Result<Vec<Command>, GcodeError> {
    Commands::from_reader(input, source)
        .map(|c| c.map(|s| s.value))
        .collect()
}
