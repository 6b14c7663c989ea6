//! The toolhead: accepts moves, checks them, runs the lookahead and appends planned moves to the sink with
//! their print times, the way Klipper's toolhead does in batch mode.

use crate::centre::{self, Passage};
use crate::kinematic_limits;
use crate::limits::{CentreTurn, ExtruderLimits, PlannerConfig, VelocityLimits};
use crate::lookahead::{BUFFER_TIME_HIGH, LookAhead, Move};
use kinematics::{Kinematics, SegmentError};
use trapq::{Motion, MoveSink, Queue, SinkError, TrapezoidMove};

/// Step generation lags at least this far behind "now" (Klipper's `MIN_KIN_TIME`).
const MIN_KIN_TIME: f64 = 0.100;
/// Klipper's batch-mode background flusher works in steps of this much print time.
const BATCH_FLUSH_TIME: f64 = 0.250;
/// It flushes step generation this far beyond the last queued move when it catches up.
const FLUSH_EXTRA_TIME: f64 = 0.250;
/// It only catches up when step generation is within this much of the last queued move.
const FLUSH_CATCH_UP_WINDOW: f64 = 1.5;
/// Step compression may flush this much earlier than step generation.
const STEPCOMPRESS_FLUSH_TIME: f64 = 0.050;
/// Below this much buffered print time, Klipper yields to its timers after each move.
const BUFFER_TIME_HIGH_PAUSE: f64 = 1.0;
/// Klipper's motors-off command dwells this long before and after disabling the motors.
const DISABLE_STALL_TIME: f64 = 0.100;

/// Why a move was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MoveError {
    #[error(
        "move to ({}, {}, {}) is not reachable: {source}",
        kinematics::readable(*x),
        kinematics::readable(*y),
        kinematics::readable(*z)
    )]
    Unreachable {
        x: f64,
        y: f64,
        z: f64,
        source: SegmentError,
    },
    #[error("extrusion without an [extruder] section")]
    NoExtruder,
    #[error(
        "extrude-only move of {distance:.3} mm exceeds max_extrude_only_distance ({max:.3} mm)"
    )]
    ExtrudeOnlyTooLong { distance: f64, max: f64 },
    #[error(
        "move exceeds the maximum extrusion cross-section ({area:.3} mm² vs {max_area:.3} mm², see max_extrude_cross_section)"
    )]
    OverExtrusion { area: f64, max_area: f64 },
    #[error("position is not finite")]
    NotFinite,
    #[error("the motor limits leave no speed on this move ({reason})")]
    NoSpeedLeft { reason: &'static str },
}

/// A move whose speed a machine limit cut hard (below [`SLOW_MOVE_FRACTION`] of the requested speed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlowMove {
    /// The move's origin (a G-code line).
    pub origin: u64,
    pub requested: f64,
    pub allowed: f64,
}

/// A move counts as slowed hard when a limit leaves it less than this share of its requested speed.
pub const SLOW_MOVE_FRACTION: f64 = 0.25;
/// How many slowed moves are kept for reporting (all are counted).
const SLOW_MOVES_KEPT: usize = 1000;

/// Moves slowed hard by machine limits: the first few, and how many in all.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SlowMoves {
    pub first: Vec<SlowMove>,
    pub total: u64,
}

/// The toolhead state machine.
#[derive(Debug)]
pub struct Toolhead<'k, S: MoveSink> {
    config: PlannerConfig,
    limits: VelocityLimits,
    kinematics: &'k dyn Kinematics,
    sink: S,
    /// The sink's first error: nothing more is handed to it, and the planner stops at the next command.
    sink_error: Option<SinkError>,
    lookahead: LookAhead,
    commanded_pos: [f64; 4],
    print_time: f64,
    /// The lookahead was fully flushed: the next moves re-synchronise the print time.
    need_prime: bool,
    /// How far step generation must go, and has gone (Klipper's motion-queuing clock).
    clock: StepGenClock,
    /// Print time above which the next move checks for a pause (Klipper's `need_check_pause`).
    need_check_pause: f64,
    slow_moves: SlowMoves,
    /// Polar machines: the last position off the centre, relative to it, whose angle is the bed angle the motors
    /// hold (the angle itself is computed only when the bed must turn); on the centre the bed keeps it.
    bed_ray: [f64; 2],
    /// Some motor has an acceleration limit, so corners are capped ([`kinematic_limits::junction_v2`]).
    corners_capped: bool,
    /// A move has enabled the motors since the start or the last M84 (Klipper enables a stepper when it steps).
    motors_enabled: bool,
}

