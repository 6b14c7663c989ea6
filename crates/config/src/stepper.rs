//! One stepper section (`[stepper_*]`, `[extruder]`): step distance, pins, travel range and homing,
//! with Klipper's defaults and checks (`stepper.py`: `parse_step_distance`, `PrinterRail`).

use kinematics::StepperParams;

use crate::document::Section;
use crate::error::ConfigError;
use crate::value::{Bounds, Pin};

/// The unit a stepper's position is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepperUnits {
    Millimetres,
    /// Rotary joints (polar bed, SCARA arms): `rotation_distance` is fixed at 2π.
    Radians,
}

/// How a section is used, which decides the keys Klipper reads from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StepperRole {
    /// A homed axis (`PrinterRail`): endstop, `position_min`/`position_max`, homing.
    Rail,
    /// A plain stepper (polar bed, extruder): no range, no homing.
    Plain,
}

/// Homing settings of a rail (an axis with an endstop).
#[derive(Debug, Clone, PartialEq)]
pub struct HomingConfig {
    pub endstop_pin: Pin,
    /// `position_endstop`; `None` only for a probe's virtual endstop (the probe supplies it).
    pub position_endstop: Option<f64>,
    /// `homing_speed` (default 5, units per second).
    pub homing_speed: f64,
    /// `homing_positive_dir`, given or inferred from where the endstop sits in the range, like Klipper.
    pub positive_dir: bool,
}

/// A configured stepper motor.
#[derive(Debug, Clone, PartialEq)]
pub struct StepperConfig {
    /// The section name (`stepper_bed`, `stepper_a`, `extruder`, …).
    pub name: String,
    pub units: StepperUnits,
    pub step_pin: Pin,
    /// `dir_pin`; `dir_pin.inverted` is the `!` inversion.
    pub dir_pin: Pin,
    pub enable_pin: Option<Pin>,
    /// mm per full motor turn; 2π for rotary steppers.
    pub rotation_distance: f64,
    pub microsteps: u32,
    pub full_steps_per_rotation: u32,
    pub gear_ratio: f64,
    /// `full_steps · microsteps · gear_ratio`, in Klipper's float order.
    pub steps_per_rotation: f64,
    /// Travel per microstep in `units`: `rotation_distance / steps_per_rotation`.
    pub step_distance: f64,
    /// `position_min`/`position_max` of a rail (default min 0), as written in the file: mm, or degrees for a rotary
    /// rail (the FEKT-SCARA configs write ±200); [`StepperConfig::params`] gives them in the motor's units.
    pub position_min: Option<f64>,
    pub position_max: Option<f64>,
    pub homing: Option<HomingConfig>,
    /// jointspace: highest step rate this motor may be asked for (steps/s), if limited.
    pub max_step_rate: Option<f64>,
    /// Klipper's `step_pulse_duration` (s), if written: how long the MCU holds the step pin, so no step of this
    /// motor can follow the one before sooner.
    pub step_pulse_duration: Option<f64>,
}

impl StepperConfig {
    /// Whether `dir_pin` is inverted (`!`).
    pub fn dir_inverted(&self) -> bool {
        self.dir_pin.inverted
    }

    /// The parameters the kinematics are built from, in the motor's units: a rotary rail's range is written in
    /// degrees (as its `position_endstop`) and the kinematics count radians.
    pub fn params(&self) -> StepperParams {
        let unit = |v: f64| match self.units {
            StepperUnits::Radians => v.to_radians(),
            StepperUnits::Millimetres => v,
        };
        StepperParams {
            name: self.name.clone(),
            step_distance: self.step_distance,
            position_min: self.position_min.map(unit),
            position_max: self.position_max.map(unit),
        }
    }
}

/// Klipper's step pulse when a stepper section writes none (`klippy/stepper.py`: 2 µs; its TMC driver modules
/// lower it to 100 ns, which a config states with `step_pulse_duration`).
pub const DEFAULT_STEP_PULSE_DURATION: f64 = 2e-6;

/// The highest step rate a motor's MCU stream may have, and where that limit comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRateLimit {
    pub steps_per_second: f64,
    pub source: StepRateSource,
}

