//! Motor speed and acceleration limits along a straight move (beyond Klipper).
//!
//! A polar bed turns at `v·d/ρ²` near its centre and a SCARA joint speeds up near singular poses, so a Cartesian
//! speed that is fine elsewhere asks too much of a motor there. Klipper either ignores this or slows the whole
//! move. Here a move is cut into collinear spans, each with its own cruise-speed and acceleration cap, derived
//! from bounds on the motor's rate `q'(s) = dq/ds` and curvature `q''(s)` over the span:
//! motor speed `q'·v ≤ V` and motor acceleration `|q''|·v² + |q'|·|a| ≤ A`. The path is unchanged, and the
//! lookahead sees ordinary moves meeting at straight (full-speed) junctions.

use kinematics::{Kinematics, MotorMap, RADIAL_ROUNDING, Vec3};

/// Limits of one motor, in its own units (mm or rad per second, per second²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorLimit {
    /// Index in the kinematics' motor order.
    pub motor: usize,
    pub max_velocity: Option<f64>,
    pub max_accel: Option<f64>,
}

/// A part of a move, from the previous span's end (or the move's start) to `end` (mm along the move), with its caps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    pub end: f64,
    pub max_speed: f64,
    pub max_accel: f64,
}

/// Band boundaries grow by this factor away from the closest approach: a span's cap is at most this much
/// (squared) below what the motor would allow at its best point.
const BAND_GROWTH: f64 = 1.15;
/// The first band around the closest approach, in units of the distance of closest approach.
const FIRST_BAND: f64 = 0.25;
/// Motors without a closed form are sampled this many times per span.
const GENERAL_SAMPLES: usize = 9;
/// …on spans at most this long (mm), and at most this many spans per move.
const GENERAL_SPAN_MM: f64 = 1.0;
const GENERAL_MAX_SPANS: usize = 256;
/// Sampled rates are inflated by this margin (they bound a smooth function from samples).
const SAMPLE_MARGIN: f64 = 1.05;

/// Spans of the move `start → end` requested at `speed` and `accel`, or an empty list when no limit binds
/// anywhere (the move then stays whole, exactly as Klipper plans it).
pub fn split(
    kin: &dyn Kinematics,
    limits: &[MotorLimit],
    start: Vec3,
    end: Vec3,
    speed: f64,
    accel: f64,
) -> Vec<Span> {
    let length = distance(start, end);
    if limits.is_empty() || length <= 0.0 {
        return Vec::new();
    }
    let dir = [
        (end[0] - start[0]) / length,
        (end[1] - start[1]) / length,
        (end[2] - start[2]) / length,
    ];
    let line = Line { start, dir, length };
    // Fast path: bounds over the whole move; most moves are nowhere near a limit.
    let slack = limits.iter().all(|l| {
        let profile = Profile::new(kin, l.motor, &line);
        let (v, a) = caps(l, profile.bounds(kin, &line, 0.0, length), speed, accel);
        v >= speed && a >= accel
    });
    if slack {
        return Vec::new();
    }
    let profiles: Vec<(MotorLimit, Profile)> = limits
        .iter()
        .map(|l| (*l, Profile::new(kin, l.motor, &line)))
        .collect();
    let mut cuts = vec![0.0, length];
    for (limit, profile) in &profiles {
        profile.breakpoints(&line, limit, speed, &mut cuts);
    }
    cuts.retain(|c| c.is_finite());
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-9);

    let mut spans: Vec<Span> = Vec::with_capacity(cuts.len());
    for pair in cuts.windows(2) {
        let (s0, s1) = (pair[0], pair[1]);
        let mut max_speed = speed;
        let mut max_accel = accel;
        for (limit, profile) in &profiles {
            let bounds = profile.bounds(kin, &line, s0, s1);
            let (v, a) = caps(limit, bounds, speed, accel);
            max_speed = max_speed.min(v);
            max_accel = max_accel.min(a);
        }
        push_merged(
            &mut spans,
            Span {
                end: s1,
                max_speed,
                max_accel,
            },
        );
    }
    let binds = spans
        .iter()
        .any(|s| s.max_speed < speed || s.max_accel < accel);
    if binds { spans } else { Vec::new() }
}

/// Cruise-speed and acceleration caps for a motor whose rate and curvature along the span are at most
/// `(rate, curvature)`: half the acceleration budget goes to the curvature term at the capped speed.
fn caps(limit: &MotorLimit, (rate, curvature): (f64, f64), speed: f64, accel: f64) -> (f64, f64) {
    let mut v = speed;
    let mut a = accel;
    if let Some(max_v) = limit.max_velocity
        && rate > 0.0
    {
        v = v.min(max_v / rate);
    }
    if let Some(max_a) = limit.max_accel {
        if curvature > 0.0 {
            v = v.min((0.5 * max_a / curvature).sqrt());
        }
        if rate > 0.0 {
            a = a.min((max_a - curvature * v * v) / rate);
        }
    }
    (v, a)
}

