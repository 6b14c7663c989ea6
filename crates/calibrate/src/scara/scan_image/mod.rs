//! SCARA calibration from a flatbed scan of the printed pattern: the crosses found on the image to a fraction of a
//! pixel, matched to the pattern's poses, and the arm identified with the scan's own frame.
//!
//! - `signal`: the scan as ink (any colours, either polarity) and its background (uneven lighting);
//! - `blobs`: marks on a coarse map, opened against strings and specks, the cross-shaped ones found roughly;
//! - `lines`: each stroke's centre line from the ink across it, the centre where the lines meet;
//! - `matching`: which cross is which pose (a similarity with or without mirror, robust to missing and extra
//!   crosses);
//! - [`calibrate_scan`]: all of it with the scale (a reference distance or the dpi) and the fit
//!   (`super::scan_fit`).

mod blobs;
mod lines;
mod matching;
mod signal;

pub use lines::{DetectedCross, StrokeLine};
pub use matching::{Matching, Similarity, match_poses};
pub use signal::{MAX_PIXELS, ScanImage};

use kinematics::ScaraFrame;

use super::scan_fit::{
    ScanFrame, ScanIdentification, ScanPoint, identify_in_scan, printer_forward,
};
use super::{ScaraError, ScaraGeometry};

/// Why a scan gives no calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanImageError {
    #[error("cannot read {file}: {message}")]
    Read { file: String, message: String },
    #[error("{file}: not an image that can be read (PNG or JPEG): {message}")]
    Decode { file: String, message: String },
    #[error(
        "{file}: {width} × {height} pixels is more than the {MAX_PIXELS} a scan may have (scan at a lower dpi)"
    )]
    TooLarge {
        file: String,
        width: usize,
        height: usize,
    },
    #[error(
        "{file}: nothing stands out of the background: a blank or uniform image, not a scan of the printed pattern"
    )]
    NoMarks { file: String },
    #[error(
        "{file}: {marks} marks found, none of them a cross ({reasons}): not a scan of the printed pattern"
    )]
    NoCrosses {
        file: String,
        marks: usize,
        reasons: String,
    },
    #[error(
        "{file}: {found} crosses found, but only {matched} of them lie where this configuration's pattern of {poses} \
         crosses puts them (at least {needed} needed): a scan of another pattern or another machine's, or too few \
         crosses found"
    )]
    NotThePattern {
        file: String,
        found: usize,
        matched: usize,
        poses: usize,
        needed: usize,
    },
    #[error(
        "{file}: the scale from {given} ({stated:.3} px/mm, {:.1} dpi) and the crosses' layout ({layout:.3} px/mm, \
         {:.1} dpi) differ by {:.1} %: a wrong --dpi or --reference", stated * 25.4, layout * 25.4,
        100.0 * (layout / stated - 1.0).abs()
    )]
    ScaleMismatch {
        file: String,
        given: String,
        stated: f64,
        layout: f64,
    },
    #[error("{file}: {message}")]
    Reference { file: String, message: String },
    #[error("{file}: {source}")]
    Fit { file: String, source: ScaraError },
}

/// A mark that was not taken for a cross, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    /// Its middle (pixels).
    pub at: [f64; 2],
    pub reason: String,
}

/// What was found on a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    pub crosses: Vec<DetectedCross>,
    pub rejected: Vec<Rejected>,
    /// Marks found in all (cross-shaped or not, specks left out).
    pub marks: usize,
}

/// Marks smaller than this many coarse blocks are specks.
const MIN_MARK_BLOCKS: usize = 12;
/// More marks than this: not a scan of a pattern (or all noise).
const MAX_MARKS: usize = 5000;

