//! Every way a path meets a polar bed's centre, measured from the generated steps: lines that pass it, corners
//! on and beside it (where the bed's speed jumps) and arcs through it, at distances from exactly 0 to 5 mm, in random directions and speeds, with and
//! without an angular acceleration limit. The bed stays within its limits, no motor steps twice on one clock,
//! every move completes at its target, and the print takes at most the bound stated in [`time_bound`].

use proptest::prelude::*;
use stepgen::Step;
use trapq::{Motion, TrapezoidMove};

use crate::limits::{
    CLOCK_HZ, MAX_ALPHA, MAX_OMEGA, peak_rates, plan, plan_and_step, polar_config,
};

const DISTANCES: [f64; 8] = [0.0, 1e-15, 1e-9, 1e-6, 1e-3, 0.1, 1.0, 5.0];
const ACCEL: f64 = 3000.0;
const ARM_MAX: f64 = 150.0;
/// The arm's step (rotation distance 40, 16 microsteps) and the kinematics' centre tolerance (half a step, at
/// most 5 µm): the farthest the nozzle may leave the path.
const CENTRE_TOLERANCE: f64 = 0.005;

#[derive(Debug, Clone, Copy)]
enum Path {
    /// A 200 mm line passing the centre at the distance.
    Pass,
    /// A corner at the distance from the centre: arrive along one direction, leave along another.
    Corner { turn: f64 },
    /// A full circle of radius 50 mm through a point at the distance from the centre (`[gcode_arcs]` chords).
    Arc,
}

#[derive(Debug, Clone, Copy)]
struct Case {
    path: Path,
    distance: f64,
    /// Direction of the path (rad).
    heading: f64,
    speed: f64,
    angular_accel: bool,
}

fn rotate(heading: f64, along: f64, across: f64) -> (f64, f64) {
    let (s, c) = heading.sin_cos();
    (along * c - across * s, along * s + across * c)
}

/// The case's G-code: the start declared, then the moves; and the target of the last move.
fn gcode(case: &Case) -> (String, [f64; 2]) {
    let (d, h) = (case.distance, case.heading);
    let f = case.speed * 60.0;
    let at = |x: f64, y: f64| format!("X{x:.17} Y{y:.17}");
    match case.path {
        Path::Pass => {
            let (x0, y0) = rotate(h, -100.0, d);
            let (x1, y1) = rotate(h, 100.0, d);
            let text = format!(
                "SET_KINEMATIC_POSITION {} Z=1\nG1 {} F{f}\n",
                at(x0, y0).replace('X', "X=").replace(" Y", " Y="),
                at(x1, y1)
            );
            (text, [x1, y1])
        }
        Path::Corner { turn } => {
            let (cx, cy) = rotate(h, 0.0, d);
            let (x0, y0) = rotate(h, -100.0, 0.0);
            let (ox, oy) = rotate(h + turn, 100.0, 0.0);
            let text = format!(
                "SET_KINEMATIC_POSITION {} Z=1\nG1 {} F{f}\nG1 {}\n",
                at(x0 + cx, y0 + cy).replace('X', "X=").replace(" Y", " Y="),
                at(cx, cy),
                at(cx + ox, cy + oy)
            );
            (text, [cx + ox, cy + oy])
        }
        Path::Arc => {
            let (x0, y0) = rotate(h, 100.0 + d, 0.0);
            let (i, j) = rotate(h, -50.0, 0.0);
            let text = format!(
                "SET_KINEMATIC_POSITION {} Z=1\nG2 {} I{i:.17} J{j:.17} F{f}\n",
                at(x0, y0).replace('X', "X=").replace(" Y", " Y="),
                at(x0, y0)
            );
            (text, [x0, y0])
        }
    }
}

fn config(angular_accel: bool) -> String {
    let config = polar_config();
    if angular_accel {
        config
    } else {
        config.replace(&format!("max_angular_accel: {MAX_ALPHA}\n"), "")
    }
}

/// The same limits on a Cartesian machine: the path at its requested speed, as Klipper plans it.
fn cartesian_config() -> String {
    let axis = |name: &str| {
        format!(
            "[stepper_{name}]\nstep_pin: P0\ndir_pin: P1\nmicrosteps: 16\nrotation_distance: 40\n\
             endstop_pin: P2\nposition_endstop: -200\nposition_min: -200\nposition_max: 200\n"
        )
    };
    format!(
        "{}{}{}[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: {ACCEL}\nmax_z_velocity: 300\n\
         max_z_accel: {ACCEL}\n[force_move]\nenable_force_move: True\n[gcode_arcs]\n",
        axis("x"),
        axis("y"),
        axis("z")
    )
}

