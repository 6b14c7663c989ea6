//! The intended Cartesian path of one move (a straight line or a helical arc), parametrised by `s ∈ [0, 1]`
//! proportional to length, with the distance from a point to any sub-range of it.

/// A Cartesian toolhead path in mm: `point(s)` for `s ∈ [0, 1]`, uniform in length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Path {
    Line {
        from: [f64; 3],
        to: [f64; 3],
    },
    /// An arc in XY about `centre`, Z changing linearly with the angle (helix). The radius changes
    /// linearly from the start's to the end's (slicers round the end point), so the path ends exactly at
    /// the written end point.
    Arc {
        centre: [f64; 2],
        /// Radius at the start and at the end.
        radius: [f64; 2],
        /// Angle of the start point about the centre (rad).
        start_angle: f64,
        /// Signed swept angle (rad): negative clockwise.
        sweep: f64,
        z: [f64; 2],
    },
}

impl Path {
    /// The arc from `start` to `end` about `centre`; `turns` extra full turns; clockwise for G2.
    pub fn arc(
        start: [f64; 3],
        end: [f64; 3],
        centre: [f64; 2],
        clockwise: bool,
        turns: u32,
    ) -> Path {
        let start_angle = (start[1] - centre[1]).atan2(start[0] - centre[0]);
        let end_angle = (end[1] - centre[1]).atan2(end[0] - centre[0]);
        let radius = [
            norm([start[0] - centre[0], start[1] - centre[1]]),
            norm([end[0] - centre[0], end[1] - centre[1]]),
        ];
        let tau = std::f64::consts::TAU;
        let mut sweep = end_angle - start_angle;
        if clockwise {
            if sweep >= 0.0 {
                sweep -= tau;
            }
        } else if sweep <= 0.0 {
            sweep += tau;
        }
        let extra = f64::from(turns) * tau;
        sweep += if clockwise { -extra } else { extra };
        Path::Arc {
            centre,
            radius,
            start_angle,
            sweep,
            z: [start[2], end[2]],
        }
    }

    pub fn point(&self, s: f64) -> [f64; 3] {
        match *self {
            Path::Line { from, to } => [
                from[0] + (to[0] - from[0]) * s,
                from[1] + (to[1] - from[1]) * s,
                from[2] + (to[2] - from[2]) * s,
            ],
            Path::Arc {
                centre,
                radius,
                start_angle,
                sweep,
                z,
            } => {
                let (sin, cos) = (start_angle + sweep * s).sin_cos();
                let r = radius[0] + (radius[1] - radius[0]) * s;
                [
                    centre[0] + r * cos,
                    centre[1] + r * sin,
                    z[0] + (z[1] - z[0]) * s,
                ]
            }
        }
    }

    /// Length in XYZ (mm).
    pub fn length(&self) -> f64 {
        match *self {
            Path::Line { from, to } => {
                let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            }
            Path::Arc {
                radius, sweep, z, ..
            } => norm([mean(radius) * sweep, z[1] - z[0]]),
        }
    }

    /// Length of the path's shadow in XY (mm): zero for Z-only and extrude-only moves.
    pub fn xy_length(&self) -> f64 {
        match *self {
            Path::Line { from, to } => norm([to[0] - from[0], to[1] - from[1]]),
            Path::Arc { radius, sweep, .. } => (mean(radius) * sweep).abs(),
        }
    }

    /// Longest piece (as a fraction of the path) for which "near the piece" implies "along the piece": a
    /// quarter turn of an arc (a piece of a closed arc could otherwise start and end at the same point).
    pub fn longest_piece(&self) -> f64 {
        match *self {
            Path::Line { .. } => 1.0,
            Path::Arc { sweep, .. } => (std::f64::consts::FRAC_PI_2 / sweep.abs()).min(1.0),
        }
    }

    /// XY distance from `q` to the part of the path between `s0` and `s1` (`s0 ≤ s1`).
    pub fn distance_xy(&self, q: [f64; 2], s0: f64, s1: f64) -> f64 {
        self.part(s0, s1).distance(q)
    }

    /// The part between `s0` and `s1`, prepared for repeated distance queries.
    pub fn part(&self, s0: f64, s1: f64) -> PathPart {
        let a = self.point(s0);
        let b = self.point(s1);
        let (a, b) = ([a[0], a[1]], [b[0], b[1]]);
        match *self {
            Path::Line { .. } => PathPart::Segment { a, b },
            Path::Arc {
                centre,
                radius,
                start_angle,
                sweep,
                ..
            } => PathPart::Arc {
                centre,
                radius: [
                    radius[0] + (radius[1] - radius[0]) * s0,
                    radius[0] + (radius[1] - radius[0]) * s1,
                ],
                from: start_angle + sweep * s0,
                span: sweep * (s1 - s0),
                a,
                b,
            },
        }
    }
}

/// A piece of a path with its end points computed once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathPart {
    Segment {
        a: [f64; 2],
        b: [f64; 2],
    },
    Arc {
        centre: [f64; 2],
        radius: [f64; 2],
        from: f64,
        span: f64,
        a: [f64; 2],
        b: [f64; 2],
    },
}

impl PathPart {
    /// XY distance from `q` to this piece.
    pub fn distance(&self, q: [f64; 2]) -> f64 {
        match *self {
            PathPart::Segment { a, b } => distance_to_segment(q, a, b),
            PathPart::Arc {
                centre,
                radius,
                from,
                span,
                a,
                b,
            } => {
                let v = [q[0] - centre[0], q[1] - centre[1]];
                let rho = (v[0] * v[0] + v[1] * v[1]).sqrt();
                if rho > 0.0 && within_sweep(v, centre, from, span, a, b) {
                    (rho - radius_towards(v, radius, from, span)).abs()
                } else {
                    norm([q[0] - a[0], q[1] - a[1]]).min(norm([q[0] - b[0], q[1] - b[1]]))
                }
            }
        }
    }
}

