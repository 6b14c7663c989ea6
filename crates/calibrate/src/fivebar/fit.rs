//! The five-bar's fit: Levenberg–Marquardt over the ten parameters with the model's analytic Jacobian
//! (`crate::lsq`), the identifiability of a pose set in the bed frame and in a free frame, the greedy D-optimal
//! choice of poses, and the verdict against the stated noise (`crate::verdict`).

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::FivebarError;
use super::model::{FivebarGeometry, PARAM_NAMES};
use crate::lsq::{Identifiability, analyse_jacobian};
use crate::measured::Measurement;
use crate::verdict::{CauseWords, Fitted, Verdict, judge_fit};

/// Parameters fitted.
pub const PARAMETERS: usize = 10;

/// The columns a free measuring frame adds: its shift along X and Y and its turn about the bed's origin.
pub const FRAME_NAMES: [&str; 3] = ["frame_x", "frame_y", "frame_turn"];

/// A fitted geometry with its uncertainty and diagnostics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identification {
    pub geometry: FivebarGeometry,
    /// 1σ per parameter, [`PARAM_NAMES`] order (mm, rad).
    pub sigma: [f64; PARAMETERS],
    /// RMS of the XY residual components (mm).
    pub rms: f64,
    /// Residual (model − measured) per measurement (mm).
    pub residuals: Vec<[f64; 2]>,
    /// What these poses determine with the measurements in the bed frame (the fit's own terms).
    pub identifiability: Identifiability,
    /// What they would determine if the measurements fixed no frame (only the crosses' places relative to each
    /// other, as a scan without the bed's marks): the frame's shift and turn are then not separable from the
    /// base positions and the zeros.
    pub free_frame: Identifiability,
}

fn stacked_jacobian(
    g: &FivebarGeometry,
    poses: &[(f64, f64)],
) -> Result<DMatrix<f64>, FivebarError> {
    let mut j = DMatrix::zeros(2 * poses.len(), PARAMETERS);
    for (i, &(a, b)) in poses.iter().enumerate() {
        let rows = g
            .parameter_jacobian(a, b)
            .ok_or(FivebarError::Degenerate { index: i })?;
        for (k, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                j[(2 * i + k, c)] = *v;
            }
        }
    }
    Ok(j)
}

/// Singular values and null combinations of the identification Jacobian at `g` for motor poses (rad), the
/// measurements in the bed frame.
pub fn analyse_poses(
    g: &FivebarGeometry,
    poses: &[(f64, f64)],
) -> Result<Identifiability, FivebarError> {
    Ok(analyse_jacobian(stacked_jacobian(g, poses)?, &PARAM_NAMES))
}

/// The same with three more unknowns, the measuring frame's shift and turn (a measured point `R(φ)·N + t`,
/// so `∂/∂t = I`, `∂/∂φ = perp(N)` at φ = 0): what relative measurements leave undetermined.
pub fn analyse_free_frame(
    g: &FivebarGeometry,
    poses: &[(f64, f64)],
) -> Result<Identifiability, FivebarError> {
    let j = stacked_jacobian(g, poses)?;
    let mut wide = j.resize_horizontally(PARAMETERS + 3, 0.0);
    for (i, &(a, b)) in poses.iter().enumerate() {
        let n = g
            .forward(a, b)
            .ok_or(FivebarError::Degenerate { index: i })?;
        let frame = [[1.0, 0.0, -n[1]], [0.0, 1.0, n[0]]];
        for (k, row) in frame.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                wide[(2 * i + k, PARAMETERS + c)] = *v;
            }
        }
    }
    let names: Vec<&str> = PARAM_NAMES.iter().chain(&FRAME_NAMES).copied().collect();
    Ok(analyse_jacobian(wide, &names))
}

/// Residuals (model − measured) of `data` at parameters `v`, None where the model is not defined or not finite.
fn residuals_at(start: &FivebarGeometry, data: &[Measurement], v: &[f64]) -> Option<DVector<f64>> {
    let g = start.with_array(v);
    let mut r = DVector::zeros(2 * data.len());
    for (i, m) in data.iter().enumerate() {
        let p = g.forward_lenient(m.motor_a, m.motor_b)?;
        r[2 * i] = p[0] - m.x;
        r[2 * i + 1] = p[1] - m.y;
    }
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// The Jacobian of the residuals the fit minimises at a trial geometry: analytic where the distal links meet; at
/// a trial step where they would not (the residuals then use the model's nearest point,
/// [`FivebarGeometry::forward_lenient`]), that point's central differences, so the fit is led back rather than
/// stopped by a zero gradient.
fn trial_jacobian(g: &FivebarGeometry, poses: &[(f64, f64)]) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(2 * poses.len(), PARAMETERS);
    for (i, &(a, b)) in poses.iter().enumerate() {
        let rows = g
            .parameter_jacobian(a, b)
            .unwrap_or_else(|| lenient_rows(g, a, b));
        for (k, row) in rows.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                j[(2 * i + k, c)] = *v;
            }
        }
    }
    j
}

