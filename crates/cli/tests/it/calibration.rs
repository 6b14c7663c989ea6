//! The SCARA calibration as a user runs it: `calibrate scara-pattern` writes crosses that `check` of the same machine
//! accepts, whose listed motor angles put the arm (a forward model written here) at the cross centres the G-code
//! writes; the filled-in measurements of an arm built differently identify it; and measurements that cannot be right
//! (columns swapped, a cross mis-measured, too few poses, another frame) are refused with a non-zero exit. And the
//! centre scan from a file knows its ring's size, so a missing last magnet is flagged.

use std::path::Path;

use crate::common::{example_machine, jointspace_in};

/// The example SCARA turned into an X-SCARA: its frame, the right elbow (the elbow endstop on that branch), the
/// shoulder off the origin, a singular band.
fn x_scara_config(dir: &Path) -> String {
    let text = std::fs::read_to_string(example_machine("scara")).expect("config");
    let text = text
        .replace("position_endstop: 105", "position_endstop: -75")
        .replace(
            "offset_x: 0\n",
            "offset_x: 2\nframe: xscara\nelbow: right\nsingularity_margin: 0.05\n",
        )
        .replace("offset_y: 0\n", "offset_y: -1.5\n");
    let path = dir.join("xscara.cfg");
    std::fs::write(&path, text).expect("write config");
    path.display().to_string()
}

/// An arm: lengths, shoulder, zeros, coupling, whether its angles count from +Y towards +X (X-SCARA).
struct Arm {
    l1: f64,
    l2: f64,
    shoulder: [f64; 2],
    zeros: [f64; 2],
    coupling: f64,
    from_y: bool,
}

impl Arm {
    /// The nozzle at motor readings in degrees: elbow at L1 along the shoulder joint, nozzle L2 further along the
    /// sum of the joints.
    fn nozzle(&self, a_deg: f64, b_deg: f64) -> [f64; 2] {
        let q1 = (a_deg - self.zeros[0]).to_radians();
        let q2 = (b_deg - self.zeros[1]).to_radians() - self.coupling * q1;
        let along = |t: f64| {
            if self.from_y {
                [t.sin(), t.cos()]
            } else {
                [t.cos(), t.sin()]
            }
        };
        let (d1, d2) = (along(q1), along(q1 + q2));
        [
            self.shoulder[0] + self.l1 * d1[0] + self.l2 * d2[0],
            self.shoulder[1] + self.l1 * d1[1] + self.l2 * d2[1],
        ]
    }
}

/// The motor angles (degrees) of each row of a measurements file, with its text lines.
fn listed_angles(template: &str) -> Vec<[f64; 2]> {
    template
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            Some([cells.first()?.parse().ok()?, cells.get(1)?.parse().ok()?])
        })
        .collect()
}

/// The cross centres the G-code writes: X of each vertical stroke, Y of each horizontal one.
fn written_centres(gcode: &str) -> Vec<[f64; 2]> {
    let field = |line: &str, key: char| -> f64 {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(key))
            .and_then(|v| v.parse().ok())
            .expect("a coordinate")
    };
    let prints: Vec<&str> = gcode.lines().filter(|l| l.starts_with("G1 X")).collect();
    prints
        .chunks(2)
        .map(|p| [field(p[1], 'X'), field(p[0], 'Y')])
        .collect()
}

