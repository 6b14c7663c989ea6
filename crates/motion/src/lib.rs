//! Motion planning with Klipper's semantics: moves from G-code commands, junction speeds, lookahead, and
//! trapezoid moves with print times handed to a [`trapq::MoveSink`].
//!
//! The arithmetic follows Klipper's toolhead closely enough that planned moves agree with Klipper's to
//! about 1e-15 relative (checked against `../shared/golden`). Kinematic checks use the whole segment.

pub mod arcs;
mod centre;
pub mod driver;
pub mod kinematic_limits;
pub mod limits;
pub mod lookahead;
pub mod machine;
pub mod toolhead;

pub use driver::{PlanError, PlanErrorKind, Planner, Warning};
pub use limits::{ExtruderLimits, Host, PlannerConfig, VelocityLimits};
pub use toolhead::{MoveError, SlowMove, SlowMoves, Toolhead};