/// Where a [`StepRateLimit`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepRateSource {
    /// The stepper's or `[printer]`'s `max_step_rate`: the planner keeps under it too.
    MaxStepRate,
    /// The stepper's `step_pulse_duration`: a step cannot start before the pulse before it has ended.
    StepPulse,
    /// Neither is written: Klipper's default pulse, [`DEFAULT_STEP_PULSE_DURATION`].
    DefaultStepPulse,
}

impl StepRateLimit {
    /// What the limit is, for a message: the rate and the setting it comes from.
    pub fn describe(&self) -> String {
        let rate = self.steps_per_second;
        match self.source {
            StepRateSource::MaxStepRate => format!("its max_step_rate of {rate:.0} steps/s"),
            StepRateSource::StepPulse => {
                format!("{rate:.0} steps/s, one step per step_pulse_duration")
            }
            StepRateSource::DefaultStepPulse => format!(
                "{rate:.0} steps/s, one step per Klipper's default 2 µs step pulse (no max_step_rate or \
                 step_pulse_duration is set; set max_step_rate for this board and the planner keeps under it)"
            ),
        }
    }
}

impl StepperConfig {
    /// The step rate the MCU stream of this motor may not exceed: `max_step_rate` where set, else one step per
    /// step pulse (the configured one, or Klipper's default).
    pub fn step_rate_limit(&self) -> StepRateLimit {
        let from_pulse = |pulse: f64, source| StepRateLimit {
            steps_per_second: 1.0 / pulse,
            source,
        };
        match (self.max_step_rate, self.step_pulse_duration) {
            (Some(rate), _) => StepRateLimit {
                steps_per_second: rate,
                source: StepRateSource::MaxStepRate,
            },
            (None, Some(pulse)) => from_pulse(pulse, StepRateSource::StepPulse),
            (None, None) => from_pulse(
                DEFAULT_STEP_PULSE_DURATION,
                StepRateSource::DefaultStepPulse,
            ),
        }
    }
}

/// Reads a stepper section. `default_max_step_rate` comes from `[printer] max_step_rate`.
pub(crate) fn read_stepper(
    section: &Section,
    units: StepperUnits,
    role: StepperRole,
    default_max_step_rate: Option<f64>,
) -> Result<StepperConfig, ConfigError> {
    let step_pin = section.get_pin("step_pin", false)?;
    let dir_pin = section.get_pin("dir_pin", false)?;
    let enable_pin = section.get_pin_opt("enable_pin", false)?;
    let rotation_distance = read_rotation_distance(section, units)?;
    let microsteps = section.get_u32("microsteps", Bounds::NONE.min(1.0))?;
    let full_steps = section.get_u32_or("full_steps_per_rotation", 200, Bounds::NONE.min(1.0))?;
    if full_steps % 4 != 0 {
        return Err(section.error_at("full_steps_per_rotation", "must be divisible by 4"));
    }
    let gear_ratio = match units {
        StepperUnits::Radians => section.get_ratio("gear_ratio")?,
        StepperUnits::Millimetres => section.get_ratio_or("gear_ratio", 1.0)?,
    };
    // Klipper: steps_per_rotation = full_steps * microsteps * gearing (exact integer product, then float).
    let whole_steps = u64::from(full_steps) * u64::from(microsteps);
    let steps_per_rotation = whole_steps as f64 * gear_ratio;
    let step_distance = rotation_distance / steps_per_rotation;
    if !(step_distance.is_finite() && step_distance > 0.0) {
        let key = if section.contains("gear_ratio") {
            "gear_ratio"
        } else {
            "rotation_distance"
        };
        return Err(section.error_at(
            key,
            format!("gives an unusable step distance ({step_distance})"),
        ));
    }
    let max_step_rate = section
        .get_f64_opt("max_step_rate", Bounds::NONE.above(0.0))?
        .or(default_max_step_rate);
    let step_pulse_duration =
        section.get_f64_opt("step_pulse_duration", Bounds::NONE.above(0.0).max(0.001))?;
    let (position_min, position_max, homing) = match role {
        StepperRole::Rail => read_rail(section)?,
        StepperRole::Plain => (None, None, None),
    };
    Ok(StepperConfig {
        name: section.name().to_string(),
        units,
        step_pin,
        dir_pin,
        enable_pin,
        rotation_distance,
        microsteps,
        full_steps_per_rotation: full_steps,
        gear_ratio,
        steps_per_rotation,
        step_distance,
        position_min,
        position_max,
        homing,
        max_step_rate,
        step_pulse_duration,
    })
}

