//! The typed machine: Klipper defaults, deprecated keys, kinematics selection and the checks that
//! turn impossible machines into errors pointing at the value.

use std::f64::consts::TAU;

use config::{ConfigError, KinematicsKind, MachineConfig};
use kinematics::{ElbowBranch, MachineParams, ScaraFrame};

const STEPPERS_POLAR: &str = "
[stepper_bed]
step_pin: PF0
dir_pin: PF1
microsteps: 16
gear_ratio: 80:16

[stepper_arm]
step_pin: PF6
dir_pin: !PF7
microsteps: 16
rotation_distance: 40
endstop_pin: ^PJ1
position_endstop: 300
position_max: 300

[stepper_z]
step_pin: PL3
dir_pin: PL1
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0.5
position_max: 200
";

const STEPPERS_SCARA: &str = "
[stepper_a]
step_pin: PF0
dir_pin: PF1
microsteps: 16
gear_ratio: 60:20
endstop_pin: ^PE5
position_endstop: 0
position_min: -200
position_max: 200
homing_positive_dir: False

[stepper_b]
step_pin: PF6
dir_pin: PF7
microsteps: 16
gear_ratio: 60:20
endstop_pin: ^PJ1
position_endstop: 0
position_min: -200
position_max: 200
homing_positive_dir: False

[stepper_z]
step_pin: PL3
dir_pin: PL1
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0.5
position_max: 200
";

fn polar(printer_extra: &str) -> String {
    format!(
        "[printer]\nkinematics: polar\nmax_velocity: 300\nmax_accel: 3000\n{printer_extra}\n{STEPPERS_POLAR}"
    )
}

fn scara(printer_extra: &str) -> String {
    format!(
        "[printer]\nkinematics: scara\nmax_velocity: 300\nmax_accel: 3000\nlink1_length: 100\nlink2_length: 100\n{printer_extra}\n{STEPPERS_SCARA}"
    )
}

fn load(text: &str) -> Result<MachineConfig, ConfigError> {
    MachineConfig::from_str(text, "printer.cfg")
}

fn machine(text: &str) -> MachineConfig {
    load(text).unwrap_or_else(|err| panic!("config failed: {err}"))
}

fn error(text: &str) -> ConfigError {
    match load(text) {
        Ok(_) => panic!("expected an error"),
        Err(err) => err,
    }
}

/// (line, column) of an error's span, and the text it underlines.
fn place(err: &ConfigError) -> (usize, usize, String) {
    let span = err
        .span()
        .unwrap_or_else(|| panic!("error without span: {err}"));
    (span.line, span.column, span.text().to_string())
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .map_or(0, |i| i + 1)
}

#[test]
fn printer_defaults_follow_klipper() {
    let m = machine(&polar(""));
    let l = &m.limits;
    assert_eq!(
        (l.minimum_cruise_ratio, l.square_corner_velocity),
        (0.5, 5.0)
    );
    assert_eq!((l.max_z_velocity, l.max_z_accel), (300.0, 3000.0));
    assert_eq!(
        (l.max_angular_velocity, l.max_angular_accel, l.max_step_rate),
        (None, None, None)
    );
    // junction_deviation = scv² (√2 − 1) / max_accel, mcr pseudo accel = accel (1 − mcr).
    assert!((l.junction_deviation() - 25.0 * 0.414_213_562_373_095_1 / 3000.0).abs() < 1e-15);
    assert_eq!(l.mcr_pseudo_accel(), 1500.0);
    assert!(m.extruder.is_none() && m.arcs.is_none());
    assert_eq!(m.steppers.len(), 3);
}

#[test]
fn deprecated_max_accel_to_decel_is_converted() {
    let m = machine(&polar("max_accel_to_decel: 1500"));
    assert_eq!(m.limits.minimum_cruise_ratio, 1.0 - 1500.0 / 3000.0);
    assert_eq!(m.warnings.len(), 1);
    assert!(m.warnings[0].message.contains("deprecated"));
    let above = machine(&polar("max_accel_to_decel: 5000"));
    assert_eq!(above.limits.minimum_cruise_ratio, 0.0);
    let explicit = machine(&polar(
        "max_accel_to_decel: 1500\nminimum_cruise_ratio: 0.2",
    ));
    assert_eq!(explicit.limits.minimum_cruise_ratio, 0.2);
    assert!(
        error(&polar("minimum_cruise_ratio: 1"))
            .to_string()
            .contains("below 1")
    );
}

#[test]
fn z_limits_may_not_exceed_the_toolhead_limits() {
    let text = polar("max_z_velocity: 400");
    let err = error(&text);
    assert_eq!(
        place(&err),
        (line_of(&text, "max_z_velocity"), 17, "400".to_string())
    );
}

