//! `jointspace simulate --correct`: the uncorrected report is always written, and a correction that cannot be
//! simulated is said why (in the report, its JSON and on standard error, exit status 3).

use crate::common::{example_machine, jointspace_in};
use std::path::Path;

/// A line printed 0.5 mm beside the bed's axis, and a travel away from it.
const BESIDE_THE_AXIS: &str =
    "G28\nM83\nG1 X20 Y0.5 Z0.3 F3000\nG1 X-20 Y0.5 E2 F1200\nG1 X-20 Y10 E0.5\n";

/// The example polar printer as believed, and as built with its arm `lateral` mm beside the axis.
fn polar_pair(dir: &Path, lateral: f64) {
    let text = std::fs::read_to_string(example_machine("polar")).expect("example config");
    std::fs::write(dir.join("believed.cfg"), &text).expect("believed");
    let actual = format!("{text}\n[printer]\narm_lateral_offset: {lateral}\n");
    std::fs::write(dir.join("actual.cfg"), actual).expect("actual");
    std::fs::write(dir.join("line.gcode"), BESIDE_THE_AXIS).expect("gcode");
}

fn simulate_correct(dir: &Path) -> std::process::Output {
    jointspace_in(
        dir,
        &[
            "simulate",
            "-c",
            "believed.cfg",
            "--actual",
            "actual.cfg",
            "line.gcode",
            "-o",
            "report",
            "--correct",
        ],
    )
}

fn report_json(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("report/report.json")).expect("report.json");
    serde_json::from_str(&text).expect("json")
}

/// The deposited path's largest deviation in the report's `run` ("before" or "after"), mm.
fn max_deviation(json: &serde_json::Value, run: &str) -> f64 {
    json[run]["deposited"]["max_path_deviation"]
        .as_f64()
        .expect(run)
}

/// An arm built 1.5 mm beside the axis never comes nearer the axis than 1.5 mm (its line passes the axis at that
/// distance), so the corrected machine cannot print a line 0.5 mm from it: the "before" report is written, the
/// reason for no "after" names the G-code line, exit status 3.
#[test]
fn a_correction_the_print_cannot_take_still_writes_the_uncorrected_report() {
    let dir = tempfile::tempdir().expect("temp dir");
    polar_pair(dir.path(), 1.5);
    let output = simulate_correct(dir.path());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    let json = report_json(dir.path());
    let why = json["after_missing"].as_str().expect("the reason");
    assert!(why.contains("line.gcode:4:1:"), "{why}");
    assert!(json["after"].is_null());
    // The calibration was made: its measured offset is the built one (the scan's 0.01 mm).
    let measured = json["correction"]["values"][1]["measured"]
        .as_f64()
        .expect("measured");
    assert!((measured - 1.5).abs() < 0.01, "{measured}");
    // The uncorrected run, whole: the line printed 1.5 mm off at most.
    let before = max_deviation(&json, "before");
    assert!(before > 0.5 && before < 1.6, "{before}");
    assert!(
        stderr.contains("warning: the correction was not simulated")
            && stderr.contains("line.gcode:4:1:")
    );
    let text = std::fs::read_to_string(dir.path().join("report/report.txt")).expect("report.txt");
    assert!(
        text.contains("== as configured ==") && text.contains(&format!("not simulated: {why}"))
    );
    assert!(dir.path().join("report/overlay.png").is_file());
    assert!(!dir.path().join("report/overlay-after.png").exists());
}

/// The same line with the arm 0.3 mm beside the axis: the corrected machine reaches it, the "after" is there.
#[test]
fn a_correction_the_print_can_take_is_simulated() {
    let dir = tempfile::tempdir().expect("temp dir");
    polar_pair(dir.path(), 0.3);
    let output = simulate_correct(dir.path());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = report_json(dir.path());
    assert!(json["after_missing"].is_null());
    let before = max_deviation(&json, "before");
    let after = max_deviation(&json, "after");
    assert!(before > 0.25 && after < 0.05, "{before} → {after}");
    assert!(dir.path().join("report/overlay-after.png").is_file());
}

