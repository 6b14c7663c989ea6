//! Fewer segments for display: consecutive segments of the same look (the limit that holds them, extruding or
//! not, slowed hard or not, speed within one colour step) that lie within `tolerance` of one straight line become
//! that line, with the peaks of its pieces (so a motor's speed against its limit shows the run's highest). What a segment shows — the limit that holds it, a move slowed
//! hard — is part of its look, so a merged segment shows it where every one of its pieces did: no limit hit leaves
//! the page. A bed turn and a refusal are never merged.

use crate::motors::{BED_TURN, Cause, REFUSED};

/// The segment extrudes.
pub const EXTRUDING: u8 = 1;
/// A machine limit slowed the move below a quarter of its requested speed.
pub const SLOWED: u8 = 2;
/// Start of a new chain (the segment does not start where the one before it ended).
pub const JUMP: u8 = 4;

/// Colour steps the page uses for speeds and motor use: segments in one step look alike.
const STEPS: f64 = 24.0;
/// The most segments merged into one (bounds the deviation check's work).
const MOST_MERGED: usize = 32;
/// The motors a segment records (every machine here has three: two in the plane and Z).
pub const MOTORS: usize = 3;

/// A straight piece of the planned path, as the page draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// The G-code line of its (first) move.
    pub line: u64,
    pub from: [f32; 3],
    pub to: [f32; 3],
    /// Print time at its start (s) and its duration.
    pub start: f64,
    pub duration: f64,
    /// Peak nozzle speed (mm/s) and the speed asked for.
    pub speed: f32,
    pub requested: f32,
    pub cause: Cause,
    pub flags: u8,
    /// Each motor's peak speed and acceleration (motor units).
    pub motor_speed: [f32; MOTORS],
    pub motor_accel: [f32; MOTORS],
}

impl Segment {
    /// Kept as it is, whatever the tolerance: a bed turn, a refusal.
    pub fn fixed(&self) -> bool {
        matches!(self.cause, BED_TURN | REFUSED)
    }
}

/// A segment every layer keeps on the page: a limit holds it, it was slowed hard, the bed turns, or it is refused.
pub fn telling(s: &Segment) -> bool {
    s.flags & SLOWED != 0 || s.cause >= BED_TURN
}

/// Only the telling segments of a layer, each starting a new chain where the one before it is gone.
pub fn telling_only(segments: Vec<Segment>) -> Vec<Segment> {
    let mut out = Vec::new();
    let mut dropped = false;
    for mut s in segments {
        if telling(&s) {
            if dropped {
                s.flags |= JUMP;
            }
            dropped = false;
            out.push(s);
        } else {
            dropped = true;
        }
    }
    out
}

/// What a merge must keep equal.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Look {
    cause: Cause,
    flags: u8,
    speed: i64,
}

/// `scales`: the speed that fills the page's colour scale.
fn look(s: &Segment, scales: &Scales) -> Look {
    let step = |value: f32, full: f64| {
        if full > 0.0 {
            (f64::from(value) / full * STEPS).floor() as i64
        } else {
            0
        }
    };
    Look {
        cause: s.cause,
        flags: s.flags & (EXTRUDING | SLOWED),
        speed: step(s.speed, scales.speed),
    }
}

/// Full scale of each colouring by value.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scales {
    pub speed: f64,
    pub motor_speed: Vec<f64>,
    pub motor_accel: Vec<f64>,
}

