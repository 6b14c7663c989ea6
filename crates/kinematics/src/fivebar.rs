//! Five-bar (parallel) SCARA: two base joints, each turning a proximal link; the two distal links are joined at the
//! nozzle (RepRapFirmware's `M669 K9` without cantilevers).
//!
//! Geometry: side `k` (left, right) has its base joint at `B_k`, proximal length `P_k`, distal length `D_k`. The
//! actuator angle `θ_k` is the proximal link's absolute angle from +X, counter-clockwise; the elbow is
//! `E_k = B_k + P_k (cos θ_k, sin θ_k)` and the nozzle `N` satisfies `|N − E_k| = D_k` on both sides. Motors:
//! `stepper_left = θ_L + left_zero`, `stepper_right = θ_R + right_zero` (rad), `stepper_z = z` (mm).
//!
//! Working mode: each side's elbow is the intersection of the circles about `B_k` (radius `P_k`) and about `N`
//! (radius `D_k`) for which the turn `B_k → E_k → N` has the configured sign (counter-clockwise positive); the
//! forward kinematics take the intersection of the distal circles for which the turn `E_L → N → E_R` has the
//! configured distal sign (RepRapFirmware: clockwise).
//!
//! Special poses: a side straight or folded (`|N − B_k|` at `P_k + D_k` or `|P_k − D_k|`: the serial singularities,
//! where that joint's speed grows without bound) and the distal links in line (the parallel singularity, where the
//! motors keep finite speed but the nozzle is not held). With strict reach a side cannot change branch, so its serial
//! singularities are its reach circles: their band is treated as the SCARA's (a path may start or end there, at rest,
//! and may not cross it between its ends). The parallel singularity lies inside the reach: its band is refused
//! everywhere, at rest too, and found along a segment by sampling, minimum search and bisection.
//!
//! [`Kinematics::inverse`] fails only where no pose exists in the working mode (beyond a side's reach, or the distal
//! links turning the other way); the soft limits (margin, motor limits, Z) are applied by
//! [`Kinematics::check_point`] / [`Kinematics::check_segment`].

mod geometry;
mod special_poses;

pub use geometry::{FivebarGeometry, FivebarSide, SideAngle};

use crate::angle::unwrap_near;
use crate::common::{
    Exempt, SEGMENT_T_TOLERANCE, check_axis_limits, check_stepper_limits, closest_approach,
    ensure_finite, ensure_finite_point, ensure_non_negative, ensure_positive, first_failure, lerp,
    motor_from,
};
use crate::{
    FivebarArm, FivebarParams, Kinematics, Motor, MotorMap, MotorUnit, ParamError, ReachError,
    SegmentError, TurningLimits, Vec3,
};

/// Motor order: left base joint (rad), right base joint (rad), z (mm).
pub const LEFT: usize = 0;
pub const RIGHT: usize = 1;
pub const Z: usize = 2;

/// The sides' names, in motor order (for messages).
pub const SIDES: [&str; 2] = ["left", "right"];

/// Spacing (mm) of the samples that look for the parallel band, the distal links turning the other way and motor
/// limits along a segment. Between two samples where the distal links' angle turns from closing to opening, its
/// smallest value is found by bisection on its derivative, so a path that grazes the band between samples is found.
pub const SEGMENT_SAMPLE_MM: f64 = 0.5;
/// Upper bound on samples per segment (long segments are sampled more coarsely).
pub const SEGMENT_MAX_SAMPLES: usize = 4096;
/// A point beyond a side's full stretch, or inside its folded reach, by no more than this (mm) is that side's straight
/// or folded pose where rounding put it.
pub const REACH_ROUNDING: f64 = 1e-9;
/// A pose whose distal links turn the other way by no more than this (|sin|) is the parallel singular pose where
/// rounding put it.
pub const PARALLEL_ROUNDING: f64 = 1e-9;

#[derive(Debug, Clone)]
pub struct Fivebar {
    params: FivebarParams,
    motors: Vec<Motor>,
    /// Each side's closed-form inverse, its angle in a window `(c − π, c + π]` (see [`window_centre`]).
    geometry: FivebarGeometry,
}

