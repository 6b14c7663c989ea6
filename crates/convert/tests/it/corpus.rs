//! Round trips of every corpus file on a polar machine (part centred on the bed, radius ≤ 300 mm) and on
//! the FEKT SCARA (part centred at (0, 130), scaled down to fit a 60 mm radius there), and the comparison
//! with Marlin's and RepRapFirmware's fixed segmentation.

use convert::{AxisMap, ConvertOptions, Segmentation, Target, VerifyReport};
use gcode::Command;

use crate::common::{corpus_files, placement, round_trip};
use crate::machines;

const TOLERANCE: f64 = Segmentation::DEFAULT_TOLERANCE;

struct Setup {
    map: AxisMap,
    options: ConvertOptions,
}

fn polar_setup(commands: &[Command]) -> Setup {
    let (scale, translate) = placement(commands, [0.0, 0.0], 300.0);
    let map = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("polar map");
    Setup { map, options: ConvertOptions { scale_xy: scale, translate, ..ConvertOptions::default() } }
}

fn scara_setup(commands: &[Command]) -> Setup {
    let (scale, translate) = placement(commands, [0.0, 130.0], 60.0);
    let map = AxisMap::motors(machines::scara(), Target::Joints).expect("SCARA map");
    Setup { map, options: ConvertOptions { scale_xy: scale, translate, ..ConvertOptions::default() } }
}

fn assert_faithful(name: &str, machine: &str, r: &VerifyReport, tolerance: f64) {
    println!(
        "{machine:6} {name:45} max {:.5} rms {:.5} mm, E {:.4}/{:.4}, time {:.1}/{:.1} s (flips {:.2} s), {} segments",
        r.max_deviation, r.rms_deviation, r.extrusion_in, r.extrusion_out, r.time_in, r.time_out, r.flip_time, r.segments
    );
    assert_eq!(r.unmatched, 0, "{name}: written segments off the path");
    assert!(r.max_deviation <= tolerance, "{name} on {machine}: deviation {} at {:?}", r.max_deviation, r.worst_point);
    // Relative to at least 1 mm: KISSlicer writes per-move E without M83, which absolute E (Klipper's
    // default) reads as a net extrusion of zero.
    let e_error = (r.extrusion_out - r.extrusion_in).abs() / r.extrusion_in.abs().max(1.0);
    assert!(e_error <= 1e-6, "{name}: extrusion {} vs {}", r.extrusion_out, r.extrusion_in);
    // Rotations in place at the exact polar centre have no Cartesian counterpart: reported, not compared.
    let t_error = (r.time_out - r.flip_time - r.time_in).abs() / r.time_in;
    assert!(t_error <= 0.005, "{name}: time {} (flips {}) vs {}", r.time_out, r.flip_time, r.time_in);
}

fn corpus_round_trip(machine: &str, setup: fn(&[Command]) -> Setup) {
    for (name, text) in corpus_files() {
        let commands = convert::read_commands(&text[..], &name).expect("corpus parses");
        let s = setup(&commands);
        let (_, _, report) = round_trip(&s.map, &s.options, &text);
        assert_faithful(&name, machine, &report, TOLERANCE);
    }
}

#[test]
fn corpus_round_trip_polar() {
    corpus_round_trip("polar", polar_setup);
}

#[test]
fn corpus_round_trip_scara() {
    corpus_round_trip("scara", scara_setup);
}

/// Decimals fine enough that rounding does not mask deviations of a few ten-thousandths of a mm.
const FINE: convert::Decimals = convert::Decimals { linear: 6, angle: 8, extrusion: 5 };

struct Row {
    max: f64,
    segments: u64,
}

fn measure(s: &Setup, text: &[u8], segmentation: Segmentation) -> Row {
    let options = ConvertOptions { segmentation, decimals: FINE, ..s.options.clone() };
    let (_, _, r) = round_trip(&s.map, &options, text);
    assert_eq!(r.unmatched, 0);
    Row { max: r.max_deviation, segments: r.segments }
}

/// Ours against a fixed rule: at the tolerance `min(default, fixed max / 10)`, ours must reach a ≥ 10×
/// smaller maximum deviation with no more segments.
fn compare(name: &str, machine: &str, s: &Setup, text: &[u8], label: &str, fixed: Segmentation) {
    let theirs = measure(s, text, fixed);
    let tolerance = TOLERANCE.min(theirs.max / 10.0);
    let ours = measure(s, text, Segmentation::Adaptive { tolerance });
    println!(
        "| {machine:6} | {name:45} | {label:6} | {:>9.5} | {:>7} | {:>9.5} | {:>7} | {:>9.1} |",
        theirs.max,
        theirs.segments,
        ours.max,
        ours.segments,
        theirs.max / ours.max.max(1e-12)
    );
    let default = measure(s, text, Segmentation::default());
    println!("    default tolerance: max {:.5} segs {}", default.max, default.segments);
}

fn fixed_comparison(machine: &str, setup: fn(&[Command]) -> Setup, marlin: Segmentation) {
    println!("| machine | file | rule | their max mm | their segs | our max mm | our segs | ratio |");
    for (name, text) in corpus_files() {
        let commands = convert::read_commands(&text[..], &name).expect("corpus parses");
        let s = setup(&commands);
        compare(&name, machine, &s, &text, "Marlin", marlin);
        compare(&name, machine, &s, &text, "RRF", Segmentation::RRF);
    }
}

#[test]
fn fixed_segmentation_comparison_polar() {
    fixed_comparison("polar", polar_setup, Segmentation::MARLIN_POLAR);
}

#[test]
fn fixed_segmentation_comparison_scara() {
    fixed_comparison("scara", scara_setup, Segmentation::MARLIN);
}
