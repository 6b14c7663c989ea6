//! What the printer executes at a SCARA's special poses: lines that end at, leave, and (at the base) pass beside
//! the straight arm's reach and the base protection circle, 1e-9, 1e-6, 1e-3, 0.1 and 1 mm inside them,
//! from several directions, with and without span cuts and the input shaper, in Klipper, Kalico and the FEKT-SCARA
//! fork with step compression off. Each run's MCU stream is audited as an MCU runs it: the host did not shut down,
//! no two steps of a motor on one clock, none the same way faster than `max_joint_velocity` allows, and the motors
//! end at the home pose they started from.
//!
//! CI samples the directions; `JOINTSPACE_FULL_GRID=1` runs every 10°.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use crate::centre_grid::audit_motor;
use crate::hosts::{Hosts, KALICO, KALICO_FEKT, KLIPPER, Run, tail, workspace_root, write};

/// `klipper/examples/scara.cfg`: links 100 + 100 mm, base protection 60 mm, both motors 9600 steps a turn
/// (200 × 16 × 60:20), `max_joint_velocity: 6`.
const MOTOR_STEP: f64 = TAU / 9600.0;
const MAX_JOINT_VELOCITY: f64 = 6.0;
const REACH: f64 = 200.0;
const BASE: f64 = 60.0;
/// Exactly at the reach or the base radius (0 and 1e-15 mm) rounding decides which side a point lies on, and the
/// kinematics refuses the far side (no allowance for rounding there yet): the grid starts 1e-9 mm inside.
const OFFSETS: [f64; 5] = [1e-9, 1e-6, 1e-3, 0.1, 1.0];
/// The home pose (shoulder 45°, elbow 90°): where the grid starts and ends.
const HOME: (f64, f64) = (0.0, 141.421_356_237_309_5);

fn config(dir: &Path, name: &str, split: bool, shaper: bool) -> PathBuf {
    let mut text = std::fs::read_to_string(workspace_root().join("klipper/examples/scara.cfg"))
        .expect("scara example");
    if !split {
        text = text.replace("[jointspace]\n", "[jointspace]\nsplit_moves: False\n");
    }
    text.push_str("\n[force_move]\nenable_force_move: True\n");
    if shaper {
        text.push_str("\n[input_shaper]\nshaper_freq_x: 40\nshaper_freq_y: 40\nshaper_type: mzv\n");
    }
    write(dir, name, &text)
}

fn at(r: f64, deg: f64) -> (f64, f64) {
    let (s, c) = deg.to_radians().sin_cos();
    (r * c, r * s)
}

fn g1(g: &mut String, (x, y): (f64, f64)) {
    g.push_str(&format!("G1 X{x:.17} Y{y:.17}\n"));
}

/// The moves at the special poses in direction `phi` (degrees from the shoulder).
fn grid_moves(phi: f64) -> String {
    let mut g = String::new();
    for d in OFFSETS {
        // The straight arm: to it, away along another direction.
        g1(&mut g, at(120.0, phi));
        g1(&mut g, at(REACH - d, phi));
        g1(&mut g, at(120.0, phi + 20.0));
        // The base circle: to it, away, and past it on a tangent.
        g1(&mut g, at(BASE + d, phi));
        g1(&mut g, at(120.0, phi - 20.0));
        let half = (120.0f64.powi(2) - (BASE + d).powi(2)).sqrt();
        let (tx, ty) = at(BASE + d, phi);
        let (ux, uy) = at(half, phi + 90.0);
        g1(&mut g, (tx + ux, ty + uy));
        g1(&mut g, (tx - ux, ty - uy));
    }
    g
}

fn directions() -> Vec<f64> {
    if std::env::var_os("JOINTSPACE_FULL_GRID").is_some() {
        (0..13).map(|k| 30.0 + 10.0 * k as f64 + 1.3).collect()
    } else {
        vec![52.0, 90.0, 123.3]
    }
}

fn grid_gcode() -> String {
    // Declared at the home pose (homing's own steps would count in the net).
    let mut g = String::from("SET_KINEMATIC_POSITION X=0 Y=141.4213562373095 Z=1\nG90\nG1 F6000\n");
    for phi in directions() {
        g += &grid_moves(phi);
    }
    g1(&mut g, HOME);
    g + "M400\n"
}

fn audit(what: &str, run: &Run) {
    assert!(
        run.success && !run.log.contains("shutdown"),
        "{what}: klippy failed; log ends:\n{}",
        tail(&run.log, 30)
    );
    let steps = run.steps();
    for motor in ["stepper_a", "stepper_b"] {
        let net = audit_motor(
            &format!("{what}: {motor}"),
            &steps[motor],
            MOTOR_STEP,
            MAX_JOINT_VELOCITY,
        );
        assert_eq!(
            net, 0,
            "{what}: {motor} ends {net} steps from the home pose"
        );
        println!("{what}: {motor} {} steps", steps[motor].len());
    }
}

fn grid_in(host: &str, variants: &[(bool, bool)]) {
    let Some(hosts) = Hosts::get("scara_grid") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let input = write(dir.path(), "grid.gcode", &grid_gcode());
    for &(split, shaper) in variants {
        let name = format!(
            "{}{}",
            if split { "split" } else { "whole-moves" },
            if shaper { "+shaper" } else { "" }
        );
        let cfg = config(dir.path(), &format!("{name}.cfg"), split, shaper);
        let run = hosts.batch(host, true, &cfg, &input, &dir.path().join(&name));
        audit(&format!("{host} {name}"), &run);
    }
}

#[test]
fn scara_grid_completes_in_klipper() {
    grid_in(KLIPPER, &[(true, false), (false, false), (true, true)]);
}

#[test]
fn scara_grid_completes_in_kalico_and_the_fekt_fork() {
    grid_in(KALICO, &[(true, false), (false, true)]);
    grid_in(KALICO_FEKT, &[(true, false), (false, false)]);
}
