//! An independent model of a printed, scanned calibration pattern: each cross printed by the arm as built (its
//! nozzle positions from `Arm::nozzle`, this test crate's own forward kinematics, at the motor angles the
//! configured machine commands along each stroke), with an extrusion width that varies stroke to stroke, the
//! scanner's blur (a Gaussian: the stroke's profile is the difference of two error functions), an uneven lighting,
//! grey-level noise, dust, strings, and the scanner's own rotation, mirror (face down) and scale error.

use calibrate::scara::Pattern;
use kinematics::Kinematics;
use kinematics::scara::Scara;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::scara_pattern::Arm;

/// How the print is scanned.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scanner {
    /// The scanner's stated resolution.
    pub dpi: f64,
    /// Its real scale over the stated one, minus one (e.g. 0.002).
    pub scale_error: f64,
    pub rotation_deg: f64,
    pub mirrored: bool,
    /// Extrusion width (mm) and its stroke-to-stroke spread (fraction).
    pub width_mm: f64,
    pub width_spread: f64,
    /// Blur (1σ, pixels).
    pub blur_px: f64,
    /// Grey-level noise (1σ).
    pub noise: f64,
    /// Lighting: grey levels lost across the image.
    pub gradient: f64,
    /// Specks of dust and strings.
    pub dust: usize,
    pub strings: usize,
    /// Filament colour on white, `None` for a greyscale scan.
    pub colour: Option<[u8; 3]>,
}

impl Scanner {
    pub(crate) fn at(dpi: f64) -> Self {
        Self {
            dpi,
            scale_error: 0.0,
            rotation_deg: 0.0,
            mirrored: false,
            width_mm: 0.45,
            width_spread: 0.1,
            blur_px: 0.8 * dpi / 600.0,
            noise: 4.0,
            gradient: 40.0,
            dust: 0,
            strings: 0,
            colour: None,
        }
    }

    /// Pixels per mm the scanner really has.
    pub(crate) fn true_px_per_mm(&self) -> f64 {
        self.dpi / 25.4 * (1.0 + self.scale_error)
    }
}

/// A rendered scan: its pixels (grey, or RGB when coloured), the true cross centres on it (pixels) and the true
/// printed strokes (printer mm).
pub(crate) struct Rendered {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
    pub rgb: bool,
    pub centres: Vec<[f64; 2]>,
    /// Per pose: the vertical stroke's ends as printed (printer mm).
    pub vertical: Vec<[[f64; 2]; 2]>,
    /// Per pose: its centre as printed (printer mm).
    pub printed: Vec<[f64; 2]>,
}

impl Rendered {
    pub(crate) fn image(&self) -> calibrate::scara::scan_image::ScanImage {
        if self.rgb {
            calibrate::scara::scan_image::ScanImage::from_rgb8(
                self.width,
                self.height,
                &self.pixels,
            )
        } else {
            calibrate::scara::scan_image::ScanImage::from_luma8(
                self.width,
                self.height,
                self.pixels.clone(),
            )
        }
        .expect("a valid image")
    }
}

/// Abramowitz–Stegun 7.1.26 (error below 1.5e-7).
fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    if x >= 0.0 { y } else { -y }
}

/// Ink coverage at distance `d` from a stroke's middle, half-width `hw`, blurred by `sigma` (pixels).
fn coverage(d: f64, hw: f64, sigma: f64) -> f64 {
    let s = std::f64::consts::SQRT_2 * sigma.max(1e-3);
    0.5 * (erf((hw - d) / s) + erf((hw + d) / s))
}

