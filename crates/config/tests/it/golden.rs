//! Every golden `printer.cfg` (and the benchmark config) loads, and its steppers, limits and kinematics
//! match `summary.json` and the values written in the file (read here by an independent scanner).

use std::f64::consts::TAU;
use std::path::Path;

use config::{KinematicsKind, MachineConfig, StepperUnits};
use kinematics::MachineParams;
use serde_json::Value;

use crate::{raw_f64, raw_value, shared_dir};

/// Step distances stated in the brief / golden README, as exact literals.
const POLAR_BED_STEP: f64 = 0.00039269908169872416;
const SCARA_JOINT_STEP: f64 = 0.0006544984694978735;

fn ulps_apart(a: f64, b: f64) -> u64 {
    (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
}

fn golden_cases() -> Vec<std::path::PathBuf> {
    let Some(shared) = shared_dir() else {
        return Vec::new();
    };
    let mut cases: Vec<_> = std::fs::read_dir(shared.join("golden"))
        .map(|dir| dir.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    cases.retain(|p| p.join("printer.cfg").is_file() && p.join("summary.json").is_file());
    cases.sort();
    cases
}

fn load(path: &Path) -> MachineConfig {
    match MachineConfig::load(path) {
        Ok(machine) => machine,
        Err(err) => panic!("{} failed to load: {err}", path.display()),
    }
}

#[test]
fn stated_step_distances_are_bit_exact() {
    assert_eq!((TAU / 16000.0).to_bits(), POLAR_BED_STEP.to_bits());
    for case in golden_cases() {
        let machine = load(&case.join("printer.cfg"));
        let step = |name: &str| machine.stepper(name).map(|s| s.step_distance);
        match machine.kinematics {
            KinematicsKind::Polar => {
                assert_eq!(
                    step("stepper_bed").map(f64::to_bits),
                    Some(POLAR_BED_STEP.to_bits())
                );
                assert_eq!(step("stepper_arm"), Some(0.0125));
            }
            KinematicsKind::Scara => {
                assert_eq!(
                    step("stepper_a").map(f64::to_bits),
                    Some(SCARA_JOINT_STEP.to_bits())
                );
                assert_eq!(
                    step("stepper_b").map(f64::to_bits),
                    Some(SCARA_JOINT_STEP.to_bits())
                );
                assert_eq!(step("stepper_a"), Some(TAU / 9600.0));
            }
            KinematicsKind::Cartesian => {
                assert_eq!(step("stepper_x"), Some(0.0125));
                assert_eq!(step("stepper_y"), Some(0.0125));
            }
            KinematicsKind::Fivebar => panic!("Klipper has no five-bar: no golden case is one"),
        }
        assert_eq!(step("stepper_z"), Some(0.0025));
        assert_eq!(step("extruder"), Some(33.5 / 3200.0));
    }
}

#[test]
fn steppers_match_summary_json() {
    let cases = golden_cases();
    for case in &cases {
        let machine = load(&case.join("printer.cfg"));
        let summary: Value = serde_json::from_str(
            &std::fs::read_to_string(case.join("summary.json")).unwrap_or_default(),
        )
        .unwrap_or(Value::Null);
        let steppers = summary["steppers"].as_object().cloned().unwrap_or_default();
        assert!(
            steppers.len() >= 4,
            "{}: summary has steppers",
            case.display()
        );
        assert_eq!(machine.steppers.len(), steppers.len(), "{}", case.display());
        for (name, expected) in &steppers {
            let Some(stepper) = machine.stepper(name) else {
                panic!("{}: stepper {name} missing", case.display());
            };
            let want_step = expected["step_dist"].as_f64().unwrap_or(f64::NAN);
            // serde_json's default float parser may differ from correct rounding by one ulp.
            assert!(
                ulps_apart(stepper.step_distance, want_step) <= 1,
                "{name}: {} vs {want_step}",
                stepper.step_distance
            );
            assert_eq!(
                Some(u64::from(stepper.microsteps)),
                expected["microsteps"].as_u64(),
                "{name}"
            );
            assert_eq!(
                Some(u64::from(stepper.full_steps_per_rotation)),
                expected["full_steps_per_rotation"].as_u64()
            );
            assert_eq!(
                Some(stepper.gear_ratio),
                expected["gear_ratio"].as_f64(),
                "{name}"
            );
            assert_eq!(
                Some(stepper.dir_inverted()),
                expected["dir_pin_inverted"].as_bool(),
                "{name}"
            );
            assert_eq!(
                Some(stepper.step_pin.name.as_str()),
                expected["step_pin"].as_str(),
                "{name}"
            );
            let rotary = expected["units"].as_str() == Some("rad");
            assert_eq!(stepper.units == StepperUnits::Radians, rotary, "{name}");
            match expected["rotation_distance"].as_f64() {
                Some(rd) => assert_eq!(stepper.rotation_distance, rd, "{name}"),
                None => assert_eq!(stepper.rotation_distance, TAU, "{name}"),
            }
        }
    }
    println!("checked {} golden configs", cases.len());
}

#[test]
fn limits_and_extruder_match_the_file() {
    for case in golden_cases() {
        let path = case.join("printer.cfg");
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        let machine = load(&path);
        check_limits(&machine, &text);
        check_extruder(&machine, &text);
        check_rails(&machine, &text);
        assert_eq!(
            machine.arcs.is_some(),
            text.contains("[gcode_arcs]"),
            "{}",
            path.display()
        );
        if let Some(arcs) = machine.arcs {
            assert_eq!(
                Some(arcs.resolution),
                raw_f64(&text, "gcode_arcs", "resolution")
            );
        }
        assert!(
            machine.unused_keys().is_empty(),
            "{}: {:?}",
            path.display(),
            machine.unused_keys()
        );
        assert!(
            machine.warnings.is_empty(),
            "{}: {:?}",
            path.display(),
            machine.warnings
        );
    }
}

fn check_limits(machine: &MachineConfig, text: &str) {
    let limits = &machine.limits;
    assert_eq!(
        Some(machine.kinematics.name().to_string()),
        raw_value(text, "printer", "kinematics")
    );
    assert_eq!(
        Some(limits.max_velocity),
        raw_f64(text, "printer", "max_velocity")
    );
    assert_eq!(
        Some(limits.max_accel),
        raw_f64(text, "printer", "max_accel")
    );
    assert_eq!(
        Some(limits.max_z_velocity),
        raw_f64(text, "printer", "max_z_velocity")
    );
    assert_eq!(
        Some(limits.max_z_accel),
        raw_f64(text, "printer", "max_z_accel")
    );
    assert_eq!(limits.square_corner_velocity, 5.0);
    assert_eq!(limits.minimum_cruise_ratio, 0.5);
}

fn check_extruder(machine: &MachineConfig, text: &str) {
    let Some(extruder) = &machine.extruder else {
        panic!("golden configs have an extruder");
    };
    let nozzle = raw_f64(text, "extruder", "nozzle_diameter").unwrap_or(f64::NAN);
    let filament = raw_f64(text, "extruder", "filament_diameter").unwrap_or(f64::NAN);
    assert_eq!(extruder.nozzle_diameter, nozzle);
    assert_eq!(extruder.filament_diameter, filament);
    let area = std::f64::consts::PI * filament * filament / 4.0;
    let default_section = 4.0 * nozzle * nozzle;
    let section = raw_f64(text, "extruder", "max_extrude_cross_section").unwrap_or(default_section);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
    assert!(close(extruder.filament_area, area));
    assert!(close(extruder.max_extrude_cross_section, section));
    assert!(close(extruder.max_extrude_ratio, section / area));
    assert!(close(
        extruder.max_extrude_only_velocity,
        machine.limits.max_velocity * default_section / area
    ));
    assert!(close(
        extruder.max_extrude_only_accel,
        machine.limits.max_accel * default_section / area
    ));
    assert_eq!(extruder.max_extrude_only_distance, 50.0);
    assert_eq!(extruder.instantaneous_corner_velocity, 1.0);
    assert_eq!(extruder.pressure_advance, 0.0);
    assert_eq!(extruder.pressure_advance_smooth_time, 0.040);
}

/// Position ranges and endstops of every rail as written; the polar bed has none.
fn check_rails(machine: &MachineConfig, text: &str) {
    for stepper in &machine.steppers {
        let name = stepper.name.as_str();
        let written_max = raw_f64(text, name, "position_max");
        assert_eq!(stepper.position_max, written_max, "{name}");
        if written_max.is_some() {
            let min = raw_f64(text, name, "position_min").unwrap_or(0.0);
            assert_eq!(stepper.position_min, Some(min), "{name}");
            let homing = stepper.homing.as_ref();
            assert_eq!(
                homing.and_then(|h| h.position_endstop),
                raw_f64(text, name, "position_endstop")
            );
            assert_eq!(
                homing.map(|h| h.homing_speed),
                Some(raw_f64(text, name, "homing_speed").unwrap_or(5.0))
            );
            assert_eq!(
                homing.map(|h| h.endstop_pin.to_string()),
                raw_value(text, name, "endstop_pin")
            );
        } else {
            assert!(
                stepper.position_min.is_none() && stepper.homing.is_none(),
                "{name}"
            );
        }
    }
}

#[test]
fn kinematics_parameters_match_summary_json() {
    for case in golden_cases() {
        let machine = load(&case.join("printer.cfg"));
        let summary: Value = serde_json::from_str(
            &std::fs::read_to_string(case.join("summary.json")).unwrap_or_default(),
        )
        .unwrap_or(Value::Null);
        assert_eq!(
            summary["kinematics"].as_str(),
            Some(machine.kinematics.name())
        );
        match &machine.params {
            MachineParams::Scara(p) => {
                let k = &summary["kinematics_params"];
                assert_eq!(Some(p.link1_length), k["link1_length"].as_f64());
                assert_eq!(Some(p.link2_length), k["link2_length"].as_f64());
                assert_eq!(Some(p.offset_x), k["offset_x"].as_f64());
                assert_eq!(Some(p.offset_y), k["offset_y"].as_f64());
                assert_eq!(p.ecr, k["ecr"].as_f64());
                assert_eq!(Some(p.elbow_coupling), k["ecr"].as_f64().map(|e| 1.0 / e));
                assert_eq!(
                    Some(p.base_protection_radius),
                    k["base_protection_radius"].as_f64()
                );
                assert_eq!(p.shoulder_stepper.name, "stepper_a");
                assert_eq!(p.elbow_stepper.name, "stepper_b");
                assert_eq!(
                    machine.home_position.as_deref(),
                    Some(&[0.0, 200.0, 0.0][..])
                );
            }
            MachineParams::Polar(p) => {
                assert_eq!((p.bed.position_min, p.bed.position_max), (None, None));
                assert_eq!(p.arm.position_max, Some(300.0));
                assert_eq!((p.arm_zero_offset, p.arm_lateral_offset), (0.0, 0.0));
            }
            MachineParams::Cartesian(p) => {
                let names: Vec<&str> = p.steppers.iter().map(|s| s.name.as_str()).collect();
                assert_eq!(names, ["stepper_x", "stepper_y", "stepper_z"]);
            }
            MachineParams::Fivebar(_) => panic!("Klipper has no five-bar: no golden case is one"),
        }
    }
}

#[test]
fn bench_config_loads_with_angular_limit() {
    let Some(shared) = shared_dir() else { return };
    let machine = load(&shared.join("bench/polar-bench.cfg"));
    assert_eq!(machine.kinematics, KinematicsKind::Polar);
    assert_eq!(machine.limits.max_angular_velocity, Some(5.0));
    assert_eq!(
        machine
            .stepper("stepper_bed")
            .map(|s| s.step_distance.to_bits()),
        Some(POLAR_BED_STEP.to_bits())
    );
    assert!(
        machine.unused_keys().is_empty(),
        "{:?}",
        machine.unused_keys()
    );
}
