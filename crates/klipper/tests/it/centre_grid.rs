//! What the printer executes near the polar centre: lines and arcs that end at, start at, pass through and pass
//! beside it (exactly 0, 1e-15, 1e-9, 1e-6, 1e-3, 0.1 and 1 mm) from many directions, in every planning mode, with
//! and without `[input_shaper]`, in Klipper and Kalico with step compression off. Each run's MCU stream is decoded
//! and audited as an MCU runs it: the host did not shut down, no two steps of a motor on one clock, no two steps
//! the same way closer than the motor's top speed allows, and the motors end where the geometry puts them. A move
//! the machine cannot make is refused whole: the motors make exactly the steps of the file without it.
//!
//! CI samples the directions; `JOINTSPACE_FULL_GRID=1` runs every 10°.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use crate::hosts::{Hosts, KALICO, KLIPPER, Run, Step, tail, workspace_root, write};

/// `klipper/examples/polar.cfg`: bed 16000 steps a turn (200 × 16 × 80:16), arm 0.0125 mm a step.
const BED_STEP: f64 = TAU / 16000.0;
const ARM_STEP: f64 = 40.0 / 3200.0;
const MAX_VELOCITY: f64 = 300.0;
const MAX_ANGULAR_VELOCITY: f64 = 5.0;
const CLOCK: f64 = 16e6;
const OFFSETS: [f64; 7] = [0.0, 1e-15, 1e-9, 1e-6, 1e-3, 0.1, 1.0];

/// The example machine, in one of the plug-in's modes, optionally with Klipper's input shaper.
fn config(dir: &Path, name: &str, mode: &str, shaper: bool) -> PathBuf {
    let mut text = std::fs::read_to_string(workspace_root().join("klipper/examples/polar.cfg"))
        .expect("polar example");
    match mode {
        "exact" => {}
        "whole-moves" => {
            text = text.replace("[jointspace]\n", "[jointspace]\nsplit_moves: False\n")
        }
        "klipper" => {
            text = text.replace(
                "arm_lateral_offset: 0\n",
                "arm_lateral_offset: 0\ncentre_slowdown: klipper\n",
            )
        }
        _ => panic!("mode {mode}"),
    }
    // SET_KINEMATIC_POSITION places the toolhead without homing.
    text.push_str("\n[force_move]\nenable_force_move: True\n");
    if shaper {
        text.push_str("\n[input_shaper]\nshaper_freq_x: 40\nshaper_freq_y: 40\nshaper_type: mzv\n");
    }
    write(dir, name, &text)
}

fn unit(angle_deg: f64) -> (f64, f64) {
    let a = angle_deg.to_radians();
    (a.cos(), a.sin())
}

/// `G1 X.. Y..` with every digit the offsets need.
fn line(code: &str, x: f64, y: f64, rest: &str) -> String {
    format!("{code} X{x:.17} Y{y:.17}{rest}\n")
}

/// The moves near the centre from direction `theta` (degrees), for every offset.
fn grid_moves(theta: f64) -> String {
    let ((ux, uy), (vx, vy)) = (unit(theta), unit(theta + 90.0));
    let (wx, wy) = unit(theta + 100.0);
    let mut g = String::new();
    for d in OFFSETS {
        // Ends beside the centre, leaves it in another direction, then passes beside it.
        g += &line("G1", 40.0 * ux, 40.0 * uy, " F6000");
        g += &line("G1", d * vx, d * vy, "");
        g += &line("G1", 40.0 * wx, 40.0 * wy, "");
        g += &line("G1", 40.0 * ux + d * vx, 40.0 * uy + d * vy, "");
        g += &line("G1", -40.0 * ux + d * vx, -40.0 * uy + d * vy, "");
    }
    // Arcs: a half circle ending on the centre, one leaving it, one through it.
    g += &line("G1", 40.0 * ux, 40.0 * uy, "");
    g += &line(
        "G2",
        0.0,
        0.0,
        &format!(" I{:.17} J{:.17}", -20.0 * ux, -20.0 * uy),
    );
    g += &line(
        "G3",
        -40.0 * ux,
        -40.0 * uy,
        &format!(" I{:.17} J{:.17}", -20.0 * ux, -20.0 * uy),
    );
    g += &line("G1", 20.0 * ux + 20.0 * vx, 20.0 * uy + 20.0 * vy, "");
    g += &line(
        "G3",
        20.0 * ux - 20.0 * vx,
        20.0 * uy - 20.0 * vy,
        &format!(" I{:.17} J{:.17}", -20.0 * vx, -20.0 * vy),
    );
    g
}

