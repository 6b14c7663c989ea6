//! Planned motion as constant-acceleration pieces: the hand-off between the planner and step generation.
//!
//! This mirrors Klipper's trapezoid queue (`trapq`): a planned move becomes up to three pieces (accelerate,
//! cruise, decelerate); each piece moves along a fixed unit direction with constant acceleration.
//! The planner (`motion`) produces pieces; step generation (`stepgen`) and the simulator consume them.
//! [`csv`] writes and reads planned moves as Klipper-comparable files (the moves CSV).

pub mod csv;

/// A Cartesian toolhead position or direction, `[x, y, z]` in mm.
pub type Vec3 = [f64; 3];

/// What a toolhead piece does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Motion {
    /// The toolhead travels along `axes_r` (Klipper's trapezoid moves are all of this kind).
    #[default]
    Travel,
    /// A polar bed turns in place while the toolhead rests on its rotation centre at `start_pos`: `axes_r` is
    /// zero and the piece's signed distance is the angle turned (rad, counter-clockwise positive: the bed motor's
    /// reading grows). The planner emits it where a path meets the centre, where the bed angle is undefined.
    BedTurn,
}

/// One constant-acceleration piece of a straight move.
///
/// Distance along the direction after `t` seconds (0 ≤ t ≤ `duration`): `(start_v + half_accel·t)·t`;
/// position: `start_pos + axes_r·distance`. A [`Motion::BedTurn`] piece does not move the toolhead; its distance
/// is the bed's turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    /// Absolute print time (s) at which the piece starts.
    pub print_time: f64,
    /// Duration (s), ≥ 0.
    pub duration: f64,
    /// Speed (mm/s) along `axes_r` at the start of the piece.
    pub start_v: f64,
    /// Half the acceleration (mm/s²) along `axes_r`; negative while decelerating.
    pub half_accel: f64,
    /// Position (mm) at the start of the piece.
    pub start_pos: Vec3,
    /// Unit direction of the move (or, for the extruder queue, `[1, 0, 0]`); zero for a bed turn.
    pub axes_r: Vec3,
    pub motion: Motion,
}

impl Piece {
    /// Distance travelled along `axes_r` after `t` seconds into the piece.
    #[inline]
    pub fn distance(&self, t: f64) -> f64 {
        (self.start_v + self.half_accel * t) * t
    }

    /// Position after `t` seconds into the piece.
    #[inline]
    pub fn position(&self, t: f64) -> Vec3 {
        let d = self.distance(t);
        [
            self.start_pos[0] + self.axes_r[0] * d,
            self.start_pos[1] + self.axes_r[1] * d,
            self.start_pos[2] + self.axes_r[2] * d,
        ]
    }

    /// Speed along `axes_r` after `t` seconds into the piece.
    #[inline]
    pub fn velocity(&self, t: f64) -> f64 {
        self.start_v + 2.0 * self.half_accel * t
    }

    /// Absolute print time at which the piece ends.
    #[inline]
    pub fn end_time(&self) -> f64 {
        self.print_time + self.duration
    }
}

/// One planned move as Klipper's `trapq_append` receives it: three phase durations and the speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrapezoidMove {
    pub print_time: f64,
    pub accel_t: f64,
    pub cruise_t: f64,
    pub decel_t: f64,
    pub start_pos: Vec3,
    pub axes_r: Vec3,
    pub start_v: f64,
    pub cruise_v: f64,
    pub accel: f64,
    pub motion: Motion,
}

impl TrapezoidMove {
    /// A polar bed turning in place by `angle` (rad, counter-clockwise positive) while the toolhead rests at
    /// `centre`, from rest to rest within `max_velocity` and `max_accel` (rad/s, rad/s²): accelerate, cruise
    /// if the angle leaves room, decelerate.
    pub fn bed_turn(
        print_time: f64,
        centre: Vec3,
        angle: f64,
        max_velocity: f64,
        max_accel: f64,
    ) -> TrapezoidMove {
        let size = angle.abs();
        let ramps = max_velocity * max_velocity / max_accel;
        let (accel_t, cruise_t, peak) = if size >= ramps {
            (
                max_velocity / max_accel,
                (size - ramps) / max_velocity,
                max_velocity,
            )
        } else {
            let peak = (size * max_accel).sqrt();
            (peak / max_accel, 0.0, peak)
        };
        let sign = if angle < 0.0 { -1.0 } else { 1.0 };
        TrapezoidMove {
            print_time,
            accel_t,
            cruise_t,
            decel_t: accel_t,
            start_pos: centre,
            axes_r: [0.0; 3],
            start_v: 0.0,
            cruise_v: sign * peak,
            accel: sign * max_accel,
            motion: Motion::BedTurn,
        }
    }

