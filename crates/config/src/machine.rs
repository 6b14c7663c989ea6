//! The typed machine: `[printer]` limits, steppers, extruder, arcs and kinematics parameters,
//! read with Klipper's defaults (`toolhead.py`, `kinematics/*.py`, `extruder.py`, `gcode_arcs.py`)
//! plus jointspace's own keys. Units inside are mm, s and rad; keys that take degrees say so.

use std::f64::consts::{PI, SQRT_2};
use std::path::{Path, PathBuf};

use kinematics::{
    CartesianParams, ElbowBranch, MachineParams, PolarParams, ScaraFrame, ScaraParams,
};

use crate::document::{ConfigDocument, Section};
use crate::error::{ConfigError, ConfigWarning};
use crate::span::Span;
use crate::stepper::{StepRateLimit, StepperConfig, StepperRole, StepperUnits, read_stepper};
use crate::value::Bounds;

/// Which kinematics `[printer] kinematics` selects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KinematicsKind {
    Cartesian,
    Polar,
    Scara,
    /// The five-bar (parallel) SCARA.
    Fivebar,
}

impl KinematicsKind {
    pub fn name(self) -> &'static str {
        match self {
            KinematicsKind::Cartesian => "cartesian",
            KinematicsKind::Polar => "polar",
            KinematicsKind::Scara => "scara",
            KinematicsKind::Fivebar => "fivebar",
        }
    }
}

/// `[printer]` motion limits (mm/s, mm/s², rad/s, rad/s², steps/s).
#[derive(Debug, Clone, PartialEq)]
pub struct PrinterLimits {
    pub max_velocity: f64,
    pub max_accel: f64,
    /// Default 0.5; derived from the deprecated `max_accel_to_decel` when only that is given.
    pub minimum_cruise_ratio: f64,
    /// Default 5.0.
    pub square_corner_velocity: f64,
    /// Default `max_velocity` (at most `max_velocity`).
    pub max_z_velocity: f64,
    /// Default `max_accel` (at most `max_accel`).
    pub max_z_accel: f64,
    /// Polar: bed angular speed limit (rad/s), Klipper's key.
    pub max_angular_velocity: Option<f64>,
    /// Polar, jointspace: bed angular acceleration limit (rad/s²).
    pub max_angular_accel: Option<f64>,
    /// SCARA, jointspace: per-joint speed limit (rad/s).
    pub max_joint_velocity: Option<f64>,
    /// SCARA, jointspace: per-joint acceleration limit (rad/s²).
    pub max_joint_accel: Option<f64>,
    /// jointspace: default step-rate limit for every stepper (steps/s).
    pub max_step_rate: Option<f64>,
}

impl PrinterLimits {
    /// Klipper: `junction_deviation = scv² · (√2 − 1) / max_accel`.
    pub fn junction_deviation(&self) -> f64 {
        let scv2 = self.square_corner_velocity * self.square_corner_velocity;
        scv2 * (SQRT_2 - 1.0) / self.max_accel
    }

    /// Klipper: `max_accel · (1 − minimum_cruise_ratio)`.
    pub fn mcr_pseudo_accel(&self) -> f64 {
        self.max_accel * (1.0 - self.minimum_cruise_ratio)
    }
}

/// `[extruder]`: its stepper and Klipper's extrusion limits.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtruderConfig {
    pub stepper: StepperConfig,
    pub nozzle_diameter: f64,
    pub filament_diameter: f64,
    /// `π · (filament_diameter / 2)²`, mm².
    pub filament_area: f64,
    /// Default `4 · nozzle_diameter²`, mm².
    pub max_extrude_cross_section: f64,
    /// `max_extrude_cross_section / filament_area`: the largest E distance per XY distance.
    pub max_extrude_ratio: f64,
    /// Default 50 mm.
    pub max_extrude_only_distance: f64,
    /// Default `max_velocity · 4·nozzle_diameter² / filament_area`.
    pub max_extrude_only_velocity: f64,
    /// Default `max_accel · 4·nozzle_diameter² / filament_area`.
    pub max_extrude_only_accel: f64,
    /// Default 1.0 mm/s.
    pub instantaneous_corner_velocity: f64,
    /// Default 0.
    pub pressure_advance: f64,
    /// Default 0.040 s.
    pub pressure_advance_smooth_time: f64,
}

