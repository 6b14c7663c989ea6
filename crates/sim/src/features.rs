//! Dimensional checks on recognisable features: closed loops of the intended path that are circles (from
//! the G-code geometry) are measured on the actual path: diameter and roundness from a geometric circle
//! fit, and the axes of the best-fitting ellipse (an oval from a wrong coupling shows up here). Loops with
//! four corners (squares, rectangles) get side lengths and corner angles from lines fitted to the middle
//! part of each side (corner rounding left out), intended and actual alike.

use crate::metrics::{PathPoint, segment_distance};
use calibrate::circle::{self, Point};
use nalgebra::{Matrix2, SymmetricEigen};
use serde::Serialize;

/// A loop closes when the intended path returns this close to its start (mm), after going `MIN_EXCURSION`.
const CLOSE_TOLERANCE: f64 = 0.3;
const MIN_EXCURSION: f64 = 3.0;
/// A loop is a circle when its intended points are within this share of the radius (or 0.06 mm) of a circle.
const CIRCLE_TOLERANCE: f64 = 0.01;
const MIN_POINTS: usize = 12;

/// An ellipse: centre, semi-axes and the major axis direction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ellipse {
    pub centre: Point,
    pub semi_major: f64,
    pub semi_minor: f64,
    /// Direction of the major axis from +X (degrees, 0..180).
    pub angle_deg: f64,
}

/// One circular loop of the print, intended vs actual (mm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CircleFeature {
    pub layer: usize,
    pub z: f64,
    pub intended_centre: Point,
    pub intended_diameter: f64,
    pub actual_centre: Point,
    pub actual_diameter: f64,
    /// Max − min distance of the actual points from the actual fitted centre.
    pub roundness: f64,
    /// Best-fitting ellipse of the actual points (major/minor axes = 2 × semi-axes).
    pub ellipse: Option<Ellipse>,
    pub points: usize,
}

impl CircleFeature {
    pub fn diameter_error(&self) -> f64 {
        self.actual_diameter - self.intended_diameter
    }

    pub fn centre_shift(&self) -> f64 {
        (self.actual_centre[0] - self.intended_centre[0])
            .hypot(self.actual_centre[1] - self.intended_centre[1])
    }
}

/// Every circular closed loop in the deposited part of `path`.
pub fn find_circles(path: &[PathPoint]) -> Vec<CircleFeature> {
    closed_loops(path)
        .into_iter()
        .filter_map(|range| measure_circle(&path[range]))
        .collect()
}

/// A four-cornered loop (square or rectangle), intended vs actual: sides in loop order (mm), interior
/// angles at the corners between consecutive sides (degrees).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuadFeature {
    pub layer: usize,
    pub z: f64,
    pub intended_corners: [Point; 4],
    pub intended_sides: [f64; 4],
    pub actual_sides: [f64; 4],
    pub intended_angles_deg: [f64; 4],
    pub actual_angles_deg: [f64; 4],
}

impl QuadFeature {
    /// Largest |actual − intended| side length (mm).
    pub fn worst_side_error(&self) -> f64 {
        (0..4)
            .map(|k| (self.actual_sides[k] - self.intended_sides[k]).abs())
            .fold(0.0, f64::max)
    }

    /// Largest |actual − intended| corner angle (degrees).
    pub fn worst_angle_error(&self) -> f64 {
        (0..4)
            .map(|k| (self.actual_angles_deg[k] - self.intended_angles_deg[k]).abs())
            .fold(0.0, f64::max)
    }
}

/// Every closed loop with exactly four corners in the deposited part of `path`.
pub fn find_quads(path: &[PathPoint]) -> Vec<QuadFeature> {
    closed_loops(path)
        .into_iter()
        .filter_map(|range| measure_quad(&path[range]))
        .collect()
}

/// Corners of the intended loop: Douglas–Peucker vertices with this tolerance (mm).
const CORNER_TOLERANCE: f64 = 0.05;
/// Share of each side left out at both ends when fitting its line.
const SIDE_MARGIN: f64 = 0.15;
const MIN_SIDE: f64 = 2.0;

