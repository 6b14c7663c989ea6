//! The closed loop on the virtual printer: simulate → calibrate → correct → simulate again, plus the
//! bundled demo machines (in-memory printer.cfg text) and a generator of circle test prints.
//!
//! Calibrations run against the *true* machine only through what a real one would offer:
//! - polar: the Hall-sensor centre scan (`calibrate::scan` over [`crate::hall::HallScanner`] built with the
//!   true arm offsets, magnet placement errors, sensor noise); the measured `arm_zero_offset` and
//!   `arm_lateral_offset` go into the believed config.
//! - SCARA: a printed calibration pattern measured on the bed: the nozzle XY at commanded motor angles on the
//!   true machine plus 0.02 mm (1σ) measurement noise, fitted by `calibrate::scara::identify`; link lengths,
//!   offsets, joint zeros and the coupling go into the believed config.

use crate::error::SimulationError;
use crate::features::{CircleFeature, QuadFeature, find_circles, find_quads};
use crate::hall::{HallBedConfig, HallScanner};
use crate::machine::Machine;
use crate::replay::{Replay, ReplayOptions, replay};
use calibrate::scan::{ScanParams, scan_centre};
use calibrate::scara::{Measurement, ScaraGeometry, identify};
use config::MachineConfig;
use kinematics::{MachineParams, PolarParams, ScaraFrame, ScaraParams};
use motion::machine::MachineSetup;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::io::BufRead;

/// One simulation: the replay and the features measured on it.
#[derive(Debug, Clone)]
pub struct Simulation {
    pub replay: Replay,
    pub circles: Vec<CircleFeature>,
    pub quads: Vec<QuadFeature>,
}

/// Plan `gcode` on the believed config, run it on `actual`, measure features.
pub fn simulate(
    believed: &MachineConfig,
    actual: &Machine,
    gcode: impl BufRead,
    source_name: &str,
    options: &ReplayOptions,
) -> Result<Simulation, SimulationError> {
    let setup = MachineSetup::from_config(believed)?;
    let replay = replay(&setup, actual, gcode, source_name, options)?;
    let circles = find_circles(&replay.path);
    let quads = find_quads(&replay.path);
    Ok(Simulation {
        replay,
        circles,
        quads,
    })
}

/// One corrected parameter: believed before, measured, true value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrectedValue {
    pub name: String,
    pub believed: f64,
    pub measured: f64,
    pub actual: f64,
}

/// What the calibration measured and applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrectionSummary {
    pub method: String,
    pub values: Vec<CorrectedValue>,
    /// Fit quality: RMS residual (mm).
    pub rms: f64,
}

/// Calibrate on the true machine and return the believed config with the measured values applied.
pub fn calibrate_and_correct(
    believed: &MachineConfig,
    actual: &Machine,
    seed: u64,
) -> Result<(MachineConfig, CorrectionSummary), SimulationError> {
    let (params, summary) = match (&believed.params, actual.params()) {
        (MachineParams::Polar(b), MachineParams::Polar(a)) => {
            let (p, s) = correct_polar(b, a, actual, seed)?;
            (MachineParams::Polar(p), s)
        }
        (MachineParams::Scara(b), MachineParams::Scara(a)) => {
            let (p, s) = correct_scara(b, a, actual, seed)?;
            (MachineParams::Scara(p), s)
        }
        _ => {
            return Err(SimulationError::Calibration(
                "automatic calibration exists for polar and SCARA machines of the same kind".into(),
            ));
        }
    };
    let mut corrected = believed.clone();
    corrected.params = params;
    Ok((corrected, summary))
}

fn correct_polar(
    believed: &PolarParams,
    truth: &PolarParams,
    actual: &Machine,
    seed: u64,
) -> Result<(PolarParams, CorrectionSummary), SimulationError> {
    let motors = actual.motor_errors();
    let microstep_error = motors
        .iter()
        .take(2)
        .map(|m| m.microstep_error)
        .fold(0.0, f64::max);
    let hw_cfg = HallBedConfig {
        arm_zero_offset: truth.arm_zero_offset,
        arm_lateral_offset: truth.arm_lateral_offset,
        arm_steps_per_mm: 1.0 / truth.arm.step_distance,
        bed_steps_per_rev: TAU / truth.bed.step_distance,
        microsteps: motors.get(1).map_or(16, |m| m.microsteps),
        microstep_error,
        seed,
        ..HallBedConfig::default()
    };
    let mut hw =
        HallScanner::new(hw_cfg).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let result = scan_centre(&mut hw, &ScanParams::default())
        .map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let corrected = PolarParams {
        arm_zero_offset: result.arm_zero_offset,
        arm_lateral_offset: result.arm_lateral_offset,
        ..believed.clone()
    };
    let rms = result.ring.as_ref().map_or(0.0, |r| r.rms);
    let summary = CorrectionSummary {
        method: format!(
            "Hall-sensor centre scan: {} of {} magnet pairs, {} sensor reads, {:.0} s of machine time",
            result.pairs_used, result.magnet_count, result.sensor_reads, result.scan_time
        ),
        values: vec![
            value(
                "arm_zero_offset",
                believed.arm_zero_offset,
                result.arm_zero_offset,
                truth.arm_zero_offset,
            ),
            value(
                "arm_lateral_offset",
                believed.arm_lateral_offset,
                result.arm_lateral_offset,
                truth.arm_lateral_offset,
            ),
        ],
        rms,
    };
    Ok((corrected, summary))
}

