//! One motor's step generator: the closed-form solvers for Cartesian axes, the extruder, the polar arm and
//! the polar bed, and the dispatch to the SCARA joint solver (`crate::scara`) and the general solver
//! (`crate::general`). Which steps a motor position makes is the step rule's (`crate::step_rule`).

use std::f64::consts::TAU;

use kinematics::scara::{ScaraGeometry, ScaraJoint};
use kinematics::{Kinematics, MotorMap, RADIAL_ROUNDING, Vec3};
use trapq::{Motion, Piece};

use crate::error::StepError;
use crate::filter::StepFilter;
use crate::general::GeneralState;
use crate::scara::ScaraJointState;
use crate::sink::StepSink;
use crate::step_rule::{LevelInverse, StepRule};
use crate::timing::{Span, clamp_between, clamp_ordered, monotonic_spans};

/// Klipper's planner can emit phases of about −1e-18 s by rounding; like Klipper, such pieces make no steps.
const NEGLIGIBLE_DURATION: f64 = 1e-9;

/// How a motor position depends on the toolhead (or extruder) position along a piece.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotorModel {
    /// position = `coeffs · p` (Cartesian axes; the extruder with `[1, 0, 0]`).
    Linear { coeffs: Vec3 },
    /// position = distance of `(x, y)` from `centre` (polar arm).
    Radius { centre: [f64; 2] },
    /// position = angle of `(x, y)` about `centre`, unwrapped (polar bed).
    Angle { centre: [f64; 2] },
    /// A SCARA joint motor (motor `index` of the kinematics), solved from the geometry alone
    /// (`crate::scara`); spans near the reach limits go through `inverse_near` as `General` does.
    ScaraJoint {
        geometry: ScaraGeometry,
        joint: ScaraJoint,
        index: usize,
    },
    /// No closed form: motor `index` of the kinematics, through `inverse_near`.
    General { index: usize },
}

impl MotorModel {
    /// The model for motor `index` of a machine, from its [`MotorMap`].
    pub fn from_map(map: MotorMap, index: usize) -> Self {
        match map {
            MotorMap::Linear { coeffs } => MotorModel::Linear { coeffs },
            MotorMap::Radius { centre } => MotorModel::Radius { centre },
            MotorMap::Angle { centre } => MotorModel::Angle { centre },
            MotorMap::ScaraJoint { geometry, joint } => MotorModel::ScaraJoint {
                geometry,
                joint,
                index,
            },
            MotorMap::General => MotorModel::General { index },
        }
    }
}

/// What one motor is: its name, step distance and position law.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorSpec {
    pub name: String,
    pub step_distance: f64,
    pub model: MotorModel,
}

/// Step generation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepGenConfig {
    /// MCU clock frequency (Hz); clock = round(print_time · clock_hz).
    pub clock_hz: f64,
    /// Step+dir+step filter window (s); Klipper: 750 µs.
    pub filter_time: f64,
}

impl Default for StepGenConfig {
    fn default() -> Self {
        StepGenConfig {
            clock_hz: 16e6,
            filter_time: 750e-6,
        }
    }
}

/// One motor's running state: the step rule (commanded position, direction and filter) and what its
/// solver keeps between pieces.
#[derive(Debug, Clone)]
pub struct MotorStepper {
    spec: MotorSpec,
    rule: StepRule,
    solver: Solver,
    /// A polar bed's ideal angle at the end of the last piece (continuous with the commanded position): the angle the bed
    /// keeps while the toolhead sits at the centre, where the angle of the position itself is undefined.
    bed_angle: f64,
    /// `(cos, sin)` of one step: a bed's levels advance by this rotation (computed once, not per stretch).
    step_rotation: [f64; 2],
}

/// What a motor without a closed form keeps between pieces.
#[derive(Debug, Clone)]
enum Solver {
    ClosedForm,
    General(GeneralState),
    ScaraJoint(ScaraJointState),
}

