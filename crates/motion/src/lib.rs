//! Motion planning with Klipper's semantics: moves from G-code commands, junction speeds, lookahead, and
//! trapezoid moves with print times handed to a [`trapq::MoveSink`].
//!
//! The arithmetic follows Klipper's toolhead operation for operation, so planned moves are the same doubles as
//! Klipper's (every golden case of `../shared/golden`, compared bit for bit). Kinematic checks use the whole
//! segment. The machine a planner plans for is built by the `machine` crate.

pub mod arcs;
mod centre;
pub mod driver;
pub mod kinematic_limits;
pub mod limits;
pub mod lookahead;
pub mod toolhead;

pub use driver::{PlanError, PlanErrorKind, Planner, Warning};
pub use limits::{ExtruderLimits, Host, PlannerConfig, VelocityLimits};
pub use toolhead::{MoveError, SlowMove, SlowMoves, Toolhead};
