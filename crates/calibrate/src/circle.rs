//! Circle fits for magnet maps: Kåsa and Taubin (algebraic), geometric Levenberg–Marquardt, robust RANSAC,
//! the centre covariance, the equal-spacing centroid cross-check and the first-harmonic fit of R-only scans.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Matrix3, Owned, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// A point in the plane (mm).
pub type Point = [f64; 2];

/// A circle: centre and radius (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Circle {
    pub cx: f64,
    pub cy: f64,
    pub r: f64,
}

impl Circle {
    /// Signed geometric residual of `p`: distance to the centre minus the radius.
    pub fn residual(&self, p: Point) -> f64 {
        (p[0] - self.cx).hypot(p[1] - self.cy) - self.r
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CircleError {
    #[error("a circle needs at least {needed} points, got {got}")]
    TooFewPoints { needed: usize, got: usize },
    #[error("the points are collinear or coincident: no circle passes through them")]
    Degenerate,
    #[error("a point lies on the fitted centre: the geometric residual has no direction")]
    PointAtCentre,
    #[error("non-finite input coordinate at point {index}")]
    NonFinite { index: usize },
    #[error("the geometric fit did not converge: {0}")]
    NoConvergence(String),
    #[error("robust fit found only {inliers} consistent points, need at least {needed}")]
    TooFewInliers { inliers: usize, needed: usize },
}

/// A geometric fit with its quality figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CircleFit {
    pub circle: Circle,
    /// Signed residual `|p_i − c| − r` per input point (mm), in input order.
    pub residuals: Vec<f64>,
    /// Root-mean-square residual of the points used (mm).
    pub rms: f64,
    /// Covariance of (cx, cy, r): `σ²(JᵀJ)⁻¹` with `σ² = Σres²/(n−3)` (zero when n = 3).
    pub covariance: [[f64; 3]; 3],
    /// Indices of points left out as outliers (empty for a plain fit).
    pub outliers: Vec<usize>,
}

fn check_points(points: &[Point], needed: usize) -> Result<(), CircleError> {
    if points.len() < needed {
        return Err(CircleError::TooFewPoints {
            needed,
            got: points.len(),
        });
    }
    if let Some(index) = points
        .iter()
        .position(|p| !p[0].is_finite() || !p[1].is_finite())
    {
        return Err(CircleError::NonFinite { index });
    }
    Ok(())
}

fn mean(points: &[Point]) -> Point {
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p[0], b + p[1]));
    [sx / n, sy / n]
}

/// Spread of the points: the RMS distance from their mean, used to judge degeneracy relative to scale.
fn spread(points: &[Point], m: Point) -> f64 {
    let s: f64 = points
        .iter()
        .map(|p| (p[0] - m[0]).powi(2) + (p[1] - m[1]).powi(2))
        .sum();
    (s / points.len() as f64).sqrt()
}

/// Collinear (or coincident) points: the smaller principal axis of the scatter is negligible.
fn is_collinear(points: &[Point]) -> bool {
    let m = mean(points);
    let scale = spread(points, m);
    if scale == 0.0 {
        return true;
    }
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (u, v) = ((p[0] - m[0]) / scale, (p[1] - m[1]) / scale);
        sxx += u * u;
        syy += v * v;
        sxy += u * v;
    }
    let n = points.len() as f64;
    let (sxx, syy, sxy) = (sxx / n, syy / n, sxy / n);
    let half_trace = 0.5 * (sxx + syy);
    let disc = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    half_trace - disc < 1e-12
}

fn finite_circle(c: Circle) -> Result<Circle, CircleError> {
    if c.cx.is_finite() && c.cy.is_finite() && c.r.is_finite() && c.r > 0.0 {
        Ok(c)
    } else {
        Err(CircleError::Degenerate)
    }
}

