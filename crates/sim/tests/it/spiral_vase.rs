//! A spiral vase (Z climbs while extruding): one layer per turn, as the slicer's layer markers count them, and
//! a report of bounded size.

use std::path::PathBuf;

use crate::common::polar_pair;
use sim::{Machine, ReplayOptions, Report, RunReport};

fn corpus_vase() -> Option<Vec<u8>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/corpus/prusaslicer-2.7.4_spiral-vase.gcode");
    match std::fs::read(&path) {
        Ok(bytes) => Some(bytes),
        Err(_) => {
            println!("SKIPPED: {} not found", path.display());
            None
        }
    }
}

#[test]
fn a_spiral_vase_has_one_layer_per_turn_and_a_bounded_report() {
    let Some(gcode) = corpus_vase() else { return };
    let (believed, actual_cfg) = polar_pair("arm_lateral_offset: 0.5", "");
    let actual = Machine::from_config(&actual_cfg).expect("actual machine");
    let sim = sim::simulate(
        &believed,
        &actual,
        &gcode[..],
        "vase.gcode",
        &ReplayOptions::default(),
    )
    .expect("simulates");
    let markers = gcode
        .split(|&b| b == b'\n')
        .filter(|l| l.starts_with(b";LAYER_CHANGE"))
        .count();
    let layers = &sim.replay.layers;
    let zs: Vec<String> = layers
        .iter()
        .take(12)
        .map(|l| format!("{:.3}–{:.3}", l.z, l.z_max))
        .collect();
    println!(
        "{} layers found, {markers} slicer layer markers (+1 prime line); first rows {zs:?}",
        sim.replay.layer_count
    );
    // The prime line is extruded before the first marker; each turn is one layer.
    let expected = markers + 1;
    assert!(
        sim.replay.layer_count.abs_diff(expected) <= expected / 100,
        "{} layers against {expected}",
        sim.replay.layer_count
    );
    // Every turn climbs about one layer height (0.3 mm); none is a sliver.
    let spiral = &layers[3..layers.len() - 2];
    for l in spiral {
        assert!(l.count == 1 && l.z_max - l.z < 0.4, "{l:?}");
    }

    let dir = tempfile::tempdir().expect("tempdir");
    let report = Report {
        believed_config: "believed.cfg".into(),
        actual_config: "actual.cfg".into(),
        gcode: "vase.gcode".into(),
        before: RunReport::new(&sim),
        correction: None,
        after: None,
        after_missing: None,
    };
    sim::write_report(dir.path(), &report, &sim, None).expect("report written");
    let text = std::fs::read_to_string(dir.path().join("report.txt")).expect("text");
    let json_len = std::fs::metadata(dir.path().join("report.json"))
        .expect("json")
        .len();
    println!(
        "report.txt {} bytes, {} lines; report.json {json_len} bytes",
        text.len(),
        text.lines().count()
    );
    assert!(text.lines().count() <= 2 * sim::report::MAX_REPORTED_LAYERS + 50);
    assert!(text.len() < 64 << 10 && json_len < 1 << 20);
    assert!(report.before.layers.len() <= sim::report::MAX_REPORTED_LAYERS);
    assert_eq!(
        report.before.layers.iter().map(|l| l.layers).sum::<usize>(),
        sim.replay.layer_count
    );
    assert!(text.contains(&format!("({} layers, ", sim.replay.layer_count)));
}