/// Linear steppers need `rotation_distance`; rotary ones turn 2π rad per output turn and may not set it.
fn read_rotation_distance(section: &Section, units: StepperUnits) -> Result<f64, ConfigError> {
    match units {
        StepperUnits::Millimetres => section.get_f64("rotation_distance", Bounds::NONE.above(0.0)),
        StepperUnits::Radians if section.contains("rotation_distance") => Err(section.error_at(
            "rotation_distance",
            "not valid on a rotary stepper (its unit is radians: set gear_ratio instead)",
        )),
        StepperUnits::Radians => Ok(std::f64::consts::TAU),
    }
}

type RailRange = (Option<f64>, Option<f64>, Option<HomingConfig>);

/// `PrinterRail`: endstop, range and homing direction. A rail without `endstop_pin` (Klipper requires one)
/// is read for its geometry: it cannot home (a `G28` is refused at its line), its range is what is given.
fn read_rail(section: &Section) -> Result<RailRange, ConfigError> {
    if !section.contains("endstop_pin") {
        // Homing keys have nothing to act on here; they are not typos.
        for key in ["position_endstop", "homing_speed", "homing_positive_dir"] {
            section.mark_read(key);
        }
        let position_min = section.get_f64_opt("position_min", Bounds::NONE)?;
        let above = position_min.map_or(Bounds::NONE, |min| Bounds::NONE.above(min));
        let position_max = section.get_f64_opt("position_max", above)?;
        return Ok((position_min, position_max, None));
    }
    let endstop_pin = section.get_pin("endstop_pin", true)?;
    // A probe's virtual endstop gets its position from the probe's z_offset.
    let is_probe = endstop_pin.chip.as_deref() == Some("probe");
    let position_endstop = if is_probe {
        section.get_f64_opt("position_endstop", Bounds::NONE)?
    } else {
        Some(section.get_f64("position_endstop", Bounds::NONE)?)
    };
    let position_min = section.get_f64_or("position_min", 0.0, Bounds::NONE)?;
    let position_max = section.get_f64("position_max", Bounds::NONE.above(position_min))?;
    if let Some(endstop) = position_endstop
        && !(position_min..=position_max).contains(&endstop)
    {
        return Err(section.error_at(
            "position_endstop",
            "must be between position_min and position_max",
        ));
    }
    let homing_speed = section.get_f64_or("homing_speed", 5.0, Bounds::NONE.above(0.0))?;
    let positive_dir = homing_direction(section, position_endstop, position_min, position_max)?;
    let homing = HomingConfig {
        endstop_pin,
        position_endstop,
        homing_speed,
        positive_dir,
    };
    Ok((Some(position_min), Some(position_max), Some(homing)))
}

/// Klipper's rule: if not given, home towards the end of the range the endstop sits in (outer quarters).
fn homing_direction(
    section: &Section,
    endstop: Option<f64>,
    min: f64,
    max: f64,
) -> Result<bool, ConfigError> {
    let given = section.get_bool_opt("homing_positive_dir")?;
    let Some(endstop) = endstop else {
        return Ok(given.unwrap_or(false));
    };
    match given {
        Some(positive) => {
            let contradicts = (positive && endstop == min) || (!positive && endstop == max);
            if contradicts {
                return Err(section.error_at(
                    "homing_positive_dir",
                    "contradicts position_endstop (the endstop is at the other end of the range)",
                ));
            }
            Ok(positive)
        }
        None => {
            let axis_len = max - min;
            if endstop <= min + axis_len / 4.0 {
                Ok(false)
            } else if endstop >= max - axis_len / 4.0 {
                Ok(true)
            } else {
                Err(section.error_at(
                    "position_endstop",
                    "unable to infer homing_positive_dir (the endstop is mid-range): set homing_positive_dir",
                ))
            }
        }
    }
}
