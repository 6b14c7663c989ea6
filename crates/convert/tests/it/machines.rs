//! Test machines: Klipper's example polar printer (300 mm arm) and the FEKT SCARA (L1 = L2 = 100 mm, ECR 3).

use std::sync::Arc;

use kinematics::polar::Polar;
use kinematics::scara::Scara;
use kinematics::{PolarParams, ScaraParams};

/// Klipper's `example-polar.cfg` steppers (16000 steps/rev bed, 80 steps/mm arm), no assembly offsets.
pub fn polar_params() -> PolarParams {
    PolarParams::klipper_example()
}

pub fn polar() -> Arc<Polar> {
    Arc::new(Polar::new(polar_params()).expect("valid polar parameters"))
}

/// FEKT-SCARA: arms 100/100 mm, ECR 3, shoulder at the origin, base protection 60 mm.
pub fn scara() -> Arc<Scara> {
    let params = ScaraParams {
        singularity_margin: 0.05,
        ..ScaraParams::fekt_example()
    };
    Arc::new(Scara::new(params).expect("valid SCARA parameters"))
}
