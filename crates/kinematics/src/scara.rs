//! SCARA arm with a general elbow coupling (FEKT-SCARA, X-SCARA, Morgan, RepRapFirmware conventions).
//!
//! Joint angles `q1` (shoulder, proximal link from the shoulder axis) and `q2` (elbow, distal link relative
//! to the proximal one). Motors: `stepper_a = q1 + shoulder_zero`, `stepper_b = q2 + c·q1 + elbow_zero`
//! (`c·q1` computed as `q1/ecr` when the config gave `ecr`, as the FEKT fork does), `stepper_z = z`.
//!
//! Frames: `Standard` measures angles from +X counter-clockwise: `u = L1 cos q1 + L2 cos(q1+q2)`,
//! `v = L1 sin q1 + L2 sin(q1+q2)` with `(u, v) = (x − ox, y − oy)`. `XScara` measures them from +Y
//! turning towards +X (the thesis' frame after its x mirror), which is the standard frame with `u` and `v`
//! swapped: `(u, v) = (y − oy, x − ox)`.
//!
//! [`Kinematics::inverse`] fails only where no arm pose exists (`OutOfReach` beyond `L1+L2`,
//! `InsideMinimumRadius` inside `|L1−L2|`); the soft limits (base protection radius, singularity margin,
//! joint and motor limits) are applied by [`Kinematics::check_point`] / [`Kinematics::check_segment`].

use std::f64::consts::{PI, TAU};

use crate::angle::unwrap_near;
use crate::common::{
    Exempt, SEGMENT_T_TOLERANCE, check_axis_limits, check_range, check_stepper_limits,
    closest_approach, ensure_finite, ensure_finite_point, ensure_non_negative, ensure_positive,
    ensure_range, first_failure, lerp, motor_from,
};
use crate::{
    ElbowBranch, Kinematics, Motor, MotorMap, MotorUnit, ParamError, ReachError, ScaraFrame,
    ScaraParams, SegmentError, TurningLimits, Vec3,
};

/// Motor order: shoulder (rad), elbow (rad), z (mm).
pub const SHOULDER: usize = 0;
pub const ELBOW: usize = 1;
pub const Z: usize = 2;

/// Spacing (mm) of the samples that look for joint-limit crossings along a segment; a crossing found
/// between two samples is refined by bisection to `SEGMENT_T_TOLERANCE`. A limit excursion shorter than
/// the spacing can be missed; q1 moves less than 1 mm / base radius between samples.
pub const SEGMENT_SAMPLE_MM: f64 = 1.0;
/// Upper bound on samples per segment (long segments are sampled more coarsely).
pub const SEGMENT_MAX_SAMPLES: usize = 1024;
/// A point beyond the arm's full stretch, or inside its folded reach, by no more than this (mm) is the straight or
/// folded arm's pose where rounding put it (the forward kinematics of a straight arm lands up to about 1e-13 mm
/// beyond `L1 + L2`): [`ScaraGeometry::joints`] takes it as that pose instead of refusing it.
pub const REACH_ROUNDING: f64 = 1e-9;

#[derive(Debug, Clone)]
pub struct Scara {
    params: ScaraParams,
    geometry: ScaraGeometry,
    motors: Vec<Motor>,
}

/// The arm's geometry and motor coupling: everything a point's joint angles and motor positions depend on.
/// Plain `Copy` data with no allocation, so a step-time callback (the Klipper plug-in's) can carry it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaraGeometry {
    link1_length: f64,
    link2_length: f64,
    offset_x: f64,
    offset_y: f64,
    elbow_coupling: f64,
    ecr: Option<f64>,
    elbow: ElbowBranch,
    frame: ScaraFrame,
    shoulder_zero: f64,
    elbow_zero: f64,
    fekt_cos_quirk: bool,
}

/// Which joint motor of a SCARA a [`MotorMap::ScaraJoint`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScaraJoint {
    /// `stepper_a = q1 + shoulder_zero`.
    Shoulder,
    /// `stepper_b = q2 + c·q1 + elbow_zero`.
    Elbow,
}

/// Joint angles of one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joints {
    pub q1: f64,
    pub q2: f64,
}

