//! Fuzz target `lexer`: arbitrary bytes through the G-code reader and the modal interpreter.
//!
//! Invariants checked beyond "no panic": every command the interpreter yields is finite (a NaN or infinite
//! coordinate must be an error, never a move), and every error names a line that exists.
#![no_main]

use gcode::{Command, Commands};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // CR, LF and CR LF all end a line; counting CR and LF separately bounds the line count from above.
    let lines = data.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u64 + 1;
    let mut commands = Commands::from_reader(data, "fuzz.gcode");
    while let Some(result) = commands.next_command() {
        match result {
            Ok(command) => check_finite(&command.value),
            Err(e) => {
                assert!(
                    e.span.line >= 1 && e.span.line <= lines,
                    "error on line {} of {lines}",
                    e.span.line
                );
                // Rendering the message must not panic either.
                let _ = e.to_string();
            }
        }
    }
});

/// A command with a non-finite number would reach the planner as NaN steps. (Commands kept as text, such as
/// `M117 NaN`, legitimately carry any word.)
fn check_finite(command: &Command) {
    let numbers: Vec<f64> = match command {
        Command::Move(m) => m.target.iter().copied().chain([m.feed]).collect(),
        Command::Arc(a) => a
            .start
            .iter()
            .chain(&a.target)
            .chain(&a.centre)
            .chain(&a.offset)
            .chain(&a.base)
            .copied()
            .chain([a.feed, a.extrude_factor])
            .chain(a.e_written)
            .collect(),
        Command::Dwell { seconds } => vec![*seconds],
        Command::SetPosition { position } => position.iter().flatten().copied().collect(),
        Command::SetKinematicPosition { position } => position.iter().flatten().copied().collect(),
        Command::SpeedFactor(v) | Command::ExtrudeFactor(v) => vec![*v],
        _ => Vec::new(),
    };
    assert!(
        numbers.iter().all(|v| v.is_finite()),
        "non-finite number in {command:?}"
    );
}
