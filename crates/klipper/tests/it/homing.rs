//! Homing and refusals inside Klipper (batch mode: an endstop "triggers" at the end of its homing move).
//! A SCARA with joint endstops homes each joint alone in joint space and then stands where forward kinematics
//! puts the endstop angles; moves the machine cannot make are refused with Klipper's error and the reason.

use std::collections::BTreeMap;
use std::path::Path;

use crate::hosts::{Hosts, KLIPPER, Step, plugin_config, shared, write};

/// FEKT's example arm (100/100 mm, ECR 3) with joint endstops at 30° (shoulder, homing towards −) and 90°
/// (elbow motor, homing towards +), no declared `home_position`.
fn scara_with_endstops(dir: &Path) -> Option<std::path::PathBuf> {
    let base = shared().join("golden/scara-fekt-synthetic/printer.cfg");
    if !base.is_file() {
        return None;
    }
    let text = std::fs::read_to_string(&base).expect("config");
    let a = text.replacen("position_endstop: 0\n", "position_endstop: 30\n", 1);
    let b = a.replacen("position_endstop: 0\n", "position_endstop: 90\n", 1);
    let b = b.replacen(
        "homing_positive_dir: False\n\n[stepper_z]",
        "homing_positive_dir: True\n\n[stepper_z]",
        1,
    );
    assert!(b.contains("position_endstop: 90") && b.contains("homing_positive_dir: True"));
    let edited = write(dir, "base.cfg", &b);
    Some(plugin_config(
        &edited,
        &[
            ("kinematics: scara", "kinematics: jointspace_scara"),
            ("home_position: 0, 200, 0", ""),
        ],
        dir,
        "printer.cfg",
    ))
}

/// Motor angles (rad) of a point for the FEKT arm, closed form (REFERENCE.md §2), left elbow.
fn fekt_inverse(x: f64, y: f64) -> (f64, f64) {
    let (l1, l2, ecr) = (100.0_f64, 100.0_f64, 3.0);
    let cos_q2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
    let q2 = cos_q2.acos();
    let q1 = y.atan2(x) - (l2 * q2.sin()).atan2(l1 + l2 * q2.cos());
    (q1, q2 + q1 / ecr)
}

/// Nozzle position of motor angles (rad), closed form.
fn fekt_forward(a: f64, b: f64) -> (f64, f64) {
    let (q1, q2) = (a, b - a / 3.0);
    (
        100.0 * q1.cos() + 100.0 * (q1 + q2).cos(),
        100.0 * q1.sin() + 100.0 * (q1 + q2).sin(),
    )
}

/// Net steps (sum of ±1) after `after` (MCU clock).
fn net_after(steps: &[Step], after: i64) -> i64 {
    steps
        .iter()
        .filter(|s| s.0 > after)
        .map(|s| if s.1 == 1 { 1 } else { -1 })
        .sum()
}

