//! `calibrate scara --image`: the arm from a flatbed scan of the printed pattern — the crosses found and matched
//! to the pattern's poses, the scan's scale from a calipers reference or its dpi, the geometry fitted with the
//! scan's own frame, judged as measured crosses are, and a picture of what was found.

use super::{Method, ScaraArgs, measurement_frame, noise_of, pattern_machine, start_geometry};
use calibrate::scara::scan_image::{self, ScanCalibration, ScanImage, ScanScale};
use calibrate::scara::{self, ScaraGeometry, Verdict};
use kinematics::ScaraFrame;
use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

pub(super) fn scara_scan(args: &ScaraArgs, image_path: &Path) -> miette::Result<ExitCode> {
    let (start, config_frame) = start_geometry(args.config.as_deref())?;
    let (poses, frame) = pattern_poses(args, config_frame)?;
    let scale = scan_scale(args)?;
    let noise = noise_of(args, Method::Scanner)?;
    crate::output::register_input(image_path);
    for path in std::iter::once(&args.out).chain(args.plot.as_ref()) {
        crate::output::refuse_input(path).map_err(super::super::plain)?;
    }
    let name = image_path.display().to_string();
    let image = ScanImage::open(image_path).map_err(|e| miette::miette!("{e}"))?;
    let cal = scan_image::calibrate_scan(&image, &name, &poses, &start, frame, &scale)
        .map_err(|e| miette::miette!("{e}"))?;
    let verdict = scara::judge(&cal.fit.measurements, &cal.fit.fit, &start, frame, noise);
    let json = result_json(&cal, &verdict, &start, frame, &name);
    crate::output::write_output(&args.out, |w| Ok(serde_json::to_writer_pretty(w, &json)?))
        .map_err(super::super::plain)?;
    if let Some(png) = &args.plot {
        crate::scan_picture::draw_scan(&image, &cal, &poses, frame, png)?;
    }
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&json).unwrap_or_default()
        );
    } else {
        let mut text = scan_report(&cal, &start, &name, &scale);
        text += &crate::report::fit_verdict(&verdict, &cal.fit.measurements);
        if !crate::output::is_stdio(&args.out) {
            let _ = writeln!(text, "  result written to {}", args.out.display());
        }
        if let Some(png) = &args.plot {
            let _ = writeln!(text, "  what was found drawn in {}", png.display());
        }
        crate::out!("{text}");
    }
    if verdict.trustworthy {
        return Ok(ExitCode::SUCCESS);
    }
    crate::errln!(
        "error: {name}: the fit is not trustworthy: {}",
        verdict.problems.join("; ")
    );
    Ok(ExitCode::FAILURE)
}

/// The pattern's poses and frame: the `--measurements` file's (the template the printer or `scara-pattern` wrote),
/// else the default pattern this config makes (as `scara-pattern` and `JOINTSPACE_SCARA_PATTERN` make it).
fn pattern_poses(
    args: &ScaraArgs,
    config_frame: Option<ScaraFrame>,
) -> miette::Result<(Vec<(f64, f64)>, ScaraFrame)> {
    if let Some(path) = &args.measurements {
        crate::output::register_input(path);
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| miette::miette!("cannot read {name}: {e}"))?;
        let file = scara::parse_pose_file(&text, &name).map_err(|e| miette::miette!("{e}"))?;
        let frame = measurement_frame(file.frame, config_frame, &name)?;
        return Ok((file.poses, frame));
    }
    let (kin, home) = pattern_machine(args.config.as_deref())?;
    let arm = kinematics::scara::Scara::of(kin.as_ref())
        .ok_or_else(|| miette::miette!("not a SCARA machine"))?;
    let options = scara::PatternOptions {
        home,
        ..scara::PatternOptions::default()
    };
    let pattern = scara::machine_pattern(arm, scara::DEFAULT_POSES, &options)
        .map_err(|e| miette::miette!("{e}"))?;
    Ok((pattern.poses, pattern.frame))
}

