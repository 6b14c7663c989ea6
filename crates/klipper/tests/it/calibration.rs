//! The SCARA calibration flow on the printer: `JOINTSPACE_SCARA_PATTERN` prints crosses and writes the measurements
//! file; filled in with where an arm built differently from its config really puts each cross, `jointspace
//! calibrate scara` recovers how it was built.

use std::ffi::OsStr;

use crate::engine::run_jointspace;
use crate::hosts::{Hosts, KLIPPER, workspace_root, write};

/// Where the arm as built (link 1 100.4 mm instead of 100, shoulder at (0.3, −0.2), ECR 3) puts the nozzle for
/// motor angles in degrees (closed form, REFERENCE.md §2).
fn as_built(a_deg: f64, b_deg: f64) -> (f64, f64) {
    let (a, b) = (a_deg.to_radians(), b_deg.to_radians());
    let (q1, q2) = (a, b - a / 3.0);
    (
        100.4 * q1.cos() + 100.0 * (q1 + q2).cos() + 0.3,
        100.4 * q1.sin() + 100.0 * (q1 + q2).sin() - 0.2,
    )
}

#[test]
fn scara_pattern_on_the_printer_then_identification() {
    let Some(hosts) = Hosts::get("scara_pattern_on_the_printer_then_identification") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = dir.path().join("printer.cfg");
    std::fs::copy(workspace_root().join("klipper/examples/scara.cfg"), &config)
        .expect("copy config");
    let gcode = write(
        dir.path(),
        "pattern.gcode",
        "M83\nG28\nJOINTSPACE_SCARA_PATTERN POSES=10\n",
    );
    let run = hosts.batch(KLIPPER, false, &config, &gcode, &dir.path().join("out"));
    run.expect_success("JOINTSPACE_SCARA_PATTERN");
    assert!(
        run.log.contains("printing 10 crosses"),
        "{}",
        crate::hosts::tail(&run.log, 20)
    );
    let template = std::fs::read_to_string(dir.path().join("jointspace-scara-measurements.csv"))
        .expect("the measurements file");
    // Fill in the template as a person with a ruler would.
    let mut filled = String::new();
    let mut rows = 0;
    for line in template.lines() {
        let cells: Vec<&str> = line.split(',').collect();
        match (
            cells.first().and_then(|c| c.parse::<f64>().ok()),
            cells.get(1).and_then(|c| c.parse::<f64>().ok()),
        ) {
            (Some(a), Some(b)) => {
                let (x, y) = as_built(a, b);
                filled += &format!("{a},{b},{x:.4},{y:.4}\n");
                rows += 1;
            }
            _ => filled += &format!("{line}\n"),
        }
    }
    assert_eq!(rows, 10, "{template}");
    let measurements = write(dir.path(), "measured.csv", &filled);
    let result = dir.path().join("scara.json");
    run_jointspace([
        OsStr::new("calibrate"),
        OsStr::new("scara"),
        OsStr::new("-c"),
        config.as_os_str(),
        OsStr::new("--measurements"),
        measurements.as_os_str(),
        OsStr::new("-o"),
        result.as_os_str(),
    ]);
    let json = std::fs::read_to_string(&result).expect("result");
    let number = |key: &str| -> f64 {
        let at = json
            .find(&format!("\"{key}\""))
            .unwrap_or_else(|| panic!("{key} in {json}"));
        let rest = &json[at + key.len() + 3..];
        let end = rest.find([',', '\n', '}']).expect("value end");
        rest[..end].trim().parse().expect("a number")
    };
    for (key, truth) in [
        ("link1_length", 100.4),
        ("link2_length", 100.0),
        ("offset_x", 0.3),
        ("offset_y", -0.2),
    ] {
        let got = number(key);
        assert!((got - truth).abs() < 0.01, "{key}: {got}, built {truth}");
    }
}