/// Finds the crosses on a scan. `px_per_mm`, when known, sizes the background cells (4 mm) and the coarse blocks
/// (0.1 mm); without it they follow the image's size.
pub fn detect_crosses(
    image: &ScanImage,
    name: &str,
    px_per_mm: Option<f64>,
) -> Result<Detection, ScanImageError> {
    let long = image.width.max(image.height) as f64;
    let (cell, factor) = match px_per_mm {
        Some(k) => ((4.0 * k).round() as usize, (k / 10.0).floor() as usize),
        None => (
            (long / 80.0).max(48.0) as usize,
            (long / 2500.0).floor() as usize,
        ),
    };
    let bg = signal::Background::of(image, cell);
    let no_marks = || ScanImageError::NoMarks {
        file: name.to_string(),
    };
    let map = blobs::coarse_map(image, &bg, factor.max(1)).ok_or_else(no_marks)?;
    let marks = blobs::marks(&map, MIN_MARK_BLOCKS, MAX_MARKS).ok_or_else(|| {
        ScanImageError::NoCrosses {
            file: name.to_string(),
            marks: MAX_MARKS,
            reasons: "more marks than a pattern has: noise or a picture".into(),
        }
    })?;
    if marks.is_empty() {
        return Err(no_marks());
    }
    let floor = 0.6 * map.threshold;
    let mut crosses = Vec::new();
    let mut rejected = Vec::new();
    for mark in &marks {
        let found =
            blobs::rough_cross(mark, map.factor).and_then(|r| lines::refine(image, &bg, &r, floor));
        match found {
            Ok(c) => crosses.push(c),
            Err(reason) => rejected.push((mark.points.len(), middle_of(&mark.points), reason)),
        }
    }
    let mut sizes: Vec<f64> = crosses.iter().map(|c| c.half_length).collect();
    sizes.sort_by(f64::total_cmp);
    let typical = sizes.get(sizes.len() / 2).copied().unwrap_or(0.0);
    let mut kept = Vec::new();
    for c in crosses {
        if (c.half_length / typical - 1.0).abs() > 0.35 {
            rejected.push((
                usize::MAX,
                c.centre,
                format!(
                    "its size differs from the other crosses' ({:.0} px, not {typical:.0})",
                    c.half_length
                ),
            ));
        } else {
            kept.push(c);
        }
    }
    // Specks far smaller than a cross are not worth naming.
    let cross_blocks = (typical * typical * 0.2 / (map.factor * map.factor) as f64) as usize;
    let rejected: Vec<Rejected> = rejected
        .into_iter()
        .filter(|(n, _, _)| kept.is_empty() || *n >= cross_blocks.max(MIN_MARK_BLOCKS))
        .map(|(_, at, reason)| Rejected { at, reason })
        .collect();
    Ok(Detection {
        crosses: kept,
        rejected,
        marks: marks.len(),
    })
}

fn middle_of(points: &[[f64; 2]]) -> [f64; 2] {
    let n = points.len().max(1) as f64;
    [
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    ]
}

/// Where the scan's scale comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScanScale {
    /// The scanner's stated resolution (dots per inch); its own error (typically 0.1–0.5 %) goes into both
    /// lengths.
    Dpi(f64),
    /// The distance (mm) between two crosses' strokes along the printer's Y (poses `first`, `second`, 1-based),
    /// measured with calipers; `dpi`, when also given, only sizes the detection.
    Reference {
        first: usize,
        second: usize,
        distance: f64,
        dpi: Option<f64>,
    },
}

impl ScanScale {
    fn dpi(&self) -> Option<f64> {
        match *self {
            ScanScale::Dpi(d) => Some(d),
            ScanScale::Reference { dpi, .. } => dpi,
        }
    }
}

/// A calibration from a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanCalibration {
    pub detection: Detection,
    pub matching: Matching,
    /// The scan's scale used (pixels per mm).
    pub px_per_mm: f64,
    /// The scale the crosses' layout gives with the configured geometry (pixels per mm).
    pub layout_px_per_mm: f64,
    /// Poses (1-based) without a cross on the scan.
    pub missing: Vec<usize>,
    /// Poses (1-based) whose cross was found but left out of the fit, with the reason.
    pub left_out: Vec<(usize, String)>,
    /// The fit; its measurements' `line` is the pose's number.
    pub fit: ScanIdentification,
}

/// Fewest crosses a scan must match for a fit worth judging (9 residual degrees of freedom).
pub const MIN_MATCHED: usize = 8;

