//! Property tests: no input panics; numbers are exact; the writer's numbers read back; arcs from R are
//! geometrically right; relative moves add up.

use gcode::{Command, Commands, Reader, Writer, WriterOptions, file_stats, format_number};
use proptest::prelude::*;

/// Every number a command carries is finite (an impossible value is an error, never NaN or inf).
fn all_finite(command: &Command) -> bool {
    let finite = |values: &[f64]| values.iter().all(|v| v.is_finite());
    let finite_opt = |values: &[Option<f64>]| values.iter().flatten().all(|v| v.is_finite());
    match command {
        Command::Move(m) => finite(&m.target) && finite(&[m.feed]),
        Command::Arc(a) => {
            finite(&a.start)
                && finite(&a.target)
                && finite(&a.centre)
                && finite(&a.offset)
                && a.feed.is_finite()
        }
        Command::Dwell { seconds } => seconds.is_finite(),
        Command::SetPosition { position } => finite_opt(position),
        Command::SetKinematicPosition { position } => finite_opt(position),
        Command::SetAccel(p) => finite_opt(&[p.s, p.p, p.t, p.r]),
        Command::SetVelocityLimit(v) => finite_opt(&[
            v.velocity,
            v.accel,
            v.square_corner_velocity,
            v.minimum_cruise_ratio,
            v.accel_to_decel,
        ]),
        Command::SpeedFactor(v) | Command::ExtrudeFactor(v) => v.is_finite(),
        Command::Home { .. } | Command::WaitForMoves | Command::Other { .. } | Command::Meta(_) => {
            true
        }
    }
}

/// Drives every stage over `input`; must never panic, whatever the bytes, nor yield a non-finite value.
fn exercise(input: &[u8]) {
    for result in Commands::from_reader(input, "fuzz") {
        match result {
            Ok(command) => assert!(all_finite(&command.value), "{:?}", command.value),
            // Display must work on any error (it is what the CLI prints).
            Err(err) => assert!(!err.to_string().is_empty()),
        }
    }
    let mut reader = Reader::new(input, "fuzz");
    let mut writer = Writer::new(Vec::new(), WriterOptions::default());
    while let Some(line) = reader.next_line() {
        if let Ok(line) = line {
            writer
                .write_line(&line)
                .expect("writing to memory cannot fail");
        }
    }
    let _ = file_stats(input, "fuzz");
}

