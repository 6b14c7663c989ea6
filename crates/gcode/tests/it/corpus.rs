//! Every corpus file: no errors, no lost values, and facts checked against an independent scan or
//! against what the slicer wrote in its own header.

use std::io::BufReader;
use std::path::Path;

use gcode::{Command, Commands, Meta, Reader, file_stats};

use crate::naive::{self, NaiveLine};
use crate::{corpus_files, file_name};

/// What our interpreter reports for a file.
#[derive(Debug, Default)]
struct Interpreted {
    g0: usize,
    g1: usize,
    arcs: usize,
    layers: Vec<Option<f64>>,
    final_gcode_e: f64,
}

fn interpret(path: &Path) -> Interpreted {
    let file = std::fs::File::open(path).expect("corpus file opens");
    let mut commands = Commands::from_reader(BufReader::new(file), file_name(path));
    let mut out = Interpreted::default();
    while let Some(command) = commands.next_command() {
        match command.unwrap_or_else(|e| panic!("{e}")).value {
            Command::Move(m) if m.rapid => out.g0 += 1,
            Command::Move(_) => out.g1 += 1,
            Command::Arc(_) => out.arcs += 1,
            Command::Meta(Meta::LayerChange { z, .. }) => out.layers.push(z),
            _ => {}
        }
    }
    out.final_gcode_e = commands.interpreter().gcode_position()[3];
    out
}

/// Every numeric word of every code line, as our lexer sees it (raw-text and extended lines excluded,
/// as in the naive scan).
fn lexed_words(path: &Path) -> Vec<(char, f64)> {
    let file = std::fs::File::open(path).expect("corpus file opens");
    let mut reader = Reader::new(BufReader::new(file), file_name(path));
    let mut words = Vec::new();
    while let Some(line) = reader.next_line() {
        let line = line.unwrap_or_else(|e| panic!("{e}"));
        if line.raw_text().is_some() {
            continue;
        }
        words.extend(
            line.words()
                .iter()
                .filter_map(|w| w.value.map(|v| (w.letter as char, v))),
        );
    }
    words
}

fn header_number(text: &str, prefix: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(prefix))
        .and_then(|v| v.trim().parse().ok())
}

fn count_named(lines: &[Option<NaiveLine>], names: &[&str]) -> usize {
    lines
        .iter()
        .flatten()
        .filter(|l| names.iter().any(|n| naive::is(l, n)))
        .count()
}

#[test]
fn corpus_files_interpret_without_errors_and_match_independent_facts() {
    let Some(files) = corpus_files() else { return };
    assert!(!files.is_empty(), "corpus directory is empty");
    for path in &files {
        let name = file_name(path);
        let text = String::from_utf8_lossy(&std::fs::read(path).expect("read")).into_owned();
        let naive_lines = naive::scan(&text);
        let ours = interpret(path);

        assert_eq!(
            ours.g1,
            count_named(&naive_lines, &["G1"]),
            "{name}: G1 count"
        );
        assert_eq!(
            ours.g0,
            count_named(&naive_lines, &["G0"]),
            "{name}: G0 count"
        );
        assert_eq!(
            ours.arcs,
            count_named(&naive_lines, &["G2", "G3"]),
            "{name}: arc count"
        );

        let naive_words: Vec<(char, f64)> = naive_lines
            .iter()
            .flatten()
            .flat_map(|l| l.words.clone())
            .collect();
        let lexed = lexed_words(path);
        assert_eq!(lexed.len(), naive_words.len(), "{name}: number of values");
        for (i, (a, b)) in lexed.iter().zip(&naive_words).enumerate() {
            assert!(
                a.0 == b.0 && a.1.to_bits() == b.1.to_bits(),
                "{name}: value {i}: {a:?} vs {b:?}"
            );
        }

        let naive_e = naive::final_e(&naive_lines);
        assert!(
            (ours.final_gcode_e - naive_e).abs() < 1e-6,
            "{name}: final E {} vs {naive_e}",
            ours.final_gcode_e
        );

        check_layers(&name, &text, &ours);
        check_bounding_box(path, &name, &text);
        println!(
            "{name}: {} G1, {} G0, {} arcs, {} layers, final E {:.5}",
            ours.g1,
            ours.g0,
            ours.arcs,
            ours.layers.len(),
            ours.final_gcode_e
        );
    }
}

