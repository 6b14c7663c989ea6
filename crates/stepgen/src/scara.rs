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
//! motor is monotonic, so its steps are exactly those of [`StepRule::monotonic`]. The shoulder's crossings
//! have a closed form (`shoulder.rs`: where the line meets the circle of radius `L2` about the elbow), taken
//! wherever its rounding is within the tolerance. Any other crossing is found by Newton's method on that
//! one motor, worked on the run's inverse (distance as a function of the motor: a step is `ds/d(motor)`
//! times the level's miss, no division), started from the last evaluated point with
//! a second-order prediction and kept inside a bracket (bisection when Newton leaves it), so a crossing can
//! be neither missed nor taken out of order. Levels go two at a time (`Crossings::try_pair`): both
//! predicted from the last crossing and evaluated from the last point side by side in the two lanes of
//! packed arithmetic (`lanes.rs`), so one set of instructions serves both and their serial chains overlap;
//! each takes Newton's steps from its own evaluation until the step lands within the tolerance (nearly
//! always the first). Typically one evaluation per step; the general solver made about five of all
//! motors, plus 17+ Jacobian samples per span.
//!
//! Run ends are evaluated with the arithmetic of `ScaraGeometry::joints` and `motors_from_joints` and
//! unwrapped as `Kinematics::inverse_near` does (near the previous evaluation; across a long run, near the
//! continued angle), so the motor function is the one the general solver crossed. Newton's evaluations go
//! from the previous point by angle increments (the turns of link 1 and of the elbow are arguments of
//! complex products, tangents over one division, a short `atan` series: no libm call), summed apart from
//! the last full evaluation's value, in full every [`CHAIN`] evaluations; they differ from a full
//! evaluation by a few 1e-16 rad. A span that
//! comes within 1e-12 of the arm's reach limits (`|cos q2| → 1`) goes to the general solver, which reports
//! unreachable points as before.

mod joint_line;
mod lanes;
mod shoulder;

use kinematics::scara::{SHOULDER, ScaraGeometry, ScaraJoint};
use kinematics::{Kinematics, ReachError};
use trapq::Piece;

use self::joint_line::{JointLine, Point, Probe};
use self::lanes::Lanes;
use self::shoulder::ShoulderCircle;

use crate::error::StepError;
use crate::general::GeneralState;
use crate::sink::StepSink;
use crate::step_rule::{LevelInverse, StepRule};
use crate::timing::{Span, clamp_between};

/// Target accuracy of a crossing, in seconds of travel (the old solver's was 1e-12 s).
const ROOT_TIME_TOL: f64 = 1e-13;
/// Most stretches pending in the run search (each halving adds one; 2⁻⁹⁰ of a span is far below `tol`).
const STACK: usize = 96;
/// Evaluations by increments between two full ones: their sum rounds at its own size, under 1e-17 rad
/// per increment of a step or two, so a chain stays within a few 1e-15 rad of full evaluations.
const CHAIN: u32 = 256;
/// Newton iterations before giving up on convergence (bisection alone needs ~60 for any span).
const MAX_ITERATIONS: usize = 200;

/// The crossings of one run, where the motor is monotonic: Newton from the previous crossing in a bracket.
/// Distances `s` are functions of the motor level here (the run's inverse): predictions and the acceptance
/// test use ds/d(motor) and its rate of change, so a Newton step is a product.
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
    /// The last evaluated point of an accepted crossing: distance, motor level and ds/d(motor).
    prev: (f64, f64, f64),
    /// `1 / (0.1·min(L1, L2))`: a curvature no motor function that matters here exceeds (acceptance slack).
    inv_length: f64,
    /// Estimate of d²s/d(motor)², from successive crossings.
    bend: f64,
    /// The last evaluated point, and how many evaluations have been chained from it since the last full one.
    anchor: Probe,
    chained: u32,
    /// Distance tolerance of a crossing.
    tol: f64,
    failure: Option<(f64, ReachError)>,
    /// The shoulder's closed form (`None` for the elbow), and whether it has taken crossings since Newton's
    /// state above was last brought up to date.
    circle: Option<ShoulderCircle>,
    stale: bool,
}