/// Klipper's motion-queuing bookkeeping: how far step generation has been flushed. In batch mode
/// (`PlannerConfig::klipper_batch_flush`) it also drives Klipper's background flusher, whose "runout" flushes
/// of the lookahead shape the planned moves.
#[derive(Debug, Clone, Copy)]
struct StepGenClock {
    last_flush_time: f64,
    last_step_gen_time: f64,
    need_flush_time: f64,
    need_step_gen_time: f64,
    /// The flush timer is idle and the next queued motion wakes it.
    kick_armed: bool,
    /// The flush timer is due to run at the next chance.
    timer_due: bool,
}

impl<'k, S: MoveSink> Toolhead<'k, S> {
    pub fn new(config: PlannerConfig, kinematics: &'k dyn Kinematics, sink: S) -> Self {
        Toolhead {
            limits: config.limits,
            clock: StepGenClock {
                last_flush_time: 0.0,
                last_step_gen_time: config.initial_step_gen_time,
                need_flush_time: 0.0,
                need_step_gen_time: 0.0,
                kick_armed: true,
                timer_due: false,
            },
            need_check_pause: -1.0,
            slow_moves: SlowMoves::default(),
            lookahead: LookAhead::new(config.lookahead),
            corners_capped: config
                .kinematic_limits
                .iter()
                .any(|l| l.max_accel.is_some()),
            config,
            kinematics,
            sink,
            sink_error: None,
            commanded_pos: [0.0; 4],
            bed_ray: [1.0, 0.0],
            print_time: 0.0,
            need_prime: true,
            motors_enabled: false,
        }
    }

    pub fn position(&self) -> [f64; 4] {
        self.commanded_pos
    }

    pub fn print_time(&self) -> f64 {
        self.print_time
    }

    pub fn limits(&self) -> VelocityLimits {
        self.limits
    }

    pub fn sink(&self) -> &S {
        &self.sink
    }

    pub fn slow_moves(&self) -> &SlowMoves {
        &self.slow_moves
    }

    /// Finish: plan and hand over every queued move (a stop after the last one).
    pub fn finish(mut self) -> Result<(S, f64, SlowMoves), SinkError> {
        self.flush_lookahead();
        let flushed = self.sink.flush(self.print_time);
        self.note_sink(flushed);
        match self.sink_error {
            Some(e) => Err(e),
            None => Ok((self.sink, self.print_time, self.slow_moves)),
        }
    }

    /// The print time Klipper's batch mode logs at the end of its input (`Exiting (print time …)`): its flush timer
    /// runs once more, then `get_last_move_time` plans what is queued and, when the queue had run empty, reports
    /// where step generation could restart if that is later than the end of the print. The planned moves and the
    /// end time [`Self::finish`] returns are the same whether this is asked or not.
    pub fn klipper_exit_time(&mut self) -> f64 {
        self.input_block_boundary();
        let primed = self.need_prime;
        self.flush_lookahead();
        let end = self.print_time;
        if primed {
            self.calc_print_time();
        }
        let exit = self.print_time;
        self.print_time = end;
        exit
    }

    /// Keep the sink's first error: planning stops at the command that met it.
    fn note_sink(&mut self, result: Result<(), SinkError>) {
        if self.sink_error.is_none() {
            self.sink_error = result.err();
        }
    }

    /// The sink's error, once it has failed (taken: it is reported once).
    pub fn take_sink_error(&mut self) -> Option<SinkError> {
        self.sink_error.take()
    }

    /// Change velocity limits (`SET_VELOCITY_LIMIT`, `M204`); queued moves keep the limits they were made with.
    pub fn set_limits(&mut self, limits: VelocityLimits) {
        self.limits = limits;
    }

