//! How the plug-in's G-code move transform cuts a move so Klipper slows only where a motor limit binds.
//!
//! Klipper's `check_move` can only cap a whole move. Cut at the boundaries of the spans the planner's motor limits
//! give (`motion::kinematic_limits::split`), each piece gets its own cap, and the pieces meet in straight
//! (full-speed) junctions. A polar move that passes through the centre, or starts there in another direction than
//! the bed stands, needs the bed to turn in place, which a toolhead move cannot say: the piece inside a circle of
//! [`TURN_RADIUS`] about the centre is replaced by an arc along that circle. The arm moves less than half a step
//! there, so what the machine does is stop, turn the bed, go on; the nozzle leaves the path by at most the
//! radius, and the arc's pieces are capped like any other (the bed at its angular limits).

use kinematics::Vec3;

/// Chords of a half turn along the turning circle.
const TURN_CHORDS: usize = 12;

/// A point the transform moves to: XY, and how far along the original move it stands for (0..=1), which Z and E
/// follow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    pub x: f64,
    pub y: f64,
    pub fraction: f64,
}

/// The polar centre, the radius within which a path meets it (the kinematics' centre tolerance: the circle the
/// bed turns in place on, and the most the nozzle leaves the path there), and the bed's angle when a move starts
/// on it (where the last move left the bed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Centre {
    pub at: [f64; 2],
    pub radius: f64,
    pub bed_angle: f64,
}

/// Where a move's span boundaries lie: `cuts(a, b)` gives the fractions of `a → b` at which its motor limits change.
pub type Cuts<'a> = &'a dyn Fn(Vec3, Vec3) -> Vec<f64>;

/// Waypoints of the move `start → end` (the end last, exactly `end` unless it is snapped onto the centre); `centre`
/// is set for a polar machine whose bed has one; `cuts`, when set, cuts the straight pieces at their span
/// boundaries (without it only the centre shapes the move).
pub fn waypoints(
    start: Vec3,
    end: Vec3,
    centre: Option<Centre>,
    cuts: Option<Cuts>,
) -> Vec<Waypoint> {
    let end = centre.map_or(end, |c| snapped_onto(c, end));
    let mut points = Vec::new();
    let Some((c, route)) = centre.and_then(|c| Some((c, through_centre(start, end, c)?))) else {
        push_line(&mut points, start, end, (0.0, 1.0), cuts);
        return points;
    };
    let at_centre = [c.at[0], c.at[1], 0.0];
    if route.arrives {
        push_line(&mut points, start, at_centre, (0.0, route.fraction), cuts);
    }
    points.extend(route.turn);
    if end[0] != c.at[0] || end[1] != c.at[1] {
        push_line(&mut points, at_centre, end, (route.fraction, 1.0), cuts);
    } else if points.last().is_none_or(|p| p.fraction < 1.0) {
        // From within the circle onto the centre: the whole move is that one radial piece.
        points.push(Waypoint {
            x: c.at[0],
            y: c.at[1],
            fraction: 1.0,
        });
    }
    points
}

/// `end`, or the centre when `end` lies within its radius: the planner's snapping, so the move arrives along a ray.
fn snapped_onto(centre: Centre, end: Vec3) -> Vec3 {
    let [cx, cy] = centre.at;
    let (dx, dy) = (end[0] - cx, end[1] - cy);
    if dx * dx + dy * dy < centre.radius * centre.radius {
        [cx, cy, end[2]]
    } else {
        end
    }
}

