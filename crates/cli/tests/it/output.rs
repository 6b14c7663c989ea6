//! Output streams: a reader that goes away (`jointspace … | head -1`) must not make the binary panic.

use std::process::{Command, Stdio};

use crate::common::{CircleStream, binary, example_machine, jointspace_in as jointspace};

#[test]
fn closed_stdout_is_not_a_panic() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("print.gcode");
    std::fs::write(&input, CircleStream::new().to_vec(1 << 16)).expect("write input");
    for args in [vec!["stats"], vec!["run", "-c"]] {
        let mut command = Command::new(binary());
        command.args(&args);
        if args[0] == "run" {
            command.arg(example_machine("cartesian"));
        }
        let mut child = command
            .arg(&input)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start jointspace");
        // Close the read end before the summary is printed.
        drop(child.stdout.take());
        let output = child.wait_with_output().expect("wait for jointspace");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            !stderr.contains("panicked") && output.status.code() != Some(101),
            "`{}` panicked when its stdout closed ({}):\n{stderr}",
            args[0],
            output.status
        );
    }
}

/// A small print with the modes slicers mix: absolute E (`M82`), `G92 E0`, and end code in `G91`.
const MIXED_MODES: &str = "G28\nM82\nG92 E0\nG1 Z0.3 F600\nG1 X20 Y0 F1800\nG1 X30 Y0 E0.5\nG1 X30 Y10 E0.6\n\
G91\nG1 Z1 E-0.1\nG1 X-5 Y5\nG90\n";

