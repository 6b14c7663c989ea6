//! The machine as built: its true kinematic parameters (the config plus assembly errors) and a motor model,
//! and the `[sim]` config section that describes the motor model in a printer.cfg.
//!
//! `[sim]` keys (all optional; the section may be absent):
//! - `microstep_error`: microstep positioning error of every motor, fraction of a full step (default 0).
//! - `microstep_error_<stepper>`: the same for one stepper, e.g. `microstep_error_stepper_bed: 0.02`.
//! - `step_scale_error_<stepper>`: relative travel-per-step error, e.g. `0.002` = 0.2 % too far.
//! - `backlash_<stepper>`: dead band, mm for linear steppers, degrees for rotary ones (bed, SCARA joints).
//!
//! Microsteps per full step come from each stepper's own section. Geometric assembly errors use the normal
//! keys: polar `arm_zero_offset`/`arm_lateral_offset`; SCARA `link1_length`, `link2_length`, `offset_x`,
//! `offset_y`, `ecr`/`elbow_coupling`, `shoulder_zero`, `elbow_zero`; five-bar `left_base_x`, `left_base_y`,
//! `right_base_x`, `right_base_y`, `left_proximal_length`, `right_proximal_length`, `left_distal_length`,
//! `right_distal_length`, `left_zero`, `right_zero` (backlash of its joints in degrees, as the SCARA's).

use crate::error::SimulationError;
use crate::motor::MotorError;
use config::{Bounds, MachineConfig, StepperUnits};
use kinematics::{Kinematics, MachineParams};

/// The true machine: kinematics with the real geometry, and one [`MotorError`] per kinematic motor.
#[derive(Debug)]
pub struct Machine {
    kinematics: Box<dyn Kinematics>,
    params: MachineParams,
    motors: Vec<MotorError>,
}

impl Machine {
    /// A machine with geometry `true_params` and `motor_model` (one entry per motor of the kinematics, in
    /// its order; an empty list means ideal motors with 16 microsteps).
    pub fn new(
        true_params: &MachineParams,
        motor_model: Vec<MotorError>,
    ) -> Result<Machine, SimulationError> {
        let kinematics =
            kinematics::build(true_params).map_err(|e| SimulationError::Machine(e.to_string()))?;
        let count = kinematics.motors().len();
        let motors = if motor_model.is_empty() {
            vec![MotorError::default(); count]
        } else {
            motor_model
        };
        if motors.len() != count {
            return Err(SimulationError::Machine(format!(
                "{} motor models for {count} motors",
                motors.len()
            )));
        }
        for (m, e) in kinematics.motors().iter().zip(&motors) {
            e.validate(&m.name).map_err(SimulationError::Machine)?;
        }
        Ok(Machine {
            kinematics,
            params: true_params.clone(),
            motors,
        })
    }

    /// The machine described by an "actual" printer.cfg: its geometry and its `[sim]` section.
    pub fn from_config(actual: &MachineConfig) -> Result<Machine, SimulationError> {
        let motors = motor_model_from_config(actual)?;
        Machine::new(&actual.params, motors)
    }

    pub fn kinematics(&self) -> &dyn Kinematics {
        self.kinematics.as_ref()
    }

    pub fn params(&self) -> &MachineParams {
        &self.params
    }

    pub fn motor_errors(&self) -> &[MotorError] {
        &self.motors
    }
}

/// Reads the `[sim]` section (if any) into one [`MotorError`] per kinematic motor.
pub fn motor_model_from_config(cfg: &MachineConfig) -> Result<Vec<MotorError>, SimulationError> {
    let kin =
        kinematics::build(&cfg.params).map_err(|e| SimulationError::Machine(e.to_string()))?;
    let section = cfg.document.section("sim");
    let default_micro = match section {
        Some(s) => s.get_f64_or("microstep_error", 0.0, Bounds::NONE.min(0.0).max(0.5))?,
        None => 0.0,
    };
    let mut out = Vec::new();
    for motor in kin.motors() {
        let stepper = cfg.stepper(&motor.name);
        let mut e = MotorError {
            microstep_error: default_micro,
            microsteps: stepper.map_or(16, |s| s.microsteps.max(1)),
            ..MotorError::default()
        };
        if let Some(s) = section {
            let name = motor.name.to_lowercase();
            e.microstep_error = s.get_f64_or(
                &format!("microstep_error_{name}"),
                default_micro,
                Bounds::NONE.min(0.0).max(0.5),
            )?;
            e.scale_error = s.get_f64_or(
                &format!("step_scale_error_{name}"),
                0.0,
                Bounds::NONE.above(-0.5).below(0.5),
            )?;
            let backlash = s.get_f64_or(&format!("backlash_{name}"), 0.0, Bounds::NONE.min(0.0))?;
            let rotary = stepper.is_some_and(|s| s.units == StepperUnits::Radians);
            e.backlash = if rotary {
                backlash.to_radians()
            } else {
                backlash
            };
        }
        out.push(e);
    }
    if let Some(s) = section
        && let Some(entry) = s.unused_entries().next()
    {
        return Err(s
            .error_at(
                entry.key(),
                format!(
                    "unknown [sim] key '{}' (see the sim crate's machine module)",
                    entry.key()
                ),
            )
            .into());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::scenario::{POLAR_EXAMPLE, with_keys};

    /// The bundled polar example, built 1 mm sideways, with a motor model.
    fn polar() -> String {
        let text = with_keys(POLAR_EXAMPLE, "printer", "arm_lateral_offset: 1.0");
        with_keys(
            &text,
            "sim",
            "microstep_error: 0.01\nbacklash_stepper_bed: 0.05\nstep_scale_error_stepper_arm: 0.002",
        )
    }

    #[test]
    fn sim_section_sets_the_motor_model() {
        let cfg = MachineConfig::from_str(&polar(), "actual.cfg").expect("config");
        let m = Machine::from_config(&cfg).expect("machine");
        let e = m.motor_errors();
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].microstep_error, 0.01);
        assert!((e[0].backlash - 0.05f64.to_radians()).abs() < 1e-15);
        assert_eq!(e[1].scale_error, 0.002);
        assert_eq!(e[1].backlash, 0.0);
        assert_eq!(e[2].microsteps, 16);
    }

    #[test]
    fn bad_sim_value_points_at_the_file() {
        let text = polar().replace("microstep_error: 0.01", "microstep_error: lots");
        let cfg = MachineConfig::from_str(&text, "actual.cfg").expect("config");
        let err = Machine::from_config(&cfg).expect_err("must refuse");
        assert!(err.to_string().contains("actual.cfg"), "{err}");
    }

    #[test]
    fn misspelt_sim_key_is_refused_at_its_line() {
        let text = polar().replace("backlash_stepper_bed", "backlash_stepper_bedd");
        let cfg = MachineConfig::from_str(&text, "actual.cfg").expect("config");
        let err = Machine::from_config(&cfg).expect_err("must refuse");
        let msg = err.to_string();
        assert!(
            msg.contains("actual.cfg:") && msg.contains("backlash_stepper_bedd"),
            "{msg}"
        );
    }

    #[test]
    fn motor_count_must_match() {
        let cfg = MachineConfig::from_str(&polar(), "actual.cfg").expect("config");
        let err = Machine::new(&cfg.params, vec![MotorError::default()]).expect_err("count");
        assert!(err.to_string().contains("1 motor models for 3 motors"));
    }
}
