//! Klipper's polar machine (rotating bed + radial arm + Z), with the assembly corrections of the centring
//! thesis: the arm's zero displaced along the arm (`dx`) and the arm's line offset sideways (`dy`).
//!
//! # Geometry and sign convention (derivation)
//! Machine frame: the bed turns about the origin; the nozzle rides on the arm, a line parallel to +X that
//! passes `dy` beside the centre, so at arm position `r` the nozzle is at `N(r) = (dx + r, dy)`.
//! Klipper's bed motor reading `θ` is such that the bed point `p` under the nozzle is `p = Rot(θ)·N(r)`
//! (ideal machine: `p = (r cos θ, r sin θ)`, i.e. `θ = atan2(y, x)`, `r = √(x²+y²)`). Physically the bed
//! has turned by `−θ` to bring `p` under the nozzle. Inverting `p = Rot(θ)·N(r)`:
//! * `|p|² = (dx + r)² + dy²`  ⇒  `r = −dx + √(|p|² − dy²)` (the arm on the +X side, `dx + r ≥ 0`);
//! * `atan2(p) = θ + atan2(dy, dx + r)`  ⇒  `θ = atan2(p_y, p_x) − atan2(dy, dx + r)`.
//!
//! The thesis writes the *bed rotation* `φ_bed = atan2(dy, dx + r) − atan2(p_y, p_x)`, which is `−θ`:
//! the same physics, the opposite sign of the motor reading. We keep Klipper's motor sign so an ideal machine
//! reproduces Klipper exactly. Points with `|p| < |dy|` never pass under the nozzle (`InsideMinimumRadius`).
//!
//! # The centre
//! At exactly `(0, 0)` on an ideal machine the bed angle is undefined: [`Kinematics::inverse`] returns
//! `AtCentre`, while [`Kinematics::inverse_near`] keeps the previous bed angle there (the arm is at 0, so
//! any bed angle puts the nozzle on the centre; keeping the old one avoids a jump).

use crate::angle::unwrap_near;
use crate::common::{
    check_axis_limits, check_stepper_limits, closest_approach, ensure_finite, ensure_finite_point,
    first_failure, lerp, motor_from,
};
use crate::{
    Kinematics, Motor, MotorMap, MotorUnit, PATH_TOLERANCE, ParamError, PolarParams,
    RADIAL_ROUNDING, ReachError, RotationCentre, SegmentError, TurningLimits, Vec3,
};

/// Motor order: bed (rad), arm (mm), z (mm).
pub const BED: usize = 0;
pub const ARM: usize = 1;
pub const Z: usize = 2;

#[derive(Debug, Clone)]
pub struct Polar {
    params: PolarParams,
    motors: Vec<Motor>,
}

impl Polar {
    pub fn new(params: PolarParams) -> Result<Self, ParamError> {
        ensure_finite("arm_zero_offset", params.arm_zero_offset)?;
        ensure_finite("arm_lateral_offset", params.arm_lateral_offset)?;
        let motors = vec![
            motor_from(&params.bed, MotorUnit::Rad)?,
            motor_from(&params.arm, MotorUnit::Mm)?,
            motor_from(&params.z, MotorUnit::Mm)?,
        ];
        Ok(Self { params, motors })
    }

    pub fn params(&self) -> &PolarParams {
        &self.params
    }

    /// True when neither assembly offset is set (Klipper's machine, closed-form motor maps).
    pub fn is_ideal(&self) -> bool {
        self.geometry().is_ideal()
    }

    /// The assembly offsets alone (for callers that compute many points without the limits).
    pub fn geometry(&self) -> PolarGeometry {
        PolarGeometry {
            arm_zero_offset: self.params.arm_zero_offset,
            arm_lateral_offset: self.params.arm_lateral_offset,
        }
    }

    /// How close (mm) a path must come to the centre to meet it: see [`RotationCentre::tolerance`].
    pub fn centre_tolerance(&self) -> f64 {
        (0.5 * self.params.arm.step_distance).min(PATH_TOLERANCE)
    }

    fn bed_and_arm(&self, x: f64, y: f64) -> Result<(f64, f64), ReachError> {
        self.geometry().bed_and_arm(x, y)
    }

    fn along_arm(&self, x: f64, y: f64) -> Result<f64, ReachError> {
        self.geometry().along_arm(x, y)
    }