fn run(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let out = jointspace_in(dir, args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The pattern of `config`, checked by `check` of the same config; returns the G-code and the measurements file.
fn checked_pattern(dir: &Path, config: &str) -> (String, String) {
    let (code, out, err) = run(dir, &["calibrate", "scara-pattern", "-c", config]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, out, err) = run(dir, &["check", "-c", config, "scara-pattern.gcode"]);
    assert_eq!(code, Some(0), "check refuses the pattern: {out}{err}");
    assert!(out.contains("0 errors"), "{out}");
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).expect("written");
    (read("scara-pattern.gcode"), read("scara-measurements.csv"))
}

#[test]
fn the_pattern_is_what_the_machine_does_and_check_accepts_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fekt = example_machine("scara").display().to_string();
    let x_scara = x_scara_config(dir.path());
    let nominal = |from_y: bool| Arm {
        l1: 100.0,
        l2: 100.0,
        shoulder: if from_y { [2.0, -1.5] } else { [0.0, 0.0] },
        zeros: [0.0, 0.0],
        coupling: 1.0 / 3.0,
        from_y,
    };
    for (config, arm, frame) in [
        (&fekt, nominal(false), "frame,standard"),
        (&x_scara, nominal(true), "frame,xscara"),
    ] {
        let (gcode, template) = checked_pattern(dir.path(), config);
        assert!(template.lines().any(|l| l == frame), "{template}");
        let (angles, centres) = (listed_angles(&template), written_centres(&gcode));
        assert_eq!(angles.len(), 20);
        assert_eq!(centres.len(), 20);
        for (&[a, b], c) in angles.iter().zip(&centres) {
            let p = arm.nozzle(a, b);
            // The listed angles (1e-10° in the file) put the nominal arm on the written centre.
            assert!(
                (p[0] - c[0]).abs() < 1e-8 && (p[1] - c[1]).abs() < 1e-8,
                "{config}: angles {a}, {b} put the nozzle at {p:?}, the cross is at {c:?}"
            );
        }
    }
}

/// The template filled in with where `arm` puts each cross, rounded to 0.01 mm as calipers read; `alter` may change
/// a row's (index, x, y).
fn fill(template: &str, arm: &Arm, alter: &dyn Fn(usize, f64, f64) -> (f64, f64)) -> String {
    let mut row = 0;
    let mut out = String::new();
    for line in template.lines() {
        let cells: Vec<&str> = line.split(',').collect();
        match (
            cells.first().and_then(|c| c.parse::<f64>().ok()),
            cells.get(1).and_then(|c| c.parse::<f64>().ok()),
        ) {
            (Some(a), Some(b)) => {
                let [x, y] = arm.nozzle(a, b);
                let (x, y) = alter(row, x, y);
                out += &format!("{},{},{x:.2},{y:.2}\n", cells[0], cells[1]);
                row += 1;
            }
            _ => out += &format!("{line}\n"),
        }
    }
    out
}

#[test]
fn measurements_identify_the_arm_or_are_refused_with_the_cause() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = x_scara_config(dir.path());
    let (_, template) = checked_pattern(dir.path(), &config);
    let built = Arm {
        l1: 100.4,
        l2: 99.7,
        shoulder: [2.3, -1.2],
        zeros: [0.4, -0.3],
        coupling: 1.0 / 3.0 * 1.002,
        from_y: true,
    };
    let fit = |name: &str, text: &str| {
        std::fs::write(dir.path().join(name), text).expect("write");
        run(
            dir.path(),
            &[
                "calibrate",
                "scara",
                "-c",
                &config,
                "--measurements",
                name,
                "--json",
            ],
        )
    };
    let (code, out, err) = fit("good.csv", &fill(&template, &built, &|_, x, y| (x, y)));
    assert_eq!(code, Some(0), "{out}{err}");
    let json: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    for (key, truth) in [
        ("link1_length", 100.4),
        ("link2_length", 99.7),
        ("offset_x", 2.3),
        ("offset_y", -1.2),
        ("shoulder_zero_deg", 0.4),
        ("elbow_zero_deg", -0.3),
        ("elbow_coupling", built.coupling),
    ] {
        let got = json[key].as_f64().expect(key);
        assert!((got - truth).abs() < 0.01, "{key}: {got}, built {truth}");
    }
    assert_eq!(json["verdict"]["trustworthy"], true);
    assert_eq!(json["frame"], "xscara");
    // x and y exchanged: refused, the swap named as the cause.
    let (code, out, _) = fit("swapped.csv", &fill(&template, &built, &|_, x, y| (y, x)));
    assert_eq!(code, Some(1));
    let json: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(json["verdict"]["trustworthy"], false);
    assert!(
        json["verdict"]["causes"][0]
            .as_str()
            .is_some_and(|c| c.contains("swapped")),
        "{out}"
    );
    // One cross read 0.5 mm off: refused, that cross named by its line.
    let off = fill(&template, &built, &|i, x, y| {
        if i == 7 { (x + 0.5, y) } else { (x, y) }
    });
    let line = off
        .lines()
        .filter(|l| l.contains('.') && !l.starts_with('#'))
        .nth(7)
        .expect("row");
    let number = off.lines().position(|l| l == line).expect("line") + 1;
    let (code, out, _) = fit("off.csv", &off);
    assert_eq!(code, Some(1));
    let json: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(json["verdict"]["worst"][0]["line"], number);
    let cause = json["verdict"]["causes"][0].as_str().unwrap_or_default();
    assert!(cause.contains(&format!("line {number}")), "{cause}");
    // Four poses: no residual freedom to show a mistake.
    let four: String = fill(&template, &built, &|_, x, y| (x, y))
        .lines()
        .filter(|l| !l.contains('.') || l.starts_with('#'))
        .chain(
            fill(&template, &built, &|_, x, y| (x, y))
                .lines()
                .filter(|l| l.contains('.') && !l.starts_with('#'))
                .take(4),
        )
        .map(|l| format!("{l}\n"))
        .collect();
    let (code, out, _) = fit("four.csv", &four);
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("residual degrees of freedom"), "{out}");
    // The file's frame is not the machine's: refused at the frame line.
    let standard =
        fill(&template, &built, &|_, x, y| (x, y)).replace("frame,xscara", "frame,standard");
    let at = standard
        .lines()
        .position(|l| l == "frame,standard")
        .expect("frame line")
        + 1;
    let (code, _, err) = fit("frame.csv", &standard);
    assert_eq!(code, Some(1));
    assert!(err.contains(&format!("frame.csv:{at}:1")), "{err}");
}