/// Layer counts against the slicer's header or its own markers counted by a plain text search.
fn check_layers(name: &str, text: &str, ours: &Interpreted) {
    let layers = ours.layers.len();
    if let Some(count) = header_number(text, ";LAYER_COUNT:") {
        assert_eq!(layers as f64, count, "{name}: Cura ;LAYER_COUNT:");
    }
    if let Some(count) = header_number(text, "; total layer number:") {
        assert_eq!(layers as f64, count, "{name}: Bambu total layer number");
    }
    let marker_count = |marker: &str| text.lines().filter(|l| l.trim_end() == marker).count();
    if text.contains(";LAYER_CHANGE") {
        assert_eq!(
            layers,
            marker_count(";LAYER_CHANGE"),
            "{name}: ;LAYER_CHANGE markers"
        );
    }
    if text.contains("BEGIN_LAYER_OBJECT") {
        let count = text
            .lines()
            .filter(|l| l.starts_with("; BEGIN_LAYER_OBJECT z="))
            .count();
        assert_eq!(layers, count, "{name}: KISSlicer layers");
    }
    if name.starts_with("simplify3d") {
        let count = text
            .lines()
            .filter(|l| l.starts_with("; layer ") && l.contains(", Z = "))
            .count();
        assert_eq!(layers, count, "{name}: Simplify3D layers");
    }
    let top = ours
        .layers
        .iter()
        .flatten()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    for prefix in ["; max_layer_z = ", "; max_z_height: "] {
        if let Some(max_z) = header_number(text, prefix) {
            assert!(
                (top - max_z).abs() < 1e-9,
                "{name}: top layer z {top} vs header {max_z}"
            );
        }
    }
}

/// Bounding box of extruding moves against Cura's `;MINX:`… header (Cura rounds to 0.001 mm).
fn check_bounding_box(path: &Path, name: &str, text: &str) {
    let keys = [";MINX:", ";MINY:", ";MINZ:", ";MAXX:", ";MAXY:", ";MAXZ:"];
    let header: Vec<Option<f64>> = keys.iter().map(|k| header_number(text, k)).collect();
    if header.iter().any(Option::is_none) {
        return;
    }
    let file = std::fs::File::open(path).expect("open");
    let stats = file_stats(BufReader::new(file), name).unwrap_or_else(|e| panic!("{e}"));
    let bbox = stats
        .extrusion_bbox
        .expect("an extruding file has a bounding box");
    let ours = [
        bbox.min[0],
        bbox.min[1],
        bbox.min[2],
        bbox.max[0],
        bbox.max[1],
        bbox.max[2],
    ];
    for ((key, theirs), ours) in keys.iter().zip(&header).zip(ours) {
        let theirs = theirs.unwrap_or_default();
        assert!(
            (ours - theirs).abs() <= 1e-3,
            "{name}: {key} {theirs} vs ours {ours}"
        );
    }
}

#[test]
fn stats_agree_with_the_naive_scan() {
    let Some(files) = corpus_files() else { return };
    for path in &files {
        let name = file_name(path);
        let text = String::from_utf8_lossy(&std::fs::read(path).expect("read")).into_owned();
        let naive_lines = naive::scan(&text);
        let stats = file_stats(text.as_bytes(), name.as_str()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(stats.lines as usize, text.lines().count(), "{name}: lines");
        assert_eq!(
            stats.moves as usize,
            count_named(&naive_lines, &["G0", "G1"]),
            "{name}: moves"
        );
        assert_eq!(
            stats.arcs as usize,
            count_named(&naive_lines, &["G2", "G3"]),
            "{name}: arcs"
        );
        let g1_lines = naive_lines
            .iter()
            .flatten()
            .filter(|l| l.command == "G1")
            .count() as u64;
        assert_eq!(
            stats.commands.get("G1").copied().unwrap_or(0),
            g1_lines,
            "{name}: G1 by name"
        );
    }
}

#[test]
fn stats_count_layers_in_files_without_layer_markers() {
    let Some(files) = corpus_files() else { return };
    for path in &files {
        let name = file_name(path);
        let text = std::fs::read(path).expect("read");
        let stats = file_stats(&text[..], name.as_str()).unwrap_or_else(|e| panic!("{e}"));
        assert!(stats.layers > 0, "{name}: no layers");
        if stats.layer_markers > 0 {
            assert_eq!(stats.layers, stats.layer_markers, "{name}");
        }
        if name.contains("slic3r-prusa-1.33_benchy") {
            // Slic3r 1.33 writes no layer comments: 0.2 mm layers from Z 0.2 to 48.0.
            let bbox = stats.extrusion_bbox.expect("extrudes");
            let expected = ((bbox.max[2] - bbox.min[2]) / 0.2).round() as u64 + 1;
            assert_eq!((stats.layer_markers, stats.layers), (0, expected), "{name}");
            assert_eq!(expected, 240);
        }
    }
    // A synthetic file: two islands per layer with a Z hop between them, three layers, no markers.
    let mut text = String::from("M83\nG1 Z0.2 F600\n");
    for layer in 1..=3 {
        let z = 0.2 * f64::from(layer);
        text += &format!(
            "G1 Z{z:.1}\nG1 X0 Y0\nG1 X10 Y0 E1\nG1 Z{:.1}\nG1 X20 Y0\n",
            z + 0.4
        );
        text += &format!("G1 Z{z:.1}\nG1 X30 Y0 E2\n");
    }
    let stats = file_stats(text.as_bytes(), "t").expect("reads");
    assert_eq!((stats.layer_markers, stats.layers), (0, 3));
}
