//! A machine ready to plan for: kinematics, planner limits and the homing pose, built from `printer.cfg`,
//! and the loop that plans a whole G-code stream.

use crate::driver::{PlanError, Planner, Warning};
use crate::kinematic_limits::MotorLimit;
use crate::limits::{CentreTurn, ExtruderLimits, PlannerConfig, VelocityLimits};
use crate::toolhead::{SlowMoves, Toolhead};
use config::{KinematicsKind, MachineConfig};
use gcode::{Commands, GcodeError};
use kinematics::{Kinematics, MotorUnit};
use std::io::BufRead;
use trapq::MoveSink;

/// Why a machine could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error("invalid machine: {0}")]
    Kinematics(String),
    #[error("the endstop positions give no homing pose: {reason}")]
    NoHomePose { reason: String },
    #[error("homing pose ({x:.3}, {y:.3}) from the endstop positions is unreachable: {reason}")]
    Home { x: f64, y: f64, reason: String },
}

/// Why planning stopped.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    #[error(transparent)]
    Plan(#[from] PlanError),
}

/// What planning a stream produced besides the moves.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSummary {
    /// Print time at which the last move ends (s).
    pub end_time: f64,
    pub warnings: Vec<Warning>,
    pub gcode_warnings: Vec<gcode::Warning>,
    /// Moves a machine limit slowed below a quarter of their requested speed.
    pub slow_moves: SlowMoves,
}

/// Kinematics + planner configuration + homing pose of one machine.
#[derive(Debug)]
pub struct MachineSetup {
    pub kinematics: Box<dyn Kinematics>,
    pub planner: PlannerConfig,
    /// Where G28 leaves the toolhead, derived from the endstop positions through the kinematics.
    pub home_position: Option<[f64; 3]>,
}

impl MachineSetup {
    pub fn from_config(machine: &MachineConfig) -> Result<MachineSetup, SetupError> {
        let kinematics = kinematics::build(&machine.params)
            .map_err(|e| SetupError::Kinematics(e.to_string()))?;
        let limits = &machine.limits;
        let mut planner = PlannerConfig::klipper(VelocityLimits {
            max_velocity: limits.max_velocity,
            max_accel: limits.max_accel,
            square_corner_velocity: limits.square_corner_velocity,
            minimum_cruise_ratio: limits.minimum_cruise_ratio,
        });
        planner.max_z_velocity = limits.max_z_velocity;
        planner.max_z_accel = limits.max_z_accel;
        planner.extruder = machine.extruder.as_ref().map(|e| ExtruderLimits {
            max_extrude_ratio: e.max_extrude_ratio,
            filament_area: e.filament_area,
            nozzle_diameter: e.nozzle_diameter,
            max_e_velocity: e.max_extrude_only_velocity,
            max_e_accel: e.max_extrude_only_accel,
            max_e_distance: e.max_extrude_only_distance,
            instantaneous_corner_velocity: e.instantaneous_corner_velocity,
        });
        if let Some(arcs) = machine.arcs {
            planner.arc_resolution = arcs.resolution;
        }
        planner.kinematic_limits = motor_limits(machine, kinematics.as_ref());
        planner.centre_turn = centre_turn(machine, kinematics.as_ref(), &planner.kinematic_limits);
        let home_position = home_position(machine, kinematics.as_ref())?;
        Ok(MachineSetup {
            kinematics,
            planner,
            home_position,
        })
    }
}

/// Motor limits from the config: polar bed (`max_angular_velocity`, `max_angular_accel`), SCARA joints
/// (`max_joint_velocity`, `max_joint_accel` on both arm motors), and every stepper's `max_step_rate` (per stepper,
/// or the `[printer]` default) as a speed limit of step rate × step distance.
fn motor_limits(machine: &MachineConfig, kin: &dyn Kinematics) -> Vec<MotorLimit> {
    let l = &machine.limits;
    let mut limits = Vec::new();
    for (index, motor) in kin.motors().iter().enumerate() {
        // The machine says which motors turn: a polar machine's bed, a SCARA's joints.
        let (mut velocity, accel) = match (machine.kinematics, motor.unit) {
            (KinematicsKind::Polar, MotorUnit::Rad) => {
                (l.max_angular_velocity, l.max_angular_accel)
            }
            (KinematicsKind::Scara, MotorUnit::Rad) => (l.max_joint_velocity, l.max_joint_accel),
            _ => (None, None),
        };
        let step_rate = machine
            .stepper(&motor.name)
            .and_then(|s| s.max_step_rate)
            .or(l.max_step_rate);
        if let Some(rate) = step_rate {
            let v = rate * motor.step_distance;
            velocity = Some(velocity.map_or(v, |limit| limit.min(v)));
        }
        if velocity.is_some() || accel.is_some() {
            limits.push(MotorLimit {
                motor: index,
                max_velocity: velocity,
                max_accel: accel,
            });
        }
    }
    limits
}