fn measure_quad(points: &[PathPoint]) -> Option<QuadFeature> {
    let intended: Vec<Point> = points
        .iter()
        .map(|p| [p.intended[0], p.intended[1]])
        .collect();
    let mut keep = vec![false; intended.len()];
    keep[0] = true;
    keep[intended.len() - 1] = true;
    douglas_peucker(&intended, 0, intended.len() - 1, &mut keep);
    let mut corners: Vec<usize> = (0..intended.len()).filter(|&i| keep[i]).collect();
    // The loop starts and ends at the same point: drop the duplicate end.
    corners.pop();
    // The start is a corner only if the path turns there.
    if corners.len() == 5 && !turns(&intended, corners[4], 0, corners[1]) {
        corners.remove(0);
    }
    if corners.len() != 4 {
        return None;
    }
    let n = intended.len() - 1;
    let mut intended_lines = Vec::with_capacity(4);
    let mut actual_lines = Vec::with_capacity(4);
    for k in 0..4 {
        let (a, b) = (
            corners[k],
            if k == 3 {
                corners[0] + n
            } else {
                corners[k + 1]
            },
        );
        let len = b - a;
        let side = distance2(intended[a % n], intended[b % n]);
        if side < MIN_SIDE || len < 4 {
            return None;
        }
        let margin = (len as f64 * SIDE_MARGIN).ceil() as usize;
        let idx: Vec<usize> = (a + margin..=b - margin).map(|i| i % n).collect();
        let pick = |f: &dyn Fn(&PathPoint) -> [f64; 3]| -> Vec<Point> {
            idx.iter()
                .map(|&i| f(&points[i]))
                .map(|p| [p[0], p[1]])
                .collect()
        };
        intended_lines.push(fit_line(&pick(&|p| p.intended))?);
        actual_lines.push(fit_line(&pick(&|p| p.actual))?);
    }
    let (ic, ia) = quad_geometry(&intended_lines)?;
    let (ac, aa) = quad_geometry(&actual_lines)?;
    let sides = |c: &[Point; 4]| std::array::from_fn(|k| distance2(c[k], c[(k + 1) % 4]));
    Some(QuadFeature {
        layer: points[0].layer,
        z: points[0].intended[2],
        intended_corners: ic,
        intended_sides: sides(&ic),
        actual_sides: sides(&ac),
        intended_angles_deg: ia,
        actual_angles_deg: aa,
    })
}

