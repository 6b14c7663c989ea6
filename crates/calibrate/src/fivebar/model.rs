//! The five-bar's identification model: the nozzle from the two motor readings as the intersection of the distal
//! circles, and its analytic derivative with respect to the ten parameters.
//!
//! Side `k`: `θ_k = m_k − zero_k`, elbow `E_k = B_k + P_k (cos θ_k, sin θ_k)`, nozzle `N` with `|N − E_k| = D_k`
//! on the configured side of the line `E_L → E_R` (the distal turn). Derivative: differentiating
//! `|N − E_k|² = D_k²` gives `(N − E_k)·dN = (N − E_k)·dE_k + D_k dD_k`, one row per side, solved for `dN` by
//! the 2×2 matrix of the distal vectors (singular where the distal links are in line, which the pattern avoids).

use serde::{Deserialize, Serialize};

/// Parameter names in vector order: the printer.cfg keys, left side then right (zeros in the file in degrees).
pub const PARAM_NAMES: [&str; 10] = [
    "left_base_x",
    "left_base_y",
    "left_proximal_length",
    "left_distal_length",
    "left_zero",
    "right_base_x",
    "right_base_y",
    "right_proximal_length",
    "right_distal_length",
    "right_zero",
];

/// One side's identified quantities (mm, rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ArmGeometry {
    pub base: [f64; 2],
    pub proximal: f64,
    pub distal: f64,
    /// The motor's reading when the proximal link points along +X (rad).
    pub zero: f64,
}

/// A five-bar's geometry as the fit sees it: both sides, and the distal turn (not fitted: an assembly choice).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FivebarGeometry {
    pub left: ArmGeometry,
    pub right: ArmGeometry,
    /// `+1` when the turn left elbow → nozzle → right elbow is counter-clockwise, `−1` clockwise.
    pub distal_turn_sign: f64,
}

impl From<&kinematics::FivebarArm> for ArmGeometry {
    fn from(a: &kinematics::FivebarArm) -> Self {
        ArmGeometry {
            base: a.base,
            proximal: a.proximal,
            distal: a.distal,
            zero: a.zero,
        }
    }
}

