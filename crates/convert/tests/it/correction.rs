//! Centre correction: the thesis' example, the sideways offset, and a print on a bed with a 1 mm offset
//! converted, verified against the real machine, and compared with the uncorrected conversion.

use std::f64::consts::FRAC_PI_4;

use convert::{
    AngleUnit, AxisMap, CentreCorrection, ConvertError, ConvertOptions, Target, read_commands,
    verify,
};

use crate::common::{convert_text, corpus_files, g1_lines, placement, round_trip, word};
use crate::machines;

fn radians() -> ConvertOptions {
    ConvertOptions {
        angle_unit: AngleUnit::Radians,
        ..crate::common::homed()
    }
}

/// The motors written for a single positioning move to `p`.
fn motors_for(
    map: &AxisMap,
    options: &ConvertOptions,
    p: [f64; 2],
) -> Result<[f64; 2], ConvertError> {
    let (out, _) = convert_text(map, options, format!("G0 X{} Y{}\n", p[0], p[1]).as_bytes())?;
    let line = out
        .lines()
        .find(|l| l.starts_with("G0"))
        .expect("a G0 line");
    let (_, words) = crate::common::parse_line(line).expect("parsable");
    Ok([word(&words, 'X').expect("X"), word(&words, 'Y').expect("Y")])
}

#[test]
fn thesis_example_recentres_the_part() {
    // Thesis: R_old = 5, φ_old = π/4, centre displaced by d = (2, 1) → R ≈ 2.97, φ ≈ 1.03 rad: the polar
    // coordinates of p − d, the part shifted (`convert --centre-shift`); its 2.97 comes from rounding 5·cos 45°
    // to 3.54 (the exact value is 2.964). Not the arm-offset model (`--centre-offset`), which for the same
    // d gives R 2.899 (see `the_part_shift_and_the_arm_offsets_are_different_models`).
    let p = [5.0 * FRAC_PI_4.cos(), 5.0 * FRAC_PI_4.sin()];
    let options = ConvertOptions {
        translate: [-2.0, -1.0],
        ..radians()
    };
    let map = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("map");
    let [r, phi] = motors_for(&map, &options, p).expect("reachable");
    assert!((r - 2.97).abs() < 0.01, "R = {r}");
    assert!((phi - 1.03).abs() < 0.01, "φ = {phi}");
    let exact = ((p[0] - 2.0).powi(2) + (p[1] - 1.0).powi(2)).sqrt();
    assert!((r - exact).abs() < 1e-4);
}

#[test]
fn sideways_offset_follows_the_general_formula() {
    // r = −dx + √(|p|² − dy²); the thesis' bed rotation φ_bed = atan2(dy, dx + r) − atan2(p) is minus the
    // bed motor reading (Klipper's sign).
    let (dx, dy) = (2.0, 1.0);
    let correction = CentreCorrection {
        arm_zero_offset: dx,
        arm_lateral_offset: dy,
    };
    let map = correction
        .motor_map(&machines::polar_params(), Target::Cylindrical)
        .expect("map");
    let p = [5.0 * FRAC_PI_4.cos(), 5.0 * FRAC_PI_4.sin()];
    let [r, bed] = motors_for(&map, &radians(), p).expect("reachable");
    let r_expected = -dx + (25.0f64 - dy * dy).sqrt();
    let phi_bed = dy.atan2(dx + r_expected) - p[1].atan2(p[0]);
    assert!((r - r_expected).abs() < 1e-4, "{r} vs {r_expected}");
    assert!((bed + phi_bed).abs() < 1e-6, "{bed} vs {}", -phi_bed);
    // Inside |dy| nothing passes under the nozzle: an error naming the line.
    match convert_text(&map, &radians(), b"G0 X5 Y5\nG1 X0.2 Y0.3 F600\n") {
        Err(ConvertError::Unreachable { span, .. }) => assert_eq!(span.line, 2),
        other => panic!("expected an unreachable error, got {other:?}"),
    }
}

#[test]
fn a_bed_with_a_one_millimetre_offset_is_corrected_and_verified() {
    let Some((name, text)) = corpus_files()
        .into_iter()
        .find(|(n, _)| n.contains("mini-cube"))
    else {
        return;
    };
    let commands = read_commands(&text[..], &name).expect("parses");
    // Part away from the unreachable core (|p| < dy), 60 mm from the centre.
    let (scale_xy, translate) = placement(&commands, [60.0, 0.0], 40.0);
    let options = ConvertOptions {
        scale_xy,
        translate,
        ..crate::common::homed()
    };
    let correction = CentreCorrection {
        arm_zero_offset: 1.0,
        arm_lateral_offset: 0.6,
    };
    let nominal = machines::polar_params();
    let real = correction
        .motor_map(&nominal, Target::Cylindrical)
        .expect("map");
    let ideal = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("map");

    // Motor-space output for the real machine, replayed on the real machine.
    let (_, _, corrected) = round_trip(&real, &options, &text);
    assert!(corrected.max_deviation <= 0.005, "{corrected:?}");
    assert!((corrected.extrusion_out - corrected.extrusion_in).abs() < 1e-6);

    // The uncorrected conversion, run on the real machine, misses by about the offset.
    let (plain, _) = convert_text(&ideal, &options, &text).expect("converts");
    let uncorrected = verify(&real, &options, &commands, plain.as_bytes()).expect("readable");
    assert!(uncorrected.max_deviation > 0.9, "{uncorrected:?}");

    // Cartesian output for a firmware with the ideal model: the real nozzle lands on the path.
    let cartesian = correction.cartesian_map(&nominal).expect("map");
    let (out, _, report) = round_trip(&cartesian, &options, &text);
    assert!(report.max_deviation <= 0.005, "{report:?}");
    assert_eq!(report.unmatched, 0);
    // The rewritten XY really differs from the input's by about the offset.
    let last = g1_lines(&out)
        .into_iter()
        .rev()
        .find(|l| word(l, 'X').is_some())
        .expect("moves");
    assert!(last.iter().all(|(_, v)| v.is_finite()));
    println!(
        "1 mm offset: corrected max {:.4} mm (motor output), {:.4} mm (Cartesian output); uncorrected {:.3} mm",
        corrected.max_deviation, report.max_deviation, uncorrected.max_deviation
    );
}

#[test]
fn the_part_shift_and_the_arm_offsets_are_different_models() {
    // Even with no sideways offset: the shifted part is |p − d| from the axis; an arm whose zero is dx along it
    // reaches |p| at r = |p| − dx.
    let p = [5.0 * FRAC_PI_4.cos(), 5.0 * FRAC_PI_4.sin()];
    let ideal = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("map");
    for (dx, dy) in [(2.0, 0.0), (2.0, 1.0)] {
        let shifted = ConvertOptions {
            translate: [-dx, -dy],
            ..radians()
        };
        let [r_shift, _] = motors_for(&ideal, &shifted, p).expect("reachable");
        let arm = CentreCorrection {
            arm_zero_offset: dx,
            arm_lateral_offset: dy,
        }
        .motor_map(&machines::polar_params(), Target::Cylindrical)
        .expect("map");
        let [r_arm, _] = motors_for(&arm, &radians(), p).expect("reachable");
        println!("d = ({dx}, {dy}): part shifted R {r_shift:.4}, arm offsets R {r_arm:.4}");
        assert!((r_shift - (p[0] - dx).hypot(p[1] - dy)).abs() < 1e-4);
        assert!((r_arm - (-dx + (25.0f64 - dy * dy).sqrt())).abs() < 1e-4);
        assert!((r_shift - r_arm).abs() > 0.05);
    }
}
