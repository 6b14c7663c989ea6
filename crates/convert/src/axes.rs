//! The map between Cartesian toolhead positions and the two planar output axes the written G-code drives
//! (motor angles/radius, or corrected Cartesian XY for a firmware with the ideal model), and back.
//!
//! Internal units: mm and rad. Z is not an output of this map: it is linear on every machine here.

use std::sync::Arc;

use kinematics::{
    Kinematics, MotorMap, MotorUnit, ReachError, RotationCentre, SegmentError, unwrap_near,
};

use crate::error::ConvertError;
use crate::options::Target;

/// Most motors a machine may have here (planar pair + Z + spare).
const MAX_MOTORS: usize = 6;

/// Cartesian ⇄ output axes.
#[derive(Debug, Clone)]
pub enum AxisMap {
    /// Output = two motors of `kin`.
    Motors {
        kin: Arc<dyn Kinematics>,
        planar: [usize; 2],
        z: Option<usize>,
        count: usize,
        /// Set when the two output axes are an ideal polar radius and angle (closed-form chord bound).
        polar: Option<PolarAxes>,
    },
    /// Output = Cartesian XY for a firmware that believes in `ideal` while the machine is `real`:
    /// `xy' = ideal.forward(real.inverse(p))`.
    Corrected {
        real: Arc<dyn Kinematics>,
        ideal: Arc<dyn Kinematics>,
        z: Option<usize>,
        count: usize,
    },
}

impl AxisMap {
    pub fn motors(kin: Arc<dyn Kinematics>, target: Target) -> Result<AxisMap, ConvertError> {
        let count = motor_count(kin.as_ref())?;
        let z = z_motor(kin.as_ref());
        let planar = match target {
            Target::Cylindrical => cylindrical_motors(kin.as_ref())?,
            Target::Joints => {
                let mut others = (0..count).filter(|&i| Some(i) != z);
                match (others.next(), others.next()) {
                    (Some(a), Some(b)) => [a, b],
                    _ => {
                        return Err(ConvertError::Setup(
                            "the machine has fewer than two planar motors".into(),
                        ));
                    }
                }
            }
        };
        let polar = polar_axes(kin.as_ref(), planar);
        Ok(AxisMap::Motors {
            kin,
            planar,
            z,
            count,
            polar,
        })
    }

    pub fn corrected(
        real: Arc<dyn Kinematics>,
        ideal: Arc<dyn Kinematics>,
    ) -> Result<AxisMap, ConvertError> {
        let count = motor_count(real.as_ref())?;
        if motor_count(ideal.as_ref())? != count {
            return Err(ConvertError::Setup(
                "real and ideal machines have different motors".into(),
            ));
        }
        let z = z_motor(real.as_ref());
        Ok(AxisMap::Corrected {
            real,
            ideal,
            z,
            count,
        })
    }

    /// Units of the two output axes.
    pub fn units(&self) -> [MotorUnit; 2] {
        match self {
            AxisMap::Motors { kin, planar, .. } => {
                let m = kin.motors();
                [m[planar[0]].unit, m[planar[1]].unit]
            }
            AxisMap::Corrected { .. } => [MotorUnit::Mm, MotorUnit::Mm],
        }
    }

    /// Output axes for toolhead position `p`, angles chosen nearest `near` (unwrapped).
    #[inline]
    pub fn to_axes(&self, p: [f64; 3], near: [f64; 2]) -> Result<[f64; 2], ReachError> {
        match self {
            AxisMap::Motors {
                polar: Some(polar), ..
            } => polar.to_axes(p, near),
            AxisMap::Motors {
                kin, planar, count, ..
            } => {
                let mut prev = [0.0; MAX_MOTORS];
                prev[planar[0]] = near[0];
                prev[planar[1]] = near[1];
                let mut out = [0.0; MAX_MOTORS];
                kin.inverse_near(p, &prev[..*count], &mut out[..*count])?;
                Ok([out[planar[0]], out[planar[1]]])
            }
            AxisMap::Corrected {
                real, ideal, count, ..
            } => {
                let mut motors = [0.0; MAX_MOTORS];
                real.inverse(p, &mut motors[..*count])?;
                let xy = ideal.forward(&motors[..*count])?;
                // The ideal firmware must choose the same motor positions for xy' (e.g. no negative radius).
                let mut back = [0.0; MAX_MOTORS];
                ideal.inverse_near(xy, &motors[..*count], &mut back[..*count])?;
                let same = motors[..*count]
                    .iter()
                    .zip(&back[..*count])
                    .all(|(a, b)| (a - b).abs() <= 1e-9 * (1.0 + a.abs()));
                if !same {
                    return Err(ReachError::BranchImpossible { x: p[0], y: p[1] });
                }
                Ok([xy[0], xy[1]])
            }
        }
    }

