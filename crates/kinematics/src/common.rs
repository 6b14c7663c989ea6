//! Small helpers shared by the machines: angle unwrapping, parameter validation, limit checks and
//! closed-form segment geometry.

use crate::{Motor, MotorUnit, ParamError, ReachError, SegmentError, StepperParams, Vec3};

pub(crate) fn ensure_finite_point(p: Vec3) -> Result<(), ReachError> {
    if p.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ReachError::NotFinite)
    }
}

pub(crate) fn ensure_finite(name: &str, value: f64) -> Result<(), ParamError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ParamError::NotFinite {
            name: name.to_string(),
            value,
        })
    }
}

pub(crate) fn ensure_positive(name: &str, value: f64) -> Result<(), ParamError> {
    ensure_finite(name, value)?;
    if value > 0.0 {
        Ok(())
    } else {
        Err(ParamError::NotPositive {
            name: name.to_string(),
            value,
        })
    }
}

pub(crate) fn ensure_non_negative(name: &str, value: f64) -> Result<(), ParamError> {
    ensure_finite(name, value)?;
    if value >= 0.0 {
        Ok(())
    } else {
        Err(ParamError::Negative {
            name: name.to_string(),
            value,
        })
    }
}

pub(crate) fn ensure_range(name: &str, range: Option<(f64, f64)>) -> Result<(), ParamError> {
    let Some((min, max)) = range else {
        return Ok(());
    };
    ensure_finite(&format!("{name} minimum"), min)?;
    ensure_finite(&format!("{name} maximum"), max)?;
    if min > max {
        return Err(ParamError::EmptyRange {
            name: name.to_string(),
            min,
            max,
        });
    }
    Ok(())
}

/// Validates one stepper's step distance and soft limits and turns it into a [`Motor`].
pub(crate) fn motor_from(stepper: &StepperParams, unit: MotorUnit) -> Result<Motor, ParamError> {
    let name = if stepper.name.is_empty() {
        "stepper"
    } else {
        stepper.name.as_str()
    };
    ensure_positive(&format!("{name} step_distance"), stepper.step_distance)?;
    if let Some(v) = stepper.position_min {
        ensure_finite(&format!("{name} position_min"), v)?;
    }
    if let Some(v) = stepper.position_max {
        ensure_finite(&format!("{name} position_max"), v)?;
    }
    if let (Some(min), Some(max)) = (stepper.position_min, stepper.position_max)
        && min > max
    {
        return Err(ParamError::EmptyRange {
            name: format!("{name} position"),
            min,
            max,
        });
    }
    Ok(Motor {
        name: stepper.name.clone(),
        unit,
        step_distance: stepper.step_distance,
    })
}

/// `JointLimit` if `value` is outside the stepper's configured soft limits.
pub(crate) fn check_stepper_limits(stepper: &StepperParams, value: f64) -> Result<(), ReachError> {
    check_range(
        &stepper.name,
        value,
        stepper.position_min,
        stepper.position_max,
    )
}

/// `JointLimit` if `value` is outside `[min, max]` (either side optional).
pub(crate) fn check_range(
    name: &str,
    value: f64,
    min: Option<f64>,
    max: Option<f64>,
) -> Result<(), ReachError> {
    let below = min.is_some_and(|m| value < m);
    let above = max.is_some_and(|m| value > m);
    if below || above {
        return Err(ReachError::JointLimit {
            motor: name.to_string(),
            value,
            min: min.unwrap_or(f64::NEG_INFINITY),
            max: max.unwrap_or(f64::INFINITY),
        });
    }
    Ok(())
}

/// `AxisLimit` if `value` is outside the stepper's soft limits (Cartesian axes and Z).
pub(crate) fn check_axis_limits(
    axis: char,
    stepper: &StepperParams,
    value: f64,
) -> Result<(), ReachError> {
    let below = stepper.position_min.is_some_and(|m| value < m);
    let above = stepper.position_max.is_some_and(|m| value > m);
    if below || above {
        return Err(ReachError::AxisLimit {
            axis,
            value,
            min: stepper.position_min.unwrap_or(f64::NEG_INFINITY),
            max: stepper.position_max.unwrap_or(f64::INFINITY),
        });
    }
    Ok(())
}