fn span_time(moves: &[TrapezoidMove]) -> f64 {
    let first = moves.first().expect("moves").print_time;
    let last = moves.last().expect("moves");
    last.print_time + last.duration() - first
}

/// Least time (s) to turn the bed through `angle` from rest to rest within `omega` and `alpha`.
fn turn_time(angle: f64, omega: f64, alpha: f64) -> f64 {
    TrapezoidMove::bed_turn(0.0, [0.0; 3], angle, omega, alpha).duration()
}

/// The bed's acceleration in a turn: its limit, or without one the rim (the arm's reach) at `max_accel`.
fn turn_alpha(angular_accel: bool) -> f64 {
    if angular_accel {
        MAX_ALPHA
    } else {
        ACCEL / ARM_MAX
    }
}

/// What physics allows: the path at its requested speed (the Cartesian plan), plus the bed's turn at its limits,
/// plus one stop. The bed must turn through at least the angle the path sweeps about the centre (off the centre
/// its angle follows the position), and a path that meets the centre stops there and turns it at most half a
/// revolution; so the turn counted is the larger of half a revolution and the swept angle (a corner beside the
/// centre sweeps up to 1.5 half turns). The stop and restart at `v` add `v/a'`, where `a'` is the acceleration
/// Klipper's lookahead ramps short moves with (`max_accel · (1 − minimum_cruise_ratio)`), and Klipper's 1 ms
/// restart delay before and after the turn. The turn is counted at most 1.5 times: near the centre the planner cuts
/// the path into bands capped at each band's worst point (up to 1.15² below the continuous limit) with toolhead
/// ramps between them.
fn time_bound(case: &Case, cartesian: f64) -> f64 {
    const RESTARTS: f64 = 2.0 * 0.001;
    const MINIMUM_CRUISE_RATIO: f64 = 0.5;
    const BANDS: f64 = 1.5;
    let v = case.speed.min(300.0);
    let turn = turn_time(
        std::f64::consts::PI.max(swept_angle(case)),
        MAX_OMEGA,
        turn_alpha(case.angular_accel),
    );
    cartesian + RESTARTS + BANDS * turn + v / (ACCEL * (1.0 - MINIMUM_CRUISE_RATIO))
}

/// The angle (rad) a corner's two legs sweep about the centre (each leg less than half a turn); zero for the
/// other paths, whose turn is bounded by half a revolution.
fn swept_angle(case: &Case) -> f64 {
    let Path::Corner { turn } = case.path else {
        return 0.0;
    };
    let (h, d) = (case.heading, case.distance);
    let corner = rotate(h, 0.0, d);
    let start = rotate(h, -100.0, d);
    let leave = rotate(h + turn, 100.0, 0.0);
    let end = (corner.0 + leave.0, corner.1 + leave.1);
    let between =
        |a: (f64, f64), b: (f64, f64)| (a.0 * b.1 - a.1 * b.0).atan2(a.0 * b.0 + a.1 * b.1).abs();
    between(start, corner) + between(corner, end)
}

fn end_position(moves: &[TrapezoidMove]) -> [f64; 3] {
    let last = moves
        .iter()
        .rev()
        .find(|m| m.motion == Motion::Travel)
        .expect("a travel");
    let piece = last.pieces().last().expect("pieces");
    piece.position(piece.duration)
}

fn check(case: &Case) -> Result<(), TestCaseError> {
    let (text, target) = gcode(case);
    let config = config(case.angular_accel);
    let (moves, steps) = plan_and_step(&config, &text);
    let step_dist = std::f64::consts::TAU / 16000.0;
    let (omega, alpha) = peak_rates(&steps[0], step_dist);
    prop_assert!(omega <= MAX_OMEGA * 1.01, "{case:?}: bed at {omega} rad/s");
    if case.angular_accel {
        prop_assert!(alpha <= MAX_ALPHA * 1.01, "{case:?}: bed at {alpha} rad/s²");
    }
    for (motor, motor_steps) in steps.iter().enumerate() {
        let shared = motor_steps.windows(2).find(|w| w[0].clock >= w[1].clock);
        prop_assert!(shared.is_none(), "{case:?}: motor {motor} {shared:?}");
    }
    let end = end_position(&moves);
    let miss = (end[0] - target[0]).hypot(end[1] - target[1]);
    prop_assert!(miss <= CENTRE_TOLERANCE, "{case:?}: ends {miss} mm off");
    let ours = span_time(&moves);
    let cartesian = span_time(&plan(&cartesian_config(), &text).1);
    let bound = time_bound(case, cartesian);
    prop_assert!(
        ours <= bound,
        "{case:?}: {ours} s, bound {bound} s (Cartesian {cartesian} s)"
    );
    Ok(())
}

