//! SCARA calibration from a scan, on scans rendered from this crate's own model of the printed pattern
//! (`scan_render`): the crosses found to 0.005 mm at 600 dpi, the arm identified as a scan can (both lengths, the
//! coupling, the elbow's zero relative to the shoulder's) within 0.02 mm / 0.02° / 0.02 %, and bad scans refused
//! with what was found.

use std::f64::consts::PI;
use std::time::Instant;

use calibrate::scara::scan_image::{ScanImageError, ScanScale, calibrate_scan};
use calibrate::scara::{self, PatternOptions, ScaraGeometry};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::scan_render::{Rendered, Scanner, render};
use crate::scara_pattern::{Arm, limited_machine, random_arm_with_links};

/// A random arm as built, FEKT-like or X-SCARA-like (lengths 90–115 mm, coupling 1/4–1, shoulder within ±5 mm,
/// zeros within ±3°), and the config its owner believes (±1 mm, ±0.5°, ±0.5 %).
fn random_arm(rng: &mut StdRng, x_scara: bool) -> (Arm, Arm) {
    random_arm_with_links(rng, x_scara, 90.0..115.0)
}

/// The scanner of arm `k`: 600 dpi, a few degrees of rotation, every third face down, every fourth in colour,
/// a scale error up to 0.3 %, dust and strings.
fn scanner(rng: &mut StdRng, k: usize) -> Scanner {
    Scanner {
        scale_error: rng.random_range(-0.003..0.003),
        rotation_deg: rng.random_range(-4.0..4.0),
        mirrored: k % 3 == 2,
        dust: 60,
        strings: 4,
        colour: (k % 4 == 3).then_some([200, 40, 30]),
        ..Scanner::at(600.0)
    }
}

/// The pair of poses best for calipers: the farthest apart along the printer's X within 20 mm along Y.
fn reference_pair(centres: &[[f64; 2]]) -> (usize, usize) {
    let mut best = (0, 1, 0.0);
    for i in 0..centres.len() {
        for j in i + 1..centres.len() {
            let (dx, dy) = (
                (centres[i][0] - centres[j][0]).abs(),
                (centres[i][1] - centres[j][1]).abs(),
            );
            if dy <= 20.0 && dx <= 150.0 && dx > best.2 {
                best = (i, j, dx);
            }
        }
    }
    (best.0, best.1)
}

/// What calipers read between the two crosses' strokes along Y as printed (the perpendicular distance between the
/// two, nearly parallel, printed lines), with 0.01 mm of noise.
fn calipers(r: &Rendered, pair: (usize, usize), rng: &mut StdRng) -> f64 {
    let dir = |v: [[f64; 2]; 2]| {
        let d = [v[1][0] - v[0][0], v[1][1] - v[0][1]];
        let l = d[0].hypot(d[1]);
        [d[0] / l, d[1] / l]
    };
    let (a, b) = (dir(r.vertical[pair.0]), dir(r.vertical[pair.1]));
    let mean = [a[0] + b[0], a[1] + b[1]];
    let l = mean[0].hypot(mean[1]);
    let n = [-mean[1] / l, mean[0] / l];
    let (p, q) = (r.printed[pair.0], r.printed[pair.1]);
    ((q[0] - p[0]) * n[0] + (q[1] - p[1]) * n[1]).abs()
        + 0.01 * (rng.random::<f64>() - 0.5) * 2.0 * 3f64.sqrt()
}

/// One arm scanned and calibrated: the largest centre error (mm) and each parameter's error over its bound
/// (lengths 0.02 mm, elbow zero relative to the shoulder's 0.02°, coupling 0.02 %).
struct Outcome {
    centre_error: f64,
    scaled: [f64; 3],
    missing: usize,
}

