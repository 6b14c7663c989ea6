//! Motor limits beyond Klipper: a polar bed's angular speed and acceleration near the centre, measured from the
//! generated steps (not from the planner's own numbers).

use machine::MachineSetup;
use printjob::plan_gcode;
use stepgen::{Step, StepGenConfig, StepGenerator};
use trapq::{Piece, Queue, TrapezoidMove};

pub(crate) const MAX_OMEGA: f64 = 5.0; // rad/s
pub(crate) const MAX_ALPHA: f64 = 200.0; // rad/s²
const MAX_VELOCITY: f64 = 300.0;
pub(crate) const CLOCK_HZ: f64 = 16e6;

/// The polar machine of these tests, with the commands they use (`SET_KINEMATIC_POSITION`, G2/G3).
pub(crate) fn polar_config() -> String {
    format!(
        "[stepper_bed]\nstep_pin: PF0\ndir_pin: PF1\nmicrosteps: 16\ngear_ratio: 80:16\n\
         [stepper_arm]\nstep_pin: PF6\ndir_pin: PF7\nmicrosteps: 16\nrotation_distance: 40\nendstop_pin: ^PJ1\n\
         position_endstop: 150\nposition_max: 150\n\
         [stepper_z]\nstep_pin: PL3\ndir_pin: PL1\nmicrosteps: 16\nrotation_distance: 8\nendstop_pin: ^PD3\n\
         position_endstop: 0.5\nposition_max: 200\n\
         [printer]\nkinematics: polar\nmax_velocity: {MAX_VELOCITY}\nmax_accel: 3000\n\
         max_angular_velocity: {MAX_OMEGA}\nmax_angular_accel: {MAX_ALPHA}\n\
         [force_move]\nenable_force_move: True\n[gcode_arcs]\n"
    )
}

/// Plan `gcode` on the machine `config` and generate every motor's steps; the toolhead moves and the steps.
pub(crate) fn plan_and_step(config: &str, gcode: &str) -> (Vec<TrapezoidMove>, Vec<Vec<Step>>) {
    let (setup, moves) = plan(config, gcode);
    let pieces: Vec<Piece> = moves.iter().flat_map(|m| m.pieces()).collect();
    let start = pieces.first().expect("moves").start_pos;
    let config = StepGenConfig {
        clock_hz: CLOCK_HZ,
        ..StepGenConfig::default()
    };
    let mut generator =
        StepGenerator::new(setup.kinematics.as_ref(), start, None, config).expect("starts");
    let mut sinks: Vec<Vec<Step>> = vec![Vec::new(); setup.kinematics.motors().len()];
    generator
        .run_chunk(&pieces, &[], &mut sinks)
        .expect("steps");
    generator.finish(&mut sinks).expect("finishes");
    (moves, sinks)
}

/// Plan `gcode` on the machine `config`: the machine and its toolhead moves.
pub(crate) fn plan(config: &str, gcode: &str) -> (MachineSetup, Vec<TrapezoidMove>) {
    let machine = config::MachineConfig::from_str(config, "printer.cfg").expect("config loads");
    let setup = MachineSetup::from_config(&machine).expect("machine builds");
    let mut moves = Vec::new();
    let sink = |q: Queue, mv: &TrapezoidMove| {
        if q == Queue::Toolhead {
            moves.push(*mv);
        }
    };
    let _ = plan_gcode(&setup, gcode.as_bytes(), "test.gcode", sink).expect("plans");
    (setup, moves)
}

/// Plan one straight pass at `offset` mm from the centre at `speed` mm/s; the planned moves and the bed's steps.
fn pass(offset: f64, speed: f64) -> (Vec<TrapezoidMove>, Vec<Step>) {
    let gcode = format!(
        "SET_KINEMATIC_POSITION X=100 Y={offset} Z=1\nG1 X-100 Y{offset} F{}\n",
        speed * 60.0
    );
    let (moves, mut steps) = plan_and_step(&polar_config(), &gcode);
    (moves, steps.swap_remove(0))
}

