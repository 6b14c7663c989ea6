//! Klipper-style `printer.cfg` reader for jointspace.
//!
//! Two layers:
//! - [`ConfigDocument`]: the generic reader. Sections, `key: value` / `key = value`, `#`/`;` comments,
//!   indented multi-line values, `[include …]` (relative paths, globs, cycle detection) and the trailing
//!   `#*#` SAVE_CONFIG block, merged the way Klipper merges them. Every value keeps a [`Span`]
//!   (file, line, column, length, line text); typed accessors on [`Section`] report errors at the value
//!   and remember which keys were read.
//! - [`MachineConfig`]: the typed machine (kinematics parameters for the `kinematics` crate, printer
//!   limits, steppers, extruder, arcs) with Klipper's defaults.
//!
//! Units inside are mm, s and rad. Keys that take degrees in the file (SCARA `shoulder_zero`,
//! `elbow_zero`, `shoulder_min`/`shoulder_max`, `elbow_min`/`elbow_max`) are converted to radians.
//! Five-bar `left_zero`/`right_zero` too.
//! Rotary steppers (polar `stepper_bed`, SCARA `stepper_a`/`stepper_b`, five-bar `stepper_left`/`stepper_right`)
//! measure radians: their
//! `rotation_distance` is 2π and `gear_ratio` is required, as in Klipper.

mod document;
mod error;
mod fivebar;
mod machine;
mod parse;
mod span;
mod stepper;
mod value;

pub use document::{ConfigDocument, Entry, Section};
pub use error::{ConfigError, ConfigWarning};
pub use machine::{
    ArcConfig, ExtruderConfig, KinematicsKind, MachineConfig, PrinterLimits, UnusedKey,
};
pub use span::Span;
pub use stepper::{
    DEFAULT_STEP_PULSE_DURATION, HomingConfig, StepRateLimit, StepRateSource, StepperConfig,
    StepperUnits,
};
pub use value::{Bounds, Pin, Pull, parse_bool, parse_f64, parse_pin};