/// Kåsa fit: linear least squares on `x²+y²+Dx+Ey+F = 0` (fast; biased towards small radii on short arcs).
pub fn kasa(points: &[Point]) -> Result<Circle, CircleError> {
    check_points(points, 3)?;
    if is_collinear(points) {
        return Err(CircleError::Degenerate);
    }
    // Centre the data for conditioning; solve the 3×3 normal equations.
    let m = mean(points);
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for p in points {
        let (u, v) = (p[0] - m[0], p[1] - m[1]);
        let row = Vector3::new(u, v, 1.0);
        ata += row * row.transpose();
        atb += row * (-(u * u + v * v));
    }
    let sol = ata.lu().solve(&atb).ok_or(CircleError::Degenerate)?;
    let (d, e, f) = (sol[0], sol[1], sol[2]);
    let r2 = 0.25 * (d * d + e * e) - f;
    if r2.is_nan() || r2 <= 0.0 {
        return Err(CircleError::Degenerate);
    }
    finite_circle(Circle {
        cx: m[0] - 0.5 * d,
        cy: m[1] - 0.5 * e,
        r: r2.sqrt(),
    })
}

/// Taubin fit (Newton on the characteristic polynomial of the Taubin-normalised algebraic fit); nearly unbiased,
/// the best algebraic start for the geometric fit.
pub fn taubin(points: &[Point]) -> Result<Circle, CircleError> {
    check_points(points, 3)?;
    if is_collinear(points) {
        return Err(CircleError::Degenerate);
    }
    let m = mean(points);
    let n = points.len() as f64;
    let (mut mxx, mut myy, mut mxy, mut mxz, mut myz, mut mzz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        let (x, y) = (p[0] - m[0], p[1] - m[1]);
        let z = x * x + y * y;
        mxx += x * x;
        myy += y * y;
        mxy += x * y;
        mxz += x * z;
        myz += y * z;
        mzz += z * z;
    }
    let (mxx, myy, mxy, mxz, myz, mzz) = (mxx / n, myy / n, mxy / n, mxz / n, myz / n, mzz / n);
    let mz = mxx + myy;
    let cov_xy = mxx * myy - mxy * mxy;
    let a3 = 4.0 * mz;
    let a2 = -3.0 * mz * mz - mzz;
    let a1 = mzz * mz + 4.0 * cov_xy * mz - mxz * mxz - myz * myz - mz * mz * mz;
    let a0 =
        mxz * mxz * myy + myz * myz * mxx - mzz * cov_xy - 2.0 * mxz * myz * mxy + mz * mz * cov_xy;
    // Newton from x = 0 towards the smallest root; stop when it no longer decreases |poly|.
    let (mut x, mut y) = (0.0f64, a0);
    for _ in 0..100 {
        let dy = a1 + x * (2.0 * a2 + 3.0 * a3 * x);
        if dy == 0.0 {
            break;
        }
        let x_new = x - y / dy;
        if x_new == x || !x_new.is_finite() {
            break;
        }
        let y_new = a0 + x_new * (a1 + x_new * (a2 + x_new * a3));
        if y_new.abs() >= y.abs() {
            break;
        }
        x = x_new;
        y = y_new;
    }
    let det = x * x - x * mz + cov_xy;
    if det == 0.0 {
        return Err(CircleError::Degenerate);
    }
    let xc = (mxz * (myy - x) - myz * mxy) / det / 2.0;
    let yc = (myz * (mxx - x) - mxz * mxy) / det / 2.0;
    finite_circle(Circle {
        cx: xc + m[0],
        cy: yc + m[1],
        r: (xc * xc + yc * yc + mz).sqrt(),
    })
}

/// The geometric problem `Σ(|p_i − c| − r)²` in the shape the LM solver wants.
struct GeometricProblem<'a> {
    points: &'a [Point],
    params: DVector<f64>,
}

impl GeometricProblem<'_> {
    fn distances(&self) -> Option<Vec<f64>> {
        let (cx, cy) = (self.params[0], self.params[1]);
        let d: Vec<f64> = self
            .points
            .iter()
            .map(|p| (p[0] - cx).hypot(p[1] - cy))
            .collect();
        d.iter().all(|&v| v > 0.0 && v.is_finite()).then_some(d)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for GeometricProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.params.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let r = self.params[2];
        let d = self.distances()?;
        Some(DVector::from_iterator(d.len(), d.iter().map(|v| v - r)))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        geometric_jacobian(self.points, self.params[0], self.params[1])
    }
}

