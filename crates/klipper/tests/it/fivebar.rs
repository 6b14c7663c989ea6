//! `jointspace_fivebar` inside Klipper and Kalico (batch mode, step compression off): a real slicer file printed on
//! the example machine, homing to the joints' endstops and to a declared pose, and moves refused at their line
//! without moving. Every MCU stream is decoded and audited against the tests' own inverse (`fivebar_reference`): the
//! motors must stand, step after step, within one step of where circle–circle geometry puts them along the path.

use std::path::{Path, PathBuf};

use crate::centre_grid::audit_motor;
use crate::fivebar_reference::{
    MAX_JOINT_VELOCITY, MOTOR_STEP, MOTORS, SIDES, audit_path, degrees_from, gcode_path, nozzle,
    reference_counts,
};
use crate::hosts::{Hosts, KALICO, KLIPPER, Run, Step, shared, tail, workspace_root, write};

/// `klipper/examples/fivebar.cfg` with whole-line replacements (each must be there) and text appended.
pub fn example_config(dir: &Path, name: &str, replace: &[(&str, &str)], extra: &str) -> PathBuf {
    let mut text = std::fs::read_to_string(workspace_root().join("klipper/examples/fivebar.cfg"))
        .expect("five-bar example");
    for (from, to) in replace {
        assert!(
            text.lines().any(|l| l.trim() == *from),
            "the example has no line '{from}'"
        );
        text = text
            .lines()
            .map(|l| if l.trim() == *from { *to } else { l })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n";
    }
    write(dir, name, &(text + extra))
}

/// The `toolhead: X:… Y:…` of GET_POSITION, as numbers.
fn reported_xy(run: &Run) -> [f64; 2] {
    let line = run
        .log
        .lines()
        .find(|l| l.starts_with("toolhead:"))
        .unwrap_or_else(|| panic!("no GET_POSITION line:\n{}", tail(&run.log, 20)));
    let value = |axis: &str| -> f64 {
        let rest = line.split_once(&format!("{axis}:")).expect(axis).1;
        rest.split_whitespace()
            .next()
            .and_then(|v| v.parse().ok())
            .expect("a number")
    };
    [value("X"), value("Y")]
}

fn arm_steps(run: &Run) -> [Vec<Step>; 2] {
    let steps = run.steps();
    MOTORS.map(|m| steps.get(m).cloned().unwrap_or_default())
}

/// Both arm motors stepped as an MCU can (strictly increasing clocks, within `max_joint_velocity`) and followed
/// the reference path from clock `after` on; prints what was measured.
fn audit_arms(what: &str, run: &Run, after: i64, path: &[[f64; 2]]) {
    assert!(
        run.success && !run.log.contains("shutdown"),
        "{what}: klippy failed; log ends:\n{}",
        tail(&run.log, 30)
    );
    let steps = arm_steps(run);
    for (motor, stream) in MOTORS.iter().zip(&steps) {
        audit_motor(
            &format!("{what}: {motor}"),
            stream,
            MOTOR_STEP,
            MAX_JOINT_VELOCITY,
        );
    }
    let reference = reference_counts(path);
    let audit = audit_path(what, [&steps[0], &steps[1]], after, &reference);
    println!(
        "{what}: {} steps ({} left, {} right) along {} reference states, {} within one step and the rest exact",
        audit.states,
        steps[0].len(),
        steps[1].len(),
        reference.len(),
        audit.off_by_one
    );
}

/// The last clock of the homing moves: the first pause of over a second after the right joint's first step (the
/// test's G-code dwells 2 s after homing).
fn homing_end(steps: &[Vec<Step>; 2]) -> i64 {
    let mut clocks: Vec<i64> = steps.iter().flatten().map(|s| s.0).collect();
    clocks.sort_unstable();
    let first_right = steps[1].first().expect("the right joint homed").0;
    clocks
        .windows(2)
        .find(|w| w[0] >= first_right && w[1] - w[0] > 16_000_000)
        .map_or(i64::MAX, |w| w[0])
}

/// A slicer's part (Cura 4.10, a Ø165 mm circle about the origin, ten layers, 1,712 moves) printed on the example
/// machine from a declared pose: in Klipper and Kalico every step of both arm motors lies within one step of where
/// the tests' inverse puts them along the file's path, within `max_joint_velocity`, ending exactly where it does.
#[test]
fn a_slicer_file_prints_on_the_fivebar_in_klipper_and_kalico() {
    let Some(hosts) = Hosts::get("a_slicer_file_prints_on_the_fivebar_in_klipper_and_kalico")
    else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    // The part's lines are 3 mm wide and 1 mm high: the extruder's cross-section limit is raised for them.
    let config = example_config(
        dir.path(),
        "printer.cfg",
        &[
            (
                "max_extrude_cross_section: 1.0",
                "max_extrude_cross_section: 12\nmin_extrude_temp: 0",
            ),
            (
                "kinematics: jointspace_fivebar",
                "kinematics: jointspace_fivebar\nhome_position: 0, 0, 0.5",
            ),
        ],
        "",
    );
    let part = std::fs::read_to_string(shared().join("corpus/cura-4.10_circle-centred.gcode"))
        .expect("corpus file");
    let input = write(dir.path(), "part.gcode", &format!("G28\n{part}\nM400\n"));
    let path = gcode_path([0.0, 0.0], &part);
    assert!(path.len() > 1500, "{} points", path.len());
    for host in [KLIPPER, KALICO] {
        let started = std::time::Instant::now();
        let run = hosts.batch(host, true, &config, &input, &dir.path().join(host));
        audit_arms(&format!("cura circle on {host}"), &run, 0, &path);
        println!(
            "cura circle on {host}: {:.1} s",
            started.elapsed().as_secs_f64()
        );
    }
}

