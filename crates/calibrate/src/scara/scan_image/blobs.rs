//! The marks on a scan, found coarsely: the ink above the background averaged over blocks of `factor` pixels,
//! thresholded between the noise and the strokes' own level, opened (a 3 × 3 erosion then dilation removes strings
//! and specks thinner than a block or two), and split into 8-connected marks. Each mark with the shape of a cross
//! (two strokes at right angles through one point, each longer than wide) gives a rough cross: its centre, its
//! strokes' directions and extents; any other mark is set aside with the reason.

use super::signal::{Background, ScanImage};

/// A mark on the scan (full-resolution pixel coordinates).
#[derive(Debug, Clone)]
pub struct Mark {
    /// Points of the mark (block centres).
    pub points: Vec<[f64; 2]>,
}

/// A mark that looks like a cross.
#[derive(Debug, Clone, Copy)]
pub struct RoughCross {
    pub centre: [f64; 2],
    /// Unit directions of the two strokes.
    pub directions: [[f64; 2]; 2],
    /// How far each stroke reaches from the centre (the shorter side, pixels).
    pub half_length: [f64; 2],
    /// Stroke width (pixels).
    pub width: f64,
}

/// The coarse ink map and what it takes to be ink.
#[derive(Debug)]
pub struct CoarseMap {
    pub factor: usize,
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
    /// The level above which a block is ink.
    pub threshold: f64,
}

/// The coarse ink map of the image, or `None` when nothing stands out of the noise.
pub fn coarse_map(image: &ScanImage, bg: &Background, factor: usize) -> Option<CoarseMap> {
    let f = factor.max(1);
    let (w, h) = (image.width.div_ceil(f), image.height.div_ceil(f));
    let mut values = vec![0f32; w * h];
    let ink = image.ink();
    for by in 0..h {
        for bx in 0..w {
            let (mut sum, mut n) = (0u32, 0u32);
            for y in by * f..((by + 1) * f).min(image.height) {
                let row = &ink[y * image.width..(y + 1) * image.width];
                for v in &row[bx * f..((bx + 1) * f).min(image.width)] {
                    sum += u32::from(*v);
                    n += 1;
                }
            }
            let centre = ((bx as f64 + 0.5) * f as f64, (by as f64 + 0.5) * f as f64);
            values[by * w + bx] =
                (f64::from(sum) / f64::from(n.max(1)) - bg.at(centre.0, centre.1)) as f32;
        }
    }
    let mut sample: Vec<f32> = values.iter().step_by(3).copied().collect();
    let median = quantile(&mut sample, 0.5);
    let mut deviations: Vec<f32> = sample.iter().map(|v| (v - median).abs()).collect();
    let noise = (1.4826 * f64::from(quantile(&mut deviations, 0.5))).max(0.5);
    let mut strong: Vec<f32> = values
        .iter()
        .copied()
        .filter(|v| f64::from(*v) > 8.0 * noise)
        .collect();
    if strong.len() < 16 {
        return None;
    }
    let peak = f64::from(quantile(&mut strong, 0.9));
    Some(CoarseMap {
        factor: f,
        width: w,
        height: h,
        values,
        threshold: (5.0 * noise).max(0.4 * peak),
    })
}

fn quantile(v: &mut [f32], q: f64) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    let (_, m, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    *m
}

/// The ink mask opened by a 3 × 3 square.
fn opened_mask(map: &CoarseMap) -> Vec<bool> {
    let (w, h) = (map.width, map.height);
    let mask: Vec<bool> = map
        .values
        .iter()
        .map(|v| f64::from(*v) > map.threshold)
        .collect();
    let morph = |src: &[bool], all: bool| -> Vec<bool> {
        let mut out = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut hit = all;
                'n: for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        if src[yy * w + xx] != all {
                            hit = !all;
                            break 'n;
                        }
                    }
                }
                out[y * w + x] = hit;
            }
        }
        out
    };
    morph(&morph(&mask, true), false)
}

