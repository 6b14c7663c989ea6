//! The move transform inside Klipper: only the part of a move near the polar centre slows, a move through the
//! centre turns the bed in place, and bed_mesh still applies on top. Measured from what the host sends the MCU.

use std::path::Path;

use crate::hosts::{Hosts, KLIPPER, Run, plugin_config, shared, write};

const LIMIT: f64 = 5.0;

/// The print time Klipper reports on exit.
fn print_time(run: &Run) -> f64 {
    run.log
        .lines()
        .rev()
        .find_map(|l| {
            l.strip_prefix("Exiting (print time ")?
                .strip_suffix("s)")?
                .parse()
                .ok()
        })
        .expect("print time in the log")
}

/// The bed's highest speed (rad/s) between two consecutive steps the same way.
fn bed_peak(run: &Run) -> f64 {
    let steps = run.steps();
    let step_dist = std::f64::consts::TAU / 16000.0;
    steps["stepper_bed"]
        .windows(2)
        .filter(|w| w[0].1 == w[1].1 && w[1].0 > w[0].0)
        .map(|w| step_dist * 16e6 / (w[1].0 - w[0].0) as f64)
        .fold(0.0, f64::max)
}

fn polar_config(dir: &Path, name: &str, kinematics: &str, limits: &str) -> std::path::PathBuf {
    let path = plugin_config(
        &shared().join("golden/polar-synthetic/printer.cfg"),
        &[(
            "kinematics: polar",
            &format!("kinematics: {kinematics}\n{limits}"),
        )],
        dir,
        name,
    );
    if kinematics == "polar" {
        let text = std::fs::read_to_string(&path)
            .expect("config")
            .replace("[jointspace]", "");
        std::fs::write(&path, text).expect("write");
    }
    path
}

/// The shared synthetic case (passes 0.3 mm and 1 mm from the centre, radial moves ending 0.5 mm from it):
/// Klipper's whole-move rule with `max_angular_velocity: 5` adds time to every move near the centre; cutting the
/// moves adds at most a fifth of that, and the bed stays within its limit.
#[test]
fn only_the_near_part_slows() {
    let Some(hosts) = Hosts::get("only_the_near_part_slows") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let gcode = shared().join("golden/polar-synthetic/input.gcode");
    let limit = format!("max_angular_velocity: {LIMIT}");
    let free = polar_config(dir.path(), "free.cfg", "polar", "");
    let klipper = polar_config(dir.path(), "klipper.cfg", "polar", &limit);
    let ours = polar_config(dir.path(), "ours.cfg", "jointspace_polar", &limit);
    let run = |cfg: &Path, name: &str| {
        let run = hosts.batch(KLIPPER, true, cfg, &gcode, &dir.path().join(name));
        run.expect_success(name);
        run
    };
    let (free, klipper, ours) = (
        run(&free, "free"),
        run(&klipper, "klipper"),
        run(&ours, "ours"),
    );
    let (t0, tk, ts) = (print_time(&free), print_time(&klipper), print_time(&ours));
    let peak = bed_peak(&ours);
    println!(
        "print time: no limit {t0:.3} s, Klipper's rule {tk:.3} s (+{:.3}), split moves {ts:.3} s (+{:.3}); \
         bed peak {peak:.3} rad/s (Klipper's rule {:.3})",
        tk - t0,
        ts - t0,
        bed_peak(&klipper)
    );
    assert!(tk > t0 * 1.5, "Klipper's rule should slow this case a lot");
    assert!(
        ts - t0 <= (tk - t0) / 5.0,
        "split moves add {:.3} s, Klipper's rule {:.3} s",
        ts - t0,
        tk - t0
    );
    assert!(peak <= LIMIT * 1.01, "bed peak {peak} rad/s");
}