/// One pose of the mechanism.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// The proximal links' absolute angles (rad), in each side's window.
    pub angles: [f64; 2],
    /// The elbows, bed coordinates.
    pub elbows: [[f64; 2]; 2],
    /// Per side, |sin| of the angle between its proximal and distal links (0: straight or folded).
    pub arm_sin: [f64; 2],
    /// Sine of the angle between the distal links, signed to be positive in the working mode (0: in line).
    pub parallel_sin: f64,
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// `v` turned a quarter counter-clockwise.
fn perp(v: [f64; 2]) -> [f64; 2] {
    [-v[1], v[0]]
}

impl Fivebar {
    pub fn new(params: FivebarParams) -> Result<Self, ParamError> {
        for (side, arm) in SIDES.iter().zip([&params.left, &params.right]) {
            ensure_positive(&format!("{side}_proximal_length"), arm.proximal)?;
            ensure_positive(&format!("{side}_distal_length"), arm.distal)?;
            ensure_finite(&format!("{side}_base_x"), arm.base[0])?;
            ensure_finite(&format!("{side}_base_y"), arm.base[1])?;
            ensure_finite(&format!("{side}_zero"), arm.zero)?;
        }
        if params.left.base == params.right.base {
            return Err(ParamError::Invalid {
                name: "left_base_x".into(),
                reason: "the two base joints must be at different places".into(),
            });
        }
        ensure_non_negative("singularity_margin", params.singularity_margin)?;
        if params.singularity_margin >= 1.0 {
            return Err(ParamError::Invalid {
                name: "singularity_margin".into(),
                reason: format!(
                    "|sin| floor {} leaves no usable pose (must be < 1)",
                    params.singularity_margin
                ),
            });
        }
        let motors = vec![
            motor_from(&params.left.stepper, MotorUnit::Rad)?,
            motor_from(&params.right.stepper, MotorUnit::Rad)?,
            motor_from(&params.z, MotorUnit::Mm)?,
        ];
        let geometry = FivebarGeometry {
            sides: [
                FivebarSide::new(
                    LEFT,
                    &params.left,
                    window_centre(&params.left, params.right.base),
                ),
                FivebarSide::new(
                    RIGHT,
                    &params.right,
                    window_centre(&params.right, params.left.base),
                ),
            ],
        };
        Ok(Self {
            params,
            motors,
            geometry,
        })
    }

    /// The five-bar behind a built machine, if it is one.
    pub fn of(kin: &dyn Kinematics) -> Option<&Fivebar> {
        kin.as_any().downcast_ref::<Fivebar>()
    }

    pub fn params(&self) -> &FivebarParams {
        &self.params
    }

    /// Side `k`'s arm (`LEFT`, `RIGHT`).
    pub fn arm(&self, side: usize) -> &FivebarArm {
        if side == LEFT {
            &self.params.left
        } else {
            &self.params.right
        }
    }

    /// Distances from side `k`'s base joint where its |sin| keeps the margin:
    /// `|cos α| ≤ k = √(1 − m²)` ⇔ `d² ∈ [P² + D² − 2PDk, P² + D² + 2PDk]`.
    pub fn band(&self, side: usize) -> (f64, f64) {
        let arm = self.arm(side);
        let (p, d) = (arm.proximal, arm.distal);
        let m = self.params.singularity_margin;
        let k = (1.0 - m * m).sqrt();
        let mid = p * p + d * d;
        let span = 2.0 * p * d * k;
        ((mid - span).max(0.0).sqrt(), (mid + span).sqrt())
    }

    /// The closed-form geometry of both sides (each base joint's angle from the nozzle's position alone).
    pub fn geometry(&self) -> FivebarGeometry {
        self.geometry
    }

    /// Side `k`'s angle, elbow and |sin| for the nozzle at `(x, y)` on its configured branch.
    fn side(&self, side: usize, x: f64, y: f64) -> Result<(f64, [f64; 2], f64), ReachError> {
        let geometry = &self.geometry.sides[side];
        let angle = geometry.angle(x, y)?;
        let (elbow, sin) = geometry.elbow_and_sin(&angle);
        Ok((angle.theta, elbow, sin))
    }

