//! A cross's centre to a fraction of a pixel: each stroke's centre line from the ink across it, sampled along the
//! stroke away from the crossing and the stroke's ends; the centre is where the two lines meet.
//!
//! At each station along a stroke the ink profile across it (bilinear between pixels, background removed) gives
//! the stroke's middle as the centroid of the ink above a quarter of the profile's peak: a blurred or spread stroke
//! stays symmetric about its middle, so neither blur nor ink spread moves it. The line is a total-least-squares fit
//! of the middles, refitted without those more than 3.5 robust deviations off (a speck of dust on a stroke, a
//! string leaving it); the whole is done twice, the second time along the first pass's lines.

use super::blobs::{RoughCross, intersection};
use super::signal::{Background, ScanImage, signal_at};

/// A fitted stroke: a point on its centre line, its unit direction, and how well its middles lie on the line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrokeLine {
    pub point: [f64; 2],
    pub direction: [f64; 2],
    /// RMS distance of the kept middles from the line (pixels).
    pub rms: f64,
    /// Middles kept on each side of the crossing.
    pub stations: [usize; 2],
}

/// A cross found on the scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectedCross {
    /// Where the strokes' centre lines meet (pixels; pixel (i, j) covers [i, i+1) × [j, j+1)).
    pub centre: [f64; 2],
    pub strokes: [StrokeLine; 2],
    /// How far the strokes reach from the centre (pixels).
    pub half_length: f64,
    /// Stroke width (pixels).
    pub width: f64,
    /// 1σ of the centre from the middles' scatter (pixels).
    pub sigma: f64,
}

/// The middle of the ink across a stroke at `at`, along the unit normal `n` within `reach`, if a stroke is there.
fn middle(
    image: &ScanImage,
    bg: &Background,
    at: [f64; 2],
    n: [f64; 2],
    reach: f64,
    floor: f64,
) -> Option<f64> {
    let samples = (2.0 * reach / 0.5).ceil() as usize + 1;
    let mut profile = Vec::with_capacity(samples);
    for k in 0..samples {
        let s = -reach + 0.5 * k as f64;
        profile.push((s, signal_at(image, bg, at[0] + s * n[0], at[1] + s * n[1])));
    }
    let peak = profile.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    if peak < floor {
        return None;
    }
    let cut = 0.25 * peak;
    let (mut sw, mut sws) = (0.0, 0.0);
    for (s, v) in &profile {
        let w = (v - cut).max(0.0);
        sw += w;
        sws += w * s;
    }
    // The whole stroke must lie within the window: no ink above the cut at its edges.
    let edge = profile[0].1.max(profile[samples - 1].1);
    (sw > 0.0 && edge < 0.5 * peak).then(|| sws / sw)
}

/// The stroke through `centre` along `u` reaching `half_length`, of width `width`, fitted from its middles.
fn fit_stroke(
    image: &ScanImage,
    bg: &Background,
    centre: [f64; 2],
    u: [f64; 2],
    half_length: f64,
    width: f64,
    floor: f64,
) -> Option<StrokeLine> {
    let n = [-u[1], u[0]];
    let inner = 1.2 * width + 3.0;
    let outer = half_length - (1.5 * width).max(0.15 * half_length);
    if outer <= inner + 4.0 {
        return None;
    }
    let step = ((outer - inner) / 300.0).max(1.0);
    let reach = 1.1 * width + 4.0;
    let mut points = Vec::new();
    for side in [-1.0, 1.0] {
        let mut t = inner;
        while t <= outer {
            let at = [centre[0] + side * t * u[0], centre[1] + side * t * u[1]];
            if let Some(s) = middle(image, bg, at, n, reach, floor) {
                points.push((side, [at[0] + s * n[0], at[1] + s * n[1]]));
            }
            t += step;
        }
    }
    robust_line(&points, u)
}

/// Total-least-squares line of the middles, refitted without the outliers; `None` with too few on either side.
fn robust_line(points: &[(f64, [f64; 2])], guess: [f64; 2]) -> Option<StrokeLine> {
    let mut kept: Vec<(f64, [f64; 2])> = points.to_vec();
    let mut line = None;
    for _ in 0..3 {
        let xy: Vec<[f64; 2]> = kept.iter().map(|p| p.1).collect();
        if xy.len() < 8 {
            return None;
        }
        let (p, mut d) = super::blobs::line_fit(&xy);
        if d[0] * guess[0] + d[1] * guess[1] < 0.0 {
            d = [-d[0], -d[1]];
        }
        let off = |q: &[f64; 2]| (q[0] - p[0]) * -d[1] + (q[1] - p[1]) * d[0];
        let mut devs: Vec<f64> = kept.iter().map(|q| off(&q.1).abs()).collect();
        devs.sort_by(f64::total_cmp);
        let limit = (3.5 * 1.4826 * devs[devs.len() / 2]).max(0.05);
        let rms = (kept.iter().map(|q| off(&q.1).powi(2)).sum::<f64>() / kept.len() as f64).sqrt();
        line = Some((p, d, rms));
        let before = kept.len();
        kept.retain(|q| off(&q.1).abs() <= limit);
        if kept.len() == before {
            break;
        }
    }
    let (point, direction, rms) = line?;
    let stations = [
        kept.iter().filter(|q| q.0 < 0.0).count(),
        kept.iter().filter(|q| q.0 > 0.0).count(),
    ];
    Some(StrokeLine {
        point,
        direction,
        rms,
        stations,
    })
}

/// The cross to sub-pixel precision from its rough shape, or why it cannot be measured.
pub fn refine(
    image: &ScanImage,
    bg: &Background,
    rough: &RoughCross,
    floor: f64,
) -> Result<DetectedCross, String> {
    let mut centre = rough.centre;
    let mut dirs = rough.directions;
    let mut width = rough.width;
    let half = rough.half_length[0].min(rough.half_length[1]);
    let mut strokes = None;
    for _ in 0..2 {
        let fitted: Option<Vec<StrokeLine>> = (0..2)
            .map(|k| fit_stroke(image, bg, centre, dirs[k], half, width, floor))
            .collect();
        let fitted = fitted.ok_or("a stroke has too little ink to measure")?;
        let lines = [fitted[0], fitted[1]];
        centre = intersection(
            (lines[0].point, lines[0].direction),
            (lines[1].point, lines[1].direction),
        )
        .ok_or("its strokes are not at right angles")?;
        dirs = [lines[0].direction, lines[1].direction];
        width = width.min(half / 3.0);
        strokes = Some(lines);
    }
    let strokes = strokes.ok_or("no strokes")?;
    let expected = ((half - (1.5 * width).max(0.15 * half) - 1.2 * width - 3.0)
        / ((half / 300.0).max(1.0)))
    .max(1.0);
    for s in &strokes {
        if (s.stations[0].min(s.stations[1]) as f64) < 0.4 * expected {
            return Err(format!(
                "a stroke is broken or smeared ({} and {} of about {:.0} points on its two sides)",
                s.stations[0], s.stations[1], expected
            ));
        }
    }
    let sigma = strokes
        .iter()
        .map(|s| s.rms / ((s.stations[0] + s.stations[1]) as f64).sqrt())
        .fold(0.0f64, |a, b| a.hypot(b));
    Ok(DetectedCross {
        centre,
        strokes,
        half_length: half,
        width,
        sigma,
    })
}