impl Crossings<'_> {
    /// Whether `x` lies in the closed bracket.
    fn inside(&self, x: f64) -> bool {
        between(x, self.before, self.after)
    }

    /// First guess for `level`: the last evaluated point advanced by a second-order Taylor step of the inverse.
    #[inline]
    fn predict(&self, level: f64) -> f64 {
        let (s0, f0, inv_slope) = self.prev;
        let df = level - f0;
        let guess = s0 + df * (inv_slope + 0.5 * self.bend * df);
        if guess.is_finite() {
            guess
        } else {
            0.5 * (self.before + self.after)
        }
    }

    /// Distance where the motor reaches `level`.
    fn solve(&mut self, level: f64) -> f64 {
        let x = self.predict(level);
        self.solve_from(level, x, self.prev)
    }

    /// [`Self::solve`] from the guess `x` (`last`: the last evaluated point, what the predictor learns from
    /// if nothing else is evaluated).
    fn solve_from(&mut self, level: f64, mut x: f64, mut last: (f64, f64, f64)) -> f64 {
        for _ in 0..MAX_ITERATIONS {
            if !strictly_between(x, self.before, self.after) {
                x = 0.5 * (self.before + self.after);
            }
            let p = match self.evaluate(x) {
                Ok(p) => p,
                Err(e) => {
                    self.failure.get_or_insert((x, e));
                    return x;
                }
            };
            last = (x, p.f, p.inv_slope);
            match self.newton_step(level, x, &p) {
                Newton::Root(root) => return self.accept(root, last),
                Newton::Next(next) => x = next,
            }
        }
        self.accept(x, last)
    }

    /// Narrow the bracket with the evaluated point `x` (where the motor is `p`) and take one Newton step
    /// towards `level`: the crossing when the step lands within the tolerance inside the bracket (or the
    /// bracket is within it), else the next point to evaluate.
    #[inline]
    fn newton_step(&mut self, level: f64, x: f64, p: &Probe) -> Newton {
        let g = (p.f - level) * self.rising;
        if g == 0.0 {
            return Newton::Root(x);
        }
        if g < 0.0 {
            self.before = x;
        } else {
            self.after = x;
        }
        let df = level - p.f;
        let next = x + df * p.inv_slope;
        if self.step_lands(df, p.inv_slope) && self.inside(next) {
            Newton::Root(next)
        } else if (self.after - self.before).abs() <= self.tol {
            Newton::Root(x)
        } else {
            Newton::Next(next)
        }
    }

    /// The motor at `x`: from the last point by increments, in full every [`CHAIN`] evaluations (so the
    /// increments' rounding cannot add up) or when the increment is too large for the series.
    #[inline]
    fn evaluate(&mut self, x: f64) -> Result<Probe, ReachError> {
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
                self.line.eval(x, self.anchor.q1)?.probe
            }
        };
        self.anchor = p;
        Ok(p)
    }

    /// Whether a Newton step of `df` in motor level (at inverse slope `inv_slope`) lands within the tolerance:
    /// its error is about |s''|·df²/2, bounded with the estimate of `s''` quadrupled and a floor on the
    /// motor's curvature (`s'' = −f''·s'³`).
    #[inline]
    fn step_lands(&self, df: f64, inv_slope: f64) -> bool {
        let kappa = 2.0 * self.bend.abs() + self.inv_length * inv_slope * inv_slope;
        df * df * kappa <= self.tol
    }

    /// Take `root` as the crossing found from the evaluated point `last` (distance, level, inverse slope).
    #[inline]
    fn accept(&mut self, root: f64, last: (f64, f64, f64)) -> f64 {
        let (_, f0, inv_slope0) = self.prev;
        if last.1 != f0 {
            let bend = (last.2 - inv_slope0) / (last.1 - f0);
            if bend.is_finite() {
                self.bend = bend;
            }
        }
        self.prev = last;
        // The next level lies between this crossing and the run end.
        self.before = root;
        self.after = self.end;
        root
    }
}

impl Crossings<'_> {
    /// Two levels at once, both predicted from the last crossing and evaluated by increments from the last
    /// point, so neither evaluation waits for the other (one level's solve is one long serial dependency:
    /// prediction, evaluation, Newton step). Each takes Newton's steps from its evaluation, in its own
    /// bracket (the second's starts at the first's crossing); nearly always the first step lands. `None`
    /// (nothing has changed) when the first evaluation is not of this path.
    #[inline]
    fn try_pair(&mut self, la: f64, lb: f64) -> Option<(f64, f64)> {
        if self.chained >= CHAIN {
            return None;
        }
        let xa = self.predict(la);
        let xb = self.predict(lb);
        let [pa, pb] = self.line.eval_near_pair(Lanes::new([xa, xb]), &self.anchor);
        let pa = pa.filter(|_| strictly_between(xa, self.before, self.after))?;
        self.chained += 1;
        self.anchor = pa;
        let ra = self.finish(la, xa, &pa);
        // `pb` is one increment from the point before `pa`: the chain is one longer, not two.
        let rb = match pb {
            Some(pb) if strictly_between(xb, self.before, self.after) => {
                self.anchor = pb;
                self.finish(lb, xb, &pb)
            }
            _ => self.solve(lb),
        };
        Some((ra, rb))
    }

    /// The crossing of `level`, from its first evaluation `p` at `x` (inside the bracket).
    #[inline]
    fn finish(&mut self, level: f64, x: f64, p: &Probe) -> f64 {
        let last = (x, p.f, p.inv_slope);
        match self.newton_step(level, x, p) {
            Newton::Root(root) => self.accept(root, last),
            Newton::Next(next) => self.solve_from(level, next, last),
        }
    }
}