/// Finds the pattern's crosses on the scan, matches them to `poses` (the motor angles of the pattern, in order),
/// fixes the scale and identifies the arm from `start` (the configured geometry) in the machine's `frame`.
pub fn calibrate_scan(
    image: &ScanImage,
    name: &str,
    poses: &[(f64, f64)],
    start: &ScaraGeometry,
    frame: ScaraFrame,
    scale: &ScanScale,
) -> Result<ScanCalibration, ScanImageError> {
    let stated = scale.dpi().map(|d| d / 25.4);
    let (detection, matching) = detect_and_match(image, name, poses, start, frame, stated)?;
    let found: Vec<[f64; 2]> = detection.crosses.iter().map(|c| c.centre).collect();
    let layout = matching.similarity.scale;
    let (px_per_mm, source) = scale_of(scale, &detection, &matching, name)?;
    if (layout / px_per_mm - 1.0).abs() > 0.05 {
        return Err(ScanImageError::ScaleMismatch {
            file: name.to_string(),
            given: source,
            stated: px_per_mm,
            layout,
        });
    }
    let missing = (0..poses.len())
        .filter(|&i| matching.assigned[i].is_none())
        .map(|i| i + 1)
        .collect();
    let points: Vec<ScanPoint> = matching
        .assigned
        .iter()
        .enumerate()
        .filter_map(|(i, j)| {
            j.map(|j| ScanPoint {
                motor_a: poses[i].0,
                motor_b: poses[i].1,
                at: [found[j][0] / px_per_mm, found[j][1] / px_per_mm],
                pose: i + 1,
            })
        })
        .collect();
    let sim = matching.similarity;
    let first = ScanFrame {
        rotation: sim.rotation,
        translation: [
            sim.translation[0] / px_per_mm,
            sim.translation[1] / px_per_mm,
        ],
        mirrored: sim.mirrored,
    };
    let (fit, left_out) = fit_leaving_out(&points, start, frame, first, name)?;
    Ok(ScanCalibration {
        detection,
        matching,
        px_per_mm,
        layout_px_per_mm: layout,
        missing,
        left_out,
        fit,
    })
}

/// The crosses on the scan and their poses (`stated`: the pixels per mm the dpi gives, when given).
fn detect_and_match(
    image: &ScanImage,
    name: &str,
    poses: &[(f64, f64)],
    start: &ScaraGeometry,
    frame: ScaraFrame,
    stated: Option<f64>,
) -> Result<(Detection, Matching), ScanImageError> {
    let detection = detect_crosses(image, name, stated)?;
    if detection.crosses.is_empty() {
        let mut reasons: Vec<String> = detection
            .rejected
            .iter()
            .map(|r| r.reason.clone())
            .collect();
        reasons.dedup();
        reasons.truncate(3);
        return Err(ScanImageError::NoCrosses {
            file: name.to_string(),
            marks: detection.marks,
            reasons: if reasons.is_empty() {
                "specks".into()
            } else {
                reasons.join("; ")
            },
        });
    }
    let nominal: Vec<[f64; 2]> = poses
        .iter()
        .map(|&(a, b)| printer_forward(start, frame, a, b))
        .collect();
    let found: Vec<[f64; 2]> = detection.crosses.iter().map(|c| c.centre).collect();
    let needed = MIN_MATCHED.max(poses.len().div_ceil(2));
    let bounds = stated.map(|k| (0.9 * k, 1.1 * k));
    let matching = match_poses(&nominal, &found, bounds);
    let matched = matching
        .as_ref()
        .map_or(0, |m| m.assigned.iter().flatten().count());
    let Some(matching) = matching.filter(|_| matched >= needed) else {
        return Err(ScanImageError::NotThePattern {
            file: name.to_string(),
            found: found.len(),
            matched,
            poses: poses.len(),
            needed,
        });
    };
    Ok((detection, matching))
}

/// A cross this far off the fit (mm), and this many times the others' typical residual, is left out: a smeared
/// or knocked cross.
const LEAVE_OUT_MM: f64 = 0.1;
const LEAVE_OUT_RATIO: f64 = 8.0;

