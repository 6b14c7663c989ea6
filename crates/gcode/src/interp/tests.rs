use std::io::BufRead;

use super::*;
use crate::command::{Command, Meta, Move, VelocityLimit};
use crate::error::{ErrorKind, GcodeError, WarningKind};
use crate::reader::{Reader, ReaderOptions};
use crate::test_input::{each_corpus_file, gcode_lines};

fn run(text: &str) -> (Vec<Command>, Interpreter) {
    let mut commands = Commands::from_reader(text.as_bytes(), "t");
    let mut out = Vec::new();
    while let Some(command) = commands.next_command() {
        out.push(command.expect("command").value);
    }
    (out, commands.interpreter().clone())
}

fn first_error(text: &str) -> GcodeError {
    first_error_or_none(text).expect("an error")
}

fn first_error_or_none(text: &str) -> Option<GcodeError> {
    Commands::from_reader(text.as_bytes(), "t").find_map(Result::err)
}

fn moves(commands: &[Command]) -> Vec<Move> {
    commands
        .iter()
        .filter_map(|c| {
            if let Command::Move(m) = c {
                Some(*m)
            } else {
                None
            }
        })
        .collect()
}

#[test]
fn absolute_relative_and_g92() {
    let (commands, state) = run("G1 X10 Y5 F600\nG91\nG1 X1 E2\nG90\nG92 X0\nG1 X3\n");
    let m = moves(&commands);
    assert_eq!(m[0].target, [10.0, 5.0, 0.0, 0.0]);
    assert_eq!(m[0].feed, 10.0);
    assert_eq!(m[1].target, [11.0, 5.0, 0.0, 2.0]);
    assert_eq!(m[2].target, [14.0, 5.0, 0.0, 2.0]);
    assert_eq!(state.base_position(), [11.0, 0.0, 0.0, 0.0]);
    assert_eq!(state.gcode_position(), [3.0, 5.0, 0.0, 2.0]);
}

#[test]
fn relative_extrusion_and_bare_g92() {
    let (commands, state) = run("M83\nG1 E1\nG1 E1.5\nG92\nG1 E0.5\n");
    let m = moves(&commands);
    assert_eq!(m[1].target[3], 2.5);
    assert_eq!(m[2].target[3], 3.0);
    assert!(commands.contains(&Command::SetPosition {
        position: [Some(0.0); 4]
    }));
    assert_eq!(state.gcode_position()[3], 0.5);
}

#[test]
fn m220_scales_speed_and_m221_keeps_e_continuous() {
    let (commands, state) = run("G1 X1 F6000\nM220 S50\nG1 X2\nM221 S200\nG1 E1\n");
    let m = moves(&commands);
    assert_eq!(m[0].feed, 100.0);
    assert_eq!(m[1].feed, 50.0);
    // E continuous at 0, then E1 at 200 % extrudes 2 mm of filament.
    assert_eq!(m[2].target[3], 2.0);
    assert_eq!(state.gcode_position()[3], 1.0);
}

#[test]
fn inches() {
    let (commands, _) = run("G20\nG1 X1 F60\n");
    assert_eq!(moves(&commands)[0].target[0], 25.4);
    assert_eq!(moves(&commands)[0].feed, 25.4);
}

#[test]
fn arcs_from_ij_and_r() {
    let (commands, _) = run("G1 X10 Y0\nG3 X0 Y10 I-10 J0\nG2 X10 Y0 R10\n");
    let arcs: Vec<_> = commands
        .iter()
        .filter_map(|c| {
            if let Command::Arc(a) = c {
                Some(**a)
            } else {
                None
            }
        })
        .collect();
    assert_eq!(arcs[0].centre, [0.0, 0.0]);
    assert!(!arcs[0].clockwise);
    // Short clockwise arc from (0,10) to (10,0): centre at the origin.
    assert!(
        arcs[1].centre[0].abs() < 1e-12 && arcs[1].centre[1].abs() < 1e-12,
        "{:?}",
        arcs[1].centre
    );
    let (commands, _) = run("G1 X10 Y0\nG2 X0 Y10 R-10\n");
    let Some(Command::Arc(long)) = commands.last() else {
        panic!("no arc")
    };
    assert!(
        long.centre[0].abs() < 1e-12 && long.centre[1].abs() < 1e-12,
        "{:?}",
        long.centre
    );
    let (commands, _) = run("G1 X10 Y0\nG3 X0 Y10 R-10\n");
    let Some(Command::Arc(long_ccw)) = commands.last() else {
        panic!("no arc")
    };
    assert!((long_ccw.centre[0] - 10.0).abs() < 1e-12 && (long_ccw.centre[1] - 10.0).abs() < 1e-12);
}