/// Lines made of G-code-ish pieces, to reach deeper than random bytes do.
fn gcode_like() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        Just("G1 ".to_owned()),
        Just("G2 ".to_owned()),
        Just("G3 ".to_owned()),
        Just("G91\n".to_owned()),
        Just("G92 ".to_owned()),
        Just("M221 S".to_owned()),
        Just("N1 ".to_owned()),
        Just("*".to_owned()),
        Just(";LAYER_CHANGE\n;Z:".to_owned()),
        Just("(".to_owned()),
        Just(")".to_owned()),
        Just("SET_KINEMATIC_POSITION X=".to_owned()),
        Just("\"".to_owned()),
        "[XYZEFIJRPS][-+]?[0-9]{0,4}(\\.[0-9]{0,4})?".prop_map(|s| s),
        "[XYZEFIJRS]9{300,310}".prop_map(|s| s),
        Just("G20\n".to_owned()),
        Just("M220 S".to_owned()),
        "[ \t\r\n]".prop_map(|s| s),
    ];
    proptest::collection::vec(piece, 0..40).prop_map(|pieces| pieces.concat().into_bytes())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(input in proptest::collection::vec(any::<u8>(), 0..2000)) {
        exercise(&input);
    }

    #[test]
    fn gcode_like_input_never_panics(input in gcode_like()) {
        exercise(&input);
    }

    #[test]
    fn word_values_equal_std_parse(int in "[0-9]{1,20}", frac in "[0-9]{0,25}", negative in any::<bool>()) {
        let text = format!("{}{int}.{frac}", if negative { "-" } else { "" });
        let line = format!("G1 X{text}");
        let mut reader = Reader::new(line.as_bytes(), "p");
        let value = reader.next_line().and_then(|l| l.ok()).and_then(|l| l.words().first().and_then(|w| w.value));
        let expected: f64 = text.parse().expect("std parses plain decimals");
        prop_assert_eq!(value.map(f64::to_bits), Some(expected.to_bits()));
    }

    #[test]
    fn shortest_numbers_read_back_exactly(value in any::<f64>().prop_filter("finite", |v| v.is_finite())) {
        let mut out = Vec::new();
        format_number(value, None, &mut out).expect("finite");
        let text = String::from_utf8(out).expect("ascii");
        prop_assert!(!text.contains('e') && !text.contains('E'), "{}", text);
        let back: f64 = text.parse().expect("parses");
        prop_assert!(back == value, "{} -> {}", value, text);
    }

    #[test]
    fn fixed_numbers_are_close_and_plain(value in -1e6f64..1e6, decimals in 0u8..8) {
        let mut out = Vec::new();
        format_number(value, Some(decimals), &mut out).expect("finite");
        let text = String::from_utf8(out).expect("ascii");
        prop_assert!(!text.contains('e') && text != "-0" && !text.ends_with('.'), "{}", text);
        prop_assert!(!text.contains('.') || !text.ends_with('0'), "{}", text);
        let back: f64 = text.parse().expect("parses");
        // The text is within half a unit of its last decimal of `value`; reading it back rounds once more, by
        // at most half an ulp (about 6e-11 near 1e6, more than a relative 1e-9 of the half unit there).
        let half_unit = 0.5 * 10f64.powi(-i32::from(decimals));
        prop_assert!((back - value).abs() <= half_unit + f64::EPSILON * value.abs(), "{} -> {}", value, text);
    }

    #[test]
    fn relative_moves_add_up(steps in proptest::collection::vec(-100.0f64..100.0, 1..50)) {
        let mut text = String::from("G91\n");
        for step in &steps {
            text.push_str(&format!("G1 X{step} E{step}\n"));
        }
        let last = Commands::from_reader(text.as_bytes(), "p")
            .filter_map(|c| match c.ok()?.value { Command::Move(m) => Some(m.target), _ => None })
            .last()
            .expect("moves");
        // `{step}` prints the shortest exact form, so the file holds exactly these values.
        let sum: f64 = steps.iter().sum();
        prop_assert!((last[0] - sum).abs() < 1e-9 && (last[3] - sum).abs() < 1e-9);
    }

    #[test]
    fn r_arcs_have_the_right_centre(
        x0 in -50.0f64..50.0, y0 in -50.0f64..50.0, x1 in -50.0f64..50.0, y1 in -50.0f64..50.0,
        extra in 0.01f64..100.0, long in any::<bool>(), clockwise in any::<bool>(),
    ) {
        let chord = (x1 - x0).hypot(y1 - y0);
        prop_assume!(chord > 1e-3);
        let radius = chord / 2.0 + extra;
        let r = if long { -radius } else { radius };
        let text = format!("G1 X{x0} Y{y0}\n{} X{x1} Y{y1} R{r}\n", if clockwise { "G2" } else { "G3" });
        let arc = Commands::from_reader(text.as_bytes(), "p")
            .filter_map(|c| match c.ok()?.value { Command::Arc(a) => Some(a), _ => None })
            .next()
            .expect("an arc");
        let to_start = (arc.start[0] - arc.centre[0]).hypot(arc.start[1] - arc.centre[1]);
        let to_end = (arc.target[0] - arc.centre[0]).hypot(arc.target[1] - arc.centre[1]);
        prop_assert!((to_start - radius).abs() < 1e-9 * radius.max(1.0) * 1e3, "{} vs {}", to_start, radius);
        prop_assert!((to_end - radius).abs() < 1e-9 * radius.max(1.0) * 1e3, "{} vs {}", to_end, radius);
        let sweep = arc.sweep();
        if long {
            prop_assert!(sweep >= std::f64::consts::PI - 1e-9, "long arc swept {}", sweep);
        } else {
            prop_assert!(sweep <= std::f64::consts::PI + 1e-9, "short arc swept {}", sweep);
        }
    }
}

/// A value where the printed decimal and the value read back differ by more than half a unit of the last
/// decimal (by the rounding of reading it back): found by the property above, kept as a fixed case.
#[test]
fn fixed_number_near_a_million_is_within_half_a_unit_and_an_ulp() {
    let value = 916_164.176_686_5;
    let mut out = Vec::new();
    format_number(value, Some(6), &mut out).expect("finite");
    let text = String::from_utf8(out).expect("ascii");
    let back: f64 = text.parse().expect("parses");
    assert!(
        (back - value).abs() <= 0.5e-6 + f64::EPSILON * value,
        "{value} -> {text}"
    );
    assert!(text == "916164.176686" || text == "916164.176687", "{text}");
}
