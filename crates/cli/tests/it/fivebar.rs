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

/// The example's geometry, written again for the check's report: bases, link lengths, the arms' turns (left
/// clockwise, right counter-clockwise) and the distal links' (clockwise).
const BASES: [[f64; 2]; 2] = [[-50.0, -200.0], [50.0, -200.0]];
const PROXIMAL: f64 = 150.0;
const DISTAL: f64 = 200.0;
const ARM_TURN: [f64; 2] = [-1.0, 1.0];

/// Twice the signed area of `a → b → c` (counter-clockwise positive).
fn turn(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
}

/// Where the circles about `c0` (radius `r0`) and `c1` (`r1`) meet.
fn meet(c0: [f64; 2], r0: f64, c1: [f64; 2], r1: f64) -> [[f64; 2]; 2] {
    let (dx, dy) = (c1[0] - c0[0], c1[1] - c0[1]);
    let d = dx.hypot(dy);
    let a = (r0 * r0 - r1 * r1 + d * d) / (2.0 * d);
    let h = (r0 * r0 - a * a).max(0.0).sqrt();
    let (mx, my) = (c0[0] + a * dx / d, c0[1] + a * dy / d);
    [
        [mx + h * dy / d, my - h * dx / d],
        [mx - h * dy / d, my + h * dx / d],
    ]
}

/// The motor angles (degrees) and the |sin| of both elbows and of the distal links at the nozzle `n`.
fn example_pose(n: [f64; 2]) -> ([f64; 2], [f64; 3]) {
    let elbow = |side: usize| {
        let e = meet(BASES[side], PROXIMAL, n, DISTAL);
        let right_turn = |e: &[f64; 2]| turn(BASES[side], *e, n) * ARM_TURN[side] > 0.0;
        e.into_iter()
            .find(right_turn)
            .expect("the example reaches the part")
    };
    let (el, er) = (elbow(0), elbow(1));
    let angle = |side: usize, e: [f64; 2]| {
        (e[1] - BASES[side][1])
            .atan2(e[0] - BASES[side][0])
            .to_degrees()
    };
    let arm_sin = |side: usize, e: [f64; 2]| turn(BASES[side], e, n).abs() / (PROXIMAL * DISTAL);
    let distal_sin = turn(el, n, er).abs() / (DISTAL * DISTAL);
    (
        [angle(0, el), angle(1, er)],
        [arm_sin(0, el), arm_sin(1, er), distal_sin],
    )
}

/// `check` on the example and Cura's Ø165 mm circle tells each arm motor's travel and the closest the print comes to
/// each special pose, as the geometry above finds them along the file's own straight lines (from the homed pose,
/// the endstops' 150° and 30°), sampled every 0.05 mm: the check samples every 0.5 mm, so its extremes lie within
/// what a quarter of its spacing can miss.
#[test]
fn check_tells_the_motor_travel_and_the_closest_approach_to_each_special_pose() {
    let Some(shared) = shared("fivebar check report") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let part = shared.join("corpus/cura-4.10_circle-centred.gcode");
    let config = roomy_example(dir.path(), &[]);
    let out = jointspace(
        dir.path(),
        &[
            "check",
            "--json",
            "-c",
            config.to_str().expect("utf-8"),
            part.to_str().expect("utf-8"),
        ],
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let (angles, sins) = walk_the_file(&std::fs::read_to_string(&part).expect("part"));
    let travel = report["motor_travel"].as_array().expect("travel");
    for (side, name) in ["stepper_left", "stepper_right"].iter().enumerate() {
        let m = travel
            .iter()
            .find(|m| m["motor"] == *name)
            .expect("motor listed");
        assert_eq!(m["unit"], "deg");
        let (min, max) = (
            m["min"].as_f64().expect("min"),
            m["max"].as_f64().expect("max"),
        );
        assert!(
            (min - angles[side].0).abs() < 0.1,
            "{name}: {min} vs {}",
            angles[side].0
        );
        assert!(
            (max - angles[side].1).abs() < 0.1,
            "{name}: {max} vs {}",
            angles[side].1
        );
    }
    let closest = report["closest_to_special_poses"]
        .as_array()
        .expect("closest");
    let poses = [
        "left arm straight or folded",
        "right arm straight or folded",
        "distal links in line",
    ];
    for (pose, truth) in poses.iter().zip(sins) {
        let c = closest
            .iter()
            .find(|c| c["pose"] == *pose)
            .expect("pose listed");
        let sin = c["sin"].as_f64().expect("sin");
        assert!(
            sin >= truth - 1e-9 && sin - truth < 0.003,
            "{pose}: {sin} vs {truth}"
        );
        assert_eq!(c["margin"].as_f64(), Some(0.1));
        assert!(c["line"].as_u64().is_some_and(|l| l > 0), "{c}");
    }
}

/// Every G0/G1 line's XY (absolute) from the homed pose, sampled every 0.05 mm: each motor's (min, max) angle and the
/// smallest |sin| of each special pose.
fn walk_the_file(text: &str) -> ([(f64, f64); 2], [f64; 3]) {
    let [el, er] = [(0, 150f64), (1, 30f64)].map(|(side, deg)| {
        let t = deg.to_radians();
        [
            BASES[side][0] + PROXIMAL * t.cos(),
            BASES[side][1] + PROXIMAL * t.sin(),
        ]
    });
    // The distal links turn clockwise at the nozzle.
    let mut at = meet(el, DISTAL, er, DISTAL)
        .into_iter()
        .find(|n| turn(el, *n, er) < 0.0)
        .expect("homed pose");
    let mut angles = [(f64::INFINITY, f64::NEG_INFINITY); 2];
    let mut sins = [f64::INFINITY; 3];
    for line in text.lines().map(|l| l.split(';').next().unwrap_or("")) {
        let mut words = line.split_whitespace();
        if !matches!(words.next(), Some("G0" | "G1")) {
            continue;
        }
        let mut to = at;
        for w in words {
            match w.split_at(1) {
                ("X", v) => to[0] = v.parse().expect("X"),
                ("Y", v) => to[1] = v.parse().expect("Y"),
                _ => {}
            }
        }
        let samples = ((to[0] - at[0]).hypot(to[1] - at[1]) / 0.05)
            .ceil()
            .max(1.0) as usize;
        for i in 0..=samples {
            let t = i as f64 / samples as f64;
            let (a, s) = example_pose([at[0] + t * (to[0] - at[0]), at[1] + t * (to[1] - at[1])]);
            for side in 0..2 {
                angles[side] = (angles[side].0.min(a[side]), angles[side].1.max(a[side]));
            }
            for k in 0..3 {
                sins[k] = sins[k].min(s[k]);
            }
        }
        at = to;
    }
    (angles, sins)
}
