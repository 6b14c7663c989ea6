//! Round trips of every corpus file on a polar machine (part centred on the bed, radius ≤ 300 mm) and on
//! the FEKT SCARA (part centred at (0, 130), scaled down to fit a 60 mm radius there), and the comparison
//! with Marlin's and RepRapFirmware's fixed segmentation.

use convert::{AxisMap, ConvertOptions, SegmentDeviation, Segmentation, Target, VerifyReport};
use gcode::Command;

use crate::common::{convert_text, corpus_files, placement, round_trip};
use crate::machines;

const TOLERANCE: f64 = Segmentation::DEFAULT_TOLERANCE;

struct Setup {
    map: AxisMap,
    options: ConvertOptions,
}

fn polar_setup(commands: &[Command]) -> Setup {
    let (scale, translate) = placement(commands, [0.0, 0.0], 300.0);
    let map = AxisMap::motors(machines::polar(), Target::Cylindrical).expect("polar map");
    Setup {
        map,
        options: ConvertOptions {
            scale_xy: scale,
            translate,
            ..crate::common::homed()
        },
    }
}

fn scara_setup(commands: &[Command]) -> Setup {
    let (scale, translate) = placement(commands, [0.0, 130.0], 60.0);
    let map = AxisMap::motors(machines::scara(), Target::Joints).expect("SCARA map");
    Setup {
        map,
        options: ConvertOptions {
            scale_xy: scale,
            translate,
            ..crate::common::homed()
        },
    }
}

