//! One piece's line as one SCARA joint motor sees it: the motor position and rate along the line
//! (`JointLine::eval`, and by angle increments `eval_near`), interval bounds on the rate
//! (`JointLine::rate_sign`) and the reach test.

use std::f64::consts::PI;

use kinematics::scara::{Joints, ScaraGeometry, ScaraJoint, normalise};
use kinematics::{ElbowBranch, ReachError, unwrap_near};

use super::lanes::Lanes;
use trapq::Piece;

/// Margin of `|cos q2|` below 1 for the closed-form solver (closer spans use the general one).
const REACH_MARGIN: f64 = 1e-12;
/// Relative widening of every interval bound (covers the rounding of the bound's own arithmetic).
const BOUND_SLACK: f64 = 1e-12;

/// The motor at one distance along the piece, as Newton's method needs it: its reading, its inverse rate,
/// and what the next evaluation by increments ([`JointLine::eval_near`]) starts from.
#[derive(Debug, Clone, Copy)]
pub(super) struct Probe {
    /// Motor position (rad), unwrapped: `base + offset`.
    pub(super) f: f64,
    /// The motor at the last full evaluation, and the increments summed since (kept apart so that a long
    /// chain of increments rounds at the size of the offset, not of the motor position).
    pub(super) base: f64,
    pub(super) offset: f64,
    /// ds/d(motor) (mm/rad): Newton's step is a product.
    pub(super) inv_slope: f64,
    /// Shoulder angle, unwrapped (for the next unwrap).
    pub(super) q1: f64,
    /// `(u + iv)·(L1 + L2·e^(−i·q2))`: link 1's direction `e^(i·q1)` scaled by `ρ²`, so the shoulder's turn
    /// between two points is one complex product's argument.
    pub(super) link: [f64; 2],
    /// `(cos q2, signed sin q2)`, `sin q2 = √(1 − cos² q2)` on the branch.
    pub(super) elbow: [f64; 2],
}

/// The motor at one distance, fully evaluated (run ends): a [`Probe`] and the angle `β` between link 1 and
/// the nozzle ray, `atan2(L2 sin q2, L1 + L2 cos q2)`, for continuing the shoulder angle along the line.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    pub(super) probe: Probe,
    pub(super) beta: f64,
    /// d²s/d(motor)² here (what a run's first prediction needs before successive crossings estimate it).
    pub(super) bend: f64,
}

/// One piece's line as seen by one joint motor.
pub(super) struct JointLine {
    pub(super) geometry: ScaraGeometry,
    pub(super) shoulder: bool,
    /// Bed-frame XY start and direction of the piece (the same arithmetic as the general solver's points).
    pub(super) start: [f64; 2],
    pub(super) dir: [f64; 2],
    /// Arm-frame start and direction (what [`Self::eval_near`] steps along).
    pub(super) arm_start: [f64; 2],
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
    /// The motor is `weight_q1·q1 + weight_q2·q2` (+ its zero): `(1, 0)` for the shoulder, `(c, 1)` for the
    /// elbow's `q2 + c·q1`.
    pub(super) weight_q1: f64,
    pub(super) weight_q2: f64,
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
            arm_start: [pu, pv],
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
            weight_q1: if joint == ScaraJoint::Shoulder {
                1.0
            } else {
                geometry.coupling(1.0)
            },
            weight_q2: if joint == ScaraJoint::Shoulder {
                0.0
            } else {
                1.0
            },
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

    /// Inverse motor rate ds/d(motor) from `ρ²`, its derivative, `cos q2` and the signed `sin q2`. With
    /// `D = 2·L1·L2·sin q2`: `q2' = −(ρ²)'/D` and `q1' = (cross − L2·(L2 + L1·cos q2)·q2')/ρ²
    /// = (cross·D + L2·(L2 + L1·cos q2)·(ρ²)')/(ρ²·D)`; the motor rate is their weighted sum over `ρ²·D`,
    /// one division for its inverse.
    #[inline(always)]
    pub(super) fn inv_slope(&self, r: Lanes, rp: Lanes, c2: Lanes, s2: Lanes) -> Lanes {
        let den = self.scale * s2;
        let q1_num = self.cross * den + self.l2 * (self.l2 + self.l1 * c2) * rp;
        let q2_num = -rp * r;
        (den * r) / (self.weight_q1 * q1_num + self.weight_q2 * q2_num)
    }