#[test]
fn scara_homes_each_joint_in_joint_space() {
    let Some(hosts) = Hosts::get("scara_homes_each_joint_in_joint_space") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let Some(config) = scara_with_endstops(dir.path()) else {
        return;
    };
    // After homing, a pause (so the steps of the move are told apart by time), then one move.
    let gcode = write(
        dir.path(),
        "home.gcode",
        "G28 X Y\nGET_POSITION\nG4 P2000\nG1 X50 Y120 F3000\nM400\n",
    );
    let mut outputs = Vec::new();
    for attempt in 0..3 {
        let run = hosts.batch(
            KLIPPER,
            true,
            &config,
            &gcode,
            &dir.path().join(format!("run{attempt}")),
        );
        run.expect_success("homing");
        outputs.push((run.queue_step(), run.steps(), run.log));
    }
    // Three runs (Klipper steps motors on several threads): identical output.
    assert!(outputs.iter().all(|o| o.0 == outputs[0].0), "runs differ");
    let (_, steps, log) = &outputs[0];
    let (a, b) = (&steps["stepper_a"], &steps["stepper_b"]);
    // Homing ends at the first pause of over a second (the dwell) after the elbow motor's first step.
    let mut clocks: Vec<i64> = a.iter().chain(b.iter()).map(|s| s.0).collect();
    clocks.sort_unstable();
    let pause = 16_000_000;
    let homing_end = clocks
        .windows(2)
        .find(|w| w[0] >= b[0].0 && w[1] - w[0] > pause)
        .map(|w| w[0])
        .expect("a pause after homing");
    // Joint space: the shoulder homes alone, then the elbow motor alone.
    let a_homing: Vec<&Step> = a.iter().filter(|s| s.0 <= homing_end).collect();
    let a_last = a_homing.last().expect("shoulder homing steps").0;
    assert!(
        a_homing.len() > 4000,
        "the shoulder made {} homing steps",
        a_homing.len()
    );
    assert!(
        a_last < b[0].0,
        "the shoulder was still moving when the elbow motor started"
    );
    assert!(
        b.iter().filter(|s| s.0 <= homing_end).count() > 7000,
        "the elbow motor did not home"
    );
    // The pose after homing is forward kinematics of the endstop angles.
    let (x, y) = fekt_forward(30f64.to_radians(), 90f64.to_radians());
    let reported = log
        .lines()
        .find(|l| l.starts_with("toolhead:"))
        .expect("GET_POSITION's toolhead line");
    let expected = format!("toolhead: X:{x:.6} Y:{y:.6}");
    assert!(
        reported.starts_with(&expected),
        "{reported} (expected {expected})"
    );
    // The move after homing: each motor's net steps are the closed-form angle change.
    let step = std::f64::consts::TAU / (200.0 * 16.0 * 3.0);
    let (a1, b1) = fekt_inverse(50.0, 120.0);
    let (a0, b0) = (30f64.to_radians(), 90f64.to_radians());
    let start = homing_end + pause;
    let nets: BTreeMap<&str, (i64, f64)> = [
        ("stepper_a", (net_after(a, start), (a1 - a0) / step)),
        ("stepper_b", (net_after(b, start), (b1 - b0) / step)),
    ]
    .into();
    for (motor, (net, expected)) in nets {
        assert!(
            (net as f64 - expected).abs() <= 1.0,
            "{motor}: {net} steps, expected {expected:.2}"
        );
    }
}

#[test]
fn unreachable_moves_are_refused_with_the_reason() {
    let Some(hosts) = Hosts::get("unreachable_moves_are_refused_with_the_reason") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let Some(scara) = scara_with_endstops(dir.path()) else {
        return;
    };
    let polar = plugin_config(
        &shared().join("golden/polar-synthetic/printer.cfg"),
        &[("kinematics: polar", "kinematics: jointspace_polar")],
        dir.path(),
        "polar.cfg",
    );
    // Without span cuts a move through the centre is still made (the bed turns in place there); one beyond the
    // arm's reach is refused naming its target and by how much.
    let text = std::fs::read_to_string(&polar).expect("config") + "split_moves: False\n";
    std::fs::write(&polar, text).expect("write");
    // Each refused move leaves the toolhead where it was; Klipper goes on with the next line.
    let cases: [(&Path, &str, &[&str]); 2] = [
        (
            &scara,
            "SET_KINEMATIC_POSITION X=0 Y=130 Z=0.5\nG1 X0 Y30 F3000\nG1 X0 Y250\nG1 X-50 Y120\nG1 X0 Y205\n",
            // Y250 lies beyond reach (said so before anything else about the move).
            &[
                "Move out of range: X0.000 Y30.000 Z0.500 (passes 30.000 mm from the shoulder, inside the base \
                 radius of 60 mm)",
                "Move out of range: X0.000 Y250.000 Z0.500 (50.000 mm beyond the arm's reach of 200 mm)",
                "Move out of range: X0.000 Y205.000 Z0.500 (5.000 mm beyond the arm's reach of 200 mm)",
                "Move out of range",
            ],
        ),
        (
            &polar,
            "SET_KINEMATIC_POSITION X=300 Y=0 Z=0.5\nG1 X100 Y0 F3000\nG1 X-100 Y0\nG1 X350 Y0\n",
            &[
                "Move out of range: X350.000 Y0.000 Z0.500 (50.000 mm beyond the arm's reach of 300 mm)",
            ],
        ),
    ];
    for (i, (config, gcode, phrases)) in cases.into_iter().enumerate() {
        let input = write(dir.path(), &format!("refused{i}.gcode"), gcode);
        let run = hosts.batch(
            KLIPPER,
            false,
            config,
            &input,
            &dir.path().join(format!("refused{i}")),
        );
        assert!(
            !run.success,
            "case {i}: refused moves must fail the batch run"
        );
        for phrase in phrases {
            assert!(
                run.log.contains(phrase),
                "case {i}: no '{phrase}' in the log:\n{}",
                crate::hosts::tail(&run.log, 30)
            );
        }
    }
}

