//! The fit of a scan: the arm's geometry together with the scan's own frame (rotation, translation and, as a
//! discrete choice made by the matching, a mirror), the scan's scale fixed beforehand (a reference distance or
//! the scanner's dpi).
//!
//! The frame absorbs what it moves rigidly: the shoulder's position (`offset_x`, `offset_y`) and a turn of the
//! whole arm about the shoulder — `shoulder_zero` by δ together with `elbow_zero` by `c·δ` — so these three
//! combinations are not identified and stay as configured (the gauge). What the scan identifies: both link
//! lengths, the elbow coupling, and the elbow joint's zero relative to the shoulder's (`elbow_zero − c·shoulder_zero`,
//! reported as `elbow_zero` with `shoulder_zero` as configured). The scale scales every length: a fit with a free
//! scale would leave `L1` and `L2` known only as a ratio, so the scale is not fitted.

use kinematics::ScaraFrame;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

use super::{
    Identifiability, Identification, Measurement, ScaraError, ScaraGeometry, swap_offsets,
};

/// Geometry parameters the scan fits, as indices into [`super::PARAM_NAMES`]: both lengths, the elbow zero, the
/// coupling.
pub const SCAN_FITTED: [usize; 4] = [0, 1, 5, 6];

/// The scan's frame: a point `p` of the printer's X/Y (mm) lies at `R(rotation)·M·p + translation` on the scan
/// (mm, the scan's pixels over its scale), M mirroring y when `mirrored`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanFrame {
    pub rotation: f64,
    pub translation: [f64; 2],
    pub mirrored: bool,
}

impl ScanFrame {
    pub fn to_scan(&self, p: [f64; 2]) -> [f64; 2] {
        let y = if self.mirrored { -p[1] } else { p[1] };
        let (s, c) = self.rotation.sin_cos();
        [
            c * p[0] - s * y + self.translation[0],
            s * p[0] + c * y + self.translation[1],
        ]
    }

    pub fn to_printer(&self, q: [f64; 2]) -> [f64; 2] {
        let (dx, dy) = (q[0] - self.translation[0], q[1] - self.translation[1]);
        let (s, c) = self.rotation.sin_cos();
        let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
        [x, if self.mirrored { -y } else { y }]
    }
}

/// The nozzle at motor angles (a, b) in the printer's X/Y, for a machine of `frame`.
pub fn printer_forward(g: &ScaraGeometry, frame: ScaraFrame, a: f64, b: f64) -> [f64; 2] {
    match frame {
        ScaraFrame::Standard => g.forward(a, b),
        ScaraFrame::XScara => {
            let p = swap_offsets(g).forward(a, b);
            [p[1], p[0]]
        }
    }
}

/// One cross on the scan: the pose's motor angles (rad) and its centre on the scan (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPoint {
    pub motor_a: f64,
    pub motor_b: f64,
    pub at: [f64; 2],
    /// The pose's number in the pattern (1-based).
    pub pose: usize,
}

/// The geometry fitted from a scan, with the frame found for it.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanIdentification {
    /// The geometry in the printer's frame: offsets and `shoulder_zero` as configured, σ 0 for them.
    pub fit: Identification,
    pub frame: ScanFrame,
    /// The crosses moved into the printer's frame by the fitted frame (`line` is the pose's number).
    pub measurements: Vec<Measurement>,
}

struct FrameProblem<'a> {
    data: &'a [ScanPoint],
    start: ScaraGeometry,
    frame: ScaraFrame,
    mirrored: bool,
    params: DVector<f64>,
}