fn value(name: &str, believed: f64, measured: f64, actual: f64) -> CorrectedValue {
    CorrectedValue {
        name: name.to_string(),
        believed,
        measured,
        actual,
    }
}

/// Motor angles of an 11×11 grid of joint poses (q1 90° ± 60°, q2 40°…130°) on the believed machine.
fn calibration_poses(g: &ScaraGeometry) -> Vec<(f64, f64)> {
    let mut poses = Vec::new();
    for i in 0..11 {
        let q1 = (-60.0 + 12.0 * f64::from(i)).to_radians() + 0.5 * PI;
        for k in 0..11 {
            let q2 = (40.0 + 9.0 * f64::from(k)).to_radians();
            poses.push((
                q1 + g.shoulder_zero,
                q2 + g.elbow_coupling * q1 + g.elbow_zero,
            ));
        }
    }
    poses
}

/// Standard deviation of the simulated pattern measurement (mm).
pub const PATTERN_NOISE: f64 = 0.02;

fn correct_scara(
    believed: &ScaraParams,
    truth: &ScaraParams,
    actual: &Machine,
    seed: u64,
) -> Result<(ScaraParams, CorrectionSummary), SimulationError> {
    if believed.frame != ScaraFrame::Standard || truth.frame != ScaraFrame::Standard {
        return Err(SimulationError::Calibration(
            "SCARA identification runs in the standard frame; X-SCARA frame machines are not supported".into(),
        ));
    }
    let start = ScaraGeometry::from(believed);
    let mut rng = StdRng::seed_from_u64(seed);
    let noise =
        Normal::new(0.0, PATTERN_NOISE).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let scale: Vec<f64> = actual
        .motor_errors()
        .iter()
        .map(|m| 1.0 + m.scale_error)
        .collect();
    let mut data = Vec::new();
    for (line, (a, b)) in calibration_poses(&start).into_iter().enumerate() {
        let motors = [a * scale[0], b * scale[1], 0.0];
        let p = actual
            .kinematics()
            .forward(&motors)
            .map_err(|e| SimulationError::Calibration(e.to_string()))?;
        data.push(Measurement {
            motor_a: a,
            motor_b: b,
            x: p[0] + noise.sample(&mut rng),
            y: p[1] + noise.sample(&mut rng),
            line: line + 1,
        });
    }
    let fit = identify(&data, &start).map_err(|e| SimulationError::Calibration(e.to_string()))?;
    let g = fit.geometry;
    let corrected = ScaraParams {
        link1_length: g.link1_length,
        link2_length: g.link2_length,
        offset_x: g.offset_x,
        offset_y: g.offset_y,
        shoulder_zero: g.shoulder_zero,
        elbow_zero: g.elbow_zero,
        elbow_coupling: g.elbow_coupling,
        ecr: None,
        ..believed.clone()
    };
    let t = ScaraGeometry::from(truth);
    let names = calibrate::scara::PARAM_NAMES;
    let values = names
        .iter()
        .zip(start.to_array())
        .zip(g.to_array())
        .zip(t.to_array())
        .map(|(((n, b), m), a)| value(n, b, m, a))
        .collect();
    let summary = CorrectionSummary {
        method: format!(
            "SCARA identification from {} measured pattern crosses ({PATTERN_NOISE} mm noise)",
            data.len()
        ),
        values,
        rms: fit.rms,
    };
    Ok((corrected, summary))
}

