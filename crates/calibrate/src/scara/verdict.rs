//! Whether a SCARA fit can be trusted: its residuals against the measurement noise the user states (a chi-square
//! test), enough residual degrees of freedom for a wrong input to show, and when the fit fails, the poses that fit
//! worst and the likely causes (checked where they can be: a single cross off, the x and y columns swapped).

use kinematics::ScaraFrame;
use serde::{Deserialize, Serialize};

use super::{Identification, Measurement, ScaraGeometry, identify_in_frame};

/// Fewest residual degrees of freedom (2·poses − 7) a fit needs for a wrong angle or a mis-measured cross to show
/// in its residuals: 8 poses.
pub const MIN_RESIDUAL_DOF: usize = 9;
/// The chi-square test's false-alarm probability: a fit of correct data at the stated noise fails once in 1000.
pub const FALSE_ALARM: f64 = 0.001;
/// The standard normal quantile of `1 − FALSE_ALARM`.
const Z_FALSE_ALARM: f64 = 3.090_232_306_167_813;

/// How the crosses were measured, and the noise (mm, 1σ per coordinate) that gives by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MeasuringMethod {
    /// Calipers from two bed edges: 0.02 mm.
    Calipers,
    /// A flatbed scan of the print with the bed's corner marks (600 dpi): 0.03 mm.
    Scanner,
    /// A measuring microscope or a camera on the toolhead: 0.005 mm.
    Microscope,
}

impl MeasuringMethod {
    pub fn noise(self) -> f64 {
        match self {
            MeasuringMethod::Calipers => 0.02,
            MeasuringMethod::Scanner => 0.03,
            MeasuringMethod::Microscope => 0.005,
        }
    }
}

/// One pose's residual.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseResidual {
    /// Index in the measurements.
    pub index: usize,
    /// Line in the measurements file (0 when not from a file).
    pub line: usize,
    /// Distance between where the fitted model puts the pose and where it was measured (mm).
    pub distance: f64,
}

/// The fit's verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    pub trustworthy: bool,
    /// The stated measurement noise (mm, 1σ per coordinate).
    pub noise: f64,
    /// Sum of squared residuals over noise².
    pub chi_square: f64,
    /// Residual degrees of freedom (2·poses − 7, 0 when fewer).
    pub dof: usize,
    /// The chi-square the residuals may reach at this noise ([`FALSE_ALARM`]).
    pub chi_square_limit: f64,
    /// The residual RMS (mm) that limit stands for.
    pub rms_limit: f64,
    /// Why the fit is not trustworthy (empty when it is).
    pub problems: Vec<String>,
    /// The worst-fitting poses, worst first (at most three).
    pub worst: Vec<PoseResidual>,
    /// The likely causes, most specific first (empty when trustworthy).
    pub causes: Vec<String>,
}

/// The `1 − FALSE_ALARM` quantile of the chi-square distribution with `dof` degrees of freedom (Wilson–Hilferty;
/// within 1 % of the exact quantile from 3 degrees of freedom up).
pub fn chi_square_limit(dof: usize) -> f64 {
    let k = dof.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + Z_FALSE_ALARM * a.sqrt()).powi(3)
}

/// Judges `fit` of `data` (bed frame `frame`, started from `start`) at the stated `noise` (mm).
pub fn judge(
    data: &[Measurement],
    fit: &Identification,
    start: &ScaraGeometry,
    frame: ScaraFrame,
    noise: f64,
) -> Verdict {
    let dof = (2 * data.len()).saturating_sub(7);
    let chi_square = chi_of(fit, noise);
    let limit = chi_square_limit(dof);
    let mut worst: Vec<PoseResidual> = fit
        .residuals
        .iter()
        .enumerate()
        .map(|(index, r)| PoseResidual {
            index,
            line: data.get(index).map_or(0, |m| m.line),
            distance: r[0].hypot(r[1]),
        })
        .collect();
    worst.sort_by(|a, b| b.distance.total_cmp(&a.distance));
    worst.truncate(3);
    let mut problems = Vec::new();
    if dof < MIN_RESIDUAL_DOF {
        problems.push(format!(
            "{} poses leave {dof} residual degrees of freedom for 7 parameters: a wrong angle or a mis-measured \
             cross would not show; measure at least {} poses",
            data.len(),
            MIN_RESIDUAL_DOF.div_ceil(2) + 4
        ));
    }
    let too_large = chi_square > limit;
    if too_large {
        problems.push(format!(
            "the residuals (RMS {:.4} mm) are too large for measurements of {noise} mm (1σ): chi-square {:.1} over \
             {dof} degrees of freedom, at most {:.1} expected (RMS {:.4} mm)",
            fit.rms,
            chi_square,
            limit,
            rms_from_chi(limit, noise, 2 * data.len())
        ));
    }
    let causes = if too_large {
        causes(data, fit, start, frame, noise)
    } else {
        Vec::new()
    };
    Verdict {
        trustworthy: problems.is_empty(),
        noise,
        chi_square,
        dof,
        chi_square_limit: limit,
        rms_limit: rms_from_chi(limit, noise, 2 * data.len()),
        problems,
        worst,
        causes,
    }
}

