//! The five-bar (parallel) SCARA from the command line: a print on the example machine passes the step audit with
//! net steps where the kinematics put the motors, a real slicer file checks clean where it fits and is refused with
//! the arm and the pose named where it does not, and `convert --to joints` verifies.

use std::path::Path;
use std::process::Command;

use crate::common::{binary, example_machine, shared};

fn jointspace(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(binary())
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run jointspace")
}

/// The example with room for the corpus' extrusion (its Cura and KISSlicer files push up to 10 mm² of filament
/// cross-section, beyond the example's 1 mm²), written to `dir`.
fn roomy_example(dir: &Path, replace: &[(&str, &str)]) -> std::path::PathBuf {
    let mut text = std::fs::read_to_string(example_machine("fivebar")).expect("example");
    text = text.replace(
        "max_extrude_cross_section: 1.0",
        "max_extrude_cross_section: 12",
    );
    for (from, to) in replace {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    let path = dir.join("printer.cfg");
    std::fs::write(&path, text).expect("write config");
    path
}

#[test]
fn a_print_on_the_fivebar_passes_the_step_audit_with_the_net_steps_of_its_path() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Homed at (0, −37.6); a square, an arc and a diagonal, ending at (30, 40, 2).
    let text = "G28\nG90\nM83\nG1 Z0.3 F600\nG1 X-60 Y-20 F6000\nG1 X60 Y-20 E4 F3000\nG1 X60 Y100 E4\n\
                G1 X-60 Y100 E4\nG1 X-60 Y-20 E4\nG2 X60 Y-20 I60 J0 E6\nG1 X30 Y40 Z2 E2\n";
    std::fs::write(dir.path().join("part.gcode"), text).expect("write");
    let config = example_machine("fivebar");
    let config = config.to_str().expect("utf-8");
    let out = jointspace(dir.path(), &["run", "--json", "-c", config, "part.gcode"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(summary["kinematics"], "fivebar");
    let (machine, _) = machine::Machine::load(Path::new(config)).expect("loads");
    let kin = machine.setup.kinematics.as_ref();
    let home = machine.setup.home_position.expect("home");
    let (mut start, mut end) = ([0.0; 3], [0.0; 3]);
    kin.inverse(home, &mut start).expect("home");
    kin.inverse([30.0, 40.0, 2.0], &mut end).expect("end");
    for (i, motor) in kin.motors().iter().enumerate() {
        let listed = summary["motors"]
            .as_array()
            .and_then(|m| m.iter().find(|m| m["name"] == motor.name.as_str()))
            .expect("motor listed");
        let expected = ((end[i] - start[i]) / motor.step_distance).round();
        let net = listed["net_steps"].as_f64().expect("net steps");
        assert!(
            (net - expected).abs() <= 1.0,
            "{}: {net} vs {expected}",
            motor.name
        );
        assert!(
            listed["steps"].as_f64().expect("steps") >= net.abs().max(500.0),
            "{}",
            motor.name
        );
    }
}

#[test]
fn a_slicer_file_checks_clean_where_it_fits_and_is_refused_by_name_where_not() {
    let Some(shared) = shared("fivebar slicer file") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let part = shared.join("corpus/cura-4.10_circle-centred.gcode");
    let part = part.to_str().expect("utf-8");
    // The Ø165 mm circle about the origin, 200 mm in front of the base joints: inside everything.
    let config = roomy_example(dir.path(), &[]);
    let out = jointspace(
        dir.path(),
        &["check", "-c", config.to_str().expect("utf-8"), part],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains(": 0 errors, 0 warnings;"), "{stdout}");
    // The base joints 120 mm behind the origin: the circle's near side reaches past what the left arm may turn to
    // and into the arms' folded poses. Every refusal names the pose and why, at its line.
    let config = roomy_example(
        dir.path(),
        &[
            ("left_base_y: -200", "left_base_y: -120"),
            ("right_base_y: -200", "right_base_y: -120"),
        ],
    );
    let out = jointspace(
        dir.path(),
        &["check", "-c", config.to_str().expect("utf-8"), part],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    let errors: Vec<&str> = stdout.lines().filter(|l| l.contains(": error: ")).collect();
    assert!(!errors.is_empty(), "{stdout}");
    for line in &errors {
        assert!(line.contains("cura-4.10_circle-centred.gcode:"), "{line}");
        let named = [
            "stepper_left",
            "stepper_right",
            "arm's singular pose",
            "arm's reach",
            "parallel singularity",
        ];
        assert!(named.iter().any(|n| line.contains(n)), "{line}");
    }
}

#[test]
fn convert_to_joints_on_the_fivebar_verifies() {
    let Some(shared) = shared("fivebar convert") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = roomy_example(dir.path(), &[]);
    let part = shared.join("corpus/cura-4.10_hex-centred.gcode");
    let out = jointspace(
        dir.path(),
        &[
            "convert",
            "-c",
            config.to_str().expect("utf-8"),
            "--to",
            "joints",
            part.to_str().expect("utf-8"),
            "-o",
            "joints.gcode",
            "--verify",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("max deviation 0.00"), "{stdout}");
}

/// `workspace` on the example names the five kinds of special pose with the length of each in the area, and the maps
/// it wrote draw them: the SVGs hold a polyline in each kind's colour, the reach PNG has pixels of the parallel
/// curve's colour, and the legend names them.
#[test]
fn the_workspace_maps_draw_the_singular_curves() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_machine("fivebar");
    let out = jointspace(
        dir.path(),
        &[
            "workspace",
            "--json",
            "-c",
            config.to_str().expect("utf-8"),
            "-o",
            "maps",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let figures: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let curves = figures["singular_curves"].as_array().expect("curves");
    let labels: Vec<&str> = curves.iter().filter_map(|c| c["label"].as_str()).collect();
    for side in ["left", "right"] {
        for pose in ["straight", "folded"] {
            assert!(
                labels.contains(&format!("{side} arm {pose}").as_str()),
                "{labels:?}"
            );
        }
    }
    assert!(labels.contains(&"distal links in line"), "{labels:?}");
    // The example's folded circles (radius 50 mm about each base) lie whole in the area but for where they meet the
    // other side's: each drawn piece is shorter than the circle.
    for c in curves {
        let length = c["length_mm"].as_f64().expect("length");
        assert!(length > 50.0, "{c}");
        if c["label"].as_str().is_some_and(|l| l.ends_with("folded")) {
            assert!(length < std::f64::consts::TAU * 50.0, "{c}");
        }
    }
    let maps = dir.path().join("maps");
    for name in ["reach", "machine", "stepper_left", "stepper_right"] {
        let svg = std::fs::read_to_string(maps.join(format!("workspace-{name}.svg"))).expect("svg");
        for colour in ["#14148c", "#006e96", "#be006e"] {
            assert!(
                svg.contains(&format!("stroke=\"{colour}\"")),
                "{name}: no {colour}"
            );
        }
    }
    let reach = std::fs::read_to_string(maps.join("workspace-reach.svg")).expect("svg");
    assert!(reach.contains("singular: distal links in line"));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(maps.join("workspace-reach.png")).expect("png"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut pixels = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut pixels).expect("png data");
    let step = info.color_type.samples();
    let magenta = pixels[..info.buffer_size()]
        .chunks(step)
        .filter(|p| p[..3] == [190, 0, 110])
        .count();
    assert!(
        magenta > 100,
        "{magenta} pixels of the parallel curve's colour"
    );
}