    /// Inlined into `check_segment`, which checks three points of every planned move.
    #[inline]
    fn check_limits(&self, p: Vec3) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let arm = match self.along_arm(p[0], p[1]) {
            Ok(s) => s - self.params.arm_zero_offset,
            // At the centre the bed angle is undefined but the arm position is not: the point is reachable
            // (a move may end or start there; crossing it is the planner's business).
            Err(ReachError::AtCentre { .. }) => -self.params.arm_zero_offset,
            Err(e) => return Err(e),
        };
        check_stepper_limits(&self.params.arm, arm)?;
        check_axis_limits('z', &self.params.z, p[2])
    }
}

impl Kinematics for Polar {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &'static str {
        "polar"
    }

    fn motors(&self) -> &[Motor] {
        &self.motors
    }

    fn motor_map(&self, motor: usize) -> MotorMap {
        match motor {
            BED if self.is_ideal() => MotorMap::Angle { centre: [0.0, 0.0] },
            ARM if self.is_ideal() => MotorMap::Radius { centre: [0.0, 0.0] },
            Z => MotorMap::Linear {
                coeffs: [0.0, 0.0, 1.0],
            },
            _ => MotorMap::General,
        }
    }

    fn rotation_centre(&self) -> Option<RotationCentre> {
        // Only the ideal machine: with the arm's line beside the centre the centre is out of reach, and with
        // either offset the bed has no closed form to turn in place with (its moves are refused at the centre).
        self.is_ideal().then(|| RotationCentre {
            point: [0.0, 0.0],
            tolerance: self.centre_tolerance(),
            bed: BED,
            rim: self.params.arm.position_max.filter(|r| *r > 0.0),
        })
    }

    fn turning_limits(&self) -> Option<TurningLimits> {
        Some(TurningLimits::Bed)
    }

    fn reach_margin(&self, p: Vec3) -> Option<f64> {
        let max = self.params.arm.position_max?;
        let g = self.geometry();
        Some(match g.bed_and_arm(p[0], p[1]) {
            Ok((_, arm)) => max - arm,
            // On the centre of an ideal bed the arm is at its zero.
            Err(ReachError::AtCentre { .. }) => max + g.arm_zero_offset,
            // Inside the circle the offset arm never passes over: negative, by how far inside.
            Err(_) => p[0].hypot(p[1]) - g.arm_lateral_offset.abs(),
        })
    }

    fn refusal_in_owner_terms(&self, _a: Vec3, b: Vec3) -> Option<String> {
        let reach = self.params.arm.position_max?;
        let beyond = -self.reach_margin(b)?;
        (beyond > 0.0).then(|| {
            let beyond = crate::beside_limit(beyond, 0.0);
            format!("{beyond} mm beyond the arm's reach of {reach} mm")
        })
    }

    fn solver_geometry(&self) -> crate::SolverGeometry {
        crate::SolverGeometry::Polar(self.geometry())
    }

    /// The arm at its endstop, the bed declared at angle 0 (a bed endstop, if any, is not used here).
    fn home_pose(&self, endstops: &[Option<f64>]) -> Result<Option<Vec3>, ReachError> {
        match (
            endstops.get(ARM).copied().flatten(),
            endstops.get(Z).copied().flatten(),
        ) {
            (Some(arm), Some(z)) => {
                let mut motors = [0.0; 3];
                write_motors(&mut motors, 0.0, arm, z);
                self.forward(&motors).map(Some)
            }
            _ => Ok(None),
        }
    }

    fn inverse(&self, p: Vec3, motors: &mut [f64]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let (bed, arm) = self.bed_and_arm(p[0], p[1])?;
        write_motors(motors, bed, arm, p[2]);
        Ok(())
    }

    fn inverse_near(
        &self,
        p: Vec3,
        previous: &[f64],
        motors: &mut [f64],
    ) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let previous_bed = previous.get(BED).copied().unwrap_or(0.0);
        match self.bed_and_arm(p[0], p[1]) {
            Ok((bed, arm)) => write_motors(motors, unwrap_near(bed, previous_bed), arm, p[2]),
            // Ideal machine at the centre: arm 0, any bed angle is right; keep the previous one.
            Err(ReachError::AtCentre { .. }) if previous_bed.is_finite() => {
                write_motors(motors, previous_bed, -self.params.arm_zero_offset, p[2])
            }
            Err(e) => return Err(e),
        }
        Ok(())
    }

    fn forward(&self, motors: &[f64]) -> Result<Vec3, ReachError> {
        let [bed, arm, z] = match motors {
            [b, a, z, ..] if b.is_finite() && a.is_finite() && z.is_finite() => [*b, *a, *z],
            _ => return Err(ReachError::NotFinite),
        };
        let (x, y) = self.geometry().forward(bed, arm);
        Ok([x, y, z])
    }

    fn jacobian(&self, p: Vec3, rows: &mut [Vec3]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let [x, y, _] = p;
        let dy = self.params.arm_lateral_offset;
        let rho2 = x * x + y * y;
        if rho2 == 0.0 {
            return Err(ReachError::AtCentre { x, y });
        }
        let s2 = rho2 - dy * dy;
        if s2 <= 0.0 {
            return Err(ReachError::InsideMinimumRadius {
                x,
                y,
                distance: rho2.sqrt(),
                min: dy.abs(),
            });
        }
        let s = s2.sqrt();
        // arm = s − dx: ∇s = p/s.  bed = atan2(y, x) − atan2(dy, s): ∂/∂s atan2(dy, s) = −dy/ρ².
        let bed = [
            -y / rho2 + dy * x / (rho2 * s),
            x / rho2 + dy * y / (rho2 * s),
            0.0,
        ];
        let arm = [x / s, y / s, 0.0];
        for (row, value) in rows.iter_mut().zip([bed, arm, [0.0, 0.0, 1.0]]) {
            *row = value;
        }
        Ok(())
    }

    /// Closed form: the arm position grows with the distance from the centre, which along a straight line is
    /// convex in `t`; so its minimum (and the centre / minimum-radius tests) is at the closest approach and
    /// its maximum at an end point. Z is linear: end points. A failure is then located by bisection (exact,
    /// as the distance is monotone on either side of the closest approach) and reported where it begins.
    fn check_segment(&self, a: Vec3, b: Vec3) -> Result<(), SegmentError> {
        for (t, p) in [(0.0, a), (1.0, b)] {
            ensure_finite_point(p).map_err(|reason| SegmentError { t, reason })?;
        }
        self.check_limits(a)
            .map_err(|reason| SegmentError { t: 0.0, reason })?;
        let (t_near, d_near) = closest_approach(a, b, [0.0, 0.0]);
        let near = lerp(a, b, t_near);
        // Passing through the centre needs the bed to turn half a revolution there; the planner splits such
        // moves at the centre, so only a segment that crosses it (not one that ends or starts on it) fails.
        // Only a segment that runs over the centre itself (up to rounding) has no bed angle there; one that
        // passes within the centre's tolerance is routed through it by the planner, or turned round it by the
        // Klipper plug-in's move transform.
        let off_centre = |p: Vec3| p[0] * p[0] + p[1] * p[1] > RADIAL_ROUNDING * RADIAL_ROUNDING;
        let crosses = off_centre(a) && off_centre(b);
        if self.params.arm_lateral_offset == 0.0 && d_near <= RADIAL_ROUNDING && crosses {
            return Err(SegmentError {
                t: t_near,
                reason: ReachError::AtCentre {
                    x: near[0],
                    y: near[1],
                },
            });
        }
        let at = |t: f64| self.check_limits(lerp(a, b, t));
        if let Err(reason) = self.check_limits(near) {
            return Err(first_failure(0.0, t_near, reason, at));
        }
        if let Err(reason) = self.check_limits(b) {
            return Err(first_failure(t_near, 1.0, reason, at));
        }
        Ok(())
    }
}

