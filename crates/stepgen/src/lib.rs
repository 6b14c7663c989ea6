//! stepgen: exact step times for every motor of a machine, from planned trapezoid pieces.
//!
//! Reproduces Klipper's step semantics (itersolve + stepcompress with step compression off): a step when the
//! ideal motor position crosses the half-step point around the commanded position, times rounded to MCU
//! clock ticks, and the step+dir+step filter. Closed forms are used where they exist (Cartesian axes and the
//! extruder, polar arm and bed), SCARA joints are solved one motor at a time from the arm's geometry, other
//! motors use a bracketed solver over [`kinematics::Kinematics`].
//!
//! Entry points: [`run_in_parallel`] (what `printjob::run` uses: planning on the calling thread, every motor on a
//! thread of its own over shared chunks), [`StepPipeline`] (a `trapq::MoveSink` stepping all motors chunk by chunk on
//! the caller's thread and rayon's), [`StepGenerator`] (the simulator's replay and the benches: chunks of pieces) or
//! [`MotorStepper`] (one motor); steps go to a [`StepSink`] per motor ([`StepFileWriter`], [`StepStats`],
//! `Vec<Step>`, ...), deterministically whatever the thread count.
//!
//! A polar bed turning in place at the centre is a `Motion::BedTurn` piece; a line that misses the centre only by
//! rounding (`kinematics::RADIAL_ROUNDING`) is taken as radial, and one that crosses the centre is refused with
//! [`StepError::ThroughCentre`] (the planner never makes one: it cuts such passes at the centre). Every other pass,
//! however close, is solved exactly; the step audit (`StepStats::audited`) then says whether an MCU could run it.

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
