//! The FEKT-SCARA arm as its fork's example config sets it up (link lengths 100 + 100, `ecr: 3`, base protection
//! 60 mm, `home_position: 0, 200, 0` — the arm stretched straight, a singular pose), with the two edits Kalico
//! requires (`gear_ratio` for the rotary steppers, an explicit `homing_positive_dir`): it homes to the declared
//! pose, prints a Ø40 circle, goes to the straight arm and back, and every step stream is one an MCU can run,
//! with the joints within their travel and, when the config sets them, their speed and acceleration limits.

use std::f64::consts::TAU;

use machine::MachineSetup;
use stepgen::Step;

use crate::limits::plan_and_step;

fn fekt_example(extra: &str) -> String {
    let joint = |name: &str, pins: &str| {
        format!(
            "[{name}]\n{pins}microsteps: 16\ngear_ratio: 60:20\nendstop_pin: ^PE5\nposition_endstop: 0\n\
             position_min: -200\nposition_max: 200\nhoming_speed: 50\nhoming_positive_dir: true\n"
        )
    };
    format!(
        "{}{}[stepper_z]\nstep_pin: PL3\ndir_pin: PL1\nmicrosteps: 16\nrotation_distance: 8\nendstop_pin: ^PD3\n\
         position_endstop: 0.5\nposition_max: 200\n\
         [printer]\nkinematics: scara\nlink1_length: 100.0\nlink2_length: 100.0\noffset_x: 0\noffset_y: 0\n\
         ecr: 3.0\nbase_protection_radius: 60.0\nhome_position: 0, 200, 0\nmax_velocity: 300\nmax_accel: 3000\n\
         max_z_velocity: 50\nmax_z_accel: 30\n{extra}",
        joint("stepper_a", "step_pin: PF0\ndir_pin: !PF1\n"),
        joint("stepper_b", "step_pin: PF6\ndir_pin: PF7\n"),
    )
}

/// G28, a Ø40 circle about (0, 130), then along the arm's line to the stretched pose and back.
const PRINT: &str =
    "G28\nG1 X0 Y130 F3000\nG2 X0 Y130 I0 J-20 F3000\nG1 X0 Y150\nG1 X0 Y200\nG1 X0 Y150\n";

#[test]
fn homing_declares_the_configured_pose() {
    let machine = config::MachineConfig::from_str(&fekt_example(""), "printer.cfg").expect("loads");
    let setup = MachineSetup::from_config(&machine).expect("builds");
    assert_eq!(setup.home_position, Some([0.0, 200.0, 0.5]));
}

#[test]
fn the_fekt_arm_homes_prints_a_circle_and_reaches_the_straight_arm() {
    let (moves, steps) = plan_and_step(&fekt_example(""), PRINT);
    let last = moves.last().expect("moves");
    let end = last.end_pos();
    assert!(
        (end[0]).abs() < 1e-9 && (end[1] - 150.0).abs() < 1e-9,
        "{end:?}"
    );
    // Each joint's reading from its own steps, from the home pose (shoulder 90°, elbow 90°·(1/3) with ecr 3:
    // the elbow motor reads q2 + q1/3), stays within its limits (±200°) and never takes two steps on a tick.
    let step = TAU / (200.0 * 16.0 * 3.0);
    for (motor, (start_deg, motor_steps)) in [(90.0, &steps[0]), (30.0, &steps[1])]
        .into_iter()
        .enumerate()
    {
        let shared = motor_steps.windows(2).find(|w| w[0].clock >= w[1].clock);
        assert!(shared.is_none(), "motor {motor}: {shared:?}");
        let mut reading: f64 = start_deg;
        let mut extreme: f64 = 0.0;
        for s in motor_steps.iter() {
            reading += if s.dir { 1.0 } else { -1.0 } * step.to_degrees();
            extreme = extreme.max(reading.abs());
        }
        assert!(extreme <= 200.0, "motor {motor} reached {extreme}°");
        assert!(!motor_steps.is_empty());
    }
    // Back at (0, 150): the shoulder at 90°, the elbow reading its closed form (q2 = 2·acos(0.75)).
    let q2 = 2.0 * (0.75f64).acos();
    let q1 = std::f64::consts::FRAC_PI_2 - q2 / 2.0;
    let expected = [q1.to_degrees() - 90.0, (q2 + q1 / 3.0).to_degrees() - 30.0];
    for (motor, expected) in expected.iter().enumerate() {
        let net: i64 = steps[motor]
            .iter()
            .map(|s: &Step| if s.dir { 1 } else { -1 })
            .sum();
        let moved = net as f64 * step.to_degrees();
        assert!(
            (moved - expected).abs() <= step.to_degrees(),
            "motor {motor}: {moved}° vs {expected}°"
        );
    }
}

/// With joint limits (`max_joint_velocity`, `max_joint_accel`, alone and together) the arm still leaves the
/// stretched pose it homed to, prints the circle and comes back to the stretched pose and away: each joint's
/// speed and acceleration, read from its own steps, stay within the limits (1% for the reading), no motor steps
/// twice on one clock, and the print ends where it should.
#[test]
fn with_joint_limits_the_arm_leaves_and_reaches_the_straight_arm_within_them() {
    let step = TAU / (200.0 * 16.0 * 3.0);
    for (velocity, accel) in [
        (Some(5.0), None),
        (None, Some(100.0)),
        (Some(2.0), Some(20.0)),
    ] {
        let mut extra = String::new();
        if let Some(v) = velocity {
            extra += &format!("max_joint_velocity: {v}\n");
        }
        if let Some(a) = accel {
            extra += &format!("max_joint_accel: {a}\n");
        }
        let (moves, steps) = plan_and_step(&fekt_example(&extra), PRINT);
        let end = moves.last().expect("moves").end_pos();
        assert!(
            end[0].abs() < 1e-9 && (end[1] - 150.0).abs() < 1e-9,
            "{extra}: {end:?}"
        );
        for (motor, motor_steps) in steps.iter().enumerate() {
            let shared = motor_steps.windows(2).find(|w| w[0].clock >= w[1].clock);
            assert!(shared.is_none(), "{extra}: motor {motor} {shared:?}");
        }
        for (motor, joint_steps) in steps.iter().take(2).enumerate() {
            let (omega, alpha) = crate::limits::peak_rates(joint_steps, step);
            if let Some(v) = velocity {
                assert!(omega <= v * 1.01, "{extra}: motor {motor} at {omega} rad/s");
            }
            if let Some(a) = accel {
                assert!(
                    alpha <= a * 1.01,
                    "{extra}: motor {motor} at {alpha} rad/s²"
                );
            }
        }
    }
}