/// `calibrate centre --scan`: the ring's size comes from the file's `magnets` line or `--magnets`, so a magnet
/// missing in the last slot is flagged; without either the command says it cannot be.
#[test]
fn a_centre_scan_file_flags_a_missing_last_magnet() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (code, out, err) = run(
        dir.path(),
        &[
            "calibrate",
            "centre",
            "--simulate",
            "--offset",
            "0.5,-0.3",
            "--save-scan",
            "s.csv",
        ],
    );
    assert_eq!(code, Some(0), "{out}{err}");
    let text = std::fs::read_to_string(dir.path().join("s.csv")).expect("scan file");
    assert!(text.lines().any(|l| l == "magnets,16"), "{text}");
    let keep = |drop_ring: bool| -> String {
        text.lines()
            .filter(|l| !(l.starts_with("15,") || drop_ring && l.starts_with("magnets,")))
            .map(|l| format!("{l}\n"))
            .collect()
    };
    std::fs::write(dir.path().join("m.csv"), keep(false)).expect("write");
    std::fs::write(dir.path().join("n.csv"), keep(true)).expect("write");
    let flagged = "magnet 15 was not found";
    let (code, out, _) = run(dir.path(), &["calibrate", "centre", "--scan", "m.csv"]);
    assert_eq!(code, Some(0));
    assert!(out.contains(flagged), "{out}");
    let (_, out, _) = run(
        dir.path(),
        &["calibrate", "centre", "--scan", "n.csv", "--magnets", "16"],
    );
    assert!(out.contains(flagged), "{out}");
    let (_, out, err) = run(dir.path(), &["calibrate", "centre", "--scan", "n.csv"]);
    assert!(
        !out.contains(flagged) && err.contains("ring's size is not known"),
        "{out}{err}"
    );
    let (code, _, err) = run(
        dir.path(),
        &["calibrate", "centre", "--scan", "m.csv", "--magnets", "12"],
    );
    assert_eq!(code, Some(1));
    assert!(
        err.contains("16 magnets") && err.contains("--magnets says 12"),
        "{err}"
    );
}

