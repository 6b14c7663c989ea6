//! `estimate` and `post-process` on real slicer files: the breakdown adds up to the total, the rewritten file reads
//! back with the same commands and only its time lines changed (progress monotonic), and a failing run leaves the
//! file as it was.

use std::path::{Path, PathBuf};
use std::process::Command as Process;

use crate::common::{binary, example_machine, shared};
use gcode::{Command, Meta};

/// Every slicer of the corpus with a machine it fits on (the polar golden machine for files centred on 0,0).
fn cases(shared: &Path) -> Vec<(PathBuf, PathBuf)> {
    let cartesian = shared.join("golden/cartesian-prusa-minicube-arcs/printer.cfg");
    let polar = shared.join("golden/polar-cura-circle/printer.cfg");
    let corpus = |name: &str| shared.join("corpus").join(name);
    vec![
        (
            corpus("prusaslicer-2.8.1_mini-cube.gcode"),
            cartesian.clone(),
        ),
        (
            corpus("bambustudio-1.9.7_square-ring.gcode"),
            cartesian.clone(),
        ),
        (corpus("prusaslicer-2.7.4_spiral-vase.gcode"), cartesian),
        (corpus("cura-4.10_circle-centred.gcode"), polar.clone()),
        (
            corpus("cura-master_implicit-abs-e.gcode"),
            example_machine("cartesian"),
        ),
        (corpus("kisslicer-1.1_cube-centred.gcode"), polar),
        (
            corpus("simplify3d-4.1.2.gcode"),
            example_machine("cartesian"),
        ),
    ]
}