/// Directions: a sample in CI (off the axes and on them), every 10° with `JOINTSPACE_FULL_GRID=1`.
fn directions() -> Vec<f64> {
    if std::env::var_os("JOINTSPACE_FULL_GRID").is_some() {
        (0..36)
            .map(|k| 10.0 * k as f64 + 3.7)
            .chain([0.0, 90.0, 180.0, 270.0])
            .collect()
    } else {
        vec![0.0, 37.0, 90.0, 143.3, 211.0, 301.7]
    }
}

/// The grid file: from the arm's end at bed angle 0 to X50 Y0 at the end (the bed back at angle 0 modulo a turn,
/// the arm 250 mm in).
fn grid_gcode() -> String {
    let mut g = String::from("SET_KINEMATIC_POSITION X=300 Y=0 Z=1\nG90\n");
    for theta in directions() {
        g += &grid_moves(theta);
    }
    g + "G1 X50 Y0 F6000\nM400\n"
}

/// Audits one motor's stream: strictly increasing clocks, no two steps the same way closer than `max_speed`
/// (units a second) allows, and the net step count.
pub fn audit_motor(what: &str, steps: &[Step], step: f64, max_speed: f64) -> i64 {
    let least = (step / max_speed * CLOCK / 1.01).floor() as i64 - 1;
    for w in steps.windows(2) {
        assert!(
            w[1].0 > w[0].0,
            "{what}: two steps at clock {} or out of order",
            w[1].0
        );
        if w[0].1 == w[1].1 {
            assert!(
                w[1].0 - w[0].0 >= least,
                "{what}: {} ticks between steps at clock {} (faster than {max_speed}: at least {least})",
                w[1].0 - w[0].0,
                w[0].0
            );
        }
    }
    steps.iter().map(|s| if s.1 == 1 { 1 } else { -1 }).sum()
}

/// The audit of a grid run: it completed, and the bed and the arm stepped as an MCU can and ended where X50 Y0 is.
/// The bed within `max_angular_velocity`, except under Klipper's own rule (`centre_slowdown: klipper`), which does
/// not hold it: it scales the limit from `max_velocity` (3× for F6000 here) and caps a whole move's cruise by its
/// closest approach only, so there the audit bounds the bed at twice that (no burst an MCU could not step).
fn audit_grid(what: &str, run: &Run, mode: &str) {
    assert!(
        run.success && !run.log.contains("shutdown"),
        "{what}: klippy failed; log ends:\n{}",
        tail(&run.log, 30)
    );
    let steps = run.steps();
    let bed_limit = if mode == "klipper" {
        2.0 * MAX_ANGULAR_VELOCITY * MAX_VELOCITY / 100.0
    } else {
        MAX_ANGULAR_VELOCITY
    };
    let bed = audit_motor(
        &format!("{what}: bed"),
        &steps["stepper_bed"],
        BED_STEP,
        bed_limit,
    );
    let arm = audit_motor(
        &format!("{what}: arm"),
        &steps["stepper_arm"],
        ARM_STEP,
        MAX_VELOCITY,
    );
    assert_eq!(
        bed.rem_euclid(16000),
        0,
        "{what}: the bed ends {bed} steps from where it started, not a whole turn"
    );
    assert_eq!(
        arm, -20000,
        "{what}: the arm made {arm} net steps, not the 250 mm in"
    );
    println!(
        "{what}: bed {} steps (net {bed}), arm {} steps",
        steps["stepper_bed"].len(),
        steps["stepper_arm"].len()
    );
}

fn grid_in(host: &str, modes: &[(&str, bool)]) {
    let Some(hosts) = Hosts::get("centre_grid") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let input = write(dir.path(), "grid.gcode", &grid_gcode());
    for (mode, shaper) in modes {
        let name = format!("{mode}{}", if *shaper { "+shaper" } else { "" });
        let cfg = config(dir.path(), &format!("{name}.cfg"), mode, *shaper);
        let run = hosts.batch(host, true, &cfg, &input, &dir.path().join(&name));
        audit_grid(&format!("{host} {name}"), &run, mode);
    }
}

#[test]
fn centre_grid_completes_in_klipper() {
    grid_in(
        KLIPPER,
        &[
            ("exact", false),
            ("whole-moves", false),
            ("klipper", false),
            ("exact", true),
            ("whole-moves", true),
            ("klipper", true),
        ],
    );
}