/// A detections file of a ring of 16 magnets on 100 mm seen by a sensor whose reading point sits `shift` (mm,
/// along and across the arm) from the nozzle, with peak field `peak_mt`: each magnet's arm and bed readings from
/// the polar geometry itself (the sensor at (r + dx + sx, dy + sy) reads the bed point Rot(θ)·that).
fn tilted_detections(offset: [f64; 2], shift: [f64; 2], peak_mt: f64) -> String {
    let (ex, ey) = (offset[0] + shift[0], offset[1] + shift[1]);
    let mut text = String::from("magnets,16\nmagnet,side,arm_mm,bed_deg,peak_mt\n");
    for k in 0..16 {
        let a = std::f64::consts::TAU * f64::from(k) / 16.0;
        let rho = 100.0 + 0.05 * f64::from(k % 3);
        let along = (rho * rho - ey * ey).sqrt();
        for (side, r) in [("near", along - ex), ("far", -along - ex)] {
            let theta = a - ey.atan2(ex + r);
            text += &format!("{k},{side},{r:.6},{:.6},{peak_mt:.3}\n", theta.to_degrees());
        }
    }
    text
}

/// Two scans 2 mm apart of a sensor tilted 2°: a dipole's peak moves h·tan α / 4 with the sensor's distance h
/// to the magnets (5.5 mm, then 7.5 mm) and its peak field falls as 1/h³. `--scan-raised` removes the bias the
/// single scan keeps.
#[test]
fn a_second_scan_higher_up_removes_the_sensors_tilt() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (truth, slope) = ([0.8, -0.6], 2f64.to_radians().tan() / 4.0);
    let (h_low, h_high) = (5.5, 7.5);
    let towards = [30f64.to_radians().cos(), 30f64.to_radians().sin()];
    for (name, h) in [("low.csv", h_low), ("high.csv", h_high)] {
        let shift = [slope * h * towards[0], slope * h * towards[1]];
        let peak = 40.0 * (h_low / h).powi(3);
        std::fs::write(dir.path().join(name), tilted_detections(truth, shift, peak)).expect("scan");
    }
    let single = [
        "calibrate",
        "centre",
        "--scan",
        "low.csv",
        "--json",
        "-o",
        "one.json",
    ];
    let (status, out, err) = run(dir.path(), &single);
    assert_eq!(status, Some(0), "{err}");
    let one: serde_json::Value = serde_json::from_str(&out).expect("json");
    let off = |v: &serde_json::Value| {
        let d = [
            v["arm_zero_offset"].as_f64().expect("dx"),
            v["arm_lateral_offset"].as_f64().expect("dy"),
        ];
        (d[0] - truth[0]).hypot(d[1] - truth[1])
    };
    assert!((off(&one) - slope * h_low).abs() < 1e-3, "{}", off(&one));
    let two = [
        "calibrate",
        "centre",
        "--scan",
        "low.csv",
        "--scan-raised",
        "high.csv",
        "--raise",
        "2",
        "--json",
    ];
    let (status, out, err) = run(dir.path(), &two);
    assert_eq!(status, Some(0), "{err}");
    let fixed: serde_json::Value = serde_json::from_str(&out).expect("json");
    assert!(off(&fixed) < 1e-3, "{}", off(&fixed));
    let tilt = &fixed["tilt"];
    assert!(
        (tilt["distance"].as_f64().expect("distance") - h_low).abs() < 0.01,
        "{tilt}"
    );
    assert!(
        (tilt["tilt_deg"].as_f64().expect("tilt") - 2.0).abs() < 0.01,
        "{tilt}"
    );
    // The text says what was removed; the raise must come with the raised scan.
    let (_, text, _) = run(dir.path(), &two[..two.len() - 1]);
    assert!(text.contains("sensor tilt removed"), "{text}");
    let (status, _, err) = run(dir.path(), &two[..6]);
    assert_ne!(status, Some(0), "{err}");
}

