//! Upstream example configs load unchanged: Klipper's example-polar.cfg and the FEKT-SCARA example.

use std::f64::consts::TAU;
use std::path::PathBuf;

use config::{KinematicsKind, MachineConfig};
use kinematics::{ElbowBranch, MachineParams, ScaraFrame, Turn};

use crate::fixture;

#[test]
fn klipper_example_polar_loads_as_is() {
    let machine =
        MachineConfig::load(fixture("example-polar.cfg")).expect("example-polar.cfg loads");
    assert_eq!(machine.kinematics, KinematicsKind::Polar);
    let MachineParams::Polar(polar) = &machine.params else {
        panic!("polar params expected");
    };
    // 200 full steps · 16 microsteps · (80/16) gearing = 16000 steps per bed turn.
    assert_eq!(polar.bed.step_distance, TAU / 16000.0);
    assert_eq!(polar.arm.step_distance, 40.0 / 3200.0);
    assert_eq!(polar.z.step_distance, 8.0 / 3200.0);
    assert_eq!(polar.arm.position_max, Some(300.0));
    let arm = machine
        .stepper("stepper_arm")
        .and_then(|s| s.homing.clone())
        .expect("arm homes");
    // position_endstop 300 = position_max: Klipper infers homing towards positive.
    assert!(arm.positive_dir);
    assert_eq!(arm.homing_speed, 50.0);
    let z = machine
        .stepper("stepper_z")
        .and_then(|s| s.homing.clone())
        .expect("z homes");
    assert!(!z.positive_dir);
    assert_eq!(machine.limits.max_z_velocity, 25.0);
    assert!(machine.document.section("heater_bed").is_some());
    assert!(machine.document.section("fan").is_some());
    assert!(
        machine.unused_keys().is_empty(),
        "{:?}",
        machine.unused_keys()
    );
}

#[test]
fn fekt_scara_example_loads() {
    let machine = MachineConfig::load(fixture("fekt-scara.cfg")).expect("fekt-scara.cfg loads");
    let MachineParams::Scara(scara) = &machine.params else {
        panic!("scara params expected");
    };
    assert_eq!((scara.link1_length, scara.link2_length), (100.0, 100.0));
    assert_eq!(scara.ecr, Some(3.0));
    assert_eq!(scara.elbow_coupling, 1.0 / 3.0);
    assert_eq!(scara.base_protection_radius, 60.0);
    assert_eq!(scara.elbow, ElbowBranch::Left);
    assert_eq!(scara.frame, ScaraFrame::Standard);
    assert_eq!(scara.singularity_margin, 0.05);
    assert_eq!((scara.shoulder_limits, scara.elbow_limits), (None, None));
    // 60:20 pulleys: 200 · 16 · 3 = 9600 steps per joint turn.
    assert_eq!(scara.shoulder_stepper.step_distance, TAU / 9600.0);
    assert_eq!(scara.elbow_stepper.step_distance, TAU / 9600.0);
    // The fork's ±200 range is in degrees, as its `position_endstop`; the kinematics count radians.
    assert_eq!(
        scara.shoulder_stepper.position_min,
        Some((-200.0f64).to_radians())
    );
    assert_eq!(
        scara.shoulder_stepper.position_max,
        Some(200.0f64.to_radians())
    );
    let a = machine.stepper("stepper_a").expect("stepper_a");
    assert!(a.dir_inverted());
    assert_eq!(a.homing.as_ref().map(|h| h.positive_dir), Some(false));
    assert_eq!(machine.home_position, Some(vec![0.0, 200.0, 0.0]));
    assert!(machine.arcs.is_none());
}

/// The five-bar example: RepRapFirmware's `M669 K9 X-50:50 Y-200:-200 P150:150 D200:200 L2` as jointspace keys,
/// rotary steppers in degrees in the file and radians inside; a missing working mode is refused at `[printer]`.
#[test]
fn fivebar_example_loads() {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/machines/fivebar.cfg");
    let machine = MachineConfig::load(&path).expect("fivebar.cfg loads");
    assert_eq!(machine.kinematics, KinematicsKind::Fivebar);
    assert!(
        machine.unused_keys().is_empty(),
        "{:?}",
        machine.unused_keys()
    );
    let MachineParams::Fivebar(p) = &machine.params else {
        panic!("five-bar params expected");
    };
    assert_eq!(
        (p.left.base, p.right.base),
        ([-50.0, -200.0], [50.0, -200.0])
    );
    assert_eq!((p.left.proximal, p.left.distal), (150.0, 200.0));
    assert_eq!((p.right.proximal, p.right.distal), (150.0, 200.0));
    assert_eq!(
        (p.left.turn, p.right.turn, p.distal_turn),
        (Turn::Cw, Turn::Ccw, Turn::Cw)
    );
    assert_eq!(p.singularity_margin, 0.1);
    assert_eq!(p.left.stepper.step_distance, TAU / 25600.0);
    assert_eq!(p.left.stepper.position_max, Some(210f64.to_radians()));
    assert_eq!(machine.limits.max_joint_velocity, Some(6.0));
    let text = std::fs::read_to_string(&path).expect("read");
    let err = MachineConfig::from_str(&text.replace("left_arm_turn: cw\n", ""), &path)
        .expect_err("the left arm's working mode is required");
    assert!(err.to_string().contains("left_arm_turn"), "{err}");
    let err = MachineConfig::from_str(
        &text.replace("left_arm_turn: cw", "left_arm_turn: up"),
        &path,
    )
    .expect_err("ccw or cw");
    assert!(err.to_string().contains("left_arm_turn"), "{err}");
}