impl Solver {
    fn for_model(model: MotorModel, start_motors: &[f64]) -> Self {
        match model {
            MotorModel::General { index } => {
                Solver::General(GeneralState::new(index, start_motors))
            }
            MotorModel::ScaraJoint {
                geometry,
                joint,
                index,
            } => Solver::ScaraJoint(ScaraJointState::new(
                geometry,
                joint,
                GeneralState::new(index, start_motors),
                start_motors,
            )),
            _ => Solver::ClosedForm,
        }
    }
}

impl MotorStepper {
    /// A motor starting at `start_position` (motor units, not rounded to the step grid).
    ///
    /// `start_motors` are all motor positions of the start pose; only general motors need them (to unwrap).
    pub fn new(
        spec: MotorSpec,
        start_position: f64,
        start_motors: &[f64],
        config: StepGenConfig,
    ) -> Self {
        let (step_sin, step_cos) = spec.step_distance.sin_cos();
        let filter = StepFilter::new(config.clock_hz, config.filter_time);
        MotorStepper {
            rule: StepRule::new(spec.step_distance, start_position, filter),
            solver: Solver::for_model(spec.model, start_motors),
            spec,
            bed_angle: start_position,
            step_rotation: [step_cos, step_sin],
        }
    }

    pub fn spec(&self) -> &MotorSpec {
        &self.spec
    }

    /// The commanded position: start position plus the net steps taken so far, times the step distance
    /// (a polar bed angle modulo 2π, kept in about [−π, π]).
    pub fn commanded_position(&self) -> f64 {
        self.rule.commanded_position()
    }

    /// Step pairs removed by the step+dir+step filter so far.
    pub fn filtered_pairs(&self) -> u64 {
        self.rule.filtered_pairs()
    }

    /// Net steps taken so far (+1 per step up, −1 per step down, before filtering).
    pub fn net_steps(&self) -> i64 {
        self.rule.net_steps()
    }