fn chi_of(fit: &Identification, noise: f64) -> f64 {
    fit.residuals
        .iter()
        .map(|r| r[0] * r[0] + r[1] * r[1])
        .sum::<f64>()
        / (noise * noise)
}

fn rms_from_chi(chi: f64, noise: f64, components: usize) -> f64 {
    noise * (chi / components.max(1) as f64).sqrt()
}

/// The likely causes of a fit too poor for its noise: those the data confirm first, then the rest.
fn causes(
    data: &[Measurement],
    fit: &Identification,
    start: &ScaraGeometry,
    frame: ScaraFrame,
    noise: f64,
) -> Vec<String> {
    let mut out = Vec::new();
    let place = |m: &Measurement, index: usize| {
        if m.line > 0 {
            format!("line {}", m.line)
        } else {
            format!("measurement {}", index + 1)
        }
    };
    // One cross off: the fit without it passes.
    if data.len() > 8 {
        for (index, _) in worst_indices(fit).into_iter().take(2) {
            let rest: Vec<Measurement> = data
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != index)
                .map(|(_, m)| *m)
                .collect();
            if passes(&rest, start, frame, noise) {
                out.push(format!(
                    "the cross at {} is mis-measured (or its row holds another cross's angles): without it the \
                     others fit within the noise; measure it again",
                    place(&data[index], index)
                ));
                break;
            }
        }
    }
    if passes(&super::swapped_xy(data), start, frame, noise) {
        out.push(
            "the x_mm and y_mm columns are swapped, or the file's frame is not the machine's (X-SCARA's frame swaps \
             them): with x and y exchanged the poses fit within the noise"
                .to_string(),
        );
    }
    out.extend(
        [
            "the motor angles are not the ones the machine commanded at these crosses (a pattern of another \
             configuration or another program, angles edited or rounded, rows out of order)",
            "the frame: x_mm, y_mm must be the printer's X and Y (the G-code's coordinates), the file's `frame` line \
             the machine's",
            "a cross measured from the wrong edge or corner, or the noise stated (--noise) smaller than the \
             measuring allows",
        ]
        .map(String::from),
    );
    out
}

/// Poses by residual, worst first.
fn worst_indices(fit: &Identification) -> Vec<(usize, f64)> {
    let mut v: Vec<(usize, f64)> = fit
        .residuals
        .iter()
        .enumerate()
        .map(|(i, r)| (i, r[0].hypot(r[1])))
        .collect();
    v.sort_by(|a, b| b.1.total_cmp(&a.1));
    v
}

/// Whether `data` fits within `noise` (the chi-square test alone).
fn passes(data: &[Measurement], start: &ScaraGeometry, frame: ScaraFrame, noise: f64) -> bool {
    let dof = (2 * data.len()).saturating_sub(7);
    identify_in_frame(data, start, frame)
        .is_ok_and(|fit| dof > 0 && chi_of(&fit, noise) <= chi_square_limit(dof))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chi_square_quantile_matches_tables() {
        // χ²_{0.999} from tables: 10 → 29.588, 33 → 63.870, 100 → 149.449.
        for (k, exact) in [(10, 29.588), (33, 63.870), (100, 149.449)] {
            let got = chi_square_limit(k);
            assert!((got - exact).abs() / exact < 0.01, "{k}: {got} vs {exact}");
        }
    }
}