/// A test print: `layers` layers of circles (centre, radius; 128 segments each) and axis-aligned squares
/// (centre, side), starting with `SET_KINEMATIC_POSITION` at `start` when given.
pub fn test_print_gcode(
    circles: &[([f64; 2], f64)],
    squares: &[([f64; 2], f64)],
    layers: usize,
    start: Option<[f64; 3]>,
) -> String {
    let mut s = String::from("; jointspace sim: circle and square test print\n");
    if let Some([x, y, z]) = start {
        let _ = writeln!(s, "SET_KINEMATIC_POSITION X={x:.3} Y={y:.3} Z={z:.3}");
    }
    s.push_str("G90\nM83\n");
    const SEGMENTS: usize = 128;
    const E_PER_MM: f64 = 0.05;
    for layer in 0..layers {
        let z = 0.3 + 0.2 * layer as f64;
        let _ = writeln!(s, ";LAYER:{layer}\nG0 Z{z:.3} F600");
        for &([cx, cy], r) in circles {
            let _ = writeln!(s, "G0 X{:.4} Y{cy:.4} F6000", cx + r);
            let e = TAU * r / SEGMENTS as f64 * E_PER_MM;
            for k in 1..=SEGMENTS {
                let a = TAU * k as f64 / SEGMENTS as f64;
                let _ = writeln!(
                    s,
                    "G1 X{:.4} Y{:.4} E{e:.5} F1800",
                    cx + r * a.cos(),
                    cy + r * a.sin()
                );
            }
        }
        for &([cx, cy], side) in squares {
            let h = 0.5 * side;
            let corners = [
                [cx - h, cy - h],
                [cx + h, cy - h],
                [cx + h, cy + h],
                [cx - h, cy + h],
                [cx - h, cy - h],
            ];
            let _ = writeln!(s, "G0 X{:.4} Y{:.4} F6000", corners[0][0], corners[0][1]);
            for c in &corners[1..] {
                let _ = writeln!(
                    s,
                    "G1 X{:.4} Y{:.4} E{:.5} F1800",
                    c[0],
                    c[1],
                    side * E_PER_MM
                );
            }
        }
    }
    s
}

/// Klipper's example polar printer (arm endstop at 300 mm, 16000 bed steps/rev, 80 arm steps/mm).
pub const POLAR_CONFIG: &str = "
[stepper_bed]
step_pin: PF0
dir_pin: PF1
microsteps: 16
gear_ratio: 80:16

[stepper_arm]
step_pin: PF6
dir_pin: PF7
microsteps: 16
rotation_distance: 40
endstop_pin: ^PJ1
position_endstop: 300
position_max: 300

[stepper_z]
step_pin: PL3
dir_pin: PL1
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0.5
position_max: 200

[extruder]
step_pin: PA4
dir_pin: PA6
microsteps: 16
rotation_distance: 33.500
nozzle_diameter: 0.400
filament_diameter: 1.750
max_extrude_cross_section: 10

[printer]
kinematics: polar
max_velocity: 300
max_accel: 3000
max_z_velocity: 25
max_z_accel: 30
";

/// The FEKT-SCARA printer (100/100 mm arms, ECR 3, 60:20 joint gearing).
pub const SCARA_CONFIG: &str = "
[stepper_a]
step_pin: PF0
dir_pin: !PF1
microsteps: 16
gear_ratio: 60:20
endstop_pin: ^PE5
position_endstop: 0
position_min: -200
position_max: 200
homing_positive_dir: False

[stepper_b]
step_pin: PF6
dir_pin: PF7
microsteps: 16
gear_ratio: 60:20
endstop_pin: ^PJ1
position_endstop: 0
position_min: -200
position_max: 200
homing_positive_dir: False

[stepper_z]
step_pin: PL3
dir_pin: PL1
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0.5
position_max: 200

[extruder]
step_pin: PA4
dir_pin: PA6
microsteps: 16
rotation_distance: 33.500
nozzle_diameter: 0.400
filament_diameter: 1.750
max_extrude_cross_section: 10

[printer]
kinematics: scara
link1_length: 100.0
link2_length: 100.0
offset_x: 0
offset_y: 0
ecr: 3.0
base_protection_radius: 60.0
max_velocity: 300
max_accel: 3000
max_z_velocity: 50
max_z_accel: 30
";

/// Circles and squares of the polar demo print: one centred, the others off centre.
pub const POLAR_CIRCLES: [([f64; 2], f64); 2] = [([0.0, 0.0], 75.0), ([30.0, 20.0], 15.0)];
pub const POLAR_SQUARES: [([f64; 2], f64); 1] = [([-30.0, -25.0], 30.0)];
/// Squares of the SCARA demo print.
pub const SCARA_SQUARES: [([f64; 2], f64); 1] = [([-20.0, 170.0], 16.0)];

/// Circles used for the SCARA scenario (inside the FEKT workspace, away from the base and full reach).
pub const SCARA_CIRCLES: [([f64; 2], f64); 3] = [
    ([0.0, 130.0], 20.0),
    ([-60.0, 110.0], 12.0),
    ([55.0, 150.0], 10.0),
];