impl Scara {
    pub fn new(params: ScaraParams) -> Result<Self, ParamError> {
        ensure_positive("link1_length", params.link1_length)?;
        ensure_positive("link2_length", params.link2_length)?;
        for (name, v) in [
            ("offset_x", params.offset_x),
            ("offset_y", params.offset_y),
            ("elbow_coupling", params.elbow_coupling),
            ("shoulder_zero", params.shoulder_zero),
            ("elbow_zero", params.elbow_zero),
        ] {
            ensure_finite(name, v)?;
        }
        ensure_non_negative("base_protection_radius", params.base_protection_radius)?;
        ensure_non_negative("singularity_margin", params.singularity_margin)?;
        if params.singularity_margin >= 1.0 {
            return Err(ParamError::Invalid {
                name: "singularity_margin".into(),
                reason: format!(
                    "|sin q2| floor {} leaves no usable pose (must be < 1)",
                    params.singularity_margin
                ),
            });
        }
        ensure_range("shoulder_limits", params.shoulder_limits)?;
        ensure_range("elbow_limits", params.elbow_limits)?;
        if let Some(ecr) = params.ecr {
            ensure_finite("ecr", ecr)?;
            if ecr == 0.0 {
                return Err(ParamError::Invalid {
                    name: "ecr".into(),
                    reason: "must not be zero".into(),
                });
            }
            if (params.elbow_coupling - 1.0 / ecr).abs() > 1e-12 {
                return Err(ParamError::Invalid {
                    name: "elbow_coupling".into(),
                    reason: format!(
                        "{} disagrees with ecr {ecr} (expected 1/ecr)",
                        params.elbow_coupling
                    ),
                });
            }
        }
        let motors = vec![
            motor_from(&params.shoulder_stepper, MotorUnit::Rad)?,
            motor_from(&params.elbow_stepper, MotorUnit::Rad)?,
            motor_from(&params.z, MotorUnit::Mm)?,
        ];
        let geometry = ScaraGeometry {
            link1_length: params.link1_length,
            link2_length: params.link2_length,
            offset_x: params.offset_x,
            offset_y: params.offset_y,
            elbow_coupling: params.elbow_coupling,
            ecr: params.ecr,
            elbow: params.elbow,
            frame: params.frame,
            shoulder_zero: params.shoulder_zero,
            elbow_zero: params.elbow_zero,
            fekt_cos_quirk: false,
        };
        Ok(Self {
            params,
            geometry,
            motors,
        })
    }

    /// Replicates the FEKT fork's quirk: where `|cos q2| < 1e-9` it uses `q2 = acos(1e-6)` instead of
    /// `acos(cos q2)` (a ~1e-6 rad jump at right-angle elbows). Only for bit-exact comparisons with its output.
    pub fn with_fekt_cos_quirk(mut self, on: bool) -> Self {
        self.geometry.fekt_cos_quirk = on;
        self
    }

    /// The geometry alone (for callers that compute many points without the limits).
    pub fn geometry(&self) -> ScaraGeometry {
        self.geometry
    }

    /// The SCARA behind a built machine, if it is one.
    pub fn of(kin: &dyn Kinematics) -> Option<&Scara> {
        kin.as_any().downcast_ref::<Scara>()
    }

    pub fn params(&self) -> &ScaraParams {
        &self.params
    }

    /// Shoulder axis in bed coordinates.
    pub fn shoulder(&self) -> [f64; 2] {
        [self.params.offset_x, self.params.offset_y]
    }

    /// Innermost distance from the shoulder allowed by geometry, base protection and singularity margin.
    pub fn min_radius(&self) -> f64 {
        let (inner, _) = self.singular_free_band();
        inner.max(self.params.base_protection_radius)
    }

    /// Outermost distance from the shoulder allowed by geometry and the singularity margin.
    pub fn max_radius(&self) -> f64 {
        self.singular_free_band().1
    }

    /// Distances from the shoulder where `|sin q2| ≥ margin` holds:
    /// `|cos q2| ≤ k = √(1 − m²)` ⇔ `ρ² ∈ [L1² + L2² − 2·L1·L2·k, L1² + L2² + 2·L1·L2·k]`.
    fn singular_free_band(&self) -> (f64, f64) {
        let (l1, l2) = (self.params.link1_length, self.params.link2_length);
        let m = self.params.singularity_margin;
        let k = (1.0 - m * m).sqrt();
        let mid = l1 * l1 + l2 * l2;
        let span = 2.0 * l1 * l2 * k;
        ((mid - span).max(0.0).sqrt(), (mid + span).sqrt())
    }

    /// Joint angles for an XY point on the configured branch (see [`ScaraGeometry::joints`]).
    pub fn joints(&self, x: f64, y: f64) -> Result<Joints, ReachError> {
        self.geometry.joints(x, y)
    }

    /// Joint angles from motor positions.
    pub fn joints_from_motors(&self, a: f64, b: f64) -> Joints {
        self.geometry.joints_from_motors(a, b)
    }

