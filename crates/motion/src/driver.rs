//! From interpreted G-code commands to toolhead actions, with Klipper's handling of each command.

use crate::arcs::{MAX_ARC_CHORDS, chord_count, probe_points, split_arc};
use crate::limits::VelocityLimits;
use crate::toolhead::{MoveError, SlowMoves, Toolhead};
use gcode::{AccelParams, Command, Span, Spanned, VelocityLimit};
use trapq::{MoveSink, SinkError};

/// A command the planner could not carry out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {}:{}: {kind}", span.line, span.column)]
pub struct PlanError {
    pub span: Span,
    pub kind: PlanErrorKind,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanErrorKind {
    #[error(transparent)]
    Move(#[from] MoveError),
    #[error("{0} must be above 0")]
    NotPositive(&'static str),
    #[error("MINIMUM_CRUISE_RATIO must be in [0, 1)")]
    CruiseRatio,
    #[error("G28: this machine has no homing position configured")]
    NoHoming,
    #[error("arc too long: it would be split into {chords:.0} chords")]
    ArcTooLong { chords: f64 },
    #[error(
        "the print would last {} by here, beyond the {MAX_PRINT_SECONDS:.0e} s any print may take (a feed rate or \
         a dwell far from what was meant?)",
        lasting(*seconds)
    )]
    TooLong { seconds: f64 },
}

/// How long a print would last, for a refusal.
fn lasting(seconds: f64) -> String {
    if seconds.is_finite() {
        format!("at least {seconds:.3e} s")
    } else {
        "for ever".to_string()
    }
}

/// The longest a print may last (s, about 31 years). Beyond it the MCU's 64-bit clock would come within reach of
/// overflowing at the clock rates of real boards, and no print takes that long: a move or dwell that would take
/// the print there (a subnormal feed rate, `G4 P1e300`) is refused at its line.
pub const MAX_PRINT_SECONDS: f64 = 1e9;

impl PlanError {
    /// The move's segment could not be reached (as opposed to a bad command).
    pub fn is_unreachable(&self) -> bool {
        matches!(
            self.kind,
            PlanErrorKind::Move(MoveError::Unreachable { .. })
        )
    }
}

/// Something the planner ignored that the user may want to know about.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    pub span: Span,
    pub message: String,
}

/// The end point of a move or arc.
fn target_of(cmd: &Spanned<Command>) -> Option<[f64; 4]> {
    match &cmd.value {
        Command::Move(mv) => Some(mv.target),
        Command::Arc(arc) => Some(arc.target),
        _ => None,
    }
}

fn xyz_of(p: [f64; 4]) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

/// Drives a [`Toolhead`] from G-code commands.
#[derive(Debug)]
pub struct Planner<'k, S: MoveSink> {
    toolhead: Toolhead<'k, S>,
    arc_resolution: f64,
    /// Where G28 leaves the toolhead (machine coordinates), if the machine can home.
    home_position: Option<[f64; 3]>,
    warnings: Vec<Warning>,
    /// The least time the commands so far take (s): each move at its requested speed, each dwell.
    least_time: f64,
}

impl<'k, S: MoveSink> Planner<'k, S> {
    pub fn new(
        toolhead: Toolhead<'k, S>,
        arc_resolution: f64,
        home_position: Option<[f64; 3]>,
    ) -> Self {
        Planner {
            toolhead,
            arc_resolution,
            home_position,
            warnings: Vec::new(),
            least_time: 0.0,
        }
    }

