//! sim: the virtual printer. A machine as built (true geometry + motor model) executes the step streams
//! jointspace generates for the machine as believed; the reconstructed nozzle path is compared with the
//! intended one (metrics, features, pictures), and the calibrations are closed-loop tested on it.

pub mod hall;

pub mod correction;
pub mod crosses;
pub mod error;
pub mod features;
pub mod machine;
pub mod metrics;
pub mod motor;
pub mod replay;
pub mod report;
pub mod scan;
pub mod scenario;
pub mod simulation;
pub mod testprint;

pub use error::SimulationError;
pub use machine::{Machine, motor_model_from_config};
pub use motor::MotorError;
pub use replay::{Replay, ReplayOptions, replay};
pub use report::{Report, RunReport, write_report};
pub use scenario::{ClosedLoop, Simulation, closed_loop, simulate};
