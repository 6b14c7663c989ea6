//! A machine ready to plan for: kinematics, planner limits and the homing pose, built from `printer.cfg`.

use crate::kinematic_limits::MotorLimit;
use crate::limits::{CentreTurn, ExtruderLimits, PlannerConfig, VelocityLimits};
use config::{KinematicsKind, MachineConfig};
use kinematics::{Kinematics, MotorUnit};

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