/// `[jointspace]` registers the command on every printer; on a polar one it says which kinematics it needs and
/// writes nothing.
#[test]
fn scara_pattern_on_a_polar_printer_names_what_it_needs() {
    let Some(hosts) = Hosts::get("scara_pattern_on_a_polar_printer_names_what_it_needs") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let config = dir.path().join("printer.cfg");
    std::fs::copy(workspace_root().join("klipper/examples/polar.cfg"), &config)
        .expect("copy config");
    let gcode = write(
        dir.path(),
        "pattern.gcode",
        "G28\nJOINTSPACE_SCARA_PATTERN\n",
    );
    let run = hosts.batch(KLIPPER, false, &config, &gcode, &dir.path().join("out"));
    assert!(
        run.log
            .contains("JOINTSPACE_SCARA_PATTERN needs kinematics: jointspace_scara"),
        "{}",
        crate::hosts::tail(&run.log, 20)
    );
    assert!(
        !dir.path()
            .join("jointspace-scara-measurements.csv")
            .exists()
    );
}

/// A text field of a pattern buffer (NUL-terminated).
fn buffer_text(buffer: &[u8]) -> String {
    let end = buffer.iter().position(|&b| b == 0).unwrap_or(buffer.len());
    String::from_utf8_lossy(&buffer[..end]).into_owned()
}

/// `JOINTSPACE_SCARA_PATTERN`'s library call and `jointspace calibrate scara-pattern` make the same pattern of one
/// printer.cfg (one pattern maker), and the plug-in's own inverse puts the motors at the listed angles at every cross
/// centre the G-code writes.
#[test]
fn the_printer_and_the_command_line_make_one_pattern() {
    use jointspace_klipper::{jointspace_inverse, jointspace_scara_pattern, machine::Machine};
    let config = workspace_root().join("klipper/examples/scara.cfg");
    let machine = Machine::from_config_file(&config, false).expect("the example machine");
    let (mut gcode, mut template) = (vec![0u8; 1 << 18], vec![0u8; 1 << 16]);
    // SAFETY: the buffers hold the lengths given; the machine outlives the call.
    let count = unsafe {
        jointspace_scara_pattern(
            &machine,
            20,
            6.0,
            gcode.as_mut_ptr().cast(),
            gcode.len(),
            template.as_mut_ptr().cast(),
            template.len(),
        )
    };
    assert_eq!(count, 20);
    let (gcode, template) = (buffer_text(&gcode), buffer_text(&template));
    let dir = tempfile::tempdir().expect("temp dir");
    let (cli_gcode, cli_template) = (dir.path().join("p.gcode"), dir.path().join("p.csv"));
    run_jointspace([
        OsStr::new("calibrate"),
        OsStr::new("scara-pattern"),
        OsStr::new("-c"),
        config.as_os_str(),
        OsStr::new("-o"),
        cli_gcode.as_os_str(),
        OsStr::new("--template"),
        cli_template.as_os_str(),
    ]);
    assert_eq!(std::fs::read_to_string(&cli_gcode).expect("G-code"), gcode);
    assert_eq!(
        std::fs::read_to_string(&cli_template).expect("template"),
        template
    );
    // Each cross centre (X of its vertical stroke, Y of its horizontal one) through the plug-in's inverse.
    let field = |line: &str, key: char| -> f64 {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(key))
            .and_then(|v| v.parse().ok())
            .expect("a coordinate")
    };
    let prints: Vec<&str> = gcode.lines().filter(|l| l.starts_with("G1 X")).collect();
    let rows: Vec<[f64; 2]> = template
        .lines()
        .filter_map(|l| {
            let mut cells = l.split(',');
            Some([cells.next()?.parse().ok()?, cells.next()?.parse().ok()?])
        })
        .collect();
    assert_eq!(rows.len(), 20);
    for (stroke, [a_deg, b_deg]) in prints.chunks(2).zip(rows) {
        let centre = [field(stroke[1], 'X'), field(stroke[0], 'Y'), 0.3];
        let mut motors = [0.0; 3];
        // SAFETY: three doubles in, three motors out, no previous, no error buffer.
        let status = unsafe {
            jointspace_inverse(
                &machine,
                centre.as_ptr(),
                std::ptr::null(),
                motors.as_mut_ptr(),
                std::ptr::null_mut(),
                0,
            )
        };
        assert_eq!(status, 0);
        assert!(
            (motors[0] - a_deg.to_radians()).abs() < 1e-9
                && (motors[1] - b_deg.to_radians()).abs() < 1e-9,
            "{centre:?}: {motors:?} vs {a_deg}°, {b_deg}°"
        );
    }
}
