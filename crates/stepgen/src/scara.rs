//! Step times of SCARA joint motors, one motor at a time, from the arm's geometry.
//!
//! Along a piece the nozzle moves on a line `P + U·s` (arm frame, `s` the travelled distance). With
//! `ρ² = |P + U·s|²` and `cos q2 = (ρ² − L1² − L2²) / (2·L1·L2)` the joint rates are algebraic:
//! `q2' = −(ρ²)' / (2·L1·L2·sin q2)` and `q1' = (cross(P, U) − L2·(L2 + L1·cos q2)·q2') / ρ²` (the direction
//! of the nozzle turns at `cross / ρ²`; the angle between link 1 and the nozzle ray changes at
//! `L2·(L2 + L1·cos q2) / ρ²` per radian of elbow). The motor is `q1` (shoulder) or `q2 + c·q1` (elbow).
//!
//! A span is cut into runs where the motor rate provably keeps its sign: interval arithmetic on the formulas
//! above over a stretch of the line (ρ² is a quadratic in `s`, so its range is exact) either excludes zero or
//! the stretch is halved, down to a stretch of ~1e-13 s of travel around each turning point. On a run the
//! motor is monotonic, so its steps are exactly those of [`StepRule::monotonic`]; each crossing is found
//! by Newton's method on that one motor, started from the previous crossing with a second-order prediction
//! and kept inside a bracket (bisection when Newton leaves it), so a crossing can be neither missed nor
//! taken out of order. Levels go two at a time (`Crossings::try_pair`): both predicted from the last
//! crossing and evaluated from the last point, so the CPU overlaps their serial chains; each passes the same
//! acceptance test or is solved alone. Typically one evaluation per step (1.04 on `scara-fekt-synthetic`);
//! the general solver made about five of all motors, plus 17+ Jacobian samples per span.
//!
//! Run ends are evaluated with the arithmetic of `ScaraGeometry::joints` and `motors_from_joints` and
//! unwrapped as `Kinematics::inverse_near` does (near the previous evaluation; across a long run, near the
//! continued angle), so the motor function is the one the general solver crossed. Newton's evaluations go
//! from the previous point by angle increments (cross and dot products, a short `atan` series: no libm
//! call), in full every [`CHAIN`] evaluations; they differ from a full evaluation by ~1e-16 rad. A span that
//! comes within 1e-12 of the arm's reach limits (`|cos q2| → 1`) goes to the general solver, which reports
//! unreachable points as before.

use std::f64::consts::PI;

use kinematics::scara::{Joints, SHOULDER, ScaraGeometry, ScaraJoint, normalise};
use kinematics::{ElbowBranch, Kinematics, ReachError, unwrap_near};
use trapq::Piece;

use crate::error::StepError;
use crate::general::GeneralState;
use crate::sink::StepSink;
use crate::step_rule::{LevelInverse, StepRule};
use crate::timing::{Span, clamp_between};

/// Target accuracy of a crossing, in seconds of travel (the old solver's was 1e-12 s).
const ROOT_TIME_TOL: f64 = 1e-13;
/// Margin of `|cos q2|` below 1 for the closed-form solver (closer spans use the general one).
const REACH_MARGIN: f64 = 1e-12;
/// Relative widening of every interval bound (covers the rounding of the bound's own arithmetic).
const BOUND_SLACK: f64 = 1e-12;
/// Most stretches pending in the run search (each halving adds one; 2⁻⁹⁰ of a span is far below `tol`).
const STACK: usize = 96;
/// Evaluations by increments between two full ones (each adds at most a few 1e-17 rad of rounding).
const CHAIN: u32 = 32;
/// Newton iterations before giving up on convergence (bisection alone needs ~60 for any span).
const MAX_ITERATIONS: usize = 200;

/// The motor at one distance along the piece.
#[derive(Debug, Clone, Copy)]
struct Point {
    /// Motor position (rad), unwrapped.
    f: f64,
    /// d(motor)/ds (rad/mm).
    slope: f64,
    /// Shoulder angle, unwrapped (for the next unwrap).
    q1: f64,
    /// Angle between link 1 and the nozzle ray, `atan2(L2 sin q2, L1 + L2 cos q2)`.
    beta: f64,
    /// Arm-frame position, `cos q2` and signed `√(1 − cos² q2)`: what [`JointLine::eval_near`] starts from.
    u: f64,
    v: f64,
    c2: f64,
    s2: f64,
}