#[test]
fn no_command_overwrites_its_input_under_any_name() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("in.gcode"), MIXED_MODES).expect("write input");
    std::fs::hard_link(dir.join("in.gcode"), dir.join("link.gcode")).expect("hard link");
    std::fs::create_dir(dir.join("sub")).expect("mkdir");
    let config = dir.join("printer.cfg");
    std::fs::copy(example_machine("polar"), &config).expect("copy config");
    let config_text = std::fs::read(&config).expect("read config");
    let cfg = config.to_str().expect("utf-8 path");
    for (args, victim) in [
        (
            vec!["convert", "-c", cfg, "in.gcode", "-o", "in.gcode"],
            "in.gcode",
        ),
        (
            vec!["convert", "-c", cfg, "in.gcode", "-o", "link.gcode"],
            "in.gcode",
        ),
        (
            vec!["convert", "-c", cfg, "in.gcode", "-o", "sub/../in.gcode"],
            "in.gcode",
        ),
        (
            vec!["convert", "-c", cfg, "in.gcode", "-o", "printer.cfg"],
            "printer.cfg",
        ),
        (
            vec!["run", "-c", cfg, "in.gcode", "--moves", "in.gcode"],
            "in.gcode",
        ),
        (
            vec!["run", "-c", cfg, "in.gcode", "--moves", "link.gcode"],
            "in.gcode",
        ),
    ] {
        let output = jointspace(dir, &args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?} succeeded");
        assert!(stderr.contains("refusing to write"), "{args:?}: {stderr}");
        assert_eq!(
            std::fs::read(dir.join("in.gcode")).expect("input still there"),
            MIXED_MODES.as_bytes(),
            "{args:?} changed {victim}"
        );
        assert_eq!(std::fs::read(&config).expect("config"), config_text);
    }
    // Standard input that is the output file, too.
    let output = Command::new(binary())
        .current_dir(dir)
        .args(["convert", "-c", cfg, "-", "-o", "in.gcode"])
        .stdin(std::fs::File::open(dir.join("in.gcode")).expect("open"))
        .output()
        .expect("run jointspace");
    assert!(!output.status.success());
    assert_eq!(
        std::fs::read(dir.join("in.gcode")).expect("input"),
        MIXED_MODES.as_bytes()
    );
    // Outputs named by the command inside a folder: the simulation's report, the workspace maps.
    std::fs::create_dir(dir.join("report")).expect("mkdir");
    std::fs::copy(dir.join("in.gcode"), dir.join("report/report.txt")).expect("copy");
    let output = jointspace(
        dir,
        &[
            "simulate",
            "-c",
            cfg,
            "--actual",
            cfg,
            "report/report.txt",
            "-o",
            "report",
        ],
    );
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("refusing to write"));
    assert_eq!(
        std::fs::read(dir.join("report/report.txt")).expect("input"),
        MIXED_MODES.as_bytes()
    );
    std::fs::copy(&config, dir.join("report/report.json")).expect("copy");
    let output = jointspace(
        dir,
        &[
            "simulate",
            "-c",
            "report/report.json",
            "--actual",
            cfg,
            "in.gcode",
            "-o",
            "report",
        ],
    );
    assert!(String::from_utf8_lossy(&output.stderr).contains("refusing to write"));
    assert_eq!(
        std::fs::read(dir.join("report/report.json")).expect("config"),
        config_text
    );
    std::fs::create_dir(dir.join("maps")).expect("mkdir");
    std::fs::copy(&config, dir.join("maps/workspace-reach.png")).expect("copy");
    let output = jointspace(
        dir,
        &["workspace", "-c", "maps/workspace-reach.png", "-o", "maps"],
    );
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("refusing to write"));
    assert_eq!(
        std::fs::read(dir.join("maps/workspace-reach.png")).expect("config"),
        config_text
    );
    // calibrate: the picture's SVG sibling is an output too, and nothing is written when one is refused.
    let scan = "# scan\nmagnet,side,arm_mm,bed_deg\n0,near,99,10\n0,far,-101,190\n1,near,99,130\n1,far,-101,310\n\
2,near,99,250\n2,far,-101,70\n";
    std::fs::write(dir.join("map.svg"), scan).expect("scan");
    let output = jointspace(
        dir,
        &[
            "calibrate",
            "centre",
            "--scan",
            "map.svg",
            "-o",
            "c.json",
            "--plot",
            "map.png",
        ],
    );
    assert!(String::from_utf8_lossy(&output.stderr).contains("refusing to write"));
    assert!(!dir.join("c.json").exists() && !dir.join("map.png").exists());
    assert_eq!(
        std::fs::read_to_string(dir.join("map.svg")).expect("scan"),
        scan
    );
    // A different file is fine.
    let output = jointspace(dir, &["convert", "-c", cfg, "in.gcode", "-o", "out.gcode"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn dash_writes_standard_output_not_a_file_named_dash() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("in.gcode"), MIXED_MODES).expect("write input");
    let cfg = example_machine("polar");
    let cfg = cfg.to_str().expect("utf-8 path");
    let output = jointspace(dir, &["convert", "-c", cfg, "in.gcode", "-o", "-"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.starts_with("; converted by jointspace\nG90\nM83\n"),
        "{stdout}"
    );
    assert!(stdout.contains("G1 "), "{stdout}");
    // Verified too: from a copy of what went out; the report on standard error, the G-code alone on stdout.
    let output = jointspace(
        dir,
        &["convert", "-c", cfg, "in.gcode", "-o", "-", "--verify"],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&output.stdout), stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("filament 0.50000 → 0.50000 mm"), "{stderr}");
    let output = jointspace(dir, &["run", "-c", cfg, "in.gcode", "--moves", "-"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(String::from_utf8_lossy(&output.stdout).starts_with("trapq,print_time,"));
    assert!(!dir.join("-").exists(), "a file named `-` was written");
}

#[cfg(unix)]
#[test]
fn output_files_get_the_permissions_of_any_new_file() {
    use std::os::unix::fs::PermissionsExt;
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("in.gcode"), MIXED_MODES).expect("write input");
    let cfg = example_machine("polar");
    let script = format!(
        "umask 022 && exec '{}' convert -c '{}' in.gcode -o out.gcode && exec true",
        binary(),
        cfg.display()
    );
    let status = Command::new("sh")
        .current_dir(dir)
        .args(["-c", &script])
        .status()
        .expect("run sh");
    assert!(status.success());
    let script = format!(
        "umask 022 && exec '{}' run -c '{}' in.gcode --moves moves.csv --steps steps",
        binary(),
        cfg.display()
    );
    assert!(
        Command::new("sh")
            .current_dir(dir)
            .args(["-c", &script])
            .status()
            .expect("sh")
            .success()
    );
    for file in ["out.gcode", "moves.csv", "steps/stepper_bed.txt"] {
        let mode = std::fs::metadata(dir.join(file))
            .expect("written")
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o644, "{file}: mode {:o}", mode & 0o777);
    }
}