/// `[gcode_arcs]`: arcs are split into segments of at most `resolution` mm (default 1.0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcConfig {
    pub resolution: f64,
}

/// A key in a section jointspace interprets that nothing read (often a typo like `max_velocty`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnusedKey {
    pub section: String,
    pub key: String,
    pub span: Span,
}

/// Everything jointspace needs from `printer.cfg`.
#[derive(Debug, Clone)]
pub struct MachineConfig {
    pub path: PathBuf,
    pub kinematics: KinematicsKind,
    pub params: MachineParams,
    pub limits: PrinterLimits,
    pub extruder: Option<ExtruderConfig>,
    pub arcs: Option<ArcConfig>,
    /// `[force_move] enable_force_move: True`: Klipper then has `SET_KINEMATIC_POSITION`.
    pub force_move: bool,
    /// Every stepper: the kinematics' steppers in their order, then the extruder's.
    pub steppers: Vec<StepperConfig>,
    /// SCARA and five-bar `home_position` (x, y[, z] in mm), the pose the FEKT-SCARA module declares when homing.
    pub home_position: Option<Vec<f64>>,
    /// The whole parsed file, for sections this struct does not interpret.
    pub document: ConfigDocument,
    /// Reader warnings plus interpretation warnings (deprecated keys, ignored stepper sections).
    pub warnings: Vec<ConfigWarning>,
}

/// Sections whose unread keys [`MachineConfig::unused_keys`] reports.
const INTERPRETED_SECTIONS: [&str; 2] = ["printer", "gcode_arcs"];

/// Keys that other Klipper modules read from the sections we interpret (not typos).
const KEYS_READ_ELSEWHERE: &[&str] = &[
    // the Klipper plug-in (klipper/jointspace_klipper/jointspace.py): which whole-move rule check_move uses near the polar centre
    "centre_slowdown",
    // toolhead
    "buffer_time_low",
    "buffer_time_high",
    "buffer_time_start",
    "move_flush_time",
    // stepper / rail homing extras
    "second_homing_speed",
    "homing_retract_speed",
    "homing_retract_dist",
    "min_home_dist",
    "use_sensorless_homing",
    // heater and temperature sensor (in [extruder])
    "heater_pin",
    "max_power",
    "sensor_type",
    "sensor_pin",
    "sensor_mcu",
    "pullup_resistor",
    "inline_resistor",
    "smooth_time",
    "control",
    "pid_kp",
    "pid_ki",
    "pid_kd",
    "max_delta",
    "pwm_cycle_time",
    "min_temp",
    "max_temp",
    "min_extrude_temp",
    "adc_voltage",
    "voltage_offset",
    "beta",
    "temperature1",
    "resistance1",
    "temperature2",
    "resistance2",
    "temperature3",
    "resistance3",
    "spi_speed",
    "spi_bus",
    "spi_software_sclk_pin",
    "spi_software_mosi_pin",
    "spi_software_miso_pin",
    "rtd_nominal_r",
    "rtd_reference_r",
    "rtd_num_of_wires",
    "rtd_use_50hz_filter",
    "tc_type",
    "tc_use_50hz_filter",
    "tc_averaging_count",
    "i2c_address",
    "i2c_mcu",
    "i2c_bus",
    "i2c_speed",
];

impl MachineConfig {
    /// Reads `path` (with includes and SAVE_CONFIG) into a machine.
    pub fn load(path: impl AsRef<Path>) -> Result<MachineConfig, ConfigError> {
        MachineConfig::from_document(ConfigDocument::load(path)?)
    }

    /// Parses `text` as the file `path` (includes resolve relative to its folder).
    pub fn from_str(text: &str, path: impl AsRef<Path>) -> Result<MachineConfig, ConfigError> {
        MachineConfig::from_document(ConfigDocument::from_str(text, path)?)
    }

