//! SCARA geometry identification: a parametric forward model with its analytic Jacobian, a Levenberg–Marquardt
//! fit of `L1, L2, offset_x, offset_y, shoulder_zero, elbow_zero, coupling` to measured nozzle XY at commanded
//! motor angles, identifiability analysis (scaled-Jacobian singular values), greedy D-optimal pose selection;
//! the measurements file (`measurements`), the printed pattern built through the machine's own kinematics
//! (`pattern`) and the fit's verdict against the stated measurement noise (`verdict`).
//!
//! Model (standard frame, angles from +X counter-clockwise, as `kinematics::ScaraParams`):
//! `q1 = a − shoulder_zero`, `q2 = b − elbow_zero − c·q1`,
//! `x = L1·cos q1 + L2·cos(q1+q2) + offset_x`, `y = L1·sin q1 + L2·sin(q1+q2) + offset_y`
//! (a, b: motor angles; c: elbow coupling, `1/ECR` on FEKT-SCARA).
//!
//! Gauge: the measurement frame is the bed frame. Its origin fixes the offsets and its orientation fixes the
//! base rotation, which is therefore not a separate parameter: a rotated base shows up as `shoulder_zero`
//! (the two are not separable, REFERENCE §4). The X-SCARA frame (`kinematics::ScaraFrame::XScara`) is the standard
//! frame with x and y swapped: [`identify_in_frame`] fits such data with x and y exchanged and gives the offsets
//! (and their uncertainty) back in the printer's X and Y.
//!
//! Identifiability in practice: a fixed shoulder leaves `L1`, the offsets, `shoulder_zero` and the coupling
//! mixed (3 null combinations); a fixed elbow joint makes the arm rigid (2 null combinations); a fixed elbow
//! *motor* is identifiable but poorly conditioned.

mod measurements;
pub(crate) mod pattern;
pub mod scan_fit;
pub mod scan_image;
mod verdict;

pub use crate::lsq::Identifiability;
pub use crate::measured::Measurement;
pub use crate::verdict::{
    FALSE_ALARM, MIN_RESIDUAL_DOF, MeasuringMethod, PoseResidual, Verdict, chi_square_limit,
};
pub use measurements::{
    CSV_HEADER, MeasurementFile, PoseFile, frame_name, measurement_template,
    parse_measurement_file, parse_measurements, parse_pose_file,
};
pub use pattern::{
    DEFAULT_POSES, MIN_POSES, Pattern, PatternError, PatternOptions, REFERENCE_ACROSS,
    REFERENCE_REACH, machine_pattern,
};
pub use verdict::judge;

use kinematics::ScaraFrame;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Parameter names in vector order.
pub const PARAM_NAMES: [&str; 7] = [
    "link1_length",
    "link2_length",
    "offset_x",
    "offset_y",
    "shoulder_zero",
    "elbow_zero",
    "elbow_coupling",
];

/// The identified quantities (mm, rad, dimensionless coupling).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScaraGeometry {
    pub link1_length: f64,
    pub link2_length: f64,
    pub offset_x: f64,
    pub offset_y: f64,
    pub shoulder_zero: f64,
    pub elbow_zero: f64,
    pub elbow_coupling: f64,
}

impl From<&kinematics::ScaraParams> for ScaraGeometry {
    /// A configured machine's nominal geometry, in the identification's terms.
    fn from(p: &kinematics::ScaraParams) -> Self {
        ScaraGeometry {
            link1_length: p.link1_length,
            link2_length: p.link2_length,
            offset_x: p.offset_x,
            offset_y: p.offset_y,
            shoulder_zero: p.shoulder_zero,
            elbow_zero: p.elbow_zero,
            elbow_coupling: p.elbow_coupling,
        }
    }
}

impl ScaraGeometry {
    /// FEKT-SCARA nominal: 100/100 mm arms, ECR 3, no offsets.
    pub fn fekt() -> Self {
        Self {
            link1_length: 100.0,
            link2_length: 100.0,
            offset_x: 0.0,
            offset_y: 0.0,
            shoulder_zero: 0.0,
            elbow_zero: 0.0,
            elbow_coupling: 1.0 / 3.0,
        }
    }