    /// d²s/d(motor)², the derivative of [`Self::inv_slope`]'s `D/N` along the motor: `(N·D' − N'·D)·D/N³`
    /// with `'` = d/ds (`(ρ²)'' = 2a`, `(cos q2)' = (ρ²)'/(2·L1·L2)`, `(sin q2)' = −cos q2·(cos q2)'/sin q2`).
    pub(super) fn bend(&self, r: f64, rp: f64, c2: f64, s2: f64) -> f64 {
        let (rpp, c2p) = (2.0 * self.a, rp * self.inv_scale);
        let s2p = -c2 * c2p / s2;
        let (den, den_p) = (self.scale * s2, self.scale * s2p);
        let (w, w_p) = (self.l2 * (self.l2 + self.l1 * c2), self.l2 * self.l1 * c2p);
        let q1_num = self.cross * den + w * rp;
        let q1_num_p = self.cross * den_p + w_p * rp + w * rpp;
        let (q2_num, q2_num_p) = (-rp * r, -(rpp * r + rp * rp));
        let n = self.weight_q1 * q1_num + self.weight_q2 * q2_num;
        let n_p = self.weight_q1 * q1_num_p + self.weight_q2 * q2_num_p;
        let (d, d_p) = (den * r, den_p * r + den * rp);
        (n * d_p - n_p * d) * d / (n * n * n)
    }

    /// Link 1's direction scaled by `ρ²` ([`Probe::link`]) from the arm-frame point and the elbow angle.
    #[inline(always)]
    fn link(&self, u: Lanes, v: Lanes, c2: Lanes, s2: Lanes) -> [Lanes; 2] {
        let (bx, by) = (self.l1 + self.l2 * c2, self.l2 * s2);
        [u * bx + v * by, v * bx - u * by]
    }

    /// `ρ²` and its derivative along the line at the arm-frame point `(u, v)`.
    #[inline]
    fn rho2_and_rate(&self, u: f64, v: f64) -> (f64, f64) {
        let r = u * u + v * v;
        let rp = 2.0 * (u * self.arm_dir[0] + v * self.arm_dir[1]);
        (r, rp)
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
        let (r, rp) = self.rho2_and_rate(u, v);
        let signed_sin = self.branch * (1.0 - cos_q2 * cos_q2).max(0.0).sqrt();
        let f = if self.shoulder { motor_a } else { motor_b };
        let lane = Lanes::splat;
        let (c2, s2) = (lane(cos_q2), lane(signed_sin));
        let link = self.link(lane(u), lane(v), c2, s2);
        let probe = Probe {
            f,
            base: f,
            offset: 0.0,
            inv_slope: self.inv_slope(lane(r), lane(rp), c2, s2).first(),
            q1,
            link: [link[0].first(), link[1].first()],
            elbow: [cos_q2, signed_sin],
        };
        Ok(Point {
            probe,
            beta,
            bend: self.bend(r, rp, cos_q2, signed_sin),
        })
    }

    /// The motor at `s` from a nearby evaluated point `from` ([`Self::eval_near_pair`] with one lane used).
    #[inline(always)]
    pub(super) fn eval_near(&self, s: f64, from: &Probe) -> Option<Probe> {
        let [p, _] = self.eval_near_pair(Lanes::splat(s), from);
        p
    }

    /// The motor at the two distances `s` from a nearby evaluated point `from`, without a libm call: the
    /// shoulder and the elbow turn by small angles whose tangents are quotients of complex products of the
    /// points' link and elbow directions (one division for both), and a small angle is its tangent's short
    /// series. `None` in a lane whose increments are too large for the series (or whose point is out of
    /// reach): the caller evaluates in full.
    #[inline(always)]
    pub(super) fn eval_near_pair(&self, s: Lanes, from: &Probe) -> [Option<Probe>; 2] {
        let u = self.arm_start[0] + self.arm_dir[0] * s;
        let v = self.arm_start[1] + self.arm_dir[1] * s;
        let r = u * u + v * v;
        let rp = 2.0 * (u * self.arm_dir[0] + v * self.arm_dir[1]);
        let c2 = (r - self.mid) * self.inv_scale;
        let s2 = self.branch * (1.0 - c2 * c2).sqrt();
        let link = self.link(u, v, c2, s2);
        let shoulder = turn(from.link, link);
        let elbow = turn(from.elbow, [c2, s2]);
        // tan of each turn, over one division for both.
        let inv = 1.0 / (shoulder[0] * elbow[0]);
        let tan_q1 = shoulder[1] * elbow[0] * inv;
        let tan_q2 = elbow[1] * shoulder[0] * inv;
        let valid = (c2.strictly_within(-1.0, 1.0))
            .and(shoulder[0].positive())
            .and(elbow[0].positive())
            .and(tan_q1.small(SMALL_TAN))
            .and(tan_q2.small(SMALL_TAN))
            .lanes();
        let (d_q1, d_q2) = (small_atan(tan_q1), small_atan(tan_q2));
        let offset = from.offset + (self.weight_q2 * d_q2 + self.weight_q1 * d_q1);
        let f = from.base + offset;
        let inv_slope = self.inv_slope(r, rp, c2, s2);
        let q1 = from.q1 + d_q1;
        let [f, offset, inv_slope, q1] = [f, offset, inv_slope, q1].map(Lanes::array);
        let [link_u, link_v, c2, s2] = [link[0], link[1], c2, s2].map(Lanes::array);
        let lane = |i: usize| Probe {
            f: f[i],
            base: from.base,
            offset: offset[i],
            inv_slope: inv_slope[i],
            q1: q1[i],
            link: [link_u[i], link_v[i]],
            elbow: [c2[i], s2[i]],
        };
        [valid[0].then(|| lane(0)), valid[1].then(|| lane(1))]
    }