    fn arm_frame(&self, x: f64, y: f64) -> (f64, f64) {
        self.geometry.arm_frame(x, y)
    }

    fn motors_from_joints(&self, j: Joints, z: f64, motors: &mut [f64]) {
        let (a, b) = self.geometry.motors_from_joints(j);
        for (m, v) in motors.iter_mut().zip([a, b, z]) {
            *m = v;
        }
    }

    /// Soft limits of one point with known joint angles (q1 as it would be commanded). `singular_ok`: the point
    /// lies next to an end of its segment that rests in the singular band (see [`Self::singular_ends`]).
    fn check_pose(&self, p: Vec3, j: Joints, singular_ok: bool) -> Result<(), ReachError> {
        let [x, y, z] = p;
        let (u, v) = self.arm_frame(x, y);
        let distance = (u * u + v * v).sqrt();
        if distance < self.params.base_protection_radius {
            return Err(ReachError::InsideMinimumRadius {
                x,
                y,
                distance,
                min: self.params.base_protection_radius,
            });
        }
        let sin_q2 = j.q2.sin().abs();
        if sin_q2 < self.params.singularity_margin && !singular_ok {
            return Err(ReachError::Singular {
                x,
                y,
                sin_q2,
                margin: self.params.singularity_margin,
            });
        }
        let branch_ok = match self.params.elbow {
            ElbowBranch::Left => j.q2 >= 0.0,
            ElbowBranch::Right => j.q2 <= 0.0,
        };
        if !branch_ok {
            return Err(ReachError::BranchImpossible { x, y });
        }
        if let Some((min, max)) = self.params.shoulder_limits {
            check_range("q1 (shoulder joint)", j.q1, Some(min), Some(max))?;
        }
        if let Some((min, max)) = self.params.elbow_limits {
            check_range("q2 (elbow joint)", j.q2, Some(min), Some(max))?;
        }
        let mut motors = [0.0; 3];
        self.motors_from_joints(j, z, &mut motors);
        check_stepper_limits(&self.params.shoulder_stepper, motors[SHOULDER])?;
        check_stepper_limits(&self.params.elbow_stepper, motors[ELBOW])?;
        check_axis_limits('z', &self.params.z, z)
    }

    /// Whether a q1-dependent limit (shoulder joint, either motor) could be crossed on a segment starting
    /// with shoulder angle `q1_start`. Along a straight segment that stays out of the singular circles,
    /// `q1 = θ − β` where the direction `θ` from the shoulder turns by less than π and `β ∈ [0, π]`
    /// (mirrored on the right branch) changes by at most π: `|q1 − q1_start| < 2π`, and `|q2| ≤ π`.
    /// Limits wider than that bound never bind, and the sampling is skipped.
    fn q1_limits_may_bind(&self, q1_start: f64) -> bool {
        let q1 = (q1_start - TAU, q1_start + TAU);
        let outside = |lo: f64, hi: f64, min: Option<f64>, max: Option<f64>| {
            min.is_some_and(|m| lo < m) || max.is_some_and(|m| hi > m)
        };
        let shoulder = self
            .params
            .shoulder_limits
            .is_some_and(|(min, max)| outside(q1.0, q1.1, Some(min), Some(max)));
        let a = &self.params.shoulder_stepper;
        let a_zero = self.params.shoulder_zero;
        let motor_a = outside(q1.0 + a_zero, q1.1 + a_zero, a.position_min, a.position_max);
        let c = self.params.elbow_coupling;
        let (c_lo, c_hi) = if c >= 0.0 {
            (c * q1.0, c * q1.1)
        } else {
            (c * q1.1, c * q1.0)
        };
        let b = &self.params.elbow_stepper;
        let b_zero = self.params.elbow_zero;
        let motor_b = outside(
            -PI + c_lo + b_zero,
            PI + c_hi + b_zero,
            b.position_min,
            b.position_max,
        );
        shoulder || motor_a || motor_b
    }

    /// Joint angles at `t` of the segment with q1 continuous from `previous_q1`.
    fn joints_near(&self, p: Vec3, previous_q1: f64) -> Result<Joints, ReachError> {
        let j = self.joints(p[0], p[1])?;
        Ok(Joints {
            q1: unwrap_near(j.q1, previous_q1),
            q2: j.q2,
        })
    }

