//! Machine builders shared by the tests (golden-config step distances, FEKT-SCARA geometry).

use std::f64::consts::TAU;

use kinematics::{PolarParams, ScaraParams, StepperParams};

pub fn stepper(name: &str, step: f64, min: Option<f64>, max: Option<f64>) -> StepperParams {
    StepperParams {
        name: name.into(),
        step_distance: step,
        position_min: min,
        position_max: max,
    }
}

/// Klipper's example polar machine: bed 16000 steps/turn, arm 80 steps/mm, bed radius 300 mm.
pub fn polar_params(dx: f64, dy: f64) -> PolarParams {
    PolarParams {
        bed: stepper("stepper_bed", TAU / 16000.0, None, None),
        arm: stepper("stepper_arm", 1.0 / 80.0, None, Some(300.0)),
        z: stepper("stepper_z", 0.0025, Some(0.0), Some(200.0)),
        arm_zero_offset: dx,
        arm_lateral_offset: dy,
    }
}

/// The FEKT-SCARA example: arms 100/100 mm, ECR 3, base protection 60 mm, 9600 steps per joint turn.
pub fn fekt_params() -> ScaraParams {
    ScaraParams {
        shoulder_stepper: stepper("stepper_a", TAU / 9600.0, Some(-200.0), Some(200.0)),
        elbow_stepper: stepper("stepper_b", TAU / 9600.0, Some(-200.0), Some(200.0)),
        z: stepper("stepper_z", 0.0025, None, Some(200.0)),
        ..ScaraParams::fekt_example()
    }
}