/// Append `span`, joining it to the previous one when their caps are equal.
fn push_merged(spans: &mut Vec<Span>, span: Span) {
    if let Some(last) = spans.last_mut()
        && last.max_speed == span.max_speed
        && last.max_accel == span.max_accel
    {
        last.end = span.end;
        return;
    }
    spans.push(span);
}

/// The move as a parametrised line: `p(s) = start + dir·s`, `0 ≤ s ≤ length`.
struct Line {
    start: Vec3,
    dir: Vec3,
    length: f64,
}

impl Line {
    fn at(&self, s: f64) -> Vec3 {
        [
            self.start[0] + self.dir[0] * s,
            self.start[1] + self.dir[1] * s,
            self.start[2] + self.dir[2] * s,
        ]
    }

    /// Where the line passes closest to `centre` in XY: (s of closest approach, signed distance, XY speed share).
    fn closest_approach(&self, centre: [f64; 2]) -> (f64, f64, f64) {
        let rel = [self.start[0] - centre[0], self.start[1] - centre[1]];
        let xy2 = self.dir[0] * self.dir[0] + self.dir[1] * self.dir[1];
        if xy2 == 0.0 {
            return (0.0, rel[0].hypot(rel[1]), 0.0);
        }
        let xy = xy2.sqrt();
        // In XY units: t along the line's XY direction, d across it.
        let ux = [self.dir[0] / xy, self.dir[1] / xy];
        let t0 = rel[0] * ux[0] + rel[1] * ux[1];
        let d = rel[0] * ux[1] - rel[1] * ux[0];
        (-t0 / xy, d, xy)
    }
}

/// How one motor's position varies along the line.
enum Profile {
    /// q' constant, q'' = 0.
    Linear {
        rate: f64,
    },
    /// Polar arm or bed about `centre`: closest approach at `s_star`, distance `d`, XY share `xy` of the path.
    Radius {
        s_star: f64,
        d: f64,
        xy: f64,
    },
    Angle {
        s_star: f64,
        d: f64,
        xy: f64,
    },
    /// Sampled through the Jacobian row of motor `motor`.
    General {
        motor: usize,
    },
}

impl Profile {
    fn new(kin: &dyn Kinematics, motor: usize, line: &Line) -> Profile {
        match kin.motor_map(motor) {
            MotorMap::Linear { coeffs } => Profile::Linear {
                rate: (coeffs[0] * line.dir[0] + coeffs[1] * line.dir[1] + coeffs[2] * line.dir[2])
                    .abs(),
            },
            MotorMap::Radius { centre } => {
                let (s_star, d, xy) = line.closest_approach(centre);
                Profile::Radius { s_star, d, xy }
            }
            MotorMap::Angle { centre } => {
                let (s_star, d, xy) = line.closest_approach(centre);
                // The planner's moves to and from the centre are radial (the bed angle is constant along them);
                // their direction misses the centre only by rounding, which must not read as a sharp pass.
                if d.abs() <= RADIAL_ROUNDING {
                    Profile::Linear { rate: 0.0 }
                } else {
                    Profile::Angle { s_star, d, xy }
                }
            }
            MotorMap::General | MotorMap::ScaraJoint { .. } => Profile::General { motor },
        }
    }

    /// Cut points (mm along the line) that keep each span's rate nearly constant where the limit may bind.
    fn breakpoints(&self, line: &Line, limit: &MotorLimit, speed: f64, cuts: &mut Vec<f64>) {
        match *self {
            Profile::Linear { .. } => {}
            Profile::Radius { s_star, d, xy } | Profile::Angle { s_star, d, xy } => {
                if xy == 0.0 {
                    return;
                }
                // Bands in XY distance from the closest approach, out to where the motor is far below its limits.
                let d = d.abs().max(1e-9);
                let reach = band_reach(limit, d, speed);
                let mut t = FIRST_BAND * d;
                cuts.push(s_star);
                while t < reach {
                    cuts.push(s_star + t / xy);
                    cuts.push(s_star - t / xy);
                    t *= BAND_GROWTH;
                }
                cuts.retain(|&c| c >= 0.0 && c <= line.length);
            }
            Profile::General { .. } => {
                let spans =
                    ((line.length / GENERAL_SPAN_MM).ceil() as usize).clamp(1, GENERAL_MAX_SPANS);
                for i in 1..spans {
                    cuts.push(line.length * i as f64 / spans as f64);
                }
            }
        }
    }