    /// Samples the segment for shoulder/motor limit crossings (q1 is not monotone along a line).
    fn sample_joint_limits(&self, a: Vec3, b: Vec3, exempt: Exempt) -> Result<(), SegmentError> {
        let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        let samples = ((length / SEGMENT_SAMPLE_MM).ceil() as usize).clamp(1, SEGMENT_MAX_SAMPLES);
        let start = self
            .joints(a[0], a[1])
            .map_err(|reason| SegmentError { t: 0.0, reason })?;
        let mut good_t = 0.0;
        let mut good_q1 = start.q1;
        for i in 1..=samples {
            let t = i as f64 / samples as f64;
            let p = lerp(a, b, t);
            let state = self
                .joints_near(p, good_q1)
                .and_then(|j| self.check_pose(p, j, exempt.covers(t)).map(|()| j));
            match state {
                Ok(j) => {
                    good_t = t;
                    good_q1 = j.q1;
                }
                Err(_) => return Err(self.refine_crossing(a, b, (good_t, good_q1), t, exempt)),
            }
        }
        Ok(())
    }

    /// Bisects between a good `t` and a bad `t` to locate where the segment first fails.
    fn refine_crossing(
        &self,
        a: Vec3,
        b: Vec3,
        (mut good_t, mut good_q1): (f64, f64),
        mut bad_t: f64,
        exempt: Exempt,
    ) -> SegmentError {
        let mut reason = ReachError::NotFinite;
        while bad_t - good_t > SEGMENT_T_TOLERANCE {
            let mid = 0.5 * (good_t + bad_t);
            let p = lerp(a, b, mid);
            match self
                .joints_near(p, good_q1)
                .and_then(|j| self.check_pose(p, j, exempt.covers(mid)).map(|()| j))
            {
                Ok(j) => {
                    good_t = mid;
                    good_q1 = j.q1;
                }
                Err(e) => {
                    bad_t = mid;
                    reason = e;
                }
            }
        }
        if reason == ReachError::NotFinite {
            let p = lerp(a, b, bad_t);
            if let Err(e) = self
                .joints_near(p, good_q1)
                .and_then(|j| self.check_pose(p, j, exempt.covers(bad_t)))
            {
                reason = e;
            }
        }
        SegmentError { t: bad_t, reason }
    }

    fn check_point_exempt(&self, p: Vec3, singular_ok: bool) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let j = self.joints(p[0], p[1])?;
        self.check_pose(p, j, singular_ok)
    }

    /// Whether `p` lies in the singular band (`|sin q2|` below the margin: the arm nearly straight or folded).
    pub fn in_singular_band(&self, p: Vec3) -> bool {
        // cos q2 from the distance to the shoulder (the law of cosines), no inverse trigonometry: the planner
        // asks this for every move. |sin q2| < m ⇔ 1 − cos² q2 < m², for points the arm reaches (|cos q2| ≤ 1).
        let (l1, l2) = (self.params.link1_length, self.params.link2_length);
        let (u, v) = self.arm_frame(p[0], p[1]);
        let cos_q2 = (u * u + v * v - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        let m = self.params.singularity_margin;
        // A straight or folded arm's pose that rounding put just beyond the reach (`REACH_ROUNDING`) is in the band.
        let rounding = REACH_ROUNDING * (l1 + l2) / (l1 * l2);
        cos_q2.abs() <= 1.0 + rounding && 1.0 - cos_q2 * cos_q2 < m * m
    }

    /// The stretches of the segment `a → b` next to an end that rests in the singular band: such an end is a
    /// pose the arm may stop at (the FEKT arm homes to the straight arm) and the planner brings the arm to rest
    /// there, so from rest its joints move at finite speed however close the pose is to singular. Only the
    /// rest of the segment must keep the margin. The distance from the shoulder is monotone on either side of
    /// the closest approach `t_near`, so each stretch ends where the segment leaves the band, found by bisection.
    fn singular_ends(&self, a: Vec3, b: Vec3, t_near: f64) -> Exempt {
        Exempt::band_ends(|t| self.in_singular_band(lerp(a, b, t)), t_near)
    }
}

/// Angle in `(−π, π]`.
impl ScaraGeometry {
    /// Arm-frame coordinates `(u, v)` of a bed point.
    pub fn arm_frame(&self, x: f64, y: f64) -> (f64, f64) {
        let (u, v) = (x - self.offset_x, y - self.offset_y);
        match self.frame {
            ScaraFrame::Standard => (u, v),
            ScaraFrame::XScara => (v, u),
        }
    }

