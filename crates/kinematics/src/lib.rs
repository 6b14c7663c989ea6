//! Machine kinematics: Cartesian, polar, SCARA and five-bar printers behind one small trait.
//!
//! Units: mm for lengths, radians for angles; motor positions are in the motor's own unit (mm or rad).
//! Nothing here reads files or G-code: machines are built from the plain parameter structs in [`params`],
//! which the `config` crate fills from `printer.cfg`.

mod angle;
pub mod cartesian;
mod common;
pub mod curves;
pub mod fivebar;
pub mod params;
pub mod polar;
pub mod scara;
pub mod workspace;

pub use angle::unwrap_near;
pub use common::closest_approach;
pub use params::*;

/// A Cartesian toolhead position `[x, y, z]` in mm.
pub type Vec3 = [f64; 3];

/// The unit a motor position is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotorUnit {
    Mm,
    Rad,
}

/// Which configured angular limits bind a machine's turning (rad) motors: a polar bed's
/// (`max_angular_velocity`, `max_angular_accel`) or a SCARA's joints' (`max_joint_velocity`, `max_joint_accel`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TurningLimits {
    Bed,
    Joints,
}

/// A motor (stepper) as the kinematics sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Motor {
    /// Config section name, e.g. `stepper_bed`, `stepper_a`, `stepper_x`.
    pub name: String,
    pub unit: MotorUnit,
    /// Motor travel per (micro)step, in `unit`.
    pub step_distance: f64,
}

/// How a motor position depends on the toolhead position, when a closed form exists.
///
/// Step generation uses this to pick an exact solver; `General` means "use [`Kinematics::inverse_near`]".
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotorMap {
    /// position = `coeffs · p` (Cartesian axes).
    Linear { coeffs: Vec3 },
    /// position = distance of `(x, y)` from `centre` (polar arm).
    Radius { centre: [f64; 2] },
    /// position = `atan2(y − cy, x − cx)`, unwrapped to be continuous (polar bed).
    Angle { centre: [f64; 2] },
    /// One joint motor of a SCARA arm: evaluated alone from the arm's geometry (no other motor computed),
    /// with derivatives along a line in closed form. Consumers without a special solver treat it as
    /// `General`.
    ScaraJoint {
        geometry: scara::ScaraGeometry,
        joint: scara::ScaraJoint,
    },
    /// No closed form (polar with a sideways arm offset, a SCARA replicating the FEKT fork's cos quirk).
    General,
}

/// A polar bed's rotation centre: the one point where the bed angle is undefined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationCentre {
    /// Where it lies, in toolhead coordinates (mm).
    pub point: [f64; 2],
    /// A path that comes this close (mm) meets the centre: it is planned through the centre itself, where the
    /// bed turns in place. Half an arm step (the arm cannot tell such points from the centre), at most
    /// [`PATH_TOLERANCE`] (the nozzle's largest deviation from the path).
    pub tolerance: f64,
    /// The bed motor's index.
    pub bed: usize,
    /// How far from the centre the arm reaches (its `position_max`, mm), when configured: the bed's rim.
    pub rim: Option<f64>,
}

/// Within this distance of a polar centre (mm), a point on a move through the centre takes its bed angle from the
/// move's direction, not from its own coordinates (the Klipper plug-in's bed solver): their rounding (about 1e-16 of
/// coordinates below a metre) would turn `atan2` by up to half a turn right at the centre, a burst of steps the MCU
/// cannot take. Here it turns the angle by at most 1e-10 rad, and a line that misses the centre by
/// [`RADIAL_ROUNDING`] by at most 1e-6 rad.
pub const CENTRE_DIRECTION_RADIUS: f64 = 1e-3;

/// Distance (mm) from the exact polar centre where a conversion for firmware without polar kinematics stops a move
/// through the centre and turns the bed in place. Not the centre's tolerance ([`RotationCentre::tolerance`], which
/// decides which paths meet the centre): the turn sweeps a half circle of this radius about the centre, so this much
/// is a path deviation, and the tolerance (up to 5 µm, half an arm step) would use the whole default conversion
/// tolerance of 5 µm, and more than a finer one. At 0.1 µm it stays far below any tolerance.
pub const CENTRE_TURN_GAP: f64 = 1e-7;

/// The largest deviation from the G-code path that jointspace allows itself anywhere (mm): at the polar centre,
/// and by default in conversions.
pub const PATH_TOLERANCE: f64 = 0.005;