    /// Queue a straight move to `target` at `speed` mm/s. `origin` identifies the source (a G-code line).
    ///
    /// When motor limits are configured and bind somewhere along the move, the move is queued as collinear
    /// spans with their own caps (see [`kinematic_limits`]); otherwise it is queued whole, as Klipper does.
    pub fn move_to(&mut self, target: [f64; 4], speed: f64, origin: u64) -> Result<(), MoveError> {
        if target.iter().any(|v| !v.is_finite()) {
            return Err(MoveError::NotFinite);
        }
        match self.config.centre_turn {
            Some(turn) => self.move_by_centre(target, speed, origin, &turn),
            None => self.move_straight(target, speed, origin),
        }
    }

    /// A move on a polar machine: planned through the rotation centre where it comes within the centre's
    /// tolerance, with the bed turning in place there (see [`centre`]).
    fn move_by_centre(
        &mut self,
        target: [f64; 4],
        speed: f64,
        origin: u64,
        turn: &CentreTurn,
    ) -> Result<(), MoveError> {
        let start = self.commanded_pos;
        let target = match centre::passage(start, target, turn) {
            Passage::Away => target,
            Passage::Arrives => centre::onto_centre(target, turn),
            Passage::Stays => {
                self.commanded_pos = centre::onto_centre(start, turn);
                centre::onto_centre(target, turn)
            }
            Passage::Leaves => {
                self.commanded_pos = centre::onto_centre(start, turn);
                if let Some(leaving) = centre::bed_angle(target, turn) {
                    let holding = self.bed_ray[1].atan2(self.bed_ray[0]);
                    let angle = centre::turn_between(holding, leaving);
                    self.turn_bed_at_centre(angle, turn, origin);
                }
                target
            }
            Passage::Through(point) => {
                self.move_by_centre(point, speed, origin, turn)?;
                return self.move_by_centre(target, speed, origin, turn);
            }
        };
        self.move_straight(target, speed, origin)?;
        self.note_bed_ray(turn);
        Ok(())
    }

    /// Off the centre, the bed holds the angle of the toolhead's position.
    fn note_bed_ray(&mut self, turn: &CentreTurn) {
        let ray = centre::ray(self.commanded_pos, turn);
        if ray != [0.0, 0.0] {
            self.bed_ray = ray;
        }
    }

    /// A straight move, cut into spans where motor limits bind.
    fn move_straight(
        &mut self,
        target: [f64; 4],
        speed: f64,
        origin: u64,
    ) -> Result<(), MoveError> {
        let start = self.commanded_pos;
        let Some(whole) = Move::new(start, target, speed, &self.limits, origin) else {
            return Ok(());
        };
        if whole.is_kinematic {
            self.check_reach(&whole)?;
        }
        let spans = if whole.is_kinematic && !self.config.kinematic_limits.is_empty() {
            let requested = speed.min(self.limits.max_velocity);
            kinematic_limits::split(
                self.kinematics,
                &self.config.kinematic_limits,
                xyz(start),
                xyz(whole.end_pos),
                requested,
                whole.accel,
                self.limits.minimum_cruise_ratio,
            )
        } else {
            Vec::new()
        };
        let rests = whole.is_kinematic && self.kinematics.rests_at(xyz(whole.end_pos));
        if spans.is_empty() {
            self.queue_move(whole, speed)?;
        } else {
            self.queue_spans(start, &whole, &spans, speed, origin)?;
        }
        if rests {
            // A pose the machine may only reach at rest: plan everything up to it to a stop.
            self.flush_lookahead();
        }
        Ok(())
    }

    /// The spans of a move, each with its own caps.
    fn queue_spans(
        &mut self,
        start: [f64; 4],
        whole: &Move,
        spans: &[kinematic_limits::Span],
        speed: f64,
        origin: u64,
    ) -> Result<(), MoveError> {
        let mut from = start;
        for (i, span) in spans.iter().enumerate() {
            if !(span.max_speed > 0.0 && span.max_speed.is_finite() && span.max_accel > 0.0) {
                return Err(MoveError::NoSpeedLeft {
                    reason: "it passes through the rotation centre or a singular pose",
                });
            }
            let to = if i + 1 == spans.len() {
                whole.end_pos
            } else {
                let f = span.end / whole.move_d;
                [0, 1, 2, 3].map(|k| start[k] + (whole.end_pos[k] - start[k]) * f)
            };
            let Some(mut part) = Move::new(from, to, speed, &self.limits, origin) else {
                continue;
            };
            part.limit_speed(span.max_speed, span.max_accel);
            self.queue_move(part, speed)?;
            from = to;
        }
        Ok(())
    }