    #[cold]
    pub(super) fn reach_error(&self, x: f64, y: f64) -> ReachError {
        // The geometry's own check names the limit (a value it accepts can only be NaN here).
        self.geometry
            .joints(x, y)
            .err()
            .unwrap_or(ReachError::NotFinite)
    }

    /// Bounds of the motor rate over `[lo, hi]` (`lo ≤ hi`), by interval arithmetic on the rates of [`Self::inv_slope`].
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
            let k = mul((self.weight_q1, self.weight_q1), dq1);
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
        at_from.probe.q1 + sweep - (beta_to - at_from.beta)
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
        let first = self.eval(to, at_from.probe.q1)?;
        let near = self.continued_q1(from, at_from, to, first.beta);
        if (first.probe.q1 - near).abs() <= 0.5 * PI {
            return Ok(first);
        }
        self.eval(to, near)
    }
}

/// Largest tangent [`small_atan`] takes: the first series term left out, t¹¹/11, is below 1e-23.
const SMALL_TAN: f64 = 1e-2;

/// `to · conj(from)` (per lane `from` is the same point): a complex number whose argument is the turn from
/// `from`'s direction to `to`'s.
#[inline(always)]
fn turn(from: [f64; 2], to: [Lanes; 2]) -> [Lanes; 2] {
    [
        to[0] * from[0] + to[1] * from[1],
        to[1] * from[0] - to[0] * from[1],
    ]
}

/// `atan(t)` for `|t| ≤ SMALL_TAN`, from its series.
#[inline(always)]
fn small_atan(t: Lanes) -> Lanes {
    // `t·(1 − t²/3 + t⁴/5 − t⁶/7 + t⁸/9)`, the powers side by side (Estrin's scheme: the divisions by
    // constants are multiplications, the chain is three products deep instead of five).
    let t2 = t * t;
    let t4 = t2 * t2;
    let low = 1.0 - t2 * (1.0 / 3.0);
    let mid = 1.0 / 5.0 - t2 * (1.0 / 7.0);
    let high = t4 * (1.0 / 9.0);
    t * (low + t4 * (mid + high))
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
                let p = line.eval(s, 1.0).expect("reachable").probe;
                let fa = line.eval(s - h, 1.0).expect("reachable").probe.f;
                let fb = line.eval(s + h, 1.0).expect("reachable").probe.f;
                let numeric = (fb - fa) / (2.0 * h);
                let slope = 1.0 / p.inv_slope;
                assert!(
                    (slope - numeric).abs() < 1e-7,
                    "{joint:?} {s}: {slope} vs {numeric}",
                );
                let (pa, pb) = (
                    line.eval(s - h, 1.0).expect("reachable").probe,
                    line.eval(s + h, 1.0).expect("reachable").probe,
                );
                let bend = line.eval(s, 1.0).expect("reachable").bend;
                let numeric_bend = (pb.inv_slope - pa.inv_slope) / (pb.f - pa.f);
                assert!(
                    (bend - numeric_bend).abs() < 1e-5 * bend.abs().max(1.0),
                    "{joint:?} {s}: bend {bend} vs {numeric_bend}",
                );
                let mut m = [0.0; 3];
                kin.inverse([0.6 / n * s, 130.0 - 0.8 / n * s, 0.0], &mut m)
                    .expect("reachable");
                let index = if joint == ScaraJoint::Shoulder { 0 } else { 1 };
                assert_eq!(p.f, m[index]);
            }
        }
    }

    /// A chain of evaluations by increments (one lane, and pairs) stays within 1e-14 rad of full ones.
    #[test]
    fn increments_follow_full_evaluations() {
        let kin = Scara::new(ScaraParams::fekt_example()).expect("params");
        let n = 0.6f64.hypot(0.8);
        for joint in [ScaraJoint::Shoulder, ScaraJoint::Elbow] {
            let line = JointLine::new(
                kin.geometry(),
                joint,
                &piece([0.0, 130.0, 0.0], [0.6 / n, -0.8 / n, 0.0]),
            );
            let mut anchor = line.eval(0.0, 1.0).expect("reachable").probe;
            for i in 1..=300 {
                let s = 0.1 * f64::from(i);
                let [a, b] = line.eval_near_pair(Lanes::new([s - 0.05, s]), &anchor);
                let (a, b) = (a.expect("small turn"), b.expect("small turn"));
                for (at, p) in [(s - 0.05, a), (s, b)] {
                    let full = line.eval(at, p.q1).expect("reachable").probe;
                    assert!((p.f - full.f).abs() < 1e-14, "{joint:?} {at}");
                    assert!((p.q1 - full.q1).abs() < 1e-14, "{joint:?} {at}");
                    assert!((p.inv_slope / full.inv_slope - 1.0).abs() < 1e-12);
                }
                anchor = b;
            }
        }
    }
}