/// Jacobian of the residuals `|p_i − c| − r` with respect to (cx, cy, r).
fn geometric_jacobian(points: &[Point], cx: f64, cy: f64) -> Option<DMatrix<f64>> {
    let mut j = DMatrix::zeros(points.len(), 3);
    for (i, p) in points.iter().enumerate() {
        let d = (p[0] - cx).hypot(p[1] - cy);
        if d <= 0.0 {
            return None;
        }
        j[(i, 0)] = -(p[0] - cx) / d;
        j[(i, 1)] = -(p[1] - cy) / d;
        j[(i, 2)] = -1.0;
    }
    Some(j)
}

/// Geometric fit: Levenberg–Marquardt on `Σ(|p_i − c| − r)²`, started from Taubin; with residuals and the
/// covariance `σ²(JᵀJ)⁻¹` of (cx, cy, r).
pub fn geometric(points: &[Point]) -> Result<CircleFit, CircleError> {
    let start = taubin(points)?;
    let problem = GeometricProblem {
        points,
        params: DVector::from_vec(vec![start.cx, start.cy, start.r]),
    };
    let (solved, report) = LevenbergMarquardt::new().minimize(problem);
    if !report.termination.was_successful() {
        return Err(CircleError::NoConvergence(format!(
            "{:?}",
            report.termination
        )));
    }
    let p = &solved.params;
    let circle = finite_circle(Circle {
        cx: p[0],
        cy: p[1],
        r: p[2],
    })?;
    fit_report(points, circle, Vec::new())
}

fn fit_report(
    points: &[Point],
    circle: Circle,
    outliers: Vec<usize>,
) -> Result<CircleFit, CircleError> {
    let residuals: Vec<f64> = points.iter().map(|&p| circle.residual(p)).collect();
    let used: Vec<Point> = points
        .iter()
        .enumerate()
        .filter(|(i, _)| !outliers.contains(i))
        .map(|(_, p)| *p)
        .collect();
    let used_res: Vec<f64> = used.iter().map(|&p| circle.residual(p)).collect();
    let ss: f64 = used_res.iter().map(|r| r * r).sum();
    let n = used.len();
    let rms = (ss / n as f64).sqrt();
    let sigma2 = if n > 3 { ss / (n - 3) as f64 } else { 0.0 };
    let j = geometric_jacobian(&used, circle.cx, circle.cy).ok_or(CircleError::PointAtCentre)?;
    let jtj = j.transpose() * &j;
    let inv = jtj.try_inverse().ok_or(CircleError::Degenerate)?;
    let mut covariance = [[0.0; 3]; 3];
    for (a, row) in covariance.iter_mut().enumerate() {
        for (b, v) in row.iter_mut().enumerate() {
            *v = sigma2 * inv[(a, b)];
        }
    }
    Ok(CircleFit {
        circle,
        residuals,
        rms,
        covariance,
        outliers,
    })
}

/// Circle through three points, if they are not collinear.
fn circle_through(a: Point, b: Point, c: Point) -> Option<Circle> {
    let d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]));
    let scale = (b[0] - a[0])
        .hypot(b[1] - a[1])
        .max((c[0] - a[0]).hypot(c[1] - a[1]));
    if d.abs() <= 1e-12 * scale * scale {
        return None;
    }
    let (a2, b2, c2) = (
        a[0] * a[0] + a[1] * a[1],
        b[0] * b[0] + b[1] * b[1],
        c[0] * c[0] + c[1] * c[1],
    );
    let cx = (a2 * (b[1] - c[1]) + b2 * (c[1] - a[1]) + c2 * (a[1] - b[1])) / d;
    let cy = (a2 * (c[0] - b[0]) + b2 * (a[0] - c[0]) + c2 * (b[0] - a[0])) / d;
    let r = (a[0] - cx).hypot(a[1] - cy);
    finite_circle(Circle { cx, cy, r }).ok()
}

/// Triples tried by RANSAC: all of them for small sets (deterministic, exhaustive), else a fixed
/// pseudo-random selection (a simple LCG keeps results reproducible without a random source).
fn ransac_triples(n: usize) -> Vec<[usize; 3]> {
    const EXHAUSTIVE_LIMIT: usize = 40;
    const SAMPLED: usize = 4000;
    if n <= EXHAUSTIVE_LIMIT {
        let mut out = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                for k in j + 1..n {
                    out.push([i, j, k]);
                }
            }
        }
        return out;
    }
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 33) as usize) % n
    };
    (0..SAMPLED)
        .map(|_| [next(), next(), next()])
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

