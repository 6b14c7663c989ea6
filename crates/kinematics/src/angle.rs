//! Angles that turn without end.

use std::f64::consts::{PI, TAU};

/// `angle` shifted by whole turns to lie within ±π of `previous`.
///
/// For `|angle − previous| ≤ π` the angle is returned untouched; one turn off gives exactly `angle ± 2π`,
/// the same arithmetic Klipper's polar bed uses, so step times stay bit-identical.
pub fn unwrap_near(angle: f64, previous: f64) -> f64 {
    let diff = angle - previous;
    if diff.abs() <= PI || !previous.is_finite() {
        return angle;
    }
    let turns = ((previous - angle) / TAU).round();
    angle + turns * TAU
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwrap_keeps_close_angles_and_adds_whole_turns() {
        assert_eq!(unwrap_near(3.0, 2.0), 3.0);
        assert_eq!(unwrap_near(-3.0, 3.0), -3.0 + TAU);
        let far = unwrap_near(0.1, 10.0 * TAU + 0.05);
        assert!((far - (10.0 * TAU + 0.1)).abs() < 1e-12);
    }
}