/// Peak speed and acceleration of a motor from its step times: speed over windows of `w` steps, and
/// acceleration from the speeds of consecutive windows (so clock quantisation stays far below 1%).
pub(crate) fn peak_rates(steps: &[Step], step_dist: f64) -> (f64, f64) {
    let t: Vec<f64> = steps.iter().map(|s| s.clock as f64 / CLOCK_HZ).collect();
    let w = 16;
    let mut omegas = Vec::new();
    let mut i = 0;
    while i + w < t.len() {
        // Only windows without a direction change.
        if steps[i..=i + w].iter().all(|s| s.dir == steps[i].dir) {
            omegas.push((
                (t[i] + t[i + w]) / 2.0,
                w as f64 * step_dist / (t[i + w] - t[i]),
            ));
        }
        i += w;
    }
    let peak_omega = omegas.iter().map(|o| o.1).fold(0.0, f64::max);
    let peak_alpha = omegas
        .windows(2)
        .map(|p| ((p[1].1 - p[0].1) / (p[1].0 - p[0].0)).abs())
        .fold(0.0, f64::max);
    (peak_omega, peak_alpha)
}

/// Klipper's `max_angular_velocity` slows the whole move by ω_max / (v_max / d_min) (REFERENCE.md §2).
fn klipper_time(length: f64, speed: f64, offset: f64) -> f64 {
    let factor = (MAX_OMEGA * offset / MAX_VELOCITY).min(1.0);
    length / (speed * factor)
}

#[test]
fn bed_speed_and_acceleration_stay_within_limits_near_the_centre() {
    let step_dist = std::f64::consts::TAU / 16000.0;
    for offset in [0.01, 0.1, 1.0, 5.0] {
        for speed in [50.0, 150.0, 300.0] {
            let (moves, steps) = pass(offset, speed);
            assert!(!steps.is_empty());
            let (omega, alpha) = peak_rates(&steps, step_dist);
            assert!(
                omega <= MAX_OMEGA * 1.01,
                "offset {offset} speed {speed}: bed at {omega} rad/s"
            );
            assert!(
                alpha <= MAX_ALPHA * 1.01,
                "offset {offset} speed {speed}: bed at {alpha} rad/s²"
            );
            let ours: f64 = moves.iter().map(|m| m.duration()).sum();
            let klipper = klipper_time(200.0, speed, offset);
            if klipper > 200.0 / speed * 1.001 {
                // Klipper slows this move; ours must take at most a fifth of its time.
                assert!(
                    ours <= klipper / 5.0,
                    "offset {offset} speed {speed}: {ours} s vs Klipper {klipper} s"
                );
            }
            eprintln!(
                "offset {offset:>5} mm, {speed:>3} mm/s: {} spans, {ours:.3} s (Klipper {klipper:.3} s), peak {omega:.3} rad/s, {alpha:.1} rad/s²",
                moves.len()
            );
        }
    }
}

#[test]
fn a_move_through_the_exact_centre_stops_turns_the_bed_and_completes() {
    let step_dist = std::f64::consts::TAU / 16000.0;
    for speed in [50.0, 300.0] {
        let (moves, steps) = pass(0.0, speed);
        let turns: Vec<&TrapezoidMove> = moves.iter().filter(|m| m.axes_r == [0.0; 3]).collect();
        assert_eq!(turns.len(), 1, "one turn in place");
        // The toolhead arrives at rest and leaves from rest.
        let i = moves
            .iter()
            .position(|m| m.axes_r == [0.0; 3])
            .expect("turn");
        let before = &moves[i - 1];
        assert!((before.cruise_v - before.accel * before.decel_t).abs() < 1e-9);
        assert_eq!(moves[i + 1].start_v, 0.0);
        // The bed turned half a revolution: 8000 net steps, all in one direction, within its limits.
        let net: i64 = steps.iter().map(|s| if s.dir { 1 } else { -1 }).sum();
        assert_eq!(net.abs(), 8000, "net bed steps");
        let (omega, alpha) = peak_rates(&steps, step_dist);
        assert!(
            omega <= MAX_OMEGA * 1.01 && alpha <= MAX_ALPHA * 1.01,
            "{omega} rad/s, {alpha} rad/s²"
        );
        let total: f64 = moves.iter().map(|m| m.duration()).sum();
        eprintln!(
            "exact centre at {speed} mm/s: {total:.3} s, bed peak {omega:.3} rad/s, {alpha:.1} rad/s²"
        );
    }
}