/// G28 runs the left joint to its endstop, then the right one, each alone in joint space, and the nozzle is where
/// the tests' forward kinematics puts the joints' readings: the endstops' 150° and 30° in Klipper, 5° back from each
/// in Kalico (its final retract, `homing_retract_dist` in degrees); the moves after homing step along the reference
/// path from there.
#[test]
fn the_fivebar_homes_each_joint_to_its_endstop() {
    let Some(hosts) = Hosts::get("the_fivebar_homes_each_joint_to_its_endstop") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_config(dir.path(), "printer.cfg", &[], "");
    let input = write(
        dir.path(),
        "home.gcode",
        "G28\nGET_POSITION\nG4 P2000\nG1 X40 Y60 F3000\nG1 X-70 Y20\nM400\n",
    );
    for (host, readings) in [(KLIPPER, [150.0, 30.0]), (KALICO, [145.0, 35.0])] {
        let run = hosts.batch(host, true, &config, &input, &dir.path().join(host));
        let steps = arm_steps(&run);
        assert!(run.success, "{host}: {}", tail(&run.log, 30));
        let end = homing_end(&steps);
        // Joint space: the left joint homes alone (from its far limit, 90° away), then the right one.
        let left_last = steps[0]
            .iter()
            .rev()
            .find(|s| s.0 <= end)
            .expect("left homing")
            .0;
        assert!(
            left_last < steps[1][0].0,
            "{host}: the left joint still moved when the right one started"
        );
        for (k, stream) in steps.iter().enumerate() {
            let homing = stream.iter().filter(|s| s.0 <= end).count();
            assert!(
                homing > 4000,
                "{host}: {}: {homing} homing steps",
                MOTORS[k]
            );
        }
        let read = reported_readings(&run);
        for k in 0..2 {
            assert!(
                (read[k].to_degrees() - readings[k]).abs() < 1e-4,
                "{host}: {} reads {}°",
                MOTORS[k],
                read[k].to_degrees()
            );
        }
        let home = nozzle(readings.map(f64::to_radians)).expect("the homed pose");
        let reported = reported_xy(&run);
        assert!(
            (reported[0] - home[0]).abs() < 1e-5 && (reported[1] - home[1]).abs() < 1e-5,
            "{host}: homed at {reported:?}, the readings' pose is {home:?}"
        );
        audit_arms(
            &format!("after homing on {host}"),
            &run,
            end,
            &[reported, [40.0, 60.0], [-70.0, 20.0]],
        );
    }
}

/// The joints' readings (rad) GET_POSITION reports (`stepper: stepper_left:… stepper_right:…`).
fn reported_readings(run: &Run) -> [f64; 2] {
    let line = run
        .log
        .lines()
        .find(|l| l.starts_with("stepper:"))
        .unwrap_or_else(|| panic!("no GET_POSITION line:\n{}", tail(&run.log, 20)));
    MOTORS.map(|m| {
        let rest = line.split_once(&format!("{m}:")).expect(m).1;
        rest.split_whitespace()
            .next()
            .and_then(|v| v.parse().ok())
            .expect("a number")
    })
}

/// With `home_position` G28 declares the pose without moving; the status Mainsail shows holds the joint readings
/// (degrees, as the tests' inverse gives them), the reach margin and the base joints.
#[test]
fn the_fivebar_declares_its_home_and_shows_its_joints() {
    let Some(hosts) = Hosts::get("the_fivebar_declares_its_home_and_shows_its_joints") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let macro_text = "\n[gcode_macro SHOW_JOINTSPACE]\ngcode:\n  {action_respond_info(\"status %s %s %s\" % (\
         printer.toolhead.jointspace_joints, printer.toolhead.jointspace_offsets, \
         printer.toolhead.axis_maximum))}\n";
    let config = example_config(
        dir.path(),
        "printer.cfg",
        &[(
            "kinematics: jointspace_fivebar",
            "kinematics: jointspace_fivebar\nhome_position: 20, 30, 0.5",
        )],
        macro_text,
    );
    let input = write(
        dir.path(),
        "home.gcode",
        "G28\nGET_POSITION\nSHOW_JOINTSPACE\nG1 X-40 Y80 F3000\nM400\n",
    );
    for host in [KLIPPER, KALICO] {
        let run = hosts.batch(host, true, &config, &input, &dir.path().join(host));
        assert!(run.success, "{host}: {}", tail(&run.log, 30));
        assert_eq!(reported_xy(&run), [20.0, 30.0], "{host}");
        let status = run
            .log
            .lines()
            .find(|l| l.contains("status {"))
            .expect("status line");
        let [left, right] =
            crate::fivebar_reference::angles([20.0, 30.0], [2.0, 1.0]).expect("home has a pose");
        let reading = |name: &str| -> f64 {
            let rest = status.split_once(&format!("'{name}': ")).expect(name).1;
            rest.split([',', '}'])
                .next()
                .and_then(|v| v.trim().parse().ok())
                .expect("a number")
        };
        for (name, expected) in [("stepper_left", left), ("stepper_right", right)] {
            let expected = degrees_from(expected, -180.0);
            assert!(
                (reading(name) - expected).abs() < 1e-9,
                "{host}: {name} reads {} (expected {expected})",
                reading(name)
            );
        }
        for base in ["'left_base_x': -50.0", "'right_base_y': -200.0"] {
            assert!(status.contains(base), "{host}: {base} not in {status}");
        }
        // The XY bounds: within each side's 350 mm of its base.
        assert!(
            ["(300.0, 150.0, 150.0", "x=300.0, y=150.0, z=150.0"]
                .iter()
                .any(|bound| status.contains(bound)),
            "{host}: {status}"
        );
        audit_arms(
            &format!("declared home on {host}"),
            &run,
            0,
            &[[20.0, 30.0], [-40.0, 80.0]],
        );
    }
}

