//! Whether a geometry fit (SCARA, five-bar) can be trusted: its residuals against the measurement noise the user
//! states (a chi-square test), enough residual degrees of freedom for a wrong input to show, and when the fit
//! fails, the poses that fit worst and the likely causes (checked where they can be, by fitting again: a single
//! cross off, the x and y columns swapped). Each machine kind gives its fit and its own words for the causes.

use serde::{Deserialize, Serialize};

use crate::measured::Measurement;

/// Fewest residual degrees of freedom (2·poses − parameters) a fit needs for a wrong angle or a mis-measured cross
/// to show in its residuals: 8 poses for a SCARA's 7 parameters, 10 for a five-bar's 10.
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
    /// Residual degrees of freedom (2·poses − parameters, 0 when fewer).
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

/// What a fit gives the verdict: the measurements, the fitted model's residual per measurement (model − measured,
/// mm), their RMS and the number of fitted parameters.
#[derive(Debug, Clone, Copy)]
pub struct Fitted<'a> {
    pub data: &'a [Measurement],
    pub residuals: &'a [[f64; 2]],
    pub rms: f64,
    pub parameters: usize,
}

/// A machine kind's own words for the causes of a poor fit: what swapped x and y columns may also mean, and the
/// causes the data cannot confirm.
#[derive(Debug, Clone, Copy)]
pub struct CauseWords {
    pub swapped: &'static str,
    pub general: &'static [&'static str],
}

/// A refit of a subset or variant of the measurements: its residuals, or None when it fails.
pub type Refit<'a> = &'a dyn Fn(&[Measurement]) -> Option<Vec<[f64; 2]>>;

/// Judges `fit` at the stated `noise` (mm); `refit` fits altered data again to confirm a cause.
pub fn judge_fit(fit: &Fitted, noise: f64, refit: Refit, words: &CauseWords) -> Verdict {
    let (data, parameters) = (fit.data, fit.parameters);
    let dof = (2 * data.len()).saturating_sub(parameters);
    let chi_square = chi_of(fit.residuals, noise);
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
            "{} poses leave {dof} residual degrees of freedom for {parameters} parameters: a wrong angle or a \
             mis-measured cross would not show; measure at least {} poses",
            data.len(),
            (MIN_RESIDUAL_DOF + parameters).div_ceil(2)
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
        causes(fit, noise, refit, words)
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

fn chi_of(residuals: &[[f64; 2]], noise: f64) -> f64 {
    residuals
        .iter()
        .map(|r| r[0] * r[0] + r[1] * r[1])
        .sum::<f64>()
        / (noise * noise)
}

fn rms_from_chi(chi: f64, noise: f64, components: usize) -> f64 {
    noise * (chi / components.max(1) as f64).sqrt()
}

/// The likely causes of a fit too poor for its noise: those the data confirm first, then the rest.
fn causes(fit: &Fitted, noise: f64, refit: Refit, words: &CauseWords) -> Vec<String> {
    let data = fit.data;
    let mut out = Vec::new();
    let passes = |d: &[Measurement]| {
        let dof = (2 * d.len()).saturating_sub(fit.parameters);
        refit(d).is_some_and(|r| dof > 0 && chi_of(&r, noise) <= chi_square_limit(dof))
    };
    let place = |m: &Measurement, index: usize| {
        if m.line > 0 {
            format!("line {}", m.line)
        } else {
            format!("measurement {}", index + 1)
        }
    };
    // One cross off: the fit without it passes.
    if data.len() > fit.parameters.div_ceil(2) + 4 {
        for index in worst_indices(fit.residuals).into_iter().take(2) {
            let rest: Vec<Measurement> = data
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != index)
                .map(|(_, m)| *m)
                .collect();
            if passes(&rest) {
                out.push(format!(
                    "the cross at {} is mis-measured (or its row holds another cross's angles): without it the \
                     others fit within the noise; measure it again",
                    place(&data[index], index)
                ));
                break;
            }
        }
    }
    if passes(&swapped_xy(data)) {
        out.push(words.swapped.to_string());
    }
    out.extend(words.general.iter().map(|c| c.to_string()));
    out
}

/// Poses by residual, worst first.
fn worst_indices(residuals: &[[f64; 2]]) -> Vec<usize> {
    let mut v: Vec<(usize, f64)> = residuals
        .iter()
        .enumerate()
        .map(|(i, r)| (i, r[0].hypot(r[1])))
        .collect();
    v.sort_by(|a, b| b.1.total_cmp(&a.1));
    v.into_iter().map(|(i, _)| i).collect()
}

/// The measurements with their x and y exchanged (an X-SCARA's frame, or swapped columns).
pub(crate) fn swapped_xy(data: &[Measurement]) -> Vec<Measurement> {
    data.iter()
        .map(|m| Measurement {
            x: m.y,
            y: m.x,
            ..*m
        })
        .collect()
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
