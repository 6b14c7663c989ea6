//! `--json` on every command that reports (check, convert, calibrate, workspace, run — errors included), and
//! warnings that name their file.

use std::process::Output;

use crate::common::{example_machine, jointspace_in as jointspace};

fn json_of(output: &Output) -> serde_json::Value {
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}\n{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

/// Line 3 has a parameter G1 ignores (a warning), line 4 a move out of reach (an error).
const PART: &str = "G28\nG1 X10 Y0 Z1 F600\nG1 X11 Y0 Q5\nG1 X300 Y0\nG1 X20 Y0\n";

fn scratch() -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("part.gcode"), PART).expect("input");
    let cfg = example_machine("polar").display().to_string();
    (dir, cfg)
}

#[test]
fn check_json_lists_every_problem() {
    let (dir, cfg) = scratch();
    let output = jointspace(dir.path(), &["check", "-c", &cfg, "part.gcode", "--json"]);
    assert_eq!(output.status.code(), Some(1));
    let json = json_of(&output);
    assert_eq!(json["errors"], 1);
    assert_eq!(json["warnings"], 1);
    let problems = json["problems"].as_array().expect("problems");
    assert_eq!(
        (problems[0]["line"].as_u64(), problems[0]["column"].as_u64()),
        (Some(3), Some(11))
    );
    assert_eq!(problems[0]["severity"], "warning");
    assert_eq!(
        problems[0]["message"],
        "parameter Q ignored by this command"
    );
    assert_eq!(
        (
            problems[1]["line"].as_u64(),
            problems[1]["severity"].as_str()
        ),
        (Some(4), Some("error"))
    );
}

#[test]
fn run_json_reports_its_error_as_json() {
    let (dir, cfg) = scratch();
    let output = jointspace(dir.path(), &["run", "-c", &cfg, "part.gcode", "--json"]);
    assert_eq!(output.status.code(), Some(1));
    let json = json_of(&output);
    assert_eq!(json["error"]["file"], "part.gcode");
    assert_eq!(
        (
            json["error"]["line"].as_u64(),
            json["error"]["column"].as_u64()
        ),
        (Some(4), Some(1))
    );
    assert!(
        json["error"]["message"]
            .as_str()
            .expect("message")
            .contains("not reachable")
    );
}

#[test]
fn convert_json_gives_counts_verification_and_errors() {
    let (dir, cfg) = scratch();
    std::fs::write(
        dir.path().join("ok.gcode"),
        "G28\nG1 X10 Y0 Z1 F600\nG1 X20 Y5 E1\n",
    )
    .expect("input");
    let args = [
        "convert",
        "-c",
        &cfg,
        "ok.gcode",
        "-o",
        "out.gcode",
        "--verify",
        "--json",
    ];
    let output = jointspace(dir.path(), &args);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = json_of(&output);
    assert_eq!(json["moves"], 1);
    assert_eq!(json["firmware"], "Marlin");
    assert_eq!(
        json["verification"]["filament_in_mm"],
        json["verification"]["filament_out_mm"]
    );
    assert!(json["verification_failure"].is_null());
    // An error: as JSON on stdout, with its place.
    let args = [
        "convert",
        "-c",
        &cfg,
        "part.gcode",
        "-o",
        "bad.gcode",
        "--json",
    ];
    let output = jointspace(dir.path(), &args);
    assert_eq!(output.status.code(), Some(1));
    let json = json_of(&output);
    assert_eq!(json["error"]["line"], 4);
    assert!(!dir.path().join("bad.gcode").exists());
}

#[test]
fn calibrate_json_is_the_result() {
    let (dir, _) = scratch();
    let args = [
        "calibrate",
        "centre",
        "--simulate",
        "--offset",
        "0.5,-0.3",
        "-o",
        "c.json",
        "--json",
    ];
    let output = jointspace(dir.path(), &args);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = json_of(&output);
    assert!((json["arm_zero_offset"].as_f64().expect("dx") - 0.5).abs() < 0.01);
    assert!((json["arm_lateral_offset"].as_f64().expect("dy") + 0.3).abs() < 0.01);
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("c.json")).expect("file"))
            .expect("json");
    assert_eq!(file, json);
}