fn distance2(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Whether the path turns at `i` (from the point `before` to the point `after`) by more than 10°.
fn turns(p: &[Point], before: usize, i: usize, after: usize) -> bool {
    let u = [p[i][0] - p[before][0], p[i][1] - p[before][1]];
    let v = [p[after][0] - p[i][0], p[after][1] - p[i][1]];
    let cross = u[0] * v[1] - u[1] * v[0];
    let dot = u[0] * v[0] + u[1] * v[1];
    cross.atan2(dot).abs() > 10f64.to_radians()
}

fn douglas_peucker(p: &[Point], a: usize, b: usize, keep: &mut [bool]) {
    if b <= a + 1 {
        return;
    }
    let (mut worst, mut at) = (0.0, a);
    for i in a + 1..b {
        let d = segment_distance(p[i], p[a], p[b]);
        if d > worst {
            (worst, at) = (d, i);
        }
    }
    if worst > CORNER_TOLERANCE {
        keep[at] = true;
        douglas_peucker(p, a, at, keep);
        douglas_peucker(p, at, b, keep);
    }
}

/// A fitted line: a point on it and its unit direction (total least squares).
#[derive(Debug, Clone, Copy)]
struct Line {
    point: Point,
    dir: Point,
}

fn fit_line(points: &[Point]) -> Option<Line> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold([0.0, 0.0], |m, p| [m[0] + p[0] / n, m[1] + p[1] / n]);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = (p[0] - mean[0], p[1] - mean[1]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    // Orient along the travel direction.
    let (first, last) = (points[0], points[points.len() - 1]);
    let mut dir = [angle.cos(), angle.sin()];
    if dir[0] * (last[0] - first[0]) + dir[1] * (last[1] - first[1]) < 0.0 {
        dir = [-dir[0], -dir[1]];
    }
    (sxx + syy > 0.0).then_some(Line { point: mean, dir })
}

/// Corners (intersections of consecutive lines; corner k ends side k−1 and starts side k) and interior
/// angles in degrees.
fn quad_geometry(lines: &[Line]) -> Option<([Point; 4], [f64; 4])> {
    let mut corners = [[0.0; 2]; 4];
    let mut angles = [0.0; 4];
    for k in 0..4 {
        let (l0, l1) = (lines[(k + 3) % 4], lines[k]);
        let cross = l0.dir[0] * l1.dir[1] - l0.dir[1] * l1.dir[0];
        if cross.abs() < 1e-9 {
            return None;
        }
        let d = [l1.point[0] - l0.point[0], l1.point[1] - l0.point[1]];
        let t = (d[0] * l1.dir[1] - d[1] * l1.dir[0]) / cross;
        corners[k] = [l0.point[0] + t * l0.dir[0], l0.point[1] + t * l0.dir[1]];
        let dot = l0.dir[0] * l1.dir[0] + l0.dir[1] * l1.dir[1];
        angles[k] = 180.0 - cross.atan2(dot).abs().to_degrees();
    }
    Some((corners, angles))
}

/// Index ranges of closed loops within runs of deposited points.
fn closed_loops(path: &[PathPoint]) -> Vec<std::ops::Range<usize>> {
    let mut loops = Vec::new();
    let mut start: Option<usize> = None;
    let mut far = false;
    for (i, p) in path.iter().enumerate() {
        if !p.deposited {
            start = None;
            continue;
        }
        let Some(s) = start else {
            start = Some(i);
            far = false;
            continue;
        };
        let d = distance(p.intended, path[s].intended);
        if d > MIN_EXCURSION {
            far = true;
        } else if far && d < CLOSE_TOLERANCE {
            loops.push(s..i + 1);
            start = Some(i);
            far = false;
        }
    }
    loops
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn measure_circle(points: &[PathPoint]) -> Option<CircleFeature> {
    if points.len() < MIN_POINTS {
        return None;
    }
    let intended: Vec<Point> = points
        .iter()
        .map(|p| [p.intended[0], p.intended[1]])
        .collect();
    let fit = circle::geometric(&intended).ok()?;
    let worst = fit.residuals.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    if worst > (CIRCLE_TOLERANCE * fit.circle.r).max(0.06) {
        return None;
    }
    let actual: Vec<Point> = points.iter().map(|p| [p.actual[0], p.actual[1]]).collect();
    let actual_fit = circle::geometric(&actual).ok()?;
    let (lo, hi) = actual_fit
        .residuals
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(*r), hi.max(*r))
        });
    Some(CircleFeature {
        layer: points[0].layer,
        z: points[0].intended[2],
        intended_centre: [fit.circle.cx, fit.circle.cy],
        intended_diameter: 2.0 * fit.circle.r,
        actual_centre: [actual_fit.circle.cx, actual_fit.circle.cy],
        actual_diameter: 2.0 * actual_fit.circle.r,
        roundness: hi - lo,
        ellipse: fit_ellipse(&actual),
        points: points.len(),
    })
}