impl FrameProblem<'_> {
    fn geometry(&self) -> ScaraGeometry {
        let mut v = self.start.to_array();
        for (k, &i) in SCAN_FITTED.iter().enumerate() {
            v[i] = self.params[k];
        }
        ScaraGeometry::from_array(v)
    }

    fn scan_frame(&self) -> ScanFrame {
        ScanFrame {
            rotation: self.params[4],
            translation: [self.params[5], self.params[6]],
            mirrored: self.mirrored,
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for FrameProblem<'_> {
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
        let (g, f) = (self.geometry(), self.scan_frame());
        let mut r = DVector::zeros(2 * self.data.len());
        for (i, m) in self.data.iter().enumerate() {
            let q = f.to_scan(printer_forward(&g, self.frame, m.motor_a, m.motor_b));
            r[2 * i] = q[0] - m.at[0];
            r[2 * i + 1] = q[1] - m.at[1];
        }
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let (g, f) = (self.geometry(), self.scan_frame());
        let (s, c) = f.rotation.sin_cos();
        let sign = if self.mirrored { -1.0 } else { 1.0 };
        let mut j = DMatrix::zeros(2 * self.data.len(), 7);
        for (i, m) in self.data.iter().enumerate() {
            let mut rows = g.parameter_jacobian(m.motor_a, m.motor_b);
            if self.frame == ScaraFrame::XScara {
                rows.swap(0, 1);
            }
            let p = printer_forward(&g, self.frame, m.motor_a, m.motor_b);
            for (k, &col) in SCAN_FITTED.iter().enumerate() {
                let (dx, dy) = (rows[0][col], sign * rows[1][col]);
                j[(2 * i, k)] = c * dx - s * dy;
                j[(2 * i + 1, k)] = s * dx + c * dy;
            }
            let y = sign * p[1];
            j[(2 * i, 4)] = -s * p[0] - c * y;
            j[(2 * i + 1, 4)] = c * p[0] - s * y;
            j[(2 * i, 5)] = 1.0;
            j[(2 * i + 1, 6)] = 1.0;
        }
        Some(j)
    }
}