/// A line that passes a polar centre closer than this (mm) runs along a radius: the planner's moves to and from
/// the centre are exactly radial, and positions computed along them (`start + direction·distance`) miss the centre
/// only by rounding (about 1e-16 of the coordinates). Every other line the planner makes stays at least the centre's
/// tolerance away.
pub const RADIAL_ROUNDING: f64 = 1e-9;

/// Why a point or a segment cannot be reached.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    #[error("({}, {}) is out of reach: {} mm from the shoulder, maximum {} mm", readable(*x), readable(*y), readable(*distance), readable(*max))]
    OutOfReach {
        x: f64,
        y: f64,
        distance: f64,
        max: f64,
    },
    #[error("({}, {}) is inside the minimum radius: {} mm from the axis, minimum {} mm", readable(*x), readable(*y), readable(*distance), readable(*min))]
    InsideMinimumRadius {
        x: f64,
        y: f64,
        distance: f64,
        min: f64,
    },
    #[error("{motor} would have to be at {}", beyond_limits(*value, *min, *max, 4))]
    JointLimit {
        motor: String,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("({}, {}) cannot be reached on the configured elbow branch", readable(*x), readable(*y))]
    BranchImpossible { x: f64, y: f64 },
    #[error("({}, {}) is too close to a singular pose (|sin q2| = {sin_q2:.4}, margin {margin:.4})", readable(*x), readable(*y))]
    Singular {
        x: f64,
        y: f64,
        sin_q2: f64,
        margin: f64,
    },
    #[error("({}, {}) is out of the {arm} arm's reach: {} mm from its base joint, which reaches from {} to {} mm", readable(*x), readable(*y), readable(*distance), readable(*min), readable(*max))]
    ArmReach {
        arm: &'static str,
        x: f64,
        y: f64,
        distance: f64,
        min: f64,
        max: f64,
    },
    #[error("({}, {}) is too close to the {arm} arm's singular pose, straight or folded (|sin| of its elbow angle {sin:.4}, margin {margin:.4})", readable(*x), readable(*y))]
    ArmSingular {
        arm: &'static str,
        x: f64,
        y: f64,
        sin: f64,
        margin: f64,
    },
    #[error("({}, {}) is too close to the parallel singularity, where the distal links are in line and the nozzle loses stiffness (|sin| of their angle {sin:.4}, margin {margin:.4})", readable(*x), readable(*y))]
    ParallelSingular {
        x: f64,
        y: f64,
        sin: f64,
        margin: f64,
    },
    #[error("the elbows are {} mm apart: the distal links join only between {} and {} mm", readable(*distance), readable(*min), readable(*max))]
    ElbowsApart { distance: f64, min: f64, max: f64 },
    #[error("({}, {}) is at the rotation centre, where the bed angle is undefined", readable(*x), readable(*y))]
    AtCentre { x: f64, y: f64 },
    #[error("axis {axis} at {}", beyond_limits(*value, *min, *max, 3))]
    AxisLimit {
        axis: char,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("position is not finite")]
    NotFinite,
}

/// A coordinate or distance for a message, in mm: three decimals, or in exponent form where that would print
/// hundreds of digits (a G-code file can ask for a point at 1e300 mm).
pub fn readable(value: f64) -> String {
    if value.abs() < 1e9 {
        format!("{value:.3}")
    } else {
        format!("{value:.3e}")
    }
}

/// `value, outside its limits [min, max]` with at least `decimals` decimals, and more where needed so that the
/// value never reads as equal to the limit it exceeds (`150.0000001`, not `150.0000`).
fn beyond_limits(value: f64, min: f64, max: f64, decimals: usize) -> String {
    let limit = if value > max { max } else { min };
    if value.abs() >= 1e9 {
        return format!("{}, outside its limits [{min}, {max}]", readable(value));
    }
    let d = decimals_apart(value, limit, decimals);
    format!("{value:.d$}, outside its limits [{min:.d$}, {max:.d$}]")
}

/// At least `decimals` decimals, and as many more (up to 15) as it takes for `value` not to read as `limit`: a
/// message never shows the offending value as the limit it breaks.
pub fn decimals_apart(value: f64, limit: f64, decimals: usize) -> usize {
    let reads = |x: f64, d: usize| format!("{x:.d$}").parse::<f64>().unwrap_or(x);
    let mut d = decimals;
    while d < 15 && reads(value, d) == reads(limit, d) {
        d += 1;
    }
    d
}

/// A problem found along a straight segment, with the fraction `t ∈ [0, 1]` of the segment where it occurs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{reason} (at {:.1}% of the segment)", t * 100.0)]
pub struct SegmentError {
    pub t: f64,
    pub reason: ReachError,
}

