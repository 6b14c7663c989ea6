//! `jointspace_polar` with zero offsets against the hosts' own polar kinematics, on the polar bench
//! (228,920 moves, G28 first): what the host sends the MCU must be the same, message for message.

use crate::hosts::{Hosts, KALICO, KLIPPER, plugin_config, shared};

/// Klipper with its `max_angular_velocity: 5` and `centre_slowdown: klipper` (Klipper's whole-move rule).
#[test]
fn bench_queue_step_is_klippers_polar() {
    let Some(hosts) = Hosts::get("bench_queue_step_is_klippers_polar") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let builtin = shared().join("bench/polar-bench.cfg");
    let gcode = shared().join("bench/polar-bench20.gcode");
    let ours = plugin_config(
        &builtin,
        &[
            ("kinematics: polar", "kinematics: jointspace_polar"),
            (
                "max_angular_velocity: 5",
                "max_angular_velocity: 5\ncentre_slowdown: klipper",
            ),
        ],
        dir.path(),
        "jointspace.cfg",
    );
    let reference = hosts.batch(
        KLIPPER,
        false,
        &builtin,
        &gcode,
        &dir.path().join("builtin"),
    );
    let run = hosts.batch(KLIPPER, false, &ours, &gcode, &dir.path().join("ours"));
    reference.expect_success("built-in polar");
    run.expect_success("jointspace_polar");
    let (a, b) = (reference.queue_step(), run.queue_step());
    assert!(
        a.lines().count() > 100_000,
        "the bench made too few messages"
    );
    assert!(a == b, "queue_step.txt differs from Klipper's polar");
}

/// Kalico (whose C helper is built with fused multiply-adds); its polar has no `max_angular_velocity`.
#[test]
fn bench_queue_step_is_kalicos_polar() {
    let Some(hosts) = Hosts::get("bench_queue_step_is_kalicos_polar") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let gcode = shared().join("bench/polar-bench20.gcode");
    let base = shared().join("bench/polar-bench.cfg");
    let builtin = plugin_config(
        &base,
        &[("max_angular_velocity: 5", "")],
        dir.path(),
        "b.cfg",
    );
    let text = std::fs::read_to_string(&builtin).expect("config");
    // The built-in needs no [jointspace]; it is harmless but keep the reference plain.
    std::fs::write(&builtin, text.replace("[jointspace]", "")).expect("write");
    let ours = plugin_config(
        &base,
        &[
            ("kinematics: polar", "kinematics: jointspace_polar"),
            ("max_angular_velocity: 5", ""),
        ],
        dir.path(),
        "jointspace.cfg",
    );
    let reference = hosts.batch(KALICO, false, &builtin, &gcode, &dir.path().join("builtin"));
    let run = hosts.batch(KALICO, false, &ours, &gcode, &dir.path().join("ours"));
    reference.expect_success("Kalico's polar");
    run.expect_success("jointspace_polar on Kalico");
    assert!(
        run.log.contains("fused multiply-add arithmetic"),
        "Kalico's arithmetic was not recognised"
    );
    assert!(
        reference.queue_step() == run.queue_step(),
        "queue_step.txt differs from Kalico's polar"
    );
}

