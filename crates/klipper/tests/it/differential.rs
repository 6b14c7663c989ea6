//! `jointspace check`/`run` tell what the printer will do: the same files through the command line and through
//! Klipper with the plug-in (batch mode, the bundled example machines) give the same print time within 0.1 % and
//! refuse the same line.

use std::path::{Path, PathBuf};

use crate::centre_grid::xorshift;
use crate::engine::jointspace;
use crate::hosts::{Hosts, KLIPPER, Run, tail, workspace_root, write};

/// A bundled example with SET_KINEMATIC_POSITION allowed (the files start from a declared pose: the command line
/// does not time homing moves).
fn example(dir: &Path, name: &str) -> PathBuf {
    let text =
        std::fs::read_to_string(workspace_root().join(format!("klipper/examples/{name}.cfg")))
            .expect("example");
    write(
        dir,
        &format!("{name}.cfg"),
        &(text + "\n[force_move]\nenable_force_move: True\n"),
    )
}

/// Random moves over an annulus about (0, 0): `count` targets between radii `r`, at angles (degrees) within
/// `window` and at most `step` from the one before (so that SCARA segments keep clear of the base circle), and one
/// beyond reach at move `refused`, if any.
struct Walk {
    start: (f64, f64),
    r: (f64, f64),
    window: (f64, f64),
    step: f64,
}

fn random_moves(seed: u64, walk: &Walk, count: usize, refused: Option<usize>) -> String {
    let mut next = xorshift(seed);
    let (x, y) = walk.start;
    let mut g = format!("SET_KINEMATIC_POSITION X={x} Y={y} Z=1\nG90\nG1 F6000\n");
    let mut angle = y.atan2(x).to_degrees();
    for i in 0..count {
        angle = (angle + walk.step * (2.0 * next() - 1.0)).clamp(walk.window.0, walk.window.1);
        let (r0, r1) = walk.r;
        let radius = if Some(i) == refused {
            r1 + 50.0
        } else {
            r0 + (r1 - r0) * next()
        };
        let (s, c) = angle.to_radians().sin_cos();
        g += &format!("G1 X{:.3} Y{:.3}\n", radius * c, radius * s);
    }
    g + "M400\n"
}

const POLAR_WALK: Walk = Walk {
    start: (300.0, 0.0),
    r: (5.0, 290.0),
    window: (-1e9, 1e9),
    step: 180.0,
};