fn scan_and_calibrate(
    truth: &Arm,
    believed: &Arm,
    s: &Scanner,
    seed: u64,
    scale: Option<ScanScale>,
) -> Outcome {
    let kin = limited_machine(believed, Some((0.0, PI)));
    let pattern = scara::machine_pattern(&kin, scara::DEFAULT_POSES, &PatternOptions::default())
        .expect("a pattern");
    let rendered = render(&kin, truth, &pattern, s, seed, &[], &[]);
    let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
    let pair = reference_pair(&pattern.centres);
    let scale = scale.unwrap_or(ScanScale::Reference {
        first: pair.0 + 1,
        second: pair.1 + 1,
        distance: calipers(&rendered, pair, &mut rng),
        dpi: Some(s.dpi),
    });
    let start = ScaraGeometry::from_array([
        believed.l1,
        believed.l2,
        believed.shoulder[0],
        believed.shoulder[1],
        believed.zero_a,
        believed.zero_b,
        believed.coupling,
    ]);
    let frame = kin.params().frame;
    let cal = calibrate_scan(
        &rendered.image(),
        "synthetic.png",
        &pattern.poses,
        &start,
        frame,
        &scale,
    )
    .expect("a calibration");
    let k = s.true_px_per_mm();
    let centre_error = cal
        .matching
        .assigned
        .iter()
        .enumerate()
        .filter_map(|(i, j)| j.map(|j| (i, cal.detection.crosses[j].centre)))
        .map(|(i, c)| (c[0] - rendered.centres[i][0]).hypot(c[1] - rendered.centres[i][1]) / k)
        .fold(0.0, f64::max);
    let g = cal.fit.fit.geometry;
    let relative_zero = |z2: f64, c: f64, z1: f64| z2 - c * z1;
    let zero_error = relative_zero(g.elbow_zero, g.elbow_coupling, believed.zero_a)
        - relative_zero(truth.zero_b, truth.coupling, truth.zero_a);
    let scaled = [
        (g.link1_length - truth.l1)
            .abs()
            .max((g.link2_length - truth.l2).abs())
            / 0.02,
        zero_error.to_degrees().abs() / 0.02,
        ((g.elbow_coupling - truth.coupling) / truth.coupling).abs() / 2e-4,
    ];
    Outcome {
        centre_error,
        scaled,
        missing: cal.missing.len() + cal.left_out.len(),
    }
}

/// `arms` random arms (every other X-SCARA-like) scanned at 600 dpi and calibrated with a calipers reference: at
/// least 90 % within 0.02 mm / 0.02° / 0.02 %, every cross found within 0.005 mm.
fn random_arms_from_scans(arms: usize, seed: u64) {
    let started = Instant::now();
    let mut rng = StdRng::seed_from_u64(seed);
    let (mut within, mut worst_centre, mut worst) = (0, 0.0f64, [0.0f64; 3]);
    for k in 0..arms {
        let (truth, believed) = random_arm(&mut rng, k % 2 == 1);
        let s = scanner(&mut rng, k);
        let o = scan_and_calibrate(&truth, &believed, &s, seed + k as u64, None);
        assert_eq!(o.missing, 0, "arm {k}: every cross found and kept");
        worst_centre = worst_centre.max(o.centre_error);
        for (w, e) in worst.iter_mut().zip(o.scaled) {
            *w = w.max(e);
        }
        within += usize::from(o.scaled.iter().all(|e| *e <= 1.0));
    }
    println!(
        "{arms} random arms scanned at 600 dpi (rotation ±4°, a third face down, a quarter in colour, scale error \
         ±0.3 %, dust, strings), calipers reference: {within} within 0.02 mm / 0.02° / 0.02 %; worst over bound: \
         lengths {:.2}, elbow zero {:.2}, coupling {:.2}; worst cross centre {:.4} mm; {:.1} s",
        worst[0],
        worst[1],
        worst[2],
        worst_centre,
        started.elapsed().as_secs_f64()
    );
    assert!(
        worst_centre <= 0.005,
        "a cross centre {worst_centre} mm off"
    );
    assert!(10 * within >= 9 * arms, "{within} of {arms} within bounds");
}

/// The sampled run: eight arms, the same accuracy ratio as the full 50.
#[test]
fn random_arms_are_identified_from_synthetic_scans() {
    random_arms_from_scans(8, 1200);
}

