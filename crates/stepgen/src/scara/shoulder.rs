//! The shoulder's crossings in closed form. With the shoulder at `q1` the elbow sits at `E = L1·e^(i·q1)`
//! (arm frame, shoulder at the origin), and the nozzle is where the piece's line `P + U·s` meets the circle
//! of radius `L2` about `E`: `a·s² + 2B·s + C = 0` with `B = P·U − E·U` and `C = |P|² − 2·E·P + L1² − L2²`.
//! Of its two roots the crossing is the one inside the bracket on the arm's elbow branch (`cross(E, N)`
//! has the branch's sign at the nozzle `N`). A root that the rounding of the coefficients could move by
//! more than the tolerance is not taken: where the line nearly grazes the circle (near a turning point of
//! the shoulder) Newton's method finds the crossing instead.
//!
//! Consecutive levels are a step apart, so `e^(i·q1)` turns by a small angle from one level to the next:
//! a rotation by the turn's short series, re-anchored on `sin_cos` every [`ROTATIONS`] levels (and
//! whenever the turn is not small). Like the evaluations by increments of Newton's path, a rotated
//! direction differs from a full evaluation by a few 1e-16 rad per rotation; that is the motor's
//! evaluation error, not the root's, and is not counted against the tolerance.

use super::joint_line::JointLine;
use super::lanes::Lanes;

/// Rotations between two `sin_cos` evaluations: each rounds within half an ulp per component, so a chain
/// stays within a few 1e-15 rad of the full evaluation.
const ROTATIONS: u32 = 16;
/// Largest turn taken by rotation: the first terms the series leave out are below 1e-24.
const SMALL_TURN: f64 = 1e-2;

/// The elbow direction `e^(i·q1)` at the last level asked for.
#[derive(Debug, Clone, Copy)]
struct ElbowDirection {
    q1: f64,
    cos: f64,
    sin: f64,
    rotations: u32,
}

impl ElbowDirection {
    /// `(cos q1, sin q1)` at two angles (lane by lane), turned from the last direction when both turns are
    /// small; the last direction becomes the second's.
    #[inline]
    fn at(&mut self, q1: [f64; 2]) -> [Lanes; 2] {
        let d = Lanes::new(q1) - self.q1;
        let (cos, sin) = if self.rotations < ROTATIONS && d.small(SMALL_TURN).all() {
            // sin d and 1 − cos d by their series; the turn is applied as a correction of the old values.
            let d2 = d * d;
            let sin_d = d
                * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))));
            let versin_d = d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
            let (c, s) = (self.cos, self.sin);
            self.rotations += 1;
            (
                c - (c * versin_d + s * sin_d),
                s + (c * sin_d - s * versin_d),
            )
        } else {
            self.rotations = 0;
            let [(sin_a, cos_a), (sin_b, cos_b)] = if q1[0] == q1[1] {
                [q1[0].sin_cos(); 2]
            } else {
                q1.map(f64::sin_cos)
            };
            (Lanes::new([cos_a, cos_b]), Lanes::new([sin_a, sin_b]))
        };
        (self.q1, self.cos, self.sin) = (q1[1], cos.array()[1], sin.array()[1]);
        [cos, sin]
    }
}

/// One run's line as the shoulder's closed form needs it.
#[derive(Debug, Clone, Copy)]
pub(super) struct ShoulderCircle {
    p: [f64; 2],
    u: [f64; 2],
    /// `ρ²(s) = a·s² + 2b·s + c`, and `1/a`.
    a: f64,
    inv_a: f64,
    b: f64,
    c: f64,
    l1: f64,
    /// `L1² − L2²`.
    links: f64,
    /// The motor's reading at `q1 = 0`.
    zero: f64,
    /// +1 on the left elbow branch, −1 on the right.
    branch: f64,
    /// Bounds of the rounding of `C` and `B` (absolute), and of `a`.
    error_c: f64,
    error_b: f64,
    error_a: f64,
    elbow: ElbowDirection,
}