    /// Speed limits of the Z axis and the extruder, then into the lookahead.
    #[inline]
    fn queue_move(&mut self, mut mv: Move, speed: f64) -> Result<(), MoveError> {
        if mv.is_kinematic && self.config.apply_z_limits && mv.axes_d[2] != 0.0 {
            let z_ratio = mv.move_d / mv.axes_d[2].abs();
            mv.limit_speed(
                self.config.max_z_velocity * z_ratio,
                self.config.max_z_accel * z_ratio,
            );
        }
        if let Some(v_rad_max) = self.config.klipper_centre_rule
            && mv.is_kinematic
            && (mv.axes_d[0] != 0.0 || mv.axes_d[1] != 0.0)
        {
            klipper_centre_slowdown(&mut mv, v_rad_max, &self.config.limits);
        }
        if mv.axes_d[3] != 0.0 {
            check_extrusion(self.config.extruder.as_ref(), &mut mv)?;
        }
        self.note_if_slowed(&mv, speed);
        self.commanded_pos = mv.end_pos;
        if let Some(prev) = self.lookahead.last() {
            let extruder_v2 = extruder_junction_v2(self.config.extruder.as_ref(), prev, &mv);
            let motors_v2 = self.motor_junction_v2(prev, &mv);
            mv.calc_junction(prev, extruder_v2.min(motors_v2));
        }
        if self.lookahead.push(mv) {
            self.process_lookahead(true);
        }
        if self.print_time > self.need_check_pause {
            self.check_pause();
        }
        Ok(())
    }

    /// The motors' cap on the junction speed² (see [`kinematic_limits::junction_v2`]).
    fn motor_junction_v2(&self, prev: &Move, mv: &Move) -> f64 {
        if !(self.corners_capped && prev.is_kinematic && mv.is_kinematic) {
            return f64::INFINITY;
        }
        let side = |m: &Move| kinematic_limits::JunctionSide {
            start: xyz(m.start_pos),
            end: xyz(m.end_pos),
            accel: m.accel,
        };
        let limits = &self.config.kinematic_limits;
        kinematic_limits::junction_v2(self.kinematics, limits, side(prev), side(mv))
    }

    fn note_if_slowed(&mut self, mv: &Move, speed: f64) {
        let requested = speed.min(self.limits.max_velocity);
        let threshold = SLOW_MOVE_FRACTION * requested;
        if mv.is_kinematic && mv.max_cruise_v2 < threshold * threshold {
            self.slow_moves.total += 1;
            if self.slow_moves.first.len() < SLOW_MOVES_KEPT {
                self.slow_moves.first.push(SlowMove {
                    origin: mv.origin,
                    requested,
                    allowed: mv.max_cruise_v2.sqrt(),
                });
            }
        }
    }

    /// On the polar centre, before leaving it along another angle than it arrived on: come to rest (a full
    /// flush) and turn the bed in place by `angle` within its limits (a [`Motion::BedTurn`]).
    fn turn_bed_at_centre(&mut self, angle: f64, turn: &CentreTurn, origin: u64) {
        // Below this (rad) the angles differ only by rounding: no turn, no stop.
        const NO_TURN: f64 = 1e-12;
        if angle.abs() <= NO_TURN {
            return;
        }
        self.flush_lookahead();
        let start = self.last_move_time();
        let centre = xyz(self.commanded_pos);
        let mv = TrapezoidMove::bed_turn(start, centre, angle, turn.max_velocity, turn.max_accel);
        // After a sink's first error it is handed nothing more.
        if self.sink_error.is_none() {
            self.sink.origin(origin);
            self.sink_error = self.sink.append(Queue::Toolhead, &mv).err();
        }
        let end = start + mv.duration();
        self.print_time = end;
        self.note_motion_queued(end);
    }

    /// Whether the toolhead could be at `p` (used to refuse arcs that leave the workspace before splitting them).
    pub fn check_point(&self, p: [f64; 3]) -> Result<(), MoveError> {
        if p.iter().any(|v| !v.is_finite()) {
            return Err(MoveError::NotFinite);
        }
        self.kinematics
            .check_point(p)
            .map_err(|reason| MoveError::Unreachable {
                x: p[0],
                y: p[1],
                z: p[2],
                source: SegmentError { t: 0.0, reason },
            })
    }