#[test]
fn unknown_kinematics_is_unsupported_with_location() {
    let text = "[printer]\nkinematics: delta\nmax_velocity: 1\nmax_accel: 1\n";
    let err = error(text);
    assert!(
        matches!(&err, ConfigError::UnsupportedKinematics { name, .. } if name == "delta"),
        "{err}"
    );
    assert_eq!(place(&err), (2, 13, "delta".to_string()));
}

#[test]
fn empty_file_has_no_printer_section() {
    let err = error("");
    assert!(
        matches!(&err, ConfigError::MissingSection { section, .. } if section == "printer"),
        "{err}"
    );
    assert!(matches!(
        error("# only a comment\n\n"),
        ConfigError::MissingSection { .. }
    ));
}

#[test]
fn missing_required_printer_keys() {
    let err = error("[printer]\nkinematics: polar\nmax_velocity: 300\n");
    assert!(
        matches!(&err, ConfigError::MissingKey { key, span, .. } if key == "max_accel" && span.line == 1),
        "{err}"
    );
    assert!(matches!(
        error(&polar("").replace("[stepper_arm]", "[stepper_xx]")),
        ConfigError::MissingSection { .. }
    ));
}

#[test]
fn rotary_steppers_need_gear_ratio_and_refuse_rotation_distance() {
    let text = polar("").replace("gear_ratio: 80:16\n", "");
    let err = error(&text);
    assert!(
        matches!(&err, ConfigError::MissingKey { key, section, .. } if key == "gear_ratio" && section == "stepper_bed"),
        "{err}"
    );
    let text = polar("").replace(
        "gear_ratio: 80:16\n",
        "gear_ratio: 80:16\nrotation_distance: 360\n",
    );
    assert_eq!(place(&error(&text)).2, "360");
}

#[test]
fn full_steps_must_be_divisible_by_four() {
    let text = polar("").replace(
        "gear_ratio: 80:16\n",
        "gear_ratio: 80:16\nfull_steps_per_rotation: 202\n",
    );
    assert_eq!(place(&error(&text)).2, "202");
    let ok = polar("").replace(
        "gear_ratio: 80:16\n",
        "gear_ratio: 80:16\nfull_steps_per_rotation: 400\n",
    );
    let m = machine(&ok);
    assert_eq!(
        m.stepper("stepper_bed").map(|s| s.step_distance),
        Some(TAU / 32000.0)
    );
}

#[test]
fn bad_ratio_in_a_stepper_points_at_it() {
    let text = polar("").replace("gear_ratio: 80:16", "gear_ratio: 80:0");
    let err = error(&text);
    assert_eq!(
        place(&err),
        (line_of(&text, "80:0"), 13, "80:0".to_string())
    );
}

#[test]
fn homing_direction_is_inferred_or_refused() {
    let m = machine(&polar(""));
    let dir = |name: &str| {
        m.stepper(name)
            .and_then(|s| s.homing.as_ref())
            .map(|h| h.positive_dir)
    };
    assert_eq!(dir("stepper_arm"), Some(true));
    assert_eq!(dir("stepper_z"), Some(false));
    let text = polar("").replace("position_endstop: 0.5", "position_endstop: 100");
    let err = error(&text);
    assert!(err.to_string().contains("homing_positive_dir"), "{err}");
    let contradiction = polar("").replace(
        "position_endstop: 300\n",
        "position_endstop: 300\nhoming_positive_dir: false\n",
    );
    assert_eq!(place(&error(&contradiction)).2, "false");
    let outside = polar("").replace("position_endstop: 300", "position_endstop: 301");
    assert_eq!(place(&error(&outside)).2, "301");
}

#[test]
fn dir_pin_inversion_and_step_rate_default() {
    let m = machine(&polar("max_step_rate: 100000").replace(
        "rotation_distance: 8\n",
        "rotation_distance: 8\nmax_step_rate: 5000\n",
    ));
    assert_eq!(
        m.stepper("stepper_arm").map(|s| s.dir_inverted()),
        Some(true)
    );
    assert_eq!(
        m.stepper("stepper_bed").map(|s| s.dir_inverted()),
        Some(false)
    );
    assert_eq!(
        m.stepper("stepper_bed").and_then(|s| s.max_step_rate),
        Some(100000.0)
    );
    assert_eq!(
        m.stepper("stepper_z").and_then(|s| s.max_step_rate),
        Some(5000.0)
    );
}

#[test]
fn polar_jointspace_keys() {
    let m = machine(&polar(
        "max_angular_velocity: 5\nmax_angular_accel: 50\narm_zero_offset: 0.3\narm_lateral_offset: -0.2",
    ));
    assert_eq!(
        (m.limits.max_angular_velocity, m.limits.max_angular_accel),
        (Some(5.0), Some(50.0))
    );
    let MachineParams::Polar(p) = &m.params else {
        panic!("polar")
    };
    assert_eq!((p.arm_zero_offset, p.arm_lateral_offset), (0.3, -0.2));
    assert_eq!(m.kinematics, KinematicsKind::Polar);
}