    /// Split into up to three pieces, skipping zero-length phases, the way Klipper's `trapq_append` does:
    /// each later piece starts at the position reached at the end of the previous one.
    pub fn pieces(&self) -> impl Iterator<Item = Piece> + use<> {
        let mut phases = [None; 3];
        let mut count = 0;
        self.each_piece(|piece| {
            phases[count] = Some(piece);
            count += 1;
        });
        phases.into_iter().flatten()
    }

    /// Append the pieces of [`Self::pieces`] to `out`, with one capacity check per move (extending from the
    /// iterator checks per piece; step generation takes every move this way).
    #[inline]
    pub fn push_pieces(&self, out: &mut Vec<Piece>) {
        out.reserve(3);
        self.each_piece(|piece| out.push(piece));
    }

    /// Each phase of non-zero duration as a piece, in order: each starts where and when the one before ended.
    #[inline(always)]
    fn each_piece(&self, mut emit: impl FnMut(Piece)) {
        let (mut print_time, mut start_pos) = (self.print_time, self.start_pos);
        // The three phases written out (a loop over them costs more than the copying it does).
        let mut phase = |duration: f64, start_v: f64, half_accel: f64| {
            if duration == 0.0 {
                return;
            }
            let piece = Piece {
                print_time,
                duration,
                start_v,
                half_accel,
                start_pos,
                axes_r: self.axes_r,
                motion: self.motion,
            };
            print_time += duration;
            start_pos = piece.position(duration);
            emit(piece);
        };
        phase(self.accel_t, self.start_v, 0.5 * self.accel);
        phase(self.cruise_t, self.cruise_v, 0.0);
        phase(self.decel_t, self.cruise_v, -0.5 * self.accel);
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.accel_t + self.cruise_t + self.decel_t
    }

    /// Signed distance covered along `axes_r` (a bed turn: the angle turned): the three phases in closed form.
    pub fn distance(&self) -> f64 {
        let accelerating = (self.start_v + 0.5 * self.accel * self.accel_t) * self.accel_t;
        let decelerating = (self.cruise_v - 0.5 * self.accel * self.decel_t) * self.decel_t;
        accelerating + self.cruise_v * self.cruise_t + decelerating
    }

    /// Where the move ends (a bed turn ends where it starts).
    pub fn end_pos(&self) -> Vec3 {
        let d = self.distance();
        let (p, u) = (self.start_pos, self.axes_r);
        [p[0] + u[0] * d, p[1] + u[1] * d, p[2] + u[2] * d]
    }
}

/// Which queue a move belongs to: the toolhead (XYZ) or the extruder (E as the X coordinate).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Queue {
    Toolhead,
    Extruder,
}

/// Why a sink could not take a move (a full disk, a consumer that has stopped): the run stops there, and the
/// planner hands the error on.
#[derive(Debug)]
pub struct SinkError(Box<dyn std::error::Error + Send + Sync>);

impl SinkError {
    pub fn new(error: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> SinkError {
        SinkError(error.into())
    }

    /// The error the sink met.
    pub fn into_inner(self) -> Box<dyn std::error::Error + Send + Sync> {
        self.0
    }
}

impl std::fmt::Display for SinkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for SinkError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

/// Receiver of planned moves, in print-time order per queue.
///
/// The planner does not know who consumes its output (step generation, a CSV writer, the simulator). A sink that
/// cannot go on says so with an error; the planner stops there (as ripgrep's `Sink` stops a search).
pub trait MoveSink {
    /// A planned move was appended to `queue`.
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError>;
    /// The moves appended next come from `origin` (a G-code line), until the next call. Sinks that report
    /// places keep it; the rest ignore it.
    #[inline]
    fn origin(&mut self, _origin: u64) {}
    /// Every move that starts before `print_time` has been appended: consumers may finish work up to it. An error
    /// stops the planner as an append's does.
    fn flush(&mut self, _print_time: f64) -> Result<(), SinkError> {
        Ok(())
    }
    /// The toolhead was declared to be at `xyz` without moving (homing, `SET_KINEMATIC_POSITION`), after every
    /// earlier move was appended; `e` is the extruder position. An error stops the planner as an append's does.
    fn set_position(&mut self, _xyz: Vec3, _e: f64) -> Result<(), SinkError> {
        Ok(())
    }
}

/// A closure that takes every move and never fails (tests, quick collectors).
impl<F: FnMut(Queue, &TrapezoidMove)> MoveSink for F {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        self(queue, mv);
        Ok(())
    }
}

/// A consumer that ignores everything (planning for its own sake: checks, timing).
impl MoveSink for () {
    fn append(&mut self, _queue: Queue, _mv: &TrapezoidMove) -> Result<(), SinkError> {
        Ok(())
    }
}

/// An optional consumer: `None` ignores everything.
impl<S: MoveSink> MoveSink for Option<S> {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        match self {
            Some(sink) => sink.append(queue, mv),
            None => Ok(()),
        }
    }
    fn origin(&mut self, origin: u64) {
        if let Some(sink) = self {
            sink.origin(origin);
        }
    }
    fn flush(&mut self, print_time: f64) -> Result<(), SinkError> {
        match self {
            Some(sink) => sink.flush(print_time),
            None => Ok(()),
        }
    }
    fn set_position(&mut self, xyz: Vec3, e: f64) -> Result<(), SinkError> {
        match self {
            Some(sink) => sink.set_position(xyz, e),
            None => Ok(()),
        }
    }
}

