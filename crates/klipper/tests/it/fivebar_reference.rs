//! The five-bar of `klipper/examples/fivebar.cfg` in the tests' own geometry (circle–circle intersections, written
//! here and not taken from the kinematics crate), and the audit of an MCU step stream against it: the motor counts
//! this inverse puts along the commanded path, which the stream must follow within one step per motor.

use std::f64::consts::{PI, TAU};

use crate::hosts::Step;

/// One side of the example: base joint, proximal and distal lengths, and the sign of the turn base → elbow →
/// nozzle (`+1` counter-clockwise).
#[derive(Debug)]
pub struct Side {
    pub base: [f64; 2],
    pub proximal: f64,
    pub distal: f64,
    pub turn: f64,
}

/// Left (clockwise elbow) and right (counter-clockwise), as in `klipper/examples/fivebar.cfg`.
pub const SIDES: [Side; 2] = [
    Side {
        base: [-50.0, -200.0],
        proximal: 150.0,
        distal: 200.0,
        turn: -1.0,
    },
    Side {
        base: [50.0, -200.0],
        proximal: 150.0,
        distal: 200.0,
        turn: 1.0,
    },
];
/// The distal links turn clockwise at the nozzle (left elbow → nozzle → right elbow).
pub const DISTAL_TURN: f64 = -1.0;
/// `singularity_margin`.
pub const MARGIN: f64 = 0.1;
/// 200 full steps × 32 microsteps × 80:20 per joint turn.
pub const MOTOR_STEP: f64 = TAU / 25600.0;
/// `max_joint_velocity` (rad/s).
pub const MAX_JOINT_VELOCITY: f64 = 6.0;
/// The motors in the order of [`SIDES`].
pub const MOTORS: [&str; 2] = ["stepper_left", "stepper_right"];

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// The two intersections of the circles about `c0` (radius `r0`) and `c1` (`r1`), if they meet.
pub fn circles(c0: [f64; 2], r0: f64, c1: [f64; 2], r1: f64) -> Option<[[f64; 2]; 2]> {
    let w = sub(c1, c0);
    let d = w[0].hypot(w[1]);
    if d == 0.0 || d > r0 + r1 || d < (r0 - r1).abs() {
        return None;
    }
    let a = (r0 * r0 - r1 * r1 + d * d) / (2.0 * d);
    let h = (r0 * r0 - a * a).max(0.0).sqrt();
    let (ux, uy) = (w[0] / d, w[1] / d);
    let foot = [c0[0] + a * ux, c0[1] + a * uy];
    Some([
        [foot[0] - h * uy, foot[1] + h * ux],
        [foot[0] + h * uy, foot[1] - h * ux],
    ])
}

/// Side `k`'s elbow for the nozzle at `n`: where the circle about its base (radius proximal) meets the circle
/// about the nozzle (radius distal), on the side whose turn base → elbow → nozzle has the configured sign.
pub fn elbow(side: &Side, n: [f64; 2]) -> Option<[f64; 2]> {
    let [e0, e1] = circles(side.base, side.proximal, n, side.distal)?;
    let turn = |e: [f64; 2]| cross(sub(e, side.base), sub(n, e)) * side.turn;
    Some(if turn(e0) >= turn(e1) { e0 } else { e1 })
}

/// Side `k`'s joint angle (rad) for the nozzle at `n`, the equivalent nearest `near`.
pub fn angle(side: &Side, n: [f64; 2], near: f64) -> Option<f64> {
    let e = elbow(side, n)?;
    let a = (e[1] - side.base[1]).atan2(e[0] - side.base[0]);
    Some(a + TAU * ((near - a) / TAU).round())
}

/// Both joint angles (rad) for the nozzle at `n`, each nearest `near`.
pub fn angles(n: [f64; 2], near: [f64; 2]) -> Option<[f64; 2]> {
    Some([angle(&SIDES[0], n, near[0])?, angle(&SIDES[1], n, near[1])?])
}

/// The nozzle for joint angles (rad): the distal circles' intersection turning as configured.
pub fn nozzle(angles: [f64; 2]) -> Option<[f64; 2]> {
    let e: Vec<[f64; 2]> = SIDES
        .iter()
        .zip(angles)
        .map(|(s, a)| {
            [
                s.base[0] + s.proximal * a.cos(),
                s.base[1] + s.proximal * a.sin(),
            ]
        })
        .collect();
    let [n0, n1] = circles(e[0], SIDES[0].distal, e[1], SIDES[1].distal)?;
    let turn = |n: [f64; 2]| cross(sub(n, e[0]), sub(e[1], n)) * DISTAL_TURN;
    Some(if turn(n0) >= turn(n1) { n0 } else { n1 })
}

/// |sin| of each side's angle between proximal and distal link, and the signed sine of the angle between the distal
/// links (positive in the configured assembly), at the nozzle `n`.
pub fn sines(n: [f64; 2]) -> Option<([f64; 2], f64)> {
    let el = elbow(&SIDES[0], n)?;
    let er = elbow(&SIDES[1], n)?;
    let arm =
        |s: &Side, e: [f64; 2]| cross(sub(e, s.base), sub(n, e)).abs() / (s.proximal * s.distal);
    let parallel =
        DISTAL_TURN * cross(sub(n, el), sub(er, n)) / (SIDES[0].distal * SIDES[1].distal);
    Some(([arm(&SIDES[0], el), arm(&SIDES[1], er)], parallel))
}