#[test]
fn convert_verify_reads_the_written_file_as_each_firmware_does() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    std::fs::write(dir.join("in.gcode"), MIXED_MODES).expect("write input");
    let cfg = example_machine("polar");
    let cfg = cfg.to_str().expect("utf-8 path");
    for firmware in ["marlin", "rrf", "klipper"] {
        for absolute in [false, true] {
            let mut args = vec![
                "convert",
                "-c",
                cfg,
                "in.gcode",
                "-o",
                "out.gcode",
                "--verify",
            ];
            args.extend(["--firmware", firmware]);
            if absolute {
                args.push("--absolute-e");
            }
            let output = jointspace(dir, &args);
            let stdout = String::from_utf8_lossy(&output.stdout);
            assert!(
                output.status.success(),
                "{args:?}: {stdout}{}",
                String::from_utf8_lossy(&output.stderr)
            );
            let line = stdout
                .lines()
                .find(|l| l.starts_with("verification"))
                .expect("report");
            assert!(line.contains("reading out.gcode"), "{line}");
            // 0.5 + 0.1 − 0.1 mm of filament, read back the same.
            assert!(line.contains("filament 0.50000 → 0.50000 mm"), "{line}");
            // Homed first: Z starts at the config's 0.5, never an invented 0.
            let written = std::fs::read_to_string(dir.join("out.gcode")).expect("output");
            assert!(
                !written
                    .lines()
                    .any(|l| l.contains(" Z0 ") || l.ends_with(" Z0")),
                "{written}"
            );
        }
    }
}

#[test]
fn convert_centre_shift_reproduces_the_thesis_example() {
    // R_old 5 at φ π/4 with the centre displaced by d = (2, 1) → R 2.97, φ 1.03 rad (exactly 2.9643, 1.0263).
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = 5.0 * std::f64::consts::FRAC_PI_4.cos();
    std::fs::write(
        dir.join("in.gcode"),
        format!("G28\nG0 X{p:.9} Y{p:.9} Z1\n"),
    )
    .expect("input");
    let cfg = example_machine("polar");
    let cfg = cfg.to_str().expect("utf-8 path");
    let args = [
        "convert",
        "-c",
        cfg,
        "in.gcode",
        "-o",
        "out.gcode",
        "--radians",
        "--centre-shift",
        "2,1",
    ];
    let output = jointspace(dir, &args);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let written = std::fs::read_to_string(dir.join("out.gcode")).expect("output");
    let line = written
        .lines()
        .find(|l| l.starts_with("G0 X"))
        .expect("positioning move");
    let value = |letter: char| -> f64 {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(letter))
            .and_then(|v| v.parse().ok())
            .expect("word")
    };
    assert!((value('X') - 2.964).abs() < 1e-3, "{line}");
    assert!((value('Y') - 1.0263).abs() < 1e-3, "{line}");
    // The arm-offset model gives another radius for the same numbers.
    let args = [
        "convert",
        "-c",
        cfg,
        "in.gcode",
        "-o",
        "arm.gcode",
        "--radians",
        "--centre-offset",
        "2,1",
    ];
    assert!(jointspace(dir, &args).status.success());
    let written = std::fs::read_to_string(dir.join("arm.gcode")).expect("output");
    assert!(written.contains("G0 X2.899"), "{written}");
}

#[test]
fn a_machine_that_reaches_nothing_is_an_error_not_an_empty_map() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let text = std::fs::read_to_string(example_machine("scara")).expect("config");
    // The base protection covers more than the arms reach (100 + 100 mm).
    let text = text.replace("base_protection_radius: 60", "base_protection_radius: 250");
    std::fs::write(dir.join("printer.cfg"), text).expect("write config");
    let output = jointspace(dir, &["workspace", "-c", "printer.cfg", "-o", "maps"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("reaches no point of the bed"), "{stderr}");
    assert!(
        !dir.join("maps").exists(),
        "pictures of nothing were written"
    );
    // The example machine itself maps fine.
    let cfg = example_machine("scara");
    let output = jointspace(
        dir,
        &[
            "workspace",
            "-c",
            cfg.to_str().expect("utf-8"),
            "-o",
            "maps",
            "--json",
        ],
    );
    assert!(output.status.success());
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    assert!(json["reachable_area_mm2"].as_f64().expect("area") > 10_000.0);
}