    /// Toolhead XY reached when the output axes are at `a` and Z at `z`.
    pub fn from_axes(&self, a: [f64; 2], z: f64) -> Result<[f64; 2], ReachError> {
        match self {
            AxisMap::Motors {
                kin,
                planar,
                z: z_index,
                count,
                ..
            } => {
                let mut m = [0.0; MAX_MOTORS];
                m[planar[0]] = a[0];
                m[planar[1]] = a[1];
                if let Some(zi) = z_index {
                    m[*zi] = z;
                }
                let p = kin.forward(&m[..*count])?;
                Ok([p[0], p[1]])
            }
            AxisMap::Corrected {
                real, ideal, count, ..
            } => {
                let mut m = [0.0; MAX_MOTORS];
                ideal.inverse([a[0], a[1], z], &mut m[..*count])?;
                let p = real.forward(&m[..*count])?;
                Ok([p[0], p[1]])
            }
        }
    }

    /// Whole-segment check on the machine that moves (reach, minimum radius, singular poses, centre).
    pub fn check_line(&self, a: [f64; 3], b: [f64; 3]) -> Result<(), SegmentError> {
        match self {
            AxisMap::Motors { kin, .. } => kin.check_segment(a, b),
            AxisMap::Corrected { real, .. } => real.check_segment(a, b),
        }
    }

    /// The output axes as an ideal polar radius and angle, if they are.
    pub fn polar(&self) -> Option<PolarAxes> {
        match self {
            AxisMap::Motors { polar, .. } => *polar,
            AxisMap::Corrected { .. } => None,
        }
    }

    /// The polar rotation centre, where a motor declares itself an angle about a point.
    pub fn centre(&self) -> Option<RotationCentre> {
        self.machine().rotation_centre()
    }

    /// The machine's motors the written axes drive: the two planar axes (none for corrected Cartesian
    /// output, which the firmware's own kinematics turn into motor moves) and Z.
    pub fn written_motors(&self) -> ([Option<usize>; 2], Option<usize>) {
        match self {
            AxisMap::Motors { planar, z, .. } => (planar.map(Some), *z),
            AxisMap::Corrected { z, .. } => ([None; 2], *z),
        }
    }

    /// The machine that moves.
    pub fn machine(&self) -> &dyn Kinematics {
        match self {
            AxisMap::Motors { kin, .. } => kin.as_ref(),
            AxisMap::Corrected { real, .. } => real.as_ref(),
        }
    }
}

/// Output axes that are exactly `radius = |p − centre|` and `angle = atan2(p − centre)` (unwrapped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarAxes {
    pub centre: [f64; 2],
    /// Which output axis (0 or 1) is the radius; the other is the angle.
    pub radius: usize,
}

impl PolarAxes {
    /// The closed forms the machine declares for these motors (the hot path of cutting, without the trait
    /// call): the angle unwrapped nearest `near`; at the centre itself, radius 0 and the angle kept.
    #[inline]
    fn to_axes(self, p: [f64; 3], near: [f64; 2]) -> Result<[f64; 2], ReachError> {
        if !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite()) {
            return Err(ReachError::NotFinite);
        }
        let (x, y) = (p[0] - self.centre[0], p[1] - self.centre[1]);
        let near_angle = near[1 - self.radius];
        let (radius, angle) = if x == 0.0 && y == 0.0 {
            (0.0, near_angle)
        } else {
            ((x * x + y * y).sqrt(), unwrap_near(y.atan2(x), near_angle))
        };
        let mut axes = [0.0; 2];
        axes[self.radius] = radius;
        axes[1 - self.radius] = angle;
        Ok(axes)
    }
}