    /// Reachability along the whole segment (not just its end points).
    fn check_reach(&self, mv: &Move) -> Result<(), MoveError> {
        let (start, end) = (xyz(mv.start_pos), xyz(mv.end_pos));
        self.kinematics
            .check_segment(start, end)
            .map_err(|source| MoveError::Unreachable {
                x: end[0],
                y: end[1],
                z: end[2],
                source,
            })
    }

    /// G4: wait `seconds` after the queued moves finish.
    pub fn dwell(&mut self, seconds: f64) {
        self.flush_lookahead();
        let start = self.last_move_time();
        self.print_time = self.print_time.max(start + seconds.max(0.0));
        self.check_pause();
    }

    /// M400: every queued move is planned to a stop.
    pub fn wait_moves(&mut self) {
        self.flush_lookahead();
    }

    /// M84/M18 as Klipper's `stepper_enable` does it: step generation flushed to the end of the queued moves, and,
    /// when some motor was enabled (a move since the start or the last M84 enabled it), a dwell before and after
    /// disabling them.
    pub fn motors_off(&mut self) {
        self.flush_lookahead();
        let need = self.clock.need_step_gen_time;
        self.advance_flush_time(need, 0.0);
        if self.motors_enabled {
            self.dwell(DISABLE_STALL_TIME);
            self.dwell(DISABLE_STALL_TIME);
            self.motors_enabled = false;
        }
    }

    /// Declare the toolhead position (homing, `SET_KINEMATIC_POSITION`): all queued motion is finished first,
    /// and step generation restarts after a short delay.
    pub fn set_position(&mut self, xyz: [f64; 3]) {
        self.flush_lookahead();
        let need = self.clock.need_step_gen_time;
        self.advance_flush_time(need, 0.0);
        self.commanded_pos[..3].copy_from_slice(&xyz);
        if let Some(turn) = self.config.centre_turn {
            self.note_bed_ray(&turn);
        }
        let declared = self.sink.set_position(xyz, self.commanded_pos[3]);
        self.note_sink(declared);
    }

    /// In batch mode: Klipper read another 4096-byte block of input, and its reactor ran due timers first.
    pub fn input_block_boundary(&mut self) {
        if self.config.klipper_batch_flush {
            self.run_flush_timer();
        }
    }

    /// Declare the extruder position without moving it.
    pub fn set_extruder_position(&mut self, e: f64) {
        self.commanded_pos[3] = e;
    }

    fn last_move_time(&mut self) -> f64 {
        if self.need_prime {
            self.flush_lookahead();
            self.calc_print_time();
        } else {
            self.process_lookahead(false);
        }
        self.print_time
    }

    fn flush_lookahead(&mut self) {
        self.process_lookahead(false);
        self.need_prime = true;
        self.need_check_pause = -1.0;
        self.lookahead.set_flush_time(BUFFER_TIME_HIGH);
    }

    /// Klipper's `_check_pause` in batch mode: with little print time buffered it yields to the reactor, whose
    /// flush timer may run; otherwise it stops checking until the next full flush.
    fn check_pause(&mut self) {
        if self.print_time - BUFFER_TIME_HIGH_PAUSE > 0.0 {
            self.need_check_pause = f64::INFINITY;
            return;
        }
        if !self.need_prime {
            self.need_check_pause = self.print_time;
            if self.config.klipper_batch_flush {
                self.run_flush_timer();
            }
        }
    }

    /// Klipper's batch-mode flush timer (`_flush_handler_debug`): step generation follows the queued moves in
    /// fixed batches; once it is close behind, it flushes past the end, which makes the toolhead plan every
    /// queued move to a stop.
    fn run_flush_timer(&mut self) {
        if !self.clock.timer_due {
            return;
        }
        let catch_up_to = self.clock.need_flush_time - FLUSH_CATCH_UP_WINDOW;
        let mut batches = 0u32;
        while self.clock.last_step_gen_time < catch_up_to {
            let mut target = self.clock.last_step_gen_time + BATCH_FLUSH_TIME;
            if batches > 100 && catch_up_to > target {
                target += ((catch_up_to - target) / BATCH_FLUSH_TIME).trunc() * BATCH_FLUSH_TIME;
            }
            self.advance_flush_time(0.0, target);
            batches += 1;
        }
        if batches > 0 {
            // The timer runs again at the reactor's next turn.
            return;
        }
        let past_end = self.clock.need_flush_time + FLUSH_EXTRA_TIME;
        self.advance_flush_time(past_end, 0.0);
        self.clock.kick_armed = true;
        self.clock.timer_due = false;
    }

