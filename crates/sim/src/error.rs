//! Errors of the virtual printer: bad machine descriptions, planning and step-generation failures, poses the
//! true machine cannot take, calibration failures and output problems.

use kinematics::ReachError;

/// Why a simulation could not run or finish.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    #[error("invalid simulated machine: {0}")]
    Machine(String),
    #[error(transparent)]
    Config(#[from] config::ConfigError),
    #[error("believed machine: {0}")]
    Setup(#[from] ::machine::SetupError),
    #[error(transparent)]
    Plan(#[from] printjob::PipelineError),
    #[error("step generation: {0}")]
    Steps(#[from] stepgen::StepError),
    #[error("the true machine has no pose for the motor positions at t = {time:.4} s: {source}")]
    Forward {
        time: f64,
        #[source]
        source: ReachError,
    },
    #[error("calibration on the simulated machine failed: {0}")]
    Calibration(String),
    #[error("cannot write {path}: {message}")]
    Output { path: String, message: String },
    #[error("plot: {0}")]
    Plot(#[from] plot::PlotError),
}