/// Robust geometric fit: RANSAC on circles through point triples (exhaustive for ≤ 40 points) keeps the
/// largest set within `inlier_tolerance` mm, then the geometric fit runs on that set and the inlier set is
/// recomputed once from the refined circle. Outlier indices are reported; a missed or spurious magnet
/// therefore does not pull the centre.
pub fn robust(points: &[Point], inlier_tolerance: f64) -> Result<CircleFit, CircleError> {
    check_points(points, 3)?;
    if is_collinear(points) {
        return Err(CircleError::Degenerate);
    }
    let inliers_of = |c: &Circle| -> Vec<usize> {
        (0..points.len())
            .filter(|&i| c.residual(points[i]).abs() <= inlier_tolerance)
            .collect()
    };
    let mut best: Vec<usize> = Vec::new();
    for t in ransac_triples(points.len()) {
        if let Some(c) = circle_through(points[t[0]], points[t[1]], points[t[2]]) {
            let inl = inliers_of(&c);
            if inl.len() > best.len() {
                best = inl;
            }
        }
    }
    let needed = 3.max(points.len().div_ceil(2));
    if best.len() < needed {
        return Err(CircleError::TooFewInliers {
            inliers: best.len(),
            needed,
        });
    }
    let mut inliers = best;
    for _ in 0..2 {
        let subset: Vec<Point> = inliers.iter().map(|&i| points[i]).collect();
        let fit = geometric(&subset)?;
        let refreshed = inliers_of(&fit.circle);
        if refreshed.len() < needed || refreshed == inliers {
            break;
        }
        inliers = refreshed;
    }
    let subset: Vec<Point> = inliers.iter().map(|&i| points[i]).collect();
    let fit = geometric(&subset)?;
    let outliers = (0..points.len()).filter(|i| !inliers.contains(i)).collect();
    fit_report(points, fit.circle, outliers)
}

/// Equal-spacing cross-check: for N magnets equally spaced on a circle the first harmonic cancels, so the
/// centroid of the points is the centre. Returns the centroid.
pub fn centroid(points: &[Point]) -> Result<Point, CircleError> {
    check_points(points, 3)?;
    Ok(mean(points))
}

/// `s(θ) = a + b·cosθ + c·sinθ`: the first-harmonic model of an R-only scan (a = mean radius, (b, c) = the
/// eccentricity vector of the ring about the rotation axis).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Harmonic {
    pub a: f64,
    pub b: f64,
    pub c: f64,
}

impl Harmonic {
    pub fn eval(&self, theta: f64) -> f64 {
        self.a + self.b * theta.cos() + self.c * theta.sin()
    }
}

/// True when `thetas` are `θ0 + k·2π/n` (in order) within `1e-9` rad.
fn equally_spaced(thetas: &[f64]) -> bool {
    let n = thetas.len() as f64;
    thetas.iter().enumerate().all(|(k, t)| {
        let expected = thetas[0] + k as f64 * TAU / n;
        let diff = (t - expected).rem_euclid(TAU);
        diff.min(TAU - diff) < 1e-9
    })
}