    /// Step generation advances; the toolhead flushes its lookahead when step generation reaches the end of
    /// the planned moves (a "runout").
    fn advance_flush_time(&mut self, want_flush_time: f64, want_step_gen_time: f64) {
        let flush_time = want_flush_time
            .max(self.clock.last_flush_time)
            .max(want_step_gen_time - STEPCOMPRESS_FLUSH_TIME);
        let step_gen_time = want_step_gen_time
            .max(self.clock.last_step_gen_time)
            .max(flush_time);
        if !self.need_prime
            && step_gen_time >= self.print_time - self.config.kin_flush_delay - 0.001
        {
            self.flush_lookahead();
        }
        self.clock.last_flush_time = flush_time;
        self.clock.last_step_gen_time = step_gen_time;
    }

    /// Motion up to `end_time` was queued for step generation.
    fn note_motion_queued(&mut self, end_time: f64) {
        self.motors_enabled = true;
        let t = end_time + self.config.kin_flush_delay;
        self.clock.need_step_gen_time = self.clock.need_step_gen_time.max(t);
        self.clock.need_flush_time = self.clock.need_flush_time.max(t);
        if self.clock.kick_armed {
            self.clock.kick_armed = false;
            self.clock.timer_due = true;
        }
    }

    /// Print time of the first move after the queue ran empty: not before the start buffer, and not before
    /// step generation can restart.
    fn calc_print_time(&mut self) {
        let kin_time =
            MIN_KIN_TIME.max(self.clock.last_step_gen_time) + self.config.kin_flush_delay;
        let min_print_time = self.config.buffer_time_start.max(kin_time);
        if min_print_time > self.print_time {
            self.print_time = min_print_time;
        }
    }

    fn process_lookahead(&mut self, lazy: bool) {
        let count = self.lookahead.flush(lazy);
        if count > 0 {
            if self.need_prime {
                self.need_prime = false;
                self.calc_print_time();
            }
            let mut next_move_time = self.print_time;
            for mv in self.lookahead.ready(count) {
                if self.sink_error.is_none() {
                    self.sink_error = emit(&mut self.sink, next_move_time, mv).err();
                }
                next_move_time =
                    next_move_time + mv.plan.accel_t + mv.plan.cruise_t + mv.plan.decel_t;
            }
            self.lookahead.release(count);
            self.print_time = self.print_time.max(next_move_time);
            self.note_motion_queued(next_move_time);
            let flushed = self.sink.flush(self.print_time);
            self.note_sink(flushed);
        }
    }
}

/// Klipper's polar rule (`polar.py`): the bed's speed at the move's closest approach to X0 Y0, at the move's cruise
/// speed, kept within `v_rad_max` by slowing the whole move, speed and acceleration scaled from the configured
/// `max_velocity` and `max_accel` (the plug-in's `centre_slowdown: klipper`, in Klipper's arithmetic).
fn klipper_centre_slowdown(mv: &mut Move, v_rad_max: f64, limits: &VelocityLimits) {
    let d = distance_to_centre(mv.start_pos, mv.end_pos);
    if d == 0.0 {
        return;
    }
    let v_angular = mv.max_cruise_v2.sqrt() / d;
    if v_rad_max < v_angular {
        let scale = v_rad_max / v_angular;
        mv.limit_speed(limits.max_velocity * scale, limits.max_accel * scale);
    }
}

