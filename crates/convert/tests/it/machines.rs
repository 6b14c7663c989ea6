//! Test machines: Klipper's example polar printer (300 mm arm) and the FEKT SCARA (L1 = L2 = 100 mm, ECR 3).

use std::sync::Arc;

use kinematics::polar::Polar;
use kinematics::scara::Scara;
use kinematics::{ElbowBranch, PolarParams, ScaraFrame, ScaraParams, StepperParams};

fn stepper(name: &str, step_distance: f64) -> StepperParams {
    StepperParams {
        name: name.into(),
        step_distance,
        position_min: None,
        position_max: None,
    }
}

/// Klipper's `example-polar.cfg` steppers (16000 steps/rev bed, 80 steps/mm arm), no assembly offsets.
pub fn polar_params() -> PolarParams {
    PolarParams {
        bed: stepper("stepper_bed", std::f64::consts::TAU / 16000.0),
        arm: stepper("stepper_arm", 1.0 / 80.0),
        z: stepper("stepper_z", 1.0 / 400.0),
        arm_zero_offset: 0.0,
        arm_lateral_offset: 0.0,
    }
}

pub fn polar() -> Arc<Polar> {
    Arc::new(Polar::new(polar_params()).expect("valid polar parameters"))
}

/// FEKT-SCARA: arms 100/100 mm, ECR 3, shoulder at the origin, base protection 60 mm.
pub fn scara() -> Arc<Scara> {
    let step = std::f64::consts::TAU / (200.0 * 16.0 * 3.0);
    let params = ScaraParams {
        shoulder_stepper: stepper("stepper_a", step),
        elbow_stepper: stepper("stepper_b", step),
        z: stepper("stepper_z", 1.0 / 400.0),
        link1_length: 100.0,
        link2_length: 100.0,
        offset_x: 0.0,
        offset_y: 0.0,
        elbow_coupling: 1.0 / 3.0,
        ecr: Some(3.0),
        elbow: ElbowBranch::Left,
        frame: ScaraFrame::Standard,
        shoulder_zero: 0.0,
        elbow_zero: 0.0,
        shoulder_limits: None,
        elbow_limits: None,
        base_protection_radius: 60.0,
        singularity_margin: 0.05,
    };
    Arc::new(Scara::new(params).expect("valid SCARA parameters"))
}