impl ShoulderCircle {
    /// The shoulder motor's circle for `line` (`None` for the elbow motor, or a line without XY motion).
    pub(super) fn new(line: &JointLine, shoulder_zero: f64) -> Option<Self> {
        if !line.shoulder || line.a <= 0.0 {
            return None;
        }
        let eps = f64::EPSILON;
        let (l1, l2) = (line.l1, line.l2);
        // Each coefficient is a few roundings at the size of its largest term.
        let c_size = line.c + 2.0 * l1 * line.c.sqrt() + l1 * l1 + l2 * l2;
        let b_size = line.b.abs() + l1 * line.a.sqrt();
        Some(ShoulderCircle {
            p: line.arm_start,
            u: line.arm_dir,
            a: line.a,
            inv_a: 1.0 / line.a,
            b: line.b,
            c: line.c,
            l1,
            links: l1 * l1 - l2 * l2,
            zero: shoulder_zero,
            branch: line.branch,
            error_c: 4.0 * eps * c_size,
            error_b: 3.0 * eps * b_size,
            error_a: 2.0 * eps * line.a,
            elbow: ElbowDirection {
                q1: f64::NAN,
                cos: 1.0,
                sin: 0.0,
                rotations: ROTATIONS,
            },
        })
    }

    /// The distances where the shoulder motor reads `levels[0]` and then `levels[1]` (the same level twice
    /// for one): the first in `[before, after]` (either order), the second between the first and `after`,
    /// each when the closed form finds exactly one on the branch and its rounding is within `tol`. The
    /// second is `None` whenever the first is. Both quadratics are solved side by side in two lanes.
    #[inline]
    pub(super) fn crossings(
        &mut self,
        levels: [f64; 2],
        before: f64,
        after: f64,
        tol: f64,
    ) -> [Option<f64>; 2] {
        let [cos, sin] = self.elbow.at(levels.map(|level| level - self.zero));
        let e = [self.l1 * cos, self.l1 * sin];
        let b = self.b - (e[0] * self.u[0] + e[1] * self.u[1]);
        let c = (self.c - 2.0 * (e[0] * self.p[0] + e[1] * self.p[1])) + self.links;
        let disc = b * b - self.a * c;
        let root_disc = disc.sqrt();
        let q = -(b + root_disc.copysign(b));
        let roots = [q * self.inv_a, c / q];
        // A root moves by the rounding of the coefficients (weighted by powers of s) over `|2·√disc|`, and
        // by the rounding of `disc` itself over `2·a·√disc`.
        let error_disc = 3.0 * f64::EPSILON * self.inv_a * (b * b + (self.a * c).abs());
        let quadratic = Quadratic {
            e: e.map(Lanes::array),
            roots: roots.map(Lanes::array),
            slack: (2.0 * tol * root_disc - error_disc).array(),
        };
        // No crossing (or a grazing one, which Newton's method takes) unless the discriminant is positive.
        let positive = disc.positive().lanes();
        let first = positive[0]
            .then(|| self.root(&quadratic, 0, before, after))
            .flatten();
        let second = first
            .filter(|_| positive[1])
            .and_then(|root| self.root(&quadratic, 1, root, after));
        [first, second]
    }

    /// Lane `lane`'s root in `[from, to]` (either order) on the branch, if it is the only one and its
    /// rounding is within the slack.
    #[inline]
    fn root(&self, quadratic: &Quadratic, lane: usize, from: f64, to: f64) -> Option<f64> {
        let (lo, hi) = if from <= to { (from, to) } else { (to, from) };
        let e = [quadratic.e[0][lane], quadratic.e[1][lane]];
        let on_branch = |s: f64| {
            let (nu, nv) = (self.p[0] + self.u[0] * s, self.p[1] + self.u[1] * s);
            s >= lo && s <= hi && (e[0] * nv - e[1] * nu) * self.branch > 0.0
        };
        let roots = [quadratic.roots[0][lane], quadratic.roots[1][lane]];
        let root = match (on_branch(roots[0]), on_branch(roots[1])) {
            (true, false) => roots[0],
            (false, true) => roots[1],
            _ => return None,
        };
        let s = root.abs();
        let error = self.error_c + 2.0 * self.error_b * s + self.error_a * s * s;
        (error <= quadratic.slack[lane]).then_some(root)
    }
}