fn estimate_json(config: &Path, file: &Path) -> serde_json::Value {
    let output = Process::new(binary())
        .args(["estimate", "--json", "-c"])
        .args([config, file])
        .output()
        .expect("jointspace runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("JSON")
}

/// The commands of a file with their lines, the slicer's time metadata left out (what post-processing may change;
/// a rewritten progress line may be longer, so spans are compared by line).
fn commands(path: &Path) -> Vec<(u64, Command)> {
    let text = std::fs::read(path).expect("read");
    let mut commands = gcode::Commands::from_reader(&text[..], "file");
    let mut out = Vec::new();
    while let Some(command) = commands.next_command() {
        let command = command.expect("reads");
        if !matches!(
            command.value,
            Command::Meta(Meta::PrintTimeEstimate { .. } | Meta::TimeElapsed(_))
        ) {
            out.push((command.span.line, command.value));
        }
    }
    out
}

fn is_time_line(line: &str) -> bool {
    let line = line.trim_start();
    line.starts_with("M73 ")
        || line.strip_prefix(';').is_some_and(|c| {
            let c = c.trim_start();
            [
                "estimated printing time (",
                "TIME:",
                "TIME_ELAPSED:",
                "Build time:",
                "Estimated Build Time:",
            ]
            .iter()
            .any(|p| c.starts_with(p))
        })
}

/// The values of `letter` on the file's M73 lines, in order.
fn m73_values(text: &str, letter: char) -> Vec<f64> {
    text.lines()
        .filter(|l| l.starts_with("M73 "))
        .flat_map(|l| l.split_whitespace().skip(1))
        .filter_map(|w| w.strip_prefix(letter)?.parse().ok())
        .collect()
}

#[test]
fn post_process_rewrites_only_the_time_lines_of_each_slicer() {
    let Some(shared) = shared("post_process_rewrites_only_the_time_lines_of_each_slicer") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    for (source, config) in cases(&shared) {
        let file = dir.path().join(source.file_name().expect("name"));
        std::fs::copy(&source, &file).expect("copy");
        let planned = estimate_json(&config, &file)["total"]
            .as_f64()
            .expect("total");
        let output = Process::new(binary())
            .args(["post-process", "-c"])
            .args([&config, &file])
            .output()
            .expect("jointspace runs");
        let name = file.display();
        assert!(
            output.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        let (before, after) = (
            std::fs::read_to_string(&source).expect("source"),
            std::fs::read_to_string(&file).expect("rewritten"),
        );
        assert_eq!(before.lines().count(), after.lines().count(), "{name}");
        let mut changed = 0;
        for (number, (a, b)) in before.lines().zip(after.lines()).enumerate() {
            if a != b {
                assert!(
                    is_time_line(a) && is_time_line(b),
                    "{name}:{}: {a} became {b}",
                    number + 1
                );
                changed += 1;
            }
        }
        // Simplify3D states whole minutes: its 31 minutes stay 31 for a plan of 31m 23s.
        assert!(
            changed > 0 || name.to_string().contains("simplify3d"),
            "{name}: no time line changed"
        );
        assert_eq!(
            commands(&source),
            commands(&file),
            "{name}: the commands changed"
        );
        for (letter, rising) in [('P', true), ('Q', true), ('R', false), ('S', false)] {
            let values = m73_values(&after, letter);
            let ordered = values
                .windows(2)
                .all(|w| if rising { w[0] <= w[1] } else { w[0] >= w[1] });
            assert!(ordered, "{name}: M73 {letter} not monotonic: {values:?}");
        }
        if after.contains("M73 P") {
            assert_eq!(m73_values(&after, 'P').last(), Some(&100.0), "{name}");
        }
        // The rewritten file states the planned time, and its estimate is now the plan's.
        let slicer = estimate_json(&config, &file)["slicer"]
            .as_f64()
            .expect("slicer estimate");
        assert!(
            (slicer - planned).abs() <= 30.0,
            "{name}: states {slicer} s for {planned} s"
        );
        println!("{name}: {changed} lines rewritten, planned {planned:.1} s");
    }
}

#[test]
fn estimate_parts_add_up_to_the_total() {
    let Some(shared) = shared("estimate_parts_add_up_to_the_total") else {
        return;
    };
    let case = shared.join("golden/cartesian-prusa-minicube-arcs");
    let json = estimate_json(&case.join("printer.cfg"), &case.join("input.gcode"));
    let total = json["total"].as_f64().expect("total");
    assert_eq!(json["slicer"].as_f64(), Some(221.0));
    for kind in ["layers", "features"] {
        let parts = json[kind].as_array().expect("parts");
        let sum: f64 = parts
            .iter()
            .map(|p| p["time"].as_f64().expect("time"))
            .sum();
        assert!(
            (sum - total).abs() < 1e-6 * total,
            "{kind}: {sum} of {total}"
        );
    }
    assert_eq!(json["layers"].as_array().map(Vec::len), Some(32));
}

#[test]
fn estimate_costs_each_motor_limit() {
    let Some(shared) = shared("estimate_costs_each_motor_limit") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let case = shared.join("golden/polar-synthetic");
    let text = std::fs::read_to_string(case.join("printer.cfg")).expect("config");
    let config = dir.path().join("printer.cfg");
    let limited = text.replacen(
        "kinematics: polar",
        "kinematics: polar\nmax_angular_velocity: 5",
        1,
    );
    std::fs::write(&config, limited).expect("write");
    let json = estimate_json(&config, &case.join("input.gcode"));
    let (total, free) = (
        json["total"].as_f64().expect("a number"),
        json["without_motor_limits"].as_f64().expect("a number"),
    );
    let limits = json["limits"].as_array().expect("limits");
    assert_eq!(limits.len(), 1);
    assert_eq!(limits[0]["motor"], "stepper_bed");
    let lost = limits[0]["lost"].as_f64().expect("a number");
    assert!(total > free + 1.0, "{total} against {free}");
    assert!(
        (lost - (total - free)).abs() < 1e-9,
        "one limit: it alone costs the difference"
    );
    assert!(json["slowed_total"].as_u64().expect("a number") > 0);
    // Klipper's own rule (whole moves slowed by the bed's speed at their closest approach): 141.1 s in Klipper with
    // the plug-in's `centre_slowdown: klipper` on this case.
    let rule = json["klipper_rule"]
        .as_f64()
        .expect("Klipper's rule's time");
    assert!((rule - 141.1).abs() < 0.05, "{rule}");
}

/// What post-process must refuse, leaving the file as it was and nothing beside it.
#[test]
fn post_process_leaves_the_file_untouched_on_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_machine("cartesian");
    let text = "; estimated printing time (normal mode) = 1m 2s\nG28\nM73 P0 R1\nG1 X10 Y10 F600\nG1 Xabc\nM73 P100 R0\n";
    let file = dir.path().join("part.gcode");
    std::fs::write(&file, text).expect("write");
    let missing = dir.path().join("missing.cfg");
    let absent = dir.path().join("absent.gcode");
    let runs: [(Vec<&Path>, &str); 4] = [
        (vec![Path::new("-c"), &config, &file], "part.gcode:5:"),
        (vec![Path::new("-c"), &missing, &file], "missing.cfg"),
        (vec![&file], "JOINTSPACE_CONFIG"),
        (vec![Path::new("-c"), &config, &absent], "absent.gcode"),
    ];
    for (args, phrase) in runs {
        let output = Process::new(binary())
            .arg("post-process")
            .args(&args)
            .env_remove("JOINTSPACE_CONFIG")
            .output()
            .expect("jointspace runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(phrase), "{args:?}: no {phrase} in {stderr}");
        assert_eq!(
            std::fs::read_to_string(&file).expect("file"),
            text,
            "{args:?}"
        );
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .expect("present")
            .map(|e| e.expect("a number").file_name())
            .collect();
        assert_eq!(names, ["part.gcode"], "{args:?}: left beside it");
    }
}

#[test]
fn post_process_takes_the_config_from_the_environment() {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("part.gcode");
    std::fs::write(&file, ";TIME:1\nG28\nG1 X100 Y100 F6000\n;TIME_ELAPSED:1\n").expect("write");
    let output = Process::new(binary())
        .args(["post-process".as_ref(), file.as_os_str()])
        .env("JOINTSPACE_CONFIG", example_machine("cartesian"))
        .output()
        .expect("jointspace runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = std::fs::read_to_string(&file).expect("file");
    let elapsed: f64 = text
        .lines()
        .nth(3)
        .and_then(|l| l.strip_prefix(";TIME_ELAPSED:"))
        .expect("present")
        .parse()
        .expect("present");
    assert!(elapsed > 1.0 && text.starts_with(";TIME:"), "{text}");
    assert_eq!(
        text.lines().next(),
        Some(format!(";TIME:{}", elapsed.round()).as_str())
    );
}