#[test]
fn without_limits_a_pass_is_one_move() {
    let machine = config::MachineConfig::from_str(
        &polar_config().replace("max_angular_velocity: 5\nmax_angular_accel: 200\n", ""),
        "polar.cfg",
    )
    .expect("config loads");
    let setup = MachineSetup::from_config(&machine).expect("machine builds");
    assert!(setup.planner.kinematic_limits.is_empty());
}

#[test]
fn scara_joint_speed_and_acceleration_stay_within_limits_near_full_reach() {
    let (max_w, max_a) = (2.0, 100.0);
    let config = format!(
        "[stepper_a]\nstep_pin: PF0\ndir_pin: PF1\nmicrosteps: 16\ngear_ratio: 60:20\nendstop_pin: ^PE5\n\
         position_endstop: 45\nposition_min: -200\nposition_max: 200\nhoming_positive_dir: true\n\
         [stepper_b]\nstep_pin: PF6\ndir_pin: PF7\nmicrosteps: 16\ngear_ratio: 60:20\nendstop_pin: ^PJ1\n\
         position_endstop: 105\nposition_min: -200\nposition_max: 200\nhoming_positive_dir: true\n\
         [stepper_z]\nstep_pin: PL3\ndir_pin: PL1\nmicrosteps: 16\nrotation_distance: 8\nendstop_pin: ^PD3\n\
         position_endstop: 0.5\nposition_max: 200\n\
         [printer]\nkinematics: scara\nlink1_length: 100\nlink2_length: 100\necr: 3\nmax_velocity: 300\n\
         max_accel: 3000\nmax_joint_velocity: {max_w}\nmax_joint_accel: {max_a}\n"
    );
    // Along y = 150 the radius runs 192 → 150 → 192 mm: the arm is nearly straight at both ends.
    let gcode = "SET_KINEMATIC_POSITION X=-120 Y=150 Z=1\nG1 X120 Y150 F18000\n";
    let (moves, steps) = plan_and_step(&config, gcode);
    let step_dist = std::f64::consts::TAU / 9600.0;
    for (name, motor_steps) in ["stepper_a", "stepper_b"].iter().zip(&steps) {
        let (w, a) = peak_rates(motor_steps, step_dist);
        assert!(w <= max_w * 1.01, "{name}: {w} rad/s");
        assert!(a <= max_a * 1.01, "{name}: {a} rad/s²");
        eprintln!(
            "scara {name}: peak {w:.3} rad/s, {a:.1} rad/s², {} spans",
            moves.len()
        );
    }
}

#[test]
fn step_rate_limit_holds_on_every_motor() {
    let limit = 20000.0;
    let config = polar_config().replace(
        "max_angular_velocity: 5\nmax_angular_accel: 200\n",
        &format!("max_step_rate: {limit}\n"),
    );
    let gcode =
        "SET_KINEMATIC_POSITION X=100 Y=0.5 Z=1\nG1 X-100 Y0.5 F18000\nG1 X-100 Y-80 Z2 F18000\n";
    let (_, steps) = plan_and_step(&config, gcode);
    for motor_steps in &steps {
        let t: Vec<f64> = motor_steps
            .iter()
            .map(|s| s.clock as f64 / CLOCK_HZ)
            .collect();
        let w = 16;
        let peak = t
            .windows(w + 1)
            .map(|x| w as f64 / (x[w] - x[0]))
            .fold(0.0, f64::max);
        assert!(peak <= limit * 1.01, "{peak} steps/s");
    }
}