/// The scan's scale from `--reference A,B=MM` or `--dpi`.
fn scan_scale(args: &ScaraArgs) -> miette::Result<ScanScale> {
    let dpi = match args.dpi {
        Some(d) if !(d.is_finite() && (50.0..=20_000.0).contains(&d)) => {
            miette::bail!("--dpi must be a scanner resolution between 50 and 20000, not {d}")
        }
        d => d,
    };
    let Some(text) = &args.reference else {
        return dpi.map(ScanScale::Dpi).ok_or_else(|| {
            miette::miette!(
                "the scan's scale is needed: give --reference A,B=MM (calipers between two crosses; the pattern \
                 names a pair) or --dpi DPI (the scanner's own scale error, typically 0.1–0.5 %, then goes into \
                 both link lengths)"
            )
        });
    };
    let bad = || {
        miette::miette!(
            "--reference takes `A,B=MM` (two cross numbers and their distance in mm), got `{text}`"
        )
    };
    let (pair, distance) = text.split_once('=').ok_or_else(bad)?;
    let (a, b) = pair.split_once(',').ok_or_else(bad)?;
    let first: usize = a.trim().parse().map_err(|_| bad())?;
    let second: usize = b.trim().parse().map_err(|_| bad())?;
    let distance: f64 = distance.trim().parse().map_err(|_| bad())?;
    if !(distance.is_finite() && distance > 0.0) {
        return Err(bad());
    }
    Ok(ScanScale::Reference {
        first,
        second,
        distance,
        dpi,
    })
}

/// Why the result leaves the offsets and the shoulder zero as configured.
const NOT_IDENTIFIED: &str = "the free frame of a scan absorbs the shoulder's position and a turn of the whole arm \
                              about it: these stay as configured (elbow_zero is relative to this shoulder_zero)";

/// The result file: what the scan identifies, what it leaves as configured, and what was found.
fn result_json(
    cal: &ScanCalibration,
    verdict: &Verdict,
    start: &ScaraGeometry,
    frame: ScaraFrame,
    name: &str,
) -> serde_json::Value {
    let g = &cal.fit.fit.geometry;
    let s = &cal.fit.fit.sigma;
    serde_json::json!({
        "link1_length": g.link1_length, "link2_length": g.link2_length,
        "elbow_zero_deg": g.elbow_zero.to_degrees(), "elbow_coupling": g.elbow_coupling,
        "ecr": 1.0 / g.elbow_coupling,
        "sigma": {"link1_length": s[0], "link2_length": s[1], "elbow_zero_deg": s[5].to_degrees(),
                  "elbow_coupling": s[6]},
        "not_identified": {"offset_x": start.offset_x, "offset_y": start.offset_y,
            "shoulder_zero_deg": start.shoulder_zero.to_degrees(),
            "why": NOT_IDENTIFIED},
        "rms_mm": cal.fit.fit.rms, "frame": scara::frame_name(frame),
        "scan": scan_json(cal, name),
        "verdict": verdict,
    })
}

/// What was found on the scan: its scale and frame, each cross with its residual, what was left out and why.
fn scan_json(cal: &ScanCalibration, name: &str) -> serde_json::Value {
    let crosses: Vec<serde_json::Value> = cal
        .fit
        .measurements
        .iter()
        .zip(&cal.fit.fit.residuals)
        .filter_map(|(m, r)| {
            let c = cal.detection.crosses[cal.matching.assigned[m.line - 1]?].centre;
            Some(
                serde_json::json!({"pose": m.line, "x_px": c[0], "y_px": c[1],
                                    "residual_mm": r[0].hypot(r[1])}),
            )
        })
        .collect();
    let rejected: Vec<serde_json::Value> = cal
        .detection
        .rejected
        .iter()
        .map(|r| serde_json::json!({"x_px": r.at[0], "y_px": r.at[1], "reason": r.reason}))
        .collect();
    let left_out: Vec<serde_json::Value> = cal
        .left_out
        .iter()
        .map(|(p, why)| serde_json::json!({"pose": p, "why": why}))
        .collect();
    serde_json::json!({
        "file": name, "px_per_mm": cal.px_per_mm, "dpi": cal.px_per_mm * 25.4,
        "layout_dpi": cal.layout_px_per_mm * 25.4,
        "rotation_deg": cal.fit.frame.rotation.to_degrees(), "mirrored": cal.fit.frame.mirrored,
        "crosses": crosses, "missing": cal.missing, "left_out": left_out, "rejected": rejected,
    })
}

