//! The SCARA joint solver against a slow reference that is correct by construction: the motor position from
//! `Kinematics::inverse_near` sampled every 5 µs, each threshold crossing bisected to 1e-15 s, the same step
//! rule (half-step levels in Klipper's arithmetic, 1e-9 reversal margin, commit when the commanded position is
//! reached) and the same filter. Every step must match in count and direction, and every clock must be the
//! reference's, or one tick off where the exact time lies within 1e-12 s of a half tick (rounding may go
//! either way there).

use std::f64::consts::TAU;

use kinematics::scara::Scara;
use kinematics::{ElbowBranch, Kinematics, MotorMap, ScaraFrame, ScaraParams};
use proptest::prelude::*;
use stepgen::{REVERSAL_MARGIN, Step, StepFilter, StepGenConfig, StepGenerator};
use trapq::{Piece, Queue, TrapezoidMove};

use crate::machines::stepper;

const CLOCK_HZ: f64 = 16e6;
const SAMPLE_DT: f64 = 5e-6;
/// How close to a half tick an exact time must be for a one-tick difference to be accepted.
const TIE_TIME: f64 = 1e-12;

fn fekt() -> Scara {
    Scara::new(ScaraParams {
        base_protection_radius: 0.0,
        ..ScaraParams::fekt_example()
    })
    .expect("valid FEKT parameters")
}

/// Coupled elbow without `ecr`, right elbow, X-SCARA frame, offsets and motor zeros.
fn coupled() -> Scara {
    let step = TAU / 6400.0;
    Scara::new(ScaraParams {
        shoulder_stepper: stepper("stepper_a", step),
        elbow_stepper: stepper("stepper_b", step),
        z: stepper("stepper_z", 0.0025),
        link1_length: 120.0,
        link2_length: 90.0,
        offset_x: 10.0,
        offset_y: -5.0,
        elbow_coupling: 0.6,
        ecr: None,
        elbow: ElbowBranch::Right,
        frame: ScaraFrame::XScara,
        shoulder_zero: 0.3,
        elbow_zero: -0.2,
        shoulder_limits: None,
        elbow_limits: None,
        base_protection_radius: 0.0,
        singularity_margin: 0.0,
    })
    .expect("valid coupled parameters")
}

