//! Machines used by the tests, built with the real `kinematics` crate.

use kinematics::scara::Scara;
use kinematics::{
    CartesianParams, ElbowBranch, Kinematics, MachineParams, PolarParams, ScaraFrame, ScaraParams,
    StepperParams,
};

pub fn stepper(name: &str, step_distance: f64) -> StepperParams {
    StepperParams {
        name: name.to_string(),
        step_distance,
        position_min: None,
        position_max: None,
    }
}

pub fn cartesian(step_x: f64, step_y: f64, step_z: f64) -> Box<dyn Kinematics> {
    let params = CartesianParams {
        steppers: [
            stepper("stepper_x", step_x),
            stepper("stepper_y", step_y),
            stepper("stepper_z", step_z),
        ],
    };
    kinematics::build(&MachineParams::Cartesian(params)).expect("valid cartesian parameters")
}

pub fn polar(step_bed: f64, step_arm: f64, step_z: f64) -> Box<dyn Kinematics> {
    let params = PolarParams {
        bed: stepper("stepper_bed", step_bed),
        arm: stepper("stepper_arm", step_arm),
        z: stepper("stepper_z", step_z),
        arm_zero_offset: 0.0,
        arm_lateral_offset: 0.0,
    };
    kinematics::build(&MachineParams::Polar(params)).expect("valid polar parameters")
}

/// The FEKT-SCARA fork's kinematics (golden/README.md): left branch, `b = q2 + q1/ecr`, with the fork's cos
/// quirk (its joints then go through the general solver).
pub fn scara_fekt(
    step_a: f64,
    step_b: f64,
    step_z: f64,
    l1: f64,
    l2: f64,
    offset: [f64; 2],
    ecr: f64,
) -> Box<dyn Kinematics> {
    scara_fekt_arm(step_a, step_b, step_z, l1, l2, offset, ecr, true)
}

/// The FEKT arm, with or without the fork's cos quirk (without it the joints use stepgen's SCARA solver).
#[allow(clippy::too_many_arguments)]
pub fn scara_fekt_arm(
    step_a: f64,
    step_b: f64,
    step_z: f64,
    l1: f64,
    l2: f64,
    offset: [f64; 2],
    ecr: f64,
    cos_quirk: bool,
) -> Box<dyn Kinematics> {
    let params = ScaraParams {
        shoulder_stepper: stepper("stepper_a", step_a),
        elbow_stepper: stepper("stepper_b", step_b),
        z: stepper("stepper_z", step_z),
        link1_length: l1,
        link2_length: l2,
        offset_x: offset[0],
        offset_y: offset[1],
        elbow_coupling: 1.0 / ecr,
        ecr: Some(ecr),
        elbow: ElbowBranch::Left,
        frame: ScaraFrame::Standard,
        shoulder_zero: 0.0,
        elbow_zero: 0.0,
        shoulder_limits: None,
        elbow_limits: None,
        base_protection_radius: 0.0,
        singularity_margin: 0.0,
    };
    Box::new(
        Scara::new(params)
            .expect("valid scara parameters")
            .with_fekt_cos_quirk(cos_quirk),
    )
}

/// A polar machine with assembly offsets: its bed and arm have no closed form (general solver).
pub fn polar_with_offsets(zero_offset: f64, lateral_offset: f64) -> Box<dyn Kinematics> {
    let params = PolarParams {
        bed: stepper("stepper_bed", std::f64::consts::TAU / 16000.0),
        arm: stepper("stepper_arm", 0.0125),
        z: stepper("stepper_z", 0.0025),
        arm_zero_offset: zero_offset,
        arm_lateral_offset: lateral_offset,
    };
    kinematics::build(&MachineParams::Polar(params)).expect("valid polar parameters")
}