/// Moves the machine cannot make are refused at their line with the reason, and move nothing: beyond the left
/// arm's reach, into the parallel band (the distal links in line), and through the left arm's folded reach (over its
/// base joint). In batch mode the host exits at the first error,
/// dropping steps not yet generated, so each refusal ends its own run, after the moves before it have been stepped
/// (SET_KINEMATIC_POSITION flushes step generation): the stream after homing is exactly their path, and the motors
/// end where it ends.
#[test]
fn refused_fivebar_moves_move_nothing() {
    let Some(hosts) = Hosts::get("refused_fivebar_moves_move_nothing") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_config(
        dir.path(),
        "printer.cfg",
        &[],
        "\n[force_move]\nenable_force_move: True\n",
    );
    let cases: [(&[[f64; 2]], &str, &str, &str); 3] = [
        (
            &[[0.0, -170.0], [30.0, 100.0]],
            "G1 X0 Y200",
            "Move out of range: X0.000 Y200.000 Z",
            "(53.113 mm beyond the left arm's reach of 350 mm)",
        ),
        (
            &[[0.0, -170.0]],
            "G1 X0 Y-195",
            "Move out of range: X0.000 Y-195.000 Z",
            "((0.000, -181.317) is too close to the parallel singularity",
        ),
        (
            &[[0.0, -170.0]],
            "G1 X-100 Y-230",
            "Move out of range: X-100.000 Y-230.000 Z",
            "(passes 0.000 mm from the left base joint, inside its folded reach of 50 mm)",
        ),
    ];
    for host in [KLIPPER, KALICO] {
        for (i, (accepted, refused, target, reason)) in cases.iter().enumerate() {
            let mut gcode = String::from("G28\nGET_POSITION\nG4 P2000\nG1 F3000\n");
            for p in *accepted {
                gcode.push_str(&format!("G1 X{} Y{}\n", p[0], p[1]));
            }
            gcode.push_str(&format!("M400\nSET_KINEMATIC_POSITION\n{refused}\n"));
            let input = write(dir.path(), &format!("refused{i}.gcode"), &gcode);
            let run = hosts.batch(
                host,
                true,
                &config,
                &input,
                &dir.path().join(format!("{host}{i}")),
            );
            assert!(!run.success, "{host}: a refused move fails the batch run");
            // The G-code line's target (Kalico's homing leaves Z elsewhere than Klipper's), then why.
            let refusal = run.log.lines().find(|l| l.starts_with(target));
            assert!(
                refusal.is_some_and(|l| l.contains(reason)),
                "{host}: no '{target}… {reason}':\n{}",
                tail(&run.log, 30)
            );
            let steps = arm_steps(&run);
            let end = homing_end(&steps);
            // Where homing left the nozzle (Kalico's final retract stops the joints short of their endstops).
            let path: Vec<[f64; 2]> = std::iter::once(reported_xy(&run))
                .chain(accepted.iter().copied())
                .collect();
            let finished = Run {
                success: true,
                log: String::new(),
                out: run.out.clone(),
            };
            audit_arms(
                &format!("{refused} refused on {host}"),
                &finished,
                end,
                &path,
            );
        }
    }
}

/// The tests' reference geometry is the example's.
#[test]
fn the_reference_is_the_examples_machine() {
    let text = std::fs::read_to_string(workspace_root().join("klipper/examples/fivebar.cfg"))
        .expect("example");
    for (side, name) in SIDES.iter().zip(["left", "right"]) {
        for (key, value) in [
            ("base_x", side.base[0]),
            ("base_y", side.base[1]),
            ("proximal_length", side.proximal),
            ("distal_length", side.distal),
        ] {
            let line = format!("{name}_{key}: {value}");
            assert!(text.lines().any(|l| l == line), "{line}");
        }
    }
}