/// Distance of the segment `p1`–`p2` from X0 Y0, operation for operation as the plug-in's `_distance_to_centre`.
fn distance_to_centre(p1: [f64; 4], p2: [f64; 4]) -> f64 {
    let (ab_x, ab_y) = (p2[0] - p1[0], p2[1] - p1[1]);
    let (ap_x, ap_y) = (-p1[0], -p1[1]);
    let dot = ab_x * ap_x + ab_y * ap_y;
    let length = (ab_x.powi(2) + ab_y.powi(2)).sqrt();
    if dot <= 0.0 {
        return (ap_x.powi(2) + ap_y.powi(2)).sqrt();
    }
    if dot >= length.powi(2) {
        return (p2[0].powi(2) + p2[1].powi(2)).sqrt();
    }
    (ab_x * ap_y - ab_y * ap_x).abs() / length
}

/// Hand a planned move's pieces to the sink: the toolhead's, and the extruder's when it extrudes.
fn emit<S: MoveSink>(sink: &mut S, print_time: f64, mv: &Move) -> Result<(), SinkError> {
    let plan = mv.plan;
    sink.origin(mv.origin);
    if mv.is_kinematic {
        sink.append(
            Queue::Toolhead,
            &TrapezoidMove {
                print_time,
                accel_t: plan.accel_t,
                cruise_t: plan.cruise_t,
                decel_t: plan.decel_t,
                start_pos: [mv.start_pos[0], mv.start_pos[1], mv.start_pos[2]],
                axes_r: mv.direction(),
                start_v: plan.start_v,
                cruise_v: plan.cruise_v,
                accel: mv.accel,
                motion: Motion::Travel,
            },
        )?;
    }
    if mv.axes_d[3] != 0.0 {
        let e_ratio = mv.axes_r[3];
        // The y component flags moves where pressure advance could apply (extruding while moving in XY).
        let pressure_advance_flag = e_ratio > 0.0 && (mv.axes_d[0] != 0.0 || mv.axes_d[1] != 0.0);
        sink.append(
            Queue::Extruder,
            &TrapezoidMove {
                print_time,
                accel_t: plan.accel_t,
                cruise_t: plan.cruise_t,
                decel_t: plan.decel_t,
                start_pos: [mv.start_pos[3], 0.0, 0.0],
                axes_r: [1.0, if pressure_advance_flag { 1.0 } else { 0.0 }, 0.0],
                start_v: plan.start_v * e_ratio,
                cruise_v: plan.cruise_v * e_ratio,
                accel: mv.accel * e_ratio,
                motion: Motion::Travel,
            },
        )?;
    }
    Ok(())
}

fn xyz(p: [f64; 4]) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

/// The extruder's limits on a move with E motion: extrude-only moves and retractions are limited to the
/// extrude-only speed; extruding moves may not exceed the maximum cross-section (tiny amounts excepted).
fn check_extrusion(extruder: Option<&ExtruderLimits>, mv: &mut Move) -> Result<(), MoveError> {
    let extruder = extruder.ok_or(MoveError::NoExtruder)?;
    let e_ratio = mv.axes_r[3];
    let e_distance = mv.axes_d[3];
    let moves_xy = mv.axes_d[0] != 0.0 || mv.axes_d[1] != 0.0;
    if !moves_xy || e_ratio < 0.0 {
        if e_distance.abs() > extruder.max_e_distance {
            return Err(MoveError::ExtrudeOnlyTooLong {
                distance: e_distance,
                max: extruder.max_e_distance,
            });
        }
        let inv_ratio = 1.0 / e_ratio.abs();
        mv.limit_speed(
            extruder.max_e_velocity * inv_ratio,
            extruder.max_e_accel * inv_ratio,
        );
    } else if e_ratio > extruder.max_extrude_ratio
        && e_distance > extruder.nozzle_diameter * extruder.max_extrude_ratio
    {
        return Err(MoveError::OverExtrusion {
            area: e_ratio * extruder.filament_area,
            max_area: extruder.max_extrude_ratio * extruder.filament_area,
        });
    }
    Ok(())
}

/// The extruder's cap on the junction speed²: its velocity may jump by at most the instantaneous corner
/// velocity.
fn extruder_junction_v2(extruder: Option<&ExtruderLimits>, prev: &Move, mv: &Move) -> f64 {
    let diff_r = mv.axes_r[3] - prev.axes_r[3];
    match extruder {
        Some(e) if diff_r != 0.0 => {
            let v = e.instantaneous_corner_velocity / diff_r.abs();
            v * v
        }
        _ => mv.max_cruise_v2,
    }
}