#[test]
fn extruder_defaults_from_nozzle_and_filament() {
    let text = polar("")
        + "\n[extruder]\nstep_pin: PA4\ndir_pin: PA6\nmicrosteps: 16\nrotation_distance: 33.5\nnozzle_diameter: 0.4\nfilament_diameter: 1.75\nheater_pin: PB4\n";
    let m = machine(&text);
    let e = m.extruder.as_ref().expect("extruder");
    let area = std::f64::consts::PI * 1.75 * 1.75 / 4.0;
    assert!((e.max_extrude_cross_section - 0.64).abs() < 1e-15);
    assert!((e.max_extrude_ratio - 0.64 / area).abs() < 1e-15);
    assert!((e.max_extrude_only_velocity - 300.0 * 0.64 / area).abs() < 1e-12);
    assert!((e.max_extrude_only_accel - 3000.0 * 0.64 / area).abs() < 1e-10);
    assert_eq!(e.stepper.step_distance, 33.5 / 3200.0);
    assert_eq!(m.steppers.last().map(|s| s.name.as_str()), Some("extruder"));
    assert!(m.unused_keys().is_empty());
    let thin = text.replace("filament_diameter: 1.75", "filament_diameter: 0.3");
    assert_eq!(place(&error(&thin)).2, "0.3");
}

#[test]
fn pressure_advance_is_warned_about_at_its_key() {
    let base = polar("")
        + "\n[extruder]\nstep_pin: PA4\ndir_pin: PA6\nmicrosteps: 16\nrotation_distance: 33.5\nnozzle_diameter: 0.4\nfilament_diameter: 1.75\nheater_pin: PB4\n";
    assert!(machine(&base).warnings.is_empty());
    let m = machine(&(base.clone() + "pressure_advance: 0.05\n"));
    assert_eq!(m.warnings.len(), 1);
    let warning = &m.warnings[0];
    assert!(
        warning.message.contains("pressure_advance is not modelled"),
        "{warning}"
    );
    let line = base.lines().count() + 1;
    assert_eq!(
        warning.span.as_ref().map(|s| s.line),
        Some(line),
        "{warning}"
    );
}

#[test]
fn misspelt_keys_are_reported_as_unused() {
    let m = machine(&polar("max_velocty: 200"));
    let unused = m.unused_keys();
    assert_eq!(unused.len(), 1);
    assert_eq!(
        (unused[0].section.as_str(), unused[0].key.as_str()),
        ("printer", "max_velocty")
    );
    assert_eq!(unused[0].span.column, 1);
    // Keys of other kinematics are not read either.
    let m = machine(&polar("max_joint_velocity: 3"));
    assert_eq!(m.unused_keys().len(), 1);
}

#[test]
fn extra_stepper_sections_are_warned_about() {
    let text = polar("") + "\n[stepper_z1]\nstep_pin: PA1\n";
    let m = machine(&text);
    assert!(m.warnings.iter().any(|w| w.message.contains("stepper_z1")));
}

#[test]
fn scara_keys_with_degrees_and_branches() {
    let m = machine(&scara(
        "ecr: 3\nelbow: right\nframe: xscara\nshoulder_zero: 90\nelbow_min: -150\nelbow_max: 150\nmax_joint_velocity: 4\nmax_joint_accel: 40",
    ));
    let MachineParams::Scara(p) = &m.params else {
        panic!("scara")
    };
    assert_eq!(p.elbow, ElbowBranch::Right);
    assert_eq!(p.frame, ScaraFrame::XScara);
    assert_eq!(p.shoulder_zero, std::f64::consts::FRAC_PI_2);
    assert_eq!(
        p.elbow_limits,
        Some((-150f64.to_radians(), 150f64.to_radians()))
    );
    assert_eq!(p.shoulder_limits, None);
    assert_eq!(p.base_protection_radius, 60.0);
    assert_eq!(
        (m.limits.max_joint_velocity, m.limits.max_joint_accel),
        (Some(4.0), Some(40.0))
    );
    assert_eq!(p.shoulder_stepper.step_distance, TAU / 9600.0);
}

#[test]
fn scara_coupling_from_ecr_or_elbow_coupling() {
    let direct = machine(&scara("elbow_coupling: 1"));
    let MachineParams::Scara(p) = &direct.params else {
        panic!("scara")
    };
    assert_eq!((p.elbow_coupling, p.ecr), (1.0, None));
    let both = machine(&scara("ecr: 3\nelbow_coupling: 0.3333333333"));
    let MachineParams::Scara(p) = &both.params else {
        panic!("scara")
    };
    assert_eq!((p.elbow_coupling, p.ecr), (1.0 / 3.0, Some(3.0)));
    let text = scara("ecr: 3\nelbow_coupling: 0.5");
    assert_eq!(
        place(&error(&text)),
        (line_of(&text, "elbow_coupling"), 17, "0.5".to_string())
    );
    assert!(matches!(
        error(&scara("")),
        ConfigError::InvalidSection { .. }
    ));
    assert!(error(&scara("ecr: 0")).to_string().contains("above 0"));
}