/// A polar machine's assembly offsets: everything a point's bed angle and arm position depend on. Plain `Copy`
/// data with no allocation, so a step-time callback (the Klipper plug-in's) can carry it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarGeometry {
    pub arm_zero_offset: f64,
    pub arm_lateral_offset: f64,
}

impl PolarGeometry {
    /// True when neither offset is set (Klipper's machine).
    pub fn is_ideal(&self) -> bool {
        self.arm_zero_offset == 0.0 && self.arm_lateral_offset == 0.0
    }

    /// Nozzle XY on the bed for a bed angle and an arm position: `p = Rot(θ)·(dx + r, dy)`.
    pub fn forward(&self, bed: f64, arm: f64) -> (f64, f64) {
        if self.is_ideal() {
            // Klipper's expressions (polar.py's calc_position).
            return (bed.cos() * arm, bed.sin() * arm);
        }
        let (nx, ny) = (self.arm_zero_offset + arm, self.arm_lateral_offset);
        let (s, c) = bed.sin_cos();
        (c * nx - s * ny, s * nx + c * ny)
    }

    /// `(bed angle in (−π, π], arm position)` for the XY point, or why there is none.
    pub fn bed_and_arm(&self, x: f64, y: f64) -> Result<(f64, f64), ReachError> {
        let s = self.along_arm(x, y)?;
        let (dx, dy) = (self.arm_zero_offset, self.arm_lateral_offset);
        if self.is_ideal() {
            // Klipper's exact expressions, so step times match bit for bit.
            return Ok((y.atan2(x), s));
        }
        // dx + r = s exactly in real arithmetic; use s to avoid a rounding step.
        let bed = y.atan2(x) - dy.atan2(s);
        let bed = if bed > std::f64::consts::PI {
            bed - std::f64::consts::TAU
        } else {
            bed
        };
        let bed = if bed <= -std::f64::consts::PI {
            bed + std::f64::consts::TAU
        } else {
            bed
        };
        Ok((bed, s - dx))
    }

