//! The move transform's routes through the C interface (`jointspace_move_waypoints`), against geometry written
//! here: near the polar centre every piece is radial through the centre or keeps away from it (the bed's angle is
//! defined along all of it), the nozzle never leaves the G-code line by more than the centre's tolerance, the route
//! ends on the line's end (or on the centre, when the end lies within the tolerance), and a line that cannot be
//! made is refused whole, before any piece is handed out, with a reason in the owner's terms.

use proptest::prelude::*;

use crate::solvers::{Owned, machine, waypoints_with_reason};

/// The bundled polar example: arm 0.0125 mm a step, so the centre's tolerance is 0.005 mm; the arm reaches 150 mm.
const TOLERANCE: f64 = 0.005;
const REACH: f64 = 150.0;

/// (rc, points as (x, y, fraction), reason) of the line at Z1, 100 mm/s, 3000 mm/s².
fn route(
    m: &Owned,
    start: [f64; 2],
    end: [f64; 2],
    bed_angle: f64,
    cut_spans: bool,
) -> (i32, Vec<[f64; 3]>, String) {
    let ends = [[start[0], start[1], 1.0], [end[0], end[1], 1.0]];
    waypoints_with_reason(m, ends, [100.0, 3000.0], bed_angle, cut_spans)
}

/// Distance from the origin to the segment a → b.
fn distance_to_centre(a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    let t = if length2 == 0.0 {
        0.0
    } else {
        (-(a[0] * dx + a[1] * dy) / length2).clamp(0.0, 1.0)
    };
    (a[0] + t * dx).hypot(a[1] + t * dy)
}

/// Distance from p to the segment a → b.
fn distance_to_line(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    distance_to_centre([a[0] - p[0], a[1] - p[1]], [b[0] - p[0], b[1] - p[1]])
}

/// The piece a → b lies on a line through the centre (within the solvers' 1e-9 mm) and does not cross it.
fn along_a_ray(a: [f64; 2], b: [f64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length = dx.hypot(dy);
    if length == 0.0 {
        return true;
    }
    let miss = (a[0] * dy - a[1] * dx).abs() / length;
    let crosses = a[0] * dx + a[1] * dy < 0.0 && b[0] * dx + b[1] * dy > 0.0;
    miss <= 1e-9 && (!crosses || a.hypot0() <= 1e-9 || b.hypot0() <= 1e-9)
}

trait Norm {
    fn hypot0(&self) -> f64;
}

impl Norm for [f64; 2] {
    fn hypot0(&self) -> f64 {
        self[0].hypot(self[1])
    }
}

/// A point at `r` mm from the centre in direction `deg`, plus `side` mm at right angles.
fn polar_point(r: f64, deg: f64, side: f64) -> [f64; 2] {
    let (s, c) = deg.to_radians().sin_cos();
    [r * c - side * s, r * s + side * c]
}

/// `bed_angle` is where the last move left the bed; off the centre the transform tracks it from the start point.
fn check_route(m: &Owned, start: [f64; 2], end: [f64; 2], bed_angle: f64, cut_spans: bool) {
    let bed_angle = if start == [0.0, 0.0] {
        bed_angle
    } else {
        start[1].atan2(start[0])
    };
    let (rc, points, reason) = route(m, start, end, bed_angle, cut_spans);
    assert!(rc >= 1, "{start:?} → {end:?}: refused ({rc}: {reason})");
    let last = points[points.len() - 1];
    let snapped = end[0].hypot(end[1]) < TOLERANCE;
    let expected_end = if snapped { [0.0, 0.0] } else { end };
    assert_eq!(
        [last[0], last[1]],
        expected_end,
        "{start:?} → {end:?}: ends elsewhere"
    );
    assert_eq!(last[2], 1.0);
    let mut from = start;
    let mut fraction = 0.0;
    for p in &points {
        let to = [p[0], p[1]];
        assert!(
            p[2] >= fraction && p[2] <= 1.0,
            "fractions go back: {points:?}"
        );
        fraction = p[2];
        assert!(
            distance_to_line(to, start, end) <= TOLERANCE * (1.0 + 1e-9),
            "{start:?} → {end:?}: {to:?} is {} mm off the line",
            distance_to_line(to, start, end)
        );
        // The bed's angle is defined along the piece: it stays clear of the centre, or runs along a ray without
        // crossing the centre (an end on it, or both ends on one side).
        assert!(
            distance_to_centre(from, to) >= TOLERANCE * 0.99 || along_a_ray(from, to),
            "{start:?} → {end:?}: the piece {from:?} → {to:?} passes {} mm from the centre",
            distance_to_centre(from, to)
        );
        from = to;
    }
}

const OFFSETS: [f64; 8] = [0.0, 1e-15, 1e-9, 1e-6, 1e-3, 4.9e-3, 0.1, 1.0];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Lines that end at, start at, pass through and beside the centre, from any direction.
    #[test]
    fn routes_near_the_centre_keep_the_bed_defined(
        deg in 0.0..360.0f64,
        turn in 1.0..359.0f64,
        offset in prop::sample::select(OFFSETS.to_vec()),
        length in 0.01..140.0f64,
        bed_angle in -3.2..3.2f64,
        cut_spans in any::<bool>(),
    ) {
        let m = Owned(machine("polar", "max_angular_velocity: 5\nmax_angular_accel: 200"));
        let far = polar_point(length, deg, 0.0);
        let near = polar_point(0.0, deg, offset);
        let away = polar_point(length, deg + turn, 0.0);
        check_route(&m, far, near, bed_angle, cut_spans);
        // Where the toolhead is after that line: on the centre when the end was snapped onto it.
        let arrived = if near[0].hypot(near[1]) < TOLERANCE { [0.0, 0.0] } else { near };
        check_route(&m, arrived, away, bed_angle, cut_spans);
        check_route(&m, far, polar_point(-length, deg, offset), bed_angle, cut_spans);
    }

    /// A target beyond the arm's reach is refused whole, with how far beyond; one within it is not.
    #[test]
    fn a_refused_route_is_refused_whole(
        deg in 0.0..360.0f64,
        start_r in 0.0..REACH,
        start_deg in 0.0..360.0f64,
        r in 0.0..2.0 * REACH,
    ) {
        prop_assume!((r - REACH).abs() > 1e-6);
        let m = Owned(machine("polar", "max_angular_velocity: 5"));
        let (rc, points, reason) = route(&m, polar_point(start_r, start_deg, 0.0), polar_point(r, deg, 0.0), 0.0, true);
        if r > REACH {
            prop_assert_eq!(rc, -2, "{:?}", points);
            prop_assert!(reason.contains("beyond the arm's reach of 150 mm"), "{}", reason);
            let beyond: f64 = reason.split(' ').next().and_then(|w| w.parse().ok()).unwrap_or(f64::NAN);
            prop_assert!((beyond - (r - REACH)).abs() < 2e-3, "{} for {} mm beyond", reason, r - REACH);
        } else {
            prop_assert!(rc >= 1, "{}: {}", rc, reason);
        }
    }
}
