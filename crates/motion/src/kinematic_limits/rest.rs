//! The part of a move next to a pose the toolhead may only rest at (a SCARA's straight or folded arm).
//!
//! There a joint's rate `q'(s)` grows without bound (as `1/√s` at a fold), so no cruise speed is safe; but the
//! planner brings the toolhead to rest at such a pose, and from rest the speed obeys `v² ≤ 2·a·s`. A joint's speed
//! is then at most `√a·g(s)` with `g = √(2s)·|q'(s)|`, which stays finite. While the toolhead accelerates from
//! the pose the joint's acceleration is `a·g'(s)·√(2s)` (zero at an exact fold), and its speed jumps from rest to
//! `√a·g(0+)`, judged over its steps like a corner's jump. Klipper's lookahead cruises or slows only beyond
//! `(1 − minimum_cruise_ratio)·len/2` of a move it accelerates from rest (its smoothed speed reaches at least
//! half of what the move's `(1 − minimum_cruise_ratio)` share of acceleration gives), where
//! `|q''|·v² + |q'|·a ≤ a·(2s·|q''| + |q'|)`. The span is capped at the speed its acceleration reaches at its end,
//! and no more than the next span allows, so it never cruises faster than that inside. Arriving is the same
//! motion reversed.

use kinematics::{Kinematics, Vec3};

use super::limit::{JUMP_WINDOW_STEPS, MotorLimit};
use super::profile::SAMPLE_MARGIN;

/// Samples of the joints along the span, spaced as `(i/N)²` so the pose's neighbourhood is seen closely.
const REST_SAMPLES: usize = 32;

/// The pose end of a move, the direction away from it along the move, and the length of the span beside it.
#[derive(Debug, Clone, Copy)]
pub(super) struct RestEnd {
    pub(super) pose: Vec3,
    pub(super) away: Vec3,
    pub(super) length: f64,
}

/// The acceleration (at most `accel`) with which the toolhead may leave the rest pose over the span, or arrive
/// there, within the `limits` of motors without a closed form (see the module's notes); zero where the joints cannot
/// be evaluated anywhere beside the pose.
pub(super) fn rest_accel(
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
    end: RestEnd,
    accel: f64,
    minimum_cruise_ratio: f64,
) -> f64 {
    let (at, rates) = joint_rates(kin, limits, end);
    if at.is_empty() {
        return 0.0;
    }
    let smoothed_from = (1.0 - minimum_cruise_ratio).max(0.0) * end.length / 2.0;
    let mut a = accel;
    for (limit, rates) in limits.iter().zip(&rates) {
        let shape = RestShape::new(&at, rates, smoothed_from);
        if let Some(max_velocity) = limit.max_velocity {
            a = a.min(max_velocity * max_velocity / (shape.speed * shape.speed));
        }
        if let Some(max_accel) = limit.max_accel {
            let window = JUMP_WINDOW_STEPS * kin.motors()[limit.motor].step_distance;
            let leaving = shape.accelerating + shape.jump * shape.jump / window;
            a = a.min(max_accel / leaving).min(max_accel / shape.cruising);
        }
    }
    a
}

/// Sample positions (mm from the pose) of a span of `length`.
fn sample_at(i: usize, length: f64) -> f64 {
    let f = i as f64 / REST_SAMPLES as f64;
    length * f * f
}

/// The samples (mm from the pose) where the kinematics give the joints' rates, and the signed `q'` of each limited
/// motor there. A sample they cannot evaluate is left out: on a span the segment check allows, that is a point
/// within rounding of the pose itself (the arm exactly straight, or a hair beyond its reach); on a span that leaves
/// the workspace there are none at all.
fn joint_rates(
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
    end: RestEnd,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let mut rows = vec![[0.0; 3]; kin.motors().len()];
    let mut at = Vec::with_capacity(REST_SAMPLES);
    let mut rates = vec![Vec::with_capacity(REST_SAMPLES); limits.len()];
    for i in 1..=REST_SAMPLES {
        let s = sample_at(i, end.length);
        let p = [0, 1, 2].map(|k| end.pose[k] + end.away[k] * s);
        if kin.jacobian(p, &mut rows).is_err() {
            continue;
        }
        at.push(s);
        for (rate, limit) in rates.iter_mut().zip(limits) {
            let row = rows[limit.motor];
            rate.push(row[0] * end.away[0] + row[1] * end.away[1] + row[2] * end.away[2]);
        }
    }
    (at, rates)
}