/// How far a pose is from one of the machine's special poses, in the measure its `singularity_margin` states (|sin|
/// of the angle whose zero is the special pose).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clearance {
    /// The special pose, e.g. `arm straight or folded`, `distal links in line`.
    pub label: &'static str,
    pub value: f64,
    /// The smallest value a path keeps between its ends (the configured margin).
    pub margin: f64,
}

/// A machine's geometry for solvers that follow one motor (see [`Kinematics::solver_geometry`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SolverGeometry {
    /// Every motor is linear in the toolhead position ([`MotorMap::Linear`]).
    Linear,
    Polar(polar::PolarGeometry),
    Scara(scara::ScaraGeometry),
    /// A five-bar: each base joint's angle from the nozzle's position alone ([`fivebar::FivebarSide::angle`]).
    Fivebar(fivebar::FivebarGeometry),
}

/// `value` with three decimals, or as many more as it takes not to read as `limit` (a refusal never shows the
/// limit itself as the offending value).
pub(crate) fn beside_limit(value: f64, limit: f64) -> String {
    let d = decimals_apart(value, limit, 3);
    format!("{value:.d$}")
}

/// A machine's kinematics. Implementations: [`cartesian::Cartesian`], [`polar::Polar`], [`scara::Scara`],
/// [`fivebar::Fivebar`].
pub trait Kinematics: Send + Sync + std::fmt::Debug {
    /// Short name as in `printer.cfg` (`cartesian`, `polar`, `scara`).
    fn name(&self) -> &'static str;

    /// The motors, in a fixed order used by every slice of motor positions below.
    fn motors(&self) -> &[Motor];

    /// How each motor's position depends on the toolhead position (same order as [`Self::motors`]).
    fn motor_map(&self, motor: usize) -> MotorMap;

    /// Motor positions for toolhead position `p`. Angles are in `(-π, π]` where a range applies.
    fn inverse(&self, p: Vec3, motors: &mut [f64]) -> Result<(), ReachError>;

    /// Motor positions for `p`, choosing for every angle the equivalent value nearest `previous`
    /// (angles unwrapped, so a bed can turn without limit and moves stay continuous).
    fn inverse_near(&self, p: Vec3, previous: &[f64], motors: &mut [f64])
    -> Result<(), ReachError>;

    /// Toolhead position for motor positions.
    fn forward(&self, motors: &[f64]) -> Result<Vec3, ReachError>;

    /// Jacobian `∂motor_i / ∂p_j` at `p` (one row per motor).
    fn jacobian(&self, p: Vec3, rows: &mut [Vec3]) -> Result<(), ReachError>;

    /// Checks a whole straight segment from `a` to `b`, not just its end points: minimum radius, reach,
    /// singular poses and joint limits along the way.
    fn check_segment(&self, a: Vec3, b: Vec3) -> Result<(), SegmentError>;

    /// The point where a bed angle is undefined, for machines that have one (an ideal polar machine).
    fn rotation_centre(&self) -> Option<RotationCentre> {
        None
    }

    /// Which angular limits bind this machine's rad motors, if it has any.
    fn turning_limits(&self) -> Option<TurningLimits> {
        None
    }

    /// The toolhead pose after homing, from each motor's endstop position (motor order, motor units; `None` where
    /// a motor has none): `None` when the machine cannot home from these. A machine's own convention fills in what
    /// its endstops leave open (a polar bed's angle is declared 0, as Klipper does).
    fn home_pose(&self, endstops: &[Option<f64>]) -> Result<Option<Vec3>, ReachError> {
        let motors: Option<Vec<f64>> = endstops.iter().copied().collect();
        match motors {
            Some(motors) if motors.len() == self.motors().len() => self.forward(&motors).map(Some),
            _ => Ok(None),
        }
    }

    /// Whether the toolhead must come to rest at `p` (a SCARA arm in its singular band: nearly straight or
    /// folded, where only motion from or to rest keeps the joints at finite speed).
    fn rests_at(&self, _p: Vec3) -> bool {
        false
    }

    /// How far `p` is from the edge of what the arm reaches (mm, negative outside): a SCARA's annulus about its
    /// shoulder, a polar arm's travel. `None` where the limits are per axis (a Cartesian machine).
    fn reach_margin(&self, _p: Vec3) -> Option<f64> {
        None
    }

