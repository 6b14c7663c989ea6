//! One piece's line as one SCARA joint motor sees it: the motor position and rate along the line
//! (`JointLine::eval`, and by angle increments `eval_near`), interval bounds on the rate
//! (`JointLine::rate_sign`) and the reach test.

use std::f64::consts::PI;

use kinematics::scara::{Joints, ScaraGeometry, ScaraJoint, normalise};
use kinematics::{ElbowBranch, ReachError, unwrap_near};
use trapq::Piece;

/// Margin of `|cos q2|` below 1 for the closed-form solver (closer spans use the general one).
const REACH_MARGIN: f64 = 1e-12;
/// Relative widening of every interval bound (covers the rounding of the bound's own arithmetic).
const BOUND_SLACK: f64 = 1e-12;

/// The motor at one distance along the piece.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    /// Motor position (rad), unwrapped.
    pub(super) f: f64,
    /// d(motor)/ds (rad/mm).
    pub(super) slope: f64,
    /// Shoulder angle, unwrapped (for the next unwrap).
    pub(super) q1: f64,
    /// Angle between link 1 and the nozzle ray, `atan2(L2 sin q2, L1 + L2 cos q2)`.
    pub(super) beta: f64,
    /// Arm-frame position, `cos q2` and signed `√(1 − cos² q2)`: what [`JointLine::eval_near`] starts from.
    pub(super) u: f64,
    pub(super) v: f64,
    pub(super) c2: f64,
    pub(super) s2: f64,
}

/// One piece's line as seen by one joint motor.
pub(super) struct JointLine {
    pub(super) geometry: ScaraGeometry,
    pub(super) shoulder: bool,
    /// Bed-frame XY start and direction of the piece (the same arithmetic as the general solver's points).
    pub(super) start: [f64; 2],
    pub(super) dir: [f64; 2],
    /// Arm-frame direction.
    pub(super) arm_dir: [f64; 2],
    /// `ρ²(s) = a·s² + 2b·s + c`.
    pub(super) a: f64,
    pub(super) b: f64,
    pub(super) c: f64,
    /// cross(P, U) in the arm frame.
    pub(super) cross: f64,
    pub(super) l1: f64,
    pub(super) l2: f64,
    /// `L1² + L2²` and `2·L1·L2`.
    pub(super) mid: f64,
    pub(super) scale: f64,
    pub(super) inv_scale: f64,
    /// +1 on the left elbow branch (`q2 ≥ 0`), −1 on the right.
    pub(super) branch: f64,
    /// `c` of `q2 + c·q1` (elbow motor).
    pub(super) coupling: f64,
}

impl JointLine {
    pub(super) fn new(geometry: ScaraGeometry, joint: ScaraJoint, piece: &Piece) -> Self {
        let start = [piece.start_pos[0], piece.start_pos[1]];
        let dir = [piece.axes_r[0], piece.axes_r[1]];
        let (pu, pv) = geometry.arm_frame(start[0], start[1]);
        let (uu, uv) = geometry.arm_direction(dir[0], dir[1]);
        let (l1, l2) = geometry.link_lengths();
        JointLine {
            geometry,
            shoulder: joint == ScaraJoint::Shoulder,
            start,
            dir,
            arm_dir: [uu, uv],
            a: uu * uu + uv * uv,
            b: pu * uu + pv * uv,
            c: pu * pu + pv * pv,
            cross: pu * uv - pv * uu,
            l1,
            l2,
            mid: l1 * l1 + l2 * l2,
            scale: 2.0 * l1 * l2,
            inv_scale: 1.0 / (2.0 * l1 * l2),
            branch: match geometry.elbow() {
                ElbowBranch::Left => 1.0,
                ElbowBranch::Right => -1.0,
            },
            coupling: geometry.coupling(1.0),
        }
    }

    pub(super) fn rho2(&self, s: f64) -> f64 {
        (self.a * s + 2.0 * self.b) * s + self.c
    }