/// Least-squares conic `A·u² + B·uv + C·v² + D·u + E·v = 1` in coordinates centred on the mean and scaled
/// to unit spread; `None` when the points are not on an ellipse.
pub fn fit_ellipse(points: &[Point]) -> Option<Ellipse> {
    if points.len() < 5 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold([0.0, 0.0], |m, p| [m[0] + p[0] / n, m[1] + p[1] / n]);
    let spread = (points
        .iter()
        .map(|p| (p[0] - mean[0]).powi(2) + (p[1] - mean[1]).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    if spread.is_nan() || spread <= 0.0 {
        return None;
    }
    let mut ata = nalgebra::Matrix5::<f64>::zeros();
    let mut atb = nalgebra::Vector5::<f64>::zeros();
    for p in points {
        let (u, v) = ((p[0] - mean[0]) / spread, (p[1] - mean[1]) / spread);
        let row = nalgebra::Vector5::new(u * u, u * v, v * v, u, v);
        ata += row * row.transpose();
        atb += row;
    }
    let s = ata.lu().solve(&atb)?;
    let (a, b, c, d, e) = (s[0], s[1], s[2], s[3], s[4]);
    let m = Matrix2::new(a, 0.5 * b, 0.5 * b, c);
    let centre = m.lu().solve(&nalgebra::Vector2::new(-0.5 * d, -0.5 * e))?;
    let (u0, v0) = (centre[0], centre[1]);
    let k = 1.0 + a * u0 * u0 + b * u0 * v0 + c * v0 * v0;
    let eigen = SymmetricEigen::new(m);
    let (l_small, l_big, axis) = if eigen.eigenvalues[0] <= eigen.eigenvalues[1] {
        (
            eigen.eigenvalues[0],
            eigen.eigenvalues[1],
            eigen.eigenvectors.column(0).into_owned(),
        )
    } else {
        (
            eigen.eigenvalues[1],
            eigen.eigenvalues[0],
            eigen.eigenvectors.column(1).into_owned(),
        )
    };
    if !(l_small > 0.0 && k > 0.0) {
        return None;
    }
    let angle = axis[1].atan2(axis[0]).to_degrees().rem_euclid(180.0);
    Some(Ellipse {
        centre: [mean[0] + u0 * spread, mean[1] + v0 * spread],
        semi_major: (k / l_small).sqrt() * spread,
        semi_minor: (k / l_big).sqrt() * spread,
        angle_deg: angle,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ellipse_points(c: Point, a: f64, b: f64, rot: f64, n: usize) -> Vec<Point> {
        (0..n)
            .map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                let (x, y) = (a * t.cos(), b * t.sin());
                let (s, co) = rot.sin_cos();
                [c[0] + co * x - s * y, c[1] + s * x + co * y]
            })
            .collect()
    }

    #[test]
    fn ellipse_fit_recovers_axes_and_angle() {
        let pts = ellipse_points([30.0, -20.0], 12.0, 9.5, 0.6, 200);
        let e = fit_ellipse(&pts).expect("ellipse");
        assert!((e.semi_major - 12.0).abs() < 1e-9, "{e:?}");
        assert!((e.semi_minor - 9.5).abs() < 1e-9);
        assert!((e.angle_deg - 0.6f64.to_degrees()).abs() < 1e-6);
        assert!((e.centre[0] - 30.0).abs() < 1e-9 && (e.centre[1] + 20.0).abs() < 1e-9);
    }

    fn point(intended: Point, actual: Point) -> PathPoint {
        PathPoint {
            time: 0.0,
            intended: [intended[0], intended[1], 0.2],
            actual: [actual[0], actual[1], 0.2],
            deviation: 0.0,
            deposited: true,
            layer: 0,
        }
    }

    #[test]
    fn circle_printed_as_an_oval_is_measured() {
        let intended = ellipse_points([5.0, 5.0], 10.0, 10.0, 0.0, 100);
        let actual = ellipse_points([5.2, 5.0], 10.3, 9.8, 0.0, 100);
        let mut path: Vec<PathPoint> = intended
            .iter()
            .zip(&actual)
            .map(|(i, a)| point(*i, *a))
            .collect();
        path.push(path[0]);
        let found = find_circles(&path);
        assert_eq!(found.len(), 1);
        let f = &found[0];
        assert!((f.intended_diameter - 20.0).abs() < 1e-6);
        let e = f.ellipse.expect("ellipse");
        assert!(
            (2.0 * e.semi_major - 20.6).abs() < 1e-6 && (2.0 * e.semi_minor - 19.6).abs() < 1e-6
        );
        assert!(f.roundness > 0.45 && f.roundness < 0.55, "{}", f.roundness);
    }

    #[test]
    fn a_sheared_square_is_measured() {
        // Intended 20 mm square; actual sheared by 0.01 in x per mm of y: angles 90 ± 0.573°.
        let corners = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]];
        let mut path = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            for i in 0..100 {
                let t = i as f64 / 100.0;
                let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                path.push(point(p, [p[0] + 0.01 * p[1], p[1]]));
            }
        }
        path.push(path[0]);
        let quads = find_quads(&path);
        assert_eq!(quads.len(), 1);
        let q = &quads[0];
        for k in 0..4 {
            assert!((q.intended_sides[k] - 20.0).abs() < 1e-9, "{q:?}");
            assert!((q.intended_angles_deg[k] - 90.0).abs() < 1e-9);
        }
        let shear = 0.01f64.atan().to_degrees();
        let sides_x = 20.0;
        let sides_y = 20.0 * (1.0f64 + 0.01 * 0.01).sqrt();
        assert!(
            (q.actual_sides[0] - sides_x).abs() < 1e-9
                && (q.actual_sides[1] - sides_y).abs() < 1e-9
        );
        assert!(
            (q.actual_angles_deg[0] - (90.0 - shear)).abs() < 1e-9,
            "{q:?}"
        );
        assert!(
            (q.actual_angles_deg[1] - (90.0 + shear)).abs() < 1e-9,
            "{q:?}"
        );
        assert!((q.worst_angle_error() - shear).abs() < 1e-9);
    }

    #[test]
    fn a_square_is_not_a_circle() {
        let corners = [[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]];
        let mut path = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            for i in 0..10 {
                let t = i as f64 / 10.0;
                let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                path.push(point(p, p));
            }
        }
        path.push(path[0]);
        assert!(find_circles(&path).is_empty());
    }
}
