//! `[include]` as a hostile or mistaken config uses it: an endless chain, a file included again and again by many
//! others, a device or a FIFO included, and an output aimed at an included file. Each is refused at the include's
//! line, quickly, without touching any input.

use std::path::Path;
use std::time::{Duration, Instant};

use crate::common::{example_machine, jointspace_in as jointspace};

/// The example polar machine with `extra` appended (includes resolve relative to `dir`).
fn printer_cfg(dir: &Path, extra: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(example_machine("polar")).expect("example config");
    let path = dir.join("printer.cfg");
    std::fs::write(&path, format!("{text}\n{extra}\n")).expect("write config");
    path
}

/// `jointspace check` of a one-move print with `cfg`: (exit code, stderr), and how long it took.
fn check(dir: &Path, cfg: &Path) -> (Option<i32>, String, Duration) {
    let gcode = dir.join("print.gcode");
    std::fs::write(&gcode, "G28\nG1 X10 Y10 F3000\n").expect("write gcode");
    let started = Instant::now();
    let out = jointspace(
        dir,
        &[
            "check",
            "-c",
            &cfg.to_string_lossy(),
            &gcode.to_string_lossy(),
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    (out.status.code(), stderr, started.elapsed())
}

fn assert_refused(dir: &Path, cfg: &Path, phrase: &str, place: &str) {
    let (code, stderr, took) = check(dir, cfg);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains(phrase), "no `{phrase}` in:\n{stderr}");
    assert!(stderr.contains(place), "no `{place}` in:\n{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(took < Duration::from_secs(20), "took {took:?}");
}

#[test]
fn an_endless_include_chain_stops_at_the_depth_limit() {
    let dir = tempfile::tempdir().expect("temp dir");
    for i in 0..2000 {
        let next = format!("[include chain{}.cfg]\n", i + 1);
        std::fs::write(dir.path().join(format!("chain{i}.cfg")), next).expect("write");
    }
    std::fs::write(dir.path().join("chain2000.cfg"), "").expect("write");
    let cfg = printer_cfg(dir.path(), "[include chain0.cfg]");
    assert_refused(
        dir.path(),
        &cfg,
        "includes nest more than 64 files deep",
        "chain62.cfg:1:",
    );
}

#[test]
fn a_diamond_of_includes_is_refused_in_linear_time() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Level i has two files, each including both files of level i + 1: 2^30 reads if nothing stopped it.
    for level in 0..30 {
        for side in ["a", "b"] {
            let text = format!("[include l{n}a.cfg]\n[include l{n}b.cfg]\n", n = level + 1);
            std::fs::write(dir.path().join(format!("l{level}{side}.cfg")), text).expect("write");
        }
    }
    for side in ["a", "b"] {
        std::fs::write(dir.path().join(format!("l30{side}.cfg")), "").expect("write");
    }
    let cfg = printer_cfg(dir.path(), "[include l0a.cfg]");
    assert_refused(
        dir.path(),
        &cfg,
        "more than 1000 files read for one config",
        ".cfg:",
    );
}

#[test]
fn a_device_or_a_fifo_is_not_included() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cfg = printer_cfg(dir.path(), "[include /dev/zero]");
    assert_refused(
        dir.path(),
        &cfg,
        "not a regular file (a device)",
        "printer.cfg:",
    );
    let fifo = dir.path().join("pipe.cfg");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let cfg = printer_cfg(dir.path(), "[include pipe.cfg]");
    assert_refused(
        dir.path(),
        &cfg,
        "not a regular file (a FIFO)",
        "printer.cfg:",
    );
    // The main file too: a FIFO given as printer.cfg is refused, not read for ever.
    let (code, stderr, took) = check(dir.path(), &fifo);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("not a regular file (a FIFO)"), "{stderr}");
    assert!(took < Duration::from_secs(20));
}

#[test]
fn no_output_replaces_an_included_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let extra = dir.path().join("extra.cfg");
    let extra_text = "[gcode_arcs]\nresolution: 1.0\n";
    std::fs::write(&extra, extra_text).expect("write");
    let cfg = printer_cfg(dir.path(), "[include extra.cfg]");
    let gcode = dir.path().join("print.gcode");
    std::fs::write(&gcode, "G28\nG1 X10 Y10 F3000\n").expect("write gcode");
    let (cfg, gcode, extra_s) = (
        cfg.to_string_lossy().into_owned(),
        gcode.to_string_lossy().into_owned(),
        extra.to_string_lossy().into_owned(),
    );
    let runs: [Vec<&str>; 2] = [
        vec!["run", "-c", &cfg, &gcode, "--moves", &extra_s],
        vec!["convert", "-c", &cfg, &gcode, "-o", &extra_s],
    ];
    for args in runs {
        let out = jointspace(dir.path(), &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains("input"), "{args:?}: {stderr}");
        let now = std::fs::read_to_string(&extra).expect("extra.cfg still there");
        assert_eq!(now, extra_text, "{args:?} replaced an included file");
    }
}