/// One piece's line as seen by one joint motor.
struct JointLine {
    geometry: ScaraGeometry,
    shoulder: bool,
    /// Bed-frame XY start and direction of the piece (the same arithmetic as the general solver's points).
    start: [f64; 2],
    dir: [f64; 2],
    /// Arm-frame direction.
    arm_dir: [f64; 2],
    /// `ρ²(s) = a·s² + 2b·s + c`.
    a: f64,
    b: f64,
    c: f64,
    /// cross(P, U) in the arm frame.
    cross: f64,
    l1: f64,
    l2: f64,
    /// `L1² + L2²` and `2·L1·L2`.
    mid: f64,
    scale: f64,
    inv_scale: f64,
    /// +1 on the left elbow branch (`q2 ≥ 0`), −1 on the right.
    branch: f64,
    /// `c` of `q2 + c·q1` (elbow motor).
    coupling: f64,
}

impl JointLine {
    fn new(geometry: ScaraGeometry, joint: ScaraJoint, piece: &Piece) -> Self {
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

    fn rho2(&self, s: f64) -> f64 {
        (self.a * s + 2.0 * self.b) * s + self.c
    }

    /// Range of `ρ²` over `[lo, hi]` (`lo ≤ hi`): the ends, and the vertex of the parabola when inside.
    fn rho2_range(&self, lo: f64, hi: f64) -> (f64, f64) {
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
    fn reachable(&self, lo: f64, hi: f64) -> bool {
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
    fn slope(&self, r: f64, rp: f64, c2: f64, s2: f64) -> f64 {
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
    fn eval(&self, s: f64, q1_near: f64) -> Result<Point, ReachError> {
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
    fn eval_near(&self, s: f64, from: &Point) -> Option<Point> {
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
    fn reach_error(&self, x: f64, y: f64) -> ReachError {
        // The geometry's own check names the limit (a value it accepts can only be NaN here).
        self.geometry
            .joints(x, y)
            .err()
            .unwrap_or(ReachError::NotFinite)
    }

    /// Bounds of the motor rate over `[lo, hi]` (`lo ≤ hi`), by interval arithmetic on [`Self::slope`].
    fn slope_bounds(&self, lo: f64, hi: f64) -> (f64, f64) {
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
    fn rate_sign(&self, from: f64, to: f64) -> Option<f64> {
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
    fn continued_q1(&self, from: f64, at_from: &Point, to: f64, beta_to: f64) -> f64 {
        let pa = self.arm_point(from);
        let pb = self.arm_point(to);
        let sweep = ((to - from) * self.cross).atan2(pa[0] * pb[0] + pa[1] * pb[1]);
        at_from.q1 + sweep - (beta_to - at_from.beta)
    }

    fn arm_point(&self, s: f64) -> [f64; 2] {
        let (u, v) = self.geometry.arm_frame(
            self.start[0] + self.dir[0] * s,
            self.start[1] + self.dir[1] * s,
        );
        [u, v]
    }

    /// The motor at `to`, unwrapped continuously from `from` however far apart they are.
    fn eval_far(&self, from: f64, at_from: &Point, to: f64) -> Result<Point, ReachError> {
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

/// The crossings of one run, where the motor is monotonic: Newton from the previous crossing in a bracket.
struct Crossings<'a> {
    line: &'a JointLine,
    span: &'a Span,
    /// Bracket: the last crossing (or run start) and the run end (or a point found past the level).
    before: f64,
    after: f64,
    /// The run end.
    end: f64,
    /// +1 when the motor rises along the travel.
    rising: f64,
    /// The last crossing: distance, level and motor rate.
    prev: (f64, f64, f64),
    /// `1 / rate` at the last crossing (the next prediction's step without a division).
    inv_slope: f64,
    /// `1 / (0.1·min(L1, L2))`: a curvature no motor function that matters here exceeds (acceptance slack).
    inv_length: f64,
    /// Estimate of d²(motor)/ds², from successive crossings.
    curvature: f64,
    /// The last evaluated point, and how many evaluations have been chained from it since the last full one.
    anchor: Point,
    chained: u32,
    /// Distance tolerance of a crossing.
    tol: f64,
    failure: Option<(f64, ReachError)>,
}

impl Crossings<'_> {
    /// Whether `x` lies in the closed bracket.
    fn inside(&self, x: f64) -> bool {
        let (lo, hi) = if self.before <= self.after {
            (self.before, self.after)
        } else {
            (self.after, self.before)
        };
        x >= lo && x <= hi
    }

    /// First guess for `level`: the previous crossing advanced by a second-order Taylor step.
    fn predict(&self, level: f64) -> f64 {
        let (s0, f0, _) = self.prev;
        let dx = (level - f0) * self.inv_slope;
        let guess = s0 + dx - 0.5 * self.curvature * dx * dx * self.inv_slope;
        if guess.is_finite() {
            guess
        } else {
            0.5 * (self.before + self.after)
        }
    }

    /// Distance where the motor reaches `level`.
    fn solve(&mut self, level: f64) -> f64 {
        let mut x = self.predict(level);
        let mut last = (self.prev.0, self.prev.2, self.inv_slope);
        for _ in 0..MAX_ITERATIONS {
            if !self.inside(x) || x == self.before || x == self.after {
                x = 0.5 * (self.before + self.after);
            }
            let p = match self.evaluate(x) {
                Ok(p) => p,
                Err(e) => {
                    self.failure.get_or_insert((x, e));
                    return x;
                }
            };
            let inv_slope = 1.0 / p.slope;
            last = (x, p.slope, inv_slope);
            let g = (p.f - level) * self.rising;
            if g == 0.0 {
                return self.accept(x, level, last);
            }
            if g < 0.0 {
                self.before = x;
            } else {
                self.after = x;
            }
            let step = -(p.f - level) * inv_slope;
            let next = x + step;
            if self.step_lands(step, inv_slope) && self.inside(next) {
                return self.accept(next, level, last);
            }
            if (self.after - self.before).abs() <= self.tol {
                return self.accept(x, level, last);
            }
            x = next;
        }
        self.accept(x, level, last)
    }

    /// The motor at `x`: from the last point by increments, in full every [`CHAIN`] evaluations (so the
    /// increments' rounding cannot add up) or when the increment is too large for the series.
    #[inline]
    fn evaluate(&mut self, x: f64) -> Result<Point, ReachError> {
        let near = if self.chained < CHAIN {
            self.line.eval_near(x, &self.anchor)
        } else {
            None
        };
        let p = match near {
            Some(p) => {
                self.chained += 1;
                p
            }
            None => {
                self.chained = 0;
                self.line.eval(x, self.anchor.q1)?
            }
        };
        self.anchor = p;
        Ok(p)
    }

    /// Whether a Newton step lands within the tolerance: its error is about |f''/(2f')|·step², with the curvature
    /// estimate doubled and a floor on it.
    #[inline]
    fn step_lands(&self, step: f64, inv_slope: f64) -> bool {
        let kappa = (2.0 * self.curvature * inv_slope).abs() + self.inv_length;
        step.is_finite() && step * step * kappa <= self.tol
    }

    /// One Newton step from `x` (where the motor reads `f`, with inverse slope `inv_slope`) towards `level`, in
    /// the bracket as [`Self::solve`] narrows it: the root when the step lands inside, within the tolerance.
    #[inline]
    fn one_step_root(&self, x: f64, f: f64, level: f64, inv_slope: f64) -> Option<f64> {
        let (mut lo, mut hi) = (self.before, self.after);
        if !strictly_between(x, lo, hi) {
            return None;
        }
        let g = (f - level) * self.rising;
        if g == 0.0 {
            return None;
        }
        if g < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let step = -(f - level) * inv_slope;
        let root = x + step;
        (self.step_lands(step, inv_slope) && between(root, lo, hi)).then_some(root)
    }

    fn accept(&mut self, root: f64, level: f64, last: (f64, f64, f64)) -> f64 {
        let (s0, _, slope0) = self.prev;
        if last.0 != s0 {
            let curvature = (last.1 - slope0) / (last.0 - s0);
            if curvature.is_finite() {
                self.curvature = curvature;
            }
        }
        self.prev = (root, level, last.1);
        self.inv_slope = last.2;
        // The next level lies between this crossing and the run end.
        self.before = root;
        self.after = self.end;
        root
    }
}

impl Crossings<'_> {
    /// Two levels at once, both predicted from the last crossing and evaluated by increments from the last
    /// point, so neither evaluation waits for the other (one level's solve is one long serial dependency:
    /// prediction, evaluation, Newton step). Each is accepted by the same test as in [`Self::solve`], in its
    /// own bracket (the second's starts at the first's crossing). `None` when anything falls outside that
    /// one-evaluation path; nothing has changed then, or only the first level is taken (`Err`).
    #[inline]
    fn try_pair(&mut self, la: f64, lb: f64) -> Option<Result<(f64, f64), f64>> {
        if self.chained >= CHAIN {
            return None;
        }
        let xa = self.predict(la);
        let xb = self.predict(lb);
        let pa = self.line.eval_near(xa, &self.anchor)?;
        let pb = self.line.eval_near(xb, &self.anchor);
        let (ia, ib) = (1.0 / pa.slope, pb.map(|p| 1.0 / p.slope));
        // The first level, as `solve`'s first iteration.
        let ra = self.one_step_root(xa, pa.f, la, ia)?;
        self.chained += 1;
        self.anchor = pa;
        self.accept(ra, la, (xa, pa.slope, ia));
        // The second level, from the same start, in the bracket the first left.
        let (Some(pb), Some(ib)) = (pb, ib) else {
            return Some(Err(ra));
        };
        let Some(rb) = self.one_step_root(xb, pb.f, lb, ib) else {
            return Some(Err(ra));
        };
        // `pb` is one increment from the point before `pa`: the chain is one longer, not two.
        self.anchor = pb;
        self.accept(rb, lb, (xb, pb.slope, ib));
        Some(Ok((ra, rb)))
    }
}

/// Whether `x` lies in the closed interval between `a` and `b` (either order).
#[inline]
fn between(x: f64, a: f64, b: f64) -> bool {
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    x >= lo && x <= hi
}

/// [`between`], and not at either end (where `solve` bisects instead).
#[inline]
fn strictly_between(x: f64, a: f64, b: f64) -> bool {
    between(x, a, b) && x != a && x != b
}

impl LevelInverse for Crossings<'_> {
    fn next_time(&mut self, level: f64) -> f64 {
        let root = self.solve(level);
        self.span.time_at(root)
    }

    const PAIRS: bool = true;

    #[inline]
    fn next_pair(&mut self, a: f64, b: f64) -> (f64, f64) {
        match self.try_pair(a, b) {
            Some(Ok((ra, rb))) => (self.span.time_at(ra), self.span.time_at(rb)),
            Some(Err(ra)) => {
                let ta = self.span.time_at(ra);
                (ta, self.next_time(b))
            }
            None => {
                let ta = self.next_time(a);
                (ta, self.next_time(b))
            }
        }
    }
}

/// What a SCARA joint motor keeps between pieces.
#[derive(Debug, Clone)]
pub(crate) struct ScaraJointState {
    geometry: ScaraGeometry,
    joint: ScaraJoint,
    /// The last shoulder angle `q1` (unwrapped), for unwrapping the next evaluation.
    q1: f64,
    /// The general solver, for spans near the reach limits.
    general: GeneralState,
}

impl ScaraJointState {
    /// A joint motor of the arm `geometry` starting at the pose whose motor positions are `start_motors`.
    pub(crate) fn new(
        geometry: ScaraGeometry,
        joint: ScaraJoint,
        general: GeneralState,
        start_motors: &[f64],
    ) -> Self {
        let q1 = start_motors
            .get(SHOULDER)
            .map_or(0.0, |a| a - geometry.shoulder_zero());
        ScaraJointState {
            geometry,
            joint,
            q1,
            general,
        }
    }

    /// Steps of this joint motor (named `motor` in errors) over one span, by `rule`.
    pub(crate) fn span_steps<S: StepSink + ?Sized>(
        &mut self,
        rule: &mut StepRule,
        motor: &str,
        piece: &Piece,
        span: &Span,
        kin: &dyn Kinematics,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let line = JointLine::new(self.geometry, self.joint, piece);
        let (d0, d1) = (span.d0, span.d1);
        if !line.reachable(d0.min(d1), d0.max(d1)) {
            return self.fallback(rule, motor, piece, span, kin, sink);
        }
        let error = |s: f64, source: ReachError| StepError::Unreachable {
            motor: motor.to_string(),
            time: piece.print_time + span.time_at(s),
            source,
        };
        let start = line.eval(d0, self.q1).map_err(|e| error(d0, e))?;
        self.q1 = start.q1;
        if line.a == 0.0 || d0 == d1 {
            // No XY motion: the joints cannot move.
            rule.settle(start.f, piece.print_time + span.t0, sink);
            return Ok(());
        }
        let tol = (span.max_speed() * ROOT_TIME_TOL)
            .max(4.0 * f64::EPSILON * d0.abs().max(d1.abs()).max(1.0));
        let context = RunContext {
            line: &line,
            span,
            print_time: piece.print_time,
            tol,
        };
        let mut runs = Runs::new(d0, d1);
        let mut at = (d0, start);
        while let Some((to, sign)) = runs.next(&line, tol) {
            let end = line.eval_far(at.0, &at.1, to).map_err(|e| error(to, e))?;
            if let Err((s, e)) = joint_run(rule, &context, (at.0, &at.1), (to, &end), sign, sink) {
                return Err(error(s, e));
            }
            self.q1 = end.q1;
            at = (to, end);
        }
        Ok(())
    }

    /// A span near the reach limits: the general solver, unwrapping from (and then continuing) this motor's
    /// shoulder angle.
    fn fallback<S: StepSink + ?Sized>(
        &mut self,
        rule: &mut StepRule,
        motor: &str,
        piece: &Piece,
        span: &Span,
        kin: &dyn Kinematics,
        sink: &mut S,
    ) -> Result<(), StepError> {
        let zero = self.geometry.shoulder_zero();
        self.general.set_motor(SHOULDER, self.q1 + zero);
        let result = self.general.span_steps(rule, motor, piece, span, kin, sink);
        if let Some(a) = self.general.motor(SHOULDER) {
            self.q1 = a - zero;
        }
        result
    }
}

/// Steps of one run from `a` to `b`; `sign` is the proven sign of the rate (`None`: a stretch of ~tol
/// around a turning point, taken as linear in the distance).
fn joint_run<S: StepSink + ?Sized>(
    rule: &mut StepRule,
    context: &RunContext,
    a: (f64, &Point),
    b: (f64, &Point),
    sign: Option<f64>,
    sink: &mut S,
) -> Result<(), (f64, ReachError)> {
    let RunContext {
        line,
        span,
        print_time,
        tol,
    } = *context;
    let ((sa, pa), (sb, pb)) = (a, b);
    let ta = span.time_at(sa);
    if sign.is_none() {
        let (fa, fb) = (pa.f, pb.f);
        let mut inverse = |level: f64| {
            let k = if fb != fa {
                (level - fa) / (fb - fa)
            } else {
                0.0
            };
            span.time_at(clamp_between(sa + k * (sb - sa), sa, sb))
        };
        rule.monotonic(fa, fb, ta, print_time, &mut inverse, sink);
        return Ok(());
    }
    let mut crossings = Crossings {
        line,
        span,
        before: sa,
        after: sb,
        end: sb,
        rising: if pb.f >= pa.f { 1.0 } else { -1.0 },
        prev: (sa, pa.f, pa.slope),
        inv_slope: 1.0 / pa.slope,
        inv_length: 10.0 / line.l1.min(line.l2),
        curvature: (pb.slope - pa.slope) / (sb - sa),
        anchor: *pa,
        chained: 0,
        tol,
        failure: None,
    };
    rule.monotonic(pa.f, pb.f, ta, print_time, &mut crossings, sink);
    match crossings.failure {
        Some(failure) => Err(failure),
        None => Ok(()),
    }
}

/// What every run of a span shares.
#[derive(Clone, Copy)]
struct RunContext<'a> {
    line: &'a JointLine,
    span: &'a Span,
    print_time: f64,
    /// Distance tolerance of a crossing.
    tol: f64,
}

/// The runs of a span in travel order: stretches of one proven rate sign (merged while the sign holds),
/// and stretches of about `tol` around turning points. A depth-first halving with its own stack.
struct Runs {
    stack: [(f64, f64); STACK],
    depth: usize,
    /// The run being grown: its start, end and sign.
    pending: Option<(f64, f64, Option<f64>)>,
}

impl Runs {
    fn new(d0: f64, d1: f64) -> Self {
        let mut stack = [(0.0, 0.0); STACK];
        stack[0] = (d0, d1);
        Runs {
            stack,
            depth: 1,
            pending: None,
        }
    }

    /// The next run's end and rate sign.
    fn next(&mut self, line: &JointLine, tol: f64) -> Option<(f64, Option<f64>)> {
        while self.depth > 0 {
            self.depth -= 1;
            let (from, to) = self.stack[self.depth];
            let sign = line.rate_sign(from, to);
            let tiny = (to - from).abs() <= tol || self.depth + 2 > STACK;
            if sign.is_none() && !tiny {
                let mid = 0.5 * (from + to);
                // Later half first on the stack, so the earlier half comes out first.
                self.stack[self.depth] = (mid, to);
                self.stack[self.depth + 1] = (from, mid);
                self.depth += 2;
                continue;
            }
            match self.pending {
                Some((start, _, run_sign)) if run_sign.is_some() && run_sign == sign => {
                    self.pending = Some((start, to, sign));
                }
                Some((_, end, run_sign)) => {
                    self.pending = Some((from, to, sign));
                    return Some((end, run_sign));
                }
                None => self.pending = Some((from, to, sign)),
            }
        }
        self.pending.take().map(|(_, end, sign)| (end, sign))
    }
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