/// The full run: 50 arms (`cargo test --release -p calibrate -- --ignored fifty`).
#[test]
#[ignore = "long: about a minute in release; the sampled test runs the same check on 8 arms"]
fn fifty_random_arms_are_identified_from_synthetic_scans() {
    random_arms_from_scans(50, 5000);
}

/// The FEKT-like arm of the edge cases, its believed config and machine (shoulder on half a turn), and its
/// pattern.
fn edge_case_arm(l: f64, seed: u64) -> (Arm, Arm, scara::Pattern, kinematics::scara::Scara) {
    let mut rng = StdRng::seed_from_u64(seed);
    let (mut truth, mut believed) = random_arm(&mut rng, false);
    let scale = l / truth.l1;
    for arm in [&mut truth, &mut believed] {
        arm.l1 *= scale;
        arm.l2 *= scale;
    }
    let kin = limited_machine(&believed, Some((0.0, PI)));
    let pattern = scara::machine_pattern(&kin, scara::DEFAULT_POSES, &PatternOptions::default())
        .expect("a pattern");
    (truth, believed, pattern, kin)
}

fn geometry_of(arm: &Arm) -> ScaraGeometry {
    ScaraGeometry::from_array([
        arm.l1,
        arm.l2,
        arm.shoulder[0],
        arm.shoulder[1],
        arm.zero_a,
        arm.zero_b,
        arm.coupling,
    ])
}

/// A cross not printed is flagged missing, a smeared one is not taken for a cross (or left out of the fit), and
/// the rest still identify the arm.
#[test]
fn a_missing_and_a_smeared_cross_are_flagged_and_left_out() {
    let (truth, believed, pattern, kin) = edge_case_arm(100.0, 31);
    let s = Scanner {
        dust: 40,
        strings: 3,
        rotation_deg: 2.0,
        ..Scanner::at(600.0)
    };
    let r = render(&kin, &truth, &pattern, &s, 8, &[2], &[6]);
    let cal = calibrate_scan(
        &r.image(),
        "edge.png",
        &pattern.poses,
        &geometry_of(&believed),
        kin.params().frame,
        &ScanScale::Dpi(600.0),
    )
    .expect("a calibration");
    assert!(cal.missing.contains(&3), "{:?}", cal.missing);
    let smeared_out = cal.missing.contains(&7) || cal.left_out.iter().any(|(p, _)| *p == 7);
    assert!(
        smeared_out,
        "missing {:?}, left out {:?}",
        cal.missing, cal.left_out
    );
    assert_eq!(cal.fit.measurements.len(), pattern.poses.len() - 2);
    let g = cal.fit.fit.geometry;
    assert!(((g.elbow_coupling - truth.coupling) / truth.coupling).abs() < 2e-4);
}

/// A JPEG at 300 dpi and a PNG at 1200 dpi (a smaller arm), both in colour: every cross found, within 0.01 mm at
/// 300 dpi and 0.005 mm at 1200.
#[test]
fn jpeg_at_300_dpi_and_png_at_1200_dpi() {
    for (dpi, l, jpeg, bound) in [(300.0, 100.0, Some(85), 0.01), (1200.0, 55.0, None, 0.005)] {
        let (truth, believed, pattern, kin) = edge_case_arm(l, 77);
        let s = Scanner {
            rotation_deg: -3.0,
            mirrored: true,
            dust: 30,
            colour: Some([40, 90, 200]),
            ..Scanner::at(dpi)
        };
        let r = render(&kin, &truth, &pattern, &s, 3, &[], &[]);
        let bytes = crate::scan_render::encode(&r, jpeg);
        let image =
            calibrate::scara::scan_image::ScanImage::decode(&bytes, "scan").expect("decodes");
        let cal = calibrate_scan(
            &image,
            "scan",
            &pattern.poses,
            &geometry_of(&believed),
            kin.params().frame,
            &ScanScale::Dpi(dpi),
        )
        .expect("a calibration");
        assert!(
            cal.missing.is_empty(),
            "{dpi} dpi: missing {:?}",
            cal.missing
        );
        let k = s.true_px_per_mm();
        for (i, j) in cal.matching.assigned.iter().enumerate() {
            let c = cal.detection.crosses[j.expect("found")].centre;
            let e = (c[0] - r.centres[i][0]).hypot(c[1] - r.centres[i][1]) / k;
            assert!(e <= bound, "{dpi} dpi: cross {} off by {e} mm", i + 1);
        }
    }
}