    /// Distance of the XY point along the arm's line from the point of that line nearest the centre (the arm
    /// position plus `arm_zero_offset`), or why the arm cannot reach it. No angle: limit checks need none.
    pub fn along_arm(&self, x: f64, y: f64) -> Result<f64, ReachError> {
        let dy = self.arm_lateral_offset;
        if dy == 0.0 && x == 0.0 && y == 0.0 {
            return Err(ReachError::AtCentre { x, y });
        }
        let rho2 = x * x + y * y;
        if dy == 0.0 {
            return Ok(rho2.sqrt());
        }
        let s2 = rho2 - dy * dy;
        if s2 < 0.0 {
            return Err(ReachError::InsideMinimumRadius {
                x,
                y,
                distance: rho2.sqrt(),
                min: dy.abs(),
            });
        }
        Ok(s2.sqrt())
    }
}

fn write_motors(motors: &mut [f64], bed: f64, arm: f64, z: f64) {
    for (m, v) in motors.iter_mut().zip([bed, arm, z]) {
        *m = v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StepperParams;
    use std::f64::consts::PI;

    fn stepper(name: &str, step: f64, max: Option<f64>) -> StepperParams {
        StepperParams {
            name: name.into(),
            step_distance: step,
            position_min: None,
            position_max: max,
        }
    }

    fn machine(dx: f64, dy: f64) -> Polar {
        Polar::new(PolarParams {
            bed: stepper("stepper_bed", 2.0 * PI / 16000.0, None),
            arm: stepper("stepper_arm", 1.0 / 80.0, Some(300.0)),
            z: stepper("stepper_z", 0.0025, Some(200.0)),
            arm_zero_offset: dx,
            arm_lateral_offset: dy,
        })
        .expect("valid params")
    }

    #[test]
    fn ideal_machine_is_klippers_formula() {
        let mut m = [0.0; 3];
        machine(0.0, 0.0)
            .inverse([3.0, 4.0, 1.0], &mut m)
            .expect("reachable");
        assert_eq!(m, [4.0f64.atan2(3.0), 5.0, 1.0]);
    }

    #[test]
    fn centre_is_an_error_but_inverse_near_keeps_the_angle() {
        let polar = machine(0.0, 0.0);
        let mut m = [0.0; 3];
        assert!(matches!(
            polar.inverse([0.0, 0.0, 0.0], &mut m),
            Err(ReachError::AtCentre { .. })
        ));
        polar
            .inverse_near([0.0, 0.0, 2.0], &[1.25, 3.0, 2.0], &mut m)
            .expect("centre with history");
        assert_eq!(m, [1.25, 0.0, 2.0]);
    }

    #[test]
    fn lateral_offset_makes_a_hole_of_radius_dy() {
        let mut m = [0.0; 3];
        let err = machine(0.5, 2.0).inverse([1.0, 1.0, 0.0], &mut m);
        assert!(matches!(err, Err(ReachError::InsideMinimumRadius { min, .. }) if min == 2.0));
        assert_eq!(machine(0.5, 2.0).motor_map(BED), MotorMap::General);
    }

    #[test]
    fn move_through_the_centre_is_refused_at_its_middle() {
        let err = machine(0.0, 0.0)
            .check_segment([-10.0, 0.0, 1.0], [10.0, 0.0, 1.0])
            .expect_err("centre");
        assert!((err.t - 0.5).abs() < 1e-12);
        assert!(matches!(err.reason, ReachError::AtCentre { .. }));
        assert!(
            machine(0.0, 0.0)
                .check_segment([-10.0, 0.1, 1.0], [10.0, 0.1, 1.0])
                .is_ok()
        );
    }
}