/// The example SCARA's pattern printed by an arm built differently (links +0.4 / −0.3 mm, ECR 3.05, elbow zero
/// +0.3°), scanned at 300 dpi (sim's scan): `calibrate scara --image` with the pattern's template and `--dpi`
/// recovers the arm as built, writes the result and the picture, and says what a scan cannot determine; the same
/// with a calipers reference; a scan of another config's pattern is refused naming what was found.
#[test]
fn a_scan_of_the_pattern_identifies_the_arm() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = example_machine("scara");
    let config = config.to_str().expect("utf-8 path");
    let (_, template) = checked_pattern(dir.path(), config);
    let (machine, _) = machine::Machine::load(Path::new(config)).expect("the example loads");
    let believed =
        kinematics::scara::Scara::of(machine.setup.kinematics.as_ref()).expect("a SCARA");
    let options = calibrate::scara::PatternOptions {
        home: machine.setup.home_position,
        ..Default::default()
    };
    let pattern =
        calibrate::scara::machine_pattern(believed, calibrate::scara::DEFAULT_POSES, &options)
            .expect("a pattern");
    assert_eq!(pattern.template, template);
    let params = believed.params().clone();
    let actual_params = kinematics::ScaraParams {
        link1_length: params.link1_length + 0.4,
        link2_length: params.link2_length - 0.3,
        elbow_coupling: 1.0 / 3.05,
        ecr: Some(3.05),
        elbow_zero: params.elbow_zero + 0.3f64.to_radians(),
        ..params.clone()
    };
    let actual = kinematics::scara::Scara::new(actual_params.clone()).expect("valid");
    let settings = sim::scan::ScanSettings {
        dpi: 300.0,
        rotation_deg: -2.0,
        noise: 3.0,
        seed: 4,
    };
    let scan = sim::scan::render_scan(believed, &actual, &pattern, &settings);
    let rgb: Vec<u8> = scan.luma.iter().flat_map(|v| [*v, *v, *v]).collect();
    let png =
        plot::overlay_png(rgb, scan.width as u32, scan.height as u32, |_| {}).expect("encodes");
    std::fs::write(dir.path().join("scan.png"), png).expect("written");
    let (code, out, err) = run(
        dir.path(),
        &[
            "calibrate",
            "scara",
            "-c",
            config,
            "--image",
            "scan.png",
            "--dpi",
            "300",
            "--measurements",
            "scara-measurements.csv",
            "--plot",
            "found.png",
        ],
    );
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("not determined by a scan"), "{out}");
    assert!(dir.path().join("found.png").exists());
    let result: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("scara.json")).expect("result"),
    )
    .expect("json");
    let got = |key: &str| result[key].as_f64().expect("a number");
    assert!(
        (got("link1_length") - actual_params.link1_length).abs() < 0.01,
        "{result}"
    );
    assert!(
        (got("link2_length") - actual_params.link2_length).abs() < 0.01,
        "{result}"
    );
    assert!((got("ecr") - 3.05).abs() < 1e-3, "{result}");
    assert_eq!(result["scan"]["crosses"].as_array().map(Vec::len), Some(20));
    // A reference between the pattern's pair, as calipers read it on the print.
    let (a, b) = pattern.reference.expect("a reference pair");
    let printed = |i: usize| {
        let (ma, mb) = pattern.poses[i];
        let p = kinematics::Kinematics::forward(&actual, &[ma, mb, 0.3]).expect("reachable");
        [p[0], p[1]]
    };
    let distance = (printed(b)[0] - printed(a)[0]).abs();
    let reference = format!("{},{}={distance:.3}", a + 1, b + 1);
    let (code, out, err) = run(
        dir.path(),
        &[
            "calibrate",
            "scara",
            "-c",
            config,
            "--image",
            "scan.png",
            "--reference",
            &reference,
            "-o",
            "ref.json",
        ],
    );
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("calipers, crosses"), "{out}");
    // Another config's pattern: refused, naming the file and what was found.
    let other = dir.path().join("other.cfg");
    let text = std::fs::read_to_string(config).expect("config");
    std::fs::write(
        &other,
        text.replace("link1_length: 100", "link1_length: 120"),
    )
    .expect("written");
    let (code, out, err) = run(
        dir.path(),
        &[
            "calibrate",
            "scara",
            "-c",
            "other.cfg",
            "--image",
            "scan.png",
            "--dpi",
            "300",
            "-o",
            "o.json",
        ],
    );
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(
        err.contains("scan.png") && err.contains("crosses found"),
        "{err}"
    );
}