impl From<&kinematics::FivebarParams> for FivebarGeometry {
    /// A configured machine's nominal geometry, in the identification's terms.
    fn from(p: &kinematics::FivebarParams) -> Self {
        FivebarGeometry {
            left: ArmGeometry::from(&p.left),
            right: ArmGeometry::from(&p.right),
            distal_turn_sign: p.distal_turn.sign(),
        }
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

impl ArmGeometry {
    fn to_array(self) -> [f64; 5] {
        [
            self.base[0],
            self.base[1],
            self.proximal,
            self.distal,
            self.zero,
        ]
    }

    fn from_array(v: [f64; 5]) -> Self {
        ArmGeometry {
            base: [v[0], v[1]],
            proximal: v[2],
            distal: v[3],
            zero: v[4],
        }
    }

    /// The proximal link's direction at motor reading `m`.
    fn direction(&self, m: f64) -> [f64; 2] {
        let theta = m - self.zero;
        [theta.cos(), theta.sin()]
    }

    fn elbow(&self, m: f64) -> [f64; 2] {
        let u = self.direction(m);
        [
            self.base[0] + self.proximal * u[0],
            self.base[1] + self.proximal * u[1],
        ]
    }

    /// The right-hand side of this side's row for each of its parameters, `d` the distal vector `N − E`:
    /// `d·∂E/∂(bx, by, P, zero)` and `D` for the distal length.
    fn row(&self, m: f64, d: [f64; 2]) -> [f64; 5] {
        let u = self.direction(m);
        let across = [-u[1], u[0]];
        [
            d[0],
            d[1],
            dot(d, u),
            self.distal,
            -self.proximal * dot(d, across),
        ]
    }
}

impl FivebarGeometry {
    pub fn to_array(&self) -> [f64; 10] {
        let (l, r) = (self.left.to_array(), self.right.to_array());
        std::array::from_fn(|k| if k < 5 { l[k] } else { r[k - 5] })
    }

    /// The geometry with the parameters `v` ([`PARAM_NAMES`] order) and this one's distal turn.
    pub fn with_array(&self, v: &[f64]) -> Self {
        FivebarGeometry {
            left: ArmGeometry::from_array(std::array::from_fn(|k| v[k])),
            right: ArmGeometry::from_array(std::array::from_fn(|k| v[k + 5])),
            distal_turn_sign: self.distal_turn_sign,
        }
    }

    /// The elbows at motor readings `(m_l, m_r)` (rad).
    pub fn elbows(&self, m_l: f64, m_r: f64) -> [[f64; 2]; 2] {
        [self.left.elbow(m_l), self.right.elbow(m_r)]
    }

    /// Nozzle XY (mm) at motor readings `(m_l, m_r)` (rad); None where the distal links cannot meet.
    pub fn forward(&self, m_l: f64, m_r: f64) -> Option<[f64; 2]> {
        let [el, er] = self.elbows(m_l, m_r);
        let (dl, dr) = (self.left.distal, self.right.distal);
        let e = sub(er, el)[0].hypot(sub(er, el)[1]);
        if !(e <= dl + dr && e >= (dl - dr).abs()) {
            return None;
        }
        self.forward_lenient(m_l, m_r)
    }

    /// [`Self::forward`] where the distal links would not quite meet: the point on the elbows' line where they
    /// come closest (continuous, so a fit's trial step there is refused by its residuals, not by a failure).
    pub fn forward_lenient(&self, m_l: f64, m_r: f64) -> Option<[f64; 2]> {
        let [el, er] = self.elbows(m_l, m_r);
        let (dl, dr) = (self.left.distal, self.right.distal);
        let w = sub(er, el);
        let e = w[0].hypot(w[1]);
        if e.is_nan() || e <= 0.0 {
            return None;
        }
        let a = (dl * dl - dr * dr + e * e) / (2.0 * e);
        let h = (dl * dl - a * a).max(0.0).sqrt();
        let unit = [w[0] / e, w[1] / e];
        // A clockwise turn E_L → N → E_R puts N counter-clockwise of the E_L → E_R line.
        let s = -self.distal_turn_sign;
        let n = [
            el[0] + a * unit[0] - s * h * unit[1],
            el[1] + a * unit[1] + s * h * unit[0],
        ];
        n.iter().all(|v| v.is_finite()).then_some(n)
    }

    /// ∂(x, y)/∂(parameters) at motor readings `(m_l, m_r)`: rows x and y, columns in [`PARAM_NAMES`] order;
    /// None where the nozzle is not defined or the distal links are in line.
    pub fn parameter_jacobian(&self, m_l: f64, m_r: f64) -> Option<[[f64; 10]; 2]> {
        let n = self.forward(m_l, m_r)?;
        let [el, er] = self.elbows(m_l, m_r);
        let (d_l, d_r) = (sub(n, el), sub(n, er));
        let det = cross(d_l, d_r);
        if det == 0.0 {
            return None;
        }
        // Columns of the inverse of [d_lᵀ; d_rᵀ]: what a unit change of each side's row does to N.
        let left_unit = [d_r[1] / det, -d_r[0] / det];
        let right_unit = [-d_l[1] / det, d_l[0] / det];
        let (rl, rr) = (self.left.row(m_l, d_l), self.right.row(m_r, d_r));
        let mut rows = [[0.0; 10]; 2];
        for (axis, row) in rows.iter_mut().enumerate() {
            for k in 0..5 {
                row[k] = left_unit[axis] * rl[k];
                row[k + 5] = right_unit[axis] * rr[k];
            }
        }
        Some(rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> FivebarGeometry {
        let arm = |x: f64| ArmGeometry {
            base: [x, -200.0],
            proximal: 150.0,
            distal: 200.0,
            zero: 0.0,
        };
        FivebarGeometry {
            left: arm(-50.0),
            right: arm(50.0),
            distal_turn_sign: -1.0,
        }
    }

    /// A symmetric pose: left arm at 150°, right at 30°: the elbows at (−50 ∓ 75√3, −125), the nozzle on the axis
    /// at the height where the distal links (200 mm) meet: y = −125 + √(200² − (50 + 75√3)²).
    #[test]
    fn the_symmetric_pose_in_closed_form() {
        let g = example();
        let n = g
            .forward(150f64.to_radians(), 30f64.to_radians())
            .expect("meets");
        let half = 50.0 + 75.0 * 3f64.sqrt();
        let y = -125.0 + (200.0f64 * 200.0 - half * half).sqrt();
        assert!(n[0].abs() < 1e-9 && (n[1] - y).abs() < 1e-9, "{n:?}");
    }

    #[test]
    fn the_jacobian_matches_central_differences() {
        let mut g = example();
        g.left.zero = 0.01;
        g.right.base[1] = -199.0;
        let (ml, mr) = (2.4, 0.9);
        let rows = g.parameter_jacobian(ml, mr).expect("regular");
        let v = g.to_array();
        for k in 0..10 {
            let h = 1e-6;
            let (mut up, mut down) = (v, v);
            up[k] += h;
            down[k] -= h;
            let (a, b) = (
                g.with_array(&up).forward(ml, mr).expect("up"),
                g.with_array(&down).forward(ml, mr).expect("down"),
            );
            for axis in 0..2 {
                let numeric = (a[axis] - b[axis]) / (2.0 * h);
                assert!(
                    (numeric - rows[axis][k]).abs() < 1e-5 * (1.0 + numeric.abs()),
                    "{}: {numeric} vs {}",
                    PARAM_NAMES[k],
                    rows[axis][k]
                );
            }
        }
    }
}