/// Distance from `p` to the segment `a`–`b` (mm).
fn distance(p: [f32; 3], a: [f32; 3], b: [f32; 3]) -> f64 {
    let d = [0, 1, 2].map(|i| f64::from(b[i]) - f64::from(a[i]));
    let w = [0, 1, 2].map(|i| f64::from(p[i]) - f64::from(a[i]));
    let len2: f64 = d.iter().map(|v| v * v).sum();
    let t = if len2 > 0.0 {
        (w.iter().zip(&d).map(|(w, d)| w * d).sum::<f64>() / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    w.iter()
        .zip(&d)
        .map(|(w, d)| (w - t * d).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The segments of `input` merged where they look alike and stay within `tolerance` mm of a straight line.
pub fn merge(input: Vec<Segment>, tolerance: f64, scales: &Scales) -> Vec<Segment> {
    merge_by(input, tolerance, scales, false)
}

/// [`merge`] where only what holds a segment and its flags must match (not its speed): for layers the page keeps
/// only the telling segments of.
pub fn merge_coarse(input: Vec<Segment>, scales: &Scales) -> Vec<Segment> {
    merge_by(input, f64::INFINITY, scales, true)
}

fn merge_by(input: Vec<Segment>, tolerance: f64, scales: &Scales, coarse: bool) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::with_capacity(input.len() / 2 + 1);
    // The inner points of the segment being grown, and its look.
    let mut inner: Vec<[f32; 3]> = Vec::new();
    let mut current: Option<Look> = None;
    for s in input {
        let mut this = look(&s, scales);
        if coarse {
            this.speed = 0;
        }
        let joins = match (out.last(), &current) {
            (Some(last), Some(l)) => {
                !s.fixed()
                    && !last.fixed()
                    && s.flags & JUMP == 0
                    && *l == this
                    && inner.len() < MOST_MERGED
                    && inner
                        .iter()
                        .chain(std::iter::once(&last.to))
                        .all(|p| distance(*p, last.from, s.to) <= tolerance)
            }
            _ => false,
        };
        match out.last_mut() {
            Some(last) if joins => {
                inner.push(last.to);
                extend(last, &s);
            }
            _ => {
                inner.clear();
                current = Some(this);
                out.push(s);
            }
        }
    }
    out
}

/// `last` now runs on through `s`.
fn extend(last: &mut Segment, s: &Segment) {
    last.to = s.to;
    last.duration = s.start + s.duration - last.start;
    last.speed = last.speed.max(s.speed);
    last.requested = last.requested.max(s.requested);
    for (mine, theirs) in last.motor_speed.iter_mut().zip(&s.motor_speed) {
        *mine = mine.max(*theirs);
    }
    for (mine, theirs) in last.motor_accel.iter_mut().zip(&s.motor_accel) {
        *mine = mine.max(*theirs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motors::{AT_REQUESTED, FIRST_MOTOR};

    fn segment(line: u64, from: [f32; 2], to: [f32; 2], cause: Cause) -> Segment {
        Segment {
            line,
            from: [from[0], from[1], 0.2],
            to: [to[0], to[1], 0.2],
            start: line as f64,
            duration: 1.0,
            speed: 50.0,
            requested: 50.0,
            cause,
            flags: EXTRUDING,
            motor_speed: [1.0; MOTORS],
            motor_accel: [1.0; MOTORS],
        }
    }

    fn scales() -> Scales {
        Scales {
            speed: 100.0,
            motor_speed: vec![10.0; MOTORS],
            motor_accel: vec![10.0; MOTORS],
        }
    }

    #[test]
    fn a_gentle_curve_becomes_one_line_and_limit_hits_stay() {
        // A polyline bending by 0.025 mm, then one segment a motor limit held, then more of the curve.
        let mut input: Vec<Segment> = (0..10u64)
            .map(|i| {
                let x = i as f32;
                let bend = |x: f32| 0.001 * x * (10.0 - x);
                segment(i, [x, bend(x)], [x + 1.0, bend(x + 1.0)], AT_REQUESTED)
            })
            .collect();
        input.push(segment(10, [10.0, 0.0], [11.0, 0.0], FIRST_MOTOR));
        input.push(segment(11, [11.0, 0.0], [12.0, 0.0], AT_REQUESTED));
        let merged = merge(input.clone(), 0.05, &scales());
        assert_eq!(merged.len(), 3, "{merged:?}");
        assert_eq!(merged[0].from, input[0].from);
        assert_eq!(merged[0].to, input[9].to);
        assert_eq!(merged[0].duration, 10.0);
        assert_eq!(merged[1], input[10]);
        // A tolerance below the bend keeps the curve's corners.
        assert!(merge(input, 0.001, &scales()).len() > 3);
    }

    #[test]
    fn a_thinned_layer_keeps_its_limit_hits_as_chains_of_their_own() {
        let input = vec![
            segment(1, [0.0, 0.0], [1.0, 0.0], AT_REQUESTED),
            segment(2, [1.0, 0.0], [2.0, 0.0], FIRST_MOTOR),
            segment(3, [2.0, 0.0], [3.0, 0.0], FIRST_MOTOR),
            segment(4, [3.0, 0.0], [4.0, 0.0], AT_REQUESTED),
        ];
        let kept = telling_only(input);
        assert_eq!(kept.iter().map(|s| s.line).collect::<Vec<_>>(), [2, 3]);
        assert!(kept[0].flags & JUMP != 0 && kept[1].flags & JUMP == 0);
    }

    #[test]
    fn segments_of_another_colour_or_after_a_jump_are_not_merged() {
        let a = segment(1, [0.0, 0.0], [1.0, 0.0], AT_REQUESTED);
        let mut slower = segment(2, [1.0, 0.0], [2.0, 0.0], AT_REQUESTED);
        slower.speed = 10.0;
        let mut jump = segment(3, [2.0, 0.0], [3.0, 0.0], AT_REQUESTED);
        jump.flags |= JUMP;
        let merged = merge(vec![a, slower, jump], 1.0, &scales());
        assert_eq!(merged.len(), 3);
    }
}