    /// Generate the steps of one piece. Pieces must come in print-time order.
    pub fn process<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        kin: &dyn Kinematics,
        sink: &mut S,
    ) -> Result<(), StepError> {
        self.validate(piece)?;
        if piece.duration <= 0.0 {
            return Ok(());
        }
        if let MotorModel::Linear { coeffs } = self.spec.model
            && dot3(coeffs, piece.axes_r) == 0.0
        {
            // This motor does not move along the piece (Z during a layer): only a jump can step it.
            self.rule
                .settle(dot3(coeffs, piece.start_pos), piece.print_time, sink);
            return Ok(());
        }
        let (spans, count) = monotonic_spans(piece);
        for span in &spans[..count] {
            match self.spec.model {
                MotorModel::Linear { coeffs } => self.linear_span(piece, span, coeffs, sink),
                MotorModel::Radius { centre } => self.radius_span(piece, span, centre, sink),
                MotorModel::Angle { centre } => self.angle_span(piece, span, centre, sink)?,
                MotorModel::ScaraJoint { .. } | MotorModel::General { .. } => {
                    self.solved_span(piece, span, kin, sink)?
                }
            }
        }
        if let MotorModel::Angle { .. } = self.spec.model {
            self.normalise_angle();
        }
        Ok(())
    }

    /// Keep a bed angle's commanded position within about [−π, π], as Klipper does after every piece: it
    /// bounds the rounding of the commanded position however many turns the bed makes.
    fn normalise_angle(&mut self) {
        if let Some(turn) = self.rule.fold_turn() {
            self.bed_angle += turn;
        }
    }

    /// Steps of a motor without a closed form over one span, by the solver its model was given.
    fn solved_span<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        span: &Span,
        kin: &dyn Kinematics,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let motor = self.spec.name.as_str();
        match &mut self.solver {
            Solver::General(state) => {
                state.span_steps(&mut self.rule, motor, piece, span, kin, sink)
            }
            Solver::ScaraJoint(state) => {
                state.span_steps(&mut self.rule, motor, piece, span, kin, sink)
            }
            // Closed-form models never come here (`process` steps them itself).
            Solver::ClosedForm => Ok(()),
        }
    }

    /// End of input: the held-back step is final, and every final step goes to the sink.
    pub fn finish<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        self.rule.finish(sink);
    }

    /// Hand the final steps generated so far to the sink (they are otherwise collected into longer slices;
    /// the held-back step stays held back).
    pub fn flush<S: StepSink + ?Sized>(&mut self, sink: &mut S) {
        self.rule.flush(sink);
    }

    #[inline]
    fn validate(&self, piece: &Piece) -> Result<(), StepError> {
        // A product with zero is 0 for every finite value and NaN otherwise: one test for all ten values,
        // which every motor makes on every piece (summed pairwise, so the additions do not wait in a chain).
        let [x, y, z] = piece.start_pos;
        let [u, v, w] = piece.axes_r;
        let zero = |a: f64, b: f64| a * 0.0 + b * 0.0;
        let zeros = (zero(piece.print_time, piece.duration)
            + zero(piece.start_v, piece.half_accel))
            + (zero(x, y) + zero(z, u))
            + zero(v, w);
        let finite = zeros == 0.0;
        if finite && piece.duration >= -NEGLIGIBLE_DURATION && piece.print_time >= 0.0 {
            return Ok(());
        }
        Err(self.invalid_piece(piece, finite))
    }

    #[cold]
    fn invalid_piece(&self, piece: &Piece, finite: bool) -> StepError {
        StepError::InvalidPiece {
            motor: self.spec.name.clone(),
            time: piece.print_time,
            reason: if finite {
                "negative time"
            } else {
                "non-finite value"
            },
        }
    }

    fn linear_span<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        span: &Span,
        k: Vec3,
        sink: &mut S,
    ) {
        let k0 = dot3(k, piece.start_pos);
        let k1 = dot3(k, piece.axes_r);
        let fa = k0 + k1 * span.d0;
        let fb = k0 + k1 * span.d1;
        let mut inverse = |level: f64| {
            let s = clamp_between((level - k0) / k1, span.d0, span.d1);
            span.time_at(s)
        };
        self.rule
            .monotonic(fa, fb, span.t0, piece.print_time, &mut inverse, sink);
    }

    fn radius_span<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        span: &Span,
        centre: [f64; 2],
        sink: &mut S,
    ) {
        let line = PlaneLine::new(piece, centre);
        let s_turn = line.closest_s();
        // The radius has one minimum along the line: split the span there.
        let (d0, d1) = (span.d0, span.d1);
        let splits: [(f64, f64); 2];
        let parts = if line.uu > 0.0 && (s_turn - d0) * (s_turn - d1) < 0.0 {
            splits = [(d0, s_turn), (s_turn, d1)];
            &splits[..]
        } else {
            splits = [(d0, d1), (d0, d1)];
            &splits[..1]
        };
        let perp = line.perpendicular_distance();
        let inv_speed_factor = 1.0 / line.uu.sqrt();
        for &(sa, sb) in parts {
            let fa = line.radius_at(sa);
            let fb = line.radius_at(sb);
            // Which side of the closest point this part lies on.
            let side = if sa + sb >= 2.0 * s_turn { 1.0 } else { -1.0 };
            let ta = span.time_at(sa);
            let mut inverse = |level: f64| {
                let along = ((level - perp) * (level + perp)).max(0.0).sqrt() * inv_speed_factor;
                span.time_at(clamp_between(s_turn + side * along, sa, sb))
            };
            self.rule
                .monotonic(fa, fb, ta, piece.print_time, &mut inverse, sink);
        }
    }

    fn angle_span<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        span: &Span,
        centre: [f64; 2],
        sink: &mut S,
    ) -> Result<(), StepError> {
        if piece.motion == Motion::BedTurn {
            self.turn_span(piece, span, sink);
            return Ok(());
        }
        let line = PlaneLine::new(piece, centre);
        if line.uu == 0.0 {
            // No XY motion (a Z move): the angle cannot change, even when parked at the centre.
            // Klipper skips such moves for XY steppers too.
            return Ok(());
        }
        let qa = line.point(span.d0);
        let qb = line.point(span.d1);
        // |cross| / |u| ≤ RADIAL_ROUNDING, without a square root on the bed's hot path.
        if line.cross * line.cross <= RADIAL_ROUNDING * RADIAL_ROUNDING * line.uu {
            return self.radial_span(piece, span, &line, sink);
        }
        let raw = qa[1].atan2(qa[0]);
        let fa = raw + TAU * ((self.rule.commanded_position() - raw) / TAU).round();
        // Swept angle along a line is below π; its sign is the sign of cross(P, U) times the travel.
        let sweep = ((span.d1 - span.d0) * line.cross).atan2(qa[0] * qb[0] + qa[1] * qb[1]);
        let fb = fa + sweep;
        let mut inverse = AngleInverse::new(&line, span, self.step_rotation);
        self.rule
            .monotonic(fa, fb, span.t0, piece.print_time, &mut inverse, sink);
        self.bed_angle = fb;
        Ok(())
    }

    /// A radial line: the bed angle is constant along it. It may end or start at the centre (the bed keeps
    /// its angle there), but not cross it: crossing needs the planner to stop and turn the bed there.
    fn radial_span<S: StepSink + ?Sized>(
        &mut self,
        piece: &Piece,
        span: &Span,
        line: &PlaneLine,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let qa = line.point(span.d0);
        let qb = line.point(span.d1);
        let on_centre = |q: [f64; 2]| q[0].hypot(q[1]) <= RADIAL_ROUNDING;
        let s = line.closest_s();
        let crosses = !on_centre(qa) && !on_centre(qb) && (s - span.d0) * (s - span.d1) < 0.0;
        if crosses {
            return Err(StepError::ThroughCentre {
                motor: self.spec.name.clone(),
                time: piece.print_time + span.t0,
            });
        }
        // The end farther from the centre gives the angle (the other may be the centre up to rounding).
        let off_centre = if qa[0].hypot(qa[1]) >= qb[0].hypot(qb[1]) {
            qa
        } else {
            qb
        };
        let angle = if on_centre(off_centre) {
            self.bed_angle
        } else {
            let raw = off_centre[1].atan2(off_centre[0]);
            raw + TAU * ((self.bed_angle - raw) / TAU).round()
        };
        self.rule.settle(angle, piece.print_time + span.t0, sink);
        self.bed_angle = angle;
        Ok(())
    }

    /// The bed turning while the toolhead stays at the centre: the piece's distance is the turn (rad,
    /// counter-clockwise positive).
    fn turn_span<S: StepSink + ?Sized>(&mut self, piece: &Piece, span: &Span, sink: &mut S) {
        let base = self.bed_angle - span.d0;
        let fa = self.bed_angle;
        let fb = base + span.d1;
        let mut inverse = |level: f64| span.time_at(clamp_between(level - base, span.d0, span.d1));
        self.rule
            .monotonic(fa, fb, span.t0, piece.print_time, &mut inverse, sink);
        self.bed_angle = fb;
    }
}