fn assert_faithful(name: &str, machine: &str, r: &VerifyReport, tolerance: f64) {
    println!(
        "{machine:6} {name:45} max {:.5} rms {:.5} mm, E {:.4}/{:.4}, time {:.1}/{:.1} s (flips {:.2} s), {} segments",
        r.max_deviation,
        r.rms_deviation,
        r.extrusion_in,
        r.extrusion_out,
        r.time_in,
        r.time_out,
        r.flip_time,
        r.segments
    );
    assert_eq!(r.unmatched, 0, "{name}: written segments off the path");
    assert!(
        r.max_deviation <= tolerance,
        "{name} on {machine}: deviation {} at {:?}",
        r.max_deviation,
        r.worst_point
    );
    // Relative to at least 1 mm: KISSlicer writes per-move E without M83, which absolute E (Klipper's
    // default) reads as a net extrusion of zero.
    let e_error = (r.extrusion_out - r.extrusion_in).abs() / r.extrusion_in.abs().max(1.0);
    assert!(
        e_error <= 1e-6,
        "{name}: extrusion {} vs {}",
        r.extrusion_out,
        r.extrusion_in
    );
    // Rotations in place at the exact polar centre have no Cartesian counterpart: reported, not compared.
    let t_error = (r.time_out - r.flip_time - r.time_in).abs() / r.time_in;
    assert!(
        t_error <= 0.005,
        "{name}: time {} (flips {}) vs {}",
        r.time_out,
        r.flip_time,
        r.time_in
    );
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

#[test]
fn other_output_conventions_round_trip() {
    // Inverse-time feed, absolute E, R/T letters and radians on two corpus files (one with arcs).
    for (name, text) in corpus_files()
        .into_iter()
        .filter(|(n, _)| n.contains("mini-cube") || n.contains("arcs"))
    {
        let commands = convert::read_commands(&text[..], &name).expect("corpus parses");
        let s = polar_setup(&commands);
        let options = ConvertOptions {
            feed: convert::FeedMode::InverseTime,
            extrusion: convert::Extrusion::Absolute,
            axis_letters: Some(['R', 'T']),
            angle_unit: convert::AngleUnit::Radians,
            decimals: convert::Decimals {
                linear: 4,
                angle: 8,
                extrusion: 5,
            },
            ..s.options
        };
        let (_, _, report) = round_trip(&s.map, &options, &text);
        assert_faithful(&name, "polar", &report, TOLERANCE);
    }
}

/// Decimals fine enough that rounding does not mask deviations of a few hundred-thousandths of a mm.
const FINE: convert::Decimals = convert::Decimals {
    linear: 6,
    angle: 8,
    extrusion: 5,
};

#[derive(Debug, Clone, Copy, Default)]
struct Row {
    max: f64,
    segments: u64,
}

fn measure(s: &Setup, text: &[u8], segmentation: Segmentation) -> Row {
    let options = ConvertOptions {
        segmentation,
        decimals: FINE,
        ..s.options.clone()
    };
    let (_, _, r) = round_trip(&s.map, &options, text);
    assert_eq!(r.unmatched, 0);
    Row {
        max: r.max_deviation,
        segments: r.segments,
    }
}

/// One row of the comparison: a file on a machine against one firmware's fixed rule.
struct Comparison {
    theirs: Row,
    /// Ours at a tolerance of a tenth of their maximum deviation.
    ours: Row,
    /// The fewest segments any segmentation needs for that tolerance, estimated from their segments.
    needed: u64,
}

impl Comparison {
    fn holds(&self) -> bool {
        self.ours.segments <= self.theirs.segments
    }
}

/// Their segments with the deviation each has, converted with `fixed`.
fn measure_each(s: &Setup, text: &[u8], fixed: Segmentation) -> (Row, Vec<SegmentDeviation>) {
    let options = ConvertOptions {
        segmentation: fixed,
        decimals: FINE,
        ..s.options.clone()
    };
    let (out, _) = convert_text(&s.map, &options, text).expect("conversion succeeds");
    let commands = convert::read_commands(text, "test.gcode").expect("input parses");
    let mut each = Vec::new();
    let r = convert::verify_segments(&s.map, &options, &commands, out.as_bytes(), |d| {
        each.push(d)
    })
    .expect("output readable");
    assert_eq!(r.unmatched, 0);
    let row = Row {
        max: r.max_deviation,
        segments: r.segments,
    };
    (row, each)
}

/// The fewest segments any segmentation needs for `tolerance`, estimated from segments measured under another
/// rule: the chord error of a piece grows with the square of its length, so a stretch written as one segment
/// with deviation `e` needs at least `√(e / tolerance)` pieces (a fraction: neighbours may share one); each
/// move needs at least one; lines without XY motion count one each on both sides.
fn segments_needed(total: u64, each: &[SegmentDeviation], tolerance: f64) -> u64 {
    let mut needed = total - each.len() as u64;
    let mut within_move = 0.0;
    for d in each {
        within_move += (d.max / tolerance).sqrt();
        if d.ends_move {
            // A relative 1e-9 keeps a move whose pieces sum to exactly k at k.
            needed += (within_move * (1.0 - 1e-9)).ceil().max(1.0) as u64;
            within_move = 0.0;
        }
    }
    if within_move > 0.0 {
        needed += (within_move * (1.0 - 1e-9)).ceil().max(1.0) as u64;
    }
    needed
}

/// One file against one fixed rule: ours at a tenth of their maximum deviation must stay within that
/// tolerance; the row reports whether that took no more segments than their rule, and how many any
/// segmentation needs there.
fn compare(s: &Setup, text: &[u8], fixed: Segmentation) -> Comparison {
    let (theirs, each) = measure_each(s, text, fixed);
    let tolerance = theirs.max / 10.0;
    let ours = measure(s, text, Segmentation::Adaptive { tolerance });
    assert!(
        ours.max <= tolerance,
        "tolerance {tolerance} exceeded: {}",
        ours.max
    );
    Comparison {
        theirs,
        ours,
        needed: segments_needed(theirs.segments, &each, tolerance),
    }
}

/// How far above the estimated minimum our count may be: the estimate lets neighbouring pieces share
/// fractions, and the probe-checked machines (SCARA) keep a 10% margin of the tolerance.
const ABOVE_MINIMUM: f64 = 1.15;

/// Every file against both fixed rules: ours at a tenth of their maximum deviation must need no more
/// segments than they do, except where the estimated minimum for any segmentation already exceeds their
/// count (their deviation is spread evenly over short segments: 10× less error needs ≈ √10× more
/// segments there); everywhere ours stays near that minimum.
fn fixed_comparison(machine: &str, setup: fn(&[Command]) -> Setup, marlin: Segmentation) {
    println!(
        "| machine | file | rule | their max mm | their segs | our tolerance | our max mm | our segs | needed | ≤ segs |"
    );
    let mut failures = Vec::new();
    let (mut rows, mut holding) = (0, 0);
    for (name, text) in corpus_files() {
        let commands = convert::read_commands(&text[..], &name).expect("corpus parses");
        let s = setup(&commands);
        for (label, rule) in [("Marlin", marlin), ("RRF", Segmentation::RRF)] {
            let c = compare(&s, &text, rule);
            println!(
                "| {machine:6} | {name:45} | {label:6} | {:>9.6} | {:>7} | {:>9.6} | {:>9.6} | {:>7} | {:>7} | {:>5} |",
                c.theirs.max,
                c.theirs.segments,
                c.theirs.max / 10.0,
                c.ours.max,
                c.ours.segments,
                c.needed,
                c.holds()
            );
            rows += 1;
            holding += usize::from(c.holds());
            if !(c.holds() || c.needed > c.theirs.segments) {
                failures.push(format!(
                    "{name} {label}: more segments, though fewer would do"
                ));
            }
            if c.ours.segments as f64 > c.needed as f64 * ABOVE_MINIMUM {
                failures.push(format!("{name} {label}: far above the minimum"));
            }
        }
    }
    println!(
        "{machine}: no more segments than the fixed rule in {holding}/{rows} rows; in the others the minimum exceeds their count"
    );
    assert!(failures.is_empty(), "{machine}: {failures:?}");
}

#[test]
fn fixed_segmentation_comparison_polar() {
    fixed_comparison("polar", polar_setup, Segmentation::MARLIN_POLAR);
}

#[test]
fn fixed_segmentation_comparison_scara() {
    fixed_comparison("scara", scara_setup, Segmentation::MARLIN);
}
