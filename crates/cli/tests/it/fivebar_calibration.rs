//! The five-bar's calibration from the command line, end to end: the pattern `calibrate fivebar-pattern` writes for
//! the example is accepted by `check`; its crosses as a machine built differently prints them (this file's own
//! circle–circle model, read to 0.01 mm as calipers read) give back that machine's keys, printed as a `[printer]`
//! section and written into a corrected config the machine builder reads; swapped columns are refused with the
//! cause named.

use std::path::Path;
use std::process::Command;

use crate::common::{binary, example_machine};

fn run(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(binary())
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run jointspace");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The machine as built: per side base, proximal and distal lengths, zero (degrees); the example's working mode
/// (distal links turning clockwise from the left elbow to the right one).
struct Built {
    sides: [([f64; 2], f64, f64, f64); 2],
}

impl Built {
    /// The nozzle at motor readings (degrees): the elbows, then the point left of left elbow → right elbow at
    /// both distal lengths (law of cosines at the left elbow).
    fn nozzle(&self, readings: [f64; 2]) -> [f64; 2] {
        let elbow = |k: usize| {
            let (base, proximal, _, zero) = self.sides[k];
            let t = (readings[k] - zero).to_radians();
            [base[0] + proximal * t.cos(), base[1] + proximal * t.sin()]
        };
        let (a, b) = (elbow(0), elbow(1));
        let (dl, dr) = (self.sides[0].2, self.sides[1].2);
        let e = (b[0] - a[0]).hypot(b[1] - a[1]);
        let line = (b[1] - a[1]).atan2(b[0] - a[0]);
        let turn = ((dl * dl + e * e - dr * dr) / (2.0 * dl * e)).acos();
        [
            a[0] + dl * (line + turn).cos(),
            a[1] + dl * (line + turn).sin(),
        ]
    }
}

/// The example built with its left base 0.3 mm left and 0.2 mm up, the right proximal link 0.4 mm long, the right
/// distal link 0.25 mm short, the left zero at 0.5° and the right at −0.3°.
const BUILT: Built = Built {
    sides: [
        ([-50.3, -199.8], 150.0, 200.0, 0.5),
        ([50.0, -200.0], 150.4, 199.75, -0.3),
    ],
};

/// The template filled in with where `built` prints each cross, read to 0.01 mm; `swap` exchanges x and y.
fn fill(template: &str, built: &Built, swap: bool) -> String {
    let mut out = String::new();
    for line in template.lines() {
        let cells: Vec<&str> = line.split(',').collect();
        let readings = (
            cells.first().and_then(|c| c.parse::<f64>().ok()),
            cells.get(1).and_then(|c| c.parse::<f64>().ok()),
        );
        match readings {
            (Some(l), Some(r)) if !line.starts_with('#') => {
                let [x, y] = built.nozzle([l, r]);
                let (x, y) = if swap { (y, x) } else { (x, y) };
                out += &format!("{},{},{x:.2},{y:.2}\n", cells[0], cells[1]);
            }
            _ => out += &format!("{line}\n"),
        }
    }
    out
}

#[test]
fn a_measured_pattern_gives_the_built_machines_keys_and_a_corrected_config() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_machine("fivebar");
    let config = config.to_str().expect("utf-8");
    let (code, out, err) = run(dir.path(), &["calibrate", "fivebar-pattern", "-c", config]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, out, err) = run(
        dir.path(),
        &["check", "-c", config, "fivebar-pattern.gcode"],
    );
    assert_eq!(code, Some(0), "check refuses the pattern: {out}{err}");
    assert!(out.contains("0 errors"), "{out}");
    let template =
        std::fs::read_to_string(dir.path().join("fivebar-measurements.csv")).expect("template");
    std::fs::write(dir.path().join("good.csv"), fill(&template, &BUILT, false)).expect("write");
    let fit = [
        "calibrate",
        "fivebar",
        "-c",
        config,
        "--measurements",
        "good.csv",
    ];
    let (code, out, err) = run(dir.path(), &[&fit[..], &["--json"]].concat());
    assert_eq!(code, Some(0), "{out}{err}");
    let json: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(json["verdict"]["trustworthy"], true);
    let truth = [
        ("left_base_x", -50.3),
        ("left_base_y", -199.8),
        ("left_zero", 0.5),
        ("right_proximal_length", 150.4),
        ("right_distal_length", 199.75),
        ("right_zero", -0.3),
        ("left_proximal_length", 150.0),
        ("right_base_x", 50.0),
    ];
    for (key, want) in truth {
        let got = json["printer"][key].as_f64().expect(key);
        assert!((got - want).abs() < 0.03, "{key}: {got}, built {want}");
    }
    // The text names the keys for printer.cfg, the relative-frame combinations, and writes the corrected config.
    let (code, out, err) = run(
        dir.path(),
        &[&fit[..], &["--corrected", "fixed.cfg"]].concat(),
    );
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(
        out.contains("corrected keys for printer.cfg:\n[printer]\n"),
        "{out}"
    );
    assert!(
        out.contains("not identified: ") && out.contains("frame_turn"),
        "{out}"
    );
    let (machine, _) = machine::Machine::load(&dir.path().join("fixed.cfg")).expect("loads");
    let kinematics::MachineParams::Fivebar(p) = machine.config.params else {
        panic!("not a five-bar");
    };
    assert!((p.left.base[0] + 50.3).abs() < 0.03 && (p.right.proximal - 150.4).abs() < 0.03);
    assert!((p.left.zero.to_degrees() - 0.5).abs() < 0.03);
    // x and y exchanged: refused, exit 1, the swap named (or the fit found nothing this machine prints).
    std::fs::write(
        dir.path().join("swapped.csv"),
        fill(&template, &BUILT, true),
    )
    .expect("write");
    let swapped = [
        "calibrate",
        "fivebar",
        "-c",
        config,
        "--measurements",
        "swapped.csv",
    ];
    let (code, out, err) = run(dir.path(), &swapped);
    assert_eq!(code, Some(1), "{out}");
    assert!(format!("{out}{err}").contains("swapped"), "{out}{err}");
    assert!(!dir.path().join("swapped.json").exists());
}