/// `centre_slowdown: exact` (the default) on Klipper: moves near the centre of the shared synthetic case
/// (passes 0.3 mm and 1 mm from it, radial moves ending 0.5 mm from it) with `max_angular_velocity: 5`. The bed's
/// speed, measured from the step stream the host sends, stays within the limit (Klipper's own rule lets it
/// exceed it: the whole move is scaled from `max_velocity`, not from the requested speed).
#[test]
fn exact_slowdown_keeps_the_bed_within_its_limit() {
    let Some(hosts) = Hosts::get("exact_slowdown_keeps_the_bed_within_its_limit") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let case = shared().join("golden/polar-synthetic");
    let limit = 5.0;
    let config = |slowdown: &str, name: &str| {
        plugin_config(
            &case.join("printer.cfg"),
            &[(
                "kinematics: polar",
                &format!(
                    "kinematics: jointspace_polar\nmax_angular_velocity: {limit}\ncentre_slowdown: {slowdown}"
                ),
            )],
            dir.path(),
            name,
        )
    };
    let gcode = case.join("input.gcode");
    let peak = |slowdown: &str| {
        let cfg = config(slowdown, &format!("{slowdown}.cfg"));
        let run = hosts.batch(KLIPPER, true, &cfg, &gcode, &dir.path().join(slowdown));
        run.expect_success(slowdown);
        let steps = run.steps();
        let bed = &steps["stepper_bed"];
        let step_dist = std::f64::consts::TAU / 16000.0;
        bed.windows(2)
            .filter(|w| w[0].1 == w[1].1 && w[1].0 > w[0].0)
            .map(|w| step_dist * 16e6 / (w[1].0 - w[0].0) as f64)
            .fold(0.0, f64::max)
    };
    let exact = peak("exact");
    let klipper = peak("klipper");
    println!(
        "bed peak angular velocity: exact {exact:.3} rad/s, Klipper's rule {klipper:.3} rad/s (limit {limit})"
    );
    assert!(
        exact <= limit * 1.01,
        "exact: bed peak {exact} rad/s over the limit {limit}"
    );
    assert!(
        klipper > exact,
        "Klipper's rule should be the looser one here"
    );
}

/// Homing keeps the input shaper: with `[input_shaper]`, `centre_slowdown: klipper` and `split_moves: False`,
/// `G28` and a print send the MCU exactly what Klipper's own polar sends (joint-space homing swaps the solver the
/// shaper wraps, not the shaper).
#[test]
fn homing_with_the_input_shaper_is_klippers_polar() {
    let Some(hosts) = Hosts::get("homing_with_the_input_shaper_is_klippers_polar") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let golden = shared().join("golden/polar-cura-circle");
    let shaper = "\n[input_shaper]\nshaper_freq_x: 40\nshaper_freq_y: 45\nshaper_type: mzv\n";
    let base = std::fs::read_to_string(golden.join("printer.cfg")).expect("config") + shaper;
    let base = crate::hosts::write(dir.path(), "base.cfg", &base);
    let builtin = plugin_config(&base, &[], dir.path(), "builtin.cfg");
    let text = std::fs::read_to_string(&builtin).expect("config");
    std::fs::write(&builtin, text.replace("[jointspace]", "")).expect("write");
    let ours = plugin_config(
        &base,
        &[(
            "kinematics: polar",
            "kinematics: jointspace_polar\ncentre_slowdown: klipper",
        )],
        dir.path(),
        "ours.cfg",
    );
    let text = std::fs::read_to_string(&ours).expect("config") + "split_moves: False\n";
    std::fs::write(&ours, text).expect("write");
    let print = std::fs::read_to_string(golden.join("input.gcode")).expect("input");
    let gcode = String::from("G28\n")
        + &print
            .lines()
            .filter(|l| !l.starts_with("SET_KINEMATIC_POSITION"))
            .collect::<Vec<_>>()
            .join("\n");
    let input = crate::hosts::write(dir.path(), "input.gcode", &gcode);
    let reference = hosts.batch(
        KLIPPER,
        false,
        &builtin,
        &input,
        &dir.path().join("builtin"),
    );
    let run = hosts.batch(KLIPPER, false, &ours, &input, &dir.path().join("ours"));
    reference.expect_success("built-in polar with the shaper");
    run.expect_success("jointspace_polar with the shaper");
    let (a, b) = (reference.queue_step(), run.queue_step());
    assert!(a.lines().count() > 1000, "too few messages");
    let first_difference = a.lines().zip(b.lines()).position(|(x, y)| x != y);
    assert!(
        a == b,
        "queue_step.txt differs from Klipper's polar at line {first_difference:?} ({} and {} lines)",
        a.lines().count(),
        b.lines().count()
    );
}