#[test]
fn arc_errors() {
    assert_eq!(first_error("G2 X1 Y1").kind, ErrorKind::ArcMissingCentre);
    assert_eq!(
        first_error("G91\nG2 X1 Y1 I1").kind,
        ErrorKind::ArcRelativeMode
    );
    assert_eq!(
        first_error("G2 X10 Y0 R2").kind,
        ErrorKind::ArcRadiusTooSmall
    );
    assert!(matches!(
        first_error("G2 X10 Y0 I1 J0").kind,
        ErrorKind::ArcInconsistent { .. }
    ));
    assert_eq!(
        first_error("G18\nG2 X1 I1").kind,
        ErrorKind::ArcPlaneUnsupported
    );
}

#[test]
fn arc_turns_are_bounded() {
    let full_circles = |p: &str| format!("G1 X10 Y0\nG2 X10 Y0 I-10 J0 {p}");
    assert!(first_error_or_none(&full_circles(&format!("P{MAX_ARC_TURNS}"))).is_none());
    let err =
        first_error_or_none(&full_circles("P4000000000")).expect("P beyond the bound is an error");
    assert_eq!(err.kind, ErrorKind::InvalidParameter("P".to_owned()));
    assert_eq!((err.span.line, err.span.column), (2, 19));
}

#[test]
fn overflowing_values_are_errors_not_infinities() {
    let huge = "9".repeat(308);
    assert_eq!(
        first_error(&format!("G20\nG1 X{huge}")).kind,
        ErrorKind::NumberOverflow
    );
    assert_eq!(
        first_error(&format!("G20\nG2 X1 Y1 I{huge}")).kind,
        ErrorKind::NumberOverflow
    );
    let err = first_error(&format!("G1 F{huge}\nM220 S{huge}"));
    assert_eq!(err.kind, ErrorKind::InvalidParameter("S".to_owned()));
    let err = first_error(&format!("G1 E1\nG92 E-{huge}\nM221 S{huge}"));
    assert_eq!(err.kind, ErrorKind::InvalidParameter("S".to_owned()));
}

#[test]
fn feed_and_dwell_errors() {
    let err = first_error("G1 X1 F0");
    assert_eq!((err.kind, err.span.column), (ErrorKind::InvalidFeedRate, 7));
    assert_eq!(first_error("G1 F-10").kind, ErrorKind::InvalidFeedRate);
    assert_eq!(first_error("G4 P-1").kind, ErrorKind::NegativeDwell);
    // Klipper reads only P: `G4 S2` does not wait, and says so at the word.
    let (commands, interpreter) = run("G4 P250\nG4 S2\nG4 P100 S5\n");
    assert_eq!(
        commands,
        vec![
            Command::Dwell { seconds: 0.25 },
            Command::Dwell { seconds: 0.0 },
            Command::Dwell { seconds: 0.1 }
        ]
    );
    let s_warnings: Vec<_> = interpreter
        .warnings()
        .list()
        .iter()
        .filter(|w| w.message.contains("G4 S"))
        .map(|w| (w.span.line, w.span.column))
        .collect();
    assert_eq!(s_warnings, vec![(2, 4), (3, 9)]);
}

#[test]
fn klipper_extended_commands() {
    let (commands, state) = run(
        "SET_VELOCITY_LIMIT ACCEL=3000 SQUARE_CORNER_VELOCITY=5\nSET_KINEMATIC_POSITION X=300 Y=0\nset_fan_speed FAN=a SPEED=1\n",
    );
    assert_eq!(
        commands[0],
        Command::SetVelocityLimit(VelocityLimit {
            accel: Some(3000.0),
            square_corner_velocity: Some(5.0),
            ..VelocityLimit::default()
        })
    );
    assert_eq!(
        commands[1],
        Command::SetKinematicPosition {
            position: [Some(300.0), Some(0.0), None]
        }
    );
    assert_eq!(state.last_position(), [300.0, 0.0, 0.0, 0.0]);
    assert_eq!(
        commands[2],
        Command::Other {
            name: "SET_FAN_SPEED".to_owned()
        }
    );
}