    /// Range of `ρ²` over `[lo, hi]` (`lo ≤ hi`): the ends, and the vertex of the parabola when inside.
    pub(super) fn rho2_range(&self, lo: f64, hi: f64) -> (f64, f64) {
        let (ra, rb) = (self.rho2(lo), self.rho2(hi));
        let (mut min, max) = (ra.min(rb), ra.max(rb));
        if self.a > 0.0 {
            let vertex = -self.b / self.a;
            if vertex > lo && vertex < hi {
                min = min.min(self.rho2(vertex));
            }
        }
        (min, max)
    }

    /// Whether every point of `[lo, hi]` has an arm pose with `|cos q2| ≤ 1 − REACH_MARGIN`.
    pub(super) fn reachable(&self, lo: f64, hi: f64) -> bool {
        let (rmin, rmax) = self.rho2_range(lo, hi);
        let (cmin, cmax) = (
            (rmin - self.mid) / self.scale,
            (rmax - self.mid) / self.scale,
        );
        rmin > 0.0 && cmin > -1.0 + REACH_MARGIN && cmax < 1.0 - REACH_MARGIN
    }

    /// Motor rate from `ρ²`, its derivative, `cos q2` and the signed `sin q2`. With `D = 2·L1·L2·sin q2`:
    /// `q2' = −(ρ²)'/D` and `q1' = (cross − L2·(L2 + L1·cos q2)·q2')/ρ² = (cross·D + L2·(L2 + L1·cos q2)·(ρ²)')/(ρ²·D)`,
    /// one division for both.
    #[inline]
    pub(super) fn slope(&self, r: f64, rp: f64, c2: f64, s2: f64) -> f64 {
        let den = self.scale * s2;
        let inv = 1.0 / (den * r);
        let dq2 = -rp * r * inv;
        let dq1 = (self.cross * den + self.l2 * (self.l2 + self.l1 * c2) * rp) * inv;
        if self.shoulder {
            dq1
        } else {
            dq2 + self.coupling * dq1
        }
    }