    /// Interprets an already parsed document.
    pub fn from_document(document: ConfigDocument) -> Result<MachineConfig, ConfigError> {
        let mut warnings = document.warnings().to_vec();
        let printer =
            document.require_section("printer", "every config needs [printer] with kinematics")?;
        let kinematics = read_kinematics_kind(printer)?;
        let limits = read_limits(printer, kinematics, &mut warnings)?;
        let mut steppers = Vec::new();
        let (params, home_position) = match kinematics {
            KinematicsKind::Cartesian => (read_cartesian(&document, &limits, &mut steppers)?, None),
            KinematicsKind::Polar => (
                read_polar(&document, printer, &limits, &mut steppers)?,
                None,
            ),
            KinematicsKind::Scara => read_scara(&document, printer, &limits, &mut steppers)?,
            KinematicsKind::Fivebar => read_fivebar(&document, printer, &limits, &mut steppers)?,
        };
        let extruder = document
            .section("extruder")
            .map(|section| read_extruder(section, &limits))
            .transpose()?;
        if let Some(extruder) = &extruder {
            steppers.push(extruder.stepper.clone());
            warn_pressure_advance(&document, extruder, &mut warnings);
        }
        let arcs = document.section("gcode_arcs").map(read_arcs).transpose()?;
        let force_move = document
            .section("force_move")
            .map(|section| section.get_bool_or("enable_force_move", false))
            .transpose()?
            .unwrap_or(false);
        warn_ignored_steppers(&document, kinematics, &steppers, &mut warnings);
        Ok(MachineConfig {
            path: document.path().to_path_buf(),
            kinematics,
            params,
            limits,
            extruder,
            arcs,
            force_move,
            steppers,
            home_position,
            document,
            warnings,
        })
    }

    /// The stepper configured in section `name`.
    pub fn stepper(&self, name: &str) -> Option<&StepperConfig> {
        self.steppers
            .iter()
            .find(|s| s.name.eq_ignore_ascii_case(name))
    }

    /// A stepper's step-rate limit (steps/s): its own `max_step_rate`, else `[printer]`'s; the extruder's
    /// stepper too.
    pub fn max_step_rate(&self, stepper: &str) -> Option<f64> {
        self.stepper_or_extruder(stepper)
            .map_or(self.limits.max_step_rate, |s| s.max_step_rate)
    }

    /// The step-rate limit the step audit holds a motor's stream to ([`StepperConfig::step_rate_limit`]); `None`
    /// for a name that is no stepper here.
    pub fn step_rate_limit(&self, stepper: &str) -> Option<StepRateLimit> {
        self.stepper_or_extruder(stepper)
            .map(StepperConfig::step_rate_limit)
    }

    fn stepper_or_extruder(&self, stepper: &str) -> Option<&StepperConfig> {
        let extruder = self.extruder.as_ref().map(|e| &e.stepper);
        self.stepper(stepper)
            .or(extruder.filter(|s| s.name.eq_ignore_ascii_case(stepper)))
    }

    /// Keys in the sections jointspace interprets that nothing read (likely misspelt), with spans.
    pub fn unused_keys(&self) -> Vec<UnusedKey> {
        let stepper_sections = self.steppers.iter().map(|s| s.name.as_str());
        let names: Vec<&str> = INTERPRETED_SECTIONS
            .into_iter()
            .chain(stepper_sections)
            .collect();
        names
            .into_iter()
            .filter_map(|name| self.document.section(name))
            .flat_map(|section| {
                section
                    .unused_entries()
                    .filter(|e| !KEYS_READ_ELSEWHERE.contains(&e.key()))
                    .map(|e| UnusedKey {
                        section: section.name().to_string(),
                        key: e.key().to_string(),
                        span: e.key_span().clone(),
                    })
            })
            .collect()
    }
}

fn read_kinematics_kind(printer: &Section) -> Result<KinematicsKind, ConfigError> {
    let name = printer.get_str("kinematics")?.trim().to_lowercase();
    match name.as_str() {
        "cartesian" => Ok(KinematicsKind::Cartesian),
        // The names the Klipper/Kalico plug-in registers, so one printer.cfg serves the printer and the CLI.
        "polar" | "jointspace_polar" => Ok(KinematicsKind::Polar),
        "scara" | "jointspace_scara" => Ok(KinematicsKind::Scara),
        "fivebar" | "jointspace_fivebar" => Ok(KinematicsKind::Fivebar),
        _ => Err(ConfigError::UnsupportedKinematics {
            span: Box::new(
                printer
                    .entry("kinematics")
                    .map_or_else(|| printer.header_span().clone(), |e| e.value_span().clone()),
            ),
            name,
        }),
    }
}