#[test]
fn klipper_quoted_values_read_as_klipper_reads_them() {
    // Klipper splits extended parameters like a shell: '…' and "…" both quote.
    for text in [
        "SET_VELOCITY_LIMIT VELOCITY='200' ACCEL=\"3000\"\n",
        "SET_VELOCITY_LIMIT VELOCITY=200 ACCEL=3000\n",
    ] {
        let (commands, _) = run(text);
        assert_eq!(
            commands[0],
            Command::SetVelocityLimit(VelocityLimit {
                velocity: Some(200.0),
                accel: Some(3000.0),
                ..VelocityLimit::default()
            }),
            "{text}"
        );
    }
}

#[test]
fn a_byte_order_mark_is_not_part_of_the_first_line() {
    let (commands, _) = run("\u{feff}G1 X10 F600\nG1 X20\n");
    assert_eq!(commands.len(), 2);
    assert!(matches!(commands[0], Command::Move(m) if m.target[0] == 10.0));
    // Elsewhere it is still an unexpected character.
    let text = "G1 X1\n\u{feff}G1 X2\n";
    let errors: Vec<_> = Commands::from_reader(text.as_bytes(), "t")
        .filter_map(Result::err)
        .collect();
    assert_eq!(errors.len(), 1);
    assert_eq!(errors[0].span.line, 2);
}

#[test]
fn layer_metadata() {
    let (commands, _) =
        run(";LAYER_CHANGE\n;Z:0.2\n;HEIGHT:0.2\nG1 X1\n; CHANGE_LAYER\nG1 X2\n;TYPE:Perimeter\n");
    assert_eq!(
        commands[0],
        Command::Meta(Meta::LayerChange {
            index: None,
            z: Some(0.2)
        })
    );
    assert_eq!(
        commands[2],
        Command::Meta(Meta::LayerChange {
            index: None,
            z: None
        })
    );
    assert_eq!(
        commands[4],
        Command::Meta(Meta::Feature("Perimeter".to_owned()))
    );
}

/// Everything a stream gives, as text (`{:?}` tells `-0.0` from `0.0`): each command or error,
/// the warnings, and the final state.
fn stream(text: &[u8], fast_lines: bool) -> String {
    stream_from(text, fast_lines)
}

/// [`stream`] from any input (a small `BufReader` splits lines across refills).
fn stream_from(input: impl BufRead, fast_lines: bool) -> String {
    let mut commands = Commands::from_reader(input, "t");
    commands.fast_lines = fast_lines;
    let out: Vec<_> = commands.by_ref().collect();
    let warnings = commands.take_warnings();
    let state = commands.interpreter();
    format!(
        "{out:?}\n{warnings:?}\n{:?} {:?}",
        state.last_position(),
        state.speed()
    )
}

#[test]
fn fast_path_gives_what_the_general_path_gives() {
    let text = "G1 X1 Y2 F600\n  g0 x-1.5\tE.5 \nG1 X1 X2\nG1 X1 Q2\nG1 X\nG1 F0\nG1X1\nG01 X1\n\
                G1 X1e5\nG1 X1 ;c\nG91\nG1 Z.2\nM83\nG1 E-0\nG20\nG1 X1 F60\n;LAYER_CHANGE\nG1 X3\n";
    assert_eq!(
        stream(text.as_bytes(), true),
        stream(text.as_bytes(), false)
    );
}

proptest::proptest! {
    #[test]
    fn fast_path_matches_the_general_path_on_any_lines(
        text in gcode_lines(
            vec![
                "G1", "G0", "g1", "G01", "G1.5", "G2", "G4", "M83", "M82", "G91", "G90",
                "G92 E0", "G92 X1", "M221 S150", "M220 S50", "G20", "G21", "N5 G1", " G1",
                ";LAYER_CHANGE", ";Z:0.4", "", "G1 ;c", "G28", "; note", ";TIME_ELAPSED:5",
                ";TYPE:Perimeter", "  ; x", ";", "   ", "\t;c", "; caf\u{e9}", "; Z:1",
                "G2", "G3", "g2", "G2 I1", "G3 J-1", "G2 X2 I1", "G3 Y0 I-1 J0", "G18",
                "G17", ";LAYER:3", "; CHANGE_LAYER", "; Z_HEIGHT: 0.6", "; printing object a",
                ";TYPE:", "; feature skirt", ";Z:x", "G92", "g92 E-1", "G92.1", "G920",
            ],
            vec![
                " X1.5", " Y-2", " Z.3", " E0.0123", " E-1.25", " F1800", " F0", " F-5",
                " X", " Q1", "X2", " x3", "\tY4", " E1e5", " X1.2.3", " ;c", " (p)",
                " *12", "  ", " X+5", " X5.", " Y-.5", " F9e9", " X#", " E99999999999",
                " Z123456789012345678901234", " I1", " E", " J1", " I-1", " J0", " R1",
                " P1", " I", " J.5",
            ],
            5,
            12,
        ),
        capacity in 1usize..48,
    ) {
        let general = stream(text.as_bytes(), false);
        proptest::prop_assert_eq!(&stream(text.as_bytes(), true), &general);
        let small_buffer = std::io::BufReader::with_capacity(capacity, text.as_bytes());
        proptest::prop_assert_eq!(&stream_from(small_buffer, true), &general);
    }
}