/// A polar bed's turn in place at the centre: within the bed's motor limits (its angular limits and step rate,
/// as the planner applies them elsewhere), and without an angular limit at the speed and acceleration that move the
/// bed's rim (the arm's reach) at `max_velocity` and `max_accel`.
fn centre_turn(
    machine: &MachineConfig,
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
) -> Option<CentreTurn> {
    let centre = kin.rotation_centre()?;
    let radius = machine
        .stepper("stepper_arm")
        .and_then(|s| s.position_max)
        .filter(|r| *r > 0.0)?;
    let l = &machine.limits;
    let bed = limits.iter().find(|m| m.motor == centre.bed);
    Some(CentreTurn {
        centre: centre.point,
        tolerance: centre.tolerance,
        max_velocity: bed
            .and_then(|b| b.max_velocity)
            .unwrap_or(l.max_velocity / radius),
        max_accel: bed
            .and_then(|b| b.max_accel)
            .unwrap_or(l.max_accel / radius),
    })
}

/// The toolhead pose after every axis has run to its endstop. Polar: the arm at its endstop, the bed angle
/// declared 0 (as Klipper does). SCARA: the declared `home_position` when the config has one (FEKT-SCARA), else
/// each joint at its endstop angle (degrees in the file), the elbow motor's reading converted through the
/// coupling by the forward kinematics. Cartesian: every axis at its endstop.
fn home_position(
    machine: &MachineConfig,
    kin: &dyn Kinematics,
) -> Result<Option<[f64; 3]>, SetupError> {
    let endstop = |name: &str| {
        machine
            .stepper(name)
            .and_then(|s| s.homing.as_ref())
            .and_then(|h| h.position_endstop)
    };
    let pose = match machine.kinematics {
        KinematicsKind::Cartesian => match (
            endstop("stepper_x"),
            endstop("stepper_y"),
            endstop("stepper_z"),
        ) {
            (Some(x), Some(y), Some(z)) => Some([x, y, z]),
            _ => None,
        },
        KinematicsKind::Polar => match (endstop("stepper_arm"), endstop("stepper_z")) {
            (Some(arm), Some(z)) => Some(kin_forward(kin, &[0.0, arm, z])?),
            _ => None,
        },
        KinematicsKind::Scara => match (
            declared_home(machine, endstop("stepper_z")),
            endstop("stepper_a"),
            endstop("stepper_b"),
            endstop("stepper_z"),
        ) {
            (Some(pose), ..) => Some(declared_pose(kin, pose)?),
            (None, Some(a), Some(b), Some(z)) => {
                Some(kin_forward(kin, &[a.to_radians(), b.to_radians(), z])?)
            }
            _ => None,
        },
    };
    Ok(pose)
}

/// FEKT-SCARA's `home_position`: homing declares the arm there without moving it (its joint endstops, if any,
/// are not used), and Z homes to its endstop when it has one.
fn declared_home(machine: &MachineConfig, z_endstop: Option<f64>) -> Option<[f64; 3]> {
    let declared = machine.home_position.as_deref()?;
    let (x, y) = (*declared.first()?, *declared.get(1)?);
    let z = z_endstop.or(declared.get(2).copied()).unwrap_or(0.0);
    Some([x, y, z])
}

/// A declared pose must be one the arm can take.
fn declared_pose(kin: &dyn Kinematics, pose: [f64; 3]) -> Result<[f64; 3], SetupError> {
    let mut motors = vec![0.0; kin.motors().len()];
    kin.inverse(pose, &mut motors)
        .map_err(|e| SetupError::Home {
            x: pose[0],
            y: pose[1],
            reason: e.to_string(),
        })?;
    Ok(pose)
}

fn kin_forward(kin: &dyn Kinematics, motors: &[f64]) -> Result<[f64; 3], SetupError> {
    let p = kin.forward(motors).map_err(|e| SetupError::NoHomePose {
        reason: e.to_string(),
    })?;
    let mut check = vec![0.0; kin.motors().len()];
    kin.inverse(p, &mut check).map_err(|e| SetupError::Home {
        x: p[0],
        y: p[1],
        reason: e.to_string(),
    })?;
    Ok(p)
}

/// One problem found by [`check_gcode`].
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub span: gcode::Span,
    pub severity: Severity,
    pub message: String,
    /// The offending line's text, when the reader kept it (G-code syntax errors).
    pub line_text: Option<(String, usize)>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    Warning,
    Error,
}

/// Everything [`check_gcode`] found, and the print time of what could be planned.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// The first `max_problems` problems found, in file order.
    pub problems: Vec<Problem>,
    pub end_time: f64,
    pub slow_moves: u64,
    /// Every error and warning found, kept or not.
    pub error_count: usize,
    pub warning_count: usize,
}

impl CheckReport {
    /// Errors found (all of them, also beyond `max_problems`).
    pub fn errors(&self) -> usize {
        self.error_count
    }
}