    /// The motor at distance `s`, its shoulder angle unwrapped near `q1_near`.
    #[inline]
    pub(super) fn eval(&self, s: f64, q1_near: f64) -> Result<Point, ReachError> {
        let x = self.start[0] + self.dir[0] * s;
        let y = self.start[1] + self.dir[1] * s;
        let (u, v) = self.geometry.arm_frame(x, y);
        let (l1, l2) = (self.l1, self.l2);
        // `ScaraGeometry::joints`, operation for operation (its reach errors included), keeping β.
        let cos_q2 = (u * u + v * v - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        if !(-1.0..=1.0).contains(&cos_q2) {
            return Err(self.reach_error(x, y));
        }
        let q2 = self.branch * cos_q2.acos();
        let (sin_q2, cos_of_q2) = q2.sin_cos();
        let beta = (l2 * sin_q2).atan2(l1 + l2 * cos_of_q2);
        let q1 = unwrap_near(normalise(v.atan2(u) - beta), q1_near);
        let (motor_a, motor_b) = self.geometry.motors_from_joints(Joints { q1, q2 });
        let r = u * u + v * v;
        let rp = 2.0 * (u * self.arm_dir[0] + v * self.arm_dir[1]);
        let signed_sin = self.branch * (1.0 - cos_q2 * cos_q2).max(0.0).sqrt();
        Ok(Point {
            f: if self.shoulder { motor_a } else { motor_b },
            slope: self.slope(r, rp, cos_q2, signed_sin),
            q1,
            beta,
            u,
            v,
            c2: cos_q2,
            s2: signed_sin,
        })
    }

    /// The motor at `s` from a nearby evaluated point `from`, without a libm call: the nozzle ray, `β` and
    /// `q2` turn by small angles whose sines and cosines are cross and dot products of the two points'
    /// vectors, and a small angle is its tangent's short series. `None` when an increment is too large for
    /// the series (or the point is out of reach): the caller evaluates in full.
    #[inline(always)]
    pub(super) fn eval_near(&self, s: f64, from: &Point) -> Option<Point> {
        let x = self.start[0] + self.dir[0] * s;
        let y = self.start[1] + self.dir[1] * s;
        let (u, v) = self.geometry.arm_frame(x, y);
        let (l1, l2) = (self.l1, self.l2);
        let c2 = (u * u + v * v - self.mid) * self.inv_scale;
        if !(c2 > -1.0 && c2 < 1.0) {
            return None;
        }
        let s2 = self.branch * (1.0 - c2 * c2).sqrt();
        let d_theta = small_atan(from.u * v - from.v * u, from.u * u + from.v * v)?;
        let (bx0, by0) = (l1 + l2 * from.c2, l2 * from.s2);
        let (bx, by) = (l1 + l2 * c2, l2 * s2);
        let d_beta = small_atan(bx0 * by - by0 * bx, bx0 * bx + by0 * by)?;
        let d_q2 = small_atan(s2 * from.c2 - c2 * from.s2, c2 * from.c2 + s2 * from.s2)?;
        let d_q1 = d_theta - d_beta;
        let d_f = if self.shoulder {
            d_q1
        } else {
            d_q2 + self.coupling * d_q1
        };
        let r = u * u + v * v;
        let rp = 2.0 * (u * self.arm_dir[0] + v * self.arm_dir[1]);
        Some(Point {
            f: from.f + d_f,
            slope: self.slope(r, rp, c2, s2),
            q1: from.q1 + d_q1,
            beta: from.beta + d_beta,
            u,
            v,
            c2,
            s2,
        })
    }

    #[cold]
    pub(super) fn reach_error(&self, x: f64, y: f64) -> ReachError {
        // The geometry's own check names the limit (a value it accepts can only be NaN here).
        self.geometry
            .joints(x, y)
            .err()
            .unwrap_or(ReachError::NotFinite)
    }

    /// Bounds of the motor rate over `[lo, hi]` (`lo ≤ hi`), by interval arithmetic on [`Self::slope`].
    pub(super) fn slope_bounds(&self, lo: f64, hi: f64) -> (f64, f64) {
        let (rmin, rmax) = self.rho2_range(lo, hi);
        let rp = (2.0 * (self.a * lo + self.b), 2.0 * (self.a * hi + self.b));
        let (cmin, cmax) = (
            (rmin - self.mid) / self.scale,
            (rmax - self.mid) / self.scale,
        );
        let far = cmin.abs().max(cmax.abs());
        let near = if cmin <= 0.0 && cmax >= 0.0 {
            0.0
        } else {
            cmin.abs().min(cmax.abs())
        };
        let (sin_min, sin_max) = ((1.0 - far * far).sqrt(), (1.0 - near * near).sqrt());
        // q2' = −branch · (ρ²)'/(2·L1·L2) / |sin q2|
        let g = mul(
            (rp.0 / self.scale, rp.1 / self.scale),
            (1.0 / sin_max, 1.0 / sin_min),
        );
        let dq2 = if self.branch > 0.0 { (-g.1, -g.0) } else { g };
        let w = (
            self.l2 * (self.l2 + self.l1 * cmin),
            self.l2 * (self.l2 + self.l1 * cmax),
        );
        let t = mul(w, dq2);
        let dq1 = mul(
            (self.cross - t.1, self.cross - t.0),
            (1.0 / rmax, 1.0 / rmin),
        );
        let (low, high) = if self.shoulder {
            dq1
        } else {
            let k = mul((self.coupling, self.coupling), dq1);
            (dq2.0 + k.0, dq2.1 + k.1)
        };
        let slack = BOUND_SLACK * low.abs().max(high.abs());
        (low - slack, high + slack)
    }

    /// Sign of the motor rate over `[from, to]` (either order), if interval arithmetic proves it.
    pub(super) fn rate_sign(&self, from: f64, to: f64) -> Option<f64> {
        let (low, high) = self.slope_bounds(from.min(to), from.max(to));
        if low > 0.0 {
            Some(1.0)
        } else if high < 0.0 {
            Some(-1.0)
        } else {
            None
        }
    }

    /// The shoulder angle at `to` continued from `from` along the line: the nozzle ray turns by less than π
    /// (`atan2` of the cross and dot products of the two rays) and `β` is continuous on its branch.
    pub(super) fn continued_q1(&self, from: f64, at_from: &Point, to: f64, beta_to: f64) -> f64 {
        let pa = self.arm_point(from);
        let pb = self.arm_point(to);
        let sweep = ((to - from) * self.cross).atan2(pa[0] * pb[0] + pa[1] * pb[1]);
        at_from.q1 + sweep - (beta_to - at_from.beta)
    }

    pub(super) fn arm_point(&self, s: f64) -> [f64; 2] {
        let (u, v) = self.geometry.arm_frame(
            self.start[0] + self.dir[0] * s,
            self.start[1] + self.dir[1] * s,
        );
        [u, v]
    }

    /// The motor at `to`, unwrapped continuously from `from` however far apart they are.
    pub(super) fn eval_far(
        &self,
        from: f64,
        at_from: &Point,
        to: f64,
    ) -> Result<Point, ReachError> {
        let first = self.eval(to, at_from.q1)?;
        let near = self.continued_q1(from, at_from, to, first.beta);
        if (first.q1 - near).abs() <= 0.5 * PI {
            return Ok(first);
        }
        self.eval(to, near)
    }
}

/// Largest tangent [`small_atan`] takes: the first series term left out, t¹¹/11, is below 1e-23.
const SMALL_TAN: f64 = 1e-2;

/// `atan2(y, x)` for a small angle (`|y/x| ≤ SMALL_TAN`, `x > 0`), from the series of `atan(t)`.
#[inline]
fn small_atan(y: f64, x: f64) -> Option<f64> {
    let t = y / x;
    if !(x > 0.0 && t.abs() <= SMALL_TAN) {
        return None;
    }
    // `t·(1 − t²/3 + t⁴/5 − t⁶/7 + t⁸/9)`, the powers side by side (Estrin's scheme: the divisions by
    // constants are multiplications, the chain is three products deep instead of five).
    let t2 = t * t;
    let t4 = t2 * t2;
    let low = 1.0 - t2 * (1.0 / 3.0);
    let mid = 1.0 / 5.0 - t2 * (1.0 / 7.0);
    let high = t4 * (1.0 / 9.0);
    Some(t * (low + t4 * (mid + high)))
}

/// Interval product.
fn mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let p = [a.0 * b.0, a.0 * b.1, a.1 * b.0, a.1 * b.1];
    let lo = p.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = p.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::scara::Scara;
    use kinematics::{Kinematics, ScaraParams};