/// Fit `s(θ) = a + b·cosθ + c·sinθ`: the exact DFT when the angles are equally spaced over a turn, linear
/// least squares otherwise. Needs three samples with angles that separate the three terms.
pub fn fit_harmonic(thetas: &[f64], values: &[f64]) -> Result<Harmonic, CircleError> {
    let n = thetas.len();
    if n < 3 || values.len() != n {
        return Err(CircleError::TooFewPoints {
            needed: 3,
            got: n.min(values.len()),
        });
    }
    if let Some(index) = (0..n).find(|&i| !thetas[i].is_finite() || !values[i].is_finite()) {
        return Err(CircleError::NonFinite { index });
    }
    if equally_spaced(thetas) {
        let nf = n as f64;
        let a = values.iter().sum::<f64>() / nf;
        let b = 2.0 / nf
            * thetas
                .iter()
                .zip(values)
                .map(|(t, s)| s * t.cos())
                .sum::<f64>();
        let c = 2.0 / nf
            * thetas
                .iter()
                .zip(values)
                .map(|(t, s)| s * t.sin())
                .sum::<f64>();
        return Ok(Harmonic { a, b, c });
    }
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for (t, s) in thetas.iter().zip(values) {
        let row = Vector3::new(1.0, t.cos(), t.sin());
        ata += row * row.transpose();
        atb += row * *s;
    }
    // Reject near-singular designs (all angles nearly equal or opposite) rather than amplify noise.
    let eig = ata.symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    if hi <= 0.0 || lo / hi < 1e-10 {
        return Err(CircleError::Degenerate);
    }
    let sol = ata.lu().solve(&atb).ok_or(CircleError::Degenerate)?;
    Ok(Harmonic {
        a: sol[0],
        b: sol[1],
        c: sol[2],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(cx: f64, cy: f64, r: f64, n: usize, phase: f64) -> Vec<Point> {
        (0..n)
            .map(|k| {
                let t = phase + k as f64 * TAU / n as f64;
                [cx + r * t.cos(), cy + r * t.sin()]
            })
            .collect()
    }

    #[test]
    fn exact_circle_is_recovered_by_every_fit() {
        let pts = ring(1.5, -2.0, 100.0, 7, 0.3);
        for c in [kasa(&pts), taubin(&pts)]
            .into_iter()
            .map(|r| r.expect("fit"))
        {
            assert!(
                (c.cx - 1.5).abs() < 1e-9
                    && (c.cy + 2.0).abs() < 1e-9
                    && (c.r - 100.0).abs() < 1e-9
            );
        }
        let g = geometric(&pts).expect("geometric");
        assert!((g.circle.cx - 1.5).abs() < 1e-9 && g.rms < 1e-9);
    }

    #[test]
    fn three_points_give_the_circumcircle() {
        let pts = [[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]];
        let c = kasa(&pts).expect("kasa");
        assert!((c.cx - 1.0).abs() < 1e-12 && (c.cy - 1.0).abs() < 1e-12);
        assert!((c.r - 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        assert!(matches!(
            kasa(&[[0.0, 0.0], [1.0, 1.0]]),
            Err(CircleError::TooFewPoints { .. })
        ));
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        assert_eq!(kasa(&line), Err(CircleError::Degenerate));
        assert_eq!(taubin(&line), Err(CircleError::Degenerate));
        assert!(geometric(&line).is_err());
        assert!(robust(&line, 0.1).is_err());
        let same = [[1.0, 1.0]; 4];
        assert_eq!(taubin(&same), Err(CircleError::Degenerate));
        assert!(matches!(
            kasa(&[[0.0, f64::NAN], [1.0, 0.0], [0.0, 1.0]]),
            Err(CircleError::NonFinite { index: 0 })
        ));
    }

    #[test]
    fn lm_problem_jacobian_matches_numerical_differentiation() {
        let pts = [
            [10.0, 1.0],
            [-3.0, 9.5],
            [-8.0, -6.0],
            [4.0, -9.0],
            [9.0, 4.0],
        ];
        let mut problem = GeometricProblem {
            points: &pts,
            params: DVector::from_vec(vec![0.3, -0.2, 9.0]),
        };
        let numeric =
            levenberg_marquardt::differentiate_numerically(&mut problem).expect("numeric");
        let analytic = problem.jacobian().expect("analytic");
        assert!((numeric - analytic).amax() < 1e-6);
    }

    #[test]
    fn harmonic_dft_matches_closed_form() {
        let thetas: Vec<f64> = (0..16).map(|k| 0.1 + k as f64 * TAU / 16.0).collect();
        let values: Vec<f64> = thetas
            .iter()
            .map(|t| 99.0 + 0.7 * t.cos() - 0.4 * t.sin())
            .collect();
        let h = fit_harmonic(&thetas, &values).expect("dft");
        assert!(
            (h.a - 99.0).abs() < 1e-12 && (h.b - 0.7).abs() < 1e-12 && (h.c + 0.4).abs() < 1e-12
        );
        let uneven = [0.0f64, 0.5, 1.7, 2.9, 4.0];
        let values: Vec<f64> = uneven
            .iter()
            .map(|t| 5.0 + 0.2 * t.cos() + 0.3 * t.sin())
            .collect();
        let h = fit_harmonic(&uneven, &values).expect("lsq");
        assert!(
            (h.a - 5.0).abs() < 1e-10 && (h.b - 0.2).abs() < 1e-10 && (h.c - 0.3).abs() < 1e-10
        );
        assert!(fit_harmonic(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_err());
    }
}