/// Point at fraction `t` of the segment `a → b`.
pub(crate) fn lerp(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Fraction `t ∈ [0, 1]` of the XY segment `a → b` closest to `centre`, and that XY distance.
///
/// Closed form: minimise `|a + t·d − c|²`, a parabola in `t`, then clamp to the segment.
pub fn closest_approach(a: Vec3, b: Vec3, centre: [f64; 2]) -> (f64, f64) {
    let (ax, ay) = (a[0] - centre[0], a[1] - centre[1]);
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (-(ax * dx + ay * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (px, py) = (ax + t * dx, ay + t * dy);
    (t, (px * px + py * py).sqrt())
}

/// Segment fractions closer than this are not separated any further by [`first_failure`].
pub(crate) const SEGMENT_T_TOLERANCE: f64 = 1e-9;

/// Where along a segment a check starts failing, by bisection between a passing fraction `good` and a
/// failing fraction `bad` (either order). Exact when the failing set is an interval that ends at `bad`,
/// which holds for every check that depends only on the distance from a centre (that distance is monotone
/// between the closest approach and either end of the segment).
pub(crate) fn first_failure(
    mut good: f64,
    mut bad: f64,
    mut reason: ReachError,
    check: impl Fn(f64) -> Result<(), ReachError>,
) -> SegmentError {
    while (bad - good).abs() > SEGMENT_T_TOLERANCE {
        let mid = 0.5 * (good + bad);
        match check(mid) {
            Ok(()) => good = mid,
            Err(e) => {
                bad = mid;
                reason = e;
            }
        }
    }
    SegmentError { t: bad, reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_approach_of_a_line_past_the_origin() {
        let (t, d) = closest_approach([-10.0, 3.0, 0.0], [10.0, 3.0, 0.0], [0.0, 0.0]);
        assert!((t - 0.5).abs() < 1e-15);
        assert!((d - 3.0).abs() < 1e-15);
        let (t, d) = closest_approach([5.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 0.0]);
        assert_eq!(t, 0.0);
        assert_eq!(d, 5.0);
    }

    #[test]
    fn limits_report_the_violated_side() {
        assert!(check_range("q1", 1.0, Some(0.0), Some(2.0)).is_ok());
        let err = check_range("q1", 3.0, None, Some(2.0));
        assert!(matches!(err, Err(ReachError::JointLimit { max, .. }) if max == 2.0));
    }
}

/// Where along a segment (`t ≤ to` or `t ≥ from`) an arm's singular band is allowed: next to an end that rests in
/// it (from rest the joints move at finite speed however close the pose is to singular).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Exempt {
    pub(crate) to: f64,
    pub(crate) from: f64,
}

impl Exempt {
    pub(crate) const NONE: Exempt = Exempt {
        to: -1.0,
        from: 2.0,
    };

    pub(crate) fn covers(&self, t: f64) -> bool {
        t <= self.to || t >= self.from
    }

    /// The stretches next to each end that lies in a band (`in_band(t)`), where the band is left monotonically on
    /// either side of `t_near` (the closest approach to the arm's axis: the distance from it is monotone there),
    /// each found to [`SEGMENT_T_TOLERANCE`] by bisection. Where the closest approach is an end itself (a line
    /// heading straight for a folded arm's pose), the distance is monotone over the whole segment: that end's
    /// stretch is looked for up to the other end.
    pub(crate) fn band_ends(in_band: impl Fn(f64) -> bool, t_near: f64) -> Exempt {
        let towards = |end: f64| {
            if (t_near - end).abs() <= SEGMENT_T_TOLERANCE {
                1.0 - end
            } else {
                t_near
            }
        };
        let leaves = |mut inside: f64, mut outside: f64| {
            if in_band(outside) {
                return outside;
            }
            while (outside - inside).abs() > SEGMENT_T_TOLERANCE {
                let mid = 0.5 * (inside + outside);
                if in_band(mid) {
                    inside = mid;
                } else {
                    outside = mid;
                }
            }
            inside
        };
        Exempt {
            to: if in_band(0.0) {
                leaves(0.0, towards(0.0))
            } else {
                -1.0
            },
            from: if in_band(1.0) {
                leaves(1.0, towards(1.0))
            } else {
                2.0
            },
        }
    }
}
