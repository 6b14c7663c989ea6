//! Closed-form upper bound on the chord error of a polar piece: the nozzle path when radius and angle move
//! linearly between two points of a straight Cartesian line.
//!
//! With `r(u) = r0 + u·Δr`, `θ(u) = θ0 + u·Δθ` the nozzle is `q(u) = r(u)·e_r(θ(u))` and
//! `q'' = 2·Δr·Δθ·e_θ − r·Δθ²·e_r`. Its offset from the chord's line, `g(u) = n·(q(u) − p0)` (`n` the
//! line's unit normal), vanishes at both ends, so `|g| ≤ max|g''| / 8`. In the radial/tangential frame of
//! the point, `q'' = v = (−r·Δθ², 2·Δr·Δθ)`, linear in `u`; that frame turns by at most `φ = |Δθ|/2` from
//! the middle one, so with `n_m` the normal seen from the middle frame
//! `max|g''| ≤ max_{u=0,1} |n_m·v| + sin φ · max_{u=0,1} |n_m⊥·v|` (the second term vanishes for a chord
//! across the radius, where the bound is the exact sagitta to first order).
//! While `|q''|` stays small against the chord length the nozzle moves monotonically along the line, so its
//! distance from the segment is `|g|` itself: the bound is a guarantee, not an estimate, and costs no
//! trigonometry.

use crate::axes::PolarAxes;

/// Added to every bound for floating-point error in the end points (mm).
const ROUNDING_SLACK: f64 = 1e-10;

/// Upper bound (mm) on the XY distance between the straight segment `p0 → p1` and the nozzle when the polar
/// axes move linearly from `a0` to `a1` (the axes of `p0` and `p1`); `None` where the bound does not apply
/// (a piece ending near the centre, a half-turn piece, or one curving too much to stay monotone).
pub fn polar_line_bound(
    polar: PolarAxes,
    (p0, a0): ([f64; 2], [f64; 2]),
    (p1, a1): ([f64; 2], [f64; 2]),
) -> Option<f64> {
    let (ri, ti) = (polar.radius, 1 - polar.radius);
    let (r0, r1) = (a0[ri], a1[ri]);
    let (dr, dt) = (r1 - r0, a1[ti] - a0[ti]);
    let chord = [p1[0] - p0[0], p1[1] - p0[1]];
    let length2 = chord[0] * chord[0] + chord[1] * chord[1];
    if !(r0 > 0.0 && r1 > 0.0 && length2 > 0.0) {
        return None;
    }
    // Radial direction at the middle angle, unnormalised: (p0 − c)/r0 + (p1 − c)/r1, times r0·r1.
    let c = polar.centre;
    let w = [
        (p0[0] - c[0]) * r1 + (p1[0] - c[0]) * r0,
        (p0[1] - c[1]) * r1 + (p1[1] - c[1]) * r0,
    ];
    let w2 = w[0] * w[0] + w[1] * w[1];
    if w2 < (r0 * r1) * (r0 * r1) {
        // More than a third of a turn: far outside the regime this bound is for.
        return None;
    }
    // The chord's normal in the middle frame (radial, tangential components), scaled by |chord|·|w|.
    let n = [-chord[1], chord[0]];
    let nm = [n[0] * w[0] + n[1] * w[1], n[1] * w[0] - n[0] * w[1]];
    let tangential = 2.0 * dr * dt;
    let v = |r: f64| [-r * dt * dt, tangential];
    // n·q'' = cos φ·(n_m·v) ± sin φ·(n_m⊥·v) with |φ| ≤ |Δθ|/2 the turn from the middle frame; both dot
    // products are linear in u, so their largest magnitudes are at the ends.
    let along = |v: [f64; 2]| (nm[0] * v[0] + nm[1] * v[1]).abs();
    let across = |v: [f64; 2]| (nm[0] * v[1] - nm[1] * v[0]).abs();
    let (v0, v1) = (v(r0), v(r1));
    // |q''| ≤ |v|: small against the chord, the nozzle moves monotonically along it.
    let norm2 = |v: [f64; 2]| v[0] * v[0] + v[1] * v[1];
    if 2.25 * norm2(v0).max(norm2(v1)) >= length2 {
        return None;
    }
    let g2 = along(v0).max(along(v1)) + across(v0).max(across(v1)) * dt.abs() / 2.0;
    Some(g2 / (8.0 * (length2 * w2).sqrt()) + ROUNDING_SLACK)
}

#[cfg(test)]
mod tests {
    use super::*;

    const POLAR: PolarAxes = PolarAxes {
        centre: [0.0, 0.0],
        radius: 0,
    };

    fn axes(p: [f64; 2], near: f64) -> [f64; 2] {
        let mut t = p[1].atan2(p[0]);
        while t - near > std::f64::consts::PI {
            t -= std::f64::consts::TAU;
        }
        [p[0].hypot(p[1]), t]
    }

    /// Distance from the polar-linear path to the segment, sampled densely.
    fn sampled(p0: [f64; 2], p1: [f64; 2]) -> f64 {
        let (a0, a1) = (axes(p0, 0.0), axes(p1, axes(p0, 0.0)[1]));
        (0..=2000)
            .map(|i| {
                let u = f64::from(i) / 2000.0;
                let (r, t) = (a0[0] + (a1[0] - a0[0]) * u, a0[1] + (a1[1] - a0[1]) * u);
                crate::path::distance_to_segment([r * t.cos(), r * t.sin()], p0, p1)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn tangential_piece_is_the_sagitta() {
        // A chord of length L perpendicular to the radius at r: the path bulges by ≈ L²/(8r).
        let (p0, p1) = ([100.0, -1.0], [100.0, 1.0]);
        let bound = polar_line_bound(POLAR, (p0, axes(p0, 0.0)), (p1, axes(p1, 0.0)));
        let exact = sampled(p0, p1);
        let bound = bound.unwrap_or(f64::INFINITY);
        assert!(
            bound >= exact && bound <= exact * 1.02,
            "{bound} vs {exact}"
        );
    }

    #[test]
    fn radial_piece_has_no_error() {
        let (p0, p1) = ([10.0, 10.0], [20.0, 20.0]);
        let bound = polar_line_bound(POLAR, (p0, axes(p0, 0.0)), (p1, axes(p1, 0.0)));
        assert!(bound.is_some_and(|b| b < 1e-9));
    }

    #[test]
    fn bounds_every_direction_and_distance() {
        // Pieces at all directions and distances from the centre: the bound holds and is rarely loose.
        let mut worst_ratio = 0.0f64;
        for k in 0..36 {
            let dir = f64::from(k) * 10f64.to_radians();
            for (r, len) in [(3.0, 0.3), (20.0, 1.0), (100.0, 5.0), (1.0, 0.05)] {
                let p0 = [r, 0.5];
                let p1 = [p0[0] + len * dir.cos(), p0[1] + len * dir.sin()];
                let a0 = axes(p0, 0.0);
                let a1 = axes(p1, a0[1]);
                let Some(bound) = polar_line_bound(POLAR, (p0, a0), (p1, a1)) else {
                    continue;
                };
                let exact = sampled(p0, p1);
                assert!(bound >= exact, "dir {k} r {r}: {bound} < {exact}");
                if exact > 1e-6 {
                    worst_ratio = worst_ratio.max(bound / exact);
                }
            }
        }
        assert!(worst_ratio < 1.5, "{worst_ratio}");
    }
}