    /// Why the segment `a → b` is refused, in its owner's terms, where the machine has them: how far beyond the
    /// arm's reach its end lies, how close to a SCARA's shoulder it passes. `None`: the [`SegmentError`]'s reason
    /// is the one to give (where along the segment it lies means nothing to a G-code line's owner). Asked only
    /// for a refusal.
    fn refusal_in_owner_terms(&self, _a: Vec3, _b: Vec3) -> Option<String> {
        None
    }

    /// The machine's geometry as plain `Copy` data, for step solvers outside this crate that follow one motor in
    /// a host's own arithmetic (the Klipper plug-in's).
    fn solver_geometry(&self) -> SolverGeometry {
        SolverGeometry::Linear
    }

    /// How far the pose at `p` is from each of the machine's special poses (appended to `out`; nothing for a
    /// machine without any, or where `p` has no pose): what `check` reports as the closest a print comes to them.
    fn clearances(&self, _p: Vec3, _out: &mut Vec<Clearance>) {}

    /// Where the machine's special poses lie within `bounds`, for drawing on a map (`spacing`: the finest detail
    /// drawn, mm). Empty for a machine without singular curves in its bed (Cartesian; a polar machine's centre is a
    /// point, a SCARA's straight and folded arm are its reach map's edges).
    fn singular_curves(
        &self,
        _bounds: &workspace::Bounds,
        _spacing: f64,
    ) -> Vec<workspace::SingularCurve> {
        Vec::new()
    }

    /// The machine itself, for a tool that acts on one kind's own parameters (the SCARA calibration pattern):
    /// `scara::Scara::of` finds the SCARA behind a built machine, so such a tool uses the machine every front-end
    /// built instead of building its own.
    fn as_any(&self) -> &dyn std::any::Any;

    /// Checks one point against everything [`Self::check_segment`] checks (soft limits included).
    ///
    /// [`Self::inverse`] fails only where the geometry has no answer (out of reach, at the polar centre);
    /// this also applies configured limits: axis/joint limits, base protection radius, singularity margin.
    fn check_point(&self, p: Vec3) -> Result<(), ReachError> {
        self.check_segment(p, p).map_err(|e| e.reason)
    }
}

/// Why machine parameters were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("{name} must be a finite number, got {value}")]
    NotFinite { name: String, value: f64 },
    #[error("{name} must be positive, got {value}")]
    NotPositive { name: String, value: f64 },
    #[error("{name} must not be negative, got {value}")]
    Negative { name: String, value: f64 },
    #[error("{name}: minimum {min} is above maximum {max}")]
    EmptyRange { name: String, min: f64, max: f64 },
    #[error("{name}: {reason}")]
    Invalid { name: String, reason: String },
}

/// Builds the machine described by `params` (validating them).
pub fn build(params: &MachineParams) -> Result<Box<dyn Kinematics>, ParamError> {
    Ok(match params {
        MachineParams::Cartesian(p) => Box::new(cartesian::Cartesian::new(p.clone())?),
        MachineParams::Polar(p) => Box::new(polar::Polar::new(p.clone())?),
        MachineParams::Scara(p) => Box::new(scara::Scara::new(p.clone())?),
        MachineParams::Fivebar(p) => Box::new(fivebar::Fivebar::new(p.clone())?),
    })
}

#[cfg(test)]
mod tests {
    use super::{ReachError, beside_limit};

    #[test]
    fn a_refusal_never_shows_the_limit_as_the_value() {
        assert_eq!(beside_limit(12.5, 60.0), "12.500");
        assert_eq!(beside_limit(59.999_999_999_99, 60.0), "59.99999999999");
        assert_eq!(beside_limit(3e-14, 0.0), "0.00000000000003");
    }

    #[test]
    fn a_value_beyond_a_limit_never_reads_as_the_limit() {
        let e = ReachError::JointLimit {
            motor: "stepper_arm".into(),
            value: 150.000_000_12,
            min: 0.0,
            max: 150.0,
        };
        assert_eq!(
            e.to_string(),
            "stepper_arm would have to be at 150.0000001, outside its limits [0.0000000, 150.0000000]"
        );
        let e = ReachError::AxisLimit {
            axis: 'Z',
            value: 300.25,
            min: 0.0,
            max: 300.0,
        };
        assert_eq!(
            e.to_string(),
            "axis Z at 300.250, outside its limits [0.000, 300.000]"
        );
        let e = ReachError::AxisLimit {
            axis: 'Z',
            value: -0.0004,
            min: 0.0,
            max: 300.0,
        };
        assert_eq!(
            e.to_string(),
            "axis Z at -0.0004, outside its limits [0.0000, 300.0000]"
        );
    }
}