fn distance_to_polyline(p: [f64; 2], line: &[[f64; 2]]) -> f64 {
    if line.len() == 1 {
        return (p[0] - line[0][0]).hypot(p[1] - line[0][1]);
    }
    line.windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l2 = dx * dx + dy * dy;
            let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0);
            (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Fast noise: a sum of uniforms scaled to 1σ.
fn noise(rng: &mut StdRng, sigma: f64) -> f64 {
    let u: f64 = rng.random::<f64>() + rng.random::<f64>() + rng.random::<f64>() - 1.5;
    u * 2.0 * sigma
}

/// A mark to draw: its middle line (pixels), half-width (pixels), darkness (0..1).
struct Ink {
    line: Vec<[f64; 2]>,
    half_width: f64,
    darkness: f64,
}

/// The true path of the commanded straight stroke from `a` to `b` (printer mm): the believed machine's motor angles
/// along it, the arm as built's nozzle there.
fn printed_stroke(kin: &Scara, truth: &Arm, a: [f64; 2], b: [f64; 2]) -> Vec<[f64; 2]> {
    (0..=16)
        .map(|i| {
            let f = i as f64 / 16.0;
            let p = [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, 0.3];
            let mut m = [0.0; 3];
            kin.inverse(p, &mut m)
                .expect("the pattern's strokes are reachable");
            truth.nozzle(m[0], m[1])
        })
        .collect()
}

/// Renders the pattern as the arm `truth` prints it on the machine `kin` (the believed one), scanned by `s`;
/// `skip` poses are not printed, `smear` poses are printed smeared into a blob.
pub(crate) fn render(
    kin: &Scara,
    truth: &Arm,
    pattern: &Pattern,
    s: &Scanner,
    seed: u64,
    skip: &[usize],
    smear: &[usize],
) -> Rendered {
    let mut rng = StdRng::seed_from_u64(seed);
    let k = s.true_px_per_mm();
    let (sin, cos) = s.rotation_deg.to_radians().sin_cos();
    let turn = |p: [f64; 2]| {
        let y = if s.mirrored { -p[1] } else { p[1] };
        [k * (cos * p[0] - sin * y), k * (sin * p[0] + cos * y)]
    };
    let half = 3.0;
    let mut strokes = Vec::new();
    let mut vertical = Vec::new();
    let mut printed = Vec::new();
    for (i, (c, &(a, b))) in pattern.centres.iter().zip(&pattern.poses).enumerate() {
        let h = printed_stroke(kin, truth, [c[0] - half, c[1]], [c[0] + half, c[1]]);
        let v = printed_stroke(kin, truth, [c[0], c[1] - half], [c[0], c[1] + half]);
        vertical.push([v[0], v[16]]);
        printed.push(truth.nozzle(a, b));
        let smeared = smear.contains(&i);
        for line in [h, v] {
            let spread = 1.0 + s.width_spread * (2.0 * rng.random::<f64>() - 1.0);
            let hw = 0.5 * s.width_mm * spread * if smeared { 5.0 } else { 1.0 };
            strokes.push((line, hw, smeared, !skip.contains(&i)));
        }
    }
    let all: Vec<[f64; 2]> = strokes
        .iter()
        .flat_map(|(l, ..)| l.iter().map(|p| turn(*p)))
        .collect();
    let margin = 8.0 * k;
    let min = [
        all.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min) - margin,
        all.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min) - margin,
    ];
    let max = [
        all.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max) + margin,
        all.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max) + margin,
    ];
    let (width, height) = (
        (max[0] - min[0]).ceil() as usize,
        (max[1] - min[1]).ceil() as usize,
    );
    let to_px = |p: [f64; 2]| {
        let q = turn(p);
        [q[0] - min[0], q[1] - min[1]]
    };
    let mut inks: Vec<Ink> = strokes
        .iter()
        .filter(|stroke| stroke.3)
        .map(|(line, hw, smeared, _)| Ink {
            line: line.iter().map(|p| to_px(*p)).collect(),
            half_width: hw * k,
            darkness: if *smeared { 0.6 } else { 1.0 },
        })
        .collect();
    add_dust(&mut inks, &mut rng, s, width, height, k);
    let centres = printed.iter().map(|p| to_px(*p)).collect();
    let pixels = paint(&inks, s, width, height, &mut rng);
    Rendered {
        width,
        height,
        rgb: s.colour.is_some(),
        pixels,
        centres,
        vertical,
        printed,
    }
}

