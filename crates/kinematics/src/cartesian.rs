//! Klipper's Cartesian machine: one stepper per axis, motor position = coordinate.

use crate::common::{check_axis_limits, ensure_finite_point, lerp, motor_from};
use crate::{
    CartesianParams, Kinematics, Motor, MotorMap, MotorUnit, ParamError, ReachError, SegmentError,
    Vec3,
};

const AXES: [char; 3] = ['x', 'y', 'z'];

/// Motors `stepper_x`, `stepper_y`, `stepper_z` (mm).
#[derive(Debug, Clone)]
pub struct Cartesian {
    params: CartesianParams,
    motors: Vec<Motor>,
}

impl Cartesian {
    pub fn new(params: CartesianParams) -> Result<Self, ParamError> {
        let motors = params
            .steppers
            .iter()
            .map(|s| motor_from(s, MotorUnit::Mm))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { params, motors })
    }

    pub fn params(&self) -> &CartesianParams {
        &self.params
    }

    fn check_limits(&self, p: Vec3) -> Result<(), ReachError> {
        for (axis, (stepper, value)) in self.params.steppers.iter().zip(p).enumerate() {
            check_axis_limits(AXES[axis], stepper, value)?;
        }
        Ok(())
    }
}

impl Kinematics for Cartesian {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &'static str {
        "cartesian"
    }

    fn motors(&self) -> &[Motor] {
        &self.motors
    }

    fn motor_map(&self, motor: usize) -> MotorMap {
        let mut coeffs = [0.0; 3];
        if let Some(c) = coeffs.get_mut(motor) {
            *c = 1.0;
        }
        MotorMap::Linear { coeffs }
    }

    fn inverse(&self, p: Vec3, motors: &mut [f64]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        for (m, v) in motors.iter_mut().zip(p) {
            *m = v;
        }
        Ok(())
    }

    fn inverse_near(
        &self,
        p: Vec3,
        _previous: &[f64],
        motors: &mut [f64],
    ) -> Result<(), ReachError> {
        self.inverse(p, motors)
    }

    fn forward(&self, motors: &[f64]) -> Result<Vec3, ReachError> {
        match motors {
            [x, y, z, ..] if x.is_finite() && y.is_finite() && z.is_finite() => Ok([*x, *y, *z]),
            _ => Err(ReachError::NotFinite),
        }
    }

    fn jacobian(&self, p: Vec3, rows: &mut [Vec3]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        for (i, row) in rows.iter_mut().enumerate().take(3) {
            *row = [0.0; 3];
            row[i] = 1.0;
        }
        Ok(())
    }

    /// Axis limits form a box, which is convex: a straight segment is inside iff its end points are.
    fn check_segment(&self, a: Vec3, b: Vec3) -> Result<(), SegmentError> {
        for t in [0.0, 1.0] {
            let p = lerp(a, b, t);
            ensure_finite_point(p)
                .and_then(|()| self.check_limits(p))
                .map_err(|reason| SegmentError { t, reason })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StepperParams;

    fn machine() -> Cartesian {
        let stepper = |name: &str, max| StepperParams {
            name: name.into(),
            step_distance: 0.0125,
            position_min: Some(0.0),
            position_max: Some(max),
        };
        Cartesian::new(CartesianParams {
            steppers: [
                stepper("stepper_x", 200.0),
                stepper("stepper_y", 200.0),
                stepper("stepper_z", 100.0),
            ],
        })
        .expect("valid params")
    }

    #[test]
    fn motor_positions_equal_coordinates() {
        let m = machine();
        let mut motors = [0.0; 3];
        m.inverse([1.5, 2.5, 3.5], &mut motors).expect("reachable");
        assert_eq!(motors, [1.5, 2.5, 3.5]);
        assert_eq!(m.forward(&motors), Ok([1.5, 2.5, 3.5]));
    }

    #[test]
    fn segment_leaving_the_box_reports_the_axis() {
        let err = machine()
            .check_segment([10.0, 10.0, 1.0], [250.0, 10.0, 1.0])
            .expect_err("outside");
        assert_eq!(err.t, 1.0);
        assert!(matches!(
            err.reason,
            ReachError::AxisLimit { axis: 'x', .. }
        ));
    }

    #[test]
    fn zero_step_distance_is_refused() {
        let mut p = machine().params().clone();
        p.steppers[1].step_distance = 0.0;
        assert!(matches!(
            Cartesian::new(p),
            Err(ParamError::NotPositive { .. })
        ));
    }
}
