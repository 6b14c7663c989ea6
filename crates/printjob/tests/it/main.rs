//! The assembled job against independent references: step files read back as an MCU would execute them, checked
//! against the closed-form motor positions; problems at their G-code lines; outputs never over inputs.

mod digests;

use std::path::{Path, PathBuf};

use printjob::{Machine, RunError, RunOptions, Severity};

const POLAR: &str = include_str!("../../../../examples/machines/polar.cfg");

fn polar(extra_printer_keys: &str) -> Machine {
    let text = POLAR.replace("[printer]\n", &format!("[printer]\n{extra_printer_keys}"));
    let config = config::MachineConfig::from_str(&text, "polar.cfg").expect("config");
    Machine::from_config(config, "polar.cfg").expect("machine")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write");
    path
}

/// Net steps of a step file read back: +1 per step with dir 1, −1 with dir 0.
fn net_steps(path: &Path) -> i64 {
    stepgen::read_step_file(path)
        .expect("step file")
        .iter()
        .map(|s| if s.dir { 1 } else { -1 })
        .sum()
}

#[test]
fn a_run_writes_step_files_whose_positions_are_the_closed_form_motor_positions() {
    let dir = tempfile::tempdir().expect("temp dir");
    let machine = polar("");
    // Homed at the arm's endstop (r = 150, bed angle 0); then to (0, 60): r 60, bed a quarter turn.
    let gcode = "G28\nG1 X0 Y60 Z5 F3000\n";
    let options = RunOptions {
        steps: Some(dir.path().join("steps")),
        ..RunOptions::default()
    };
    let summary =
        printjob::run(&machine, gcode.as_bytes(), "in.gcode", &options, || false).expect("runs");
    let steps = dir.path().join("steps");
    let arm_step = 40.0 / (200.0 * 16.0);
    let bed_step = std::f64::consts::TAU / (200.0 * 16.0 * 5.0);
    let z_step = 8.0 / (200.0 * 16.0);
    let expect = |motor: &str, travel: f64, step: f64| {
        let net = net_steps(&steps.join(format!("{motor}.txt")));
        assert!(
            (net as f64 - travel / step).abs() <= 1.0,
            "{motor}: {net} steps for {travel}"
        );
    };
    expect("stepper_arm", 60.0 - 150.0, arm_step);
    expect("stepper_bed", std::f64::consts::FRAC_PI_2, bed_step);
    expect("stepper_z", 5.0 - 0.5, z_step);
    assert_eq!(summary.toolhead_moves, 1);
    assert!(summary.print_time_s > 0.0);
}

#[test]
fn a_step_stream_too_fast_for_the_mcu_is_an_error_naming_motor_time_and_line() {
    let dir = tempfile::tempdir().expect("temp dir");
    let machine = polar("max_step_rate: 2000\n");
    let gcode = "G28\nG1 X100 Y0 F3000\nG1 E-2 F3000\nG1 E2\n";
    let file = write(dir.path(), "in.gcode", gcode);
    let options = RunOptions {
        steps: Some(dir.path().join("steps")),
        ..RunOptions::default()
    };
    let err = printjob::run(&machine, gcode.as_bytes(), "in.gcode", &options, || false)
        .expect_err("refused");
    let RunError::Steps(e) = err else {
        panic!("not a step-stream error: {err}")
    };
    assert_eq!(e.motor, "extruder");
    let line = printjob::audit::locate(&machine, options.plan, &file, e.time);
    assert_eq!(line, Some(3));
    // Nothing half-written: the step files appear only with a complete, audited run, and the folder made for them
    // goes with them.
    assert!(!dir.path().join("steps").exists());
    // A check flags what the run refuses, at the same line.
    let problem = printjob::audit_file(&machine, &file, "in.gcode").expect("flagged");
    assert_eq!((problem.span.line, problem.severity), (3, Severity::Error));
}

#[test]
fn a_check_reports_every_problem_at_its_line_and_goes_on() {
    let machine = polar("");
    let gcode = "G28\nG1 X500 Y0 F3000\nG1 X10 Y10\nG1 X0 Y900\nG1 X20 Y20\n";
    let report = printjob::check_gcode(&machine.setup, gcode.as_bytes(), "in.gcode", 10);
    let errors: Vec<u64> = report
        .problems
        .iter()
        .filter(|p| p.severity == Severity::Error)
        .map(|p| p.span.line)
        .collect();
    assert_eq!(errors, [2, 4]);
    assert_eq!(report.errors(), 2);
    // At most `max_problems` are kept, all are counted.
    let report = printjob::check_gcode(&machine.setup, gcode.as_bytes(), "in.gcode", 1);
    assert_eq!((report.problems.len(), report.errors()), (1, 2));
}

#[test]
fn the_moves_file_never_replaces_an_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let machine = polar("");
    let gcode = "G28\nG1 X10 Y10 F3000\n";
    let input = write(dir.path(), "in.gcode", gcode);
    outfile::register_input(&input);
    let options = RunOptions {
        moves: Some(input.clone()),
        ..RunOptions::default()
    };
    let err = printjob::run(&machine, gcode.as_bytes(), "in.gcode", &options, || false)
        .expect_err("refused");
    assert!(matches!(err, RunError::Output(_)), "{err}");
    assert_eq!(std::fs::read_to_string(&input).expect("input"), gcode);
}

#[test]
fn a_cancelled_run_fails_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let machine = polar("");
    let gcode = "G28\nG1 X10 Y10 F3000\nG1 X20 Y-10\n".repeat(50);
    let options = RunOptions {
        steps: Some(dir.path().join("steps")),
        moves: Some(dir.path().join("moves.csv")),
        ..RunOptions::default()
    };
    let err = printjob::run(&machine, gcode.as_bytes(), "in.gcode", &options, || true)
        .expect_err("cancelled");
    assert!(matches!(err, RunError::Cancelled), "{err}");
    assert!(!dir.path().join("moves.csv").exists());
    assert!(
        !dir.path().join("steps").exists(),
        "an empty step folder is left"
    );
}