    /// Arm-frame components of a bed-frame direction (the offsets cancel; the X-SCARA frame swaps).
    pub fn arm_direction(&self, dx: f64, dy: f64) -> (f64, f64) {
        match self.frame {
            ScaraFrame::Standard => (dx, dy),
            ScaraFrame::XScara => (dy, dx),
        }
    }

    /// `(L1, L2)`.
    pub fn link_lengths(&self) -> (f64, f64) {
        (self.link1_length, self.link2_length)
    }

    pub fn elbow(&self) -> ElbowBranch {
        self.elbow
    }

    pub fn shoulder_zero(&self) -> f64 {
        self.shoulder_zero
    }

    /// Whether [`Scara::with_fekt_cos_quirk`] is on.
    pub fn fekt_cos_quirk(&self) -> bool {
        self.fekt_cos_quirk
    }

    pub fn bed_frame(&self, u: f64, v: f64) -> (f64, f64) {
        let (a, b) = match self.frame {
            ScaraFrame::Standard => (u, v),
            ScaraFrame::XScara => (v, u),
        };
        (a + self.offset_x, b + self.offset_y)
    }

    /// Joint angles for an XY point on the configured branch, `q1` normalised to `(−π, π]` (the difference
    /// of two `atan2` can leave that range; inside it the value is bit-identical to the fork's expression).
    pub fn joints(&self, x: f64, y: f64) -> Result<Joints, ReachError> {
        let (u, v) = self.arm_frame(x, y);
        let (l1, l2) = (self.link1_length, self.link2_length);
        let mut cos_q2 = (u * u + v * v - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        if cos_q2 > 1.0 {
            let distance = (u * u + v * v).sqrt();
            if distance - (l1 + l2) > REACH_ROUNDING {
                return Err(ReachError::OutOfReach {
                    x,
                    y,
                    distance,
                    max: l1 + l2,
                });
            }
            cos_q2 = 1.0;
        }
        if cos_q2 < -1.0 {
            let distance = (u * u + v * v).sqrt();
            if (l1 - l2).abs() - distance > REACH_ROUNDING {
                return Err(ReachError::InsideMinimumRadius {
                    x,
                    y,
                    distance,
                    min: (l1 - l2).abs(),
                });
            }
            cos_q2 = -1.0;
        }
        if cos_q2.is_nan() {
            return Err(ReachError::NotFinite);
        }
        let used_cos = if self.fekt_cos_quirk && cos_q2.abs() < 1e-9 {
            1e-6
        } else {
            cos_q2
        };
        let q2 = match self.elbow {
            ElbowBranch::Left => used_cos.acos(),
            ElbowBranch::Right => -used_cos.acos(),
        };
        let q1 = v.atan2(u) - (l2 * q2.sin()).atan2(l1 + l2 * q2.cos());
        Ok(Joints {
            q1: normalise(q1),
            q2,
        })
    }

    /// `c·q1`, as a division when `ecr` was configured (the fork's exact arithmetic).
    pub fn coupling(&self, q1: f64) -> f64 {
        match self.ecr {
            Some(ecr) => q1 / ecr,
            None => self.elbow_coupling * q1,
        }
    }

    /// Motor positions `(stepper_a, stepper_b)` of a pose.
    pub fn motors_from_joints(&self, j: Joints) -> (f64, f64) {
        let a = j.q1 + self.shoulder_zero;
        let b = j.q2 + self.coupling(j.q1) + self.elbow_zero;
        (a, b)
    }

    /// Joint angles from motor positions.
    pub fn joints_from_motors(&self, a: f64, b: f64) -> Joints {
        let q1 = a - self.shoulder_zero;
        let q2 = b - self.elbow_zero - self.coupling(q1);
        Joints { q1, q2 }
    }

    /// Nozzle XY of motor positions `(stepper_a, stepper_b)`.
    pub fn forward(&self, a: f64, b: f64) -> (f64, f64) {
        let Joints { q1, q2 } = self.joints_from_motors(a, b);
        let (l1, l2) = (self.link1_length, self.link2_length);
        let u = l1 * q1.cos() + l2 * (q1 + q2).cos();
        let v = l1 * q1.sin() + l2 * (q1 + q2).sin();
        self.bed_frame(u, v)
    }
}

/// The shoulder range firmware can follow: at most (−π, π], where it reads the shoulder angle (atan2, as Marlin, the
/// FEKT-SCARA module and the Klipper plug-in's step solvers take it). A move through ±π would turn the elbow motor by
/// `2π·coupling` at one point, so the configured range is cut there and such a move is refused as a joint limit.
pub fn within_branch_cut(limits: Option<(f64, f64)>) -> (f64, f64) {
    let (min, max) = limits.unwrap_or((-PI, PI));
    (min.max(-PI), max.min(PI))
}

/// Angle in `(−π, π]` (as [`ScaraGeometry::joints`] gives `q1`).
pub fn normalise(a: f64) -> f64 {
    if a > PI {
        a - TAU
    } else if a <= -PI {
        a + TAU
    } else {
        a
    }
}

impl Kinematics for Scara {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &'static str {
        "scara"
    }