/// Moves through the exact centre and past it at 1e-15 … 1 mm, an arc through it, a move ending on it and one
/// leaving it in another direction: each completes; the bed stays within its limit; the time is the moves at their
/// speed plus the bed's half turns at its limit, not a creep.
#[test]
fn through_the_centre_the_bed_turns_in_place() {
    let Some(hosts) = Hosts::get("through_the_centre_the_bed_turns_in_place") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let mut gcode = String::from("SET_KINEMATIC_POSITION X=300 Y=0 Z=1\nG90\nG1 X100 Y0 F6000\n");
    let passes = [0.0, 1e-15, 1e-9, 1e-6, 1e-3, 0.1, 1.0];
    for d in passes {
        gcode.push_str(&format!("G1 X100 Y{d} F6000\nG1 X-100 Y{d} F6000\n"));
    }
    gcode.push_str("G1 X100 Y0\nG2 X100 Y0 I-50 J0 F3000\nG1 X0 Y0 F6000\nG1 X50 Y80\nM400\n");
    let input = write(dir.path(), "centre.gcode", &gcode);
    let limits = format!("max_angular_velocity: {LIMIT}\nmax_angular_accel: 100");
    let ours = polar_config(dir.path(), "ours.cfg", "jointspace_polar", &limits);
    let free = polar_config(dir.path(), "free.cfg", "jointspace_polar", "");
    let run = hosts.batch(KLIPPER, true, &ours, &input, &dir.path().join("ours"));
    run.expect_success("through the centre");
    let unlimited = hosts.batch(KLIPPER, true, &free, &input, &dir.path().join("free"));
    unlimited.expect_success("through the centre, no bed limits");
    let (t, t0, peak) = (print_time(&run), print_time(&unlimited), bed_peak(&run));
    // The bed's turns: every pass (the first at d = 0, then two per offset: there and back, then back to X100)
    // turns it half a turn, so does the arc through the centre; leaving the centre towards (50, 80) turns it by
    // atan2(80, 50). Each takes its angle at the speed limit plus a speed-up and a slow-down at the acceleration
    // limit (2ω/α), on top of the same file with no bed limits.
    let pi = std::f64::consts::PI;
    let passes_count = 1 + 2 * (passes.len() - 1) + 1;
    let mut turns = vec![pi; passes_count + 1];
    turns.push(80f64.atan2(50.0));
    let least: f64 = turns.iter().map(|a| a / LIMIT).sum();
    let bound = t0 + least + turns.len() as f64 * 2.0 * LIMIT / 100.0;
    println!(
        "through the centre: {t:.3} s (no bed limits {t0:.3} s, least {:.3} s, bound {bound:.3} s), bed peak {peak:.3} rad/s",
        t0 + least
    );
    assert!(peak <= LIMIT * 1.01, "bed peak {peak} rad/s");
    assert!(t <= bound, "{t} s over the bound {bound} s");
    // The bound is tight: the bed cannot turn faster than its limit allows.
    assert!(
        t >= t0 + least,
        "{t} s: faster than the bed can turn ({} s at least)",
        t0 + least
    );
}

/// The bed's peak speed and acceleration from its steps: speed over windows of 16 steps the same way, and
/// acceleration between consecutive windows (as jointspace's own planner tests read them).
fn bed_rates(run: &Run) -> (f64, f64) {
    let steps = run.steps();
    let step_dist = std::f64::consts::TAU / 16000.0;
    let t: Vec<(f64, i8)> = steps["stepper_bed"]
        .iter()
        .map(|&(clock, dir)| (clock as f64 / 16e6, dir))
        .collect();
    let w = 16;
    let speeds: Vec<(f64, f64)> = t
        .chunks_exact(w + 1)
        .filter(|c| c.iter().all(|s| s.1 == c[0].1))
        .map(|c| {
            let (t0, t1) = (c[0].0, c[w].0);
            ((t0 + t1) / 2.0, w as f64 * step_dist / (t1 - t0))
        })
        .collect();
    let omega = speeds.iter().map(|s| s.1).fold(0.0, f64::max);
    let alpha = speeds
        .windows(2)
        .map(|p| ((p[1].1 - p[0].1) / (p[1].0 - p[0].0)).abs())
        .fold(0.0, f64::max);
    (omega, alpha)
}