#[test]
fn a_map_needs_no_endstops() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let text = std::fs::read_to_string(example_machine("scara")).expect("config");
    let without: String = text
        .lines()
        .filter(|l| !l.starts_with("endstop_pin") && !l.starts_with("position_endstop"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(!without.contains("endstop_pin"));
    std::fs::write(dir.join("printer.cfg"), without).expect("write config");
    let output = jointspace(
        dir,
        &["workspace", "-c", "printer.cfg", "-o", "maps", "--json"],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("json");
    // The same map as with endstops: they change nothing in where the arm reaches.
    let cfg = example_machine("scara");
    let with = jointspace(
        dir,
        &[
            "workspace",
            "-c",
            cfg.to_str().expect("utf-8"),
            "-o",
            "maps2",
            "--json",
        ],
    );
    let with: serde_json::Value = serde_json::from_slice(&with.stdout).expect("json");
    assert_eq!(json["reachable_area_mm2"], with["reachable_area_mm2"]);
    // Homing is what needs them: G28 is refused at its line.
    std::fs::write(dir.join("home.gcode"), "G28\n").expect("write");
    let output = jointspace(dir, &["run", "-c", "printer.cfg", "home.gcode"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        stderr.contains("home.gcode:1:1") && stderr.contains("no homing position"),
        "{stderr}"
    );
}

/// A full disk under an output stops the run where it happens, with the error, not after planning the whole file:
/// the moves CSV to standard output on `/dev/full` (every write fails with "No space left on device").
#[test]
#[cfg(target_os = "linux")]
fn a_full_output_stops_the_run_early_with_its_error() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("SKIPPED: no /dev/full here");
        return;
    };
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("print.gcode");
    let lines = 200_000;
    let text: String = (0..lines)
        .map(|i| format!("G1 X{} Y{} F6000\n", 10 + i % 50, 10 + (i / 50) % 50))
        .collect();
    std::fs::write(&input, text).expect("write input");
    let output = Command::new(binary())
        .args(["run", "--moves", "-", "-c"])
        .arg(example_machine("cartesian"))
        .arg(&input)
        .stdout(full)
        .stderr(Stdio::piped())
        .output()
        .expect("run jointspace");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("No space left on device"), "{stderr}");
    // The line where planning stopped: within the first few thousand of 200,000.
    let stopped_at: u64 = stderr
        .split("print.gcode:")
        .nth(1)
        .and_then(|rest| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no stopping line in: {stderr}"));
    assert!(
        stopped_at < 5_000,
        "stopped only at line {stopped_at}: {stderr}"
    );
}

/// A G-code file with terminal escape sequences (retitle, clear screen, a C1 CSI) in a refused line: the
/// diagnostic shows them escaped, never raw.
#[test]
fn escape_sequences_in_a_file_never_reach_the_terminal() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("evil.gcode");
    let evil = "G28\nG1 X10 Y10 F3000\nG1 X\u{1b}]0;pwned\u{7}\u{1b}[2J\u{9b}31m5\n";
    std::fs::write(&input, evil).expect("write input");
    let machine = example_machine("cartesian");
    for command in ["run", "check"] {
        let out = jointspace(
            scratch.path(),
            &[
                command,
                "-c",
                &machine.to_string_lossy(),
                &input.to_string_lossy(),
            ],
        );
        assert_ne!(out.status.code(), Some(0), "{command} accepted the line");
        for (stream, bytes) in [("stderr", &out.stderr), ("stdout", &out.stdout)] {
            let text = String::from_utf8_lossy(bytes);
            assert!(
                !text.contains(['\u{1b}', '\u{7}', '\u{9b}']),
                "{command}: a raw control character on {stream}:\n{text:?}"
            );
        }
        if command == "run" {
            // The refused line is shown, escaped.
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(stderr.contains("X\\x1B]0;pwned\\x07"), "{stderr}");
        }
    }
}

/// A closed standard input is not an empty file, and a closed standard output is not a success.
#[test]
fn closed_standard_streams_are_errors() {
    let machine = example_machine("cartesian");
    let run = |args: &[&str], close: &str| {
        // The shell closes the stream (`<&-`, `>&-`) before jointspace starts.
        let line = format!("{} {} {close}", binary(), args.join(" "));
        Command::new("sh")
            .arg("-c")
            .arg(line)
            .output()
            .expect("sh runs")
    };
    let machine = machine.to_string_lossy();
    let closed_in = run(&["check", "-c", &machine, "-"], "<&-");
    assert_eq!(closed_in.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&closed_in.stderr).contains("standard input: it is closed"));
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("print.gcode");
    std::fs::write(&input, "G28\nG1 X10 Y10 F3000\n").expect("write input");
    let closed_out = run(&["run", "-c", &machine, &input.to_string_lossy()], ">&-");
    assert_eq!(closed_out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&closed_out.stderr).contains("standard output: it is closed"));
}
