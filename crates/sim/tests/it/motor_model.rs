//! The motor model against closed forms: a wrong step distance scales the arm's travel from its endstop,
//! the microstep error of one motor reaches its configured amplitude, backlash makes reversals lag.

use crate::common::{polar_pair, polar_print};
use sim::scenario::simulate;
use sim::{Machine, ReplayOptions};

#[test]
fn arm_step_scale_error_shrinks_circles_as_predicted() {
    // The arm homes at 300 mm; with 0.2 % too much travel per step a reading r is really 300 + (r−300)·1.002.
    let (believed, actual_cfg) = polar_pair("", "step_scale_error_stepper_arm: 0.002");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let s = simulate(
        &believed,
        &actual,
        polar_print().as_bytes(),
        "p",
        &ReplayOptions::default(),
    )
    .expect("sim");
    let centred = s
        .circles
        .iter()
        .find(|c| c.intended_centre[0].hypot(c.intended_centre[1]) < 0.1)
        .expect("centred circle");
    let r = 0.5 * centred.intended_diameter;
    let expected = 2.0 * (300.0 + (r - 300.0) * 1.002);
    println!(
        "scale error: Ø {:.4} → {:.4} (closed form {expected:.4})",
        centred.intended_diameter, centred.actual_diameter
    );
    assert!(
        (centred.actual_diameter - expected).abs() < 0.005,
        "{centred:?}"
    );
}

#[test]
fn arm_microstep_error_reaches_its_amplitude() {
    // 5 % of a full arm step (16 × 0.0125 mm = 0.2 mm): 0.01 mm, along the arm only.
    let (believed, actual_cfg) = polar_pair("", "microstep_error_stepper_arm: 0.05");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let s = simulate(
        &believed,
        &actual,
        polar_print().as_bytes(),
        "p",
        &ReplayOptions::default(),
    )
    .expect("sim");
    let max = s.replay.all.max_model_error;
    println!("arm microstep error 5 %: max model error {max:.5} mm");
    assert!(max <= 0.01 + 1e-12 && max > 0.0099, "{max}");
}

#[test]
fn thesis_scale_microstep_error_stays_below_0_02_degrees() {
    // 1 % of a 1.8° full step on the bed motor: 0.018° at the motor; the bed turns 5× slower (80:16).
    let (believed, actual_cfg) = polar_pair("", "microstep_error_stepper_bed: 0.01");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let s = simulate(
        &believed,
        &actual,
        polar_print().as_bytes(),
        "p",
        &ReplayOptions::default(),
    )
    .expect("sim");
    // Largest radius printed: 75 mm circle. Bed angle error ≤ 0.01 × 2π/1000 rad.
    let bound = 0.01 * std::f64::consts::TAU / 1000.0 * 75.0;
    let max = s.replay.deposited.max_model_error;
    println!("bed microstep error 1 %: max {max:.5} mm (bound {bound:.5} mm)");
    assert!(max <= bound + 1e-9 && max > 0.9 * bound);
}

#[test]
fn bed_backlash_shifts_the_print_by_the_dead_band() {
    // 0.1° dead band on the bed: the output trails the motor by half of it in the direction of motion.
    let (believed, actual_cfg) = polar_pair("", "backlash_stepper_bed: 0.1");
    let actual = Machine::from_config(&actual_cfg).expect("machine");
    let s = simulate(
        &believed,
        &actual,
        polar_print().as_bytes(),
        "p",
        &ReplayOptions::default(),
    )
    .expect("sim");
    let half = 0.05f64.to_radians();
    let max = s.replay.deposited.max_model_error;
    // At most half the dead band at the largest radius (75 mm), and it is reached on the big circle.
    let bound = 2.0 * 75.0 * (0.5 * half).sin();
    println!("bed backlash 0.1°: max model error {max:.4} mm (bound {bound:.4})");
    assert!(max <= bound + 1e-9 && max > 0.9 * bound, "{max} vs {bound}");
}
