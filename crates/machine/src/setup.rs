//! A machine ready to plan for: kinematics, planner limits and the homing pose, built from `printer.cfg`.

use config::MachineConfig;
use kinematics::{Kinematics, MachineParams, MotorMap, MotorUnit, TurningLimits};
use motion::kinematic_limits::MotorLimit;
use motion::limits::{CentreTurn, ExtruderLimits, PlannerConfig, VelocityLimits};
use std::sync::Arc;

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

/// Kinematics + planner configuration + homing pose of one machine. Cloning shares the kinematics (a set-up
/// planned another way is a clone with other planner options, not a second build).
#[derive(Debug, Clone)]
pub struct MachineSetup {
    pub kinematics: Arc<dyn Kinematics>,
    pub planner: PlannerConfig,
    /// Where G28 leaves the toolhead, derived from the endstop positions through the kinematics.
    pub home_position: Option<[f64; 3]>,
    /// How Klipper reads G-code on this printer: the commands its configuration gives it.
    pub reading: gcode::InterpreterOptions,
}

impl MachineSetup {
    pub fn from_config(machine: &MachineConfig) -> Result<MachineSetup, SetupError> {
        let kinematics: Arc<dyn Kinematics> = kinematics::build(&read_as_firmware(&machine.params))
            .map_err(|e| SetupError::Kinematics(e.to_string()))?
            .into();
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
            reading: gcode::InterpreterOptions::klipper(klipper_commands(machine)),
        })
    }
}

/// The optional commands Klipper has with this configuration (`[gcode_arcs]`, `[force_move]`).
fn klipper_commands(machine: &MachineConfig) -> gcode::CommandSet {
    gcode::CommandSet {
        arcs: machine.arcs.is_some(),
        kinematic_position: machine.force_move,
        ..gcode::CommandSet::ALL
    }
}

/// The machine's parameters as firmware reads its motors: a SCARA's shoulder angle in (−π, π] (atan2, as Marlin,
/// the FEKT-SCARA module and the plug-in's step solvers take it). A move through ±π would turn the elbow motor by
/// `2π·coupling` at one point, so the configured shoulder range is cut there and such a move is refused as a joint
/// limit by every front-end alike.
fn read_as_firmware(params: &MachineParams) -> MachineParams {
    let mut params = params.clone();
    if let MachineParams::Scara(p) = &mut params {
        p.shoulder_limits = Some(kinematics::scara::within_branch_cut(p.shoulder_limits));
    }
    params
}

/// Motor limits from the config: polar bed (`max_angular_velocity`, `max_angular_accel`), SCARA joints
/// (`max_joint_velocity`, `max_joint_accel` on both arm motors), and every stepper's `max_step_rate` (per stepper,
/// or the `[printer]` default) as a speed limit of step rate × step distance.
fn motor_limits(machine: &MachineConfig, kin: &dyn Kinematics) -> Vec<MotorLimit> {
    let l = &machine.limits;
    let mut limits = Vec::new();
    for (index, motor) in kin.motors().iter().enumerate() {
        // The machine says which limits bind its turning motors: a polar bed's, a SCARA's joints'.
        let (mut velocity, accel) = match (kin.turning_limits(), motor.unit) {
            (Some(TurningLimits::Bed), MotorUnit::Rad) => {
                (l.max_angular_velocity, l.max_angular_accel)
            }
            (Some(TurningLimits::Joints), MotorUnit::Rad) => {
                (l.max_joint_velocity, l.max_joint_accel)
            }
            _ => (None, None),
        };
        if let Some(rate) = machine.max_step_rate(&motor.name) {
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
    let radius = centre.rim?;
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

/// The toolhead pose after homing: the declared `home_position` when the config has one (FEKT-SCARA), else the
/// kinematics' pose for the motors' endstop positions (angles in degrees in the file), checked to be reachable.
fn home_position(
    machine: &MachineConfig,
    kin: &dyn Kinematics,
) -> Result<Option<[f64; 3]>, SetupError> {
    let z_endstop = z_motor(kin).and_then(|z| endstop(machine, &kin.motors()[z].name));
    if let Some(pose) = declared_home(machine, z_endstop) {
        return declared_pose(kin, pose).map(Some);
    }
    let endstops: Vec<Option<f64>> = kin
        .motors()
        .iter()
        .map(|motor| {
            let position = endstop(machine, &motor.name);
            match motor.unit {
                MotorUnit::Rad => position.map(f64::to_radians),
                MotorUnit::Mm => position,
            }
        })
        .collect();
    let pose = kin
        .home_pose(&endstops)
        .map_err(|e| SetupError::NoHomePose {
            reason: e.to_string(),
        })?;
    pose.map(|p| declared_pose(kin, p)).transpose()
}

/// The motor that moves Z alone (its position is the toolhead's Z), as the kinematics map it: the role comes from
/// the machine, not from a stepper's name.
fn z_motor(kin: &dyn Kinematics) -> Option<usize> {
    (0..kin.motors().len()).find(
        |&i| matches!(kin.motor_map(i), MotorMap::Linear { coeffs } if coeffs == [0.0, 0.0, 1.0]),
    )
}

/// A stepper's `position_endstop`, in the file's unit.
fn endstop(machine: &MachineConfig, stepper: &str) -> Option<f64> {
    machine
        .stepper(stepper)
        .and_then(|s| s.homing.as_ref())
        .and_then(|h| h.position_endstop)
}

/// FEKT-SCARA's `home_position`: homing declares the arm there without moving it (its joint endstops, if any,
/// are not used), and Z homes to its endstop when it has one.
fn declared_home(machine: &MachineConfig, z_endstop: Option<f64>) -> Option<[f64; 3]> {
    let declared = machine.home_position.as_deref()?;
    let (x, y) = (*declared.first()?, *declared.get(1)?);
    let z = z_endstop.or(declared.get(2).copied()).unwrap_or(0.0);
    Some([x, y, z])
}

/// A home pose must be one the machine can take.
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
