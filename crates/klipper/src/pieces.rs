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

/// Radius (mm) of the circle about a polar centre inside which a move turns the bed in place; also the most the
/// nozzle leaves the intended path there.
pub const TURN_RADIUS: f64 = 0.005;
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

/// The polar centre, and the bed's angle when a move starts on it (where the last move left the bed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Centre {
    pub at: [f64; 2],
    pub bed_angle: f64,
}

/// Waypoints of the move `start → end` (the end last). `cuts(a, b)` gives the fractions of `a → b` at which its
/// motor limits change (the span boundaries); `centre` is set for an ideal polar machine.
pub fn waypoints(
    start: Vec3,
    end: Vec3,
    centre: Option<Centre>,
    cuts: &dyn Fn(Vec3, Vec3) -> Vec<f64>,
) -> Vec<Waypoint> {
    let mut points = Vec::new();
    match centre.and_then(|c| turn_in_place(start, end, c)) {
        Some(turn) => {
            push_line(
                &mut points,
                start,
                turn.entry,
                (0.0, turn.entry_fraction),
                cuts,
            );
            points.extend(turn.arc);
            points.push(Waypoint {
                x: turn.exit[0],
                y: turn.exit[1],
                fraction: turn.exit_fraction,
            });
            if turn.exit_fraction < 1.0 {
                push_line(&mut points, turn.exit, end, (turn.exit_fraction, 1.0), cuts);
            }
        }
        None => push_line(&mut points, start, end, (0.0, 1.0), cuts),
    }
    points
}

/// The straight piece `a → b` (fractions `span` of the original move), cut where its limits change.
fn push_line(
    points: &mut Vec<Waypoint>,
    a: Vec3,
    b: Vec3,
    span: (f64, f64),
    cuts: &dyn Fn(Vec3, Vec3) -> Vec<f64>,
) {
    let at = |f: f64| Waypoint {
        x: a[0] + (b[0] - a[0]) * f,
        y: a[1] + (b[1] - a[1]) * f,
        fraction: span.0 + (span.1 - span.0) * f,
    };
    if a != b {
        points.extend(
            cuts(a, b)
                .into_iter()
                .filter(|f| *f > 0.0 && *f < 1.0)
                .map(at),
        );
    }
    points.push(at(1.0));
}

/// The part of a move that turns the bed in place: entry and exit on the turning circle and the arc between.
struct Turn {
    entry: Vec3,
    entry_fraction: f64,
    arc: Vec<Waypoint>,
    exit: Vec3,
    exit_fraction: f64,
}

/// Where the move enters and leaves the turning circle, if it needs the bed to turn in place there: it passes
/// inside the circle (through the centre or near it), or starts on the centre heading away from where the bed
/// stands. A move that ends on the centre needs no turn (it arrives along a ray, the bed standing still).
fn turn_in_place(start: Vec3, end: Vec3, centre: Centre) -> Option<Turn> {
    let [cx, cy] = centre.at;
    let (sx, sy) = (start[0] - cx, start[1] - cy);
    let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
    let length2 = dx * dx + dy * dy;
    if length2 == 0.0 {
        return None;
    }
    let r = TURN_RADIUS;
    // |s + t·d|² = r²: t² |d|² + 2 t (s·d) + |s|² − r² = 0.
    let b = sx * dx + sy * dy;
    let c = sx * sx + sy * sy - r * r;
    let disc = b * b - length2 * c;
    if disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let (t1, t2) = ((-b - root) / length2, (-b + root) / length2);
    let on_centre = sx == 0.0 && sy == 0.0;
    if on_centre {
        // Out along the bed's current ray to the circle, around to the move's direction, then on.
        let heading = dy.atan2(dx);
        let exit_t = t2.min(1.0);
        let entry = [
            cx + r * centre.bed_angle.cos(),
            cy + r * centre.bed_angle.sin(),
            start[2],
        ];
        let turn = angle_between(centre.bed_angle, heading);
        if turn.abs() < 1e-12 {
            return None;
        }
        let exit = point(start, end, exit_t);
        let arc = arc(centre.at, centre.bed_angle, turn, (0.0, 0.0));
        return Some(Turn {
            entry,
            entry_fraction: 0.0,
            arc,
            exit,
            exit_fraction: exit_t,
        });
    }
    // Only a move that passes through the circle (both ends outside it) turns the bed there; one that ends inside
    // it arrives along a nearly radial line and is slowed by its spans.
    if t1 <= 0.0 || t2 >= 1.0 {
        return None;
    }
    let (entry, exit) = (point(start, end, t1), point(start, end, t2));
    let from = (entry[1] - cy).atan2(entry[0] - cx);
    let to = (exit[1] - cy).atan2(exit[0] - cx);
    // The short way round: the minor arc lies on the side the line passes (through the exact centre, a half turn
    // counter-clockwise).
    let turn = angle_between(from, to);
    let arc = arc(centre.at, from, turn, (t1, t2));
    Some(Turn {
        entry,
        entry_fraction: t1,
        arc,
        exit,
        exit_fraction: t2,
    })
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

fn point(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// Chord ends along the turning circle from angle `from` turning by `turn`, the last one excluded (the caller
/// adds the exit); fractions spread over `span`.
fn arc(centre: [f64; 2], from: f64, turn: f64, span: (f64, f64)) -> Vec<Waypoint> {
    let chords = ((turn.abs() / std::f64::consts::PI) * TURN_CHORDS as f64)
        .ceil()
        .max(1.0) as usize;
    (1..chords)
        .map(|i| {
            let f = i as f64 / chords as f64;
            let angle = from + turn * f;
            Waypoint {
                x: centre[0] + TURN_RADIUS * angle.cos(),
                y: centre[1] + TURN_RADIUS * angle.sin(),
                fraction: span.0 + (span.1 - span.0) * f,
            }
        })
        .collect()
}