/// `[printer]` limits with Klipper's defaults and bounds (toolhead.py, cartesian.py/polar.py).
fn read_limits(
    printer: &Section,
    kinematics: KinematicsKind,
    warnings: &mut Vec<ConfigWarning>,
) -> Result<PrinterLimits, ConfigError> {
    let positive = Bounds::NONE.above(0.0);
    let max_velocity = printer.get_f64("max_velocity", positive)?;
    let max_accel = printer.get_f64("max_accel", positive)?;
    let minimum_cruise_ratio = read_minimum_cruise_ratio(printer, max_accel, warnings)?;
    let square_corner_velocity =
        printer.get_f64_or("square_corner_velocity", 5.0, Bounds::NONE.min(0.0))?;
    let max_z_velocity =
        printer.get_f64_or("max_z_velocity", max_velocity, positive.max(max_velocity))?;
    let max_z_accel = printer.get_f64_or("max_z_accel", max_accel, positive.max(max_accel))?;
    let polar = kinematics == KinematicsKind::Polar;
    // Both arms' joints: the SCARA's and the five-bar's.
    let scara = matches!(kinematics, KinematicsKind::Scara | KinematicsKind::Fivebar);
    let only_if = |wanted: bool, key: &str| -> Result<Option<f64>, ConfigError> {
        if wanted {
            printer.get_f64_opt(key, positive)
        } else {
            Ok(None)
        }
    };
    Ok(PrinterLimits {
        max_velocity,
        max_accel,
        minimum_cruise_ratio,
        square_corner_velocity,
        max_z_velocity,
        max_z_accel,
        max_angular_velocity: only_if(polar, "max_angular_velocity")?,
        max_angular_accel: only_if(polar, "max_angular_accel")?,
        max_joint_velocity: only_if(scara, "max_joint_velocity")?,
        max_joint_accel: only_if(scara, "max_joint_accel")?,
        max_step_rate: printer.get_f64_opt("max_step_rate", positive)?,
    })
}

/// `minimum_cruise_ratio`, or Klipper's conversion of the deprecated `max_accel_to_decel`.
fn read_minimum_cruise_ratio(
    printer: &Section,
    max_accel: f64,
    warnings: &mut Vec<ConfigWarning>,
) -> Result<f64, ConfigError> {
    let mut default = 0.5;
    if !printer.contains("minimum_cruise_ratio")
        && let Some(accel_to_decel) =
            printer.get_f64_opt("max_accel_to_decel", Bounds::NONE.above(0.0))?
    {
        default = 1.0 - (accel_to_decel / max_accel).min(1.0);
        warnings.push(ConfigWarning {
            span: printer
                .entry("max_accel_to_decel")
                .map(|e| e.key_span().clone()),
            message: format!(
                "max_accel_to_decel is deprecated: use minimum_cruise_ratio: {default} instead"
            ),
        });
    }
    printer.get_f64_or(
        "minimum_cruise_ratio",
        default,
        Bounds::NONE.min(0.0).below(1.0),
    )
}

fn stepper_section<'a>(
    document: &'a ConfigDocument,
    name: &str,
    kinematics: &str,
) -> Result<&'a Section, ConfigError> {
    document.require_section(name, &format!("required by {kinematics} kinematics"))
}

/// A stepper section a kinematics needs: its name, its units and how it homes.
type StepperSlot<'a> = (&'a str, StepperUnits, StepperRole);

/// Reads a kinematics' three stepper sections in order and records each in `steppers`.
fn add_steppers(
    document: &ConfigDocument,
    kinematics: KinematicsKind,
    slots: [StepperSlot<'_>; 3],
    limits: &PrinterLimits,
    steppers: &mut Vec<StepperConfig>,
) -> Result<[StepperConfig; 3], ConfigError> {
    let mut add = |(name, units, role): StepperSlot<'_>| -> Result<StepperConfig, ConfigError> {
        let section = stepper_section(document, name, kinematics.name())?;
        let stepper = read_stepper(section, units, role, limits.max_step_rate)?;
        steppers.push(stepper.clone());
        Ok(stepper)
    };
    let [first, second, third] = slots;
    Ok([add(first)?, add(second)?, add(third)?])
}

const MM_RAIL: (StepperUnits, StepperRole) = (StepperUnits::Millimetres, StepperRole::Rail);