/// FEKT-SCARA's homing: with `home_position` the XY joints are declared at that pose (no motion), as the FEKT
/// module does; the status Mainsail shows under `printer.toolhead` then holds the joint angles, the reach margin
/// and the offsets.
#[test]
fn declared_home_and_status() {
    let Some(hosts) = Hosts::get("declared_home_and_status") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let base = shared().join("golden/scara-fekt-synthetic/printer.cfg");
    let config = plugin_config(
        &base,
        &[
            ("kinematics: scara", "kinematics: jointspace_scara"),
            (
                "home_position: 0, 200, 0",
                "home_position: 0, 141.4213562373095, 0",
            ),
        ],
        dir.path(),
        "printer.cfg",
    );
    let mut text = std::fs::read_to_string(&config).expect("config");
    text.push_str(
        "\n[gcode_macro SHOW_JOINTSPACE]\ngcode:\n  {action_respond_info(\"status %s %s %s\" % (\
         printer.toolhead.jointspace_joints, printer.toolhead.jointspace_reach_margin, \
         printer.toolhead.jointspace_offsets))}\n",
    );
    std::fs::write(&config, text).expect("write");
    let gcode = write(
        dir.path(),
        "home.gcode",
        "G28\nGET_POSITION\nSHOW_JOINTSPACE\nG1 X20 Y150 F3000\nM400\n",
    );
    let run = hosts.batch(KLIPPER, false, &config, &gcode, &dir.path().join("out"));
    run.expect_success("declared home");
    assert!(
        run.log
            .contains("toolhead: X:0.000000 Y:141.421356 Z:0.500000"),
        "{}",
        crate::hosts::tail(&run.log, 20)
    );
    // q1 = 45°, q2 = 90°: the elbow motor reads 90 + 45/3 = 105°. 141.42 mm from the shoulder; the base
    // protection 60 mm inside, the singular band (|sin q2| < 0.05) from √(2·10⁴·(1 + √(1 − 0.05²))) =
    // 199.937 mm outside: margin 58.516 mm.
    let status = run
        .log
        .lines()
        .find(|l| l.contains("status {"))
        .expect("status line");
    for needed in [
        "'stepper_a': 45.0",
        "'stepper_b': 105.0",
        " 58.516",
        "'offset_x': 0.0",
    ] {
        assert!(status.contains(needed), "{needed} not in {status}");
    }
}

