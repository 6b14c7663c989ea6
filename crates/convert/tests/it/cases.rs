//! Closed-form cases: the polar centre, unwrapping, exact extrusion, feed conventions, letters and units,
//! pass-through, homing, errors with line numbers, and a property test on random lines.

use std::f64::consts::PI;

use convert::{
    AngleUnit, AxisMap, ConvertError, ConvertOptions, Extrusion, FeedMode, Segmentation, Target,
    read_commands, verify,
};
use proptest::prelude::*;

use crate::common::{convert_text, g1_lines, parse_line, round_trip, word};
use crate::machines;

fn polar_map() -> AxisMap {
    AxisMap::motors(machines::polar(), Target::Cylindrical).expect("polar map")
}

fn scara_map() -> AxisMap {
    AxisMap::motors(machines::scara(), Target::Joints).expect("SCARA map")
}

#[test]
fn a_line_through_the_centre_turns_the_bed_in_place() {
    let text = b"G0 X-10 Y0\nG1 X10 Y0 E2 F1200\n";
    let (out, stats, report) = round_trip(&polar_map(), &crate::common::homed(), text);
    let lines = g1_lines(&out);
    // In: radial to the centre at 180°; flip by half a turn without E; out: radial at the new angle.
    assert_eq!(lines.len(), 3, "{out}");
    assert_eq!(stats.flips, 1);
    let flip = &lines[1];
    assert_eq!(word(flip, 'E'), None);
    assert!(word(flip, 'X').unwrap_or(0.0).abs() < 1e-3);
    let turn = (word(flip, 'Y').expect("flip turns the bed") - 180.0).abs();
    assert!((turn - 180.0).abs() < 1e-9, "turn {turn}");
    let e: f64 = lines.iter().filter_map(|l| word(l, 'E')).sum();
    assert!((e - 2.0).abs() < 1e-12);
    assert!(report.max_deviation < 1e-6, "{report:?}");
    assert!((report.time_out - report.flip_time - 20.0 / 20.0).abs() < 1e-6);
}

#[test]
fn lines_grazing_the_centre_stay_within_tolerance() {
    // Within the machine's centre tolerance (half an arm step, at most 5 µm: what the planner plans through
    // the centre too) the line is converted through the centre (a flip); beyond it the bed swings by half a turn
    // within a few of these, cut finely there.
    let tolerance = polar_map().centre().expect("a polar centre").tolerance;
    assert!(tolerance > 1e-4 && tolerance <= 0.005, "{tolerance}");
    for miss in [1e-8, 1e-4, 0.99 * tolerance, 1.01 * tolerance, 0.01] {
        let text = format!("G0 X-20 Y{miss}\nG1 X20 Y{miss} E1 F1800\n");
        let (_, stats, report) = round_trip(&polar_map(), &crate::common::homed(), text.as_bytes());
        assert_eq!(report.unmatched, 0);
        assert!(
            report.max_deviation <= Segmentation::DEFAULT_TOLERANCE,
            "{miss}: {report:?}"
        );
        assert_eq!(stats.flips, u64::from(miss <= tolerance), "{miss}");
    }
}

#[test]
fn angles_unwrap_over_several_turns() {
    let mut text = String::from("G0 X10 Y0\nG1 F3000\n");
    for _ in 0..3 {
        text.push_str("G1 X0 Y10\nG1 X-10 Y0\nG1 X0 Y-10\nG1 X10 Y0\n");
    }
    let (out, _, report) = round_trip(&polar_map(), &crate::common::homed(), text.as_bytes());
    let angles: Vec<f64> = g1_lines(&out).iter().filter_map(|l| word(l, 'Y')).collect();
    let largest_step = angles
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    assert!(largest_step <= 45.0 + 1e-9, "jump of {largest_step}°");
    assert!((angles.last().copied().unwrap_or(0.0) - 3.0 * 360.0).abs() < 1e-6);
    assert!(report.max_deviation <= Segmentation::DEFAULT_TOLERANCE);
}

