//! `jointspace_scara` on the FEKT-SCARA fork against the FEKT module's own steps: the shared `scara-fekt-*`
//! golden cases, exact mode (step compression 0), Z limits raised where the fork ignores them.

use crate::hosts::{Hosts, KALICO_FEKT, assert_same_steps, plugin_config, read_step_dir, shared};

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
