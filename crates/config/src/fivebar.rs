//! Five-bar (parallel) SCARA: `[printer] kinematics: fivebar` with one value per key, Klipper style. Angles in the
//! file are degrees. RepRapFirmware's `M669 K9` maps as: `X` → `left_base_x`, `right_base_x`; `Y` → `left_base_y`,
//! `right_base_y`; `P` → `left_proximal_length`, `right_proximal_length`; `D` (two values) → `left_distal_length`,
//! `right_distal_length`; `L` workmode 1–4 → `left_arm_turn`/`right_arm_turn` ccw/ccw, cw/ccw, ccw/cw, cw/cw.

use kinematics::{FivebarArm, FivebarParams, Turn};

use crate::document::Section;
use crate::error::ConfigError;
use crate::stepper::StepperConfig;
use crate::value::Bounds;

const TURNS: [(&str, Turn); 2] = [("ccw", Turn::Ccw), ("cw", Turn::Cw)];

/// The machine from `[printer]`'s keys and its steppers (`stepper_left`, `stepper_right`, `stepper_z`, read by the
/// caller).
pub(crate) fn read_fivebar(
    printer: &Section,
    [left, right, z]: &[StepperConfig; 3],
) -> Result<FivebarParams, ConfigError> {
    let arm = |side: &str, stepper: &StepperConfig| -> Result<FivebarArm, ConfigError> {
        let positive = Bounds::NONE.above(0.0);
        Ok(FivebarArm {
            stepper: stepper.params(),
            base: [
                printer.get_f64(&format!("{side}_base_x"), Bounds::NONE)?,
                printer.get_f64_or(&format!("{side}_base_y"), 0.0, Bounds::NONE)?,
            ],
            proximal: printer.get_f64(&format!("{side}_proximal_length"), positive)?,
            distal: printer.get_f64(&format!("{side}_distal_length"), positive)?,
            turn: printer.get_choice(&format!("{side}_arm_turn"), &TURNS)?,
            zero: printer
                .get_f64_or(&format!("{side}_zero"), 0.0, Bounds::NONE)?
                .to_radians(),
        })
    };
    let (left, right) = (arm("left", left)?, arm("right", right)?);
    if left.base == right.base {
        return Err(printer.error_at(
            "right_base_x",
            "the base joints must be at different places",
        ));
    }
    Ok(FivebarParams {
        left,
        right,
        z: z.params(),
        distal_turn: printer.get_choice_or("distal_turn", &TURNS, Turn::Cw)?,
        singularity_margin: printer.get_f64_or(
            "singularity_margin",
            0.05,
            Bounds::NONE.min(0.0).below(1.0),
        )?,
    })
}
