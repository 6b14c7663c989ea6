//! How a straight move meets a polar bed's rotation centre, where the bed angle is undefined.
//!
//! A path that comes within the kinematics' centre tolerance of the centre is planned through the centre
//! itself: its end points there are moved onto the centre exactly, and a move that passes by is cut there.
//! The nozzle leaves the G-code path by at most that tolerance (half an arm step, at most 5 µm). On the
//! centre the bed turns in place from the angle the toolhead arrived along to the angle it leaves along;
//! anywhere else the bed angle follows the position. A path that stays farther out is left to the motor
//! limits (`kinematic_limits`), which slow only the spans near the centre.

use crate::limits::CentreTurn;

/// Where a move `start → end` meets the centre (positions `[x, y, z, e]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Passage {
    /// It stays farther out than the tolerance.
    Away,
    /// Both ends lie within the tolerance: the toolhead stays on the centre (a Z or E move).
    Stays,
    /// It starts on the centre and leaves it.
    Leaves,
    /// It ends on the centre.
    Arrives,
    /// It passes the centre between its ends: the move's point nearest to it, with X/Y exactly on the centre.
    Through([f64; 4]),
}

/// How the move `start → end` meets the centre of `turn`.
pub(crate) fn passage(start: [f64; 4], end: [f64; 4], turn: &CentreTurn) -> Passage {
    let c = turn.centre;
    let tol2 = turn.tolerance * turn.tolerance;
    let near = |p: [f64; 4]| {
        let (x, y) = (p[0] - c[0], p[1] - c[1]);
        x * x + y * y <= tol2
    };
    match (near(start), near(end)) {
        (true, true) => return Passage::Stays,
        (true, false) => return Passage::Leaves,
        (false, true) => return Passage::Arrives,
        (false, false) => {}
    }
    let d = [end[0] - start[0], end[1] - start[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = -((start[0] - c[0]) * d[0] + (start[1] - c[1]) * d[1]) / len2;
    // Both ends are off the centre, so a closest point within the tolerance lies strictly between them.
    if !(t > 0.0 && t < 1.0) {
        return Passage::Away;
    }
    let closest = [start[0] + d[0] * t - c[0], start[1] + d[1] * t - c[1]];
    if closest[0] * closest[0] + closest[1] * closest[1] > tol2 {
        return Passage::Away;
    }
    Passage::Through([
        c[0],
        c[1],
        start[2] + (end[2] - start[2]) * t,
        start[3] + (end[3] - start[3]) * t,
    ])
}

/// `p` with X/Y moved onto the centre.
pub(crate) fn onto_centre(p: [f64; 4], turn: &CentreTurn) -> [f64; 4] {
    [turn.centre[0], turn.centre[1], p[2], p[3]]
}

/// The toolhead position `p` relative to the centre.
pub(crate) fn ray(p: [f64; 4], turn: &CentreTurn) -> [f64; 2] {
    [p[0] - turn.centre[0], p[1] - turn.centre[1]]
}

/// The bed angle (rad) at which the toolhead position `p` lies under the arm, or `None` on the centre.
pub(crate) fn bed_angle(p: [f64; 4], turn: &CentreTurn) -> Option<f64> {
    let [x, y] = ray(p, turn);
    (x != 0.0 || y != 0.0).then(|| y.atan2(x))
}

/// The turn (rad, in [−π, π]) that brings the bed from `from` to `to`.
pub(crate) fn turn_between(from: f64, to: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let turn = (to - from).rem_euclid(TAU);
    if turn > PI { turn - TAU } else { turn }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TURN: CentreTurn = CentreTurn {
        centre: [0.0, 0.0],
        tolerance: 0.005,
        max_velocity: 5.0,
        max_accel: 200.0,
    };

    #[test]
    fn a_move_meets_the_centre_by_where_it_comes_within_the_tolerance() {
        let p = |x: f64, y: f64| [x, y, 1.0, 0.0];
        assert_eq!(passage(p(10.0, 1.0), p(-10.0, 1.0), &TURN), Passage::Away);
        assert_eq!(passage(p(10.0, 0.0), p(20.0, 0.0), &TURN), Passage::Away);
        assert_eq!(passage(p(1e-15, 0.0), p(0.01, 1.0), &TURN), Passage::Leaves);
        assert_eq!(
            passage(p(0.01, 1.0), p(0.004, 0.0), &TURN),
            Passage::Arrives
        );
        assert_eq!(passage(p(0.001, 0.0), p(0.0, 0.002), &TURN), Passage::Stays);
        let through = passage([10.0, 0.004, 1.0, 0.0], [-10.0, 0.004, 3.0, 2.0], &TURN);
        assert_eq!(through, Passage::Through([0.0, 0.0, 2.0, 1.0]));
        assert_eq!(
            passage(p(10.0, 0.006), p(-10.0, 0.006), &TURN),
            Passage::Away
        );
    }

    #[test]
    fn the_bed_turns_the_short_way() {
        use std::f64::consts::PI;
        assert!((turn_between(0.1, -0.1) + 0.2).abs() < 1e-15);
        assert!((turn_between(3.0, -3.0) - (2.0 * PI - 6.0)).abs() < 1e-12);
        assert!((turn_between(0.0, PI) - PI).abs() < 1e-15);
        assert_eq!(bed_angle([0.0, 0.0, 5.0, 1.0], &TURN), None);
        assert_eq!(bed_angle([0.0, 2.0, 0.0, 0.0], &TURN), Some(PI / 2.0));
    }
}
