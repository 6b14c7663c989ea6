//! The closed loop on the virtual printer: simulate → calibrate → correct → simulate again, plus the
//! demo machines (the bundled examples, set up as the scenarios need them) and a generator of circle test
//! prints. How the printer is calibrated: the
//! `correction` module; one simulation: the `simulation` module (both re-exported here).

use crate::error::SimulationError;
use crate::machine::Machine;
use crate::replay::ReplayOptions;
use crate::report::{Report, RunReport, write_report};
use config::MachineConfig;
use std::io::BufRead;

pub use crate::correction::{
    CorrectedValue, CorrectionSummary, PATTERN_NOISE, Rejected, calibrate_and_correct,
};
pub use crate::simulation::{Simulation, simulate};
pub use crate::testprint::test_print_gcode;

/// The bundled example polar printer (`examples/machines/polar.cfg`, as `jointspace demo` runs it).
pub const POLAR_EXAMPLE: &str = include_str!("../../../examples/machines/polar.cfg");
/// The bundled example SCARA printer (`examples/machines/scara.cfg`): FEKT-SCARA's 100/100 mm arms, ECR 3.
pub const SCARA_EXAMPLE: &str = include_str!("../../../examples/machines/scara.cfg");

/// The bundled example five-bar (`examples/machines/fivebar.cfg`): bases 100 mm apart, 150/200 mm links, homed at
/// its endstops with the nozzle at (0, −37.6).
pub const FIVEBAR_EXAMPLE: &str = include_str!("../../../examples/machines/fivebar.cfg");

/// `text` with `keys` (`key: value` lines) set in `[section]`: a second `[section]` at the end, which the
/// reader merges into the first as Klipper does, its keys winning.
pub fn with_keys(text: &str, section: &str, keys: &str) -> String {
    format!("{text}\n[{section}]\n{keys}\n")
}

/// The polar scenarios' machine: the bundled example set up as Klipper's own polar example, on which the
/// scenarios' numbers were taken: the arm homes at 300 mm (a print starts with a travel from there) and Z
/// accelerates at 30 mm/s². The corpus prints the tests replay need more room: 10 mm² of extrusion
/// cross-section, Z up to 200 mm (the spiral vase is 170 mm tall).
pub fn polar_config() -> String {
    let text = with_keys(
        POLAR_EXAMPLE,
        "stepper_arm",
        "position_endstop: 300\nposition_max: 300",
    );
    let text = with_keys(&text, "stepper_z", "position_max: 200");
    let text = with_keys(&text, "extruder", "max_extrude_cross_section: 10");
    with_keys(&text, "printer", "max_z_accel: 30")
}

/// The SCARA scenarios' machine: the bundled example set up as the FEKT-SCARA printer the scenarios' numbers
/// were taken on: both joints home at 0° from above (where the replay starts, before a print's
/// `SET_KINEMATIC_POSITION`), and it accelerates at 3000 mm/s², Z at 30 mm/s².
pub fn scara_config() -> String {
    let homed_at_zero = "position_endstop: 0\nhoming_positive_dir: False";
    let text = with_keys(SCARA_EXAMPLE, "stepper_a", homed_at_zero);
    let text = with_keys(&text, "stepper_b", homed_at_zero);
    with_keys(&text, "printer", "max_accel: 3000\nmax_z_accel: 30")
}

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

/// Circles and squares of the five-bar demo print, inside the example's printing area away from its special poses.
pub const FIVEBAR_CIRCLES: [([f64; 2], f64); 3] = [
    ([0.0, 40.0], 20.0),
    ([-45.0, 80.0], 12.0),
    ([45.0, 10.0], 10.0),
];
pub const FIVEBAR_SQUARES: [([f64; 2], f64); 1] = [([-30.0, 0.0], 16.0)];

/// Believed and actual config of a scenario, from config text plus `[printer]` keys that set the actual one
/// apart (its assembly errors).
pub fn scenario_configs(
    text: &str,
    actual_printer_keys: &str,
) -> Result<(MachineConfig, MachineConfig), SimulationError> {
    let believed = MachineConfig::from_str(text, "believed.cfg")?;
    let actual_text = with_keys(text, "printer", actual_printer_keys);
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
    let (believed, actual_cfg) = scenario_configs(&polar_config(), "arm_lateral_offset: 1.0")?;
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
    let (believed, actual_cfg) =
        scenario_configs(&scara_config(), "link1_length: 100.5\necr: 3.2")?;
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

/// The five-bar demo's assembly errors: the left base joint 0.3 mm further left, the right proximal link 0.4 mm
/// long, the left motor's zero 0.5° off.
pub const FIVEBAR_ERRORS: &str = "left_base_x: -50.3\nright_proximal_length: 150.4\nleft_zero: 0.5";

/// The five-bar demo: the example built with [`FIVEBAR_ERRORS`], homed, printing the generated circles.
pub fn fivebar_loop() -> Result<ClosedLoop, SimulationError> {
    let (believed, actual_cfg) = scenario_configs(FIVEBAR_EXAMPLE, FIVEBAR_ERRORS)?;
    let actual = Machine::from_config(&actual_cfg)?;
    let text = format!(
        "G28\n{}",
        test_print_gcode(&FIVEBAR_CIRCLES, &FIVEBAR_SQUARES, 2, None)
    );
    closed_loop(
        &believed,
        &actual,
        || Ok(text.as_bytes()),
        "fivebar-circles",
        &ReplayOptions::default(),
        13,
    )
}

/// Run a closed-loop scenario and write its report into `out_dir`; returns the report.
pub fn write_closed_loop_report(
    out_dir: &std::path::Path,
    run: &ClosedLoop,
    believed_name: &str,
    actual_name: &str,
    gcode_name: &str,
) -> Result<Report, SimulationError> {
    let report = Report {
        believed_config: believed_name.to_string(),
        actual_config: actual_name.to_string(),
        gcode: gcode_name.to_string(),
        before: RunReport::new(&run.before),
        correction: Some(run.correction.clone()),
        after: Some(RunReport::new(&run.after)),
        after_missing: None,
    };
    write_report(out_dir, &report, &run.before, Some(&run.after))?;
    Ok(report)
}

/// The polar demo written to `out_dir` (1 mm sideways arm offset, generated circles): its report.
pub fn polar_lateral_offset_demo(out_dir: &std::path::Path) -> Result<Report, SimulationError> {
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
pub fn scara_coupling_demo(out_dir: &std::path::Path) -> Result<Report, SimulationError> {
    let run = scara_coupling_loop()?;
    write_closed_loop_report(
        out_dir,
        &run,
        "FEKT-SCARA (ECR 3, 100/100 mm)",
        "ECR 3.2, L1 100.5 mm",
        "generated circles",
    )
}

/// The five-bar demo written to `out_dir` (left base 0.3 mm off, right proximal link 0.4 mm long, left zero 0.5°).
pub fn fivebar_demo(out_dir: &std::path::Path) -> Result<Report, SimulationError> {
    let run = fivebar_loop()?;
    write_closed_loop_report(
        out_dir,
        &run,
        "five-bar example (150/200 mm links)",
        "left base −50.3, right proximal 150.4 mm, left zero 0.5°",
        "generated circles",
    )
}