/// Specks (0.03–0.25 mm) and strings (thin, faint, wandering) scattered over the scan.
fn add_dust(
    inks: &mut Vec<Ink>,
    rng: &mut StdRng,
    s: &Scanner,
    width: usize,
    height: usize,
    k: f64,
) {
    for _ in 0..s.dust {
        inks.push(Ink {
            line: vec![[
                rng.random::<f64>() * width as f64,
                rng.random::<f64>() * height as f64,
            ]],
            half_width: rng.random_range(0.03..0.25) * k,
            darkness: rng.random_range(0.3..1.0),
        });
    }
    for _ in 0..s.strings {
        let mut p = [
            rng.random::<f64>() * width as f64,
            rng.random::<f64>() * height as f64,
        ];
        let mut heading: f64 = rng.random::<f64>() * std::f64::consts::TAU;
        let mut line = vec![p];
        for _ in 0..40 {
            heading += rng.random_range(-0.2..0.2);
            p = [p[0] + k * heading.cos(), p[1] + k * heading.sin()];
            line.push(p);
        }
        inks.push(Ink {
            line,
            half_width: 0.03 * k,
            darkness: 0.5,
        });
    }
}

/// The scan's pixels: paper with its lighting and noise, each mark's ink over it.
fn paint(inks: &[Ink], s: &Scanner, width: usize, height: usize, rng: &mut StdRng) -> Vec<u8> {
    let paper = |x: f64, y: f64| {
        235.0 - s.gradient * x / width as f64 + 0.3 * s.gradient * y / height as f64
    };
    let ink_level = 35.0;
    let mut grey = vec![0f32; width * height];
    for y in 0..height {
        for x in 0..width {
            grey[y * width + x] = (paper(x as f64, y as f64) + noise(rng, s.noise)) as f32;
        }
    }
    for ink in inks {
        let reach = ink.half_width + 4.0 * s.blur_px + 2.0;
        let x0 = ink.line.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min) - reach;
        let x1 = ink
            .line
            .iter()
            .map(|p| p[0])
            .fold(f64::NEG_INFINITY, f64::max)
            + reach;
        let y0 = ink.line.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min) - reach;
        let y1 = ink
            .line
            .iter()
            .map(|p| p[1])
            .fold(f64::NEG_INFINITY, f64::max)
            + reach;
        for y in (y0.max(0.0) as usize)..(y1.max(0.0) as usize).min(height) {
            for x in (x0.max(0.0) as usize)..(x1.max(0.0) as usize).min(width) {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let c = ink.darkness
                    * coverage(
                        distance_to_polyline([px, py], &ink.line),
                        ink.half_width,
                        s.blur_px,
                    );
                if c < 1e-4 {
                    continue;
                }
                let bg = paper(px, py);
                let v = (bg - (bg - ink_level) * c + noise(rng, s.noise)) as f32;
                let cell = &mut grey[y * width + x];
                *cell = cell.min(v);
            }
        }
    }
    match s.colour {
        None => grey
            .iter()
            .map(|v| v.round().clamp(0.0, 255.0) as u8)
            .collect(),
        Some(colour) => {
            // Ink of `colour` over white: each channel darkens by the ink's coverage towards the colour.
            let mut out = Vec::with_capacity(3 * grey.len());
            for (i, v) in grey.iter().enumerate() {
                let (x, y) = ((i % width) as f64 + 0.5, (i / width) as f64 + 0.5);
                let bg = paper(x, y);
                let c = ((bg - f64::from(*v)) / (bg - ink_level)).clamp(-0.2, 1.0);
                for ch in colour {
                    let target = f64::from(ch) * bg / 255.0;
                    out.push((bg - (bg - target) * c).round().clamp(0.0, 255.0) as u8);
                }
            }
            out
        }
    }
}

/// Encodes grey or RGB pixels as PNG or JPEG bytes.
pub(crate) fn encode(r: &Rendered, jpeg_quality: Option<u8>) -> Vec<u8> {
    use image::ImageEncoder;
    let colour = if r.rgb {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::L8
    };
    let mut out = Vec::new();
    match jpeg_quality {
        Some(q) => image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, q)
            .write_image(&r.pixels, r.width as u32, r.height as u32, colour)
            .expect("encodes"),
        None => image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&r.pixels, r.width as u32, r.height as u32, colour)
            .expect("encodes"),
    }
    out
}