/// The scan of another machine's pattern, a blank page, a page of dust and strings and a truncated file are
/// refused with what was found.
#[test]
fn scans_that_are_not_this_pattern_are_refused() {
    let (truth, believed, pattern, kin) = edge_case_arm(100.0, 5);
    let s = Scanner::at(300.0);
    let r = render(&kin, &truth, &pattern, &s, 1, &[], &[]);
    let (_, other, _, other_kin) = edge_case_arm(120.0, 6);
    let other_pattern =
        scara::machine_pattern(&other_kin, scara::DEFAULT_POSES, &PatternOptions::default())
            .expect("a pattern");
    let wrong = calibrate_scan(
        &r.image(),
        "other.png",
        &other_pattern.poses,
        &geometry_of(&other),
        other_kin.params().frame,
        &ScanScale::Dpi(300.0),
    );
    assert!(
        matches!(wrong, Err(ScanImageError::NotThePattern { ref file, found: 20, .. }) if file == "other.png"),
        "{wrong:?}"
    );
    let start = geometry_of(&believed);
    let frame = kin.params().frame;
    let blank = calibrate::scara::scan_image::ScanImage::from_luma8(400, 300, vec![230; 120_000])
        .expect("image");
    let refused = calibrate_scan(
        &blank,
        "blank.png",
        &pattern.poses,
        &start,
        frame,
        &ScanScale::Dpi(300.0),
    );
    assert!(
        matches!(refused, Err(ScanImageError::NoMarks { .. })),
        "{refused:?}"
    );
    let dusty = Scanner {
        dust: 300,
        strings: 20,
        ..Scanner::at(300.0)
    };
    let only_dust = render(
        &kin,
        &truth,
        &pattern,
        &dusty,
        2,
        &(0..20).collect::<Vec<_>>(),
        &[],
    );
    let refused = calibrate_scan(
        &only_dust.image(),
        "dust.png",
        &pattern.poses,
        &start,
        frame,
        &ScanScale::Dpi(300.0),
    );
    assert!(
        matches!(
            refused,
            Err(ScanImageError::NoCrosses { .. } | ScanImageError::NotThePattern { .. })
        ),
        "{refused:?}"
    );
    let bytes = crate::scan_render::encode(&r, None);
    let cut = calibrate::scara::scan_image::ScanImage::decode(&bytes[..bytes.len() / 2], "cut.png");
    assert!(
        matches!(cut, Err(ScanImageError::Decode { ref file, .. }) if file == "cut.png"),
        "{cut:?}"
    );
}

/// With the scanner's dpi instead of a reference, its scale error goes into both lengths (0.3 % here: 0.3 mm on a
/// 100 mm link) while the coupling and the elbow zero, which a scale does not change, stay within bounds.
#[test]
fn the_dpi_scale_error_goes_into_the_lengths_only() {
    let mut rng = StdRng::seed_from_u64(404);
    let (truth, believed) = random_arm(&mut rng, true);
    let s = Scanner {
        scale_error: 0.003,
        ..Scanner::at(600.0)
    };
    let o = scan_and_calibrate(&truth, &believed, &s, 9, Some(ScanScale::Dpi(600.0)));
    let expected = 0.003 * truth.l1.max(truth.l2) / 0.02;
    assert!(
        o.scaled[0] > 0.7 * expected && o.scaled[0] < 1.3 * expected,
        "{:?} vs {expected}",
        o.scaled
    );
    assert!(o.scaled[1] <= 1.0 && o.scaled[2] <= 1.0, "{:?}", o.scaled);
}