#[test]
fn warnings_name_their_file() {
    let (dir, cfg) = scratch();
    std::fs::write(
        dir.path().join("w.gcode"),
        "G28\nG1 X10 Y0 Z1 F600\nG1 X11 Y0 Q5\n",
    )
    .expect("input");
    let run = jointspace(dir.path(), &["run", "-c", &cfg, "w.gcode"]);
    assert!(
        String::from_utf8_lossy(&run.stdout).contains("w.gcode:3:11: warning: parameter Q ignored")
    );
    let check = jointspace(dir.path(), &["check", "-c", &cfg, "w.gcode"]);
    let text = String::from_utf8_lossy(&check.stdout);
    assert!(
        text.contains("w.gcode:3:11: warning: parameter Q ignored by this command\n"),
        "{text}"
    );
    let convert = jointspace(
        dir.path(),
        &["convert", "-c", &cfg, "w.gcode", "-o", "o.gcode"],
    );
    assert!(convert.status.success());
    let text = String::from_utf8_lossy(&convert.stderr);
    assert!(
        text.contains("w.gcode:3:11: warning: parameter Q ignored"),
        "{text}"
    );
}

#[test]
fn simulate_names_the_file_of_a_planning_error() {
    let (dir, cfg) = scratch();
    std::fs::write(
        dir.path().join("fat.gcode"),
        "G28\nG1 X10 Y0 Z1 F600\nG1 X20 Y0 E50\n",
    )
    .expect("input");
    let output = jointspace(
        dir.path(),
        &[
            "simulate",
            "-c",
            &cfg,
            "--actual",
            &cfg,
            "fat.gcode",
            "-o",
            "report",
        ],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("fat.gcode:3:1: move exceeds the maximum extrusion cross-section"),
        "{stderr}"
    );
}

/// The fastest written speed (written units per second) of X (the arm, mm) and Y (the bed, degrees) over the
/// timed `G1` lines of converted G-code (absolute axes, F in mm/min of the combined X Y Z distance).
fn fastest_axes(written: &str) -> [f64; 2] {
    let (mut pos, mut feed, mut fastest) = ([0.0f64; 3], 0.0f64, [0.0f64; 2]);
    for line in written.lines() {
        let code = line.split(';').next().unwrap_or("");
        let mut words = code.split_ascii_whitespace();
        let head = words.next();
        let before = pos;
        for w in words {
            let value: f64 = w[1..].parse().expect("a number");
            match &w[..1] {
                "X" => pos[0] = value,
                "Y" => pos[1] = value,
                "Z" => pos[2] = value,
                "F" => feed = value,
                _ => {}
            }
        }
        if head != Some("G1") {
            continue;
        }
        let d = [0, 1, 2].map(|i| pos[i] - before[i]);
        let length = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        if length > 0.0 {
            let time = 60.0 * length / feed;
            for i in 0..2 {
                fastest[i] = fastest[i].max(d[i].abs() / time);
            }
        }
    }
    fastest
}

#[test]
fn convert_keeps_the_configs_motor_speed_limits() {
    let (dir, _) = scratch();
    let cfg = std::fs::read_to_string(example_machine("polar")).expect("config");
    // The bed at 5 rad/s, the arm at 8000 steps/s (80 steps/mm: 100 mm/s).
    let cfg = cfg
        .replace("[printer]\n", "[printer]\nmax_angular_velocity: 5\n")
        .replace(
            "position_max: 150\n",
            "position_max: 150\nmax_step_rate: 8000\n",
        );
    std::fs::write(dir.path().join("limited.cfg"), cfg).expect("config");
    // A travel 1 µm beside the centre, one 1 µm … 0.1 mm away, and printing lines through the middle.
    std::fs::write(
        dir.path().join("near.gcode"),
        "G28\nG1 X-30 Y0.000001 Z1 F12000\nG1 X30 Y0.001\nG1 X-30 Y0.1\nG1 X30 Y-5 E2 F6000\n",
    )
    .expect("input");
    let args = [
        "convert",
        "-c",
        "limited.cfg",
        "near.gcode",
        "-o",
        "out.gcode",
        "--verify",
        "--json",
    ];
    let output = jointspace(dir.path(), &args);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = json_of(&output);
    assert!(
        json["limited_segments"].as_u64().is_some_and(|n| n > 0),
        "{json}"
    );
    let v = &json["verification"];
    assert_eq!(v["over_limit_segments"], 0, "{json}");
    let limited = v["motor_limited_time_s"].as_f64().expect("a time");
    let (time_in, time_out) = (v["time_in_s"].as_f64(), v["time_out_s"].as_f64());
    assert!(time_out > time_in && limited > 0.0, "{json}");
    let written = std::fs::read_to_string(dir.path().join("out.gcode")).expect("output");
    let [arm, bed] = fastest_axes(&written);
    let bed = bed.to_radians();
    assert!(
        arm <= 100.0 * 1.001 && bed <= 5.0 * 1.001,
        "arm {arm} mm/s, bed {bed} rad/s"
    );
    assert!(
        arm >= 99.9 || bed >= 4.995,
        "no limit binds: arm {arm} mm/s, bed {bed} rad/s"
    );
}
