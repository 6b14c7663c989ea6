//! `check` from outside: after a refused move it goes on from where the file meant to be (no follow-on errors
//! that are not there), and it exits non-zero when it found errors, also when its output pipe closed.

use std::process::{Command, Stdio};

use crate::common::{binary, example_machine};

fn check(text: &str) -> (Vec<String>, Option<i32>) {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("part.gcode");
    std::fs::write(&input, text).expect("write input");
    let output = Command::new(binary())
        .args(["check", "-c"])
        .arg(example_machine("polar"))
        .arg(&input)
        .output()
        .expect("run jointspace");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let problems = stdout
        .lines()
        .filter(|l| l.contains(": error: ") || l.contains(": warning: "))
        .map(|l| {
            l.split_once("part.gcode:")
                .map_or(l, |(_, rest)| rest)
                .to_string()
        })
        .collect();
    (problems, output.status.code())
}

#[test]
fn a_refused_move_makes_no_follow_on_errors() {
    // Line 5 extrudes far too much; lines 6-9 are ordinary moves (the last back to line 5's end point, which
    // after a skipped line 5 would look like an extrude-only move of all the E so far).
    let text = "G28\nG1 Z0.3 F600\nG1 X10 Y10 F1800\nG1 X10 Y20 E0.5\nG1 X30 Y20 E60\n\
G1 X30 Y30 E60.5\nG1 X20 Y30 E61\nG1 X40 Y30 E62\nG1 X30 Y20 E62.5\n";
    let (problems, code) = check(text);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].starts_with("5:1: error: move exceeds the maximum extrusion cross-section")
    );
    assert_eq!(code, Some(1));

    // An unreachable target: the machine stays, E goes on; the move back inside is fine.
    let text =
        "G28\nG1 Z0.3 F600\nG1 X100 Y0 F1800\nG1 X200 Y0 E1\nG1 X100 Y10 E1.5\nG1 X100 Y20 E2\n";
    let (problems, code) = check(text);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].starts_with("4:1: error: move to (200.000, 0.000, 0.300) is not reachable")
    );
    assert_eq!(code, Some(1));
}

#[test]
fn errors_give_a_non_zero_exit_even_when_the_output_pipe_closed() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("part.gcode");
    let mut text = String::from("G28\nG1 Z0.3 F600\nG1 X10 Y10 F1800\n");
    for i in 0..500 {
        text += &format!("G1 X{} Y10 E{}\n", 10 + i % 2 * 10, 60 * (i + 1));
    }
    std::fs::write(&input, &text).expect("write input");
    for _ in 0..3 {
        let mut child = Command::new(binary())
            .args(["check", "-c"])
            .arg(example_machine("polar"))
            .arg(&input)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start jointspace");
        // `jointspace check … | head -0`: the reader is gone before anything is written.
        drop(child.stdout.take());
        let output = child.wait_with_output().expect("wait");
        assert_eq!(
            output.status.code(),
            Some(1),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
}

/// Extruder steps of `run --skip-unreachable --json` on `text`.
fn extruder_steps(text: &str) -> u64 {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("part.gcode");
    std::fs::write(&input, text).expect("write input");
    let output = Command::new(binary())
        .args(["run", "--skip-unreachable", "--json", "-c"])
        .arg(example_machine("polar"))
        .arg(&input)
        .output()
        .expect("run jointspace");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    json["motors"]
        .as_array()
        .expect("motors")
        .iter()
        .find(|m| m["name"] == "extruder")
        .and_then(|m| m["steps"].as_u64())
        .expect("extruder steps")
}

#[test]
fn a_skipped_move_pushes_none_of_its_filament_into_the_next() {
    // Absolute E: line 6 is out of reach and skipped; the next moves extrude 0.5 mm each, as in the same file
    // without line 6 (before: the first of them tried to push the skipped 10 mm too and run stopped).
    let skipped = "G28\nM82\nG92 E0\nG1 Z0.3 F600\nG1 X100 Y0 F1800\nG1 X200 Y0 E10\nG1 X100 Y10 E10.5\n\
G1 X100 Y20 E11\n";
    let without =
        "G28\nM82\nG92 E0\nG1 Z0.3 F600\nG1 X100 Y0 F1800\nG1 X100 Y10 E0.5\nG1 X100 Y20 E1\n";
    let steps = extruder_steps(without);
    assert!(steps > 50, "{steps}");
    assert_eq!(extruder_steps(skipped), steps);
}

#[test]
fn errors_beyond_the_listed_ones_still_count() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("part.gcode");
    std::fs::write(
        &input,
        "G28\nG1 X10 Y0 Z1 F600\nG1 X300 Y0\nG1 X10 Y0\nG1 X400 Y0 Q1\n",
    )
    .expect("input");
    for (max, listed) in [("0", 0), ("1", 1), ("200", 3)] {
        let output = Command::new(binary())
            .args(["check", "--max-problems", max, "-c"])
            .arg(example_machine("polar"))
            .arg(&input)
            .output()
            .expect("run jointspace");
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert_eq!(
            output.status.code(),
            Some(1),
            "--max-problems {max}: {stdout}"
        );
        assert!(stdout.contains(": 2 errors, 1 warnings;"), "{stdout}");
        assert_eq!(
            stdout
                .lines()
                .filter(|l| l.contains(": error: ") || l.contains(": warning: "))
                .count(),
            listed
        );
    }
}

/// A SCARA whose joint endstops hold the arm straight loads for every arm length: the straight arm's homing pose,
/// which the forward kinematics puts a few ulps beyond `L1 + L2` for many lengths, is not refused as out of reach.
#[test]
fn a_straight_arm_homing_pose_loads_for_every_arm_length() {
    let example = std::fs::read_to_string(example_machine("scara")).expect("config");
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("part.gcode");
    std::fs::write(&input, "G28\nG1 Z1 F600\n").expect("write input");
    let mut refused = Vec::new();
    for i in 0..40 {
        let l1 = 90.0 + 1.5125 * i as f64;
        let l2 = 254.05 - l1;
        // Shoulder endstop at 45°, elbow motor at 45°/3: the elbow joint at 0°, the arm straight.
        let text = example
            .replace("position_endstop: 105", "position_endstop: 15")
            .replace("link1_length: 100", &format!("link1_length: {l1}"))
            .replace("link2_length: 100", &format!("link2_length: {l2}"))
            .replace("base_protection_radius: 60", "base_protection_radius: 0");
        let config = scratch.path().join("printer.cfg");
        std::fs::write(&config, text).expect("write config");
        let output = Command::new(binary())
            .args(["check", "-c"])
            .arg(&config)
            .arg(&input)
            .output()
            .expect("run jointspace");
        if output.status.code() != Some(0) {
            refused.push(format!(
                "{l1}/{l2}: {}",
                String::from_utf8_lossy(&output.stderr)
            ));
        }
    }
    assert!(refused.is_empty(), "{refused:#?}");
}