/// The text report of a scan's calibration.
fn scan_report(
    cal: &ScanCalibration,
    start: &ScaraGeometry,
    name: &str,
    scale: &ScanScale,
) -> String {
    let (g, s) = (&cal.fit.fit.geometry, &cal.fit.fit.sigma);
    let mut t = String::new();
    let _ = writeln!(
        t,
        "SCARA calibration from the scan {name}: {} crosses found, {} matched to the pattern's {} poses",
        cal.detection.crosses.len(),
        cal.fit.measurements.len() + cal.left_out.len(),
        cal.matching.assigned.len()
    );
    let source = match scale {
        ScanScale::Dpi(d) => {
            format!("--dpi {d} (the scanner's scale error goes into both lengths)")
        }
        ScanScale::Reference {
            first,
            second,
            distance,
            ..
        } => {
            format!("calipers, crosses {first} and {second} {distance} mm apart")
        }
    };
    let _ = writeln!(
        t,
        "  scale {:.4} px/mm ({:.2} dpi) from {source}; the crosses' layout on the configured geometry says {:.2} dpi",
        cal.px_per_mm,
        cal.px_per_mm * 25.4,
        cal.layout_px_per_mm * 25.4
    );
    let _ = writeln!(
        t,
        "  scan turned {:.2}°{}",
        cal.fit.frame.rotation.to_degrees(),
        if cal.fit.frame.mirrored {
            ", mirrored (scanned face down)"
        } else {
            ""
        }
    );
    let _ = writeln!(t, "  link1_length   {:.4} mm ± {:.4}", g.link1_length, s[0]);
    let _ = writeln!(t, "  link2_length   {:.4} mm ± {:.4}", g.link2_length, s[1]);
    let _ = writeln!(
        t,
        "  elbow_zero     {:.4}° ± {:.4} (relative to shoulder_zero as configured)",
        g.elbow_zero.to_degrees(),
        s[5].to_degrees()
    );
    let _ = writeln!(
        t,
        "  elbow_coupling {:.6} ± {:.6} (ecr {:.5})",
        g.elbow_coupling,
        s[6],
        1.0 / g.elbow_coupling
    );
    let _ = writeln!(
        t,
        "  not determined by a scan (kept as configured): offset_x {:.3}, offset_y {:.3}, shoulder_zero {:.4}° — the \
         scan's free frame absorbs the shoulder's position and a turn of the whole arm about it; parts come out \
         true in size and shape, placed on the bed as these values say",
        start.offset_x,
        start.offset_y,
        start.shoulder_zero.to_degrees()
    );
    let _ = writeln!(t, "  residual RMS {:.4} mm", cal.fit.fit.rms);
    t += &scan_warnings(cal);
    t
}

/// The crosses missing or left out, and the marks not taken for crosses.
fn scan_warnings(cal: &ScanCalibration) -> String {
    let mut t = String::new();
    for pose in &cal.missing {
        let _ = writeln!(
            t,
            "  warning: cross {pose} not found on the scan (missing or smeared): left out"
        );
    }
    for (pose, why) in &cal.left_out {
        let _ = writeln!(t, "  warning: cross {pose} left out: {why}");
    }
    for r in &cal.detection.rejected {
        let _ = writeln!(
            t,
            "  note: a mark at pixel ({:.0}, {:.0}) is not a cross: {}",
            r.at[0], r.at[1], r.reason
        );
    }
    t
}