#[test]
fn centre_grid_completes_in_kalico() {
    grid_in(
        KALICO,
        &[("exact", false), ("whole-moves", true), ("klipper", false)],
    );
}

/// Pseudo-random targets beyond the arm's reach, after a few moves, in every mode: Klipper refuses the line naming
/// its G-code target and by how much it is beyond the reach, never a piece or a percentage of one. (Batch mode exits
/// at the first error without stepping what was queued, so whether earlier pieces were queued cannot be seen here:
/// `routes::a_refused_route_is_refused_whole` shows the transform's route is refused whole before any piece of it
/// is handed out.)
#[test]
fn a_refused_move_names_its_target() {
    let Some(hosts) = Hosts::get("a_refused_move_names_its_target") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let before = "SET_KINEMATIC_POSITION X=300 Y=0 Z=1\nG90\nG1 X50 Y0.5 F6000\nG1 X20 Y30\n";
    let mut next = xorshift(0x2545_f491_4f6c_dd1d);
    let mut targets = vec![(-400.0, 0.5)];
    for _ in 0..2 {
        let (r, a) = (310.0 + 500.0 * next(), TAU * next());
        targets.push((r * a.cos(), r * a.sin()));
    }
    for (mode, (x, y)) in ["exact", "whole-moves", "klipper"].into_iter().zip(targets) {
        let cfg = config(dir.path(), &format!("{mode}.cfg"), mode, false);
        let input = write(
            dir.path(),
            "refused.gcode",
            &format!("{before}G1 X{x:.3} Y{y:.3}\n"),
        );
        let run = hosts.batch(KLIPPER, true, &cfg, &input, &dir.path().join(mode));
        // As written in the file (three decimals).
        let written = |v: f64| format!("{v:.3}").parse::<f64>().unwrap_or(v);
        let beyond = written(x).hypot(written(y)) - 300.0;
        let message = format!(
            "Move out of range: X{x:.3} Y{y:.3} Z1.000 ({beyond:.3} mm beyond the arm's reach of 300 mm)"
        );
        assert!(
            run.log.contains(&message) && !run.log.contains("% of the segment"),
            "{mode}: no '{message}' in the log:\n{}",
            tail(&run.log, 20)
        );
    }
}

/// Uniform numbers in [0, 1) from `seed` (xorshift64).
pub fn xorshift(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random sequence of moves near the centre from `seed`: lines ending at, passing by and leaving it at the grid's
/// offsets, and arcs ending on it, ending at X50 Y0.
fn random_sequence(seed: u64) -> String {
    let mut next = xorshift(seed);
    let mut g = String::from("SET_KINEMATIC_POSITION X=300 Y=0 Z=1\nG90\nG1 X40 Y0 F6000\n");
    for _ in 0..60 {
        let deg = 360.0 * next();
        let d = OFFSETS[(next() * OFFSETS.len() as f64) as usize % OFFSETS.len()];
        let ((ux, uy), (vx, vy)) = (unit(deg), unit(deg + 90.0));
        let r = 5.0 + 100.0 * next();
        match (next() * 4.0) as u32 {
            0 => g += &line("G1", d * vx, d * vy, ""),
            1 => {
                g += &line("G1", r * ux + d * vx, r * uy + d * vy, "");
                g += &line("G1", -r * ux + d * vx, -r * uy + d * vy, "");
            }
            2 => {
                let ij = format!(" I{:.17} J{:.17}", -0.5 * r * ux, -0.5 * r * uy);
                g += &line("G1", r * ux, r * uy, "");
                g += &line("G2", 0.0, 0.0, &ij);
            }
            _ => g += &line("G1", r * ux, r * uy, ""),
        }
    }
    g + "G1 X50 Y0\nM400\n"
}

/// Random sequences of lines and arcs near the centre, one per mode: each run's MCU stream passes the grid's audit.
#[test]
fn random_sequences_complete() {
    let Some(hosts) = Hosts::get("random_sequences_complete") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let runs = [
        (0x2545_f491_4f6c_dd1d_u64, "exact"),
        (0x9e37_79b9_7f4a_7c15, "whole-moves"),
        (0xd1b5_4a32_d192_ed03, "klipper"),
    ];
    for (seed, mode) in runs {
        let cfg = config(dir.path(), &format!("{mode}.cfg"), mode, false);
        let input = write(dir.path(), &format!("{mode}.gcode"), &random_sequence(seed));
        let run = hosts.batch(KLIPPER, true, &cfg, &input, &dir.path().join(mode));
        audit_grid(&format!("random {mode} (seed {seed:x})"), &run, mode);
    }
}