impl PolarAxes {
    /// Axes of `p1` seen from a nearby point `p0` whose axes are `a0` (the cutting loop's next trial): the
    /// radius directly, the angle as `a0`'s plus the turn from `p0` to `p1`, an arctangent of a small ratio
    /// summed as a series instead of an `atan2` call and an unwrap. The same angle as
    /// [`PolarAxes::to_axes`] to within a few 1e-16 rad per step (far below the written resolution); where the
    /// turn is not small, or at the centre, it is [`PolarAxes::to_axes`] itself.
    #[inline]
    pub fn step(
        self,
        (p0, a0): ([f64; 3], [f64; 2]),
        p1: [f64; 3],
    ) -> Result<[f64; 2], ReachError> {
        let c = self.centre;
        let v0 = [p0[0] - c[0], p0[1] - c[1]];
        let v1 = [p1[0] - c[0], p1[1] - c[1]];
        let cross = v0[0] * v1[1] - v0[1] * v1[0];
        let dot = v0[0] * v1[0] + v0[1] * v1[1];
        // `dot > 0` also rules out either point at the centre and any NaN.
        if !(dot > 0.0 && cross.abs() <= SMALL_TURN * dot && p1.iter().all(|v| v.is_finite())) {
            return self.to_axes(p1, a0);
        }
        let mut axes = [0.0; 2];
        axes[self.radius] = (v1[0] * v1[0] + v1[1] * v1[1]).sqrt();
        axes[1 - self.radius] = a0[1 - self.radius] + atan_small(cross / dot);
        Ok(axes)
    }
}

/// Largest `tan` of a turn [`PolarAxes::step`] sums as a series (about 11°); beyond it, `atan2`.
const SMALL_TURN: f64 = 0.2;

/// `atan(t)` for `|t| ≤ SMALL_TURN` by its Taylor series to `t²¹` (the first term left out is below
/// `0.2²³/23 ≈ 4e-18`), the terms grouped in pairs and powers of `t⁴` (Estrin's scheme) so the sum is a
/// short chain of dependent operations rather than ten (the cutting loop waits on it every trial).
#[inline]
fn atan_small(t: f64) -> f64 {
    let t2 = t * t;
    let t4 = t2 * t2;
    let t8 = t4 * t4;
    // The coefficients (−1)^k / (2k + 1) of t^(2k), k = 1..=10, two by two.
    let pair = |even: f64, odd: f64| even + t2 * odd;
    let q0 = pair(-1.0 / 3.0, 1.0 / 5.0);
    let q1 = pair(-1.0 / 7.0, 1.0 / 9.0);
    let q2 = pair(-1.0 / 11.0, 1.0 / 13.0);
    let q3 = pair(-1.0 / 15.0, 1.0 / 17.0);
    let q4 = pair(-1.0 / 19.0, 1.0 / 21.0);
    let sum = (q0 + t4 * q1) + t8 * (q2 + t4 * q3) + (t8 * t8) * q4;
    t + t * t2 * sum
}

fn polar_axes(kin: &dyn Kinematics, planar: [usize; 2]) -> Option<PolarAxes> {
    match (kin.motor_map(planar[0]), kin.motor_map(planar[1])) {
        (MotorMap::Radius { centre: c }, MotorMap::Angle { centre }) if c == centre => {
            Some(PolarAxes { centre, radius: 0 })
        }
        (MotorMap::Angle { centre: c }, MotorMap::Radius { centre }) if c == centre => {
            Some(PolarAxes { centre, radius: 1 })
        }
        _ => None,
    }
}

fn motor_count(kin: &dyn Kinematics) -> Result<usize, ConvertError> {
    let n = kin.motors().len();
    if (2..=MAX_MOTORS).contains(&n) {
        Ok(n)
    } else {
        Err(ConvertError::Setup(format!(
            "unsupported number of motors: {n}"
        )))
    }
}

/// The motor that is the Z axis itself (position = z), if any.
fn z_motor(kin: &dyn Kinematics) -> Option<usize> {
    (0..kin.motors().len()).find(|&i| matches!(kin.motor_map(i), MotorMap::Linear { coeffs } if coeffs == [0.0, 0.0, 1.0]))
        .or_else(|| kin.motors().iter().position(|m| m.name.ends_with("_z")))
}