    /// Upper bounds of |q'| and |q''| over `[s0, s1]`.
    fn bounds(&self, kin: &dyn Kinematics, line: &Line, s0: f64, s1: f64) -> (f64, f64) {
        match *self {
            Profile::Linear { rate } => (rate, 0.0),
            Profile::Radius { s_star, d, xy } | Profile::Angle { s_star, d, xy } => {
                // |t| range over the span, in XY mm.
                let (t0, t1) = ((s0 - s_star) * xy, (s1 - s_star) * xy);
                let lo = if t0 <= 0.0 && t1 >= 0.0 {
                    0.0
                } else {
                    t0.abs().min(t1.abs())
                };
                let hi = t0.abs().max(t1.abs());
                let d = d.abs();
                let (rate, curvature) = if matches!(self, Profile::Radius { .. }) {
                    radius_bounds(d, lo, hi)
                } else {
                    angle_bounds(d, lo, hi)
                };
                // Derivatives per mm of path: XY moves xy mm per mm.
                (rate * xy, curvature * xy * xy)
            }
            Profile::General { motor } => general_bounds(kin, motor, line, s0, s1),
        }
    }
}

/// XY distance from the closest approach beyond which the polar limits are slack at `speed`.
fn band_reach(limit: &MotorLimit, d: f64, speed: f64) -> f64 {
    // Rate 1/ρ and curvature ≤ 2/ρ² (angle), rate ≤ 1 and curvature ≤ 1/ρ (radius): far enough out both are small.
    let mut rho: f64 = d;
    if let Some(v) = limit.max_velocity {
        rho = rho.max(2.0 * speed / v);
    }
    if let Some(a) = limit.max_accel {
        rho = rho
            .max((8.0 * speed * speed / a).sqrt())
            .max(4.0 * speed * speed / a);
    }
    (rho * rho - d * d).max(0.0).sqrt() * BAND_GROWTH
}

/// Bed angle θ = atan2 about the centre: |θ'| = d/(d²+t²), |θ''| = 2d|t|/(d²+t²)², for |t| in [lo, hi].
fn angle_bounds(d: f64, lo: f64, hi: f64) -> (f64, f64) {
    if d == 0.0 {
        // Radial line: the angle is constant (a crossing of the centre itself is split off by the planner).
        return (0.0, 0.0);
    }
    let rate = d / (d * d + lo * lo);
    let peak = (d / 3f64.sqrt()).clamp(lo, hi);
    let curvature = 2.0 * d * peak / (d * d + peak * peak).powi(2);
    (rate, curvature)
}

/// Arm radius r = √(d²+t²): |r'| = |t|/r ≤ 1, r'' = d²/r³, for |t| in [lo, hi].
fn radius_bounds(d: f64, lo: f64, hi: f64) -> (f64, f64) {
    let r_hi = (d * d + hi * hi).sqrt();
    let rate = if r_hi > 0.0 { hi / r_hi } else { 0.0 };
    let r_lo = (d * d + lo * lo).sqrt();
    let curvature = if r_lo > 0.0 {
        d * d / (r_lo * r_lo * r_lo)
    } else {
        0.0
    };
    (rate, curvature)
}

/// |q'| and |q''| of a motor without a closed form, from its Jacobian row at samples across the span.
fn general_bounds(kin: &dyn Kinematics, motor: usize, line: &Line, s0: f64, s1: f64) -> (f64, f64) {
    let mut rows = vec![[0.0; 3]; kin.motors().len()];
    let mut max_rate = 0.0f64;
    let mut max_curvature = 0.0f64;
    let mut prev: Option<f64> = None;
    let step = (s1 - s0) / (GENERAL_SAMPLES - 1) as f64;
    for i in 0..GENERAL_SAMPLES {
        let s = s0 + step * i as f64;
        if kin.jacobian(line.at(s), &mut rows).is_err() {
            // Unreachable or singular inside the span: the segment check reports it; allow no speed here.
            return (f64::INFINITY, f64::INFINITY);
        }
        let row = rows[motor];
        let rate = row[0] * line.dir[0] + row[1] * line.dir[1] + row[2] * line.dir[2];
        max_rate = max_rate.max(rate.abs());
        if let Some(p) = prev
            && step > 0.0
        {
            max_curvature = max_curvature.max(((rate - p) / step).abs());
        }
        prev = Some(rate);
    }
    (max_rate * SAMPLE_MARGIN, max_curvature * SAMPLE_MARGIN)
}

fn distance(a: Vec3, b: Vec3) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}