/// A trapezoid from `start` to `end` starting and ending at rest.
fn trapezoid(
    print_time: f64,
    start: [f64; 3],
    end: [f64; 3],
    cruise: f64,
    accel: f64,
) -> TrapezoidMove {
    let d = [end[0] - start[0], end[1] - start[1], end[2] - start[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let peak = cruise.min((accel * len).sqrt());
    let ramp_t = peak / accel;
    let ramp_d = 0.5 * peak * ramp_t;
    TrapezoidMove {
        print_time,
        accel_t: ramp_t,
        cruise_t: ((len - 2.0 * ramp_d) / peak).max(0.0),
        decel_t: ramp_t,
        start_pos: start,
        axes_r: [d[0] / len, d[1] / len, d[2] / len],
        start_v: 0.0,
        cruise_v: peak,
        accel,
        motion: trapq::Motion::Travel,
    }
}

fn generated(kin: &dyn Kinematics, start: [f64; 3], moves: &[TrapezoidMove]) -> Vec<Vec<Step>> {
    let mut generator =
        StepGenerator::new(kin, start, None, StepGenConfig::default()).expect("generator");
    let mut sinks = vec![Vec::new(); generator.motor_count()];
    generator
        .run_moves(moves.iter().map(|m| (Queue::Toolhead, *m)), 16, &mut sinks)
        .expect("steps for a reachable move");
    sinks
}

/// The reference solver for one motor.
struct Reference<'a> {
    kin: &'a dyn Kinematics,
    motor: usize,
    pieces: Vec<Piece>,
    /// Samples so far: time and all motor positions (for unwrapping the bisection's evaluations).
    samples: Vec<(f64, Vec<f64>)>,
    commanded: f64,
    half_step: f64,
    dir_up: bool,
    filter: StepFilter,
    out: Vec<Step>,
    /// Every step before filtering: exact time and direction.
    raw: Vec<(f64, bool)>,
}

impl<'a> Reference<'a> {
    fn new(
        kin: &'a dyn Kinematics,
        motor: usize,
        start: [f64; 3],
        moves: &[TrapezoidMove],
    ) -> Self {
        let mut motors = vec![0.0; kin.motors().len()];
        kin.inverse(start, &mut motors).expect("start reachable");
        Reference {
            kin,
            motor,
            pieces: moves.iter().flat_map(|m| m.pieces()).collect(),
            commanded: motors[motor],
            samples: vec![(0.0, motors)],
            half_step: 0.5 * kin.motors()[motor].step_distance,
            dir_up: false,
            filter: StepFilter::new(CLOCK_HZ, 750e-6),
            out: Vec::new(),
            raw: Vec::new(),
        }
    }

    /// All motors at absolute time `t`, unwrapped near `near`.
    fn motors_at(&self, t: f64, near: &[f64]) -> Vec<f64> {
        let i = self.pieces.partition_point(|p| p.print_time <= t).max(1) - 1;
        let piece = &self.pieces[i];
        let local = (t - piece.print_time).clamp(0.0, piece.duration);
        let mut motors = vec![0.0; near.len()];
        self.kin
            .inverse_near(piece.position(local), near, &mut motors)
            .expect("reachable pose");
        motors
    }

    fn run(mut self) -> (Vec<Step>, Vec<(f64, bool)>) {
        let first = self.pieces[0].print_time;
        let last = self
            .pieces
            .last()
            .map_or(first, |p| p.print_time + p.duration);
        let count = ((last - first) / SAMPLE_DT).ceil() as usize;
        self.samples[0].0 = first;
        for k in 1..=count {
            let t = (first + k as f64 * SAMPLE_DT).min(last);
            let motors = self.motors_at(t, &self.samples[k - 1].1);
            let f = motors[self.motor];
            self.samples.push((t, motors));
            self.steps_at(f);
        }
        self.filter.commit(&mut self.out);
        self.filter.flush(&mut self.out);
        (self.out, self.raw)
    }

    /// The step rule at a sample with position `f`.
    fn steps_at(&mut self, f: f64) {
        loop {
            let up_level = self.commanded + self.half_step;
            let down_level = self.commanded - self.half_step;
            let up = if self.dir_up {
                f >= up_level
            } else {
                f > up_level + REVERSAL_MARGIN
            };
            let down = if self.dir_up {
                f < down_level - REVERSAL_MARGIN
            } else {
                f <= down_level
            };
            if !(up || down) {
                break;
            }
            let level = if up { up_level } else { down_level };
            let t = self.crossing(level, up);
            self.commanded = if up {
                (self.commanded + self.half_step) + self.half_step
            } else {
                (self.commanded - self.half_step) - self.half_step
            };
            self.dir_up = up;
            self.raw.push((t, up));
            self.filter.push(t, up, &mut self.out);
        }
        let reached = if self.dir_up {
            f > self.commanded
        } else {
            f < self.commanded
        };
        if reached {
            self.filter.commit(&mut self.out);
        }
    }

    /// The last time the position reached `level` (going up when `up`): the newest sample before the level,
    /// then bisection to 1e-15 s. (A reversal may have passed the level samples ago, within its margin.)
    fn crossing(&self, level: f64, up: bool) -> f64 {
        let past = |f: f64| if up { f > level } else { f < level };
        let newest = self.samples.len() - 1;
        let j = (0..newest)
            .rev()
            .find(|&j| !past(self.samples[j].1[self.motor]))
            .unwrap_or(0);
        let near = &self.samples[j].1;
        let (mut lo, mut hi) = (self.samples[j].0, self.samples[j + 1].0);
        while hi - lo > 1e-15 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if past(self.motors_at(mid, near)[self.motor]) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    }
}

/// Compare one motor's steps with the reference.
fn check_motor(
    kin: &dyn Kinematics,
    start: [f64; 3],
    moves: &[TrapezoidMove],
    motor: usize,
    steps: &[Step],
) -> Result<(), TestCaseError> {
    let (expected, raw) = Reference::new(kin, motor, start, moves).run();
    prop_assert_eq!(steps.len(), expected.len(), "motor {} step count", motor);
    prop_assert!(
        !expected.is_empty() || raw.is_empty(),
        "reference lost steps"
    );
    let clock_of = |t: f64| StepFilter::new(CLOCK_HZ, 750e-6).clock_of(t);
    let mut r = 0;
    for (i, (got, want)) in steps.iter().zip(&expected).enumerate() {
        prop_assert_eq!(got.dir, want.dir, "motor {} step {} direction", motor, i);
        // The unfiltered reference step that became this one.
        while r < raw.len() && (clock_of(raw[r].0) != want.clock || raw[r].1 != want.dir) {
            r += 1;
        }
        prop_assert!(
            r < raw.len(),
            "motor {} step {} not in the raw reference",
            motor,
            i
        );
        let exact_ticks = raw[r].0 * CLOCK_HZ;
        let tie = ((exact_ticks - exact_ticks.floor()) - 0.5).abs() <= TIE_TIME * CLOCK_HZ;
        let close = got.clock == want.clock || (tie && got.clock.abs_diff(want.clock) == 1);
        prop_assert!(
            close,
            "motor {} step {}: clock {} but the reference crossing is at {} ticks",
            motor,
            i,
            got.clock,
            exact_ticks
        );
        r += 1;
    }
    Ok(())
}

fn check_machine(
    kin: &Scara,
    points: [[f64; 3]; 3],
    speeds: [(f64, f64); 2],
) -> Result<(), TestCaseError> {
    for i in 0..2 {
        prop_assume!(kin.check_segment(points[i], points[i + 1]).is_ok());
        // Lines through the shoulder turn q1 by π in an instant; 20 mm away the 5 µs samples follow it.
        prop_assume!(closest_approach(points[i], points[i + 1], kin.shoulder()) >= 20.0);
        let d: f64 = (0..3)
            .map(|k| (points[i + 1][k] - points[i][k]).powi(2))
            .sum();
        prop_assume!(d > 1e-2);
    }
    for motor in 0..2 {
        let joint = matches!(kin.motor_map(motor), MotorMap::ScaraJoint { .. });
        prop_assert!(joint, "motor {} is not solved as a SCARA joint", motor);
    }
    let first = trapezoid(0.25, points[0], points[1], speeds[0].0, speeds[0].1);
    let second_start = 0.25 + first.accel_t + first.cruise_t + first.decel_t;
    let second = trapezoid(second_start, points[1], points[2], speeds[1].0, speeds[1].1);
    let moves = [first, second];
    let steps = generated(kin, points[0], &moves);
    for (motor, motor_steps) in steps.iter().enumerate().take(2) {
        check_motor(kin, points[0], &moves, motor, motor_steps)?;
    }
    Ok(())
}

/// Distance from `centre` to the XY segment `a`–`b`.
fn closest_approach(a: [f64; 3], b: [f64; 3], centre: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let p = [a[0] - centre[0], a[1] - centre[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (-(p[0] * d[0] + p[1] * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] + t * d[0]).hypot(p[1] + t * d[1])
}

/// A point `r` from `centre` (any direction), Z in [0, 5].
fn annulus(centre: [f64; 2], r_min: f64, r_max: f64) -> impl Strategy<Value = [f64; 3]> {
    (r_min..r_max, 0.0..TAU, 0.0..5.0f64)
        .prop_map(move |(r, a, z)| [centre[0] + r * a.cos(), centre[1] + r * a.sin(), z])
}

fn speed() -> impl Strategy<Value = (f64, f64)> {
    (2.0..250.0f64, 200.0..5000.0f64)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn scara_joint_solver_matches_the_reference_on_the_fekt_arm(
        a in annulus([0.0, 0.0], 5.0, 199.0),
        b in annulus([0.0, 0.0], 5.0, 199.0),
        c in annulus([0.0, 0.0], 5.0, 199.0),
        speeds in [speed(), speed()],
    ) {
        check_machine(&fekt(), [a, b, c], speeds)?;
    }

    #[test]
    fn scara_joint_solver_matches_the_reference_on_a_coupled_x_scara(
        a in annulus([10.0, -5.0], 31.0, 209.0),
        b in annulus([10.0, -5.0], 31.0, 209.0),
        c in annulus([10.0, -5.0], 31.0, 209.0),
        speeds in [speed(), speed()],
    ) {
        check_machine(&coupled(), [a, b, c], speeds)?;
    }
}
