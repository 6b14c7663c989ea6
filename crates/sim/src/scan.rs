//! A flatbed scan of the printed SCARA calibration pattern, for the demo and the command line's tests: each
//! cross's strokes where the machine as built prints them (its forward kinematics at the motor angles the believed
//! machine commands along each stroke), 0.45 mm wide, blurred, dark on paper under an uneven light with noise, at
//! the scanner's dpi and turned as the print lay on the glass.

use calibrate::scara::Pattern;
use kinematics::Kinematics;
use kinematics::scara::Scara;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// How the print is scanned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanSettings {
    pub dpi: f64,
    pub rotation_deg: f64,
    /// Grey-level noise (1σ).
    pub noise: f64,
    pub seed: u64,
}

/// A synthetic scan: grey pixels row by row, and where each cross's centre was printed (pixels).
#[derive(Debug, Clone)]
pub struct SyntheticScan {
    pub width: usize,
    pub height: usize,
    pub luma: Vec<u8>,
    pub centres: Vec<[f64; 2]>,
}

/// Stroke width (mm) and the scanner's blur (1σ, mm).
const STROKE: f64 = 0.45;
const BLUR: f64 = 0.035;

/// The printed path of the straight stroke `a`–`b` (bed mm): commanded by `believed`, placed by `actual`.
fn printed(believed: &Scara, actual: &Scara, a: [f64; 2], b: [f64; 2]) -> Vec<[f64; 2]> {
    (0..=12)
        .filter_map(|i| {
            let f = f64::from(i) / 12.0;
            let mut m = [0.0; 3];
            let p = [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, 0.3];
            believed.inverse(p, &mut m).ok()?;
            actual.forward(&m).ok().map(|q| [q[0], q[1]])
        })
        .collect()
}

fn distance(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    line.windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy).max(1e-12))
                .clamp(0.0, 1.0);
            (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The scan of `pattern` (made for `believed`) printed by `actual`.
pub fn render_scan(
    believed: &Scara,
    actual: &Scara,
    pattern: &Pattern,
    s: &ScanSettings,
) -> SyntheticScan {
    let k = s.dpi / 25.4;
    let (sin, cos) = s.rotation_deg.to_radians().sin_cos();
    let turn = |p: [f64; 2]| [k * (cos * p[0] - sin * p[1]), k * (sin * p[0] + cos * p[1])];
    let mut strokes = Vec::new();
    let mut centres = Vec::new();
    for (c, &(a, b)) in pattern.centres.iter().zip(&pattern.poses) {
        strokes.push(printed(
            believed,
            actual,
            [c[0] - 3.0, c[1]],
            [c[0] + 3.0, c[1]],
        ));
        strokes.push(printed(
            believed,
            actual,
            [c[0], c[1] - 3.0],
            [c[0], c[1] + 3.0],
        ));
        let q = actual
            .forward(&[a, b, 0.3])
            .map_or([c[0], c[1]], |q| [q[0], q[1]]);
        centres.push(turn(q));
    }
    let lines: Vec<Vec<[f64; 2]>> = strokes
        .iter()
        .map(|l| l.iter().map(|p| turn(*p)).collect())
        .collect();
    let all = lines.iter().flatten();
    let lo = all
        .clone()
        .fold([f64::INFINITY; 2], |m, p| [m[0].min(p[0]), m[1].min(p[1])]);
    let hi = all.fold([f64::NEG_INFINITY; 2], |m, p| {
        [m[0].max(p[0]), m[1].max(p[1])]
    });
    let origin = [lo[0] - 8.0 * k, lo[1] - 8.0 * k];
    let width = ((hi[0] - origin[0]) + 8.0 * k).ceil().max(1.0) as usize;
    let height = ((hi[1] - origin[1]) + 8.0 * k).ceil().max(1.0) as usize;
    let mut rng = StdRng::seed_from_u64(s.seed);
    let paper = |x: f64| 232.0 - 30.0 * x / width as f64;
    let mut luma: Vec<u8> = (0..width * height)
        .map(|i| {
            (paper((i % width) as f64) + s.noise * (rng.random::<f64>() - 0.5) * 3.46)
                .clamp(0.0, 255.0) as u8
        })
        .collect();
    for line in &lines {
        let shifted: Vec<[f64; 2]> = line
            .iter()
            .map(|p| [p[0] - origin[0], p[1] - origin[1]])
            .collect();
        ink_stroke(&mut luma, width, height, &shifted, k, &paper);
    }
    for c in &mut centres {
        *c = [c[0] - origin[0], c[1] - origin[1]];
    }
    SyntheticScan {
        width,
        height,
        luma,
        centres,
    }
}

/// The stroke along `line` (pixels) inked over `luma` (`width` × `height`), `k` pixels per mm, on `paper`.
fn ink_stroke(
    luma: &mut [u8],
    width: usize,
    height: usize,
    line: &[[f64; 2]],
    k: f64,
    paper: &dyn Fn(f64) -> f64,
) {
    let (hw, blur) = (0.5 * STROKE * k, BLUR * k);
    let reach = hw + 4.0 * blur + 2.0;
    let lo = line
        .iter()
        .fold([f64::INFINITY; 2], |m, p| [m[0].min(p[0]), m[1].min(p[1])]);
    let hi = line.iter().fold([f64::NEG_INFINITY; 2], |m, p| {
        [m[0].max(p[0]), m[1].max(p[1])]
    });
    let (x0, y0) = (
        (lo[0] - reach).max(0.0) as usize,
        (lo[1] - reach).max(0.0) as usize,
    );
    let (x1, y1) = (
        (hi[0] + reach).max(0.0) as usize,
        (hi[1] + reach).max(0.0) as usize,
    );
    for y in y0..y1.min(height) {
        for x in x0..x1.min(width) {
            let d = distance([x as f64 + 0.5, y as f64 + 0.5], line);
            // The blurred stroke: a smooth step from full ink within the stroke to none beyond it.
            let cover = 0.5 * (1.0 - ((d - hw) / (blur.max(0.3) * 1.7)).tanh());
            let v = paper(x as f64) - (paper(x as f64) - 40.0) * cover;
            let cell = &mut luma[y * width + x];
            *cell = (*cell).min(v.clamp(0.0, 255.0) as u8);
        }
    }
}
