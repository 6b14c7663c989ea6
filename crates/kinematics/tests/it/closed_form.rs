//! Closed-form cases worked out by hand, the centring thesis example, and parameters flowing through.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use kinematics::polar::Polar;
use kinematics::scara::Scara;
use kinematics::{Kinematics, MachineParams, MotorMap, ScaraParams};

use crate::machines::{fekt_params, polar_params};

fn scara_l100_c_third() -> ScaraParams {
    ScaraParams {
        ecr: None,
        elbow_coupling: 1.0 / 3.0,
        ..fekt_params()
    }
}

#[test]
fn scara_right_angle_elbow_at_100_100() {
    // q1 = 0 puts the elbow at (100, 0); q2 = 90° turns the distal link to +Y: nozzle at (100, 100),
    // |p| = 141.421356… = 100·√2. motor_b = q2 + q1/3 = 90°.
    let scara = Scara::new(scara_l100_c_third()).expect("valid");
    let mut m = [0.0; 3];
    scara
        .inverse([100.0, 100.0, 0.0], &mut m)
        .expect("reachable");
    assert!(m[0].abs() < 1e-12, "q1 = {}", m[0]);
    assert!((m[1] - FRAC_PI_2).abs() < 1e-12, "motor_b = {}", m[1]);
    let j = scara.joints(100.0, 100.0).expect("reachable");
    assert!((j.q2 - FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn scara_right_angle_elbow_on_the_y_axis() {
    // (0, 141.421356…) has the same |p|, so q2 = 90°; the whole arm is turned by 45°:
    // q1 = atan2(141.42, 0) − atan2(100, 100) = 90° − 45° = 45°, motor_b = 90° + 45°/3 = 105°.
    let scara = Scara::new(scara_l100_c_third()).expect("valid");
    let mut m = [0.0; 3];
    scara
        .inverse([0.0, 100.0 * 2f64.sqrt(), 0.0], &mut m)
        .expect("reachable");
    assert!((m[0] - FRAC_PI_4).abs() < 1e-12);
    assert!((m[1] - (FRAC_PI_2 + FRAC_PI_4 / 3.0)).abs() < 1e-12);
}

#[test]
fn xscara_frame_measures_from_plus_y() {
    // X-SCARA frame: q1 = 0 points the proximal link along +Y, angles grow towards +X.
    let params = ScaraParams {
        frame: kinematics::ScaraFrame::XScara,
        ..scara_l100_c_third()
    };
    let scara = Scara::new(params).expect("valid");
    let p = scara.forward(&[0.0, FRAC_PI_2, 0.0]).expect("finite");
    assert!(
        (p[0] - 100.0).abs() < 1e-12 && (p[1] - 100.0).abs() < 1e-12,
        "{p:?}"
    );
    let p = scara.forward(&[0.0, 0.0, 0.0]).expect("finite");
    assert!(p[0].abs() < 1e-12 && (p[1] - 200.0).abs() < 1e-12, "{p:?}");
}

#[test]
fn fekt_fork_expression_order_for_motor_b() {
    // With ecr given, motor_b = q2 + q1/ecr (division), as the fork computes it.
    let scara = Scara::new(fekt_params()).expect("valid");
    let (x, y) = (37.25_f64, 131.5_f64);
    let cos_q2 = (x * x + y * y - 100.0 * 100.0 - 100.0 * 100.0) / (2.0 * 100.0 * 100.0);
    let q2 = cos_q2.acos();
    let q1 = y.atan2(x) - (100.0 * q2.sin()).atan2(100.0 + 100.0 * q2.cos());
    let mut m = [0.0; 3];
    scara.inverse([x, y, 0.0], &mut m).expect("reachable");
    assert_eq!(m[0].to_bits(), q1.to_bits());
    assert_eq!(m[1].to_bits(), (q2 + q1 / 3.0).to_bits());
}

#[test]
fn fekt_cos_quirk_only_changes_right_angle_elbows() {
    let plain = Scara::new(fekt_params()).expect("valid");
    let quirky = Scara::new(fekt_params())
        .expect("valid")
        .with_fekt_cos_quirk(true);
    let (a, b) = (
        plain.joints(100.0, 100.0).expect("ok"),
        quirky.joints(100.0, 100.0).expect("ok"),
    );
    assert!((a.q2 - FRAC_PI_2).abs() < 1e-15);
    assert_eq!(b.q2, 1e-6f64.acos());
    let (mut ma, mut mb) = ([0.0; 3], [0.0; 3]);
    plain.inverse([50.0, 120.0, 0.0], &mut ma).expect("ok");
    quirky.inverse([50.0, 120.0, 0.0], &mut mb).expect("ok");
    assert_eq!(ma, mb);
}

#[test]
fn polar_thesis_recentring_example() {
    // Thesis (NURE, §2.4): R_old = 5, φ_old = π/4, rotation centre moved by d = (2, 1): x' = x − dx,
    // y' = y − dy, then back to polar. It prints R ≈ 2.97 and φ ≈ 1.03 rad.
    let old = [5.0 * FRAC_PI_4.cos(), 5.0 * FRAC_PI_4.sin()];
    let polar = Polar::new(polar_params(0.0, 0.0)).expect("valid");
    let mut m = [0.0; 3];
    polar
        .inverse([old[0] - 2.0, old[1] - 1.0, 3.0], &mut m)
        .expect("reachable");
    // Exact values: R = 2.96425, φ = 1.02627 rad. The thesis' 2.97 comes from rounding x', y' to 1.54, 2.54
    // before squaring (√8.82 = 2.970); its φ agrees.
    assert!((m[1] - 2.964_253).abs() < 1e-6, "R = {}", m[1]);
    assert!((m[0] - 1.026_265).abs() < 1e-6, "φ = {}", m[0]);
    assert!(((1.54f64 * 1.54 + 2.54 * 2.54).sqrt() - 2.97).abs() < 1e-3);
    assert!((m[0] - 1.03).abs() < 0.005);
    assert_eq!(m[2], 3.0);
}

#[test]
fn polar_lateral_offset_against_a_direct_rotation() {
    let (dx, dy) = (1.5, 2.0);
    let polar = Polar::new(polar_params(dx, dy)).expect("valid");
    for p in [[120.0, 35.0], [-80.0, 10.0], [3.0, -2.5], [0.0, -250.0]] {
        let mut m = [0.0; 3];
        polar.inverse([p[0], p[1], 0.0], &mut m).expect("reachable");
        let (bed, arm) = (m[0], m[1]);
        // The bed physically turns by −bed; the bed point p is then at Rot(−bed)·p in the machine frame,
        // which must be the nozzle on the offset arm line at (dx + arm, dy).
        let (s, c) = (-bed).sin_cos();
        let moved = [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        assert!(
            (moved[0] - (dx + arm)).abs() < 1e-9 && (moved[1] - dy).abs() < 1e-9,
            "{moved:?} for {p:?}"
        );
        // The thesis' bed-rotation formula φ_bed = atan2(dy, dx + r) − atan2(p_y, p_x) is −bed (mod 2π).
        let phi_bed = dy.atan2(dx + arm) - p[1].atan2(p[0]);
        let diff = (phi_bed + bed).rem_euclid(TAU);
        assert!(
            diff < 1e-9 || TAU - diff < 1e-9,
            "φ_bed {phi_bed} vs bed {bed}"
        );
    }
}

#[test]
fn golden_step_distances_flow_through_unchanged() {
    let kin = kinematics::build(&MachineParams::Polar(polar_params(0.0, 0.0))).expect("valid");
    let motors = kin.motors();
    assert_eq!(motors[0].name, "stepper_bed");
    assert_eq!(
        motors[0].step_distance.to_bits(),
        (2.0 * PI / 16000.0).to_bits()
    );
    assert_eq!(motors[1].step_distance.to_bits(), (1.0f64 / 80.0).to_bits());
    assert_eq!(kin.motor_map(0), MotorMap::Angle { centre: [0.0, 0.0] });
    assert_eq!(kin.motor_map(1), MotorMap::Radius { centre: [0.0, 0.0] });
    let scara = kinematics::build(&MachineParams::Scara(fekt_params())).expect("valid");
    assert_eq!(
        scara.motors()[1].step_distance.to_bits(),
        (TAU / 9600.0).to_bits()
    );
    assert_eq!(scara.name(), "scara");
}

#[test]
fn invalid_parameters_are_refused() {
    let mut p = fekt_params();
    p.link2_length = -1.0;
    assert!(kinematics::build(&MachineParams::Scara(p)).is_err());
    let mut p = fekt_params();
    p.offset_x = f64::NAN;
    assert!(kinematics::build(&MachineParams::Scara(p)).is_err());
    let mut p = polar_params(0.0, f64::INFINITY);
    assert!(kinematics::build(&MachineParams::Polar(p.clone())).is_err());
    p.arm_lateral_offset = 0.0;
    p.bed.step_distance = 0.0;
    assert!(kinematics::build(&MachineParams::Polar(p)).is_err());
}