/// The straight piece `a → b` (fractions `span` of the original move), cut where its limits change; it ends on `b`
/// exactly.
fn push_line(points: &mut Vec<Waypoint>, a: Vec3, b: Vec3, span: (f64, f64), cuts: Option<Cuts>) {
    let at = |f: f64| Waypoint {
        x: a[0] + (b[0] - a[0]) * f,
        y: a[1] + (b[1] - a[1]) * f,
        fraction: span.0 + (span.1 - span.0) * f,
    };
    if let Some(cuts) = cuts.filter(|_| a != b) {
        points.extend(
            cuts(a, b)
                .into_iter()
                .filter(|f| *f > 0.0 && *f < 1.0)
                .map(at),
        );
    }
    points.push(Waypoint {
        x: b[0],
        y: b[1],
        fraction: span.1,
    });
}

/// A move routed through the centre itself: straight in (when it starts outside the circle), the bed's turn in
/// place there, straight out.
struct Route {
    /// It starts outside the circle and arrives at the centre along a ray.
    arrives: bool,
    /// The fraction of the move the centre stands for (where it passes closest).
    fraction: f64,
    /// Out along the ray the bed stands on to the circle, around it to the ray the move leaves along, back in to
    /// the centre; empty when the two rays are the same.
    turn: Vec<Waypoint>,
}

/// How the move `start → end` meets the centre, if it does: it passes within the circle, or starts within it in
/// another direction than the bed stands (a move that ends on the centre from outside arrives along a ray, and needs
/// no route). Every piece of the route is radial or on the circle, so the bed's angle is defined along all of them
/// and it turns only on the circle, where its motor limits cap the speed.
fn through_centre(start: Vec3, end: Vec3, centre: Centre) -> Option<Route> {
    let [cx, cy] = centre.at;
    let (sx, sy) = (start[0] - cx, start[1] - cy);
    let (ex, ey) = (end[0] - cx, end[1] - cy);
    let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
    let length2 = dx * dx + dy * dy;
    let r = centre.radius;
    let starts_inside = sx * sx + sy * sy < r * r;
    let ends_on_centre = ex == 0.0 && ey == 0.0;
    if length2 == 0.0 || (ends_on_centre && !starts_inside) {
        return None;
    }
    let fraction = if starts_inside {
        0.0
    } else {
        let t = (-(sx * dx + sy * dy) / length2).clamp(0.0, 1.0);
        let (px, py) = (sx + t * dx, sy + t * dy);
        if px * px + py * py >= r * r {
            return None;
        }
        t
    };
    let ray_in = if starts_inside {
        centre.bed_angle
    } else {
        sy.atan2(sx)
    };
    let turn = if ends_on_centre {
        Vec::new()
    } else {
        turn_at_centre(centre, ray_in, ey.atan2(ex), fraction)
    };
    Some(Route {
        arrives: !starts_inside,
        fraction,
        turn,
    })
}

/// The bed's turn in place from ray `from` to ray `to`: out to the circle, along it, back to the centre (all at
/// `fraction` of the move); nothing when the rays agree.
fn turn_at_centre(centre: Centre, from: f64, to: f64, fraction: f64) -> Vec<Waypoint> {
    let turn = angle_between(from, to);
    if turn.abs() < 1e-12 {
        return Vec::new();
    }
    let on_circle = |angle: f64| Waypoint {
        x: centre.at[0] + centre.radius * angle.cos(),
        y: centre.at[1] + centre.radius * angle.sin(),
        fraction,
    };
    let chords = ((turn.abs() / std::f64::consts::PI) * TURN_CHORDS as f64)
        .ceil()
        .max(1.0) as usize;
    let mut points: Vec<Waypoint> = (0..=chords)
        .map(|i| on_circle(from + turn * (i as f64 / chords as f64)))
        .collect();
    points.push(Waypoint {
        x: centre.at[0],
        y: centre.at[1],
        fraction,
    });
    points
}

/// `b − a` wrapped into (−π, π].
fn angle_between(a: f64, b: f64) -> f64 {
    let mut d = (b - a) % std::f64::consts::TAU;
    if d > std::f64::consts::PI {
        d -= std::f64::consts::TAU;
    } else if d <= -std::f64::consts::PI {
        d += std::f64::consts::TAU;
    }
    d
}