/// The XY trace of a piece relative to a centre: `Q(s) = P + U·s`.
#[derive(Debug, Clone, Copy)]
struct PlaneLine {
    p: [f64; 2],
    u: [f64; 2],
    uu: f64,
    /// cross(P, U): constant along the line; its sign is the turning direction about the centre.
    cross: f64,
}

impl PlaneLine {
    fn new(piece: &Piece, centre: [f64; 2]) -> Self {
        let p = [
            piece.start_pos[0] - centre[0],
            piece.start_pos[1] - centre[1],
        ];
        let u = [piece.axes_r[0], piece.axes_r[1]];
        PlaneLine {
            p,
            u,
            uu: u[0] * u[0] + u[1] * u[1],
            cross: p[0] * u[1] - p[1] * u[0],
        }
    }

    #[inline]
    fn point(&self, s: f64) -> [f64; 2] {
        [self.p[0] + self.u[0] * s, self.p[1] + self.u[1] * s]
    }

    /// The arm position `√(x² + y²)`, in Klipper's own arithmetic (not `hypot`: slower, and it can differ in
    /// the last bit).
    #[inline]
    fn radius_at(&self, s: f64) -> f64 {
        let q = self.point(s);
        (q[0] * q[0] + q[1] * q[1]).sqrt()
    }