    fn turning_limits(&self) -> Option<TurningLimits> {
        Some(TurningLimits::Joints)
    }

    fn motors(&self) -> &[Motor] {
        &self.motors
    }

    /// Joint motors have a one-motor model, except with the FEKT cos quirk: its 1e-6 rad jump at right-angle
    /// elbows has no derivative, and only bit-exact comparisons with the fork use it (general solver).
    fn motor_map(&self, motor: usize) -> MotorMap {
        let joint = match motor {
            Z => {
                return MotorMap::Linear {
                    coeffs: [0.0, 0.0, 1.0],
                };
            }
            SHOULDER => ScaraJoint::Shoulder,
            ELBOW => ScaraJoint::Elbow,
            _ => return MotorMap::General,
        };
        if self.geometry.fekt_cos_quirk {
            MotorMap::General
        } else {
            MotorMap::ScaraJoint {
                geometry: self.geometry,
                joint,
            }
        }
    }

    fn inverse(&self, p: Vec3, motors: &mut [f64]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let j = self.joints(p[0], p[1])?;
        self.motors_from_joints(j, p[2], motors);
        Ok(())
    }

    fn inverse_near(
        &self,
        p: Vec3,
        previous: &[f64],
        motors: &mut [f64],
    ) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let j = self.joints(p[0], p[1])?;
        let q1 = match previous.get(SHOULDER) {
            Some(prev) if prev.is_finite() => unwrap_near(j.q1, prev - self.params.shoulder_zero),
            _ => j.q1,
        };
        self.motors_from_joints(Joints { q1, q2: j.q2 }, p[2], motors);
        Ok(())
    }

    fn forward(&self, motors: &[f64]) -> Result<Vec3, ReachError> {
        let [a, b, z] = match motors {
            [a, b, z, ..] if a.is_finite() && b.is_finite() && z.is_finite() => [*a, *b, *z],
            _ => return Err(ReachError::NotFinite),
        };
        let (x, y) = self.geometry.forward(a, b);
        Ok([x, y, z])
    }

    fn jacobian(&self, p: Vec3, rows: &mut [Vec3]) -> Result<(), ReachError> {
        ensure_finite_point(p)?;
        let [x, y, _] = p;
        let Joints { q1, q2 } = self.joints(x, y)?;
        let (l1, l2) = (self.params.link1_length, self.params.link2_length);
        let det = l1 * l2 * q2.sin();
        if det == 0.0 {
            return Err(ReachError::Singular {
                x,
                y,
                sin_q2: 0.0,
                margin: self.params.singularity_margin,
            });
        }
        // Forward Jacobian [[∂u/∂q1, ∂u/∂q2], [∂v/∂q1, ∂v/∂q2]] inverted in closed form (det = L1·L2·sin q2).
        let (s1, c1) = q1.sin_cos();
        let (s12, c12) = (q1 + q2).sin_cos();
        let (du_dq1, du_dq2) = (-l1 * s1 - l2 * s12, -l2 * s12);
        let (dv_dq1, dv_dq2) = (l1 * c1 + l2 * c12, l2 * c12);
        let q1_uv = [dv_dq2 / det, -du_dq2 / det];
        let q2_uv = [-dv_dq1 / det, du_dq1 / det];
        let to_xy = |g: [f64; 2]| match self.params.frame {
            ScaraFrame::Standard => [g[0], g[1], 0.0],
            ScaraFrame::XScara => [g[1], g[0], 0.0],
        };
        let q1_row = to_xy(q1_uv);
        let q2_row = to_xy(q2_uv);
        let c = self.params.elbow_coupling;
        let b_row = [q2_row[0] + c * q1_row[0], q2_row[1] + c * q1_row[1], 0.0];
        for (row, value) in rows.iter_mut().zip([q1_row, b_row, [0.0, 0.0, 1.0]]) {
            *row = value;
        }
        Ok(())
    }

    /// Closed form for everything that depends only on the distance `ρ` from the shoulder (reach, base
    /// protection, singular band, q2 and its limits): `ρ(t)` is convex along a line, so its minimum is at the
    /// closest approach and its maximum at an end point; a failure is located by bisection where it begins.
    /// q1 and the motor limits are sampled every [`SEGMENT_SAMPLE_MM`] (only when such limits are
    /// configured tightly enough to bind) and crossings refined by bisection to 1e-9 of the segment.
    /// No branch switch can happen inside an accepted segment: it would need `sin q2 = 0`, i.e. `ρ` at
    /// `L1 + L2` or `|L1 − L2|`, which the reach checks refuse.
    fn check_segment(&self, a: Vec3, b: Vec3) -> Result<(), SegmentError> {
        for (t, p) in [(0.0, a), (1.0, b)] {
            ensure_finite_point(p).map_err(|reason| SegmentError { t, reason })?;
        }
        let (t_near, _) = closest_approach(a, b, self.shoulder());
        let exempt = if self.params.singularity_margin > 0.0 {
            self.singular_ends(a, b, t_near)
        } else {
            Exempt::NONE
        };
        self.check_point_exempt(a, exempt.covers(0.0))
            .map_err(|reason| SegmentError { t: 0.0, reason })?;
        // Sampling first, so the reported `t` is the first crossing even when the end point fails too.
        let q1_start = self.joints(a[0], a[1]).map(|j| j.q1).unwrap_or(0.0);
        if self.q1_limits_may_bind(q1_start) {
            self.sample_joint_limits(a, b, exempt)?;
        }
        let at = |t: f64| self.check_point_exempt(lerp(a, b, t), exempt.covers(t));
        if let Err(reason) = at(t_near) {
            return Err(first_failure(0.0, t_near, reason, at));
        }
        if let Err(reason) = at(1.0) {
            return Err(first_failure(t_near, 1.0, reason, at));
        }
        Ok(())
    }

    fn check_point(&self, p: Vec3) -> Result<(), ReachError> {
        // A point alone is a pose the arm rests at: the singular band is allowed there (see `singular_ends`).
        self.check_point_exempt(p, true)
    }

    fn rests_at(&self, p: Vec3) -> bool {
        self.in_singular_band(p)
    }

    fn clearances(&self, p: Vec3, out: &mut Vec<crate::Clearance>) {
        if let Ok(j) = self.joints(p[0], p[1]) {
            out.push(crate::Clearance {
                label: "arm straight or folded",
                value: j.q2.sin().abs(),
                margin: self.params.singularity_margin,
            });
        }
    }

    fn reach_margin(&self, p: Vec3) -> Option<f64> {
        let [sx, sy] = self.shoulder();
        let rho = (p[0] - sx).hypot(p[1] - sy);
        Some((rho - self.min_radius()).min(self.max_radius() - rho))
    }

    fn refusal_in_owner_terms(&self, a: Vec3, b: Vec3) -> Option<String> {
        let [sx, sy] = self.shoulder();
        let reach = self.params.link1_length + self.params.link2_length;
        let beyond = (b[0] - sx).hypot(b[1] - sy) - reach;
        if beyond > 0.0 {
            let beyond = crate::beside_limit(beyond, 0.0);
            return Some(format!("{beyond} mm beyond the arm's reach of {reach} mm"));
        }
        let (_, closest) = crate::closest_approach(a, b, self.shoulder());
        let base = self.params.base_protection_radius;
        (closest < base).then(|| {
            let closest = crate::beside_limit(closest, base);
            format!("passes {closest} mm from the shoulder, inside the base radius of {base} mm")
        })
    }

    fn solver_geometry(&self) -> crate::SolverGeometry {
        crate::SolverGeometry::Scara(self.geometry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StepperParams;

    fn stepper(name: &str) -> StepperParams {
        StepperParams {
            name: name.into(),
            step_distance: TAU / 9600.0,
            position_min: None,
            position_max: None,
        }
    }

    pub(crate) fn fekt() -> Scara {
        Scara::new(ScaraParams {
            shoulder_stepper: stepper("stepper_a"),
            elbow_stepper: stepper("stepper_b"),
            z: stepper("stepper_z"),
            ..ScaraParams::fekt_example()
        })
        .expect("valid params")
    }

    #[test]
    fn out_of_reach_is_an_error_not_nan() {
        let mut m = [0.0; 3];
        let err = fekt().inverse([0.0, 250.0, 0.0], &mut m);
        assert!(matches!(err, Err(ReachError::OutOfReach { max, .. }) if max == 200.0));
    }

    #[test]
    fn base_protection_applies_to_points_not_to_inverse() {
        let mut m = [0.0; 3];
        assert!(fekt().inverse([0.0, 30.0, 0.0], &mut m).is_ok());
        assert!(matches!(
            fekt().check_point([0.0, 30.0, 0.0]),
            Err(ReachError::InsideMinimumRadius { .. })
        ));
    }

    #[test]
    fn a_straight_or_folded_arm_is_reachable_for_every_length() {
        // The forward kinematics of a straight arm lands a few ulps beyond L1 + L2 for about 4 in 10 lengths: such
        // a pose (a homing pose at the straight arm) is the straight arm, not out of reach.
        let mut refused = 0;
        for i in 0..2000 {
            let l1 = 90.0 + 0.0301 * i as f64;
            for (l2, folded) in [(254.05 - l1, false), (l1 - 30.0, true)] {
                let mut p = fekt().params().clone();
                (p.link1_length, p.link2_length, p.base_protection_radius) = (l1, l2, 0.0);
                let s = Scara::new(p).expect("valid");
                for a in [0.0f64, 45.0, 90.0, 135.0, 200.0].map(f64::to_radians) {
                    let q2 = if folded { PI } else { 0.0 };
                    let q = s.forward(&[a, a / 3.0 + q2, 0.0]).expect("forward");
                    let mut m = [0.0; 3];
                    refused += usize::from(s.inverse(q, &mut m).is_err());
                    // Where it is taken, it is the straight (folded) arm: the nozzle where the links put it.
                    let (u, v) = (q[0].hypot(q[1]), if folded { l1 - l2 } else { l1 + l2 });
                    assert!((u - v).abs() < 1e-9, "{l1} {l2}: {u} vs {v}");
                }
            }
        }
        assert_eq!(refused, 0);
        // Beyond the rounding, still out of reach.
        let mut m = [0.0; 3];
        assert!(matches!(
            fekt().inverse([200.0 + 2e-9, 0.0, 0.0], &mut m),
            Err(ReachError::OutOfReach { .. })
        ));
        assert!(fekt().inverse([200.0 + 1e-10, 0.0, 0.0], &mut m).is_ok() && m[1] == 0.0);
    }

    #[test]
    fn mismatched_ecr_and_coupling_are_refused() {
        let mut p = fekt().params().clone();
        p.elbow_coupling = 0.5;
        assert!(matches!(Scara::new(p), Err(ParamError::Invalid { .. })));
    }

    #[test]
    fn singular_band_matches_the_margin() {
        let mut p = fekt().params().clone();
        p.singularity_margin = 0.1;
        let s = Scara::new(p).expect("valid");
        // |sin q2| = 0.1 ⇒ cos q2 = √0.99 ⇒ ρ² = 2·100²·(1 + √0.99)
        let expected = (20000.0 * (1.0 + 0.99f64.sqrt())).sqrt();
        assert!((s.max_radius() - expected).abs() < 1e-9);
        // The arm may rest in the band (the FEKT arm homes stretched straight) and move from or to there: the
        // planner stops it there.
        assert!(s.rests_at([0.0, 199.9, 0.0]) && !s.rests_at([0.0, 150.0, 0.0]));
        assert_eq!(s.check_point([0.0, 199.9, 0.0]), Ok(()));
        assert_eq!(s.check_point([0.0, 200.0, 0.0]), Ok(()));
        assert_eq!(
            s.check_segment([0.0, 200.0, 0.0], [0.0, 130.0, 0.0]),
            Ok(())
        );
        assert_eq!(
            s.check_segment([0.0, 130.0, 0.0], [0.0, 200.0, 0.0]),
            Ok(())
        );
    }

    #[test]
    fn a_segment_through_the_folded_band_is_refused_where_it_enters_it() {
        let mut p = fekt().params().clone();
        p.singularity_margin = 0.1;
        p.base_protection_radius = 0.0;
        let s = Scara::new(p).expect("valid");
        // |sin q2| = 0.1 folded ⇒ ρ = √(2·100²·(1 − √0.99)) ≈ 10.0 mm: a line 5 mm from the shoulder crosses it.
        let inner = (20000.0 * (1.0 - 0.99f64.sqrt())).sqrt();
        let err = s
            .check_segment([-50.0, 5.0, 0.0], [50.0, 5.0, 0.0])
            .expect_err("crosses the folded band");
        assert!(matches!(err.reason, ReachError::Singular { .. }), "{err}");
        let x = -50.0 + 100.0 * err.t;
        assert!((x.hypot(5.0) - inner).abs() < 1e-6, "enters at x = {x}");
    }
}