#[test]
fn a_circle_about_the_centre_is_straight_in_motor_space() {
    // Radius constant, angle linear: only the 45° limit per segment cuts it.
    let (out, stats, report) = round_trip(
        &polar_map(),
        &crate::common::homed(),
        b"G0 X20 Y0\nG3 X20 Y0 I-20 J0 F600\n",
    );
    assert_eq!(stats.segments, 8, "{out}");
    for line in g1_lines(&out) {
        assert!((word(&line, 'X').unwrap_or(20.0) - 20.0).abs() < 1e-9);
    }
    assert!(report.max_deviation < 1e-6);
    assert!((report.time_out - 2.0 * PI * 20.0 / 10.0).abs() < 1e-6);
}

/// E written by each G1 line, per mode.
fn written_extrusion(out: &str, relative: bool) -> f64 {
    let mut total = 0.0;
    let mut e = 0.0;
    for (head, words) in out.lines().filter_map(parse_line) {
        match (head.as_str(), word(&words, 'E')) {
            ("G92", Some(v)) => e = v,
            ("G1", Some(v)) if relative => total += v,
            ("G1", Some(v)) => {
                total += v - e;
                e = v;
            }
            _ => {}
        }
    }
    total
}

#[test]
fn extrusion_is_distributed_exactly() {
    // One long move close to the centre (many segments) with an awkward E, then a G92 reset.
    let text = b"M83\nG0 X-40 Y0.5\nG1 X40 Y0.7 E1.23457 F1800\nG92 E0\nG1 X40 Y30 E0.33333\n";
    for extrusion in [Extrusion::Relative, Extrusion::Absolute] {
        let options = ConvertOptions {
            extrusion,
            ..crate::common::homed()
        };
        let (out, stats) = convert_text(&polar_map(), &options, text).expect("converts");
        assert!(stats.segments > 20, "{stats:?}");
        let total = written_extrusion(&out, extrusion == Extrusion::Relative);
        assert!(
            (total - (1.23457 + 0.33333)).abs() < 1e-9,
            "{extrusion:?}: {total}"
        );
        assert!(out.contains("G92 E0"), "G92 E kept");
    }
}

#[test]
fn inverse_time_feed_gives_each_segment_its_cartesian_time() {
    let options = ConvertOptions {
        feed: FeedMode::InverseTime,
        ..crate::common::homed()
    };
    let text = b"G0 X-30 Y2\nG1 X30 Y5 E3 F1200\n";
    let (out, _) = convert_text(&polar_map(), &options, text).expect("converts");
    let minutes: f64 = g1_lines(&out)
        .iter()
        .map(|l| 1.0 / word(l, 'F').expect("every line has F"))
        .sum();
    let length = 60f64.hypot(3.0);
    assert!((minutes * 60.0 - length / 20.0).abs() < 1e-6, "{minutes}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines.iter().position(|l| *l == "G93") < lines.iter().position(|l| l.starts_with("G1"))
    );
    assert_eq!(lines.last(), Some(&"G94"));
}