/// The fit, refitted without the worst cross while one lies far off the others (at most two left out).
fn fit_leaving_out(
    points: &[ScanPoint],
    start: &ScaraGeometry,
    frame: ScaraFrame,
    first: ScanFrame,
    name: &str,
) -> Result<(ScanIdentification, Vec<(usize, String)>), ScanImageError> {
    let failed = |source| ScanImageError::Fit {
        file: name.to_string(),
        source,
    };
    let mut points = points.to_vec();
    let mut left_out = Vec::new();
    loop {
        let fit = identify_in_scan(&points, start, frame, first).map_err(failed)?;
        let mut distances: Vec<(usize, f64)> = fit
            .fit
            .residuals
            .iter()
            .enumerate()
            .map(|(i, r)| (i, r[0].hypot(r[1])))
            .collect();
        distances.sort_by(|a, b| b.1.total_cmp(&a.1));
        let typical = distances[distances.len() / 2].1;
        let (worst, off) = distances[0];
        if left_out.len() >= 2
            || points.len() <= MIN_MATCHED
            || off < LEAVE_OUT_MM
            || off < LEAVE_OUT_RATIO * typical
        {
            return Ok((fit, left_out));
        }
        let pose = points[worst].pose;
        left_out.push((
            pose,
            format!(
                "{off:.3} mm off the fit of the others (typical {typical:.3} mm): smeared or moved"
            ),
        ));
        points.remove(worst);
    }
}

/// The scale (pixels per mm) and where it comes from.
fn scale_of(
    scale: &ScanScale,
    detection: &Detection,
    matching: &Matching,
    name: &str,
) -> Result<(f64, String), ScanImageError> {
    match *scale {
        ScanScale::Dpi(dpi) => Ok((dpi / 25.4, format!("--dpi {dpi}"))),
        ScanScale::Reference {
            first,
            second,
            distance,
            ..
        } => {
            let px = reference_pixels(detection, matching, first, second).map_err(|message| {
                ScanImageError::Reference {
                    file: name.to_string(),
                    message,
                }
            })?;
            Ok((
                px / distance,
                format!("--reference {first},{second}={distance}"),
            ))
        }
    }
}

/// The distance (pixels) between the strokes along the printer's Y of poses `first` and `second` (1-based).
fn reference_pixels(
    detection: &Detection,
    matching: &Matching,
    first: usize,
    second: usize,
) -> Result<f64, String> {
    let cross = |pose: usize| -> Result<&DetectedCross, String> {
        let index = pose
            .checked_sub(1)
            .filter(|i| *i < matching.assigned.len())
            .ok_or(format!(
                "the reference names cross {pose}; the pattern's crosses are numbered 1 to {}",
                matching.assigned.len()
            ))?;
        matching.assigned[index]
            .map(|j| &detection.crosses[j])
            .ok_or(format!("reference cross {pose} was not found on the scan"))
    };
    if first == second {
        return Err(format!("the reference names cross {first} twice"));
    }
    let (a, b) = (cross(first)?, cross(second)?);
    let y = matching.similarity.direction([0.0, 1.0]);
    let along_y = |c: &DetectedCross| {
        let d = c
            .strokes
            .iter()
            .map(|s| s.direction)
            .max_by(|p, q| {
                (p[0] * y[0] + p[1] * y[1])
                    .abs()
                    .total_cmp(&(q[0] * y[0] + q[1] * y[1]).abs())
            })
            .unwrap_or(y);
        if d[0] * y[0] + d[1] * y[1] < 0.0 {
            [-d[0], -d[1]]
        } else {
            d
        }
    };
    let (da, db) = (along_y(a), along_y(b));
    let mean = [da[0] + db[0], da[1] + db[1]];
    let l = mean[0].hypot(mean[1]);
    let normal = [-mean[1] / l, mean[0] / l];
    let d =
        ((b.centre[0] - a.centre[0]) * normal[0] + (b.centre[1] - a.centre[1]) * normal[1]).abs();
    if d < 10.0 * a.width {
        return Err(format!(
            "reference crosses {first} and {second} are too close across the printer's Y to measure"
        ));
    }
    Ok(d)
}