fn path() -> impl Strategy<Value = Path> {
    prop_oneof![
        Just(Path::Pass),
        (-3.1f64..3.1).prop_map(|turn| Path::Corner { turn }),
        Just(Path::Arc),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 160, ..ProptestConfig::default() })]

    #[test]
    fn every_path_near_the_centre_completes_within_the_bed_limits_and_the_time_bound(
        path in path(),
        distance in proptest::sample::select(DISTANCES.to_vec()),
        heading in -3.2f64..3.2,
        speed in 5.0f64..300.0,
        angular_accel in any::<bool>(),
    ) {
        check(&Case { path, distance, heading, speed, angular_accel })?;
    }
}

/// The whole grid once in a fixed direction, at the slowest and fastest speeds, so no distance is left to chance.
#[test]
fn the_whole_grid_in_one_direction() {
    for path in [Path::Pass, Path::Corner { turn: 2.0 }, Path::Arc] {
        for distance in DISTANCES {
            for speed in [5.0, 300.0] {
                for angular_accel in [false, true] {
                    let case = Case {
                        path,
                        distance,
                        heading: 0.3,
                        speed,
                        angular_accel,
                    };
                    if let Err(e) = check(&case) {
                        panic!("{e}");
                    }
                }
            }
        }
    }
}

/// The bound is tight: on cases whose least time is known in closed form it is at most twice that time.
#[test]
fn the_time_bound_is_within_twice_the_least_time_solved_by_hand() {
    let l = 200.0;
    // Rest to rest over `length` at `v` and `ACCEL` (long enough to cruise).
    let rest_to_rest = |length: f64, v: f64| length / v + v / ACCEL;
    let case = |distance: f64, speed: f64| Case {
        path: Path::Pass,
        distance,
        heading: 0.0,
        speed,
        angular_accel: true,
    };
    let half_turn = turn_time(std::f64::consts::PI, MAX_OMEGA, MAX_ALPHA);
    // Through the exact centre at 300 mm/s: the nozzle must rest on it while the bed turns half a revolution.
    let least = 2.0 * rest_to_rest(l / 2.0, 300.0) + half_turn;
    let bound = time_bound(&case(0.0, 300.0), rest_to_rest(l, 300.0));
    assert!(least <= bound && bound <= 2.0 * least, "{least} vs {bound}");
    // 1 mm beside it at 20 mm/s: at least the path at full speed, and at least the turn it needs.
    let angle = std::f64::consts::PI - 2.0 * (1.0f64 / 100.0).atan();
    let least = rest_to_rest(l, 20.0).max(turn_time(angle, MAX_OMEGA, MAX_ALPHA));
    let bound = time_bound(&case(1.0, 20.0), rest_to_rest(l, 20.0));
    assert!(bound <= 2.0 * least, "{bound} vs {least}");
    // And what the planner takes lies between the two.
    let (text, _) = gcode(&case(1.0, 20.0));
    let ours = span_time(&plan_and_step(&config(true), &text).0);
    assert!(
        least <= ours && ours <= bound,
        "{least} <= {ours} <= {bound}"
    );
}

#[test]
fn steps_of_one_motor_never_share_a_clock_across_a_turn_in_place() {
    // Arrive on the centre, leave at a right angle: the bed turns a quarter revolution in place.
    let text = "SET_KINEMATIC_POSITION X=100 Y=0 Z=1\nG1 X0 Y0 F3000\nG1 X0.01 Y1\n";
    let (moves, steps) = plan_and_step(&polar_config(), text);
    let turns: Vec<&TrapezoidMove> = moves
        .iter()
        .filter(|m| m.motion == Motion::BedTurn)
        .collect();
    assert_eq!(turns.len(), 1);
    let turned: f64 = turns[0].pieces().map(|p| p.distance(p.duration)).sum();
    let expected = 1.0f64.atan2(0.01);
    assert!((turned - expected).abs() < 1e-12, "{turned} vs {expected}");
    let bed: &[Step] = &steps[0];
    let min_interval = bed
        .windows(2)
        .map(|w| w[1].clock - w[0].clock)
        .min()
        .expect("steps");
    // 5 rad/s with 16000 steps a turn: at least 16e6 / (5 · 16000 / 2π) ≈ 1257 ticks apart.
    let least = (CLOCK_HZ / (MAX_OMEGA * 16000.0 / std::f64::consts::TAU)).floor() as u64 - 1;
    assert!(min_interval >= least, "{min_interval} ticks");
}
