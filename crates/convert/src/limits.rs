//! Motor speed limits on the written axes: the shortest time a written segment may take.
//!
//! The firmware interpolates linearly in motor space between written points at the written feed, so every
//! motor of a segment moves at a constant speed: its travel over the segment's time. A segment whose time is
//! at least `travel / limit` for every limited motor keeps every motor within its limit all along the
//! segment. The converter gives each segment `max(Cartesian time, that minimum)`
//! ([`crate::Converter`], `write_motion`), and verification checks the written feeds against the same
//! minimum ([`crate::verify`]).
//!
//! Limits apply to the axes the output drives as motors: the two planar axes of
//! [`AxisMap::Motors`] and Z. For corrected Cartesian output ([`AxisMap::Corrected`]) the firmware runs its own
//! kinematics, so only Z is limited here.

use crate::axes::AxisMap;
use crate::options::MotorLimit;

/// Largest speed (internal units per second: mm/s, rad/s) of each written axis: the two planar axes and Z;
/// infinite where nothing limits it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    pub max_velocity: [f64; 3],
}

impl AxisLimits {
    /// No limit on any axis.
    pub const NONE: AxisLimits = AxisLimits {
        max_velocity: [f64::INFINITY; 3],
    };

    /// The written axes' speed limits from the motors' limits (the smallest where a motor has several).
    pub fn new(map: &AxisMap, limits: &[MotorLimit]) -> AxisLimits {
        let (planar, z) = map.written_motors();
        let motors = [planar[0], planar[1], z];
        let max_velocity = motors.map(|motor| {
            limits
                .iter()
                .filter(|l| Some(l.motor) == motor)
                .filter_map(|l| l.max_velocity)
                .filter(|v| *v > 0.0)
                .fold(f64::INFINITY, f64::min)
        });
        AxisLimits { max_velocity }
    }

    /// Whether any axis is limited.
    pub fn any(&self) -> bool {
        self.max_velocity.iter().any(|v| v.is_finite())
    }

    /// The shortest time (s) of a segment moving the axes by `travel` (internal units, signs ignored).
    pub fn min_time(&self, travel: [f64; 3]) -> f64 {
        (0..3)
            .map(|i| travel[i].abs() / self.max_velocity[i])
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slowest_axis_sets_the_time() {
        let limits = AxisLimits {
            max_velocity: [100.0, 5.0, f64::INFINITY],
        };
        assert!(limits.any());
        assert_eq!(limits.min_time([10.0, -1.0, 1000.0]), 0.2);
        assert_eq!(limits.min_time([-50.0, 0.1, 0.0]), 0.5);
        assert_eq!(AxisLimits::NONE.min_time([1e9, 1e9, 1e9]), 0.0);
        assert!(!AxisLimits::NONE.any());
    }
}