/// What one Newton step from an evaluated point gives: the crossing, or the next point to evaluate.
enum Newton {
    Root(f64),
    Next(f64),
}

fn finite_or_zero(x: f64) -> f64 {
    if x.is_finite() { x } else { 0.0 }
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

impl Crossings<'_> {
    /// The crossing of `level`: in closed form for the shoulder where that is within the tolerance, else by
    /// Newton's method.
    #[inline]
    fn crossing(&mut self, level: f64) -> f64 {
        if let Some(circle) = &mut self.circle {
            let [root, _] = circle.crossings([level; 2], self.before, self.after, self.tol);
            if let Some(root) = root {
                return self.take(root);
            }
            if self.stale {
                self.refresh(level);
            }
        }
        self.solve(level)
    }

    /// The shoulder's crossings of `a` and then `b`: those of the closed form's `pair` (solved side by
    /// side), and one at a time where it found none.
    #[inline]
    fn crossing_pair(&mut self, pair: [Option<f64>; 2], a: f64, b: f64) -> (f64, f64) {
        match pair {
            [Some(ra), Some(rb)] => {
                self.take(ra);
                (ra, self.take(rb))
            }
            [Some(ra), None] => {
                self.take(ra);
                (ra, self.crossing(b))
            }
            _ => {
                let ra = self.crossing(a);
                (ra, self.crossing(b))
            }
        }
    }

    /// Take a closed-form crossing: the next level lies beyond it.
    #[inline]
    fn take(&mut self, root: f64) -> f64 {
        self.before = root;
        self.stale = true;
        root
    }

    /// After closed-form crossings, Newton's state describes an older point: evaluate in full at the last
    /// crossing (its shoulder angle is within a step of `level`'s).
    #[cold]
    fn refresh(&mut self, level: f64) {
        self.stale = false;
        let q1_near = level - self.line.geometry.shoulder_zero();
        match self.line.eval(self.before, q1_near) {
            Ok(p) => {
                self.anchor = p.probe;
                self.chained = 0;
                self.prev = (self.before, p.probe.f, p.probe.inv_slope);
                self.bend = finite_or_zero(p.bend);
            }
            Err(e) => {
                self.failure.get_or_insert((self.before, e));
            }
        }
    }
}

impl LevelInverse for Crossings<'_> {
    fn next_time(&mut self, level: f64) -> f64 {
        let root = self.crossing(level);
        self.span.time_at(root)
    }

    const PAIRS: bool = true;

    #[inline]
    fn next_pair(&mut self, a: f64, b: f64) -> (f64, f64) {
        if let Some(circle) = &mut self.circle {
            let pair = circle.crossings([a, b], self.before, self.after, self.tol);
            let (ra, rb) = self.crossing_pair(pair, a, b);
            return (self.span.time_at(ra), self.span.time_at(rb));
        }
        match self.try_pair(a, b) {
            Some((ra, rb)) => (self.span.time_at(ra), self.span.time_at(rb)),
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
        self.q1 = start.probe.q1;
        if line.a == 0.0 || d0 == d1 {
            // No XY motion: the joints cannot move.
            rule.settle(start.probe.f, piece.print_time + span.t0, sink);
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
            self.q1 = end.probe.q1;
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
    let ((sa, pa), (sb, pb)) = ((a.0, &a.1.probe), (b.0, &b.1.probe));
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
        prev: (sa, pa.f, pa.inv_slope),
        inv_length: 10.0 / line.l1.min(line.l2),
        bend: finite_or_zero(a.1.bend),
        anchor: *pa,
        chained: 0,
        tol,
        failure: None,
        circle: ShoulderCircle::new(line, line.geometry.shoulder_zero()),
        stale: false,
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
