//! The least-squares plumbing the geometry fits share (SCARA, five-bar): Levenberg–Marquardt over a model given
//! by its residuals and analytic Jacobian, the parameter covariance, the identifiability analysis by the
//! column-scaled Jacobian's singular values, and the greedy D-optimal choice of poses.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use serde::{Deserialize, Serialize};

/// How well a pose set determines the parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identifiability {
    /// Singular values of the column-normalised Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Largest over smallest singular value (infinite when a combination is not identified at all).
    pub condition_number: f64,
    /// Parameter combinations the poses cannot determine: right singular vectors with negligible singular
    /// value, as (parameter name, weight) pairs with |weight| ≥ 0.1.
    pub unidentifiable: Vec<Vec<(String, f64)>>,
}

impl Identifiability {
    pub fn is_identifiable(&self) -> bool {
        self.unidentifiable.is_empty()
    }

    /// A readable list of the unidentifiable combinations.
    pub fn describe(&self) -> String {
        self.unidentifiable
            .iter()
            .map(|combo| {
                combo
                    .iter()
                    .map(|(n, w)| format!("{w:+.2}·{n}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Relative singular value below which a combination counts as not identified.
pub const NULL_RELATIVE: f64 = 1e-7;

/// Singular values and null combinations of the stacked identification Jacobian `j` (columns named by `names`).
/// Columns are normalised to unit length first so mm and rad parameters compare fairly.
pub fn analyse_jacobian(mut j: DMatrix<f64>, names: &[&str]) -> Identifiability {
    let n = names.len();
    for c in 0..n {
        let norm = j.column(c).norm();
        if norm > 0.0 {
            j.column_mut(c).unscale_mut(norm);
        }
    }
    // Pad to at least n rows so the SVD yields all n right singular vectors.
    if j.nrows() < n {
        j = j.resize_vertically(n, 0.0);
    }
    let svd = j.svd(false, true);
    let mut pairs: Vec<(f64, Vec<f64>)> = match &svd.v_t {
        Some(vt) => (0..n)
            .map(|k| (svd.singular_values[k], vt.row(k).iter().copied().collect()))
            .collect(),
        None => Vec::new(),
    };
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let smax = pairs.first().map_or(0.0, |p| p.0);
    let unidentifiable: Vec<Vec<(String, f64)>> = pairs
        .iter()
        .filter(|(s, _)| smax <= 0.0 || *s <= NULL_RELATIVE * smax)
        .map(|(_, v)| named_combination(v, names))
        .collect();
    let smin = pairs.last().map_or(0.0, |p| p.0);
    let condition_number = if unidentifiable.is_empty() && smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    Identifiability {
        singular_values: pairs.iter().map(|p| p.0).collect(),
        condition_number,
        unidentifiable,
    }
}

/// A null vector as its named weights of at least 0.1, signed so the largest is positive (a sign-free answer).
fn named_combination(v: &[f64], names: &[&str]) -> Vec<(String, f64)> {
    let largest = v
        .iter()
        .copied()
        .fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m });
    let sign = if largest < 0.0 { -1.0 } else { 1.0 };
    v.iter()
        .enumerate()
        .filter(|(_, w)| w.abs() >= 0.1)
        .map(|(k, w)| (names[k].to_string(), sign * w))
        .collect()
}

/// A model for Levenberg–Marquardt: its residuals (None when not finite) and their Jacobian at a parameter vector.
pub(crate) struct Problem<'a> {
    pub params: DVector<f64>,
    pub residuals: &'a dyn Fn(&[f64]) -> Option<DVector<f64>>,
    pub jacobian: &'a dyn Fn(&[f64]) -> DMatrix<f64>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
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
        (self.residuals)(self.params.as_slice())
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        Some((self.jacobian)(self.params.as_slice()))
    }
}

/// The parameters minimising the residuals from `start`, or why the minimisation failed.
pub fn minimise(
    start: &[f64],
    residuals: &dyn Fn(&[f64]) -> Option<DVector<f64>>,
    jacobian: &dyn Fn(&[f64]) -> DMatrix<f64>,
) -> Result<Vec<f64>, String> {
    let problem = Problem {
        params: DVector::from_row_slice(start),
        residuals,
        jacobian,
    };
    let (solved, report) = LevenbergMarquardt::new()
        .with_patience(200)
        .minimize(problem);
    if !report.termination.was_successful() {
        return Err(format!("{:?}", report.termination));
    }
    Ok(solved.params.iter().copied().collect())
}

/// The parameter covariance `σ²(JᵀJ)⁻¹`, σ² from the residuals over their degrees of freedom (at least 1).
pub fn covariance(j: &DMatrix<f64>, residual: &DVector<f64>) -> Option<DMatrix<f64>> {
    let dof = (residual.len() as f64 - j.ncols() as f64).max(1.0);
    let sigma2 = residual.norm_squared() / dof;
    (j.transpose() * j).try_inverse().map(|inv| inv * sigma2)
}

/// Greedy D-optimal design: indices of `count` candidates (their information matrices `JᵀJ` in `candidates`)
/// added to `current` (the information already held), each time the one that most increases the determinant;
/// a small ridge lets the first picks proceed before the matrix has full rank.
pub fn greedy_d_optimal(
    current: DMatrix<f64>,
    candidates: &[DMatrix<f64>],
    count: usize,
) -> Vec<usize> {
    let n = current.nrows();
    let scale = candidates.iter().map(|m| m.trace()).sum::<f64>()
        / (n as f64 * candidates.len().max(1) as f64);
    let mut m = current + DMatrix::identity(n, n) * (1e-6 * scale.max(1e-12));
    let mut chosen = Vec::new();
    let mut used = vec![false; candidates.len()];
    for _ in 0..count {
        let best = (0..candidates.len())
            .filter(|&i| !used[i])
            .map(|i| (i, (&m + &candidates[i]).determinant()))
            .filter(|(_, d)| d.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { break };
        used[i] = true;
        m += &candidates[i];
        chosen.push(i);
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two columns equal up to scale: one null combination, named with both, and an infinite condition number.
    #[test]
    fn a_repeated_column_is_one_null_combination() {
        let j = DMatrix::from_row_slice(3, 3, &[1.0, 2.0, 0.0, 2.0, 4.0, 1.0, 0.0, 0.0, 3.0]);
        let id = analyse_jacobian(j, &["a", "b", "c"]);
        assert_eq!(id.unidentifiable.len(), 1);
        let names: Vec<&str> = id.unidentifiable[0]
            .iter()
            .map(|(n, _)| n.as_str())
            .collect();
        assert_eq!(names, ["a", "b"]);
        assert!(id.condition_number.is_infinite());
    }

    /// A straight line's fit by least squares: the exact line and its covariance's closed form.
    #[test]
    fn minimise_fits_a_line_and_its_covariance() {
        let xs = [0.0, 1.0, 2.0, 3.0];
        let ys = [1.0, 3.1, 4.9, 7.0];
        let residuals = |p: &[f64]| {
            Some(DVector::from_iterator(
                4,
                xs.iter().zip(ys).map(|(x, y)| p[0] + p[1] * x - y),
            ))
        };
        let jacobian = |_: &[f64]| DMatrix::from_fn(4, 2, |i, c| if c == 0 { 1.0 } else { xs[i] });
        let p = minimise(&[0.0, 0.0], &residuals, &jacobian).expect("fits");
        // By hand: slope Σ(x−x̄)(y−ȳ) / Σ(x−x̄)² = 9.9 / 5, intercept ȳ − slope·x̄ = 4 − 2.97.
        assert!(
            (p[1] - 1.98).abs() < 1e-9 && (p[0] - 1.03).abs() < 1e-9,
            "{p:?}"
        );
        let r = residuals(&p).expect("finite");
        let cov = covariance(&jacobian(&p), &r).expect("invertible");
        let sigma2 = r.norm_squared() / 2.0;
        assert!((cov[(1, 1)] - sigma2 / 5.0).abs() < 1e-12);
    }
}