/// Degrees in `(-180, 180]` turned into `(lo, lo + 360]`.
pub fn degrees_from(a: f64, lo: f64) -> f64 {
    let d = a.to_degrees();
    d - 360.0 * ((d - lo) / 360.0).floor()
}

/// The motor counts (steps from `start`) the reference inverse puts at every point of the polyline `path`, sampled
/// (by bisection where needed) so that consecutive entries differ by at most one count per motor; consecutive equal
/// entries are merged.
pub fn reference_counts(path: &[[f64; 2]]) -> Vec<[i64; 2]> {
    let start = angles(path[0], [PI / 2.0; 2]).expect("the path starts at a pose");
    let mut counts = vec![[0, 0]];
    let mut last = start;
    for w in path.windows(2) {
        sample_segment(w[0], w[1], start, &mut last, &mut counts);
    }
    counts
}

fn counts_of(a: [f64; 2], start: [f64; 2]) -> [i64; 2] {
    [0, 1].map(|k| ((a[k] - start[k]) / MOTOR_STEP).round() as i64)
}

fn sample_segment(
    a: [f64; 2],
    b: [f64; 2],
    start: [f64; 2],
    last: &mut [f64; 2],
    counts: &mut Vec<[i64; 2]>,
) {
    let at = |t: f64| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    // Stack of (t0, t1) still to sample, in order; each emits its end's counts once it is fine enough.
    let mut pending = vec![(0.0f64, 1.0f64, 0u32)];
    while let Some((t0, t1, depth)) = pending.pop() {
        let p = at(t1);
        let angles = angles(p, *last).unwrap_or_else(|| panic!("({}, {}) has no pose", p[0], p[1]));
        let c = counts_of(angles, start);
        let prev = *counts.last().expect("counts start with the start");
        let jump = (c[0] - prev[0]).abs().max((c[1] - prev[1]).abs());
        if jump > 1 && depth < 60 {
            let mid = 0.5 * (t0 + t1);
            pending.push((mid, t1, depth + 1));
            pending.push((t0, mid, depth + 1));
            continue;
        }
        *last = angles;
        if c != prev {
            counts.push(c);
        }
    }
}

/// How far the stream strayed from the reference: the number of step states that matched a reference entry only
/// within one count (not exactly), of all states.
#[derive(Debug)]
pub struct PathAudit {
    pub states: usize,
    pub off_by_one: usize,
}

/// How far ahead of the last matched reference entry a step state may match (the reference advances about one entry
/// per step).
const WINDOW: usize = 256;

/// Follows the two motors' step streams (merged by clock, counted from `after`) along the reference counts: every
/// state must lie within one count of each motor of an entry at or after the last one matched, and the last state
/// must be the reference's last entry exactly.
pub fn audit_path(
    what: &str,
    steps: [&[Step]; 2],
    after: i64,
    reference: &[[i64; 2]],
) -> PathAudit {
    let mut events: Vec<(i64, usize, i64)> = Vec::new();
    for (k, stream) in steps.iter().enumerate() {
        events.extend(
            stream
                .iter()
                .filter(|s| s.0 > after)
                .map(|s| (s.0, k, if s.1 == 1 { 1 } else { -1 })),
        );
    }
    events.sort_unstable();
    let (mut state, mut at, mut off_by_one) = ([0i64; 2], 0usize, 0usize);
    for &(clock, k, dir) in &events {
        state[k] += dir;
        let near = |r: &[i64; 2]| (state[0] - r[0]).abs().max((state[1] - r[1]).abs());
        let end = reference.len().min(at + WINDOW);
        let mut found = (at..end).find(|&j| near(&reference[j]) <= 1).unwrap_or_else(|| {
            panic!(
                "{what}: at clock {clock} the motors stand at {state:?} steps, more than one step from the path \
                 (reference near {:?})",
                &reference[at..end.min(at + 4)]
            )
        });
        // The first entry within one step may be the one just before an exact match: take the closest of the run.
        while found + 1 < reference.len() && near(&reference[found + 1]) < near(&reference[found]) {
            found += 1;
        }
        if near(&reference[found]) == 1 {
            off_by_one += 1;
        }
        at = found;
    }
    assert_eq!(
        state,
        *reference.last().expect("reference"),
        "{what}: the motors end elsewhere than the path's end"
    );
    PathAudit {
        states: events.len(),
        off_by_one,
    }
}

/// The XY targets of the G0/G1 moves of a G-code text (absolute coordinates), from `start`, repeats dropped.
pub fn gcode_path(start: [f64; 2], text: &str) -> Vec<[f64; 2]> {
    let mut path = vec![start];
    let mut at = start;
    for line in text.lines() {
        let code = line.split(';').next().unwrap_or("").trim();
        let mut words = code.split_whitespace();
        if !matches!(words.next(), Some("G0" | "G1")) {
            continue;
        }
        for word in words {
            let value = |w: &str| w[1..].parse::<f64>().expect("a number");
            match word.as_bytes()[0] {
                b'X' => at[0] = value(word),
                b'Y' => at[1] = value(word),
                _ => {}
            }
        }
        if path.last() != Some(&at) {
            path.push(at);
        }
    }
    path
}
