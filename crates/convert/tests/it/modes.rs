//! Mode lines and unknown positions: the input's modes never reach the output live, verification reads the
//! written text with each firmware's mode semantics (so a stray mode line is caught), and no coordinate is
//! invented where the input has not set it.

use convert::{
    AxisMap, ConvertError, ConvertOptions, Extrusion, Firmware, Target, VerifyReport,
    read_commands, verify,
};
use gcode::{CommandWord, Reader};

use crate::common::{convert_text, corpus_files, homed, placement};
use crate::machines;

const FIRMWARES: [Firmware; 3] = [Firmware::Marlin, Firmware::Rrf, Firmware::Klipper];
const EXTRUSIONS: [Extrusion; 2] = [Extrusion::Relative, Extrusion::Absolute];

fn polar_map() -> AxisMap {
    AxisMap::motors(machines::polar(), Target::Cylindrical).expect("polar map")
}

/// The live (not commented) mode commands of a G-code text, in order, read with the project's reader.
fn live_modes(text: &str) -> Vec<String> {
    let mut reader = Reader::new(text.as_bytes(), "out");
    let mut modes = Vec::new();
    while let Some(line) = reader.next_line() {
        let line = line.expect("output lexes");
        if let Some(CommandWord::Code {
            letter,
            major,
            minor: None,
        }) = line.command()
        {
            let is_mode = matches!((letter, major), (b'G', 17..=21 | 90 | 91) | (b'M', 82 | 83));
            if is_mode {
                modes.push(format!("{}{major}", letter as char));
            }
        }
    }
    modes
}

/// The output's only live mode lines are its own header: `G90` and then the E mode of `extrusion`.
fn assert_header_only(out: &str, extrusion: Extrusion) {
    let e_mode = match extrusion {
        Extrusion::Relative => "M83",
        Extrusion::Absolute => "M82",
    };
    assert_eq!(live_modes(out), ["G90", e_mode], "{out}");
}

fn verify_as(
    map: &AxisMap,
    options: &ConvertOptions,
    input: &[u8],
    out: &str,
    firmware: Firmware,
) -> VerifyReport {
    let commands = read_commands(input, "in").expect("input parses");
    let options = ConvertOptions {
        firmware,
        ..options.clone()
    };
    verify(map, &options, &commands, out.as_bytes()).expect("output replays")
}

fn assert_extrusion_equal(what: &str, r: &VerifyReport) {
    let error = (r.extrusion_out - r.extrusion_in).abs() / r.extrusion_in.abs().max(1.0);
    assert!(
        error <= 1e-6,
        "{what}: extrusion read back {} against the input's {}",
        r.extrusion_out,
        r.extrusion_in
    );
}

/// Every mode the input switches between: absolute and relative E, relative moves (Simplify3D's end code
/// style: `G91` then relative moves), inches, the arc plane.
const MIXED_MODES: &[u8] = b"G21\nG90\nM82\nG92 E0\nG1 Z0.3 F600\nG1 X20 Y0 F1800\n\
G1 X30 Y0 E5\nG91\nG1 X5 Y5 E1\nG90\nM83\nG1 X40 Y0 E1.5\nG17\nG91\nG1 Z1\nG1 X-5 Y2 E0.5\nG20\nG1 X0.1\n\
G21\nG90\nM82\nG92 E0\nG1 X35 Y10 E2\n";

#[test]
fn input_modes_are_translated_and_every_firmware_reads_the_same_print() {
    let map = polar_map();
    for extrusion in EXTRUSIONS {
        let options = ConvertOptions {
            extrusion,
            ..homed()
        };
        let (out, _) = convert_text(&map, &options, MIXED_MODES).expect("converts");
        assert_header_only(&out, extrusion);
        for firmware in FIRMWARES {
            let r = verify_as(&map, &options, MIXED_MODES, &out, firmware);
            let what = format!("{extrusion:?} read by {firmware:?}");
            assert_extrusion_equal(&what, &r);
            assert_eq!(r.unmatched, 0, "{what}: {r:?}\n{out}");
            assert!(r.max_deviation <= 0.005, "{what}: {r:?}");
            // 10 + 1 (G92 E0 then absolute) … every E the input gives: 5 + 1 + 1.5 + 0.5 + 2.
            assert!((r.extrusion_in - 10.0).abs() < 1e-9, "{r:?}");
        }
    }
}

#[test]
fn verification_catches_a_stray_mode_line_as_the_firmware_reads_it() {
    let map = polar_map();
    let input: &[u8] =
        b"M83\nG1 Z0.3 F600\nG1 X20 Y0 F1800\nG1 X30 Y0 E5\nG1 X30 Y10 E1\nG1 X20 Y10 E1\n";
    let options = homed();
    let (out, _) = convert_text(&map, &options, input).expect("converts");
    for firmware in FIRMWARES {
        let r = verify_as(&map, &options, input, &out, firmware);
        assert_extrusion_equal("as written", &r);
        assert_eq!(r.unmatched, 0);
    }
    // The header's `M83` before its `G90`: Marlin's G90 then makes E absolute again, RRF's and Klipper's not.
    let swapped = out.replacen("G90\nM83\n", "M83\nG90\n", 1);
    assert_ne!(swapped, out);
    for firmware in FIRMWARES {
        let r = verify_as(&map, &options, input, &swapped, firmware);
        let equal =
            (r.extrusion_out - r.extrusion_in).abs() <= 1e-6 * r.extrusion_in.abs().max(1.0);
        assert_eq!(equal, firmware != Firmware::Marlin, "{firmware:?}: {r:?}");
    }
    // A live `G91` before the last lines: every firmware then moves by the written absolute positions.
    let lines: Vec<&str> = out.lines().collect();
    let at = lines.len() - 2;
    let stray = [&lines[..at], &["G91"], &lines[at..]].concat().join("\n");
    for firmware in FIRMWARES {
        let r = verify_as(&map, &options, input, &stray, firmware);
        assert!(
            r.unmatched > 0 || r.max_deviation > 1.0,
            "{firmware:?} did not notice the G91: {r:?}"
        );
    }
    // A live `M82` in a relative-E output: the deltas become positions.
    let stray = out.replacen("M83\n", "M83\nM82\n", 1);
    assert_ne!(stray, out);
    for firmware in FIRMWARES {
        let r = verify_as(&map, &options, input, &stray, firmware);
        assert!(
            (r.extrusion_out - r.extrusion_in).abs() > 0.5,
            "{firmware:?}: {r:?}"
        );
    }
}

