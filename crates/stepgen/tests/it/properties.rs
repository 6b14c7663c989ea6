//! Property tests: monotonic clocks, net steps of monotonic moves, no failure on ordinary random moves.

use proptest::prelude::*;
use stepgen::{Step, StepGenConfig, StepGenerator};
use trapq::{Queue, TrapezoidMove};

use crate::machines;

/// A trapezoid move from `start` to `end` with the given speeds (accelerate, cruise, decelerate to `end_v`).
fn trapezoid(
    print_time: f64,
    start: [f64; 3],
    end: [f64; 3],
    v0: f64,
    cruise: f64,
    accel: f64,
) -> TrapezoidMove {
    let d = [end[0] - start[0], end[1] - start[1], end[2] - start[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let axes_r = [d[0] / len, d[1] / len, d[2] / len];
    // Peak speed limited by the length: accelerate from v0 and decelerate to 0 within `len`.
    let peak = cruise
        .min(((2.0 * accel * len + v0 * v0) / 2.0).sqrt())
        .max(v0);
    let accel_t = (peak - v0) / accel;
    let decel_t = peak / accel;
    let accel_d = (v0 + peak) * 0.5 * accel_t;
    let decel_d = peak * 0.5 * decel_t;
    let cruise_t = ((len - accel_d - decel_d) / peak).max(0.0);
    TrapezoidMove {
        print_time,
        accel_t,
        cruise_t,
        decel_t,
        start_pos: start,
        axes_r,
        start_v: v0,
        cruise_v: peak,
        accel,
        motion: trapq::Motion::Travel,
    }
}

fn generate(
    kin: &dyn kinematics::Kinematics,
    start: [f64; 3],
    moves: &[TrapezoidMove],
) -> Vec<Vec<Step>> {
    let mut generator =
        StepGenerator::new(kin, start, None, StepGenConfig::default()).expect("generator");
    let mut sinks = vec![Vec::new(); generator.motor_count()];
    generator
        .run_moves(moves.iter().map(|m| (Queue::Toolhead, *m)), 16, &mut sinks)
        .expect("steps for an ordinary move");
    sinks
}

fn net(steps: &[Step]) -> i64 {
    steps.iter().map(|s| if s.dir { 1 } else { -1 }).sum()
}

fn monotonic(steps: &[Step]) -> bool {
    steps.windows(2).all(|w| w[0].clock <= w[1].clock)
}

fn point_strategy() -> impl Strategy<Value = [f64; 3]> {
    (-150.0..150.0f64, -150.0..150.0f64, 0.0..10.0f64).prop_map(|(x, y, z)| [x, y, z])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn cartesian_net_steps_match_the_displacement(
        start in point_strategy(),
        end in point_strategy(),
        v0 in 0.0..20.0f64,
        cruise in 20.0..300.0f64,
        accel in 500.0..5000.0f64,
    ) {
        prop_assume!((0..3).map(|i| (end[i] - start[i]).powi(2)).sum::<f64>() > 1e-6);
        let kin = machines::cartesian(0.0125, 0.0125, 0.0025);
        let steps = generate(kin.as_ref(), start, &[trapezoid(0.5, start, end, v0, cruise, accel)]);
        let mv = trapezoid(0.5, start, end, v0, cruise, accel);
        // Where the move really ends (the trapezoid's distance, not `end`, is what the motors follow).
        let last = mv.pieces().last().map(|p| p.position(p.duration)).unwrap_or(start);
        for (axis, step) in [0.0125, 0.0125, 0.0025].into_iter().enumerate() {
            prop_assert!(monotonic(&steps[axis]));
            let expected = ((last[axis] - start[axis]) / step).round() as i64;
            prop_assert_eq!(net(&steps[axis]), expected, "axis {}", axis);
            // One direction only on a straight move.
            prop_assert!(steps[axis].iter().all(|s| s.dir == (expected > 0)));
        }
    }

    #[test]
    fn polar_bed_and_arm_follow_the_line(
        start in point_strategy(),
        end in point_strategy(),
        cruise in 20.0..300.0f64,
    ) {
        // Keep the line away from the centre (closest approach ≥ 1 mm).
        let (d, p) = ([end[0] - start[0], end[1] - start[1]], [start[0], start[1]]);
        let len2 = d[0] * d[0] + d[1] * d[1];
        prop_assume!(len2 > 1e-4);
        let t = (-(p[0] * d[0] + p[1] * d[1]) / len2).clamp(0.0, 1.0);
        prop_assume!((p[0] + t * d[0]).hypot(p[1] + t * d[1]) >= 1.0);
        let bed_step = std::f64::consts::TAU / 16000.0;
        let kin = machines::polar(bed_step, 0.0125, 0.0025);
        let mv = trapezoid(0.5, start, end, 0.0, cruise, 3000.0);
        let last = mv.pieces().last().map(|p| p.position(p.duration)).unwrap_or(start);
        let steps = generate(kin.as_ref(), start, &[mv]);
        prop_assert!(steps.iter().all(|m| monotonic(m)));
        // The bed angle is monotonic along a line: net = swept angle / step.
        let sweep = (start[0] * last[1] - start[1] * last[0]).atan2(start[0] * last[0] + start[1] * last[1]);
        prop_assert_eq!(net(&steps[0]), (sweep / bed_step).round() as i64);
        let arm = (last[0].hypot(last[1]) - start[0].hypot(start[1])) / 0.0125;
        prop_assert_eq!(net(&steps[1]), arm.round() as i64);
    }

    #[test]
    fn chains_of_moves_give_monotonic_clocks(
        points in prop::collection::vec(point_strategy(), 2..8),
        cruise in 20.0..200.0f64,
    ) {
        let mut moves = Vec::new();
        let mut time = 0.25;
        for pair in points.windows(2) {
            let len2: f64 = (0..3).map(|i| (pair[1][i] - pair[0][i]).powi(2)).sum();
            if len2 < 1e-6 {
                continue;
            }
            let mv = trapezoid(time, pair[0], pair[1], 0.0, cruise, 2000.0);
            time += mv.duration();
            moves.push(mv);
        }
        prop_assume!(!moves.is_empty());
        let start = moves[0].start_pos;
        for kin in [machines::cartesian(0.0125, 0.0125, 0.0025)] {
            let steps = generate(kin.as_ref(), start, &moves);
            for motor in &steps {
                prop_assert!(monotonic(motor));
                prop_assert!(motor.iter().all(|s| s.clock <= (time * 16e6).ceil() as u64));
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// No NaN can hide in a clock (it would turn into 0): every step of a move lies inside the move's time,
    /// even for lines passing within a micrometre of the polar centre.
    #[test]
    fn polar_clocks_stay_inside_the_move(
        start in point_strategy(),
        angle in 0.0..std::f64::consts::TAU,
        miss in prop_oneof![1e-6..1e-3f64, 1e-3..50.0f64],
        cruise in 5.0..300.0f64,
    ) {
        // A line passing `miss` mm from the centre, from `start` through the closest point and beyond.
        let r = start[0].hypot(start[1]);
        prop_assume!(r > 2.0 * miss + 1.0);
        let near = [miss * angle.cos(), miss * angle.sin()];
        let end = [2.0 * near[0] - start[0], 2.0 * near[1] - start[1], start[2]];
        let kin = machines::polar(std::f64::consts::TAU / 16000.0, 0.0125, 0.0025);
        let mv = trapezoid(0.5, start, end, 0.0, cruise, 3000.0);
        let mut generator = StepGenerator::new(kin.as_ref(), start, None, StepGenConfig::default()).expect("generator");
        let mut sinks = vec![Vec::new(); generator.motor_count()];
        match generator.run_moves([(Queue::Toolhead, mv)], 16, &mut sinks) {
            Ok(()) => {
                let (first, last) = ((0.5 * 16e6) as u64, ((0.5 + mv.duration()) * 16e6).ceil() as u64);
                for motor in &sinks {
                    prop_assert!(monotonic(motor));
                    prop_assert!(motor.iter().all(|s| s.clock >= first && s.clock <= last));
                }
            }
            // Only an exact pass through the centre may be refused.
            Err(e) => prop_assert!(matches!(e, stepgen::StepError::ThroughCentre { .. }), "{e}"),
        }
    }
}

/// For each general motor: every step brackets the crossing of its level within half a tick (evaluated
/// straight from the kinematics, through `Piece::position` at absolute times rather than the solver's
/// distance parameter), and the net count is the rounded change of the motor position.
fn check_general_motors(
    kin: &dyn kinematics::Kinematics,
    mv: &TrapezoidMove,
) -> Result<(), TestCaseError> {
    let start = mv.start_pos;
    let pieces: Vec<trapq::Piece> = mv.pieces().collect();
    let end = pieces
        .last()
        .map(|p| p.position(p.duration))
        .unwrap_or(start);
    let steps = generate(kin, start, &[*mv]);
    let count = kin.motors().len();
    let (mut p0, mut p1) = (vec![0.0; count], vec![0.0; count]);
    kin.inverse(start, &mut p0).expect("start reachable");
    kin.inverse_near(end, &p0, &mut p1).expect("end reachable");
    for motor in 0..count {
        if !matches!(
            kin.motor_map(motor),
            kinematics::MotorMap::General | kinematics::MotorMap::ScaraJoint { .. }
        ) {
            continue;
        }
        let step = kin.motors()[motor].step_distance;
        let motor_steps = &steps[motor];
        prop_assert!(monotonic(motor_steps));
        prop_assert_eq!(
            net(motor_steps),
            ((p1[motor] - p0[motor]) / step).round() as i64,
            "motor {}",
            motor
        );
        let position = |t: f64| {
            let piece = pieces
                .iter()
                .rev()
                .find(|p| p.print_time <= t)
                .unwrap_or(&pieces[0]);
            let local = (t - piece.print_time).clamp(0.0, piece.duration);
            let mut m = vec![0.0; count];
            kin.inverse_near(piece.position(local), &p0, &mut m)
                .expect("pose on the move");
            m[motor]
        };
        let mut n = 0i64;
        for s in motor_steps {
            let level = p0[motor] + (n as f64 + if s.dir { 0.5 } else { -0.5 }) * step;
            let t = s.clock as f64 / 16e6;
            let (before, after) = (
                position(t - 0.5 / 16e6) - level,
                position(t + 0.5 / 16e6) - level,
            );
            // A crossing inside the tick; or, when the exact time sits on a half-tick boundary (rounding can go
            // either way), within 1e-9 of the level at the tick's edge.
            let crosses = before * after <= 0.0 || before.abs().min(after.abs()) <= 1e-9;
            prop_assert!(
                crosses,
                "motor {} step at {} misses its level",
                motor,
                s.clock
            );
            n += if s.dir { 1 } else { -1 };
        }
    }
    Ok(())
}

fn polar_point(r_min: f64, r_max: f64) -> impl Strategy<Value = [f64; 3]> {
    (r_min..r_max, 0.0..std::f64::consts::TAU).prop_map(|(r, a)| [r * a.cos(), r * a.sin(), 1.0])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn general_solver_on_scara_lines(
        start in polar_point(80.0, 180.0),
        end in polar_point(80.0, 180.0),
        cruise in 20.0..300.0f64,
    ) {
        // Upper half plane, and the line keeps 70 mm from the shoulder (the arm never folds or straightens).
        prop_assume!(start[1] > 30.0 && end[1] > 30.0);
        let (d, len2) = ([end[0] - start[0], end[1] - start[1]], (end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2));
        prop_assume!(len2 > 1.0);
        let t = (-(start[0] * d[0] + start[1] * d[1]) / len2).clamp(0.0, 1.0);
        prop_assume!((start[0] + t * d[0]).hypot(start[1] + t * d[1]) >= 70.0);
        let step = std::f64::consts::TAU / 9600.0;
        let kin = machines::scara_fekt(step, step, 0.0025, 100.0, 100.0, [0.0, 0.0], 3.0);
        check_general_motors(kin.as_ref(), &trapezoid(0.5, start, end, 0.0, cruise, 3000.0))?;
    }

    #[test]
    fn general_solver_on_offset_polar_lines(
        start in polar_point(20.0, 150.0),
        end in polar_point(20.0, 150.0),
        cruise in 20.0..300.0f64,
    ) {
        let (d, len2) = ([end[0] - start[0], end[1] - start[1]], (end[0] - start[0]).powi(2) + (end[1] - start[1]).powi(2));
        prop_assume!(len2 > 1.0);
        let t = (-(start[0] * d[0] + start[1] * d[1]) / len2).clamp(0.0, 1.0);
        prop_assume!((start[0] + t * d[0]).hypot(start[1] + t * d[1]) >= 10.0);
        let kin = machines::polar_with_offsets(1.0, 2.0);
        check_general_motors(kin.as_ref(), &trapezoid(0.5, start, end, 0.0, cruise, 3000.0))?;
    }
}