/// Both lanes' quadratics, solved: the elbow positions, the two roots, and what rounding may still cost
/// (twice the tolerance times `√disc`, less the discriminant's own rounding).
struct Quadratic {
    e: [[f64; 2]; 2],
    roots: [[f64; 2]; 2],
    slack: [f64; 2],
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::ScaraParams;
    use kinematics::scara::{Scara, ScaraJoint};
    use trapq::Piece;

    fn line(start: [f64; 2], dir: [f64; 2]) -> JointLine {
        let kin = Scara::new(ScaraParams::fekt_example()).expect("params");
        let n = dir[0].hypot(dir[1]);
        let piece = Piece {
            print_time: 0.0,
            duration: 1.0,
            start_v: 10.0,
            half_accel: 0.0,
            start_pos: [start[0], start[1], 0.0],
            axes_r: [dir[0] / n, dir[1] / n, 0.0],
            motion: trapq::Motion::Travel,
        };
        JointLine::new(kin.geometry(), ScaraJoint::Shoulder, &piece)
    }

    /// A rotated direction stays within 1e-15 of `sin_cos` over a whole chain of small turns.
    #[test]
    fn rotations_follow_sin_cos() {
        let mut direction = ElbowDirection {
            q1: f64::NAN,
            cos: 1.0,
            sin: 0.0,
            rotations: ROTATIONS,
        };
        let step = std::f64::consts::TAU / 9600.0;
        for i in 0..2000 {
            let q1 = 1.3 + step * f64::from(i) * if i % 700 < 350 { 1.0 } else { -1.0 };
            let q1 = [q1, q1 + step];
            let [c, s] = direction.at(q1).map(Lanes::array);
            for lane in 0..2 {
                let (sin, cos) = q1[lane].sin_cos();
                let error = (c[lane] - cos).abs().max((s[lane] - sin).abs());
                assert!(error < 1e-15, "{i} lane {lane}: {error}");
            }
        }
    }

    /// Each crossing the closed form gives is where a full evaluation of the motor reads the level (within
    /// a few 1e-15 rad), on lines across the FEKT arm's workspace and through turning points of the shoulder.
    #[test]
    fn crossings_are_where_the_motor_reads_the_level() {
        let zero = Scara::new(ScaraParams::fekt_example())
            .expect("params")
            .geometry()
            .shoulder_zero();
        let mut taken = 0;
        for (start, dir) in [
            ([-60.0, 120.0], [1.0, 0.0]),
            ([40.0, 170.0], [-0.3, -1.0]),
            ([-80.0, 90.0], [1.0, 0.7]),
            ([0.0, 199.0], [0.01, -1.0]),
        ] {
            let line = line(start, dir);
            let mut circle = ShoulderCircle::new(&line, zero).expect("shoulder");
            let mut q1 = line.eval(0.0, 0.0).expect("reachable").probe.q1;
            for i in 1..=1200 {
                let s = 0.1 * f64::from(i);
                let Ok(p) = line.eval(s, q1) else { break };
                q1 = p.probe.q1;
                // The level read here, searched for between the points 0.05 mm either side.
                if let [Some(root), _] = circle.crossings([p.probe.f; 2], s - 0.05, s + 0.05, 1e-9)
                {
                    let at = line.eval(root, q1).expect("reachable").probe.f;
                    assert!(
                        (at - p.probe.f).abs() < 5e-15,
                        "{start:?} {s}: {at} vs {}",
                        p.probe.f
                    );
                    assert!((root - s).abs() < 1e-9, "{start:?} {s}: root {root}");
                    taken += 1;
                }
            }
        }
        assert!(taken > 2000, "closed form taken {taken} times");
    }
}