/// The 8-connected marks of at least `min_points` blocks, at most `max_marks` of them (`None` beyond: the image is
/// mostly ink or noise).
pub fn marks(map: &CoarseMap, min_points: usize, max_marks: usize) -> Option<Vec<Mark>> {
    let (w, h) = (map.width, map.height);
    let mask = opened_mask(map);
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    let f = map.factor as f64;
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut points = Vec::new();
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            points.push([(x as f64 + 0.5) * f, (y as f64 + 0.5) * f]);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    let j = yy * w + xx;
                    if mask[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if points.len() >= min_points {
            out.push(Mark { points });
            if out.len() > max_marks {
                return None;
            }
        }
    }
    Some(out)
}

/// Total-least-squares line through `points`: (mean, unit direction).
pub fn line_fit(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let n = points.len().max(1) as f64;
    let mx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    ([mx, my], [angle.cos(), angle.sin()])
}

/// Where two lines (point, direction) meet, if they are not parallel.
pub fn intersection(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2])) -> Option<[f64; 2]> {
    let (p, u) = a;
    let (q, v) = b;
    let det = u[0] * v[1] - u[1] * v[0];
    if det.abs() < 0.2 {
        return None;
    }
    let t = ((q[0] - p[0]) * v[1] - (q[1] - p[1]) * v[0]) / det;
    Some([p[0] + t * u[0], p[1] + t * u[1]])
}

/// The mark as a rough cross, or why it is not one.
pub fn rough_cross(mark: &Mark, factor: usize) -> Result<RoughCross, String> {
    let pts = &mark.points;
    let n = pts.len() as f64;
    let c = [
        pts.iter().map(|p| p[0]).sum::<f64>() / n,
        pts.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    // Orientation modulo 90°: the arms' angle, four times over, weighted by the squared distance.
    let (mut s4, mut c4) = (0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        let r2 = dx * dx + dy * dy;
        let phi = dy.atan2(dx);
        s4 += r2 * (4.0 * phi).sin();
        c4 += r2 * (4.0 * phi).cos();
    }
    let alpha = s4.atan2(c4) / 4.0;
    let dirs = [[alpha.cos(), alpha.sin()], [-alpha.sin(), alpha.cos()]];
    let mut first = Vec::new();
    let mut second = Vec::new();
    for p in pts {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        let across0 = (dx * dirs[0][1] - dy * dirs[0][0]).abs();
        let across1 = (dx * dirs[1][1] - dy * dirs[1][0]).abs();
        if across0 < across1 {
            first.push(*p)
        } else {
            second.push(*p)
        }
    }
    if (first.len().min(second.len()) as f64) < 0.2 * n {
        return Err("one stroke, not two".into());
    }
    let lines = [line_fit(&first), line_fit(&second)];
    let centre = intersection(lines[0], lines[1]).ok_or("its strokes are not at right angles")?;
    let cos = (lines[0].1[0] * lines[1].1[0] + lines[0].1[1] * lines[1].1[1]).abs();
    if cos > 0.26 {
        return Err("its strokes are not at right angles".into());
    }
    let mut half_length = [0.0; 2];
    for (k, (group, line)) in [&first, &second].iter().zip(&lines).enumerate() {
        let u = line.1;
        let mut along: Vec<f64> = group
            .iter()
            .map(|p| (p[0] - centre[0]) * u[0] + (p[1] - centre[1]) * u[1])
            .collect();
        along.sort_by(f64::total_cmp);
        let lo = -along[(along.len() as f64 * 0.02) as usize];
        let hi = along[((along.len() - 1) as f64 * 0.98) as usize];
        if lo.min(hi) < 0.3 * lo.max(hi) {
            return Err("its strokes do not cross near their middles".into());
        }
        half_length[k] = lo.min(hi);
    }
    let area = n * (factor * factor) as f64;
    let width = area / (2.0 * (half_length[0] + half_length[1])).max(1.0);
    if half_length[0].min(half_length[1]) < 2.5 * width {
        return Err("a blob, not two strokes".into());
    }
    if half_length[0].max(half_length[1]) > 2.0 * half_length[0].min(half_length[1]) {
        return Err("its strokes differ in length".into());
    }
    Ok(RoughCross {
        centre,
        directions: [lines[0].1, lines[1].1],
        half_length,
        width,
    })
}