/// Believed and actual config of a scenario, from config text plus `[printer]` overrides for the actual one.
pub fn scenario_configs(
    text: &str,
    actual_printer_keys: &str,
) -> Result<(MachineConfig, MachineConfig), SimulationError> {
    let believed = MachineConfig::from_str(text, "believed.cfg")?;
    let actual_text = text.replace(
        "[printer]\n",
        &format!("[printer]\n{actual_printer_keys}\n"),
    );
    let actual = MachineConfig::from_str(&actual_text, "actual.cfg")?;
    Ok((believed, actual))
}

/// Before and after correction, with what the calibration applied.
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    pub before: Simulation,
    pub correction: CorrectionSummary,
    pub after: Simulation,
    pub corrected_config: MachineConfig,
}

/// simulate → calibrate → correct → simulate again. `open` gives a fresh reader of the G-code each time.
pub fn closed_loop<R: BufRead>(
    believed: &MachineConfig,
    actual: &Machine,
    mut open: impl FnMut() -> Result<R, SimulationError>,
    source_name: &str,
    options: &ReplayOptions,
    seed: u64,
) -> Result<ClosedLoop, SimulationError> {
    let before = simulate(believed, actual, open()?, source_name, options)?;
    let (corrected_config, correction) = calibrate_and_correct(believed, actual, seed)?;
    let after = simulate(&corrected_config, actual, open()?, source_name, options)?;
    Ok(ClosedLoop {
        before,
        correction,
        after,
        corrected_config,
    })
}

/// The polar demo: 1 mm sideways arm offset, a generated centred circle print (or `gcode` if given).
pub fn polar_lateral_offset_loop(gcode: Option<&[u8]>) -> Result<ClosedLoop, SimulationError> {
    let (believed, actual_cfg) = scenario_configs(POLAR_CONFIG, "arm_lateral_offset: 1.0")?;
    let actual = Machine::from_config(&actual_cfg)?;
    let generated;
    let text: &[u8] = match gcode {
        Some(t) => t,
        None => {
            generated = test_print_gcode(&POLAR_CIRCLES, &POLAR_SQUARES, 3, None);
            generated.as_bytes()
        }
    };
    closed_loop(
        &believed,
        &actual,
        || Ok(text),
        "polar-circles",
        &ReplayOptions::default(),
        7,
    )
}

/// The SCARA demo: built with ECR 3.2 and a 0.5 mm longer proximal arm, configured as ECR 3 / 100 mm.
pub fn scara_coupling_loop() -> Result<ClosedLoop, SimulationError> {
    let believed = MachineConfig::from_str(SCARA_CONFIG, "believed.cfg")?;
    let actual_text = SCARA_CONFIG
        .replace("link1_length: 100.0", "link1_length: 100.5")
        .replace("ecr: 3.0", "ecr: 3.2");
    let actual_cfg = MachineConfig::from_str(&actual_text, "actual.cfg")?;
    let actual = Machine::from_config(&actual_cfg)?;
    let text = test_print_gcode(&SCARA_CIRCLES, &SCARA_SQUARES, 2, Some([0.0, 130.0, 0.5]));
    closed_loop(
        &believed,
        &actual,
        || Ok(text.as_bytes()),
        "scara-circles",
        &ReplayOptions::default(),
        11,
    )
}

/// Run a closed-loop scenario and write its report into `out_dir`; returns the report.
pub fn write_closed_loop_report(
    out_dir: &std::path::Path,
    run: &ClosedLoop,
    believed_name: &str,
    actual_name: &str,
    gcode_name: &str,
) -> Result<crate::report::Report, SimulationError> {
    let report = crate::report::Report {
        believed_config: believed_name.to_string(),
        actual_config: actual_name.to_string(),
        gcode: gcode_name.to_string(),
        before: crate::report::RunReport::new(&run.before),
        correction: Some(run.correction.clone()),
        after: Some(crate::report::RunReport::new(&run.after)),
    };
    crate::report::write_report(out_dir, &report, &run.before, Some(&run.after))?;
    Ok(report)
}

/// The polar demo written to `out_dir` (1 mm sideways arm offset, generated circles): its report.
pub fn polar_lateral_offset_demo(
    out_dir: &std::path::Path,
) -> Result<crate::report::Report, SimulationError> {
    let run = polar_lateral_offset_loop(None)?;
    write_closed_loop_report(
        out_dir,
        &run,
        "polar (Klipper example)",
        "polar, arm 1 mm sideways",
        "generated circles",
    )
}

/// The SCARA demo written to `out_dir` (ECR 3.2 and +0.5 mm proximal arm built, ECR 3 configured).
pub fn scara_coupling_demo(
    out_dir: &std::path::Path,
) -> Result<crate::report::Report, SimulationError> {
    let run = scara_coupling_loop()?;
    write_closed_loop_report(
        out_dir,
        &run,
        "FEKT-SCARA (ECR 3, 100/100 mm)",
        "ECR 3.2, L1 100.5 mm",
        "generated circles",
    )
}