    pub fn toolhead(&self) -> &Toolhead<'k, S> {
        &self.toolhead
    }

    pub fn warnings(&self) -> &[Warning] {
        &self.warnings
    }

    /// Record a warning.
    pub fn warn(&mut self, span: Span, message: String) {
        self.warnings.push(Warning { span, message });
    }

    /// Klipper's batch mode read another block of input (see [`Toolhead::input_block_boundary`]).
    pub fn input_block_boundary(&mut self) {
        self.toolhead.input_block_boundary();
    }

    /// Start from a known pose (the machine was homed before the file begins).
    pub fn start_at(&mut self, xyz: [f64; 3]) {
        self.toolhead.set_position(xyz);
    }

    /// After `cmd` was refused, go on from where the file meant the machine to be, so that the next commands
    /// are judged on their own (for checking, not for printing: nothing moves there). A move's or arc's
    /// target is taken as the new position when the machine can be there (declared, as
    /// `SET_KINEMATIC_POSITION` does); otherwise X, Y and Z stay where the machine is. The extruder takes the
    /// target's E either way, so that the next move's extrusion is its own. Returns the machine position.
    pub fn resync_after_refusal(&mut self, cmd: &Spanned<Command>) -> [f64; 4] {
        let Some(target) = target_of(cmd) else {
            return self.toolhead.position();
        };
        let xyz = [target[0], target[1], target[2]];
        if self.toolhead.check_point(xyz).is_ok() && xyz != xyz_of(self.toolhead.position()) {
            if target[3].is_finite() {
                self.toolhead.set_extruder_position(target[3]);
            }
            self.toolhead.set_position(xyz);
            return self.toolhead.position();
        }
        self.skip(cmd)
    }

    /// After a move or arc was skipped (`--skip-unreachable`): the machine stays where it is, and the extruder
    /// is declared at the target's E without pushing filament (as a `G92 E` would), so that the next move
    /// extrudes its own amount, not the skipped move's as well. Returns the machine position.
    pub fn skip(&mut self, cmd: &Spanned<Command>) -> [f64; 4] {
        let position = self.toolhead.position();
        if let Some(target) = target_of(cmd)
            && target[3].is_finite()
            && target[3] != position[3]
        {
            self.toolhead.set_extruder_position(target[3]);
            // Declared to the step generators too: the extruder's steps continue from here, no jump.
            self.toolhead.set_position(xyz_of(position));
        }
        self.toolhead.position()
    }

    /// Finish planning: the sink, the final print time, the warnings and the moves slowed hard; or the sink's
    /// error when it failed.
    pub fn finish(self) -> Result<(S, f64, Vec<Warning>, SlowMoves), SinkError> {
        let (sink, end, slow) = self.toolhead.finish()?;
        Ok((sink, end, self.warnings, slow))
    }

    /// The print time Klipper's batch mode logs when its input ends ([`Toolhead::klipper_exit_time`]).
    pub fn klipper_exit_time(&mut self) -> f64 {
        self.toolhead.klipper_exit_time()
    }

    /// The sink's error, once it has failed: planning should stop.
    pub fn take_sink_error(&mut self) -> Option<SinkError> {
        self.toolhead.take_sink_error()
    }

    /// Carry out one command. Returns the machine position when it differs from what the G-code interpreter
    /// computed (G28, `SET_KINEMATIC_POSITION`, the end of a split arc), so the interpreter can follow.
    pub fn command(&mut self, cmd: &Spanned<Command>) -> Result<Option<[f64; 4]>, PlanError> {
        let span = cmd.span;
        let err = |kind: PlanErrorKind| PlanError { span, kind };
        let least_time = self.least_time + self.least_duration(&cmd.value);
        if least_time.is_nan() || least_time > MAX_PRINT_SECONDS {
            // A target out of reach says so first: that is the likelier mistake.
            if let Some(target) = target_of(cmd) {
                self.toolhead
                    .check_point(xyz_of(target))
                    .map_err(|e| err(e.into()))?;
            }
            return Err(err(PlanErrorKind::TooLong {
                seconds: least_time,
            }));
        }
        self.least_time = least_time;
        match &cmd.value {
            Command::Move(mv) => {
                self.toolhead
                    .move_to(mv.target, mv.feed, span.line)
                    .map_err(|e| err(e.into()))?;
            }
            Command::Arc(arc) => {
                // Reach first (a huge arc is refused for where it goes), then size.
                for p in probe_points(arc, 64) {
                    self.toolhead.check_point(p).map_err(|e| err(e.into()))?;
                }
                let chords = chord_count(arc, self.arc_resolution);
                if chords > MAX_ARC_CHORDS {
                    return Err(err(PlanErrorKind::ArcTooLong { chords }));
                }
                for point in split_arc(arc, self.arc_resolution) {
                    self.toolhead
                        .move_to(point, arc.feed, span.line)
                        .map_err(|e| err(e.into()))?;
                }
                return Ok(Some(self.toolhead.position()));
            }
            Command::Dwell { seconds } => self.toolhead.dwell(*seconds),
            Command::WaitForMoves => self.toolhead.wait_moves(),
            Command::Home { axes } => {
                self.home(*axes).map_err(err)?;
                return Ok(Some(self.toolhead.position()));
            }
            Command::SetKinematicPosition { position } => {
                let current = self.toolhead.position();
                let xyz = [0, 1, 2].map(|i| position[i].unwrap_or(current[i]));
                self.toolhead.check_point(xyz).map_err(|e| err(e.into()))?;
                self.toolhead.set_position(xyz);
                return Ok(Some(self.toolhead.position()));
            }
            Command::SetAccel(params) => self.set_accel(span, params).map_err(err)?,
            Command::SetVelocityLimit(v) => self.set_velocity_limit(v).map_err(err)?,
            Command::Other { name } if name == "M84" || name == "M18" => self.toolhead.motors_off(),
            Command::SetPosition { .. }
            | Command::SpeedFactor(_)
            | Command::ExtrudeFactor(_)
            | Command::Other { .. }
            | Command::Meta(_) => {}
        }
        Ok(None)
    }

    /// The least time `command` takes (s): a move's or arc's straight distance at its requested speed, a dwell's
    /// wait; nothing for the rest.
    fn least_duration(&self, command: &Command) -> f64 {
        let from = self.toolhead.position();
        let at_speed = |target: [f64; 4], feed: f64| {
            let xyz = (0..3)
                .map(|i| (target[i] - from[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            let distance = if xyz > 0.0 {
                xyz
            } else {
                (target[3] - from[3]).abs()
            };
            if distance > 0.0 { distance / feed } else { 0.0 }
        };
        match command {
            Command::Move(mv) => at_speed(mv.target, mv.feed),
            Command::Arc(arc) => at_speed(arc.target, arc.feed),
            Command::Dwell { seconds } => *seconds,
            _ => 0.0,
        }
    }

    /// G28: the machine runs to its endstops; the pose there is known from the configuration.
    /// Axes not named keep their position; a polar or SCARA machine homes X and Y together.
    fn home(&mut self, axes: [bool; 3]) -> Result<[f64; 3], PlanErrorKind> {
        let home = self.home_position.ok_or(PlanErrorKind::NoHoming)?;
        let all = axes == [false; 3];
        let current = self.toolhead.position();
        let xy = all || axes[0] || axes[1];
        let pick = |i: usize, homed: bool| if homed { home[i] } else { current[i] };
        let xyz = [pick(0, xy), pick(1, xy), pick(2, all || axes[2])];
        self.toolhead.set_position(xyz);
        Ok(xyz)
    }

    /// M204 as Klipper reads it: `S`, or else the smaller of `P` and `T` (both needed).
    fn set_accel(&mut self, span: Span, params: &AccelParams) -> Result<(), PlanErrorKind> {
        let accel = match (params.s, params.p, params.t) {
            (Some(s), _, _) => s,
            (None, Some(p), Some(t)) => {
                positive(p, "P")?;
                positive(t, "T")?;
                p.min(t)
            }
            _ => {
                self.warnings.push(Warning {
                    span,
                    message: "M204 needs S, or both P and T; ignored".into(),
                });
                return Ok(());
            }
        };
        positive(accel, "M204 acceleration")?;
        let mut limits = self.toolhead.limits();
        limits.max_accel = accel;
        self.toolhead.set_limits(limits);
        Ok(())
    }

    fn set_velocity_limit(&mut self, v: &VelocityLimit) -> Result<(), PlanErrorKind> {
        let mut limits: VelocityLimits = self.toolhead.limits();
        if let Some(velocity) = v.velocity {
            limits.max_velocity = positive(velocity, "VELOCITY")?;
        }
        if let Some(accel) = v.accel {
            limits.max_accel = positive(accel, "ACCEL")?;
        }
        if let Some(scv) = v.square_corner_velocity {
            if scv.is_nan() || scv < 0.0 || !scv.is_finite() {
                return Err(PlanErrorKind::NotPositive("SQUARE_CORNER_VELOCITY"));
            }
            limits.square_corner_velocity = scv;
        }
        let ratio = match (v.minimum_cruise_ratio, v.accel_to_decel) {
            (Some(ratio), _) => Some(ratio),
            // The old ACCEL_TO_DECEL parameter, converted as Klipper converts max_accel_to_decel.
            (None, Some(atd)) => {
                Some(1.0 - (positive(atd, "ACCEL_TO_DECEL")? / limits.max_accel).min(1.0))
            }
            (None, None) => None,
        };
        if let Some(ratio) = ratio {
            if !(0.0..1.0).contains(&ratio) {
                return Err(PlanErrorKind::CruiseRatio);
            }
            limits.minimum_cruise_ratio = ratio;
        }
        self.toolhead.set_limits(limits);
        Ok(())
    }
}

fn positive(value: f64, what: &'static str) -> Result<f64, PlanErrorKind> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(PlanErrorKind::NotPositive(what))
    }
}
