//! What a motor may do, and the caps a span of a move gets from it.

/// Limits of one motor, in its own units (mm or rad per second, per second²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorLimit {
    /// Index in the kinematics' motor order.
    pub motor: usize,
    pub max_velocity: Option<f64>,
    pub max_accel: Option<f64>,
}

/// A part of a move, from the previous span's end (or the move's start) to `end` (mm along the move), with its caps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub end: f64,
    pub max_speed: f64,
    pub max_accel: f64,
}

/// A corner changes every motor's speed at once (Klipper plans corners so). Judged over this many of the motor's
/// steps, as the step stream shows it, the jump must fit in the acceleration the moves on either side leave.
pub(super) const JUMP_WINDOW_STEPS: f64 = 16.0;

/// Whether corners are capped for these limits: some motor has an acceleration limit (see
/// [`super::junction_v2`]).
pub fn caps_corners(limits: &[MotorLimit]) -> bool {
    limits.iter().any(|l| l.max_accel.is_some())
}

/// Cruise-speed and acceleration caps for a motor whose rate and curvature along the span are at most
/// `(rate, curvature)`: half the acceleration budget goes to the curvature term at the capped speed.
pub(super) fn caps(
    limit: &MotorLimit,
    (rate, curvature): (f64, f64),
    speed: f64,
    accel: f64,
) -> (f64, f64) {
    let mut v = speed;
    let mut a = accel;
    if let Some(max_v) = limit.max_velocity
        && rate > 0.0
    {
        v = v.min(max_v / rate);
    }
    if let Some(max_a) = limit.max_accel {
        if curvature > 0.0 {
            v = v.min((0.5 * max_a / curvature).sqrt());
        }
        if rate > 0.0 {
            a = a.min((max_a - curvature * v * v) / rate);
        }
    }
    (v, a)
}
