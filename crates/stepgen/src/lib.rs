//! stepgen: exact step times for every motor of a machine, from planned trapezoid pieces.
//!
//! Reproduces Klipper's step semantics (itersolve + stepcompress with step compression off): a step when the
//! ideal motor position crosses the half-step point around the commanded position, times rounded to MCU
//! clock ticks, and the step+dir+step filter. Closed forms are used where they exist (Cartesian axes and the
//! extruder, polar arm and bed), SCARA joints are solved one motor at a time from the arm's geometry, other
//! motors use a bracketed solver over [`kinematics::Kinematics`].
//!
//! Entry points: [`StepPipeline`] (a `trapq::MoveSink` for the planner), [`StepGenerator`] (all motors,
//! parallel over motors, chunks of pieces) or [`MotorStepper`] (one motor); steps go to a [`StepSink`] per
//! motor ([`StepFileWriter`], [`StepStats`], `Vec<Step>`, ...), deterministically whatever the thread count.
//!
//! A move passing exactly through the polar rotation centre is refused with
//! [`StepError::ThroughCentre`] (the bed angle is undefined there; Klipper fails too); passes any distance
//! away, however small, are solved exactly (bed steps may then share a clock tick).

mod audit;
mod error;
mod files;
mod filter;
mod general;
mod generator;
mod gzip;
mod motor;
mod moves_csv;
mod pipeline;
mod scara;
mod sink;
mod stats;
mod step_rule;
mod timing;
mod writer;

pub use audit::{ExpectedTravel, StepProblem, min_step_ticks, net_agrees};
pub use error::{FileError, MovesCsvError, StepError, StepFileError};
pub use files::{FileAndStats, finish_step_files, step_file_sinks};
pub use filter::StepFilter;
pub use generator::{ExtruderSpec, StepGenerator};
pub use motor::{MotorModel, MotorSpec, MotorStepper, StepGenConfig};
pub use moves_csv::read_moves_csv;
pub use pipeline::{ChunkSender, StepPipeline, run_in_parallel};
pub use sink::{CountSink, Step, StepSink, Tee};
pub use stats::{MotorStats, StepStats};
pub use step_rule::REVERSAL_MARGIN;
pub use writer::{StepFileWriter, read_step_file};
