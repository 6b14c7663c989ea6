//! Motor speed and acceleration limits along a straight move (beyond Klipper).
//!
//! A polar bed turns at `v·d/ρ²` near its centre and a SCARA joint speeds up near singular poses, so a Cartesian
//! speed that is fine elsewhere asks too much of a motor there. Klipper either ignores this or slows the whole
//! move. Here a move is cut into collinear spans, each with its own cruise-speed and acceleration cap, derived
//! from bounds on the motor's rate `q'(s) = dq/ds` and curvature `q''(s)` over the span:
//! motor speed `q'·v ≤ V` and motor acceleration `|q''|·v² + |q'|·|a| ≤ A`. The path is unchanged, and the
//! lookahead sees ordinary moves meeting at straight (full-speed) junctions.

mod junction;
mod limit;
mod profile;
mod rest;
mod spans;

pub use junction::{JunctionSide, junction_v2};
pub use limit::{MotorLimit, Span, caps_corners};
pub use spans::split;