    pub fn to_array(&self) -> [f64; 7] {
        [
            self.link1_length,
            self.link2_length,
            self.offset_x,
            self.offset_y,
            self.shoulder_zero,
            self.elbow_zero,
            self.elbow_coupling,
        ]
    }

    pub fn from_array(v: [f64; 7]) -> Self {
        Self {
            link1_length: v[0],
            link2_length: v[1],
            offset_x: v[2],
            offset_y: v[3],
            shoulder_zero: v[4],
            elbow_zero: v[5],
            elbow_coupling: v[6],
        }
    }

    /// Joint angles (q1, q2) from motor angles (a, b).
    pub fn joints(&self, a: f64, b: f64) -> (f64, f64) {
        let q1 = a - self.shoulder_zero;
        (q1, b - self.elbow_zero - self.elbow_coupling * q1)
    }

    /// Nozzle XY (mm) at motor angles (a, b) in rad.
    pub fn forward(&self, a: f64, b: f64) -> [f64; 2] {
        let (q1, q2) = self.joints(a, b);
        let phi = q1 + q2;
        [
            self.link1_length * q1.cos() + self.link2_length * phi.cos() + self.offset_x,
            self.link1_length * q1.sin() + self.link2_length * phi.sin() + self.offset_y,
        ]
    }

    /// ∂(x, y)/∂(parameters) at motor angles (a, b): rows x and y, columns in [`PARAM_NAMES`] order.
    pub fn parameter_jacobian(&self, a: f64, b: f64) -> [[f64; 7]; 2] {
        let (q1, q2) = self.joints(a, b);
        let phi = q1 + q2;
        let (l1, l2, c) = (self.link1_length, self.link2_length, self.elbow_coupling);
        let (s1, c1, sp, cp) = (q1.sin(), q1.cos(), phi.sin(), phi.cos());
        // dq1/dz1 = −1, dφ/dz1 = c − 1, dφ/dz2 = −1, dφ/dc = −q1.
        [
            [
                c1,
                cp,
                1.0,
                0.0,
                l1 * s1 + l2 * sp * (1.0 - c),
                l2 * sp,
                l2 * sp * q1,
            ],
            [
                s1,
                sp,
                0.0,
                1.0,
                -l1 * c1 - l2 * cp * (1.0 - c),
                -l2 * cp,
                -l2 * cp * q1,
            ],
        ]
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScaraError {
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{got} measurements give {rows} equations for 7 parameters; need at least 4 poses")]
    TooFewMeasurements { got: usize, rows: usize },
    #[error("the poses cannot identify: {0}")]
    Unidentifiable(String),
    #[error("the fit did not converge: {0}")]
    NoConvergence(String),
    #[error("non-finite value in measurement {index}")]
    NonFinite { index: usize },
}

fn stacked_jacobian(g: &ScaraGeometry, poses: &[(f64, f64)]) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(2 * poses.len(), 7);
    for (i, &(a, b)) in poses.iter().enumerate() {
        let rows = g.parameter_jacobian(a, b);
        for (k, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                j[(2 * i + k, c)] = *v;
            }
        }
    }
    j
}

/// Singular values and null combinations of the identification Jacobian at `g` for motor poses (rad).
/// Columns are normalised to unit length first so mm and rad parameters compare fairly.
pub fn analyse_poses(g: &ScaraGeometry, poses: &[(f64, f64)]) -> Identifiability {
    crate::lsq::analyse_jacobian(stacked_jacobian(g, poses), &PARAM_NAMES)
}

/// A fitted geometry with its uncertainty and diagnostics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identification {
    pub geometry: ScaraGeometry,
    /// 1σ per parameter, [`PARAM_NAMES`] order (mm, rad, 1).
    pub sigma: [f64; 7],
    /// Parameter covariance `σ²(JᵀJ)⁻¹`.
    pub covariance: Vec<[f64; 7]>,
    /// RMS of the XY residual components (mm).
    pub rms: f64,
    /// Residual (model − measured) per measurement (mm).
    pub residuals: Vec<[f64; 2]>,
    pub identifiability: Identifiability,
}

