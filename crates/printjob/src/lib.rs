//! A print job assembled in one place, between the libraries and the front-ends: a machine built from
//! `printer.cfg` ([`Machine`]), and a G-code stream planned ([`plan_gcode`]), checked for every problem
//! ([`check_gcode`], [`audit_file`]), estimated with its time broken down ([`estimate`]) or run to every motor's audited steps ([`run`]). Summaries, warnings and
//! problems come back as data and failures as typed errors; the front-ends (the CLI, the simulator, the fuzz
//! targets, the benches) render them. Cancellation is passed in.

pub mod audit;
mod check;
mod envelope;
mod estimate;

mod moves_file;
mod plan;
mod run;

pub use audit::StepStreamError;
pub use check::{CheckReport, Problem, Severity, audit_file, check_gcode};
pub use envelope::{ClosestApproach, Envelope, MotorTravel, SAMPLE_MM};
pub use estimate::{
    Estimate, EstimateError, LimitCost, Part, Reopen, SlowLine, estimate, estimate_watched,
};
pub use machine::{ConfigNote, LoadError, Machine, PlanOptions};
pub use moves_file::MovesFile;
pub use plan::{
    Observer, PipelineError, PlanSummary, plan_gcode, plan_gcode_observed, plan_gcode_watched,
};
pub use run::{MotorSummary, RunError, RunOptions, RunSummary, WarningLine, run};
