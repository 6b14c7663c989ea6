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
    let cases = [
        (
            "polar-prusa-minicube-arcs",
            Some(("kinematics: polar", "kinematics: jointspace_polar")),
        ),
        (
            "polar-cura-circle",
            Some(("kinematics: polar", "kinematics: jointspace_polar")),
        ),
        (
            "scara-fekt-cura-hex",
            Some(("kinematics: scara", "kinematics: jointspace_scara")),
        ),
        ("cartesian-prusa-minicube-arcs", None),
        ("cartesian-bambu-square-ring", None),
    ];
    for (name, swap) in cases {
        let case = shared().join("golden").join(name);
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
        let ours =
            cli_json(&["estimate", "-c", &cfg, &gcode, "--klipper-batch", "--json"])["total"]
                .as_f64()
                .expect("total");
        let run = hosts.batch(KLIPPER, false, &config, &input, &dir.path().join(name));
        run.expect_success(name);
        let host = host_print_time(&run);
        let diff = (ours - host) / host;
        println!(
            "{name}: jointspace estimate {ours:.4} s, Klipper {host:.4} s ({:+.5} %)",
            100.0 * diff
        );
        assert!(
            diff.abs() <= 1e-4,
            "{name}: {ours} s against the host's {host} s"
        );
    }
}