fn read_cartesian(
    document: &ConfigDocument,
    limits: &PrinterLimits,
    steppers: &mut Vec<StepperConfig>,
) -> Result<MachineParams, ConfigError> {
    let (mm, rail) = MM_RAIL;
    let [x, y, z] = add_steppers(
        document,
        KinematicsKind::Cartesian,
        [
            ("stepper_x", mm, rail),
            ("stepper_y", mm, rail),
            ("stepper_z", mm, rail),
        ],
        limits,
        steppers,
    )?;
    Ok(MachineParams::Cartesian(CartesianParams {
        steppers: [x.params(), y.params(), z.params()],
    }))
}

fn read_polar(
    document: &ConfigDocument,
    printer: &Section,
    limits: &PrinterLimits,
    steppers: &mut Vec<StepperConfig>,
) -> Result<MachineParams, ConfigError> {
    let (mm, rail) = MM_RAIL;
    let [bed, arm, z] = add_steppers(
        document,
        KinematicsKind::Polar,
        [
            ("stepper_bed", StepperUnits::Radians, StepperRole::Plain),
            ("stepper_arm", mm, rail),
            ("stepper_z", mm, rail),
        ],
        limits,
        steppers,
    )?;
    Ok(MachineParams::Polar(PolarParams {
        bed: bed.params(),
        arm: arm.params(),
        z: z.params(),
        arm_zero_offset: printer.get_f64_or("arm_zero_offset", 0.0, Bounds::NONE)?,
        arm_lateral_offset: printer.get_f64_or("arm_lateral_offset", 0.0, Bounds::NONE)?,
    }))
}

/// SCARA: FEKT-SCARA's keys (`link1_length`, `ecr`, …) plus jointspace's. Angles in the file are degrees.
fn read_scara(
    document: &ConfigDocument,
    printer: &Section,
    limits: &PrinterLimits,
    steppers: &mut Vec<StepperConfig>,
) -> Result<(MachineParams, Option<Vec<f64>>), ConfigError> {
    let (mm, rail) = MM_RAIL;
    let rad = StepperUnits::Radians;
    let [shoulder, elbow, z] = add_steppers(
        document,
        KinematicsKind::Scara,
        [
            ("stepper_a", rad, rail),
            ("stepper_b", rad, rail),
            ("stepper_z", mm, rail),
        ],
        limits,
        steppers,
    )?;
    let positive = Bounds::NONE.above(0.0);
    let (elbow_coupling, ecr) = read_elbow_coupling(printer)?;
    let degrees = |key: &str| -> Result<f64, ConfigError> {
        Ok(printer.get_f64_or(key, 0.0, Bounds::NONE)?.to_radians())
    };
    let params = ScaraParams {
        shoulder_stepper: shoulder.params(),
        elbow_stepper: elbow.params(),
        z: z.params(),
        link1_length: printer.get_f64("link1_length", positive)?,
        link2_length: printer.get_f64("link2_length", positive)?,
        offset_x: printer.get_f64_or("offset_x", 0.0, Bounds::NONE)?,
        offset_y: printer.get_f64_or("offset_y", 0.0, Bounds::NONE)?,
        elbow_coupling,
        ecr,
        elbow: printer.get_choice_or(
            "elbow",
            &[("left", ElbowBranch::Left), ("right", ElbowBranch::Right)],
            ElbowBranch::Left,
        )?,
        frame: printer.get_choice_or(
            "frame",
            &[
                ("standard", ScaraFrame::Standard),
                ("xscara", ScaraFrame::XScara),
            ],
            ScaraFrame::Standard,
        )?,
        shoulder_zero: degrees("shoulder_zero")?,
        elbow_zero: degrees("elbow_zero")?,
        shoulder_limits: read_joint_limits(printer, "shoulder_min", "shoulder_max")?,
        elbow_limits: read_joint_limits(printer, "elbow_min", "elbow_max")?,
        // FEKT-SCARA's default; 0 disables the check.
        base_protection_radius: printer.get_f64_or(
            "base_protection_radius",
            60.0,
            Bounds::NONE.min(0.0),
        )?,
        singularity_margin: printer.get_f64_or(
            "singularity_margin",
            0.05,
            Bounds::NONE.min(0.0).below(1.0),
        )?,
    };
    Ok((MachineParams::Scara(params), read_home_position(printer)?))
}