/// What one joint does beside the pose, per unit of toolhead acceleration `a` (bounds from samples, with margin).
struct RestShape {
    /// `max g`: the joint's speed is at most `√a` times this.
    speed: f64,
    /// `g(0+)`: its jump from rest is `√a` times this.
    jump: f64,
    /// `max |g'|·√(2s)`: its acceleration while the toolhead accelerates from rest, per unit `a`.
    accelerating: f64,
    /// `max 2s·|q''| + |q'|` beyond where the lookahead may cruise or slow: its acceleration there, per unit `a`.
    cruising: f64,
}

impl RestShape {
    /// From the rates at the samples `s` (at least one, increasing).
    fn new(s: &[f64], rates: &[f64], smoothed_from: f64) -> RestShape {
        let g: Vec<f64> = s
            .iter()
            .zip(rates)
            .map(|(s, q)| (2.0 * s).sqrt() * q.abs())
            .collect();
        let mut shape = RestShape {
            speed: g.iter().copied().fold(0.0, f64::max),
            jump: g.first().copied().unwrap_or(0.0),
            accelerating: 0.0,
            cruising: 0.0,
        };
        for i in 1..s.len() {
            let ds = s[i] - s[i - 1];
            let slope = (g[i] - g[i - 1]).abs() / ds;
            shape.accelerating = shape.accelerating.max(slope * (2.0 * s[i]).sqrt());
            if s[i] >= smoothed_from {
                let curvature = (rates[i] - rates[i - 1]).abs() / ds;
                let rate = rates[i].abs().max(rates[i - 1].abs());
                shape.cruising = shape.cruising.max(2.0 * s[i] * curvature + rate);
            }
        }
        shape.speed *= SAMPLE_MARGIN;
        shape.jump *= SAMPLE_MARGIN;
        shape.accelerating *= SAMPLE_MARGIN;
        shape.cruising *= SAMPLE_MARGIN;
        shape
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::ScaraParams;
    use kinematics::scara::Scara;

    /// The FEKT arm (100 + 100 mm) with the elbow motor reading the elbow joint alone.
    fn arm() -> Scara {
        Scara::new(ScaraParams {
            elbow_coupling: 0.0,
            ecr: None,
            ..ScaraParams::fekt_example()
        })
        .expect("valid params")
    }

    fn limit(motor: usize, max_velocity: Option<f64>, max_accel: Option<f64>) -> MotorLimit {
        MotorLimit {
            motor,
            max_velocity,
            max_accel,
        }
    }

    /// Straight in from the stretched arm at (0, 200): the elbow bends as `q2 = acos(1 − (2Rs − s²)/(2·L1·L2))`,
    /// so `g(0+) = √(2s)·q2'(s) → √(R/(L1·L2)) = √0.02`; the shoulder turns half as fast.
    const IN_FROM_STRAIGHT: RestEnd = RestEnd {
        pose: [0.0, 200.0, 0.0],
        away: [0.0, -1.0, 0.0],
        length: 1.0,
    };

    #[test]
    fn leaving_the_straight_arm_the_elbow_speed_sets_the_acceleration() {
        let limits = [limit(0, Some(5.0), None), limit(1, Some(5.0), None)];
        let a = rest_accel(&arm(), &limits, IN_FROM_STRAIGHT, 3000.0, 0.5);
        // a·g² ≤ V², with the samples' margin.
        let expected = 25.0 / (0.02 * SAMPLE_MARGIN * SAMPLE_MARGIN);
        assert!((a / expected - 1.0).abs() < 0.01, "{a} vs {expected}");
    }

    #[test]
    fn leaving_the_straight_arm_the_elbows_jump_from_rest_sets_the_acceleration() {
        // The elbow's acceleration while the toolhead accelerates is nearly zero at the fold; its jump to √(a·0.02)
        // read over 16 steps must stay within 100 rad/s²: a ≤ 100 · 16 · step / 0.02 (with margins).
        let limits = [limit(1, None, Some(100.0))];
        let a = rest_accel(&arm(), &limits, IN_FROM_STRAIGHT, 3000.0, 0.5);
        let window = JUMP_WINDOW_STEPS * std::f64::consts::TAU / 9600.0;
        let jump_only = 100.0 * window / (0.02 * SAMPLE_MARGIN * SAMPLE_MARGIN);
        assert!(a <= jump_only && a > 0.9 * jump_only, "{a} vs {jump_only}");
        // Within the limit the toolhead may not keep the requested acceleration.
        assert!(a < 3000.0);
    }

    #[test]
    fn a_pose_the_kinematics_cannot_evaluate_leaves_no_acceleration() {
        let outward = RestEnd {
            away: [0.0, 1.0, 0.0],
            ..IN_FROM_STRAIGHT
        };
        let limits = [limit(1, Some(5.0), None)];
        assert_eq!(rest_accel(&arm(), &limits, outward, 3000.0, 0.5), 0.0);
    }
}
