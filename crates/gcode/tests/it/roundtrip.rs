//! parse → write → parse gives the same commands and values on every corpus file.

use std::io::BufReader;
use std::path::Path;

use gcode::{Command, Commands, Decimals, NumberFormat, Reader, Writer, WriterOptions};

use crate::{corpus_files, file_name};

fn commands_of(input: &[u8]) -> Vec<Command> {
    Commands::from_reader(input, "mem")
        .map(|c| c.unwrap_or_else(|e| panic!("{e}")).value)
        .collect()
}

fn rewrite(path: &Path, options: WriterOptions) -> Vec<u8> {
    let file = std::fs::File::open(path).expect("open");
    let mut reader = Reader::new(BufReader::new(file), file_name(path));
    let mut writer = Writer::new(Vec::new(), options);
    while let Some(line) = reader.next_line() {
        writer
            .write_line(&line.unwrap_or_else(|e| panic!("{e}")))
            .expect("write to memory");
    }
    writer.into_inner()
}

fn assert_same_commands(path: &Path, options: WriterOptions) {
    let name = file_name(path);
    let original = std::fs::read(path).expect("read");
    let expected = commands_of(&original);
    let written = rewrite(path, options);
    let again = commands_of(&written);
    assert_eq!(expected.len(), again.len(), "{name}: command count");
    for (i, (a, b)) in expected.iter().zip(&again).enumerate() {
        assert_eq!(a, b, "{name}: command {i}");
    }
}

#[test]
fn shortest_numbers_round_trip_exactly() {
    let Some(files) = corpus_files() else { return };
    let options = WriterOptions {
        numbers: NumberFormat::Shortest,
        ..WriterOptions::default()
    };
    for path in &files {
        assert_same_commands(path, options);
    }
}

/// The corpus has at most 3 decimals on X Y Z, 5 on E and F (Bambu writes `F1680.297`): fixed decimals
/// of that size lose nothing of what the interpreter uses.
#[test]
fn fixed_decimals_round_trip_slicer_output() {
    let Some(files) = corpus_files() else { return };
    let decimals = Decimals {
        xyz: 3,
        e: 5,
        f: 5,
        other: 4,
    };
    let options = WriterOptions {
        numbers: NumberFormat::Fixed(decimals),
        ..WriterOptions::default()
    };
    for path in &files {
        assert_same_commands(path, options);
    }
}

/// Without comments the metadata goes, but every other command survives.
#[test]
fn dropping_comments_keeps_every_other_command() {
    let Some(files) = corpus_files() else { return };
    let options = WriterOptions {
        numbers: NumberFormat::Shortest,
        keep_comments: false,
        ..WriterOptions::default()
    };
    for path in &files {
        let name = file_name(path);
        let not_meta = |c: &Command| !matches!(c, Command::Meta(_));
        let expected: Vec<Command> = commands_of(&std::fs::read(path).expect("read"))
            .into_iter()
            .filter(not_meta)
            .collect();
        let again: Vec<Command> = commands_of(&rewrite(path, options))
            .into_iter()
            .filter(not_meta)
            .collect();
        assert!(
            expected == again,
            "{name}: commands differ without comments"
        );
    }
}

#[test]
fn fixed_decimals_bound_the_error() {
    let input = b"G1 X1.23456789 Y-0.00049 E0.1234567 F1234.56\n";
    let options = WriterOptions {
        numbers: NumberFormat::Fixed(Decimals {
            xyz: 3,
            e: 5,
            f: 1,
            other: 4,
        }),
        ..WriterOptions::default()
    };
    let mut reader = Reader::new(&input[..], "mem");
    let mut writer = Writer::new(Vec::new(), options);
    while let Some(line) = reader.next_line() {
        writer.write_line(&line.expect("line")).expect("write");
    }
    assert_eq!(
        String::from_utf8(writer.into_inner()).ok().as_deref(),
        Some("G1 X1.235 Y0 E0.12346 F1234.6\n")
    );
}
