//! The speed at a corner, where every motor's speed jumps.

use kinematics::{Kinematics, Vec3};

use super::limit::{JUMP_WINDOW_STEPS, MotorLimit, caps_corners};
use super::profile::{GENERAL_SPAN_MM, Line, Profile};

/// One side of a junction: a straight move and the acceleration it is planned with.
#[derive(Debug, Clone, Copy)]
pub struct JunctionSide {
    pub start: Vec3,
    pub end: Vec3,
    pub accel: f64,
}

/// Cap on the junction speed² from `incoming` into `outgoing` (which starts where `incoming` ends): each motor
/// with an acceleration limit `A` changes its speed there by `jump·v` (`jump` = the change of `q'` between the
/// moves), which over its steps reads as `jump·q'·v²/(W·step)`; with the moves' own `|q''|·v² + |q'|·a` it must
/// stay within `A`. Infinite where no such motor's speed jumps.
pub fn junction_v2(
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
    incoming: JunctionSide,
    outgoing: JunctionSide,
) -> f64 {
    if !caps_corners(limits) {
        return f64::INFINITY;
    }
    let lines = (
        Line::new(incoming.start, incoming.end),
        Line::new(outgoing.start, outgoing.end),
    );
    let (Some(line_in), Some(line_out)) = lines else {
        return f64::INFINITY;
    };
    let mut rows = vec![[0.0; 3]; kin.motors().len()];
    if kin.jacobian(incoming.end, &mut rows).is_err() {
        // The centre or a singular pose: the planner brings the toolhead to rest there.
        return f64::INFINITY;
    }
    let turn = [0, 1, 2].map(|k| line_out.dir[k] - line_in.dir[k]);
    let mut cap = f64::INFINITY;
    for limit in limits {
        let Some(max_accel) = limit.max_accel else {
            continue;
        };
        let row = rows[limit.motor];
        let jump = (row[0] * turn[0] + row[1] * turn[1] + row[2] * turn[2]).abs();
        if jump == 0.0 {
            continue;
        }
        let (rate_in, curvature_in) = rates_at(kin, limit.motor, &line_in, line_in.length);
        let (rate_out, curvature_out) = rates_at(kin, limit.motor, &line_out, 0.0);
        let spare = max_accel - (rate_in * incoming.accel).max(rate_out * outgoing.accel);
        if spare <= 0.0 {
            return 0.0;
        }
        let window = JUMP_WINDOW_STEPS * kin.motors()[limit.motor].step_distance;
        let per_v2 = curvature_in.max(curvature_out) + jump * rate_in.max(rate_out) / window;
        cap = cap.min(spare / per_v2);
    }
    cap
}

/// |q'| and |q''| of `motor` at `s` along the line (closed forms at the point; sampled motors over the span
/// length they are capped on).
fn rates_at(kin: &dyn Kinematics, motor: usize, line: &Line, s: f64) -> (f64, f64) {
    let profile = Profile::new(kin, motor, line);
    if let Profile::General { .. } = profile {
        let half = 0.5 * GENERAL_SPAN_MM.min(line.length);
        let s0 = (s - half).max(0.0);
        return profile.bounds(kin, line, s0, (s0 + 2.0 * half).min(line.length));
    }
    profile.bounds(kin, line, s, s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::polar::Polar;
    use kinematics::{PolarParams, StepperParams};
    use std::f64::consts::TAU;

    const BED_STEP: f64 = TAU / 16000.0;

    fn polar() -> Polar {
        let stepper = |name: &str, step: f64| StepperParams {
            name: name.into(),
            step_distance: step,
            position_min: None,
            position_max: Some(300.0),
        };
        Polar::new(PolarParams {
            bed: stepper("stepper_bed", BED_STEP),
            arm: stepper("stepper_arm", 1.0 / 80.0),
            z: stepper("stepper_z", 0.0025),
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
        })
        .expect("valid params")
    }

    fn bed(max_accel: Option<f64>) -> [MotorLimit; 1] {
        [MotorLimit {
            motor: 0,
            max_velocity: Some(5.0),
            max_accel,
        }]
    }

    fn side(start: Vec3, end: Vec3, accel: f64) -> JunctionSide {
        JunctionSide { start, end, accel }
    }

    #[test]
    fn a_corner_beside_the_centre_caps_the_jump_of_the_beds_speed() {
        // Across the centre's side at (0, 1): the bed turns at 1 rad/mm there (q'' = 0 at the closest approach);
        // then straight out: 0 rad/mm. The jump of 1 rad/mm takes the budget the incoming move leaves:
        // v² ≤ (200 − 1 · 100) / (1 · 1 / (16 steps)).
        let cap = junction_v2(
            &polar(),
            &bed(Some(200.0)),
            side([-1.0, 1.0, 0.0], [0.0, 1.0, 0.0], 100.0),
            side([0.0, 1.0, 0.0], [0.0, 3.0, 0.0], 3000.0),
        );
        let expected = 100.0 * 16.0 * BED_STEP;
        assert!((cap - expected).abs() < 1e-12 * expected, "{cap}");
        // An incoming move that already uses the whole budget leaves none: the toolhead stops at the corner.
        let cap = junction_v2(
            &polar(),
            &bed(Some(200.0)),
            side([-1.0, 1.0, 0.0], [0.0, 1.0, 0.0], 200.0),
            side([0.0, 1.0, 0.0], [0.0, 3.0, 0.0], 3000.0),
        );
        assert_eq!(cap, 0.0);
    }

    #[test]
    fn no_cap_where_no_limited_motor_jumps() {
        let straight = [
            side([-1.0, 1.0, 0.0], [0.0, 1.0, 0.0], 100.0),
            side([0.0, 1.0, 0.0], [1.0, 1.0, 0.0], 100.0),
        ];
        let corner = [
            side([-1.0, 1.0, 0.0], [0.0, 1.0, 0.0], 100.0),
            side([0.0, 1.0, 0.0], [0.0, 3.0, 0.0], 100.0),
        ];
        let kin = polar();
        assert_eq!(
            junction_v2(&kin, &bed(Some(200.0)), straight[0], straight[1]),
            f64::INFINITY
        );
        // Without an acceleration limit the speeds on either side are capped by the spans alone.
        assert_eq!(
            junction_v2(&kin, &bed(None), corner[0], corner[1]),
            f64::INFINITY
        );
    }
}