/// Five-bar: `stepper_left`, `stepper_right` (rotary rails, degrees in the file) and `stepper_z`; the keys are read in
/// `fivebar.rs`.
fn read_fivebar(
    document: &ConfigDocument,
    printer: &Section,
    limits: &PrinterLimits,
    steppers: &mut Vec<StepperConfig>,
) -> Result<(MachineParams, Option<Vec<f64>>), ConfigError> {
    let (mm, rail) = MM_RAIL;
    let rad = StepperUnits::Radians;
    let read = add_steppers(
        document,
        KinematicsKind::Fivebar,
        [
            ("stepper_left", rad, rail),
            ("stepper_right", rad, rail),
            ("stepper_z", mm, rail),
        ],
        limits,
        steppers,
    )?;
    let params = crate::fivebar::read_fivebar(printer, &read)?;
    Ok((MachineParams::Fivebar(params), read_home_position(printer)?))
}

/// `elbow_coupling` (c) directly, or FEKT-SCARA's `ecr` (c = 1/ecr); both given must agree (to 1e-6,
/// relative). Returns `(c, ecr)`; when `ecr` is given, `c` is exactly `1/ecr`.
fn read_elbow_coupling(printer: &Section) -> Result<(f64, Option<f64>), ConfigError> {
    let ecr = printer.get_f64_opt("ecr", Bounds::NONE.above(0.0))?;
    let coupling = printer.get_f64_opt("elbow_coupling", Bounds::NONE)?;
    match (ecr, coupling) {
        (None, None) => Err(ConfigError::InvalidSection {
            span: Box::new(printer.header_span().clone()),
            section: printer.name().to_string(),
            message: "SCARA needs 'ecr' (elbow crosstalk ratio) or 'elbow_coupling'".to_string(),
        }),
        (Some(ecr), None) => Ok((positive_finite(printer, "ecr", 1.0 / ecr)?, Some(ecr))),
        (None, Some(c)) => Ok((c, None)),
        (Some(ecr), Some(c)) => {
            let from_ecr = positive_finite(printer, "ecr", 1.0 / ecr)?;
            if (from_ecr - c).abs() > 1e-6 * from_ecr.abs().max(c.abs()) {
                return Err(printer.error_at(
                    "elbow_coupling",
                    format!("{c} contradicts ecr: {ecr} (which means elbow_coupling {from_ecr})"),
                ));
            }
            Ok((from_ecr, Some(ecr)))
        }
    }
}

/// A pair of joint limits in degrees, converted to radians; both or neither must be given.
fn read_joint_limits(
    printer: &Section,
    min_key: &str,
    max_key: &str,
) -> Result<Option<(f64, f64)>, ConfigError> {
    let min = printer.get_f64_opt(min_key, Bounds::NONE)?;
    let max = printer.get_f64_opt(max_key, Bounds::NONE)?;
    match (min, max) {
        (None, None) => Ok(None),
        (Some(_), None) => Err(printer.error_at(min_key, format!("needs {max_key} too"))),
        (None, Some(_)) => Err(printer.error_at(max_key, format!("needs {min_key} too"))),
        (Some(lo), Some(hi)) if lo >= hi => {
            Err(printer.error_at(max_key, format!("must be above {min_key} ({lo})")))
        }
        (Some(lo), Some(hi)) => Ok(Some((lo.to_radians(), hi.to_radians()))),
    }
}

fn read_home_position(printer: &Section) -> Result<Option<Vec<f64>>, ConfigError> {
    let home = printer.get_f64_list_opt("home_position")?;
    if let Some(values) = &home
        && !(2..=3).contains(&values.len())
    {
        return Err(printer.error_at("home_position", "must have 2 or 3 values (x, y[, z])"));
    }
    Ok(home)
}