/// Radius of a (slightly spiral) arc part in direction `v`, which lies within its sweep.
fn radius_towards(v: [f64; 2], radius: [f64; 2], from: f64, span: f64) -> f64 {
    if radius[0] == radius[1] || span == 0.0 {
        return radius[0];
    }
    let mut rel = v[1].atan2(v[0]) - from;
    if span < 0.0 {
        rel = -rel;
    }
    let fraction = (rel.rem_euclid(std::f64::consts::TAU) / span.abs()).clamp(0.0, 1.0);
    radius[0] + (radius[1] - radius[0]) * fraction
}

fn mean(pair: [f64; 2]) -> f64 {
    (pair[0] + pair[1]) / 2.0
}

/// Whether direction `v` (from the centre) lies in the angular range `from .. from + span`.
fn within_sweep(
    v: [f64; 2],
    centre: [f64; 2],
    from: f64,
    span: f64,
    a: [f64; 2],
    b: [f64; 2],
) -> bool {
    if span.abs() <= std::f64::consts::FRAC_PI_2 {
        // Short arcs: two cross products instead of an atan2 (the hot case when cutting).
        let ua = [a[0] - centre[0], a[1] - centre[1]];
        let ub = [b[0] - centre[0], b[1] - centre[1]];
        let sign = span.signum();
        let after_start = sign * (ua[0] * v[1] - ua[1] * v[0]) >= 0.0;
        let before_end = sign * (v[0] * ub[1] - v[1] * ub[0]) >= 0.0;
        let same_side = ua[0] * v[0] + ua[1] * v[1] > 0.0 || ub[0] * v[0] + ub[1] * v[1] > 0.0;
        return after_start && before_end && same_side;
    }
    let mut rel = v[1].atan2(v[0]) - from;
    if span < 0.0 {
        rel = -rel;
    }
    rel.rem_euclid(std::f64::consts::TAU) <= span.abs()
}

fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// Distance from `q` to the segment `a`–`b` in the plane.
pub fn distance_to_segment(q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let aq = [q[0] - a[0], q[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 {
        ((aq[0] * ab[0] + aq[1] * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm([aq[0] - t * ab[0], aq[1] - t * ab[1]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn quarter_arc_counter_clockwise() {
        let p = Path::arc([1.0, 0.0, 0.0], [0.0, 1.0, 2.0], [0.0, 0.0], false, 0);
        assert_abs_diff_eq!(p.xy_length(), std::f64::consts::FRAC_PI_2, epsilon = 1e-12);
        let mid = p.point(0.5);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert_abs_diff_eq!(mid[0], h, epsilon = 1e-12);
        assert_abs_diff_eq!(mid[1], h, epsilon = 1e-12);
        assert_abs_diff_eq!(mid[2], 1.0, epsilon = 1e-12);
    }

    #[test]
    fn clockwise_full_circle_when_end_equals_start() {
        let p = Path::arc([1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0], true, 0);
        assert_abs_diff_eq!(p.xy_length(), std::f64::consts::TAU, epsilon = 1e-12);
        // Clockwise from +X goes through −Y first.
        assert!(p.point(0.25)[1] < -0.99);
    }

    #[test]
    fn arc_distance_inside_and_outside_the_angular_range() {
        let p = Path::arc([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0], false, 0);
        assert_abs_diff_eq!(p.distance_xy([0.0, 2.0], 0.0, 1.0), 1.0, epsilon = 1e-12);
        // (0, −2) is outside the quarter arc: nearest is the start point (1, 0).
        assert_abs_diff_eq!(
            p.distance_xy([0.0, -2.0], 0.0, 1.0),
            5f64.sqrt(),
            epsilon = 1e-12
        );
        // Restricted to the second half, (1, 0) is far from the sub-arc.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert_abs_diff_eq!(
            p.distance_xy([1.0, 0.0], 0.5, 1.0),
            (1.0 - h).hypot(h),
            epsilon = 1e-12
        );
    }

    #[test]
    fn short_and_long_sweeps_agree_on_the_angular_range() {
        // The cross-product test (short parts) and the atan2 test (long parts) classify alike.
        let p = Path::arc([10.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 0.0], true, 0);
        for k in 0..64 {
            let angle = k as f64 * 0.1;
            let q = [12.0 * angle.cos(), 12.0 * angle.sin()];
            for (s0, s1) in [(0.0, 0.2), (0.3, 0.35), (0.1, 0.9)] {
                let part = p.part(s0, s1);
                let sweep = -std::f64::consts::TAU;
                let rel = (-(angle - sweep * s0)).rem_euclid(std::f64::consts::TAU);
                let inside = rel <= (sweep * (s1 - s0)).abs();
                let d = part.distance(q);
                assert_eq!(
                    inside,
                    (d - 2.0).abs() < 1e-9,
                    "angle {angle}, part {s0}..{s1}"
                );
            }
        }
    }

    #[test]
    fn segment_distance_clamps_to_end_points() {
        assert_abs_diff_eq!(distance_to_segment([3.0, 4.0], [0.0, 0.0], [0.0, 0.0]), 5.0);
        assert_abs_diff_eq!(distance_to_segment([0.5, 2.0], [0.0, 0.0], [1.0, 0.0]), 2.0);
        assert_abs_diff_eq!(
            distance_to_segment([-3.0, 4.0], [0.0, 0.0], [1.0, 0.0]),
            5.0
        );
    }
}
