//! The one place a machine is built. `printer.cfg` (a file, or the sections' text) → [`Machine`]: the
//! configuration as read, its warnings and unknown keys as [`ConfigNote`]s, and the [`MachineSetup`] every
//! front-end plans with (kinematics, planner limits and the motor limits along a move, the homing pose). The CLI,
//! the simulator, the Klipper plug-in, the fuzz targets and the benches all get their machine here, so one
//! printer.cfg means one machine everywhere.

mod load;
mod setup;

pub use load::{ConfigNote, LoadError, Machine, PlanOptions};
pub use setup::{MachineSetup, SetupError};