#[test]
fn scara_joint_limits_need_both_ends_in_order() {
    assert!(
        error(&scara("ecr: 3\nshoulder_min: -90"))
            .to_string()
            .contains("shoulder_max")
    );
    assert!(
        error(&scara("ecr: 3\nshoulder_min: 90\nshoulder_max: 10"))
            .to_string()
            .contains("shoulder_min")
    );
    assert!(
        error(&scara("ecr: 3\nelbow: sideways"))
            .to_string()
            .contains("left, right")
    );
    assert!(
        error(&scara("ecr: 3\nhome_position: 1"))
            .to_string()
            .contains("2 or 3")
    );
    assert!(
        error(&scara("ecr: 3\nlink1_length: 0").replacen("link1_length: 100\n", "", 1))
            .to_string()
            .contains("above 0")
    );
}

#[test]
fn extreme_values_are_refused_instead_of_producing_inf_or_nan() {
    let tiny_gear = polar("").replace("gear_ratio: 80:16", "gear_ratio: 1e-300:1e300");
    assert_eq!(place(&error(&tiny_gear)).2, "1e-300:1e300");
    let huge_gear = polar("").replace(
        "rotation_distance: 40",
        "rotation_distance: 40\ngear_ratio: 1e300:1e-300",
    );
    assert!(error(&huge_gear).to_string().contains("step distance"));
    let huge_nozzle = polar("")
        + "\n[extruder]\nstep_pin: PA4\ndir_pin: PA6\nmicrosteps: 16\nrotation_distance: 33.5\nnozzle_diameter: 1e200\nfilament_diameter: 1e200\n";
    assert!(error(&huge_nozzle).to_string().contains("unusable"));
    let tiny_ecr = scara("ecr: 1e-320");
    assert_eq!(place(&error(&tiny_ecr)).2, "1e-320");
}

#[test]
fn plugin_kinematics_names_load_the_same_machines() {
    // One printer.cfg serves the Klipper plug-in and the CLI: its names mean the same machines.
    for (ours, plain) in [
        (
            polar("").replace("kinematics: polar", "kinematics: jointspace_polar"),
            polar(""),
        ),
        (
            scara("ecr: 3").replace("kinematics: scara", "kinematics: jointspace_scara"),
            scara("ecr: 3"),
        ),
    ] {
        let (a, b) = (machine(&ours), machine(&plain));
        assert_eq!(a.kinematics, b.kinematics);
        assert_eq!(a.params, b.params);
    }
}

/// The step audit's limit: `max_step_rate` where set (the stepper's, else `[printer]`'s), else one step per
/// `step_pulse_duration`, else one per Klipper's default 2 µs pulse.
#[test]
fn step_rate_limits_come_from_the_rate_the_pulse_or_klippers_default() {
    use config::StepRateSource::{DefaultStepPulse, MaxStepRate, StepPulse};
    let limit = |text: &str, stepper: &str| {
        let l = machine(text).step_rate_limit(stepper).expect("a stepper");
        (l.steps_per_second, l.source)
    };
    assert_eq!(
        limit(&scara("ecr: 1"), "stepper_a"),
        (500_000.0, DefaultStepPulse)
    );
    assert_eq!(
        limit(&scara("ecr: 1\nmax_step_rate: 40000"), "stepper_a"),
        (40_000.0, MaxStepRate)
    );
    let pulse = scara("ecr: 1").replace(
        "[stepper_b]\n",
        "[stepper_b]\nstep_pulse_duration: 0.000000100\n",
    );
    assert_eq!(limit(&pulse, "stepper_a"), (500_000.0, DefaultStepPulse));
    let (rate, source) = limit(&pulse, "stepper_b");
    assert_eq!(source, StepPulse);
    assert!((rate - 1e7).abs() < 1e-6, "{rate}");
    let both = pulse.replace(
        "step_pulse_duration",
        "max_step_rate: 123\nstep_pulse_duration",
    );
    assert_eq!(limit(&both, "stepper_b"), (123.0, MaxStepRate));
    assert!(
        machine(&scara("ecr: 1"))
            .step_rate_limit("stepper_q")
            .is_none()
    );
    let describe = machine(&scara("ecr: 1"))
        .step_rate_limit("stepper_a")
        .expect("a")
        .describe();
    assert!(
        describe.contains("Klipper's default 2 µs step pulse"),
        "{describe}"
    );
}