/// `[radius motor, angle motor]` of a polar machine: `stepper_arm` and `stepper_bed` by name, else by map.
fn cylindrical_motors(kin: &dyn Kinematics) -> Result<[usize; 2], ConvertError> {
    let motors = kin.motors();
    let by_name = |part: &str| motors.iter().position(|m| m.name.contains(part));
    let by_map = |want_angle: bool| {
        (0..motors.len()).find(|&i| match kin.motor_map(i) {
            MotorMap::Angle { .. } => want_angle,
            MotorMap::Radius { .. } => !want_angle,
            _ => false,
        })
    };
    let radius = by_name("arm").or_else(|| by_map(false));
    let angle = by_name("bed").or_else(|| by_map(true));
    match (radius, angle) {
        (Some(r), Some(a))
            if r != a && motors[r].unit == MotorUnit::Mm && motors[a].unit == MotorUnit::Rad =>
        {
            Ok([r, a])
        }
        _ => Err(ConvertError::Setup(format!(
            "cylindrical output needs a polar machine (arm and bed motors); `{}` has none",
            kin.name()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::Target;
    use kinematics::PolarParams;
    use kinematics::polar::Polar;

    #[test]
    fn polar_closed_form_matches_the_machine() {
        let kin: Arc<dyn Kinematics> =
            Arc::new(Polar::new(PolarParams::klipper_example()).expect("valid"));
        let map = AxisMap::motors(Arc::clone(&kin), Target::Cylindrical).expect("map");
        let polar = map.polar().expect("ideal polar axes");
        let AxisMap::Motors { planar, count, .. } = map else {
            return;
        };
        for (i, p) in [
            [10.0, 0.0],
            [-3.0, 4.0],
            [-5.0, -1e-9],
            [0.0, 0.0],
            [1e-12, -7.0],
        ]
        .into_iter()
        .enumerate()
        {
            let near = [0.0, 3.0 * i as f64];
            let mut prev = [0.0; MAX_MOTORS];
            prev[planar[0]] = near[0];
            prev[planar[1]] = near[1];
            let mut motors = [0.0; MAX_MOTORS];
            kin.inverse_near([p[0], p[1], 1.0], &prev[..count], &mut motors[..count])
                .expect("reachable");
            let fast = polar.to_axes([p[0], p[1], 1.0], near).expect("reachable");
            assert_eq!(fast, [motors[planar[0]], motors[planar[1]]], "{p:?}");
        }
        assert!(polar.to_axes([f64::NAN, 0.0, 0.0], [0.0; 2]).is_err());
    }

    #[test]
    fn stepped_angle_stays_with_the_closed_form() {
        // Many small steps round and round an off-centre circle, each from the last stepped axes: the
        // summed angle stays within 1e-12 rad of the closed form's unwrapped angle.
        let polar = PolarAxes {
            centre: [1.0, -2.0],
            radius: 1,
        };
        let point = |k: usize| {
            let t = k as f64 * 0.01;
            [1.0 + 30.0 * t.cos() + 0.5, -2.0 + 30.0 * t.sin(), 0.0]
        };
        let mut axes = polar.to_axes(point(0), [0.0; 2]).expect("reachable");
        let mut worst = 0.0f64;
        for k in 1..20_000 {
            let (p0, p1) = (point(k - 1), point(k));
            let stepped = polar.step((p0, axes), p1).expect("reachable");
            let exact = polar.to_axes(p1, axes).expect("reachable");
            assert_eq!(stepped[1], exact[1]);
            worst = worst.max((stepped[0] - exact[0]).abs());
            axes = stepped;
        }
        assert!(worst < 1e-12, "{worst}");
        // A large turn and the centre itself fall back to the closed form.
        let far = polar
            .step((point(0), axes), [1.0, 40.0, 0.0])
            .expect("reachable");
        assert_eq!(
            far,
            polar.to_axes([1.0, 40.0, 0.0], axes).expect("reachable")
        );
        let centre = polar
            .step((point(0), axes), [1.0, -2.0, 0.0])
            .expect("reachable");
        assert_eq!(centre, [axes[0], 0.0]);
        assert!(polar.step((point(0), axes), [f64::NAN, 0.0, 0.0]).is_err());
    }
}
