//! How a motor position varies along a straight move, and bounds on its rate and curvature.

use kinematics::{Kinematics, MotorMap, RADIAL_ROUNDING, Vec3};

use super::limit::MotorLimit;

/// Band boundaries grow by this factor away from the closest approach: a span's cap is at most this much
/// (squared) below what the motor would allow at its best point.
const BAND_GROWTH: f64 = 1.15;
/// The first band around the closest approach, in units of the distance of closest approach.
const FIRST_BAND: f64 = 0.25;
/// Motors without a closed form are sampled this many times per span.
const GENERAL_SAMPLES: usize = 9;
/// …on spans at most this long (mm), and at most this many spans per move.
pub(super) const GENERAL_SPAN_MM: f64 = 1.0;
const GENERAL_MAX_SPANS: usize = 256;
/// Sampled rates are inflated by this margin (they bound a smooth function from samples).
pub(super) const SAMPLE_MARGIN: f64 = 1.05;

/// The move as a parametrised line: `p(s) = start + dir·s`, `0 ≤ s ≤ length`.
pub(super) struct Line {
    pub(super) start: Vec3,
    pub(super) dir: Vec3,
    pub(super) length: f64,
}

impl Line {
    /// The line `start → end`, or `None` when it has no length, or no finite one (a non-finite end, or ends so far
    /// apart that the squared distance overflows: its direction would be NaN; the segment check refuses such moves).
    pub(super) fn new(start: Vec3, end: Vec3) -> Option<Line> {
        let length = distance(start, end);
        (length > 0.0 && length.is_finite()).then(|| Line {
            start,
            dir: [0, 1, 2].map(|k| (end[k] - start[k]) / length),
            length,
        })
    }

    pub(super) fn at(&self, s: f64) -> Vec3 {
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
pub(super) enum Profile {
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
    pub(super) fn new(kin: &dyn Kinematics, motor: usize, line: &Line) -> Profile {
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

    /// Whether the motor has no closed form along the line (its rate is sampled, and unbounded at a singular
    /// pose).
    pub(super) fn is_sampled(&self) -> bool {
        matches!(self, Profile::General { .. })
    }

    /// Cut points (mm along the line) that keep each span's rate nearly constant where the limit may bind.
    pub(super) fn breakpoints(
        &self,
        line: &Line,
        limit: &MotorLimit,
        speed: f64,
        cuts: &mut Vec<f64>,
    ) {
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
    pub(super) fn bounds(&self, kin: &dyn Kinematics, line: &Line, s0: f64, s1: f64) -> (f64, f64) {
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