/// Two consumers fed the same moves, in order.
impl<A: MoveSink, B: MoveSink> MoveSink for (A, B) {
    fn append(&mut self, queue: Queue, mv: &TrapezoidMove) -> Result<(), SinkError> {
        self.0.append(queue, mv)?;
        self.1.append(queue, mv)
    }
    #[inline]
    fn origin(&mut self, origin: u64) {
        self.0.origin(origin);
        self.1.origin(origin);
    }
    fn flush(&mut self, print_time: f64) -> Result<(), SinkError> {
        self.0.flush(print_time)?;
        self.1.flush(print_time)
    }
    fn set_position(&mut self, xyz: Vec3, e: f64) -> Result<(), SinkError> {
        self.0.set_position(xyz, e)?;
        self.1.set_position(xyz, e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_skip_empty_phases_and_chain_positions() {
        let mv = TrapezoidMove {
            print_time: 1.0,
            accel_t: 0.5,
            cruise_t: 0.0,
            decel_t: 0.5,
            start_pos: [0.0, 0.0, 0.0],
            axes_r: [1.0, 0.0, 0.0],
            start_v: 0.0,
            cruise_v: 10.0,
            accel: 20.0,
            motion: Motion::Travel,
        };
        let pieces: Vec<Piece> = mv.pieces().collect();
        assert_eq!(pieces.len(), 2);
        // accelerating 0→10 mm/s over 0.5 s covers 2.5 mm
        assert_eq!(pieces[1].start_pos, [2.5, 0.0, 0.0]);
        assert_eq!(pieces[1].print_time, 1.5);
        assert_eq!(pieces[1].start_v, 10.0);
        assert_eq!(pieces[1].half_accel, -10.0);
        assert_eq!(pieces[1].position(0.5), [5.0, 0.0, 0.0]);
        assert_eq!(pieces[1].velocity(0.5), 0.0);
    }

    #[test]
    fn pushed_pieces_are_the_iterated_pieces() {
        let full = TrapezoidMove {
            print_time: 0.25,
            accel_t: 0.1,
            cruise_t: 0.3,
            decel_t: 0.2,
            start_pos: [1.0, -2.0, 0.5],
            axes_r: [0.6, 0.8, 0.0],
            start_v: 3.0,
            cruise_v: 13.0,
            accel: 100.0,
            motion: Motion::Travel,
        };
        let mut variants = vec![
            full,
            TrapezoidMove::bed_turn(1.0, [0.0; 3], -2.0, 5.0, 200.0),
        ];
        for phase in 0..4 {
            let mut mv = full;
            if phase == 0 || phase == 3 {
                mv.accel_t = 0.0;
            }
            if phase == 1 || phase == 3 {
                mv.cruise_t = 0.0;
            }
            if phase == 2 || phase == 3 {
                mv.decel_t = 0.0;
            }
            variants.push(mv);
        }
        let earlier = full.pieces().next().expect("a piece");
        for mv in variants {
            let mut pushed = vec![earlier];
            mv.push_pieces(&mut pushed);
            let iterated: Vec<Piece> = mv.pieces().collect();
            assert_eq!(pushed[0], earlier);
            assert_eq!(pushed[1..], iterated[..]);
        }
    }

    #[test]
    fn a_bed_turn_covers_its_signed_angle_from_rest_to_rest_within_its_limits() {
        for (angle, omega, alpha) in [(3.0, 5.0, 200.0), (-1.5, 5.0, 10.0), (0.01, 5.0, 200.0)] {
            let mv = TrapezoidMove::bed_turn(2.0, [0.0; 3], angle, omega, alpha);
            let pieces: Vec<Piece> = mv.pieces().collect();
            let turned: f64 = pieces.iter().map(|p| p.distance(p.duration)).sum();
            assert!((turned - angle).abs() < 1e-12, "{turned} vs {angle}");
            assert!((mv.distance() - turned).abs() < 1e-12);
            let last = pieces.last().expect("pieces");
            assert!(last.velocity(last.duration).abs() < 1e-12);
            assert!(pieces.iter().all(|p| p.motion == Motion::BedTurn));
            assert!(mv.cruise_v.abs() <= omega && mv.accel.abs() == alpha);
            assert_eq!(mv.start_pos, [0.0; 3]);
        }
        // Without room to cruise the turn is a triangle: 2·√(θ/α).
        let mv = TrapezoidMove::bed_turn(0.0, [0.0; 3], 0.01, 5.0, 200.0);
        assert!((mv.duration() - 2.0 * (0.01f64 / 200.0).sqrt()).abs() < 1e-12);
    }
}
