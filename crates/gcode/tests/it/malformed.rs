//! Malformed input: each case asserts the error kind, line and column; nothing panics, and the stream
//! continues after a bad line.

use gcode::{Command, Commands, ErrorKind, GcodeError};

/// All results of interpreting `input`.
fn run(input: &[u8]) -> (Vec<Command>, Vec<GcodeError>) {
    let mut commands = Vec::new();
    let mut errors = Vec::new();
    for result in Commands::from_reader(input, "bad.gcode") {
        match result {
            Ok(command) => commands.push(command.value),
            Err(err) => errors.push(err),
        }
    }
    (commands, errors)
}

fn first_error(input: &[u8]) -> GcodeError {
    let (_, errors) = run(input);
    errors
        .into_iter()
        .next()
        .unwrap_or_else(|| panic!("no error for {:?}", String::from_utf8_lossy(input)))
}

/// (input, expected kind, line, column)
type Case = (&'static [u8], ErrorKind, u64, u32);

fn cases() -> Vec<Case> {
    let mut cases = lexer_cases();
    cases.extend(interpreter_cases());
    cases
}

/// Bytes the reader or the lexer refuses.
fn lexer_cases() -> Vec<Case> {
    vec![
        (b"G1 X1.2.3 Y1", ErrorKind::InvalidNumber, 1, 4),
        (b"G1 X- Y1", ErrorKind::InvalidNumber, 1, 4),
        (b"G1 X.", ErrorKind::InvalidNumber, 1, 4),
        (b"G1 Xabc", ErrorKind::InvalidNumber, 1, 4),
        (b"G1 Y2 Xnan", ErrorKind::InvalidNumber, 1, 7),
        (b"G1 XINF", ErrorKind::InvalidNumber, 1, 4),
        (b"G1 X1e999", ErrorKind::ExponentNotAllowed, 1, 4),
        (b"G1 X10 Y1e5", ErrorKind::ExponentNotAllowed, 1, 8),
        (b"G1 X1 #5", ErrorKind::UnexpectedCharacter('#'), 1, 7),
        (b"G1 X1 ?", ErrorKind::UnexpectedCharacter('?'), 1, 7),
        (b"-5 G1", ErrorKind::UnexpectedCharacter('-'), 1, 1),
        (
            b"N1 G1 X1*99",
            ErrorKind::ChecksumMismatch {
                written: 99,
                computed: 96,
            },
            1,
            9,
        ),
        (b"N1 G1 X1*", ErrorKind::MalformedChecksum, 1, 9),
        (b"G1 (unclosed X1", ErrorKind::UnterminatedComment, 1, 4),
        (b"G1 X1\nG1 X\xff2", ErrorKind::InvalidUtf8, 2, 5),
        (
            b"EXCLUDE_OBJECT_START NAME",
            ErrorKind::MalformedParameter,
            1,
            22,
        ),
        (
            b"RESPOND MSG=\"unterminated",
            ErrorKind::UnterminatedString,
            1,
            13,
        ),
        (
            b"N99999999999999999999999 G1",
            ErrorKind::NumberOverflow,
            1,
            1,
        ),
        (b"G99999999999 X1", ErrorKind::NumberOverflow, 1, 1),
        (
            b"G1 X1\r\nG1 X2\r\nG1 X1..2",
            ErrorKind::InvalidNumber,
            3,
            4,
        ),
        (
            b"\x00\x01\x02\xfe\xff\x80garbage",
            ErrorKind::InvalidUtf8,
            1,
            4,
        ),
        (
            b"\x00\x01binary",
            ErrorKind::UnexpectedCharacter('\0'),
            1,
            1,
        ),
    ]
}

/// Lines that lex but that the interpreter refuses.
fn interpreter_cases() -> Vec<Case> {
    vec![
        (b"G1 X1 F0", ErrorKind::InvalidFeedRate, 1, 7),
        (b"G1 X1 F-10", ErrorKind::InvalidFeedRate, 1, 7),
        (b"G1 X", ErrorKind::InvalidParameter("X".into()), 1, 4),
        (b"G1 X10 Y10\nG2 X20 Y0", ErrorKind::ArcMissingCentre, 2, 1),
        (
            b"G1 X10 Y0\nG2 X0 Y10 I-10 J5",
            ErrorKind::ArcInconsistent {
                start_radius: 0.0,
                end_radius: 0.0,
            },
            2,
            1,
        ),
        (b"G2 X10 Y0 R4.9", ErrorKind::ArcRadiusTooSmall, 1, 1),
        (b"G91\nG2 X10 Y0 I5", ErrorKind::ArcRelativeMode, 2, 1),
        (b"G2 X0 Y0 I0 J0", ErrorKind::ArcZeroRadius, 1, 1),
        (b"G1 X10 Y0\nG2 X10 Y0 R100", ErrorKind::ArcRClosed, 2, 1),
        (b"G1 X10 Y0\nG2 X20 Y0 R0", ErrorKind::ArcZeroRadius, 2, 1),
        (b"G18\nG3 X1 Z1 I1", ErrorKind::ArcPlaneUnsupported, 2, 1),
        (b"G4 P-5", ErrorKind::NegativeDwell, 1, 4),
        (b"M220 S0", ErrorKind::InvalidParameter("S".into()), 1, 6),
        (
            b"SET_VELOCITY_LIMIT ACCEL=fast",
            ErrorKind::InvalidParameter("ACCEL".into()),
            1,
            20,
        ),
    ]
}

fn same_kind(a: &ErrorKind, b: &ErrorKind) -> bool {
    match (a, b) {
        (ErrorKind::ArcInconsistent { .. }, ErrorKind::ArcInconsistent { .. }) => true,
        _ => a == b,
    }
}

#[test]
fn malformed_inputs_report_kind_line_and_column() {
    let cases = cases();
    assert!(cases.len() >= 25);
    for (input, kind, line, column) in cases {
        let err = first_error(input);
        let shown = String::from_utf8_lossy(input);
        assert!(
            same_kind(&err.kind, &kind),
            "{shown:?}: got {:?}, expected {kind:?}",
            err.kind
        );
        assert_eq!(
            (err.span.line, err.span.column),
            (line, column),
            "{shown:?}: {err}"
        );
        assert_eq!(err.to_string().split(':').next(), Some("bad.gcode"));
    }
}

#[test]
fn inconsistent_arc_reports_both_radii() {
    let err = first_error(b"G1 X10 Y0\nG2 X0 Y10 I-10 J5");
    let ErrorKind::ArcInconsistent {
        start_radius,
        end_radius,
    } = err.kind
    else {
        panic!("{err}")
    };
    assert!((start_radius - 125f64.sqrt()).abs() < 1e-12);
    assert!((end_radius - 125f64.sqrt()).abs() > 1.0);
}

#[test]
fn the_stream_continues_after_an_error() {
    let (commands, errors) = run(b"G1 X1\nG1 X1.2.3\nG1 X3\n");
    assert_eq!(errors.len(), 1);
    let xs: Vec<f64> = commands
        .iter()
        .filter_map(|c| {
            if let Command::Move(m) = c {
                Some(m.target[0])
            } else {
                None
            }
        })
        .collect();
    assert_eq!(xs, vec![1.0, 3.0]);
}

#[test]
fn a_failed_line_leaves_the_state_unchanged() {
    let (commands, errors) = run(b"G1 X5 F600\nG1 X7 F0\nG1 Y1\n");
    assert_eq!(errors.len(), 1);
    let Some(Command::Move(last)) = commands.last() else {
        panic!("no move")
    };
    assert_eq!(last.target, [5.0, 1.0, 0.0, 0.0]);
    assert_eq!(last.feed, 10.0);
}

#[test]
fn empty_input_is_fine() {
    let (commands, errors) = run(b"");
    assert!(commands.is_empty() && errors.is_empty());
    let (commands, errors) = run(b"\n\r\n   \n; only a comment\n");
    assert!(commands.is_empty() && errors.is_empty());
}

#[test]
fn ten_megabyte_lines_are_handled_in_linear_time() {
    let started = std::time::Instant::now();
    let mut comment = b";".to_vec();
    comment.extend(std::iter::repeat_n(b'A', 10 << 20));
    comment.extend_from_slice(b"\nG1 X1\n");
    let (commands, errors) = run(&comment);
    assert!(errors.is_empty());
    assert_eq!(commands.len(), 1);

    let mut number = b"G1 X".to_vec();
    number.extend(std::iter::repeat_n(b'9', 10 << 20));
    let err = first_error(&number);
    assert_eq!((err.kind, err.span.column), (ErrorKind::NumberOverflow, 4));
    assert!(
        err.line_text.len() <= 200,
        "the error keeps only a window of the line"
    );

    let mut garbage = b"G1 X1 ".to_vec();
    garbage.extend(std::iter::repeat_n(b'@', 10 << 20));
    let err = first_error(&garbage);
    assert_eq!(
        (err.kind, err.span.column),
        (ErrorKind::UnexpectedCharacter('@'), 7)
    );
    // Quadratic behaviour on 10 MB would take minutes even in release mode.
    assert!(
        started.elapsed().as_secs() < 60,
        "took {:?}",
        started.elapsed()
    );
}
