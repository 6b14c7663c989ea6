//! Fuzz target `convert`: arbitrary G-code bytes converted for a polar machine (cylindrical output, adaptive
//! segmentation); every move the converter writes must carry finite numbers.
#![no_main]

use std::sync::OnceLock;

use convert::{AxisMap, ConvertOptions, Converter, Target, convert_gcode};
use libfuzzer_sys::fuzz_target;

const MACHINE: &str = include_str!("../../examples/machines/polar.cfg");

fn axis_map() -> &'static AxisMap {
    static MAP: OnceLock<AxisMap> = OnceLock::new();
    MAP.get_or_init(|| {
        let machine = machine::Machine::from_text(MACHINE, "examples/machines/polar.cfg")
            .expect("example machine is valid");
        AxisMap::motors(machine.setup.kinematics.clone(), Target::Cylindrical)
            .expect("polar axis map")
    })
}

/// Coordinates (mm) beyond which this target skips the input. `convert` neither refuses nor bounds a move to
/// a point far outside the machine (`G1 X-999999999999999999999` runs for ever): a known, reported finding,
/// kept in `crates/cli/tests/fuzz_regressions/convert-timeout-huge-coordinate.gcode` and the catalogue case
/// `convert-absurd-coordinate`. Remove this filter once `convert` checks reach first.
const MAX_COORDINATE: f64 = 1e4;

/// Whether any move or arc of `data` goes further than [`MAX_COORDINATE`] from the origin on an axis.
fn goes_far_outside(data: &[u8]) -> bool {
    gcode::Commands::from_reader(data, "fuzz.gcode").any(|c| match c {
        Ok(c) => match c.value {
            gcode::Command::Move(m) => m.target[..3].iter().any(|v| !(v.abs() <= MAX_COORDINATE)),
            gcode::Command::Arc(a) => {
                let radius = a.offset[0].hypot(a.offset[1]);
                a.target[..3].iter().any(|v| !(v.abs() <= MAX_COORDINATE))
                    || !(radius <= MAX_COORDINATE)
            }
            _ => false,
        },
        Err(_) => false,
    })
}

fuzz_target!(|data: &[u8]| {
    if goes_far_outside(data) {
        return;
    }
    // Homed, as the CLI converts (without a homing pose most inputs stop at their first unset Z).
    let options = ConvertOptions {
        home: Some([100.0, 0.0, 0.0]),
        ..ConvertOptions::default()
    };
    let Ok(mut converter) = Converter::new(axis_map().clone(), options, Vec::new()) else {
        return;
    };
    if convert_gcode(data, "fuzz.gcode", &mut converter).is_err() {
        return;
    }
    if let Ok((out, _stats)) = converter.finish() {
        let text = String::from_utf8_lossy(&out);
        for line in text.lines().filter(|l| is_motion_line(l)) {
            assert!(
                numbers_are_finite(line),
                "non-finite number in a written move: {line}"
            );
        }
    }
});

/// Lines the converter writes itself (comments and other commands pass through as the input had them).
fn is_motion_line(line: &str) -> bool {
    let command = line.split_whitespace().next().unwrap_or("");
    matches!(command, "G0" | "G1" | "G2" | "G3" | "G92")
}

/// Every `LETTERvalue` word before a `;` comment has a finite value.
fn numbers_are_finite(line: &str) -> bool {
    let code = line.split(';').next().unwrap_or("");
    code.split_whitespace().skip(1).all(|word| {
        word.get(1..)
            .is_none_or(|v| v.parse::<f64>().is_ok_and(f64::is_finite))
    })
}