#[test]
fn motor_space_feed_gives_each_segment_its_cartesian_time() {
    let text = b"G0 X-30 Y2\nG1 X30 Y5 Z0.2 E3 F1200\n";
    let (out, _) = convert_text(&polar_map(), &crate::common::homed(), text).expect("converts");
    let (mut previous, mut seconds) = (
        [
            30f64.hypot(2.0),
            180.0 - (2f64 / 30.0).atan().to_degrees(),
            0.0,
        ],
        0.0,
    );
    for line in g1_lines(&out) {
        let next = [
            word(&line, 'X').unwrap_or(previous[0]),
            word(&line, 'Y').unwrap_or(previous[1]),
            word(&line, 'Z').unwrap_or(previous[2]),
        ];
        let motor_length = (0..3)
            .map(|i| (next[i] - previous[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        seconds += motor_length / word(&line, 'F').expect("F") * 60.0;
        previous = next;
    }
    let length = (60f64.powi(2) + 9.0 + 0.04).sqrt();
    assert!((seconds - length / 20.0).abs() < 1e-5, "{seconds}");
}

#[test]
fn letters_and_radians_follow_the_options() {
    let options = ConvertOptions {
        axis_letters: Some(['R', 'T']),
        angle_unit: AngleUnit::Radians,
        ..crate::common::homed()
    };
    let (out, _) = convert_text(
        &polar_map(),
        &options,
        b"G28 X Y\nG0 X3 Y4\nG1 X0 Y5 F600\n",
    )
    .expect("converts");
    assert!(out.contains("G28 R T"), "{out}");
    let last = g1_lines(&out).pop().expect("a G1");
    assert!((word(&last, 'R').expect("R") - 5.0).abs() < 1e-4);
    assert!((word(&last, 'T').expect("T") - PI / 2.0).abs() < 1e-6);
}

#[test]
fn joints_on_a_polar_machine_are_its_raw_motors() {
    // Motor order of the polar machine: bed angle, then arm.
    let map = AxisMap::motors(machines::polar(), Target::Joints).expect("map");
    let (out, _) = convert_text(&map, &crate::common::homed(), b"G0 X0 Y7\n").expect("converts");
    let line = out.lines().find(|l| l.starts_with("G0")).expect("G0");
    assert!(line.starts_with("G0 X90 Y7 "), "{line}");
}

#[test]
fn other_lines_pass_through_unchanged() {
    let text = "; generated by test\nM104 S215 ; hot\n;LAYER_CHANGE\n;Z:0.2\nG0 X10 Y10\nSET_FAN_SPEED FAN=a SPEED=0.5\nG4 P100\n";
    let (out, _) =
        convert_text(&polar_map(), &crate::common::homed(), text.as_bytes()).expect("converts");
    let mut lines = out.lines();
    for expected in [
        "; generated by test",
        "M104 S215 ; hot",
        ";LAYER_CHANGE",
        ";Z:0.2",
        "SET_FAN_SPEED FAN=a SPEED=0.5",
        "G4 P100",
    ] {
        assert!(
            lines.any(|l| l == expected),
            "missing {expected:?} in\n{out}"
        );
    }
}

#[test]
fn homing_makes_the_next_move_a_positioning_move() {
    let (out, stats) = convert_text(
        &polar_map(),
        &crate::common::homed(),
        b"G0 X5 Y5\nG28\nG1 X10 Y0 F600\nG1 X20 Y0\n",
    )
    .expect("converts");
    assert_eq!(stats.positioning_moves, 2);
    let heads: Vec<String> = out
        .lines()
        .filter_map(parse_line)
        .map(|(h, _)| h)
        .filter(|h| h.starts_with('G'))
        .collect();
    assert_eq!(heads, ["G90", "G0", "G28", "G0", "G1"]);
}

#[test]
fn moves_before_any_xy_do_not_move_the_arm() {
    let text = b"G28\nG1 E2 F300\nG1 Z5 F600\nG1 X10 Y0\nG1 X20 Y0 E3\n";
    let (out, _, report) = round_trip(&polar_map(), &crate::common::homed(), text);
    let motion: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("G0") || l.starts_with("G1"))
        .collect();
    assert_eq!(motion[..2], ["G1 E2 F300", "G0 Z5"], "{out}");
    assert!(motion[2].starts_with("G0 X10 Y0"), "{out}");
    assert_eq!(report.unmatched, 0);
    assert!(
        (report.time_in - (2.0 / 5.0 + 10.0 / 10.0)).abs() < 1e-9,
        "{report:?}"
    );
    assert!(
        (report.time_out - report.time_in).abs() < 1e-6,
        "{report:?}"
    );
    assert!((report.extrusion_out - 3.0).abs() < 1e-12);
}

fn error_of(map: &AxisMap, text: &[u8]) -> ConvertError {
    convert_text(map, &crate::common::homed(), text).expect_err("conversion fails")
}

#[test]
fn unreachable_moves_are_errors_with_line_and_column() {
    // SCARA: a straight move from (0, 130) to (0, 10) enters the 60 mm base protection radius.
    match error_of(&scara_map(), b"G0 X0 Y130\n\n  G1 X0 Y10 F600\n") {
        ConvertError::Unreachable { span, .. } => assert_eq!((span.line, span.column), (3, 3)),
        e => panic!("unexpected {e}"),
    }
    match error_of(&polar_map(), b"G0 X1 Y1\nSET_KINEMATIC_POSITION X=0 Y=0\n") {
        ConvertError::Unsupported { span, .. } => assert_eq!(span.line, 2),
        e => panic!("unexpected {e}"),
    }
}

#[test]
fn options_are_validated() {
    let bad = ConvertOptions {
        segmentation: Segmentation::Adaptive { tolerance: -1.0 },
        ..crate::common::homed()
    };
    assert!(convert::Converter::new(polar_map(), bad, Vec::new()).is_err());
    let too_fine = ConvertOptions {
        segmentation: Segmentation::Adaptive { tolerance: 1e-5 },
        ..crate::common::homed()
    };
    assert!(
        convert::Converter::new(polar_map(), too_fine, Vec::new()).is_err(),
        "below the rounding of 4 decimals"
    );
    assert!(
        AxisMap::motors(machines::scara(), Target::Cylindrical).is_err(),
        "a SCARA has no radius axis"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Any line in a 300 mm polar workspace, through or near the centre: within tolerance, E exact,
    /// Cartesian time kept.
    #[test]
    fn random_polar_lines_stay_within_tolerance(
        a in (-200.0f64..200.0, -200.0f64..200.0),
        b in (-200.0f64..200.0, -200.0f64..200.0),
        e in 0.0f64..5.0,
        feed in 5.0f64..200.0,
    ) {
        let text = format!("G0 X{:.3} Y{:.3}\nG1 X{:.3} Y{:.3} E{:.5} F{:.1}\n", a.0, a.1, b.0, b.1, e, feed * 60.0);
        let options = crate::common::homed();
        let map = polar_map();
        let (out, _) = convert_text(&map, &options, text.as_bytes()).expect("converts");
        let commands = read_commands(text.as_bytes(), "p").expect("parses");
        let r = verify(&map, &options, &commands, out.as_bytes()).expect("readable");
        prop_assert_eq!(r.unmatched, 0);
        prop_assert!(r.max_deviation <= Segmentation::DEFAULT_TOLERANCE, "{:?}", r);
        prop_assert!((r.extrusion_out - r.extrusion_in).abs() < 1e-9);
        prop_assert!((r.time_out - r.flip_time - r.time_in).abs() <= 1e-6 * r.time_in.max(1.0));
    }

    /// Any line inside the SCARA's comfortable annulus around (0, 130).
    #[test]
    fn random_scara_lines_stay_within_tolerance(
        a in (0.0f64..std::f64::consts::TAU, 0.0f64..60.0),
        b in (0.0f64..std::f64::consts::TAU, 0.0f64..60.0),
    ) {
        let point = |(angle, r): (f64, f64)| (r * angle.cos(), 130.0 + r * angle.sin());
        let (p, q) = (point(a), point(b));
        let text = format!("G0 X{:.3} Y{:.3}\nG1 X{:.3} Y{:.3} E1 F3000\n", p.0, p.1, q.0, q.1);
        let map = scara_map();
        let options = crate::common::homed();
        match convert_text(&map, &options, text.as_bytes()) {
            Ok((out, _)) => {
                let commands = read_commands(text.as_bytes(), "p").expect("parses");
                let r = verify(&map, &options, &commands, out.as_bytes()).expect("readable");
                prop_assert!(r.max_deviation <= Segmentation::DEFAULT_TOLERANCE, "{:?}", r);
            }
            // A chord may cut inside the base protection radius: then it must be refused, on line 2.
            Err(ConvertError::Unreachable { span, .. }) => prop_assert_eq!(span.line, 2),
            Err(e) => prop_assert!(false, "{}", e),
        }
    }
}