    /// Distance parameter of the point closest to the centre (meaningful when `uu > 0`).
    fn closest_s(&self) -> f64 {
        if self.uu > 0.0 {
            -(self.p[0] * self.u[0] + self.p[1] * self.u[1]) / self.uu
        } else {
            0.0
        }
    }

    /// Distance from the centre to the line, from the cross product (no cancellation).
    fn perpendicular_distance(&self) -> f64 {
        if self.uu > 0.0 {
            self.cross.abs() / self.uu.sqrt()
        } else {
            self.p[0].hypot(self.p[1])
        }
    }
}

/// Bed angle → distance: the line meets the ray at angle θ where cross((cos θ, sin θ), P + U·s) = 0.
/// Within one monotonic stretch the levels come one step apart in one direction, so (cos θ, sin θ) advance
/// by a fixed rotation; the exact value is computed at the first level of every batch (at most
/// [`crate::step_rule::STEP_BATCH`] levels), so rounding cannot accumulate (measured drift at most 1.3e-14 after 63 rotations).
struct AngleInverse<'a> {
    line: &'a PlaneLine,
    span: &'a Span,
    /// `(cos, sin)` of one step up.
    step_rotation: [f64; 2],
    /// The rotation by one step in the batch's direction.
    rotation: [f64; 2],
    /// `(cos θ, sin θ)` of the next level.
    ray: [f64; 2],
    /// The span's speed when it cruises: distance / speed in one division (the clamp in time then equals
    /// the clamp in distance).
    cruise_speed: Option<f64>,
}

impl<'a> AngleInverse<'a> {
    fn new(line: &'a PlaneLine, span: &'a Span, step_rotation: [f64; 2]) -> Self {
        AngleInverse {
            line,
            span,
            step_rotation,
            rotation: step_rotation,
            ray: [1.0, 0.0],
            cruise_speed: span.cruise_speed(),
        }
    }
}

impl LevelInverse for AngleInverse<'_> {
    #[inline]
    fn start_batch(&mut self, first: f64, dir: f64) {
        // sin is odd and cos even, so the rotation by one step down is exactly the conjugate.
        self.rotation = [self.step_rotation[0], dir * self.step_rotation[1]];
        let (s, c) = first.sin_cos();
        self.ray = [c, s];
    }

    #[inline(always)]
    fn next_time(&mut self, _level: f64) -> f64 {
        let [c, s] = self.ray;
        let [rc, rs] = self.rotation;
        let (p, u) = (self.line.p, self.line.u);
        // Where the level's ray meets the line: numerator and denominator of the distance −num/den.
        let num = c * p[1] - s * p[0];
        let den = c * u[1] - s * u[0];
        self.ray = [c * rc - s * rs, s * rc + c * rs];
        let span = self.span;
        match self.cruise_speed {
            Some(v) if den != 0.0 => span.clamp_time(-num / (den * v)),
            Some(_) => span.time_at(span.d0),
            None => {
                let (lo, hi) = if span.d0 <= span.d1 {
                    (span.d0, span.d1)
                } else {
                    (span.d1, span.d0)
                };
                let dist = if den != 0.0 { -num / den } else { span.d0 };
                span.time_at(clamp_ordered(dist, lo, hi))
            }
        }
    }
}

#[inline]
fn dot3(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