/// A SCARA built with ECR 3.2 and a 100.5 mm proximal link, configured as the example's ECR 3 and 100 mm: the
/// correction is calibrated from the printed pattern's crosses as measured, says the noise it assumed and the
/// fit's verdict, and leaves the assembly error within 0.03 mm.
#[test]
fn a_scara_is_corrected_from_its_printed_pattern() {
    let dir = tempfile::tempdir().expect("temp dir");
    let text = std::fs::read_to_string(example_machine("scara")).expect("example config");
    std::fs::write(dir.path().join("believed.cfg"), &text).expect("believed");
    let actual = format!("{text}\n[printer]\nlink1_length: 100.5\necr: 3.2\n");
    std::fs::write(dir.path().join("actual.cfg"), actual).expect("actual");
    let mut gcode = String::from("G28\nM83\nG1 X20 Y130 Z0.3 F3000\n");
    for k in 1..=72 {
        let t = std::f64::consts::TAU * f64::from(k) / 72.0;
        gcode += &format!(
            "G1 X{:.3} Y{:.3} E0.06 F1200\n",
            20.0 * t.cos(),
            130.0 + 20.0 * t.sin()
        );
    }
    std::fs::write(dir.path().join("line.gcode"), gcode).expect("gcode");
    let output = simulate_correct(dir.path());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = report_json(dir.path());
    let correction = &json["correction"];
    let method = correction["method"].as_str().expect("method");
    assert!(
        method.contains("printed by the machine as built"),
        "{method}"
    );
    let notes = correction["notes"].to_string();
    assert!(
        notes.contains("0.02 mm noise") && notes.contains("read to 0.01 mm"),
        "{notes}"
    );
    assert!(notes.contains("trustworthy"), "{notes}");
    let before = json["before"]["deposited"]["max_model_error"]
        .as_f64()
        .expect("before");
    let after = json["after"]["deposited"]["max_model_error"]
        .as_f64()
        .expect("after");
    assert!(before > 1.0 && after < 0.03, "{before} → {after}");
    let text = std::fs::read_to_string(dir.path().join("report/report.txt")).expect("report.txt");
    assert!(text.contains("0.02 mm noise (1σ per coordinate), read to 0.01 mm"));
}

/// A five-bar built with its right base 0.4 mm off, the left distal link 0.3 mm long and the right zero at −0.4°,
/// configured as the example: the report's circle is measured, the correction is the five-bar's identification
/// from its printed pattern (trustworthy), and the assembly error left is within 0.03 mm.
#[test]
fn a_fivebar_is_corrected_from_its_printed_pattern() {
    let dir = tempfile::tempdir().expect("temp dir");
    let text = std::fs::read_to_string(example_machine("fivebar")).expect("example config");
    std::fs::write(dir.path().join("believed.cfg"), &text).expect("believed");
    let errors = "right_base_x: 50.4\nleft_distal_length: 200.3\nright_zero: -0.4";
    let actual = format!("{text}\n[printer]\n{errors}\n");
    std::fs::write(dir.path().join("actual.cfg"), actual).expect("actual");
    let mut gcode = String::from("G28\nM83\nG1 X20 Y40 Z0.3 F3000\n");
    for k in 1..=72 {
        let t = std::f64::consts::TAU * f64::from(k) / 72.0;
        gcode += &format!(
            "G1 X{:.3} Y{:.3} E0.06 F1200\n",
            20.0 * t.cos(),
            40.0 + 20.0 * t.sin()
        );
    }
    std::fs::write(dir.path().join("line.gcode"), gcode).expect("gcode");
    let output = simulate_correct(dir.path());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let json = report_json(dir.path());
    let method = json["correction"]["method"].as_str().expect("method");
    assert!(method.starts_with("five-bar identification"), "{method}");
    assert!(
        json["correction"]["notes"]
            .to_string()
            .contains(": trustworthy")
    );
    let error = |run: &str| {
        json[run]["deposited"]["max_model_error"]
            .as_f64()
            .expect(run)
    };
    assert!(
        error("before") > 0.5 && error("after") < 0.03,
        "{} → {}",
        error("before"),
        error("after")
    );
    assert!(
        json["before"]["circles"]
            .as_array()
            .is_some_and(|c| !c.is_empty()),
        "{json}"
    );
}