    /// The pose for the nozzle at `(x, y)` in the working mode.
    pub fn pose(&self, x: f64, y: f64) -> Result<Pose, ReachError> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(ReachError::NotFinite);
        }
        let (tl, el, sl) = self.side(LEFT, x, y)?;
        let (tr, er, sr) = self.side(RIGHT, x, y)?;
        let n = [x, y];
        let scale = self.params.left.distal * self.params.right.distal;
        let parallel = self.params.distal_turn.sign() * cross(sub(n, el), sub(er, n)) / scale;
        if parallel < -PARALLEL_ROUNDING {
            return Err(ReachError::BranchImpossible { x, y });
        }
        Ok(Pose {
            angles: [tl, tr],
            elbows: [el, er],
            arm_sin: [sl, sr],
            parallel_sin: parallel,
        })
    }

    /// The nozzle's XY for the proximal links' absolute angles (rad).
    pub fn nozzle(&self, angles: [f64; 2]) -> Result<[f64; 2], ReachError> {
        let elbow = |arm: &FivebarArm, t: f64| {
            [
                arm.base[0] + arm.proximal * t.cos(),
                arm.base[1] + arm.proximal * t.sin(),
            ]
        };
        let (el, er) = (
            elbow(&self.params.left, angles[0]),
            elbow(&self.params.right, angles[1]),
        );
        let (dl, dr) = (self.params.left.distal, self.params.right.distal);
        let w = sub(er, el);
        let e = w[0].hypot(w[1]);
        let (min, max) = ((dl - dr).abs(), dl + dr);
        if e - max > REACH_ROUNDING || min - e > REACH_ROUNDING || e == 0.0 || !e.is_finite() {
            return Err(ReachError::ElbowsApart {
                distance: e,
                min,
                max,
            });
        }
        let a = (dl * dl - dr * dr + e * e) / (2.0 * e);
        let h = (dl * dl - a * a).max(0.0).sqrt();
        let unit = [w[0] / e, w[1] / e];
        // A clockwise turn E_L → N → E_R puts N counter-clockwise of the E_L → E_R line.
        let s = -self.params.distal_turn.sign();
        let side = perp(unit);
        Ok([
            el[0] + a * unit[0] + s * h * side[0],
            el[1] + a * unit[1] + s * h * side[1],
        ])
    }

    /// Whether `p` lies in side `k`'s serial band (|sin| of its elbow angle below the margin), from its distance to
    /// the base joint alone (the planner asks this for every move).
    pub fn in_arm_band(&self, side: usize, p: Vec3) -> bool {
        let arm = self.arm(side);
        let (pl, dl) = (arm.proximal, arm.distal);
        let d2 = (p[0] - arm.base[0]).powi(2) + (p[1] - arm.base[1]).powi(2);
        let cos = (pl * pl + dl * dl - d2) / (2.0 * pl * dl);
        let m = self.params.singularity_margin;
        let rounding = REACH_ROUNDING * (pl + dl) / (pl * dl);
        cos.abs() <= 1.0 + rounding && 1.0 - cos * cos < m * m
    }

    /// What depends on side `k`'s distance from its base alone: its reach and its serial band (`exempt`: `p` lies
    /// next to an end of its segment that rests in that band).
    fn check_side(&self, side: usize, p: Vec3, exempt: bool) -> Result<(), ReachError> {
        let arm = self.arm(side);
        let d = (p[0] - arm.base[0]).hypot(p[1] - arm.base[1]);
        let (min, max) = ((arm.proximal - arm.distal).abs(), arm.proximal + arm.distal);
        if d - max > REACH_ROUNDING || min - d > REACH_ROUNDING {
            return Err(ReachError::ArmReach {
                arm: SIDES[side],
                x: p[0],
                y: p[1],
                distance: d,
                min,
                max,
            });
        }
        if !exempt && self.in_arm_band(side, p) {
            let (pl, dl) = (arm.proximal, arm.distal);
            let cos = ((pl * pl + dl * dl - d * d) / (2.0 * pl * dl)).clamp(-1.0, 1.0);
            return Err(ReachError::ArmSingular {
                arm: SIDES[side],
                x: p[0],
                y: p[1],
                sin: (1.0 - cos * cos).sqrt(),
                margin: self.params.singularity_margin,
            });
        }
        Ok(())
    }

    /// Everything one point must satisfy; `exempt[k]`: side `k`'s serial band is allowed here.
    fn check_pose(&self, p: Vec3, exempt: [bool; 2]) -> Result<Pose, ReachError> {
        ensure_finite_point(p)?;
        self.check_side(LEFT, p, exempt[0])?;
        self.check_side(RIGHT, p, exempt[1])?;
        let pose = self.pose(p[0], p[1])?;
        let margin = self.params.singularity_margin;
        if pose.parallel_sin < margin {
            return Err(ReachError::ParallelSingular {
                x: p[0],
                y: p[1],
                sin: pose.parallel_sin.abs(),
                margin,
            });
        }
        for side in [LEFT, RIGHT] {
            let arm = self.arm(side);
            check_stepper_limits(&arm.stepper, pose.angles[side] + arm.zero)?;
        }
        check_axis_limits('z', &self.params.z, p[2])?;
        Ok(pose)
    }

    /// Rate of change of the signed parallel sine along the XY direction `dir` (per unit of `dir`): the elbows move
    /// with their joints, `E_k' = θ_k' · perp(E_k − B_k)`, `θ_k' = (N − E_k)·dir / ((E_k − B_k) × (N − E_k))`.
    fn parallel_rate(&self, pose: &Pose, n: [f64; 2], dir: [f64; 2]) -> f64 {
        let mut elbow_rate = [[0.0; 2]; 2];
        for side in [LEFT, RIGHT] {
            let arm = self.arm(side);
            let e = pose.elbows[side];
            let (radial, distal) = (sub(e, arm.base), sub(n, e));
            let c = cross(radial, distal);
            if c == 0.0 {
                return 0.0;
            }
            let rate = (distal[0] * dir[0] + distal[1] * dir[1]) / c;
            elbow_rate[side] = [rate * perp(radial)[0], rate * perp(radial)[1]];
        }
        let [el, er] = pose.elbows;
        let turn =
            cross(sub(dir, elbow_rate[0]), sub(er, n)) + cross(sub(n, el), sub(elbow_rate[1], dir));
        let scale = self.params.left.distal * self.params.right.distal;
        self.params.distal_turn.sign() * turn / scale
    }

    /// Per side, the stretches of `a → b` next to an end that rests in that side's serial band (see the SCARA's
    /// `singular_ends`: the distance from the base is monotone on either side of its closest approach).
    fn singular_ends(&self, side: usize, a: Vec3, b: Vec3) -> Exempt {
        if self.params.singularity_margin == 0.0 {
            return Exempt::NONE;
        }
        let (t_near, _) = closest_approach(a, b, self.arm(side).base);
        Exempt::band_ends(|t| self.in_arm_band(side, lerp(a, b, t)), t_near)
    }

    /// The first failure of the distance-only checks of each side, in closed form: the distance from a base is
    /// convex along a line, so its minimum is at the closest approach and its maximum at an end.
    fn check_sides(&self, a: Vec3, b: Vec3, exempt: [Exempt; 2]) -> Option<SegmentError> {
        let mut first: Option<SegmentError> = None;
        for side in [LEFT, RIGHT] {
            let (t_near, _) = closest_approach(a, b, self.arm(side).base);
            let at = |t: f64| self.check_side(side, lerp(a, b, t), exempt[side].covers(t));
            let found = match (at(0.0), at(t_near), at(1.0)) {
                (Err(reason), _, _) => Some(SegmentError { t: 0.0, reason }),
                (_, Err(reason), _) => Some(first_failure(0.0, t_near, reason, at)),
                (_, _, Err(reason)) => Some(first_failure(t_near, 1.0, reason, at)),
                _ => None,
            };
            first = earliest(first, found);
        }
        first
    }

    /// The first failure found by sampling (the parallel band and branch, motor limits): each failing sample is
    /// refined by bisection from the last good one, and each closing-then-opening of the distal links' angle between
    /// two samples is searched for its smallest value.
    fn sample_segment(&self, a: Vec3, b: Vec3, exempt: [Exempt; 2]) -> Option<SegmentError> {
        let dir = [b[0] - a[0], b[1] - a[1]];
        let length = dir[0].hypot(dir[1]);
        let samples = ((length / SEGMENT_SAMPLE_MM).ceil() as usize).clamp(1, SEGMENT_MAX_SAMPLES);
        let check = |t: f64| {
            let p = lerp(a, b, t);
            let covered = [exempt[0].covers(t), exempt[1].covers(t)];
            self.check_pose(p, covered).map(|pose| (pose, p))
        };
        let rate = |(pose, p): &(Pose, Vec3)| self.parallel_rate(pose, [p[0], p[1]], dir);
        let at = |t: f64| check(t).map(|_| ());
        let mut good = match check(0.0) {
            Ok(state) => (0.0, rate(&state)),
            Err(reason) => return Some(SegmentError { t: 0.0, reason }),
        };
        for i in 1..=samples {
            let t = i as f64 / samples as f64;
            let state = match check(t) {
                Ok(state) => state,
                Err(reason) => return Some(first_failure(good.0, t, reason, at)),
            };
            let r = rate(&state);
            if good.1 < 0.0 && r > 0.0 {
                let t_min =
                    self.smallest_parallel(good.0, t, |s| check(s).ok().map(|st| rate(&st)));
                if let Err(reason) = at(t_min) {
                    return Some(first_failure(good.0, t_min, reason, at));
                }
            }
            good = (t, r);
        }
        None
    }

    /// Where between `lo` (closing) and `hi` (opening) the distal links' angle is smallest: bisection on its rate.
    fn smallest_parallel(
        &self,
        mut lo: f64,
        mut hi: f64,
        rate: impl Fn(f64) -> Option<f64>,
    ) -> f64 {
        while hi - lo > SEGMENT_T_TOLERANCE {
            let mid = 0.5 * (lo + hi);
            match rate(mid) {
                Some(r) if r < 0.0 => lo = mid,
                Some(_) => hi = mid,
                // A point that fails its checks: it is the smallest, or beside it.
                None => return mid,
            }
        }
        0.5 * (lo + hi)
    }

    fn motors_of(&self, pose: &Pose, z: f64, motors: &mut [f64]) {
        let values = [
            pose.angles[0] + self.params.left.zero,
            pose.angles[1] + self.params.right.zero,
            z,
        ];
        for (m, v) in motors.iter_mut().zip(values) {
            *m = v;
        }
    }
}