#[test]
fn fast_path_gives_the_arcs_the_general_path_gives() {
    let text = "G1 X10 Y0 F600\nG3 X0 Y10 I-10 J0 E1\nG2 X10 Y0 I0 J-10 F1200\nG3 X10 Y0 J5\n\
                G2 X0 Y0 I0 J0\nG2 X1 Y1 I1 I2\nG2 X1 Y1 I1 Q2\nG2 X5 Y5 I3\nM83\nM221 S90\n\
                G92 E0\nG3 X10 Y10 Z1 I-5 J5 E.5\nG20\nG2 X0 Y0 I.1 J.1\nG21\nG18\nG2 X1 I1\n\
                G17\nG91\nG2 X1 I1\nG90\n;LAYER_CHANGE\nG3 X0 Y0 I1 J1\n;Z:2\nG2 X0 Y0 I-1 F0\n";
    assert_eq!(
        stream(text.as_bytes(), true),
        stream(text.as_bytes(), false)
    );
}

#[test]
fn fast_path_gives_the_g92_the_general_path_gives() {
    let huge = "9".repeat(308);
    let text = format!(
        "G1 X5 E3\nG92 E0\nG92\nM221 S50\nG92 E1 X2 Y3 Z4\nG20\nG92 X{huge}\nG92 E2 E3\n\
         G92 F1\nG92 E\n;LAYER_CHANGE\nG92 E0\n"
    );
    assert_eq!(
        stream(text.as_bytes(), true),
        stream(text.as_bytes(), false)
    );
}

#[test]
fn fast_path_keeps_comment_warnings_and_the_line_limit() {
    let text =
        b"G1 X1\n; caf\xe9\n  ;\xff\r\n;ok\n\nG1 X2 Y3 E4 F5\n; a longer comment line\nG1 X3\n";
    assert_eq!(stream(text, true), stream(text, false));
    assert!(stream(text, true).contains("LossyComment"));
    for max_line_len in 0..24 {
        let run = |fast_lines| {
            let reader = Reader::with_options(&text[..], "t", ReaderOptions { max_line_len });
            let mut commands = Commands::new(reader, InterpreterOptions::default());
            commands.fast_lines = fast_lines;
            format!("{:?}", commands.collect::<Vec<_>>())
        };
        assert_eq!(run(true), run(false), "max_line_len {max_line_len}");
    }
}

/// Input that fails after its text.
struct FailingAfter<'a>(&'a [u8]);

impl std::io::Read for FailingAfter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.0.is_empty() {
            return Err(std::io::Error::other("disk on fire"));
        }
        let n = self.0.len().min(buf.len());
        buf[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        Ok(n)
    }
}

#[test]
fn fast_path_keeps_io_errors() {
    let text = b"G1 X1\r\nG1 X2\rG1 X3\nG1 X4";
    for capacity in [4, 8, 64] {
        let run = |fast_lines| {
            let input = std::io::BufReader::with_capacity(capacity, FailingAfter(text));
            let mut commands = Commands::from_reader(input, "t");
            commands.fast_lines = fast_lines;
            format!("{:?}", commands.collect::<Vec<_>>())
        };
        let fast = run(true);
        assert_eq!(fast, run(false));
        assert!(fast.contains("disk on fire"), "{fast}");
    }
}

#[test]
fn fast_path_matches_the_general_path_on_the_corpus() {
    each_corpus_file(|path, text| {
        let fast = stream(text, true);
        assert!(fast == stream(text, false), "{}", path.display());
    });
}

#[test]
fn unknown_parameters_warn() {
    let mut commands = Commands::from_reader(&b"G1 X1 Q2 X3\n"[..], "t");
    let all: Vec<_> = commands.by_ref().collect();
    assert_eq!(all.len(), 1);
    let kinds: Vec<_> = commands
        .take_warnings()
        .into_iter()
        .map(|w| w.kind)
        .collect();
    assert_eq!(
        kinds,
        vec![
            WarningKind::UnknownParameter,
            WarningKind::DuplicateParameter
        ]
    );
}

