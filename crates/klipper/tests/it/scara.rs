//! `jointspace_scara` on the FEKT-SCARA fork against the FEKT module's own steps: the shared `scara-fekt-*`
//! golden cases, exact mode (step compression 0), Z limits raised where the fork ignores them.

use std::ffi::OsStr;

use crate::engine::run_jointspace;
use crate::hosts::{
    Hosts, KALICO_FEKT, assert_same_steps, plugin_config, read_step_dir, shared, write,
};

fn golden_case(case: &str) {
    let Some(hosts) = Hosts::get(case) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let golden = shared().join("golden").join(case);
    let text = std::fs::read_to_string(golden.join("printer.cfg")).expect("golden config");
    let line = |key: &str| {
        text.lines()
            .find(|l| l.starts_with(key))
            .unwrap_or_else(|| panic!("{case}: no {key}"))
            .trim()
            .to_string()
    };
    // The fork applies no Z limits: raise ours to max_velocity/max_accel so they bind nowhere.
    let config = plugin_config(
        &golden.join("printer.cfg"),
        &[
            ("kinematics: scara", "kinematics: jointspace_scara"),
            (&line("max_z_velocity"), "max_z_velocity: 300"),
            (&line("max_z_accel"), "max_z_accel: 3000"),
        ],
        dir.path(),
        "printer.cfg",
    );
    let run = hosts.batch(
        KALICO_FEKT,
        true,
        &config,
        &golden.join("input.gcode"),
        &dir.path().join("out"),
    );
    run.expect_success(case);
    let worst = assert_same_steps(case, &read_step_dir(&golden.join("steps")), &run.steps(), 1);
    println!(
        "{case}: every stepper's steps as the FEKT module's, largest clock difference {worst} ticks"
    );
}

#[test]
fn fekt_synthetic_steps_are_the_fekt_modules() {
    golden_case("scara-fekt-synthetic");
}

#[test]
fn fekt_cura_hex_steps_are_the_fekt_modules() {
    golden_case("scara-fekt-cura-hex");
}

/// From a Slic3r benchy late in the print (lines 13,746–13,755, moved into the arm's workspace): a short travel that
/// reverses onto a slow, nearly collinear extrusion. Kalico's lookahead caps the travel's peak at the slow move's
/// speed (20 mm/s) where Klipper's would let it reach 22.4 mm/s, and every later move starts 96 µs apart.
/// `jointspace run --host kalico-fekt` plans as the fork: its steps are the fork's own (FEKT module, exact mode).
#[test]
fn a_travel_before_a_slow_move_peaks_as_the_forks_lookahead() {
    let Some(hosts) = Hosts::get("a_travel_before_a_slow_move_peaks_as_the_forks_lookahead") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let golden = shared().join("golden/scara-fekt-cura-hex");
    let text = std::fs::read_to_string(golden.join("printer.cfg")).expect("golden config");
    let config = write(dir.path(), "printer.cfg", &text);
    let gcode = write(
        dir.path(),
        "reversal.gcode",
        "SET_KINEMATIC_POSITION X=0 Y=130 Z=0.5\nG92 E0\nG1 Z0.3 F600\nG1 X8.913 Y115.219 F6600\nG1 X8.958 Y115.634\n\
         G1 X8.488 Y115.743\nG1 F1200\nG1 X8.398 Y115.698 E0.05\nG1 X8.488 Y115.743 F6600\nG1 F1200\n\
         G1 X9.637 Y116.200 E0.1\nG1 X8.109 Y115.686 F6600\nG1 X20 Y130 E0.3 F1200\nM400\n",
    );
    let run = hosts.batch(KALICO_FEKT, true, &config, &gcode, &dir.path().join("fork"));
    run.expect_success("the fork");
    let ours = dir.path().join("ours");
    run_jointspace([
        OsStr::new("run"),
        OsStr::new("-c"),
        config.as_os_str(),
        OsStr::new("--host"),
        OsStr::new("kalico-fekt"),
        OsStr::new("--klipper-batch"),
        OsStr::new("--steps"),
        ours.as_os_str(),
        gcode.as_os_str(),
    ]);
    let worst = assert_same_steps("reversal", &run.steps(), &read_step_dir(&ours), 1);
    println!(
        "a travel before a slow move: the fork's steps, largest clock difference {worst} ticks"
    );
}

/// The FEKT arm homes to the straight arm, a pose it may only rest at. Inside Klipper the plug-in ends every move
/// that arrives there at rest (Klipper's next junction set to zero) and caps the part beside it as an acceleration
/// from rest: with `max_joint_velocity: 5` the arm leaves the pose, comes back to the band (Y199.99) and to the
/// pose itself, and each joint, read from the steps Klipper sends, stays within 5 rad/s.
#[test]
fn the_arm_reaches_and_leaves_the_straight_pose_at_rest() {
    let Some(hosts) = Hosts::get("the_arm_reaches_and_leaves_the_straight_pose_at_rest") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = plugin_config(
        &shared().join("golden/scara-fekt-synthetic/printer.cfg"),
        &[(
            "kinematics: scara",
            "kinematics: jointspace_scara\nmax_joint_velocity: 5",
        )],
        dir.path(),
        "printer.cfg",
    );
    let gcode = write(
        dir.path(),
        "straight.gcode",
        "G28\nG1 X0 Y150 F6000\nG1 X0 Y199.99\nG1 X0 Y150\nG1 X0 Y200\nG1 X20 Y150\nM400\nGET_POSITION\n",
    );
    let run = hosts.batch(
        crate::hosts::KLIPPER,
        true,
        &config,
        &gcode,
        &dir.path().join("out"),
    );
    run.expect_success("to the straight arm and back");
    assert!(
        run.log.contains("toolhead: X:20.000000 Y:150.000000"),
        "{}",
        crate::hosts::tail(&run.log, 20)
    );
    let step = std::f64::consts::TAU / 9600.0;
    for (name, steps) in run.steps() {
        if !name.starts_with("stepper_a") && !name.starts_with("stepper_b") {
            continue;
        }
        let peak = steps
            .windows(17)
            .filter(|w| w.iter().all(|s| s.1 == w[0].1))
            .map(|w| 16.0 * step * 16e6 / (w[16].0 - w[0].0) as f64)
            .fold(0.0, f64::max);
        println!("{name}: peak {peak:.3} rad/s");
        assert!(peak <= 5.0 * 1.01, "{name} at {peak} rad/s");
    }
}
