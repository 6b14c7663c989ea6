//! Klipper's own regression tests `exclude_object.test` and `multi_z.test` (`test/klippy/` of the pinned tree) with
//! the kinematics swapped for `jointspace_polar`: their moves end on X0 Y0, leave it, and reach the probe points
//! through Z_TILT_ADJUST and BED_TILT_CALIBRATE (moves sent to the toolhead directly, not through G-code), all of
//! which must complete.

use crate::hosts::{Hosts, KLIPPER, tail, write};

/// The test's cartesian config as a polar printer: `[stepper_x]`'s driver turns the bed (80:16, no endstop),
/// `[stepper_y]`'s drives a 300 mm arm homing at its end; everything else as it is.
fn polar_config(cartesian: &str) -> String {
    let mut out = String::new();
    let mut section = String::new();
    for line in cartesian.lines() {
        if line.starts_with('[') {
            section = line.to_string();
            match line {
                "[stepper_x]" => {
                    out.push_str("[stepper_bed]\ngear_ratio: 80:16\n");
                    continue;
                }
                "[stepper_y]" => {
                    out.push_str("[stepper_arm]\nposition_endstop: 300\nposition_max: 300\n");
                    continue;
                }
                _ => {}
            }
        }
        let key = line.split(':').next().unwrap_or("").trim();
        let dropped = match section.as_str() {
            "[stepper_x]" => {
                ["rotation_distance", "endstop_pin", "homing_speed"].contains(&key)
                    || key.starts_with("position_")
                    || key.starts_with("homing_")
            }
            "[stepper_y]" => key.starts_with("position_"),
            _ => false,
        };
        if line.trim() == "kinematics: cartesian" {
            out.push_str("kinematics: jointspace_polar\n");
        } else if !dropped {
            out.push_str(line);
            out.push('\n');
        }
    }
    out + "\n[jointspace]\n"
}

#[test]
fn klippers_regression_tests_pass_with_jointspace_polar() {
    let Some(hosts) = Hosts::get("klippers_regression_tests_pass_with_jointspace_polar") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let tests = hosts.tree(KLIPPER, false).join("test/klippy");
    for name in ["exclude_object", "multi_z"] {
        let cfg = std::fs::read_to_string(tests.join(format!("{name}.cfg"))).expect("test config");
        let test = std::fs::read_to_string(tests.join(format!("{name}.test"))).expect("test");
        let gcode: String = test
            .lines()
            .filter(|l| !l.starts_with("CONFIG") && !l.starts_with("DICTIONARY"))
            .map(|l| format!("{l}\n"))
            .collect();
        let cfg = write(dir.path(), &format!("{name}.cfg"), &polar_config(&cfg));
        let input = write(dir.path(), &format!("{name}.gcode"), &gcode);
        let run = hosts.batch(KLIPPER, false, &cfg, &input, &dir.path().join(name));
        assert!(
            run.success && !run.log.contains("shutdown"),
            "{name}.test with jointspace_polar:\n{}",
            tail(&run.log, 30)
        );
    }
}