pub fn cli_json(args: &[&str]) -> serde_json::Value {
    let output = std::process::Command::new(jointspace())
        .args(args)
        .output()
        .expect("jointspace runs");
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| {
        panic!(
            "{e}: {}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

pub fn host_print_time(run: &Run) -> f64 {
    run.log
        .lines()
        .find_map(|l| {
            l.strip_prefix("Exiting (print time ")?
                .strip_suffix("s)")?
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("no print time in:\n{}", tail(&run.log, 20)))
}

#[test]
fn print_time_agrees_with_the_host() {
    let Some(hosts) = Hosts::get("print_time_agrees_with_the_host") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    // Polar: anywhere on the bed; SCARA: within the annulus it reaches freely, clear of the shoulder's branch cut.
    let scara_walk = Walk {
        start: (0.0, 141.421_356_237_309_5),
        r: (70.0, 190.0),
        window: (20.0, 160.0),
        step: 30.0,
    };
    let cases = [
        ("polar", &POLAR_WALK, 0x1234_5678_9abc_def1_u64),
        ("scara", &scara_walk, 0x0fed_cba9_8765_4321),
    ];
    for (name, walk, seed) in cases {
        let cfg = example(dir.path(), name);
        let input = write(
            dir.path(),
            &format!("{name}.gcode"),
            &random_moves(seed, walk, 300, None),
        );
        let (cfg_s, input_s) = (cfg.to_string_lossy(), input.to_string_lossy());
        let cli = cli_json(&["run", "-c", &cfg_s, &input_s, "--klipper-batch", "--json"]);
        let ours = cli["print_time_s"].as_f64().expect("print time");
        let run = hosts.batch(KLIPPER, false, &cfg, &input, &dir.path().join(name));
        run.expect_success(name);
        let host = host_print_time(&run);
        println!("{name}: jointspace run {ours:.4} s, Klipper with the plug-in {host:.3} s");
        assert!(
            (ours - host).abs() <= 1e-3 * host,
            "{name}: {ours} s against the host's {host} s"
        );
    }
}

#[test]
fn refusals_agree_with_the_host() {
    let Some(hosts) = Hosts::get("refusals_agree_with_the_host") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let cfg = example(dir.path(), "polar");
    let mut pick = xorshift(0xa5a5_5a5a_1234_4321);
    for case in 0..3 {
        let refused = 2 + (pick() * 20.0) as usize;
        let text = random_moves(0x5151_f00d + case, &POLAR_WALK, 25, Some(refused));
        let input = write(dir.path(), &format!("refused{case}.gcode"), &text);
        let input_s = input.to_string_lossy();
        let check = cli_json(&["check", "-c", &cfg.to_string_lossy(), &input_s, "--json"]);
        let problems = check["problems"].as_array().expect("problems");
        let error = problems
            .iter()
            .find(|p| p["severity"] == "error")
            .expect("a refusal");
        let line = error["line"].as_u64().expect("the refused line") as usize;
        let target = text.lines().nth(line - 1).expect("that line");
        assert_eq!(
            line,
            4 + refused,
            "case {case}: check refused line {line} ({target})"
        );
        let run = hosts.batch(
            KLIPPER,
            false,
            &cfg,
            &input,
            &dir.path().join(format!("refused{case}")),
        );
        let (x, y) = target
            .strip_prefix("G1 ")
            .and_then(|t| t.split_once(' '))
            .expect("G1 X.. Y..");
        let message = format!("Move out of range: {x} {y}");
        assert!(
            run.log.contains(&message),
            "case {case}: no '{message}':\n{}",
            tail(&run.log, 10)
        );
    }
}

/// `gcode` on the polar example: `check` refuses it first at `line`, and Klipper with the plug-in stops saying
/// `host_says`.
fn refused_alike(test: &str, gcode: &str, line: u64, host_says: &str) {
    let Some(hosts) = Hosts::get(test) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let cfg = example(dir.path(), "polar");
    let input = write(dir.path(), "input.gcode", gcode);
    let (cfg_s, input_s) = (cfg.to_string_lossy(), input.to_string_lossy());
    let check = cli_json(&["check", "-c", &cfg_s, &input_s, "--json"]);
    let problems = check["problems"].as_array().expect("problems");
    let error = problems
        .iter()
        .find(|p| p["severity"] == "error")
        .expect("a refusal");
    assert_eq!(error["line"].as_u64(), Some(line), "{error}");
    let run = hosts.batch(KLIPPER, false, &cfg, &input, &dir.path().join("out"));
    assert!(run.log.contains(host_says), "{}", tail(&run.log, 10));
}

/// An arc given by its radius: Klipper refuses it ("G2/G3 does not support R moves"), and `check` refuses the same
/// line, where jointspace's reader would otherwise take it as Marlin does.
#[test]
fn radius_arcs_are_refused_as_klipper_refuses_them() {
    // The example has `[gcode_arcs]`: Klipper reads arcs, and refuses this one for its R.
    let gcode = "G28\nG1 X50 Y10 F3000\nG2 X60 Y20 R10 F3000\nG1 X40 Y10\n";
    refused_alike(
        "radius_arcs_are_refused_as_klipper_refuses_them",
        gcode,
        3,
        "G2/G3 does not support R moves",
    );
}

/// `SET_GCODE_OFFSET` shifts the G-code frame in Klipper; `check` applies it too, so a move the offset carries out
/// of reach is refused at the same line by both.
#[test]
fn gcode_offsets_are_applied_as_klipper_applies_them() {
    // The arm reaches 300 mm: with the offset, X20 is at 280 mm and X50 at 310 mm.
    let gcode = "G28\nG1 X50 Y10 F3000\nSET_GCODE_OFFSET X=260\nG1 X20 Y10\nG1 X50 Y10\n";
    refused_alike(
        "gcode_offsets_are_applied_as_klipper_applies_them",
        gcode,
        5,
        "Move out of range: X310.000 Y10.000",
    );
}

/// G20: Klipper refuses inch units ("Machine does not support G20 (inches) command"), and `check` refuses the same
/// line, where jointspace's reader would otherwise switch to inches.
#[test]
fn inch_units_are_refused_as_klipper_refuses_them() {
    let gcode = "G28\nG1 X50 Y10 F3000\nG20\nG1 X2 Y2\n";
    refused_alike(
        "inch_units_are_refused_as_klipper_refuses_them",
        gcode,
        3,
        "Machine does not support G20 (inches) command",
    );
}

/// Without `[gcode_arcs]` Klipper has no G2/G3: it answers "Unknown command" and goes on. `check` says so at the
/// line and skips the arc too, so both give the same print time (the arcs here would add more than 10 s).
#[test]
fn arcs_without_gcode_arcs_are_skipped_as_klipper_skips_them() {
    let test = "arcs_without_gcode_arcs_are_skipped_as_klipper_skips_them";
    let Some(hosts) = Hosts::get(test) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let with_arcs = std::fs::read_to_string(example(dir.path(), "polar")).expect("example");
    let without_arcs = with_arcs.replace("[gcode_arcs]\nresolution: 1.0\n", "");
    assert_ne!(with_arcs, without_arcs, "the example has [gcode_arcs]");
    let cfg = write(dir.path(), "no-arcs.cfg", &without_arcs);
    let gcode = "SET_KINEMATIC_POSITION X=100 Y=0 Z=1\nG90\nG1 X100 Y0 F600\n\
                 G2 X100 Y0 I-50 J0\nG3 X100 Y0 I-80 J0\nG1 X50 Y50\nM400\n";
    let input = write(dir.path(), "input.gcode", gcode);
    let (cfg_s, input_s) = (cfg.to_string_lossy(), input.to_string_lossy());
    let check = cli_json(&["check", "-c", &cfg_s, &input_s, "--json"]);
    let problems = check["problems"].as_array().expect("problems");
    let skipped: Vec<u64> = problems
        .iter()
        .filter(|p| {
            p["message"]
                .as_str()
                .is_some_and(|m| m.contains("Unknown command"))
        })
        .filter_map(|p| p["line"].as_u64())
        .collect();
    assert_eq!(skipped, [4, 5], "{problems:?}");
    let cli = cli_json(&["run", "-c", &cfg_s, &input_s, "--klipper-batch", "--json"]);
    let ours = cli["print_time_s"].as_f64().expect("print time");
    let run = hosts.batch(KLIPPER, false, &cfg, &input, &dir.path().join("out"));
    run.expect_success(test);
    assert!(
        run.log.contains("Unknown command:\"G2\""),
        "{}",
        tail(&run.log, 10)
    );
    let host = host_print_time(&run);
    println!("{test}: jointspace run {ours:.4} s, Klipper with the plug-in {host:.3} s");
    assert!(
        (ours - host).abs() <= 1e-3 * host,
        "{ours} s against the host's {host} s"
    );
}