/// Corners beside the centre (0.1 and 1 mm from it) change the bed's speed at once; with `max_angular_accel` the
/// plug-in caps those corners (Klipper's `limit_next_junction_speed`) so that the jump fits the acceleration the
/// moves leave: the bed, read from the steps Klipper sends, stays within its limits.
#[test]
fn corners_beside_the_centre_keep_the_bed_within_its_acceleration() {
    let Some(hosts) = Hosts::get("corners_beside_the_centre_keep_the_bed_within_its_acceleration")
    else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let mut gcode = String::from("SET_KINEMATIC_POSITION X=100 Y=0 Z=1\nG90\n");
    for d in [0.1, 1.0] {
        for (x, y) in [(60.0, 80.0), (-100.0, 10.0), (20.0, -100.0)] {
            gcode.push_str(&format!(
                "G1 X-100 Y{d} F6000\nG1 X0 Y{d}\nG1 X{x} Y{y}\nG1 X100 Y{d}\n"
            ));
        }
    }
    gcode.push_str("M400\n");
    let input = write(dir.path(), "corners.gcode", &gcode);
    let alpha_limit = 100.0;
    let limits = format!("max_angular_velocity: {LIMIT}\nmax_angular_accel: {alpha_limit}");
    let ours = polar_config(dir.path(), "ours.cfg", "jointspace_polar", &limits);
    let run = hosts.batch(KLIPPER, true, &ours, &input, &dir.path().join("ours"));
    run.expect_success("corners beside the centre");
    let (omega, alpha) = bed_rates(&run);
    println!("corners beside the centre: bed peak {omega:.3} rad/s, {alpha:.1} rad/s²");
    assert!(omega <= LIMIT * 1.01, "bed at {omega} rad/s");
    assert!(alpha <= alpha_limit * 1.01, "bed at {alpha} rad/s²");
}

/// bed_mesh chained after the transform: a mesh profile raises Z where it says, on moves the transform cut.
#[test]
fn bed_mesh_still_applies() {
    let Some(hosts) = Hosts::get("bed_mesh_still_applies") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = polar_config(
        dir.path(),
        "mesh.cfg",
        "jointspace_polar",
        "max_angular_velocity: 5",
    );
    let mut text = std::fs::read_to_string(&config).expect("config");
    text.push_str(MESH);
    std::fs::write(&config, text).expect("write");
    let gcode = "SET_KINEMATIC_POSITION X=300 Y=0 Z=1\nBED_MESH_PROFILE LOAD=default\nG1 X80 Y0 F6000\n\
                 G1 X-80 Y0 F3000\nG1 X0 Y0\nG1 X50 Y50\nM400\nGET_POSITION\n";
    let input = write(dir.path(), "mesh.gcode", gcode);
    let run = hosts.batch(KLIPPER, true, &config, &input, &dir.path().join("out"));
    run.expect_success("bed mesh");
    // The mesh's value at (50, 50) is 0.1 mm (a bump of 0.4 mm at the centre falling to 0 at the edge).
    assert!(
        run.log
            .contains("toolhead: X:50.000000 Y:50.000000 Z:1.100000"),
        "{}",
        crate::hosts::tail(&run.log, 10)
    );
    assert!(
        run.steps()["stepper_z"].len() > 100,
        "Z did not follow the mesh"
    );
}

const MESH: &str = "
[probe]
pin: ^PD2
z_offset: 0

[bed_mesh]
mesh_radius: 100
mesh_origin: 0, 0
round_probe_count: 5

#*# <---------------------- SAVE_CONFIG ---------------------->
#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.
#*#
#*# [bed_mesh default]
#*# version = 1
#*# points =
#*# 	  0.0, 0.0, 0.0, 0.0, 0.0
#*# 	  0.0, 0.1, 0.2, 0.1, 0.0
#*# 	  0.0, 0.2, 0.4, 0.2, 0.0
#*# 	  0.0, 0.1, 0.2, 0.1, 0.0
#*# 	  0.0, 0.0, 0.0, 0.0, 0.0
#*# x_count = 5
#*# y_count = 5
#*# mesh_x_pps = 2
#*# mesh_y_pps = 2
#*# algo = lagrange
#*# tension = 0.2
#*# min_x = -100.0
#*# max_x = 100.0
#*# min_y = -100.0
#*# max_y = 100.0
";