/// The fixture scans (`tests/fixtures/scan/`): small crops of real-looking edge cases, made by
/// [`write_scan_fixtures`] from this crate's scan model, each with the true centre of its cross (pixels) beside it.
fn fixture_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/scan")
}

/// A one-cross crop of the pattern of arm `seed`'s first pose, scanned by `s`.
fn one_cross(s: &Scanner, seed: u64, smeared: bool) -> Rendered {
    let (truth, _, mut pattern, kin) = edge_case_arm(100.0, seed);
    pattern.poses.truncate(1);
    pattern.centres.truncate(1);
    render(
        &kin,
        &truth,
        &pattern,
        s,
        seed,
        &[],
        if smeared { &[0] } else { &[] },
    )
}

/// A scanner with little noise, so the fixture files stay small.
fn quiet(dpi: f64) -> Scanner {
    Scanner {
        noise: 1.5,
        ..Scanner::at(dpi)
    }
}

/// Writes the fixture scans (`cargo test --release -p calibrate -- --ignored write_scan_fixtures`).
#[test]
#[ignore = "writes the fixture files; run by hand when the scan model changes"]
fn write_scan_fixtures() {
    let dir = fixture_dir();
    std::fs::create_dir_all(&dir).expect("fixture folder");
    let dusty = Scanner {
        rotation_deg: 7.0,
        dust: 6,
        strings: 2,
        noise: 6.0,
        colour: Some([220, 170, 20]),
        ..Scanner::at(600.0)
    };
    let cases = [
        (
            "yellow-cross-jpeg-q60.jpg",
            one_cross(&dusty, 41, false),
            Some(60),
        ),
        (
            "grey-cross-1200dpi-q85.jpg",
            one_cross(&quiet(1200.0), 42, false),
            Some(85),
        ),
        (
            "smeared-cross.png",
            one_cross(&quiet(600.0), 43, true),
            None,
        ),
    ];
    for (name, r, jpeg) in cases {
        std::fs::write(dir.join(name), crate::scan_render::encode(&r, jpeg)).expect("written");
        let truth = format!("{} {}\n", r.centres[0][0], r.centres[0][1]);
        std::fs::write(dir.join(name).with_extension("txt"), truth).expect("written");
    }
}

/// The fixtures read as a user's files would be: the yellow cross (JPEG at quality 60, turned 7°, dust and strings)
/// and the 1200 dpi one found within 0.005 mm of where they were printed, the smeared one not taken for a cross.
#[test]
fn fixture_scans_are_read_as_they_should_be() {
    use calibrate::scara::scan_image::{ScanImage, detect_crosses};
    let dir = fixture_dir();
    for (name, dpi) in [
        ("yellow-cross-jpeg-q60.jpg", 600.0),
        ("grey-cross-1200dpi-q85.jpg", 1200.0),
    ] {
        let path = dir.join(name);
        assert!(
            std::fs::metadata(&path).expect("fixture").len() < 200_000,
            "{name} is small"
        );
        let image = ScanImage::open(&path).expect("decodes");
        let truth: Vec<f64> = std::fs::read_to_string(path.with_extension("txt"))
            .expect("truth")
            .split_whitespace()
            .map(|v| v.parse().expect("a number"))
            .collect();
        let found = detect_crosses(&image, name, Some(dpi / 25.4)).expect("marks");
        assert_eq!(found.crosses.len(), 1, "{name}: {:?}", found.rejected);
        let c = found.crosses[0].centre;
        let error = (c[0] - truth[0]).hypot(c[1] - truth[1]) * 25.4 / dpi;
        assert!(error <= 0.005, "{name}: {error} mm off");
    }
    let image = ScanImage::open(&dir.join("smeared-cross.png")).expect("decodes");
    let found = detect_crosses(&image, "smeared-cross.png", Some(600.0 / 25.4)).expect("marks");
    assert!(
        found.crosses.is_empty() && !found.rejected.is_empty(),
        "{found:?}"
    );
}