/// A polar bed with an endstop homes after the arm, in degrees; the pose is forward kinematics of both.
#[test]
fn polar_bed_with_an_endstop_homes_after_the_arm() {
    let Some(hosts) = Hosts::get("polar_bed_with_an_endstop_homes_after_the_arm") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = plugin_config(
        &shared().join("golden/polar-synthetic/printer.cfg"),
        &[
            ("kinematics: polar", "kinematics: jointspace_polar"),
            (
                "gear_ratio: 80:16",
                "gear_ratio: 80:16\nendstop_pin: ^PE5\nposition_endstop: 90\nposition_min: -360\n\
                 position_max: 360\nhoming_speed: 30\nhoming_positive_dir: true",
            ),
        ],
        dir.path(),
        "printer.cfg",
    );
    let gcode = write(
        dir.path(),
        "home.gcode",
        "G28\nGET_POSITION\nG1 X0 Y250 F3000\nM400\n",
    );
    let run = hosts.batch(KLIPPER, false, &config, &gcode, &dir.path().join("out"));
    run.expect_success("bed homing");
    // Bed at 90°, arm at its 300 mm endstop: (300·cos 90°, 300·sin 90°).
    let expected = format!(
        "toolhead: X:{:.6} Y:300.000000",
        300.0 * 90f64.to_radians().cos()
    );
    assert!(
        run.log.contains(&expected),
        "{expected}: {}",
        crate::hosts::tail(&run.log, 20)
    );
    let queue = run.queue_step();
    let oid = queue
        .lines()
        .find(|l| l.starts_with("config_stepper") && l.contains("step_pin=PF0"))
        .and_then(|l| l.split_whitespace().nth(1))
        .expect("the bed's config_stepper")
        .to_string();
    let bed_steps = queue
        .lines()
        .filter(|l| l.starts_with(&format!("queue_step {oid} ")))
        .count();
    assert!(bed_steps > 0, "the bed did not move while homing");
}

/// `printer.toolhead.jointspace_joints` are the motors' readings: after two full turns of the bed clockwise and a
/// quarter back, the bed reads −630°, not the 90° the toolhead position's inverse gives; on the centre, where the
/// position has no bed angle, the readings are still there (the bed where it arrived, the arm at 0).
#[test]
fn status_shows_the_motors_readings() {
    let Some(hosts) = Hosts::get("status_shows_the_motors_readings") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = plugin_config(
        &shared().join("golden/polar-synthetic/printer.cfg"),
        &[("kinematics: polar", "kinematics: jointspace_polar")],
        dir.path(),
        "printer.cfg",
    );
    let mut text = std::fs::read_to_string(&config).expect("config");
    text.push_str(
        "\n[gcode_arcs]\nresolution: 1.0\n[gcode_macro SHOW_JOINTSPACE]\ngcode:\n  {action_respond_info(\"joints %s\" % (\
         printer.toolhead.jointspace_joints,))}\n",
    );
    std::fs::write(&config, text).expect("write");
    let gcode = write(
        dir.path(),
        "turns.gcode",
        "SET_KINEMATIC_POSITION X=100 Y=0 Z=1\nG2 X100 Y0 I-100 J0 F6000\nG2 X100 Y0 I-100 J0\n\
         G1 X0 Y100\nM400\nSHOW_JOINTSPACE\nG1 X0 Y0\nM400\nSHOW_JOINTSPACE\n",
    );
    let run = hosts.batch(KLIPPER, false, &config, &gcode, &dir.path().join("out"));
    run.expect_success("turns");
    let shown: Vec<(f64, f64)> = run
        .log
        .lines()
        .filter_map(|l| l.split_once("joints {"))
        .map(|(_, rest)| {
            let value = |name: &str| -> f64 {
                let after = rest.split_once(&format!("'{name}': ")).expect(name).1;
                let number: String = after
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || "-.e".contains(*c))
                    .collect();
                number.parse().expect("a number")
            };
            (value("stepper_bed"), value("stepper_arm"))
        })
        .collect();
    let bed_step = 360.0 / 16000.0;
    assert_eq!(shown.len(), 2, "{}", crate::hosts::tail(&run.log, 20));
    assert!(
        (shown[0].0 + 630.0).abs() <= bed_step,
        "bed {} after the turns",
        shown[0].0
    );
    assert!((shown[0].1 - 100.0).abs() <= 0.0125, "arm {}", shown[0].1);
    assert!(
        (shown[1].0 + 630.0).abs() <= bed_step,
        "bed {} on the centre",
        shown[1].0
    );
    assert!(
        shown[1].1.abs() <= 0.0125,
        "arm {} on the centre",
        shown[1].1
    );
}