    fn piece(start: [f64; 3], dir: [f64; 3]) -> Piece {
        Piece {
            print_time: 0.0,
            duration: 1.0,
            start_v: 10.0,
            half_accel: 0.0,
            start_pos: start,
            axes_r: dir,
            motion: trapq::Motion::Travel,
        }
    }

    #[test]
    fn slope_matches_finite_differences() {
        let kin = Scara::new(ScaraParams::fekt_example()).expect("params");
        let g = kin.geometry();
        let n = 0.6f64.hypot(0.8);
        for joint in [ScaraJoint::Shoulder, ScaraJoint::Elbow] {
            let line = JointLine::new(
                g,
                joint,
                &piece([0.0, 130.0, 0.0], [0.6 / n, -0.8 / n, 0.0]),
            );
            for s in [0.0, 5.0, 20.0] {
                let h = 1e-5;
                let p = line.eval(s, 1.0).expect("reachable");
                let fa = line.eval(s - h, 1.0).expect("reachable").f;
                let fb = line.eval(s + h, 1.0).expect("reachable").f;
                let numeric = (fb - fa) / (2.0 * h);
                assert!(
                    (p.slope - numeric).abs() < 1e-7,
                    "{joint:?} {s}: {} vs {numeric}",
                    p.slope
                );
                let mut m = [0.0; 3];
                kin.inverse([0.6 / n * s, 130.0 - 0.8 / n * s, 0.0], &mut m)
                    .expect("reachable");
                let index = if joint == ScaraJoint::Shoulder { 0 } else { 1 };
                assert_eq!(p.f, m[index]);
            }
        }
    }
}