/// Residuals (model − measured) of `data` at parameters `v`, None when not finite.
fn residuals_at(data: &[Measurement], v: &[f64]) -> Option<DVector<f64>> {
    let g = ScaraGeometry::from_array(std::array::from_fn(|k| v[k]));
    let mut r = DVector::zeros(2 * data.len());
    for (i, m) in data.iter().enumerate() {
        let p = g.forward(m.motor_a, m.motor_b);
        r[2 * i] = p[0] - m.x;
        r[2 * i + 1] = p[1] - m.y;
    }
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// Fit the geometry to `data`, starting from `start` (the nominal machine). Refuses pose sets that cannot
/// identify every parameter, naming the combinations.
pub fn identify(data: &[Measurement], start: &ScaraGeometry) -> Result<Identification, ScaraError> {
    if data.len() < 4 {
        return Err(ScaraError::TooFewMeasurements {
            got: data.len(),
            rows: 2 * data.len(),
        });
    }
    if let Some(index) = data.iter().position(|m| {
        ![m.motor_a, m.motor_b, m.x, m.y]
            .iter()
            .all(|v| v.is_finite())
    }) {
        return Err(ScaraError::NonFinite { index });
    }
    let poses: Vec<(f64, f64)> = data.iter().map(|m| (m.motor_a, m.motor_b)).collect();
    let before = analyse_poses(start, &poses);
    if !before.is_identifiable() {
        return Err(ScaraError::Unidentifiable(before.describe()));
    }
    let jacobian = |v: &[f64]| {
        stacked_jacobian(
            &ScaraGeometry::from_array(std::array::from_fn(|k| v[k])),
            &poses,
        )
    };
    let residuals = |v: &[f64]| residuals_at(data, v);
    let solved = crate::lsq::minimise(&start.to_array(), &residuals, &jacobian)
        .map_err(ScaraError::NoConvergence)?;
    let g = ScaraGeometry::from_array(std::array::from_fn(|k| solved[k]));
    let residual = residuals_at(data, &solved)
        .ok_or_else(|| ScaraError::NoConvergence("non-finite residuals".into()))?;
    let j = stacked_jacobian(&g, &poses);
    let identifiability = analyse_poses(&g, &poses);
    let cov = crate::lsq::covariance(&j, &residual)
        .ok_or_else(|| ScaraError::Unidentifiable(identifiability.describe()))?;
    let covariance: Vec<[f64; 7]> = (0..7)
        .map(|a| std::array::from_fn(|b| cov[(a, b)]))
        .collect();
    let sigma = std::array::from_fn(|k| covariance[k][k].max(0.0).sqrt());
    let residuals = (0..data.len())
        .map(|i| [residual[2 * i], residual[2 * i + 1]])
        .collect();
    let rms = (residual.norm_squared() / residual.len() as f64).sqrt();
    Ok(Identification {
        geometry: g,
        sigma,
        covariance,
        rms,
        residuals,
        identifiability,
    })
}

/// [`identify`] for measurements in the printer's X and Y on a machine of `frame`, from `start` in the same terms:
/// X-SCARA data is fitted with x and y exchanged (its arm frame), and the offsets, their covariance, the
/// residuals and the unidentifiable combinations come back in the printer's X and Y.
pub fn identify_in_frame(
    data: &[Measurement],
    start: &ScaraGeometry,
    frame: ScaraFrame,
) -> Result<Identification, ScaraError> {
    if frame == ScaraFrame::Standard {
        return identify(data, start);
    }
    let mut fit = identify(&swapped_xy(data), &swap_offsets(start))?;
    fit.geometry = swap_offsets(&fit.geometry);
    fit.sigma.swap(2, 3);
    fit.covariance.swap(2, 3);
    for row in &mut fit.covariance {
        row.swap(2, 3);
    }
    for r in &mut fit.residuals {
        r.swap(0, 1);
    }
    for combination in &mut fit.identifiability.unidentifiable {
        for (name, _) in combination.iter_mut() {
            *name = match name.as_str() {
                "offset_x" => "offset_y".to_string(),
                "offset_y" => "offset_x".to_string(),
                other => other.to_string(),
            };
        }
    }
    Ok(fit)
}

pub(crate) use crate::verdict::swapped_xy;

/// The geometry with its offsets exchanged (between the printer's X/Y and the X-SCARA arm frame).
pub(crate) fn swap_offsets(g: &ScaraGeometry) -> ScaraGeometry {
    ScaraGeometry {
        offset_x: g.offset_y,
        offset_y: g.offset_x,
        ..*g
    }
}

/// Candidate poses on a grid of motor angles (rad), `n_a × n_b` points including the ends.
pub fn pose_grid(
    a_range: (f64, f64),
    b_range: (f64, f64),
    n_a: usize,
    n_b: usize,
) -> Vec<(f64, f64)> {
    let lerp = |(lo, hi): (f64, f64), k: usize, n: usize| {
        if n <= 1 {
            lo
        } else {
            lo + (hi - lo) * k as f64 / (n - 1) as f64
        }
    };
    (0..n_a)
        .flat_map(|i| (0..n_b).map(move |k| (lerp(a_range, i, n_a), lerp(b_range, k, n_b))))
        .collect()
}

/// Greedy D-optimal design: add `count` poses from `candidates` to `current`, each time the one that most
/// increases `det(JᵀJ)` (a small ridge lets the first picks proceed before the matrix has full rank).
pub fn suggest_poses(
    g: &ScaraGeometry,
    current: &[(f64, f64)],
    candidates: &[(f64, f64)],
    count: usize,
) -> Vec<(f64, f64)> {
    let info = |poses: &[(f64, f64)]| {
        let j = stacked_jacobian(g, poses);
        j.transpose() * j
    };
    let cand_info: Vec<DMatrix<f64>> = candidates
        .iter()
        .map(|p| info(std::slice::from_ref(p)))
        .collect();
    crate::lsq::greedy_d_optimal(info(current), &cand_info, count)
        .into_iter()
        .map(|i| candidates[i])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_closed_forms() {
        let g = ScaraGeometry::fekt();
        let p = g.forward(0.0, 0.0);
        assert!((p[0] - 200.0).abs() < 1e-12 && p[1].abs() < 1e-12);
        // Shoulder 90°, elbow motor 90°·c + 90°: q2 = 90° → nozzle at (−100, 100).
        let a = 90f64.to_radians();
        let p = g.forward(a, a + a / 3.0);
        assert!((p[0] + 100.0).abs() < 1e-9 && (p[1] - 100.0).abs() < 1e-9);
    }

    #[test]
    fn lm_problem_jacobian_matches_numerical_differentiation() {
        let g = ScaraGeometry {
            link1_length: 101.0,
            link2_length: 99.0,
            offset_x: 0.5,
            offset_y: -1.0,
            shoulder_zero: 0.01,
            elbow_zero: -0.02,
            elbow_coupling: 0.34,
        };
        let data: Vec<Measurement> = (0..6)
            .map(|k| {
                let (a, b) = (0.3 * k as f64 - 0.5, 1.1 - 0.2 * k as f64);
                let p = ScaraGeometry::fekt().forward(a, b);
                Measurement {
                    motor_a: a,
                    motor_b: b,
                    x: p[0],
                    y: p[1],
                    line: 0,
                }
            })
            .collect();
        let residuals = |v: &[f64]| residuals_at(&data, v);
        let poses: Vec<(f64, f64)> = data.iter().map(|m| (m.motor_a, m.motor_b)).collect();
        let jacobian = |v: &[f64]| {
            stacked_jacobian(
                &ScaraGeometry::from_array(std::array::from_fn(|k| v[k])),
                &poses,
            )
        };
        let mut problem = crate::lsq::Problem {
            params: DVector::from_row_slice(&g.to_array()),
            residuals: &residuals,
            jacobian: &jacobian,
        };
        let numeric =
            levenberg_marquardt::differentiate_numerically(&mut problem).expect("numeric");
        let analytic = jacobian(&g.to_array());
        assert!((numeric - analytic).amax() < 1e-5);
    }
}
