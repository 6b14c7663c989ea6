//! `jointspace estimate` tells the time the printer takes: the golden cases (real slicer files of the corpus placed
//! on each machine, and the synthetic ones) through the command line (`--klipper-batch`) and through Klipper in batch
//! mode — with the plug-in for the polar and SCARA machines, Klipper's own kinematics for the Cartesian ones — give
//! the same print time within 0.01 %: the time Klipper logs at the end of its input (`Exiting (print time …)`, to the
//! millisecond), which the estimate reproduces (`klipper_exit_time`: the end of the print, or where Klipper's step
//! generation could restart after a final M84, 52 ms later).

use crate::differential::{cli_json, host_print_time};
use crate::hosts::{Hosts, KLIPPER, plugin_config, shared};

#[test]
fn estimate_agrees_with_the_host() {
    let Some(hosts) = Hosts::get("estimate_agrees_with_the_host") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let polar = Some(("kinematics: polar", "kinematics: jointspace_polar"));
    let scara = Some(("kinematics: scara", "kinematics: jointspace_scara"));
    // The bed's limits make the plug-in cut moves near the centre and cap each piece: 73.8 s instead of 60.6 s.
    let limited = Some((
        "kinematics: polar",
        "kinematics: jointspace_polar\nmax_angular_velocity: 5\nmax_angular_accel: 200",
    ));
    let cases = [
        (
            "polar-prusa-minicube-arcs",
            "polar-prusa-minicube-arcs",
            polar,
        ),
        ("polar-cura-circle", "polar-cura-circle", polar),
        ("polar-kisslicer-cube", "polar-kisslicer-cube", polar),
        ("polar-synthetic", "polar-synthetic", polar),
        ("polar-synthetic-bed-limits", "polar-synthetic", limited),
        ("scara-fekt-cura-hex", "scara-fekt-cura-hex", scara),
        ("scara-fekt-synthetic", "scara-fekt-synthetic", scara),
        (
            "cartesian-prusa-minicube-arcs",
            "cartesian-prusa-minicube-arcs",
            None,
        ),
        (
            "cartesian-bambu-square-ring",
            "cartesian-bambu-square-ring",
            None,
        ),
    ];
    for (name, golden, swap) in cases {
        let case = shared().join("golden").join(golden);
        let config = match swap {
            Some(line) => plugin_config(
                &case.join("printer.cfg"),
                &[line],
                dir.path(),
                &format!("{name}.cfg"),
            ),
            None => case.join("printer.cfg"),
        };
        let input = case.join("input.gcode");
        let (cfg, gcode) = (config.to_string_lossy(), input.to_string_lossy());
        let json = cli_json(&["estimate", "-c", &cfg, &gcode, "--klipper-batch", "--json"]);
        let logged = json["klipper_exit_time"].as_f64().expect("exit time");
        let total = json["total"].as_f64().expect("total");
        // The print ends at `total`; Klipper's log adds only its restart delay after it (none, or 52 ms after M84).
        assert!(
            (0.0..0.06).contains(&(logged - total)),
            "{name}: ends at {total} s, logged {logged} s"
        );
        let run = hosts.batch(KLIPPER, false, &config, &input, &dir.path().join(name));
        run.expect_success(name);
        let host = host_print_time(&run);
        let diff = (logged - host) / host;
        println!(
            "{name}: jointspace estimate {total:.4} s (logged {logged:.4} s), Klipper {host:.3} s ({:+.5} %)",
            100.0 * diff
        );
        assert!(
            diff.abs() <= 1e-4,
            "{name}: {logged} s against the host's {host} s"
        );
    }
}
