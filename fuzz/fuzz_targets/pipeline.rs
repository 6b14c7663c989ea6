//! Fuzz target `pipeline`: arbitrary G-code bytes through the whole `run` pipeline (interpreter, planner with
//! lookahead, step generation, the step audit) on the fixed example Cartesian machine, built and run exactly as
//! `jointspace run` builds and runs it (`machine::Machine`, `printjob::run`).
//!
//! Invariants: no panic; a successful run has a finite, non-negative print time; every motor's step stream passes
//! the audit an MCU needs (clocks never repeat or go back, net steps where the planned path takes the motor): a
//! G-code file may be refused, but never with a step stream no MCU could run — unless it raises the machine's
//! speed limit (`SET_VELOCITY_LIMIT`), when the audit refusing what no MCU could step is the right answer.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use printjob::{RunError, RunOptions};

const MACHINE: &str = include_str!("../../examples/machines/cartesian.cfg");

fn machine() -> &'static machine::Machine {
    static MACHINE_BUILT: OnceLock<machine::Machine> = OnceLock::new();
    MACHINE_BUILT.get_or_init(|| {
        machine::Machine::from_text(MACHINE, "examples/machines/cartesian.cfg")
            .expect("example machine is valid")
    })
}

fuzz_target!(|data: &[u8]| {
    match printjob::run(machine(), data, "fuzz.gcode", &RunOptions::default(), || false) {
        Ok(summary) => assert!(
            summary.print_time_s.is_finite() && summary.print_time_s >= 0.0,
            "print time {}",
            summary.print_time_s
        ),
        Err(RunError::Steps(e)) if !raises_speed_limit(data) => {
            panic!("a step stream no MCU could run: {e}")
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});

/// Whether the file may raise the configured speed limit beyond what the motors can step.
fn raises_speed_limit(data: &[u8]) -> bool {
    const COMMAND: &[u8] = b"SET_VELOCITY_LIMIT";
    data.windows(COMMAND.len()).any(|w| w.eq_ignore_ascii_case(COMMAND))
}