/// Plan a stream without generating steps and collect every problem instead of stopping at the first:
/// syntax errors, unreachable segments, commands the planner refused (after each refusal the check goes on
/// from the refused move's target when the machine can be there, else from where it is, with the target's E:
/// [`Planner::resync_after_refusal`]),
/// ignored commands, and moves that a machine limit slows below a quarter of their requested speed.
/// At most `max_problems` are kept (all are counted in the error total).
pub fn check_gcode(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    max_problems: usize,
) -> CheckReport {
    let toolhead = Toolhead::new(setup.planner.clone(), setup.kinematics.as_ref(), ());
    let mut planner = Planner::new(toolhead, setup.planner.arc_resolution, setup.home_position);
    let mut commands = Commands::from_reader(input, source_name);
    if let Some(home) = setup.home_position {
        planner.start_at(home);
        let mut position = commands.interpreter().last_position();
        position[..3].copy_from_slice(&home);
        commands.interpreter_mut().set_position(position);
    }
    let mut problems = Vec::new();
    let (mut error_count, mut warning_count) = (0, 0);
    let mut push = |problem: Problem| {
        match problem.severity {
            Severity::Error => error_count += 1,
            Severity::Warning => warning_count += 1,
        }
        if problems.len() < max_problems {
            problems.push(problem);
        }
    };
    while let Some(command) = commands.next_command() {
        match command {
            Err(e) => push(Problem {
                span: e.span,
                severity: Severity::Error,
                message: e.kind.to_string(),
                line_text: Some((e.line_text.clone(), e.line_text_offset)),
            }),
            Ok(command) => match planner.command(&command) {
                Ok(Some(position)) => commands.interpreter_mut().set_position(position),
                Ok(None) => {}
                Err(e) => {
                    push(Problem {
                        span: e.span,
                        severity: Severity::Error,
                        message: e.kind.to_string(),
                        line_text: None,
                    });
                    // Go on from where the file meant to be, so no follow-on errors are invented.
                    let position = planner.resync_after_refusal(&command);
                    commands.interpreter_mut().set_position(position);
                }
            },
        }
    }
    for w in commands.take_warnings() {
        push(Problem {
            span: w.span,
            severity: Severity::Warning,
            message: w.message.clone(),
            line_text: None,
        });
    }
    let (_, end_time, warnings, slow) = planner.finish();
    for w in warnings {
        push(Problem {
            span: w.span,
            severity: Severity::Warning,
            message: w.message,
            line_text: None,
        });
    }
    for s in &slow.first {
        push(Problem {
            span: gcode::Span {
                line: s.origin,
                column: 1,
                len: 0,
            },
            severity: Severity::Warning,
            message: format!(
                "move slowed to {:.1} mm/s by a machine limit (requested {:.1} mm/s)",
                s.allowed, s.requested
            ),
            line_text: None,
        });
    }
    problems.sort_by_key(|p| (p.span.line, p.span.column));
    CheckReport {
        problems,
        end_time,
        slow_moves: slow.total,
        error_count,
        warning_count,
    }
}

/// Bytes Klipper's batch mode reads from its input at a time.
const KLIPPER_INPUT_BLOCK: u64 = 4096;

/// Plan a whole G-code stream on `setup`, handing planned moves to `sink`. Memory stays bounded: the
/// stream is read line by line and the lookahead holds at most a few seconds of moves.
pub fn plan_gcode<S: MoveSink>(
    setup: &MachineSetup,
    input: impl BufRead,
    source_name: &str,
    sink: S,
) -> Result<(S, PlanSummary), PipelineError> {
    let toolhead = Toolhead::new(setup.planner.clone(), setup.kinematics.as_ref(), sink);
    let mut planner = Planner::new(toolhead, setup.planner.arc_resolution, setup.home_position);
    let mut commands = Commands::from_reader(input, source_name);
    // A file is printed on a homed machine: start at the homing pose.
    if let Some(home) = setup.home_position {
        planner.start_at(home);
        let mut position = commands.interpreter().last_position();
        position[..3].copy_from_slice(&home);
        commands.interpreter_mut().set_position(position);
    }
    let mut block = 0u64;
    while let Some(command) = commands.next_command() {
        let command = command?;
        // Klipper's batch mode reads its input in 4096-byte blocks and runs its timers between blocks.
        let line_end_block =
            commands.reader().bytes_consumed().saturating_sub(1) / KLIPPER_INPUT_BLOCK;
        while block < line_end_block {
            planner.input_block_boundary();
            block += 1;
        }
        match planner.command(&command) {
            Ok(Some(position)) => commands.interpreter_mut().set_position(position),
            Ok(None) => {}
            Err(e) if setup.planner.skip_unreachable && e.is_unreachable() => {
                planner.warn(e.span, e.kind.to_string());
                // The machine stays where it was (later relative moves continue from there); the skipped
                // move's filament is not pushed by the next one.
                let position = planner.skip(&command);
                commands.interpreter_mut().set_position(position);
            }
            Err(e) => return Err(e.into()),
        }
    }
    let gcode_warnings = commands.take_warnings();
    let (sink, end_time, warnings, slow_moves) = planner.finish();
    Ok((
        sink,
        PlanSummary {
            end_time,
            warnings,
            gcode_warnings,
            slow_moves,
        },
    ))
}