/// `[extruder]` in Klipper's order of computation (extruder.py).
fn read_extruder(section: &Section, limits: &PrinterLimits) -> Result<ExtruderConfig, ConfigError> {
    let stepper = read_stepper(
        section,
        StepperUnits::Millimetres,
        StepperRole::Plain,
        limits.max_step_rate,
    )?;
    let positive = Bounds::NONE.above(0.0);
    let nozzle_diameter = section.get_f64("nozzle_diameter", positive)?;
    let filament_diameter =
        section.get_f64("filament_diameter", Bounds::NONE.min(nozzle_diameter))?;
    let half = filament_diameter * 0.5;
    let filament_area = PI * (half * half);
    let def_max_cross_section = 4.0 * (nozzle_diameter * nozzle_diameter);
    let def_max_extrude_ratio = def_max_cross_section / filament_area;
    let max_extrude_cross_section =
        section.get_f64_or("max_extrude_cross_section", def_max_cross_section, positive)?;
    // Extreme diameters can overflow these products; refuse rather than carry inf/NaN limits.
    let checked = |key: &str, value: f64| positive_finite(section, key, value);
    Ok(ExtruderConfig {
        stepper,
        nozzle_diameter,
        filament_diameter,
        filament_area: checked("filament_diameter", filament_area)?,
        max_extrude_cross_section: checked("nozzle_diameter", max_extrude_cross_section)?,
        max_extrude_ratio: checked(
            "filament_diameter",
            max_extrude_cross_section / filament_area,
        )?,
        max_extrude_only_velocity: checked(
            "nozzle_diameter",
            section.get_f64_or(
                "max_extrude_only_velocity",
                limits.max_velocity * def_max_extrude_ratio,
                positive,
            )?,
        )?,
        max_extrude_only_accel: checked(
            "nozzle_diameter",
            section.get_f64_or(
                "max_extrude_only_accel",
                limits.max_accel * def_max_extrude_ratio,
                positive,
            )?,
        )?,
        max_extrude_only_distance: section.get_f64_or(
            "max_extrude_only_distance",
            50.0,
            Bounds::NONE.min(0.0),
        )?,
        instantaneous_corner_velocity: section.get_f64_or(
            "instantaneous_corner_velocity",
            1.0,
            Bounds::NONE.min(0.0),
        )?,
        pressure_advance: section.get_f64_or("pressure_advance", 0.0, Bounds::NONE.min(0.0))?,
        pressure_advance_smooth_time: section.get_f64_or(
            "pressure_advance_smooth_time",
            0.040,
            Bounds::NONE.above(0.0).max(0.200),
        )?,
    })
}

/// `value` (derived from `key`) if it is finite and positive, else an error at `key`.
fn positive_finite(section: &Section, key: &str, value: f64) -> Result<f64, ConfigError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(section.error_at(key, format!("leads to an unusable derived value ({value})")))
    }
}

fn read_arcs(section: &Section) -> Result<ArcConfig, ConfigError> {
    Ok(ArcConfig {
        resolution: section.get_f64_or("resolution", 1.0, Bounds::NONE.above(0.0))?,
    })
}

/// Pressure advance shifts the extruder's steps in time (Klipper smooths the extrusion rate); jointspace plans and
/// steps the nominal extrusion, so a config that sets it is told its extruder steps will differ from Klipper's.
fn warn_pressure_advance(
    document: &ConfigDocument,
    extruder: &ExtruderConfig,
    warnings: &mut Vec<ConfigWarning>,
) {
    if extruder.pressure_advance == 0.0 {
        return;
    }
    let span = document
        .section("extruder")
        .and_then(|s| s.entry("pressure_advance"))
        .map(|e| e.key_span().clone());
    warnings.push(ConfigWarning {
        span,
        message: "pressure_advance is not modelled: the extruder's steps follow the nominal extrusion, not \
                  Klipper's pressure-advanced one (moves and the other motors are unaffected)"
            .into(),
    });
}

/// Warns about `[stepper_*]` sections the kinematics do not use (e.g. a second Z motor `stepper_z1`).
fn warn_ignored_steppers(
    document: &ConfigDocument,
    kinematics: KinematicsKind,
    steppers: &[StepperConfig],
    warnings: &mut Vec<ConfigWarning>,
) {
    for section in document.sections() {
        let kind = section.kind();
        let used = steppers.iter().any(|s| s.name.eq_ignore_ascii_case(kind));
        if kind.starts_with("stepper_") && section.argument().is_empty() && !used {
            warnings.push(ConfigWarning {
                span: Some(section.header_span().clone()),
                message: format!(
                    "[{}] is not used by {} kinematics and is ignored",
                    section.name(),
                    kinematics.name()
                ),
            });
        }
    }
}