#[test]
fn corpus_extrusion_read_back_by_each_firmware_equals_the_input() {
    corpus_read_back(&polar_map(), [0.0, 0.0], 300.0);
}

#[test]
fn corpus_extrusion_read_back_on_a_scara_equals_the_input() {
    let map = AxisMap::motors(machines::scara(), Target::Joints).expect("SCARA map");
    corpus_read_back(&map, [0.0, 130.0], 60.0);
}

/// Every corpus file placed within `radius` of `at`, converted with relative and absolute E, re-read by each
/// firmware: path within the tolerance, every segment on its move, extrusion equal within 1e-6.
fn corpus_read_back(map: &AxisMap, at: [f64; 2], radius: f64) {
    let map = map.clone();
    let files = corpus_files();
    for (name, text) in &files {
        let commands = read_commands(&text[..], name).expect("corpus parses");
        let (scale, translate) = placement(&commands, at, radius);
        for extrusion in EXTRUSIONS {
            let options = ConvertOptions {
                extrusion,
                scale_xy: scale,
                translate,
                ..homed()
            };
            let (out, _) = convert_text(&map, &options, text).expect("corpus converts");
            assert_header_only(&out, extrusion);
            for firmware in FIRMWARES {
                let r = verify_as(&map, &options, text, &out, firmware);
                let what = format!("{name} {extrusion:?} read by {firmware:?}");
                println!(
                    "{what}: E {:.6} → {:.6}, max {:.5} mm, {} unmatched",
                    r.extrusion_in, r.extrusion_out, r.max_deviation, r.unmatched
                );
                assert_extrusion_equal(&what, &r);
                assert_eq!(r.unmatched, 0, "{what}");
                assert!(r.max_deviation <= 0.005, "{what}: {r:?}");
            }
        }
    }
}

fn first_motion(out: &str) -> &str {
    out.lines()
        .find(|l| l.starts_with("G0") || l.starts_with("G1"))
        .expect("a motion line")
}

#[test]
fn an_unknown_coordinate_is_refused_or_taken_from_the_homing_pose() {
    let map = polar_map();
    let unknown = |text: &[u8]| match convert_text(&map, &ConvertOptions::default(), text) {
        Err(ConvertError::UnknownPosition { span, axis }) => (span.line, axis),
        other => panic!("expected an unknown position, got {other:?}"),
    };
    // No homing pose: Z (and Y, when only X is given) are not guessed.
    assert_eq!(unknown(b"G1 X10 Y5 E1 F600\n"), (1, 'Z'));
    assert_eq!(unknown(b"; start\nG1 X10 Z1 F600\n"), (2, 'Y'));
    assert_eq!(unknown(b"G1 X10 Y5 Z1 F600\nG28\nG1 X10 Y5\n"), (3, 'Z'));
    // A relative Z from an unknown Z is still unknown.
    assert_eq!(unknown(b"G91\nG1 Z5\n"), (2, 'Z'));
    // Set first, it is known.
    assert!(
        convert_text(
            &map,
            &ConvertOptions::default(),
            b"G1 Z0.2\nG1 X10 Y5 F600\n"
        )
        .is_ok()
    );
    // An arc's end names its axes (from an unknown start it is a positioning move); one it leaves out is
    // not known.
    let arc = convert_text(
        &map,
        &ConvertOptions::default(),
        b"G1 Z1\nG3 X10 Y10 I10 J0 F600\n",
    );
    assert!(arc.is_ok(), "{arc:?}");
    assert_eq!(unknown(b"G1 Z1\nG2 X20 I10 J0 F600\n"), (2, 'Y'));

    // With the homing pose (as `convert` takes from the config), the machine starts there and G28 returns
    // there: Z is the homed Z, not 0.
    let options = ConvertOptions {
        home: Some([150.0, 0.0, 0.5]),
        ..ConvertOptions::default()
    };
    let (out, _) = convert_text(&map, &options, b"G1 X10 Y5 E1 F600\n").expect("converts");
    assert!(first_motion(&out).contains(" Z0.5"), "{out}");
    let (out, _) = convert_text(&map, &options, b"G1 Z3\nG28\nG1 X10 Y5 F600\n").expect("converts");
    let after_home = out.split("G28").nth(1).expect("G28 written");
    assert!(first_motion(after_home).contains(" Z0.5"), "{out}");
    assert!(!out.contains(" Z0 ") && !out.contains(" Z0\n"), "{out}");
    // Only X given: Y is the homing pose's.
    let (out, _) = convert_text(&map, &options, b"G1 X100 F600\n").expect("converts");
    assert!(first_motion(&out).starts_with("G0 X100 Y0 Z0.5"), "{out}");
}