/// Klipper's `gcode_move`: `SET_GCODE_OFFSET` shifts the frame by the change of the offset (`_ADJUST` adds to it),
/// `MOVE=1` moves by that change, and `G28` restores the offsets `SET_GCODE_OFFSET` set, dropping a `G92` one.
#[test]
fn gcode_offsets_as_klipper_applies_them() {
    let (commands, interp) = run("G1 X10 Y10 Z1 F600\nSET_GCODE_OFFSET Z=0.2\nG1 X20 Z1\n\
         SET_GCODE_OFFSET Z_ADJUST=-0.05\nG1 Z1\nSET_GCODE_OFFSET X=1 MOVE=1 MOVE_SPEED=5\n");
    let m = moves(&commands);
    assert_eq!(m[1].target[2], 1.2);
    assert!((m[2].target[2] - 1.15).abs() < 1e-12);
    // MOVE=1: the toolhead moves by the change (+1 in X) at 5 mm/s, the frame keeps the point.
    assert_eq!((m[3].target[0], m[3].feed), (21.0, 5.0));
    assert_eq!(interp.gcode_position()[0], 20.0);
    let (commands, interp) = run("G92 X5\nSET_GCODE_OFFSET Y=2\nG28\nG1 X0 Y0 F600\n");
    let m = moves(&commands);
    assert_eq!((m[0].target[0], m[0].target[1]), (0.0, 2.0));
    assert_eq!(interp.base_position()[..2], [0.0, 2.0]);
}

/// What a stream gave: each command or error, and each warning's line and kind.
type Read = (Vec<Result<Command, ErrorKind>>, Vec<(u64, WarningKind)>);

/// Every command, error and warning of `text` read as Klipper reads it with `commands`, on the fast path or not.
fn klipper_stream(text: &str, commands: CommandSet, fast_lines: bool) -> Read {
    let reader = Reader::new(text.as_bytes(), "t");
    let mut stream = Commands::new(reader, InterpreterOptions::klipper(commands));
    stream.fast_lines = fast_lines;
    let out = stream
        .by_ref()
        .map(|c| c.map(|c| c.value).map_err(|e| e.kind))
        .collect();
    let warnings = stream
        .take_warnings()
        .iter()
        .map(|w| (w.span.line, w.kind))
        .collect();
    (out, warnings)
}

#[test]
fn commands_klipper_lacks_are_skipped_with_a_warning_on_both_paths() {
    let text = "G1 X10 Y0 F600\nG2 X10 Y0 I-5 J0\nG3 X10 Y0 I-5 J0 E1\nG18\nSET_KINEMATIC_POSITION X=1\nG1 X20\n";
    let without = CommandSet {
        arcs: false,
        kinematic_position: false,
        inches: true,
    };
    for fast_lines in [true, false] {
        let (out, warnings) = klipper_stream(text, without, fast_lines);
        let skipped: Vec<(u64, WarningKind)> =
            (2..=5).map(|l| (l, WarningKind::UnknownCommand)).collect();
        assert_eq!(warnings, skipped, "fast path {fast_lines}");
        let targets: Vec<[f64; 4]> = out
            .iter()
            .map(|c| match c {
                Ok(Command::Move(m)) => m.target,
                other => panic!("only the two moves are left, not {other:?}"),
            })
            .collect();
        assert_eq!(targets, [[10.0, 0.0, 0.0, 0.0], [20.0, 0.0, 0.0, 0.0]]);
        let (out, warnings) = klipper_stream(text, CommandSet::ALL, fast_lines);
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(
            out.iter()
                .filter(|c| matches!(c, Ok(Command::Arc(_))))
                .count(),
            2
        );
    }
}

#[test]
fn klipper_refuses_inch_units_whatever_the_command_set_says() {
    let (out, _) = klipper_stream("G21\nG20\nG1 X1\n", CommandSet::ALL, true);
    assert_eq!(out.first().map(Result::is_err), Some(true), "{out:?}");
    assert!(
        matches!(out[0], Err(ErrorKind::InchUnitsUnsupported)),
        "{out:?}"
    );
    let (commands, _) = run("G20\nG1 X1\n");
    assert_eq!(
        moves(&commands)[0].target[0],
        25.4,
        "other firmware reads inches"
    );
}