/// A side's angle window: centred on its motor's range when both limits are set (a range narrower than a turn is
/// then always read whole), else pointing away from the other base joint (where the arm of an outward elbow works).
fn window_centre(arm: &FivebarArm, other: [f64; 2]) -> f64 {
    match (arm.stepper.position_min, arm.stepper.position_max) {
        (Some(min), Some(max)) => 0.5 * (min + max) - arm.zero,
        _ => (arm.base[1] - other[1]).atan2(arm.base[0] - other[0]),
    }
}

fn earliest(a: Option<SegmentError>, b: Option<SegmentError>) -> Option<SegmentError> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.t < a.t { b } else { a }),
        (a, b) => a.or(b),
    }
}

impl Kinematics for Fivebar {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &'static str {
        "fivebar"
    }

    fn turning_limits(&self) -> Option<TurningLimits> {
        Some(TurningLimits::Joints)
    }

    fn motors(&self) -> &[Motor] {
        &self.motors
    }

    fn solver_geometry(&self) -> crate::SolverGeometry {
        crate::SolverGeometry::Fivebar(self.geometry)
    }

    /// Each base joint's angle is a closed form of the position alone ([`FivebarSide::angle`], which the Klipper
    /// plug-in's solvers follow), but stepgen has no one-motor solver for it yet: step generation uses the bracketed
    /// solver over [`Kinematics::inverse_near`], exact to its time tolerance.
    fn motor_map(&self, motor: usize) -> MotorMap {
        match motor {
            Z => MotorMap::Linear {
                coeffs: [0.0, 0.0, 1.0],
            },
            _ => MotorMap::General,
        }
    }

    fn inverse(&self, p: Vec3, motors: &mut [f64]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let pose = self.pose(p[0], p[1])?;
        self.motors_of(&pose, p[2], motors);
        Ok(())
    }

    fn inverse_near(
        &self,
        p: Vec3,
        previous: &[f64],
        motors: &mut [f64],
    ) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let mut pose = self.pose(p[0], p[1])?;
        for side in [LEFT, RIGHT] {
            if let Some(prev) = previous.get(side).filter(|v| v.is_finite()) {
                let zero = self.arm(side).zero;
                pose.angles[side] = unwrap_near(pose.angles[side], prev - zero);
            }
        }
        self.motors_of(&pose, p[2], motors);
        Ok(())
    }

    fn forward(&self, motors: &[f64]) -> Result<Vec3, ReachError> {
        let [l, r, z] = match motors {
            [l, r, z, ..] if l.is_finite() && r.is_finite() && z.is_finite() => [*l, *r, *z],
            _ => return Err(ReachError::NotFinite),
        };
        let [x, y] = self.nozzle([l - self.params.left.zero, r - self.params.right.zero])?;
        Ok([x, y, z])
    }

    /// `∂θ_k/∂(x, y) = (N − E_k) / ((E_k − B_k) × (N − E_k))`: from `|N − E_k|² = D_k²` with the elbow turning about
    /// its base. Infinite on a side's straight or folded pose (`Singular`); finite across the parallel singularity.
    fn jacobian(&self, p: Vec3, rows: &mut [Vec3]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let pose = self.pose(p[0], p[1])?;
        let n = [p[0], p[1]];
        let mut joint_rows = [[0.0; 3]; 2];
        for side in [LEFT, RIGHT] {
            let e = pose.elbows[side];
            let distal = sub(n, e);
            let c = cross(sub(e, self.arm(side).base), distal);
            if c == 0.0 {
                return Err(ReachError::Singular {
                    x: p[0],
                    y: p[1],
                    sin_q2: 0.0,
                    margin: self.params.singularity_margin,
                });
            }
            joint_rows[side] = [distal[0] / c, distal[1] / c, 0.0];
        }
        for (row, value) in rows
            .iter_mut()
            .zip([joint_rows[0], joint_rows[1], [0.0, 0.0, 1.0]])
        {
            *row = value;
        }
        Ok(())
    }

    /// Closed form for each side's reach and serial band (distance from its base, convex along a line); sampling
    /// every [`SEGMENT_SAMPLE_MM`] with a minimum search between samples for the parallel band and the distal
    /// links' turn, and for the motor limits; every failure located by bisection to 1e-9 of the segment, the first
    /// reported. No side changes branch inside an accepted segment: that needs it straight or folded, which its
    /// reach check refuses between the ends.
    fn check_segment(&self, a: Vec3, b: Vec3) -> Result<(), SegmentError> {
        for (t, p) in [(0.0, a), (1.0, b)] {
            ensure_finite_point(p).map_err(|reason| SegmentError { t, reason })?;
        }
        let exempt = [
            self.singular_ends(LEFT, a, b),
            self.singular_ends(RIGHT, a, b),
        ];
        let sides = self.check_sides(a, b, exempt);
        if sides.as_ref().is_some_and(|e| e.t == 0.0) {
            return Err(sides.unwrap_or(SegmentError {
                t: 0.0,
                reason: ReachError::NotFinite,
            }));
        }
        match earliest(sides, self.sample_segment(a, b, exempt)) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    fn check_point(&self, p: Vec3) -> Result<(), ReachError> {
        // A point alone is a pose the mechanism rests at: the serial bands are allowed there, the parallel one not.
        self.check_pose(p, [true, true]).map(|_| ())
    }

    fn rests_at(&self, p: Vec3) -> bool {
        self.in_arm_band(LEFT, p) || self.in_arm_band(RIGHT, p)
    }

    fn reach_margin(&self, p: Vec3) -> Option<f64> {
        let margin = |side: usize| {
            let base = self.arm(side).base;
            let d = (p[0] - base[0]).hypot(p[1] - base[1]);
            let (inner, outer) = self.band(side);
            (d - inner).min(outer - d)
        };
        Some(margin(LEFT).min(margin(RIGHT)))
    }

    fn singular_curves(
        &self,
        bounds: &crate::workspace::Bounds,
        spacing: f64,
    ) -> Vec<crate::workspace::SingularCurve> {
        special_poses::singular_curves(self, bounds, spacing)
    }

    fn clearances(&self, p: Vec3, out: &mut Vec<crate::Clearance>) {
        special_poses::clearances(self, p, out);
    }

    fn refusal_in_owner_terms(&self, a: Vec3, b: Vec3) -> Option<String> {
        for side in [LEFT, RIGHT] {
            let arm = self.arm(side);
            let reach = arm.proximal + arm.distal;
            let beyond = (b[0] - arm.base[0]).hypot(b[1] - arm.base[1]) - reach;
            if beyond > REACH_ROUNDING {
                let beyond = crate::beside_limit(beyond, 0.0);
                let name = SIDES[side];
                return Some(format!(
                    "{beyond} mm beyond the {name} arm's reach of {reach} mm"
                ));
            }
            let folded = (arm.proximal - arm.distal).abs();
            let (_, closest) = closest_approach(a, b, arm.base);
            if folded - closest > REACH_ROUNDING {
                let closest = crate::beside_limit(closest, folded);
                let name = SIDES[side];
                return Some(format!(
                    "passes {closest} mm from the {name} base joint, inside its folded reach of {folded} mm"
                ));
            }
        }
        None
    }
}
