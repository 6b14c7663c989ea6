//! Integration tests of the planner: Klipper's own planned moves on real G-code (`../shared/golden`).

mod centre;
mod golden;
mod limits;
mod scara_poses;
