//! The example printer.cfg files of `klipper/examples/` load in Klipper and Kalico, home and print a circle with
//! extrusion; the `jointspace` command line reads the same files (one printer.cfg serves both).

use std::ffi::OsStr;
use std::path::Path;

use crate::engine::run_jointspace;
use crate::hosts::{Hosts, KALICO, KLIPPER, workspace_root, write};

const POLAR_CIRCLE: &str = "G28\nG90\nM83\nG1 Z0.3 F600\nG1 X50 Y0 F6000\nG2 X50 Y0 I-50 J0 E10 F3000\nG1 X20 Y5 F6000\nG1 X-20 Y5 E2\nM400\n";
/// From the endstops' pose (0, −37.6): a circle of 40 mm about (0, 40), a line back.
const FIVEBAR_CIRCLE: &str = "G28\nG90\nM83\nG1 Z0.3 F600\nG1 X40 Y40 F6000\nG2 X40 Y40 I-40 J0 E5 F3000\nG1 X-40 Y0 E2\nM400\n";
const SCARA_CIRCLE: &str = "G28\nG90\nM83\nG1 Z0.3 F600\nG1 X20 Y130 F6000\nG2 X20 Y130 I-20 J0 E5 F3000\nG1 X-40 Y100 E2\nM400\n";

fn example(name: &str, gcode: &str) {
    let test = format!("example_{name}");
    let Some(hosts) = Hosts::get(&test) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = workspace_root().join(format!("klipper/examples/{name}.cfg"));
    let input = write(dir.path(), "print.gcode", gcode);
    for host in [KLIPPER, KALICO] {
        let run = hosts.batch(host, false, &config, &input, &dir.path().join(host));
        run.expect_success(&format!("{name} on {host}"));
        let messages = run
            .queue_step()
            .lines()
            .filter(|l| l.starts_with("queue_step"))
            .count();
        assert!(
            messages > 50,
            "{name} on {host}: only {messages} step messages"
        );
    }
    check_with_cli(&config, &input);
}

fn check_with_cli(config: &Path, input: &Path) {
    run_jointspace([
        OsStr::new("check"),
        OsStr::new("-c"),
        config.as_os_str(),
        input.as_os_str(),
    ]);
}

#[test]
fn polar_example_prints_in_both_hosts() {
    example("polar", POLAR_CIRCLE);
}

#[test]
fn scara_example_prints_in_both_hosts() {
    example("scara", SCARA_CIRCLE);
}

#[test]
fn fivebar_example_prints_in_both_hosts() {
    example("fivebar", FIVEBAR_CIRCLE);
}