/// Singular values of the column-normalised Jacobian, largest first.
fn singular_values(mut j: DMatrix<f64>) -> Vec<f64> {
    for c in 0..j.ncols() {
        let norm = j.column(c).norm();
        if norm > 0.0 {
            j.column_mut(c).unscale_mut(norm);
        }
    }
    let mut s: Vec<f64> = j.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// What a scan leaves undetermined, in the terms of [`Identifiability`].
fn frame_gauge(g: &ScaraGeometry) -> Vec<Vec<(String, f64)>> {
    let c = g.elbow_coupling;
    let norm = (1.0 + c * c).sqrt();
    vec![
        vec![("offset_x".to_string(), 1.0)],
        vec![("offset_y".to_string(), 1.0)],
        vec![
            ("shoulder_zero".to_string(), 1.0 / norm),
            ("elbow_zero".to_string(), c / norm),
        ],
    ]
}

/// Fits the geometry and the scan's frame to crosses on a scan (mm), from the configured geometry `start` (its
/// offsets and shoulder zero kept: the gauge) and a first frame (from matching the pattern).
pub fn identify_in_scan(
    data: &[ScanPoint],
    start: &ScaraGeometry,
    frame: ScaraFrame,
    first: ScanFrame,
) -> Result<ScanIdentification, ScaraError> {
    if data.len() < 4 {
        return Err(ScaraError::TooFewMeasurements {
            got: data.len(),
            rows: 2 * data.len(),
        });
    }
    if let Some(index) = data.iter().position(|m| {
        ![m.motor_a, m.motor_b, m.at[0], m.at[1]]
            .iter()
            .all(|v| v.is_finite())
    }) {
        return Err(ScaraError::NonFinite { index });
    }
    let mut params: Vec<f64> = SCAN_FITTED.iter().map(|&i| start.to_array()[i]).collect();
    params.extend([first.rotation, first.translation[0], first.translation[1]]);
    let problem = FrameProblem {
        data,
        start: *start,
        frame,
        mirrored: first.mirrored,
        params: DVector::from_vec(params),
    };
    let before = problem.jacobian().map(singular_values).unwrap_or_default();
    if before.last().is_none_or(|s| *s <= 1e-7 * before[0]) {
        return Err(ScaraError::Unidentifiable(
            "the poses and the scan's free frame leave the lengths, the coupling and the elbow zero mixed".into(),
        ));
    }
    let (solved, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(problem);
    if !report.termination.was_successful() {
        return Err(ScaraError::NoConvergence(format!(
            "{:?}",
            report.termination
        )));
    }
    finish(&solved)
}

/// The fit's geometry, covariance (σ² from the residuals), residuals and the crosses in the printer's frame.
fn finish(solved: &FrameProblem<'_>) -> Result<ScanIdentification, ScaraError> {
    let (g, f) = (solved.geometry(), solved.scan_frame());
    let r = solved
        .residuals()
        .ok_or_else(|| ScaraError::NoConvergence("non-finite residuals".into()))?;
    let j = solved
        .jacobian()
        .ok_or_else(|| ScaraError::NoConvergence("no Jacobian".into()))?;
    let n = solved.data.len();
    let sigma2 = r.norm_squared() / (r.len() as f64 - 7.0).max(1.0);
    let inv = (j.transpose() * &j)
        .try_inverse()
        .ok_or_else(|| ScaraError::Unidentifiable("the scan's fit is singular".into()))?;
    let mut covariance = vec![[0.0; 7]; 7];
    for (a, &ia) in SCAN_FITTED.iter().enumerate() {
        for (b, &ib) in SCAN_FITTED.iter().enumerate() {
            covariance[ia][ib] = sigma2 * inv[(a, b)];
        }
    }
    let sigma = std::array::from_fn(|k| covariance[k][k].max(0.0).sqrt());
    let back = |v: [f64; 2]| {
        let o = f.to_printer([0.0, 0.0]);
        let p = f.to_printer(v);
        [p[0] - o[0], p[1] - o[1]]
    };
    let residuals: Vec<[f64; 2]> = (0..n).map(|i| back([r[2 * i], r[2 * i + 1]])).collect();
    let measurements = solved
        .data
        .iter()
        .map(|m| {
            let p = f.to_printer(m.at);
            Measurement {
                motor_a: m.motor_a,
                motor_b: m.motor_b,
                x: p[0],
                y: p[1],
                line: m.pose,
            }
        })
        .collect();
    let s = singular_values(j);
    let condition_number = s[0] / s[s.len() - 1];
    Ok(ScanIdentification {
        fit: Identification {
            geometry: g,
            sigma,
            covariance,
            rms: (r.norm_squared() / r.len() as f64).sqrt(),
            residuals,
            identifiability: Identifiability {
                singular_values: s,
                condition_number,
                unidentifiable: frame_gauge(&g),
            },
        },
        frame: f,
        measurements,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn analytic_jacobian_matches_numerical_differentiation() {
        let start = ScaraGeometry {
            link1_length: 101.0,
            link2_length: 99.0,
            offset_x: 0.5,
            offset_y: -1.0,
            shoulder_zero: 0.01,
            elbow_zero: -0.02,
            elbow_coupling: 0.34,
        };
        let data: Vec<ScanPoint> = (0..6)
            .map(|k| ScanPoint {
                motor_a: 0.3 * k as f64 - 0.5,
                motor_b: 1.1 - 0.2 * k as f64,
                at: [k as f64, 2.0 * k as f64],
                pose: k + 1,
            })
            .collect();
        for (frame, mirrored) in [(ScaraFrame::Standard, false), (ScaraFrame::XScara, true)] {
            let mut problem = FrameProblem {
                data: &data,
                start,
                frame,
                mirrored,
                params: DVector::from_vec(vec![101.5, 98.0, 0.03, 0.33, 0.4, 10.0, -20.0]),
            };
            let numeric =
                levenberg_marquardt::differentiate_numerically(&mut problem).expect("numeric");
            let analytic = problem.jacobian().expect("analytic");
            assert!((numeric - analytic).amax() < 1e-5);
        }
    }

    #[test]
    fn frame_round_trip() {
        let f = ScanFrame {
            rotation: 0.7,
            translation: [3.0, -4.0],
            mirrored: true,
        };
        let p = [12.5, -7.25];
        let q = f.to_printer(f.to_scan(p));
        assert!((q[0] - p[0]).abs() < 1e-12 && (q[1] - p[1]).abs() < 1e-12);
    }
}