/// Central differences of [`FivebarGeometry::forward_lenient`] (zero where it is not defined either).
fn lenient_rows(g: &FivebarGeometry, a: f64, b: f64) -> [[f64; PARAMETERS]; 2] {
    const STEP: f64 = 1e-6;
    let v = g.to_array();
    let mut rows = [[0.0; PARAMETERS]; 2];
    for c in 0..PARAMETERS {
        let (mut up, mut down) = (v, v);
        up[c] += STEP;
        down[c] -= STEP;
        let moved = (
            g.with_array(&up).forward_lenient(a, b),
            g.with_array(&down).forward_lenient(a, b),
        );
        if let (Some(p), Some(q)) = moved {
            rows[0][c] = (p[0] - q[0]) / (2.0 * STEP);
            rows[1][c] = (p[1] - q[1]) / (2.0 * STEP);
        }
    }
    rows
}

/// Checks the measurements before a fit: enough of them, all finite.
fn check_data(data: &[Measurement]) -> Result<(), FivebarError> {
    if 2 * data.len() < PARAMETERS {
        return Err(FivebarError::TooFewMeasurements { got: data.len() });
    }
    match data.iter().position(|m| {
        ![m.motor_a, m.motor_b, m.x, m.y]
            .iter()
            .all(|v| v.is_finite())
    }) {
        Some(index) => Err(FivebarError::NonFinite { index }),
        None => Ok(()),
    }
}

/// Fit the geometry to `data` (measured in the bed frame), starting from `start` (the configured machine).
/// Refuses pose sets that cannot identify every parameter, naming the combinations.
pub fn identify(
    data: &[Measurement],
    start: &FivebarGeometry,
) -> Result<Identification, FivebarError> {
    check_data(data)?;
    let poses: Vec<(f64, f64)> = data.iter().map(|m| (m.motor_a, m.motor_b)).collect();
    let before = analyse_poses(start, &poses)?;
    if !before.is_identifiable() {
        return Err(FivebarError::Unidentifiable(before.describe()));
    }
    let jacobian = |v: &[f64]| trial_jacobian(&start.with_array(v), &poses);
    let residuals = |v: &[f64]| residuals_at(start, data, v);
    let solved = crate::lsq::minimise(&start.to_array(), &residuals, &jacobian)
        .map_err(FivebarError::NoConvergence)?;
    let g = start.with_array(&solved);
    let residual = residuals_at(start, data, &solved)
        .filter(|r| r.norm_squared().is_finite())
        .ok_or_else(|| FivebarError::NoConvergence("the fitted links do not meet".into()))?;
    let far = |e: FivebarError| match e {
        FivebarError::Degenerate { index } => FivebarError::NoConvergence(format!(
            "the fit ends where pose {} has no nozzle: the measurements are far from anything this machine \
             prints (x_mm and y_mm swapped, left and right exchanged, another machine's file?)",
            index + 1
        )),
        other => other,
    };
    let identifiability = analyse_poses(&g, &poses).map_err(far)?;
    let j = stacked_jacobian(&g, &poses).map_err(far)?;
    let cov = crate::lsq::covariance(&j, &residual)
        .ok_or_else(|| FivebarError::Unidentifiable(identifiability.describe()))?;
    Ok(Identification {
        geometry: g,
        sigma: std::array::from_fn(|k| cov[(k, k)].max(0.0).sqrt()),
        rms: (residual.norm_squared() / residual.len() as f64).sqrt(),
        residuals: (0..data.len())
            .map(|i| [residual[2 * i], residual[2 * i + 1]])
            .collect(),
        identifiability,
        free_frame: analyse_free_frame(&g, &poses).map_err(far)?,
    })
}

/// Indices of `count` poses from `candidates` added to `current`, greedy D-optimal at `g`; candidates where the
/// model is not regular are never chosen.
pub fn suggest_poses(
    g: &FivebarGeometry,
    current: &[(f64, f64)],
    candidates: &[(f64, f64)],
    count: usize,
) -> Vec<usize> {
    let info = |poses: &[(f64, f64)]| stacked_jacobian(g, poses).ok().map(|j| j.transpose() * j);
    let zero = DMatrix::zeros(PARAMETERS, PARAMETERS);
    let cand_info: Vec<DMatrix<f64>> = candidates
        .iter()
        .map(|p| info(std::slice::from_ref(p)).unwrap_or_else(|| zero.clone()))
        .collect();
    let held = info(current).unwrap_or(zero);
    crate::lsq::greedy_d_optimal(held, &cand_info, count)
}

const WORDS: CauseWords = CauseWords {
    swapped: "the x_mm and y_mm columns are swapped: with x and y exchanged the poses fit within the noise",
    general: &[
        "the motor angles are not the ones the machine commanded at these crosses (a pattern of another \
         configuration or another program, angles edited or rounded, rows out of order, left and right exchanged)",
        "x_mm, y_mm must be the printer's X and Y (the G-code's coordinates) measured from the bed's origin",
        "a cross measured from the wrong edge or corner, or the noise stated (--noise) smaller than the \
         measuring allows",
    ],
};

/// Judges `fit` of `data` (started from `start`) at the stated `noise` (mm).
pub fn judge(
    data: &[Measurement],
    fit: &Identification,
    start: &FivebarGeometry,
    noise: f64,
) -> Verdict {
    let fitted = Fitted {
        data,
        residuals: &fit.residuals,
        rms: fit.rms,
        parameters: PARAMETERS,
    };
    let refit = |d: &[Measurement]| identify(d, start).ok().map(|f| f.residuals);
    judge_fit(&fitted, noise, &refit, &WORDS)
}
